"""The fixed-point rate loop (core/fastpass/fixedrate.py) against the float controller and mixer, and its viper twin.

Portable: under MicroPython (tests/portable/mprun.py) the viper twin (accel/rate.py) must be the one
chosen and must give the Python twin's bits on every output; on both runtimes the fixed pass must
agree with the float stages it stands in for, pass by pass from the same state. The 32-bit bounds
are checked on CPython by tests/test_fixedrate_bounds.py.
"""

from array import array

from hoverfly.compat import IS_MICROPYTHON
from hoverfly.core.config.params import Params
from hoverfly.core.fastpass import fixedrate
from hoverfly.core.signals import Signals
from hoverfly.core.stages.control import Controller
from hoverfly.core.stages.mixer import Mixer

if IS_MICROPYTHON:
    from hoverfly.accel import rate as rate_viper
else:
    rate_viper = None


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
    for name, value in sets:
        p.set(name, value)
    s = Signals()
    c = Controller(s.pid_terms)
    m = Mixer()
    c.configure(p, 1000)
    m.configure(p)
    fx = fixedrate.FixedRate()
    on = fx.configure(c, m, 1000, pid_math, s)
    return s, c, m, fx, on


def test_the_fixed_pass_runs_where_pid_math_and_the_configuration_allow_it():
    assert fixedrate.HAS_ACCEL == IS_MICROPYTHON  # the unix VM has viper; CPython has not
    assert _stages(())[4]
    assert _stages((), "auto")[4] == IS_MICROPYTHON
    assert not _stages((), "float")[4]
    # what it does not do keeps the float stages: a D-term biquad, a servo-yaw frame
    assert not _stages((("dterm_lpf1_type", "biquad"),))[4]
    assert not _stages((("mixer_type", "tri"),))[4]
    assert _stages((("dterm_lpf1_type", "pt2"), ("mixer_type", "hexx")))[4]


def _walk(x, step, lim, rnd):
    x += rnd.span(step)
    if x > lim:
        return lim
    if x < -lim:
        return -lim
    return x


def set_attitude(att, roll_rad, pitch_rad):
    """The estimate as the estimators leave it: the attributes (the float controller's) and the array
    (FixedRate's), alike (Attitude.set_from writes both)."""
    att.roll_rad = roll_rad
    att.pitch_rad = pitch_rad
    att.angles[0] = roll_rad
    att.angles[1] = pitch_rad


def _inputs(rnd, n, sp, s):
    """The next pass's inputs: a random walk as a flight's signals move (the gyro noisier), and a
    pass time that jitters by a few µs. Returns dt in µs."""
    sp.throttle_norm = 0.5 + _walk(sp.throttle_norm - 0.5, 0.01, 0.3, rnd)
    sp.roll_angle_rad = _walk(sp.roll_angle_rad, 0.001, 0.9, rnd)
    sp.pitch_angle_rad = _walk(sp.pitch_angle_rad, 0.001, 0.9, rnd)
    # the attitude follows its setpoint, a little off
    a = s.attitude
    set_attitude(a, sp.roll_angle_rad + _walk(a.roll_rad - sp.roll_angle_rad, 0.002, 0.08, rnd),
                 sp.pitch_angle_rad + _walk(a.pitch_rad - sp.pitch_angle_rad, 0.002, 0.08, rnd))
    for k in range(3):
        s.gyro_rad_s[k] = _walk(s.gyro_rad_s[k], 0.05, 2.0, rnd)
        sp.rate_rad_s[k] = _walk(sp.rate_rad_s[k], 0.02, 2.0, rnd)
        sp.stick_norm[k] = _walk(sp.stick_norm[k], 0.02, 1.0, rnd)
    return 995 + n % 11


def _span(m, torque):
    lo = 1e9
    hi = -1e9
    for row in m._rows:
        v = torque[0] * row[0] + torque[1] * row[1] + torque[2] * row[2]
        lo = v if v < lo else lo
        hi = v if v > hi else hi
    return hi - lo


def _agree(sets, mode, passes=300, seed=7):
    """Worst differences of the fixed pass from the float stages over `passes` passes from shared state."""
    s, c, m, fx, on = _stages(sets)
    assert on
    sp = s.setpoint
    rnd = Lcg(seed)
    worst = [0.0, 0.0, 0.0, 0.0]  # torque/terms, i-terms, motors, rate setpoint
    flag_checks = 0
    for n in range(passes):
        dt_us = _inputs(rnd, n, sp, s)
        sp.mode = mode
        i_active = rnd.unit() > 0.2
        airmode = rnd.unit() > 0.5
        fx.give_state()  # the float stages take the fixed pass's state: one pass of each from the same place
        keep = array("f", sp.rate_rad_s)
        c.update(sp, s.attitude, s.gyro_rad_s, dt_us * 1e-6, i_active, m.saturated, s.torque_norm)
        m.update(sp.throttle_norm, s.torque_norm, airmode, s.motor_norm)
        want = (array("f", s.torque_norm), array("f", s.pid_terms), array("f", s.motor_norm), array("f", sp.rate_rad_s),
                m.saturated, c.tpa)
        for k in range(3):
            sp.rate_rad_s[k] = keep[k]
        fx.update(sp, dt_us, i_active, airmode)
        for k in range(3):
            worst[0] = max(worst[0], abs(want[0][k] - s.torque_norm[k]))
            worst[0] = max(worst[0], abs(want[1][k] - s.pid_terms[k]), abs(want[1][k + 6] - s.pid_terms[k + 6]),
                           abs(want[1][k + 9] - s.pid_terms[k + 9]))
            worst[1] = max(worst[1], abs(want[1][k + 3] - s.pid_terms[k + 3]))
            worst[3] = max(worst[3], abs(want[3][k] - sp.rate_rad_s[k]))
        span = _span(m, want[0])
        if abs(span - 1.0) > 2e-3:  # not at the mixer's one discontinuity (desaturation starts)
            for i in range(m.n):
                worst[2] = max(worst[2], abs(want[2][i] - s.motor_norm[i]))
            edge = False
            for i in range(m.n):
                if want[2][i] < 1e-3 or want[2][i] > 1.0 - 1e-3:
                    edge = True
            if not edge:  # no motor at a limit: saturation is then the span's alone, and must agree
                assert m.saturated == want[4], (n, m.saturated, want[4])
                flag_checks += 1
        assert abs(c.tpa - want[5]) < 1e-4, (c.tpa, want[5])
    return worst, flag_checks


def test_the_fixed_pass_agrees_with_the_float_controller_and_mixer():
    cases = (
        ((), 1),  # the defaults, angle mode
        ((), 0),  # acro
        ((), 2),  # horizon
        ((("dterm_lpf1_type", "pt2"), ("iterm_relax", "rpy"), ("tpa_mode", "pd"), ("ff_static_pct", 30.0)), 0),
        ((("iterm_relax", "off"), ("mixer_type", "hexx"), ("tpa_breakpoint", 1100), ("d_roll", 0)), 1),
        ((("mixer_type", "quadp"), ("yaw_motors_rev", 1), ("horizon_level", 100), ("angle_ff", 200)), 2),
    )
    checked = 0
    for sets, mode in cases:
        worst, flags = _agree(sets, mode)
        # Q16 outputs: a few steps of 2**-16 (1.5e-5) of the mixer range, and 1/dt as an integer (2.5e-5
        # off at 995 µs) times the feed-forwards; a DShot throttle step is 5e-4
        assert worst[0] < 3e-4, (sets, mode, worst)
        assert worst[1] < 1e-6, (sets, mode, worst)
        assert worst[2] < 4e-4, (sets, mode, worst)
        assert worst[3] < 2e-4, (sets, mode, worst)
        assert flags > 0, (sets, mode, flags)
        checked += flags
    assert checked > 500, checked  # the saturation flag compared on most passes


def test_the_state_goes_back_to_the_float_stages_when_the_fixed_pass_stops():
    s, c, m, fx, on = _stages(())
    sp = s.setpoint
    rnd = Lcg(3)
    for n in range(50):
        dt_us = _inputs(rnd, n, sp, s)
        sp.throttle_norm = 0.4
        fx.update(sp, dt_us, True, True)
    fixed_i = s.pid_terms[3]
    assert fixed_i != 0.0
    assert fx.configure(c, m, 1000, "float", s) is False
    assert not fx.active
    assert abs(c.roll.i - fixed_i) < 1e-6
    assert abs(c.roll.out - s.torque_norm[0]) < 1e-4
    # and a float pass goes on from there as the fixed pass would have
    twin = fixedrate.FixedRate()
    assert twin.configure(c, m, 1000, "fixed", s)
    dt_us = _inputs(rnd, 50, sp, s)
    keep = array("f", sp.rate_rad_s)
    c.update(sp, s.attitude, s.gyro_rad_s, dt_us * 1e-6, True, m.saturated, s.torque_norm)
    want = array("f", s.torque_norm)
    for k in range(3):
        sp.rate_rad_s[k] = keep[k]
    twin.update(sp, dt_us, True, True)
    for k in range(3):
        assert abs(want[k] - s.torque_norm[k]) < 2e-4, (k, want[k], s.torque_norm[k])


_ODD = (float("nan"), float("inf"), -float("inf"), 1e30, -1e30, -0.0, 1e-40, 127.99, -128.5, 4.5, -3.9999,
        1.0000001, 0.9999999, 2.0 ** -17, -(2.0 ** -16))


def test_the_viper_twin_gives_the_python_twins_bits():
    if not IS_MICROPYTHON:
        assert fixedrate.FixedRate.update is fixedrate.update_python  # no viper: the Python twin runs
        return
    assert fixedrate.FixedRate.update is rate_viper.update
    configs = ((("iterm_relax", "off"),),
               (("dterm_lpf1_type", "pt2"), ("tpa_mode", "pd"), ("ff_static_pct", 50.0), ("mixer_type", "hexx"),
                ("iterm_relax", "rpy"), ("tpa_breakpoint", 1999)),
               # zero gains: the viper twin skips their products
               (("p_pitch", 0), ("i_roll", 0), ("d_roll", 0), ("f_yaw", 0), ("angle_ff", 0), ("angle_p_gain", 0),
                ("tpa_rate", 0)))
    for sets in configs:
        # two stages, each on its own signals: the Python twin's update on one, the viper twin's on the other
        sa, ca, ma, fa, on = _stages(sets)
        sb, cb, mb, fb, on = _stages(sets)
        for fx in (fa, fb):
            # roll's I-term limit 2**25 - 1 (25 bits of ones): an I-term held there rounds up into the next
            # power of two when it becomes a float32, the encode's carry case
            fx.co[fixedrate.AXIS + fixedrate.ILIM] = 0x1FFFFFF
            fx.terms_every(3 if sets is configs[1] else 1)  # the terms and torques every third pass, alike
        rnd = Lcg(11)
        for n in range(1500):
            odd = n % 5 == 4  # every fifth pass: some inputs are not numbers, infinite or huge
            fin = []
            for k in range(5):
                v = rnd.span(1.5) if k else rnd.unit() * 1.1
                if odd and rnd.unit() < 0.3:
                    v = _ODD[int(rnd.unit() * len(_ODD))]
                fin.append(v)
            for s in (sa, sb):
                s.setpoint.throttle_norm = fin[0]
                s.setpoint.roll_angle_rad = fin[1]
                s.setpoint.pitch_angle_rad = fin[2]
                set_attitude(s.attitude, fin[3], fin[4])
            for arr in range(3):
                for k in range(3):
                    v = rnd.span(40.0 if arr < 2 else 1.2)
                    if odd and rnd.unit() < 0.3:
                        v = _ODD[int(rnd.unit() * len(_ODD))]
                    for s in (sa, sb):
                        (s.gyro_rad_s, s.setpoint.rate_rad_s, s.setpoint.stick_norm)[arr][k] = v
            mode = int(rnd.unit() * 3)
            i_active = rnd.unit() > 0.2
            airmode = rnd.unit() > 0.5
            dt_us = (0, -5, 10, 64, 999, 1000, 1001, 125, 4000, 70000)[n % 10]
            sa.setpoint.mode = sb.setpoint.mode = mode
            fixedrate.update_python(fa, sa.setpoint, dt_us, i_active, airmode)
            fb.update(sb.setpoint, dt_us, i_active, airmode)
            assert ma.saturated == mb.saturated, (sets, n, ma.saturated, mb.saturated)
            assert ca.tpa == cb.tpa, (sets, n, ca.tpa, cb.tpa)
            for k in range(40):
                assert fa.st[k] == fb.st[k], (sets, n, "st", k, fa.st[k], fb.st[k])
            for name in ("pid_terms", "torque_norm", "motor_norm"):
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

    s, c, m, fx, on = _stages(())
    sp = s.setpoint
    sp.throttle_norm = 0.45
    rnd = Lcg(5)
    _inputs(rnd, 0, sp, s)
    fx.update(sp, 1000, True, True)
    gc.collect()
    gc.disable()
    try:
        a0 = gc.mem_alloc()
        for n in range(50):
            sp.mode = n % 3
            fx.update(sp, 1000 + (n & 1), True, n & 2)
        used = gc.mem_alloc() - a0
    finally:
        gc.enable()
    assert used == 0, used


def test_an_unconfigured_stage_writes_nothing():
    # the viper twin reaches its arrays through addresses that configure writes: before it, none
    if not IS_MICROPYTHON:
        return
    s = Signals()
    fx = fixedrate.FixedRate()
    s.setpoint.throttle_norm = 0.5
    fx.update(s.setpoint, 1000, True, True)
    assert list(fx.st) == [0] * fixedrate.ST_SIZE
    assert list(s.motor_norm) == [0.0] * len(s.motor_norm)


def test_the_pid_terms_are_written_every_terms_every_passes():
    # FixedRate.terms_every: the PID terms and torques (outputs for the log and the maintenance telemetry)
    # every pass while a log runs, every few passes otherwise; the motors every pass either way
    for every in (1, 4):
        s, c, m, fx, on = _stages()
        assert on
        fx.terms_every(every)
        rnd = Lcg(5)
        changed = []
        for _ in range(40):
            s.setpoint.throttle_norm = 0.5
            s.setpoint.mode = 0
            for k in range(3):
                s.gyro_rad_s[k] = rnd.span(2.0)
                s.setpoint.rate_rad_s[k] = rnd.span(2.0)
            before = list(s.pid_terms) + list(s.torque_norm)
            motors = list(s.motor_norm)
            fx.update(s.setpoint, 1000, True, False)
            changed.append(list(s.pid_terms) + list(s.torque_norm) != before)
            assert list(s.motor_norm) != motors  # the gyro moved: the motors follow at every pass
        if every == 1:
            assert all(changed)
        else:
            assert changed == [n % 4 == 0 for n in range(40)], changed
