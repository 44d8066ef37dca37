"""The RPM filter (core/stages/rpmfilter.py) and its fixed-point form (core/fastpass/fixedrpm.py).

Portable: the same functions run under CPython (pytest) and MicroPython (tests/portable/mprun.py), where
the viper twin (accel/rpmfilter.py) must be chosen and give the Python twin's bits.
"""

import math
from array import array

from fastpathkit import heap_bytes
from test_fixedrate import Lcg  # the same deterministic numbers on every port

from hoverfly.compat import IS_MICROPYTHON
from hoverfly.core.config.params import Params
from hoverfly.core.events import EV_RPM_LOST, EV_RPM_RESTORED, EventLog
from hoverfly.core.fastpass import fixedrpm
from hoverfly.core.signals import Signals
from hoverfly.core.stages.rpmfilter import RpmFilter

LOOP_HZ = 1000


class Reply:
    """An ESC reply as ErpmDecoder leaves it: kind 0 (eRPM) when valid, -1 when it failed its checks."""

    def __init__(self, kind=0):
        self.kind = kind


def _filter(sets=(), bidir=True, motors=4, events=None):
    p = Params()
    p.set("rpm_harmonics", 1)
    for name, value in sets:
        assert p.set(name, value) is None, name
    f = RpmFilter(events)
    f.configure(p, LOOP_HZ, motors, bidir)
    return f


def _rpm(hz, motors=4):
    return array("i", [int(hz * 60.0 + 0.5)] * motors)


def _amplitude(f, hz, rpm, passes=1500, replies=None, axis=0, tail=500):
    """Peak output on `axis` of a unit sine at hz over the last `tail` passes (the filter settled)."""
    g = [0.0, 0.0, 0.0]
    replies = replies if replies is not None else [Reply()] * len(rpm)
    peak = 0.0
    for n in range(passes):
        g[0] = g[1] = g[2] = 0.0
        g[axis] = math.sin(2.0 * math.pi * hz * n / LOOP_HZ)
        f.telemetry(replies, len(rpm))
        f.update(g, rpm, n)
        if n >= passes - tail:
            peak = max(peak, abs(g[axis]))
    return peak


def test_a_notch_at_the_motor_frequency_removes_it_and_passes_the_flight_band():
    rpm = _rpm(170.0)
    f = _filter()
    assert f.active and f.refused == ""
    for axis in range(3):
        assert _amplitude(_filter(), 170.0, rpm, axis=axis) < 0.01  # -40 dB at least, on every axis
    # what the pilot flies (a few Hz to tens of Hz) goes through: Q 5 at 170 Hz is 34 Hz wide
    assert 0.97 < _amplitude(f, 20.0, rpm) <= 1.001
    # a peak between two motors' frequencies is cut only by their skirts
    assert _amplitude(_filter(), 250.0, rpm) > 0.7


def test_each_harmonic_gets_its_notch_and_one_past_048_of_the_loop_rate_none():
    f = _filter((("rpm_harmonics", 3),))
    rpm = _rpm(150.0)
    assert _amplitude(f, 150.0, rpm) < 0.01
    assert _amplitude(_filter((("rpm_harmonics", 3),)), 300.0, rpm) < 0.01
    # 450 Hz: inside the fade below 480 Hz (0.48 x 1 kHz), so the notch is at 60 % of its depth
    w = _filter((("rpm_harmonics", 3),))
    _amplitude(w, 10.0, rpm, passes=200)
    assert abs(w.weight[2] - 0.6) < 1e-9
    w = _filter((("rpm_harmonics", 3),))
    _amplitude(w, 10.0, _rpm(170.0), passes=200)  # 510 Hz: off
    assert w.weight[2] == 0.0 and w.weight[0] == 1.0


def test_below_rpm_min_hz_the_gyro_passes_untouched_and_the_notch_fades_in_above_it():
    f = _filter()
    rpm = _rpm(90.0)  # below rpm_min_hz (100)
    g = [0.0, 0.0, 0.0]
    for n in range(300):
        x = math.sin(2.0 * math.pi * 90.0 * n / LOOP_HZ) + 0.3
        g[0] = g[1] = g[2] = x
        f.telemetry([Reply()] * 4, 4)
        f.update(g, rpm, n)
        assert g[0] == x and g[1] == x and g[2] == x  # exactly: a weight of 0 is a pass-through
    # 125 Hz is half way through the 50 Hz fade: half the depth
    f = _filter()
    _amplitude(f, 10.0, _rpm(125.0), passes=200)
    assert abs(f.weight[0] - 0.5) < 1e-9
    f = _filter((("rpm_weight1_pct", 40),))
    _amplitude(f, 10.0, _rpm(200.0), passes=200)
    assert abs(f.weight[0] - 0.4) < 1e-9


def test_a_motor_whose_telemetry_stops_fades_to_pass_through_and_says_so():
    events = EventLog()
    f = _filter(events=events)
    rpm = _rpm(170.0)
    good = [Reply()] * 4
    _amplitude(f, 170.0, rpm, passes=400, replies=good)
    assert f.lost == 0 and f.weight[0] == 1.0
    # motor 2's ESC stops answering (its replies fail their checks): its notch goes, the others stay
    bad = [Reply(), Reply(-1), Reply(), Reply()]
    g = [0.0, 0.0, 0.0]
    lost_at = None
    for n in range(400, 600):
        g[0] = math.sin(2.0 * math.pi * 170.0 * n / LOOP_HZ)
        f.telemetry(bad, 4)
        f.update(g, rpm, n)
        if f.lost and lost_at is None:
            lost_at = n
        assert g[0] == g[0] and abs(g[0]) <= 1.5  # never a NaN, never a jump
    assert f.lost == 1 << 1
    assert 400 + 20 <= lost_at <= 400 + 25  # RPM_LOST_MS after its last reply, on its round-robin turn
    assert f.weight[1] == 0.0 and f.weight[0] == f.weight[2] == f.weight[3] == 1.0
    assert events.event[0] == EV_RPM_LOST and events.detail[0] == 2 and events.t_us[0] == lost_at
    # a motor that answers again gets its notch back
    for n in range(600, 700):
        f.telemetry(good, 4)
        f.update(g, rpm, n)
    assert f.lost == 0 and f.weight[1] == 1.0
    assert events.event[1] == EV_RPM_RESTORED and events.detail[1] == 2 and events.count == 2


def test_no_reply_at_all_counts_as_lost_too():
    f = _filter()
    g = [0.0, 0.0, 0.0]
    for n in range(100):
        f.update(g, _rpm(170.0), n)  # the board hands over nothing (telemetry() never called)
    assert f.lost == 0b1111
    assert max(f.weight) == 0.0


def test_without_bidirectional_dshot_the_filter_refuses_and_says_why():
    f = _filter(bidir=False)
    assert not f.active
    assert "dshot_bidir = 1" in f.refused and "rpm_harmonics = 1" in f.refused
    off = RpmFilter()
    p = Params()
    off.configure(p, LOOP_HZ, 4, False)  # rpm_harmonics 0: nothing asked, nothing refused
    assert not off.active and off.refused == ""


def _fixed(sets=()):
    f = _filter(sets)
    s = Signals()
    fx = fixedrpm.FixedRpmFilter()
    assert fx.configure(f, s, True)
    return f, s, fx


def test_the_fixed_filter_runs_only_with_the_fixed_imu_filter_and_an_active_float_one():
    f = _filter()
    fx = fixedrpm.FixedRpmFilter()
    assert not fx.configure(f, Signals(), False)
    assert not fx.configure(_filter(bidir=False), Signals(), True)
    assert fx.configure(f, Signals(), True)


def test_the_fixed_filter_agrees_with_the_float_one():
    for sets in ((), (("rpm_harmonics", 2), ("rpm_filter_q", 300)), (("rpm_harmonics", 3), ("rpm_min_hz", 60))):
        f, s, fx = _fixed(sets)
        ref = _filter(sets)
        rnd = Lcg(3)
        g = [0.0, 0.0, 0.0]
        replies = [Reply()] * 4
        worst = 0.0
        for n in range(1200):
            # four motors drifting apart through the fade and the band, a flight-like gyro: their
            # vibration on top of a slow manoeuvre and noise
            for m in range(4):
                s.motor_rpm[m] = 5000 + 40 * n + 700 * m
            for k in range(3):
                v = 0.3 * math.sin(n * 0.02 + k) + rnd.span(0.2)
                for m in range(4):
                    v += 0.2 * math.sin(2.0 * math.pi * s.motor_rpm[m] / 60.0 * n / LOOP_HZ)
                s.gyro_rad_s[k] = v
                g[k] = s.gyro_rad_s[k]  # the float32 value the fixed one reads
            fx.telemetry(replies, 4)
            fx.update(n)
            ref.telemetry(replies, 4)
            ref.update(g, s.motor_rpm, n)
            for k in range(3):
                worst = max(worst, abs(g[k] - s.gyro_rad_s[k]))
        # Q16 in and out (1.5e-5), Q14 coefficients: the notch centre within 0.1 Hz of the float one's
        assert worst < 3e-3, (sets, worst)
        assert worst > 0.0


def test_the_fixed_filter_keeps_its_state_bounded_on_wild_inputs():
    f, s, fx = _fixed((("rpm_harmonics", 3),))
    wild = (float("nan"), float("inf"), -float("inf"), 1e30, -1e30, 0.0, 127.9)
    rpms = (-5, 0, 10 ** 9, -(10 ** 9), 2 ** 31 - 1, 12000)
    for n in range(700):
        for k in range(3):
            s.gyro_rad_s[k] = wild[(n + k) % len(wild)]
        for m in range(4):
            s.motor_rpm[m] = rpms[(n * 3 + m) % len(rpms)]
        fx.telemetry([Reply()] * 4, 4)
        fx.update(n)
        for k in range(3):
            v = s.gyro_rad_s[k]
            assert v == v and -600.0 < v < 600.0, (n, k, v)
    for v in fx.st:
        assert -(1 << 31) <= v < (1 << 31)


def test_the_fixed_filter_notes_a_lost_motor_as_the_float_one_does():
    events = EventLog()
    f = _filter(events=events)
    s = Signals()
    fx = fixedrpm.FixedRpmFilter()
    fx.configure(f, s, True)
    for m in range(4):
        s.motor_rpm[m] = 10200
    for n in range(300):
        fx.telemetry([Reply(), Reply(), Reply(), Reply(-1)], 4)
        fx.update(n)
    assert f.lost == 1 << 3  # the supervisor's arming reason reads the float stage's bits
    assert events.event[0] == EV_RPM_LOST and events.detail[0] == 4
    assert fx.co[fixedrpm.C_NOTCH + 4 * 3 + 3] == 0 and fx.co[fixedrpm.C_NOTCH + 3] == 1 << 14


if IS_MICROPYTHON:
    from hoverfly.accel import rpmfilter as rpm_viper
else:
    rpm_viper = None


def test_the_viper_twin_gives_the_python_twins_bits():
    if not IS_MICROPYTHON:
        assert fixedrpm.FixedRpmFilter.update is fixedrpm.update_python  # no viper: the Python twin runs
        return
    assert fixedrpm.FixedRpmFilter.update is rpm_viper.update
    for sets in ((), (("rpm_harmonics", 3), ("rpm_filter_q", 2500), ("rpm_fade_hz", 0)),
                 (("rpm_harmonics", 2), ("rpm_min_hz", 30), ("rpm_weight2_pct", 35))):
        fa = _fixed(sets)[2]
        fb = _fixed(sets)[2]
        sa = fa._gyro
        sb = fb._gyro
        rnd = Lcg(17)
        for n in range(900):
            for k in range(3):
                v = rnd.span(3.0) if n % 97 else (float("nan") if k == 0 else 1e9)
                sa[k] = sb[k] = v
            for m in range(4):
                r = 3000 + 31 * n + 500 * m if n % 211 else -7
                fa._rpm[m] = fb._rpm[m] = r
            ok = [Reply(0 if (n // 50 + m) % 5 else -1) for m in range(4)]
            fa.telemetry(ok, 4)
            fb.telemetry(ok, 4)
            fixedrpm.update_python(fa, n)
            fb.update(n)
            for k in range(fixedrpm.ST_SIZE):
                assert fa.st[k] == fb.st[k], (sets, n, "st", k, fa.st[k], fb.st[k])
            for k in range(fixedrpm.CO_SIZE):
                assert fa.co[k] == fb.co[k], (sets, n, "co", k, fa.co[k], fb.co[k])
            for k in range(3):
                assert sa[k] == sb[k], (sets, n, "gyro", k, sa[k], sb[k])


def test_a_fixed_rpm_pass_allocates_nothing_on_micropython():
    if not IS_MICROPYTHON:
        return
    f, s, fx = _fixed((("rpm_harmonics", 3),))
    for m in range(4):
        s.motor_rpm[m] = 9000 + 100 * m
    fx.update(0)
    used = heap_bytes(lambda: fx.update(1), 50)
    assert used == 0, used
