"""The dynamic notch (core/stages/dynnotch.py): it finds the gyro's peaks and follows them.

Portable: the same functions run under CPython (pytest) and MicroPython (tests/portable/mprun.py).
"""

import math

from test_fixedrate import Lcg  # the same deterministic numbers on every port

from hoverfly.core.config.params import Params
from hoverfly.core.stages.dynnotch import DynNotch

LOOP_HZ = 1000


def _notch(sets=()):
    p = Params()
    p.values["dyn_notch_count"] = 1  # past the check: MicroPython refuses it (the last test), the stage runs anyway
    for name, value in sets:
        if name == "dyn_notch_count":
            p.values[name] = value
        else:
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


def test_micropython_refuses_the_dynamic_notch_with_the_reason():
    from hoverfly.compat import IS_MICROPYTHON

    p = Params()
    err = p.set("dyn_notch_count", 2)
    if IS_MICROPYTHON:  # float only: far beyond the fixed-point pass's budget there
        assert err is not None and "dyn_notch_count = 2" in err and "float only" in err
        assert p.get("dyn_notch_count") == 0
    else:
        assert err is None and p.get("dyn_notch_count") == 2
    assert p.set("dyn_notch_count", 0) is None
