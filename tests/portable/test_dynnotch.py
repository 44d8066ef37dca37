"""The dynamic notch (core/stages/dynnotch.py) and its fixed-point form (core/fastpass/fixeddyn.py): they find
the gyro's peaks and follow them.

Portable: the same functions run under CPython (pytest) and MicroPython (tests/portable/mprun.py), where the
fixed form's viper twin (accel/dynnotch.py) must be chosen and give the Python twin's bits.
"""

import math

from test_fixedrate import Lcg  # the same deterministic numbers on every port

from hoverfly.core.config.params import Params
from hoverfly.core.stages.dynnotch import DynNotch

LOOP_HZ = 1000


def _notch(sets=()):
    p = Params()
    p.set("dyn_notch_count", 1)
    for name, value in sets:
        assert p.set(name, value) is None, name
    d = DynNotch()
    d.configure(p, LOOP_HZ)
    return d


def test_the_notch_follows_a_peak_that_moves_and_takes_it_out():
    d = _notch()
    rnd = Lcg(9)
    g = [0.0, 0.0, 0.0]
    out = [0.0]
    phase = 0.0
    worst_hz = 0.0
    peak_after = 0.0
    for n in range(4000):
        hz = 150.0 + 150.0 * min(1.0, n / 3000.0)  # a resonance sweeping 150 -> 300 Hz over 3 s
        phase += 2.0 * math.pi * hz / LOOP_HZ
        x = math.sin(phase) + rnd.span(0.1) + 0.3 * math.sin(2.0 * math.pi * 5.0 * n / LOOP_HZ)
        g[0] = x
        g[1] = g[2] = rnd.span(0.1)
        d.update(g)
        if n >= 300:
            d.centres_hz(0, out)
            worst_hz = max(worst_hz, abs(out[0] - hz))
        if n >= 3500:
            peak_after = max(peak_after, abs(g[0] - 0.3 * math.sin(2.0 * math.pi * 5.0 * n / LOOP_HZ)))
    assert worst_hz < 10.0, worst_hz  # within 10 Hz while it sweeps (the notch is 100 Hz wide at Q 3)
    assert peak_after < 0.3, peak_after  # the unit sine is down by 10 dB and more, noise included
    # the axes with noise alone have no peak that stands out: no notch there
    d.centres_hz(1, out)
    assert out[0] == 0.0 and d.weight[3] == 0.0


def test_two_notches_take_two_peaks_lowest_first():
    d = _notch((("dyn_notch_count", 2),))
    g = [0.0, 0.0, 0.0]
    out = [0.0, 0.0]
    for n in range(1500):
        t = n / LOOP_HZ
        g[0] = math.sin(2.0 * math.pi * 140.0 * t) + 0.6 * math.sin(2.0 * math.pi * 330.0 * t)
        g[1] = g[2] = 0.0
        d.update(g)
    d.centres_hz(0, out)
    assert abs(out[0] - 140.0) < 3.0 and abs(out[1] - 330.0) < 3.0, out


def test_peaks_outside_the_band_are_left_alone():
    d = _notch((("dyn_notch_min_hz", 200), ("dyn_notch_max_hz", 400)))
    g = [0.0, 0.0, 0.0]
    for n in range(1500):
        x = math.sin(2.0 * math.pi * 80.0 * n / LOOP_HZ)  # a flight manoeuvre's band, below dyn_notch_min_hz
        g[0] = x
        g[1] = g[2] = 0.0
        d.update(g)
        assert abs(g[0] - x) < 1e-12  # nothing notched: exactly the input
    assert max(d.weight) == 0.0


def test_the_band_stops_below_048_of_the_loop_rate_and_a_nan_does_not_stick():
    d = _notch((("dyn_notch_max_hz", 1000),))
    assert d.max_hz == 480.0 and (d.k_hi + 2) * LOOP_HZ / 32 <= 500.0
    g = [float("nan"), 0.0, 0.0]
    d.update(g)
    assert g[1] == 0.0 and g[2] == 0.0  # one axis's NaN stays on its axis
    d.reset()  # what Flight.restart_estimation does after a non-finite gyro
    for n in range(200):
        g[0] = g[1] = g[2] = math.sin(n * 0.3)
        d.update(g)
        assert g[0] == g[0]


def test_every_runtime_takes_the_dynamic_notch():
    p = Params()
    assert p.set("dyn_notch_count", 2) is None and p.get("dyn_notch_count") == 2
    assert p.set("dyn_notch_count", 4) is not None  # 0..3, as the table says


# ---------------------------------------------------------------- the fixed-point form (core/fastpass/fixeddyn.py)
from fastpathkit import heap_bytes  # noqa: E402

from hoverfly.compat import IS_MICROPYTHON  # noqa: E402
from hoverfly.core.fastpass import fixeddyn  # noqa: E402
from hoverfly.core.signals import Signals  # noqa: E402


def _fixed(sets=()):
    d = _notch(sets)
    s = Signals()
    fx = fixeddyn.FixedDynNotch()
    assert fx.configure(d, s, True)
    return d, s, fx


def _sweep(n, rnd, phase):
    hz = 150.0 + 150.0 * min(1.0, n / 3000.0)
    phase += 2.0 * math.pi * hz / LOOP_HZ
    return hz, phase, math.sin(phase) + rnd.span(0.1)


def test_the_fixed_notch_follows_a_moving_peak_as_the_float_one_does():
    d, s, fx = _fixed()
    ref = _notch()
    rnd = Lcg(9)
    g = [0.0, 0.0, 0.0]
    out = [0.0]
    out_ref = [0.0]
    phase = 0.0
    worst = worst_ref = peak_after = 0.0
    for n in range(4000):
        hz, phase, x = _sweep(n, rnd, phase)
        s.gyro_rad_s[0] = x
        s.gyro_rad_s[1] = s.gyro_rad_s[2] = rnd.span(0.1)
        g[0] = s.gyro_rad_s[0]
        g[1] = s.gyro_rad_s[1]
        g[2] = s.gyro_rad_s[2]
        fx.update()
        ref.update(g)
        if n >= 300:
            fx.centres_hz(0, out)
            ref.centres_hz(0, out_ref)
            worst = max(worst, abs(out[0] - hz))
            worst_ref = max(worst_ref, abs(out_ref[0] - hz))
        if n >= 3500:
            peak_after = max(peak_after, abs(s.gyro_rad_s[0]))
    assert worst < 10.0 and worst_ref < 10.0, (worst, worst_ref)
    assert peak_after < 0.3, peak_after
    fx.centres_hz(1, out)
    assert out[0] == 0.0  # noise alone: no notch, as the float one


def test_the_fixed_notch_keeps_its_state_bounded_on_wild_inputs():
    d, s, fx = _fixed((("dyn_notch_count", 3),))
    wild = (float("nan"), float("inf"), -float("inf"), 1e30, -1e30, 0.0, 127.9, -127.9)
    for n in range(800):
        for k in range(3):
            s.gyro_rad_s[k] = wild[(n * 3 + k) % len(wild)] if n % 5 else 100.0 * math.sin(n * 2.1)
        fx.update()
        for k in range(3):
            v = s.gyro_rad_s[k]
            assert v == v and -600.0 < v < 600.0, (n, k, v)
    for v in fx.st:
        assert -(1 << 31) <= v < (1 << 31)


def test_the_fixed_notch_viper_twin_gives_the_python_twins_bits():
    if not IS_MICROPYTHON:
        assert fixeddyn.FixedDynNotch.update is fixeddyn.update_python
        return
    from hoverfly.accel import dynnotch as dyn_viper

    assert fixeddyn.FixedDynNotch.update is dyn_viper.update
    for sets in ((), (("dyn_notch_count", 3), ("dyn_notch_q", 150)), (("dyn_notch_count", 2),
                                                                       ("dyn_notch_min_hz", 60))):
        fa = _fixed(sets)[2]
        fb = _fixed(sets)[2]
        ga = fa._gyro
        gb = fb._gyro
        rnd = Lcg(21)
        phase = 0.0
        for n in range(1200):
            hz, phase, x = _sweep(n * 3, rnd, phase)
            for k in range(3):
                v = x * (k + 1) + rnd.span(0.3) if n % 101 else (float("nan") if k else 3e9)
                ga[k] = gb[k] = v
            fixeddyn.update_python(fa)
            fb.update()
            for k in range(fixeddyn.ST_SIZE):
                assert fa.st[k] == fb.st[k], (sets, n, "st", k, fa.st[k], fb.st[k])
            for k in range(fixeddyn.CO_SIZE):
                assert fa.co[k] == fb.co[k], (sets, n, "co", k, fa.co[k], fb.co[k])
            for k in range(3):
                assert ga[k] == gb[k], (sets, n, "gyro", k, ga[k], gb[k])


def test_a_fixed_dynamic_notch_pass_allocates_nothing_on_micropython():
    if not IS_MICROPYTHON:
        return
    d, s, fx = _fixed((("dyn_notch_count", 3),))
    s.gyro_rad_s[0] = 0.5
    fx.update()
    used = heap_bytes(fx.update, 50)
    assert used == 0, used
