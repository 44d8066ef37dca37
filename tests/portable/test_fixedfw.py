"""The fixed-wing law in fixed point (core/fastpass/fixedfw.py) against the float FwController, and its viper twin.

Portable: on both runtimes the fixed pass must agree with the float stage it stands in for, pass by pass from
the same state, within the bounds below; under MicroPython (tests/portable/mprun.py, the 64-bit VM and the
32-bit one, where viper's integers wrap as on an RP2040) the viper twin (accel/fw.py) must be the one chosen,
give the Python twin's bits on every output, and allocate nothing.
"""

from array import array

from hoverfly.compat import IS_MICROPYTHON
from hoverfly.core.config.params import Params
from hoverfly.core.fastpass import fixedfw
from hoverfly.core.signals import Signals
from hoverfly.core.stages.control import MODE_ACRO, MODE_ANGLE, MODE_HORIZON, MODE_MANUAL
from hoverfly.core.stages.fwcontrol import FwController

if IS_MICROPYTHON:
    from hoverfly.accel import fw as fw_viper
else:
    fw_viper = None


class Lcg:
    """Deterministic numbers: the same sequence on every port."""

    def __init__(self, seed):
        self.s = seed

    def unit(self):
        self.s = (self.s * 1103515245 + 12345) & 0x7FFFFFFF
        return (self.s >> 7) / 16777216.0

    def span(self, a):
        return (self.unit() * 2.0 - 1.0) * a


def _stages(sets=(), pid_math="fixed"):
    p = Params()
    p.set("mixer_type", "airplane")
    for name, value in sets:
        assert p.set(name, value) is None, name
    s = Signals()
    fw = FwController(s.pid_terms)
    fw.configure(p)
    fx = fixedfw.FixedFw()
    on = fx.configure(fw, 1000, pid_math, s)
    return s, fw, fx, on


def test_the_fixed_pass_runs_where_pid_math_allows_it():
    assert fixedfw.HAS_ACCEL == IS_MICROPYTHON  # the unix VM has viper; CPython has not
    assert _stages(())[3]
    assert _stages((), "auto")[3] == IS_MICROPYTHON
    assert not _stages((), "float")[3]


def _walk(x, step, lim, rnd):
    x += rnd.span(step)
    if x > lim:
        return lim
    if x < -lim:
        return -lim
    return x


def _set_attitude(s, roll, pitch):
    """A quaternion and angles for this bank and pitch (yaw 0), by the half-angle series (no math import)."""
    a = s.attitude
    hr = roll * 0.5
    hp = pitch * 0.5
    cr = 1.0 - hr * hr / 2.0 + hr ** 4 / 24.0
    sr = hr - hr ** 3 / 6.0 + hr ** 5 / 120.0
    cp = 1.0 - hp * hp / 2.0 + hp ** 4 / 24.0
    spp = hp - hp ** 3 / 6.0 + hp ** 5 / 120.0
    n = ((cr * cp) ** 2 + (sr * cp) ** 2 + (cr * spp) ** 2 + (sr * spp) ** 2) ** 0.5
    a.q[0] = cr * cp / n
    a.q[1] = sr * cp / n
    a.q[2] = cr * spp / n
    a.q[3] = -sr * spp / n
    a.roll_rad = roll
    a.pitch_rad = pitch


def _inputs(rnd, n, s, fw, st):
    """The next pass's inputs, a random walk as a flight's signals move. st: [roll, pitch]. Returns dt in µs."""
    sp = s.setpoint
    sp.throttle_norm = 0.5 + _walk(sp.throttle_norm - 0.5, 0.02, 0.5, rnd)
    for k in range(3):
        sp.stick_norm[k] = _walk(sp.stick_norm[k], 0.03, 1.0, rnd)
        s.gyro_rad_s[k] = _walk(s.gyro_rad_s[k], 0.05, 3.0, rnd)
    st[0] = _walk(st[0], 0.01, 1.2, rnd)
    st[1] = _walk(st[1], 0.01, 0.6, rnd)
    _set_attitude(s, st[0], st[1])
    fw.pitch_offset_rad = -0.05 if n % 200 < 100 else 0.3
    return 995 + n % 11


def _agree(sets, mode, passes=400, seed=7):
    """Worst differences of the fixed pass from the float stage over `passes` passes from shared state:
    outputs and P/FF terms, I-terms, rate set points."""
    s, fw, fx, on = _stages(sets)
    assert on
    sp = s.setpoint
    rnd = Lcg(seed)
    att = [0.0, 0.0]
    worst = [0.0, 0.0, 0.0]
    for n in range(passes):
        dt_us = _inputs(rnd, n, s, fw, att)
        sp.mode = mode
        i_active = rnd.unit() > 0.1
        fx.give_state()  # the float stage takes the fixed pass's integrators: one pass of each from one place
        fw.update(sp, s.attitude, s.gyro_rad_s, dt_us * 1e-6, i_active, s.torque_norm)
        want = (array("f", s.torque_norm), array("f", s.pid_terms), array("f", sp.rate_rad_s))
        fx.update(sp, s.attitude, dt_us, i_active)
        for k in range(3):
            worst[0] = max(worst[0], abs(want[0][k] - s.torque_norm[k]), abs(want[1][k] - s.pid_terms[k]),
                           abs(want[1][k + 9] - s.pid_terms[k + 9]))
            worst[1] = max(worst[1], abs(want[1][k + 3] - s.pid_terms[k + 3]))
            if mode != MODE_MANUAL:
                worst[2] = max(worst[2], abs(want[2][k] - sp.rate_rad_s[k]))
    return worst


def test_the_fixed_pass_agrees_with_the_float_law():
    cases = (
        ((), MODE_ANGLE),
        ((), MODE_ACRO),
        ((), MODE_HORIZON),
        ((), MODE_MANUAL),
        ((("fw_tpa_rate", 100), ("fw_tpa_bp_us", 1300), ("fw_p_roll", 40), ("fw_i_pitch", 60)), MODE_ANGLE),
        ((("fw_tpa_rate", 50), ("fw_turn_yaw_gain", 2.0), ("fw_turn_pit_gain", 0.5), ("horizon_level", 100),
          ("fw_ref_speed_m_s", 5.0)), MODE_HORIZON),
        ((("manual_rc_expo", 0), ("manual_roll_pct", 37)), MODE_MANUAL),
    )
    for sets, mode in cases:
        worst = _agree(sets, mode)
        # Q16 outputs and terms: a few steps of 2**-16 of the throw (1.5e-5 each), and TPA's factor in Q14;
        # the rate set points: the angle error's Q24 and the gains' 15-bit mantissas (1 part in 16384)
        assert worst[0] < 3e-4, (sets, mode, worst)
        assert worst[1] < 2e-5, (sets, mode, worst)
        assert worst[2] < 1e-3, (sets, mode, worst)


def test_the_integrators_go_back_to_the_float_stage_when_the_fixed_pass_stops():
    s, fw, fx, on = _stages(())
    sp = s.setpoint
    sp.mode = MODE_ACRO
    sp.stick_norm[0] = 0.5
    for _ in range(100):
        fx.update(sp, s.attitude, 1000, True)
    fixed_i = s.pid_terms[3]
    assert fixed_i > 0.0
    p = Params()
    p.set("mixer_type", "airplane")
    assert fx.configure(fw, 1000, "float", s) is False
    assert not fx.active
    assert abs(fw.i[0] - fixed_i) < 1e-7


_ODD = (float("nan"), float("inf"), -float("inf"), 1e30, -1e30, -0.0, 1e-40, 127.99, -128.5, 4.5, -3.9999,
        1.0000001, 0.9999999, 2.0 ** -17, -(2.0 ** -16))


def test_the_viper_twin_gives_the_python_twins_bits():
    if not IS_MICROPYTHON:
        assert fixedfw.FixedFw.update is fixedfw.update_python  # no viper: the Python twin runs
        return
    assert fixedfw.FixedFw.update is fw_viper.update
    configs = ((),
               (("fw_tpa_rate", 100), ("fw_tpa_bp_us", 1001), ("fw_i_roll", 200), ("fw_iterm_limit", 500),
                ("fw_turn_yaw_gain", 2.0), ("fw_ref_speed_m_s", 3.0), ("horizon_level", 100)),
               (("fw_p_roll", 0), ("fw_ff_pitch", 0), ("fw_p_level", 0), ("manual_rc_expo", 100)))
    for sets in configs:
        # two stages, each on its own signals: the Python twin's update on one, the viper twin's on the other
        sa, wa, fa, on = _stages(sets)
        sb, wb, fb, on = _stages(sets)
        rnd = Lcg(11)
        for n in range(1500):
            odd = n % 5 == 4  # every fifth pass: some inputs are not numbers, infinite or huge
            vals = []
            for k in range(15):
                v = rnd.span(1.5) if k != 0 else rnd.unit() * 1.2
                if k >= 4 and k < 7:
                    v = rnd.span(40.0)  # the gyro
                if odd and rnd.unit() < 0.3:
                    v = _ODD[int(rnd.unit() * len(_ODD))]
                vals.append(v)
            for s, w in ((sa, wa), (sb, wb)):
                sp = s.setpoint
                sp.throttle_norm = vals[0]
                for k in range(3):
                    sp.stick_norm[k] = vals[1 + k]
                    s.gyro_rad_s[k] = vals[4 + k]
                s.attitude.roll_rad = vals[7]
                s.attitude.pitch_rad = vals[8]
                for k in range(4):
                    s.attitude.q[k] = vals[9 + k] * 0.7
                w.pitch_offset_rad = vals[13]
                sp.mode = n % 4
            i_active = rnd.unit() > 0.2
            dt_us = (0, -5, 10, 64, 999, 1000, 1001, 125, 4000, 70000)[n % 10]
            fixedfw.update_python(fa, sa.setpoint, sa.attitude, dt_us, i_active)
            fb.update(sb.setpoint, sb.attitude, dt_us, i_active)
            assert fa.manual == fb.manual
            for k in range(fixedfw.ST_SIZE):
                assert fa.st[k] == fb.st[k], (sets, n, "st", k, fa.st[k], fb.st[k])
            for name in ("pid_terms", "torque_norm"):
                a = getattr(sa, name)
                b = getattr(sb, name)
                for k in range(len(a)):
                    assert a[k] == b[k] or (a[k] != a[k] and b[k] != b[k]), (sets, n, name, k, a[k], b[k])
            for k in range(3):
                a = sa.setpoint.rate_rad_s[k]
                b = sb.setpoint.rate_rad_s[k]
                assert a == b or (a != a and b != b), (sets, n, "rate", k, a, b)


def test_a_fixed_pass_allocates_nothing_on_micropython():
    if not IS_MICROPYTHON:
        return
    import gc

    s, fw, fx, on = _stages(())
    sp = s.setpoint
    sp.throttle_norm = 0.45
    rnd = Lcg(5)
    att = [0.0, 0.0]
    _inputs(rnd, 0, s, fw, att)
    fx.update(sp, s.attitude, 1000, True)
    gc.collect()
    gc.disable()
    try:
        a0 = gc.mem_alloc()
        for n in range(50):
            sp.mode = n % 4
            fx.update(sp, s.attitude, 1000 + (n & 1), True)
        used = gc.mem_alloc() - a0
    finally:
        gc.enable()
    assert used == 0, used


def test_an_unconfigured_stage_writes_nothing():
    # the viper twin reaches its arrays through addresses that configure writes: before it, none
    if not IS_MICROPYTHON:
        return
    s = Signals()
    fx = fixedfw.FixedFw()
    s.setpoint.throttle_norm = 0.5
    fx.update(s.setpoint, s.attitude, 1000, True)
    assert list(fx.st) == [0] * fixedfw.ST_SIZE
    assert list(s.torque_norm) == [0.0, 0.0, 0.0]
