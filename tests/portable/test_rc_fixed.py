"""The stick shaping in fixed point (core/stages/rc.py `rc_pass`) against the float stage, and its viper twin.

Portable: under MicroPython (tests/portable/mprun.py) the viper twin (accel/rc.py) must be the one
chosen and must give the Python twin's bits on every output, state word and change mask; on both
runtimes the fixed stage must agree with the float smoothing and curves it stands in for, pass by
pass, within the bound stated here.
"""

import struct
from array import array

from fastpathkit import heap_bytes
from fastpathkit import params as _params
from test_fixedrate import Lcg  # the same deterministic numbers on every port

from hoverfly.compat import IS_MICROPYTHON
from hoverfly.core.signals import Setpoint
from hoverfly.core.stages import rc as rcmod
from hoverfly.core.stages.rc import CO_SIZE, S_S1, S_X, S_Y, ST_SIZE, RcInput

if IS_MICROPYTHON:
    from hoverfly.accel import rc as rc_viper
else:
    rc_viper = None


def _rc(pid_math, **kw):
    rc = RcInput()
    rc.configure(_params(pid_math=pid_math, **kw), 1000)
    return rc


def _frame(n):
    """A flight-like frame at pass n: sweeps and steps on every stick, a throttle ramp, full deflections."""
    phase = (n // 400) % 4
    roll = 1500 + ((n * 7) % 1100) - 550 if phase == 0 else (2000 if phase == 1 else 1500 + (n // 4) % 9)
    pitch = 1000 if phase == 2 else 1500 + ((n * 3) % 600) - 300
    yaw = 1500 + (n % 900) - 450 if phase != 3 else 1500
    thr = 1000 + (n * 5) % 1100
    return array("H", [roll, pitch, thr, yaw, 1000, 1500] + [1500] * 10)  # as the Flight's rc_channels_us


def _bits32(a, n):
    return [struct.pack("<f", a[i]) for i in range(n)]


def test_the_fixed_stage_runs_with_the_fixed_rate_loop_and_a_pt2():
    assert rcmod.HAS_ACCEL == IS_MICROPYTHON  # the unix VM has viper; CPython has not
    assert _rc("fixed").fixed
    assert not _rc("float").fixed
    assert _rc("auto").fixed == IS_MICROPYTHON
    assert not _rc("fixed", rc_smooth_type="pt1").fixed
    assert not _rc("fixed", rc_smooth_type="alphabeta").fixed
    assert _rc("fixed", rc_smoothing_hz=0).fixed  # smoothing off: a gain of one


def test_the_fixed_stage_agrees_with_the_float_stage():
    for kw in ({}, {"rc_smoothing_hz": 0}, {"rc_smoothing_hz": 150, "roll_expo": 40, "yaw_expo": 100,
                                            "angle_limit": 45, "roll_srate": 200, "pitch_rc_rate": 255}):
        a = _rc("float", **kw)
        b = _rc("fixed", **kw)
        sa = Setpoint()
        sb = Setpoint()
        worst_stick = worst_rate = worst_angle = worst_thr = 0.0
        rate_bound = 0.0
        for axis in range(3):
            r = a.rates[axis]
            rate_bound = max(rate_bound, 1e-4 * (r.centre_rad_s + 2.0 * r.travel_rad_s) + 2e-5)
        for n in range(1600):
            if n % 4 == 0:
                ch = _frame(n)
                a.new_frame(ch)
                b.new_frame(ch)
            a.update(sa)
            b.update(sb)
            for i in range(3):
                worst_stick = max(worst_stick, abs(sa.stick_norm[i] - sb.stick_norm[i]))
                worst_rate = max(worst_rate, abs(sa.rate_rad_s[i] - sb.rate_rad_s[i]))
            worst_angle = max(worst_angle, abs(sa.roll_angle_rad - sb.roll_angle_rad),
                              abs(sa.pitch_angle_rad - sb.pitch_angle_rad))
            worst_thr = max(worst_thr, abs(sa.throttle_norm - sb.throttle_norm))
        # The Q15 gain's rounding (at most 2**-16 of it) times the swing (a full-stick step: up to 6e-5),
        # the Q20 states' rounding (a few 1e-6) and the curve's Q16 stick (1.5e-5 of stick) times its
        # slope, centre + 2 travel at full stick: a thousandth of a degree per second on a 600 deg/s curve.
        assert worst_stick < 1e-4, (kw, worst_stick)
        assert worst_rate < rate_bound, (kw, worst_rate, rate_bound)
        assert worst_angle < 1e-4 * a.angle_limit_rad, (kw, worst_angle)
        assert worst_thr < 1e-4, (kw, worst_thr)
        if not kw:
            assert worst_stick > 0.0  # the two really are different arithmetic


def test_a_centred_stick_comes_back_to_exactly_zero():
    rc = _rc("fixed")
    sp = Setpoint()
    ch = array("H", [1900, 1100, 1500, 1800] + [1500] * 12)
    for n in range(400):
        if n % 4 == 0:
            rc.new_frame(ch)
        rc.update(sp)
    ch = array("H", [1500, 1500, 1000, 1500] + [1500] * 12)
    for n in range(600):
        if n % 4 == 0:
            rc.new_frame(ch)
        rc.update(sp)
    assert list(sp.stick_norm) == [0.0, 0.0, 0.0]
    assert list(sp.rate_rad_s) == [0.0, 0.0, 0.0]
    assert sp.roll_angle_rad == 0.0 and sp.pitch_angle_rad == 0.0 and sp.throttle_norm == 0.0


def test_a_full_stick_gives_the_full_rate_and_angle():
    rc = _rc("fixed", roll_rc_rate=20, roll_srate=80, angle_limit=55)
    sp = Setpoint()
    for n in range(800):
        if n % 4 == 0:
            rc.new_frame(array("H", [2011, 988, 2011, 1500] + [1500] * 12))
        rc.update(sp)
    assert sp.stick_norm[0] == 1.0 and sp.stick_norm[1] == 1.0  # pitch stick back: nose up
    assert abs(sp.rate_rad_s[0] - rc.rates[0].max_rate_rad_s()) < 2e-5
    assert abs(sp.roll_angle_rad - 55.0 * 3.141592653589793 / 180.0) < 1e-6
    assert sp.throttle_norm == 1.0


def test_the_setpoint_is_rewritten_every_pass():
    # the failsafe and the autopilot overwrite the setpoint after rc.update (Flight.command)
    rc = _rc("fixed")
    sp = Setpoint()
    ref = Setpoint()
    rc.new_frame(array("H", [1700, 1400, 1600, 1450] + [1500] * 12))
    for _ in range(600):
        rc.update(sp)
    rc.update(ref)
    sp.stick_norm[0] = 0.5
    sp.rate_rad_s[1] = 0.5
    sp.roll_angle_rad = 0.5
    sp.pitch_angle_rad = 0.5
    sp.throttle_norm = 0.5
    rc.update(sp)
    assert _bits32(sp.stick_norm, 3) == _bits32(ref.stick_norm, 3)
    assert _bits32(sp.rate_rad_s, 3) == _bits32(ref.rate_rad_s, 3)
    assert (sp.roll_angle_rad, sp.pitch_angle_rad, sp.throttle_norm) == (
        ref.roll_angle_rad, ref.pitch_angle_rad, ref.throttle_norm)


def test_switching_hands_the_smoothing_state_over_both_ways():
    p = _params(pid_math="fixed")
    rc = RcInput()
    rc.configure(p, 1000)
    sp = Setpoint()
    rc.new_frame(array("H", [1800, 1500, 1500, 1500] + [1500] * 12))
    for _ in range(10):
        rc.update(sp)
    mid = sp.stick_norm[0]
    held = rc.stick_raw[0]  # 295 / 495
    assert 0.0 < mid < held
    p.set("pid_math", "float")
    rc.configure(p, 1000)  # mid-step: the float filters carry on from the fixed state
    assert not rc.fixed and abs(rc.filters[0].y - mid) < 1e-6
    rc.update(sp)
    assert sp.stick_norm[0] > mid
    mid = sp.stick_norm[0]
    p.set("pid_math", "fixed")
    rc.configure(p, 1000)
    assert rc.fixed
    rc.update(sp)
    assert mid < sp.stick_norm[0] < held
    rc.reset_smoothing()  # straight to the stick
    rc.update(sp)
    assert abs(sp.stick_norm[0] - held) < 1e-6 and abs(sp.roll_angle_rad - held * rc.angle_limit_rad) < 1e-6


def test_a_fixed_update_allocates_only_the_floats_of_a_moving_angle_or_throttle():
    rc = _rc("fixed")
    sp = Setpoint()
    rc.new_frame(array("H", [1600, 1500, 1400, 1500] + [1500] * 12))
    for _ in range(600):  # settled: nothing moves
        rc.update(sp)
    assert heap_bytes(lambda: rc.update(sp), 50) == 0
    rc.new_frame(array("H", [1500, 1500, 1400, 1700] + [1500] * 12))  # roll and yaw move: the roll angle is remade
    one = heap_bytes(lambda: rc.update(sp), 1)
    assert one <= 32  # one float (a GC block on the 64-bit VM), the stick and rate arrays written in place


def _lcg_config(rnd):
    co = array("i", [0] * CO_SIZE)
    co[0] = (32768, 1, 9000, 20000, 32767)[int(rnd.unit() * 5)]
    for i in range(3):
        co[1 + i] = int(rnd.unit() * 0x3FFFFF)
        co[4 + i] = int(rnd.unit() * 0x3FFFFF)
        co[7 + i] = (0, 65536, int(rnd.unit() * 65536))[int(rnd.unit() * 3)]
    return co


def test_the_viper_twin_gives_the_python_twins_bits():
    if not IS_MICROPYTHON:
        assert RcInput.update is rcmod.update_python
        return  # CPython has no viper: the Python twin is the stage (the test above)
    assert RcInput.update is rc_viper.update
    rnd = Lcg(11)
    one = 1 << 20
    # two fixed stages, each with its own set point: the Python update on one, the viper update on the other
    rp = _rc("fixed")
    rv = _rc("fixed")
    sp_p = Setpoint()
    sp_v = Setpoint()
    for config in range(40):
        co = _lcg_config(rnd)
        for k in range(CO_SIZE):
            rp._co[k] = rv._co[k] = co[k]
        rp._angle_per_q = rv._angle_per_q = rnd.unit() * 2.0 / one
        for i in range(4):
            lo = 0 if i == 3 else -one
            for base in (S_X, S_S1, S_Y):
                rp._st[base + i] = rv._st[base + i] = lo + int(rnd.unit() * (one - lo + 1))
        rp._refresh()
        rv._refresh()
        for n in range(60):
            if n % 7 == 0:
                for i in range(4):
                    lo = 0 if i == 3 else -one
                    v = (lo, one, 0, lo + int(rnd.unit() * (one - lo + 1)))[int(rnd.unit() * 4)]
                    rp._st[S_X + i] = rv._st[S_X + i] = v
            rcmod.update_python(rp, sp_p)
            rv.update(sp_v)
            assert list(rp._st) == list(rv._st), (config, n)
            assert _bits32(sp_p.stick_norm, 3) == _bits32(sp_v.stick_norm, 3), (config, n)
            assert _bits32(sp_p.rate_rad_s, 3) == _bits32(sp_v.rate_rad_s, 3), (config, n)
            for name in ("roll_angle_rad", "pitch_angle_rad", "throttle_norm"):
                assert getattr(sp_p, name) == getattr(sp_v, name), (config, n, name)


def test_rc_frame_twins_agree():
    # new_frame's integer part (core/stages/rc.py rc_frame; accel/rc.py's viper twin on MicroPython): the same
    # moved-stick mask, switch bits, last µs and Q20 inputs on random tables and frames
    from hoverfly.core.stages.rc import FC_SIZE

    if not IS_MICROPYTHON:
        assert rcmod._rc_frame is rcmod.rc_frame
    twin = rc_viper.rc_frame if IS_MICROPYTHON else rcmod.rc_frame
    rnd = Lcg(5)

    def pick(n):
        return int(rnd.unit() * n)

    seen = 0
    for config in range(60):
        fco = array("i", [0] * FC_SIZE)
        order = [0, 1, 2, 3]
        for i in range(3, 0, -1):
            j = pick(i + 1)
            order[i], order[j] = order[j], order[i]
        for i in range(4):
            fco[i] = order[i]
        fco[4] = pick(60)
        fco[5] = pick(60)
        fco[6] = config % 2
        for k in range(7, FC_SIZE, 3):
            fco[k] = pick(20)  # 0 = none, 17..19: beyond the frame
            fco[k + 1] = 900 + pick(800)
            fco[k + 2] = fco[k + 1] + pick(900)
        last_p = array("i", [-1, -1, -1, -1])
        last_v = array("i", last_p)
        st_p = array("i", [0] * ST_SIZE)
        st_v = array("i", [0] * ST_SIZE)
        ch = array("H", [1500] * 16)  # the receiver's frame, copied into each twin's pilot frame (18 words)
        dst_p = array("H", [0] * 18)
        dst_v = array("H", [0] * 18)
        for n in range(40):
            for i in range(16):
                if pick(3) == 0:
                    ch[i] = (880, 1000, 1500, 1505, 1495, 2000, 2120, 1000 + pick(1001))[pick(8)]
            if n % 2:
                rp = rcmod.rc_frame(fco, last_p, dst_p, st_p, ch)
                rv = twin(fco, last_v, dst_v, st_v, ch)
            else:  # in place, as new_frame(channels) without a source
                dst_p[0:16] = ch
                dst_v[0:16] = ch
                rp = rcmod.rc_frame(fco, last_p, dst_p, st_p, dst_p)
                rv = twin(fco, last_v, dst_v, st_v, dst_v)
            assert rp == rv, (config, n, rp, rv)
            assert list(last_p) == list(last_v) and list(st_p) == list(st_v), (config, n)
            assert list(dst_p[:16]) == list(ch) and list(dst_v) == list(dst_p), (config, n)
            seen |= rp
    assert seen == 511  # every stick moved and every switch read on somewhere
