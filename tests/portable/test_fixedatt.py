"""The fixed-point attitude estimator (core/fastpass/fixedatt.py) against the float Mahony, and its viper twin.

Portable: under MicroPython (tests/portable/mprun.py) the viper twin (accel/att.py) must be the one
chosen and must give the Python twin's bits on every output and state word, NaN, infinite and huge
inputs included; on both runtimes the fixed estimator must follow the float one (core/stages/estimator.py)
over a minute of flying, and its angles must be the float stage's for the same quaternion.
"""

import math
from array import array

from fastpathkit import heap_bytes
from test_fixedrate import Lcg  # the same deterministic numbers on every port

from hoverfly.compat import IS_MICROPYTHON
from hoverfly.core.config.params import Params
from hoverfly.core.fastpass import fixedatt
from hoverfly.core.stages.estimator import COS_TILT, PITCH, ROLL, YAW, Attitude, Mahony

if IS_MICROPYTHON:
    from hoverfly.accel import att as att_viper
else:
    att_viper = None

_G = 9.80665
_DEG = math.pi / 180.0


class _Signals:
    def __init__(self):
        self.gyro_rad_s = array("f", [0.0, 0.0, 0.0])
        self.accel_m_s2 = array("f", [0.0, 0.0, -_G])


def _stages(sets=(), every=4, loop_hz=1000, on=True):
    p = Params()
    for name, value in sets:
        p.set(name, value)
    m = Mahony()
    m.configure(p)
    att = Attitude()
    s = _Signals()
    fx = fixedatt.FixedAttitude()
    return m, att, s, fx, fx.configure(m, att, s, loop_hz, every, on)


def _angle_deg(q, r):
    """The rotation between two unit quaternions, degrees (from their distance: acos of the dot
    product has no digits left for small angles)."""
    dm = math.sqrt(sum((q[i] - r[i]) ** 2 for i in range(4)))
    dp = math.sqrt(sum((q[i] + r[i]) ** 2 for i in range(4)))
    return 4.0 * math.asin(min(1.0, min(dm, dp) * 0.5)) / _DEG


def _wrap(a):
    while a > math.pi:
        a -= 2.0 * math.pi
    while a < -math.pi:
        a += 2.0 * math.pi
    return a


def test_the_fixed_estimator_runs_where_asked():
    assert fixedatt.HAS_ACCEL == IS_MICROPYTHON  # the unix VM has viper; CPython has not
    assert _stages()[4]
    assert not _stages(on=False)[4]
    assert not _stages(every=256)[4]  # the gyro sum's bound
    assert _stages((("imu_dcm_kp", 50000), ("imu_dcm_ki", 50000)), every=1)[4]  # the largest gains


class _Flight:
    """A minute of flying for both estimators: the truth turned by smooth rates with two flips a
    second apart, the accelerometer its gravity plus lateral pushes, vibration and stretches of
    1.07 g (half trusted) and 1.3 g (not trusted), disarmed for the first 10 s (the boosted gain)."""

    def __init__(self, seed):
        self.rnd = Lcg(seed)
        self.q = [1.0, 0.0, 0.0, 0.0]
        self.gyro = [0.0, 0.0, 0.0]
        self.accel = [0.0, 0.0, -_G]

    def sample(self, n, dt_s):
        t = n * dt_s
        rnd = self.rnd
        g = self.gyro
        g[0] = 1.2 * math.sin(t * 0.9) + (12.0 if 20.0 <= t % 30.0 < 20.5236 else 0.0)  # a roll flip
        g[1] = 0.8 * math.sin(t * 0.55 + 1.0) + (12.0 if 21.5 <= t % 30.0 < 22.0236 else 0.0)  # a pitch flip
        g[2] = 0.6 * math.sin(t * 0.31)
        w, x, y, z = self.q
        h = 0.5 * dt_s
        gx, gy, gz = g[0] * h, g[1] * h, g[2] * h
        nw = w - x * gx - y * gy - z * gz
        nx = x + w * gx + y * gz - z * gy
        ny = y + w * gy - x * gz + z * gx
        nz = z + w * gz + x * gy - y * gx
        k = 1.0 / math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
        self.q = [nw * k, nx * k, ny * k, nz * k]
        w, x, y, z = self.q
        # gravity's direction (NED down) in the body frame; the accelerometer reads its opposite
        dx = 2.0 * (x * z - w * y)
        dy = 2.0 * (w * x + y * z)
        dz = w * w - x * x - y * y + z * z
        phase = t % 7.0
        lift = 1.0 if phase < 5.0 else (1.07 if phase < 6.0 else 1.3)
        a = self.accel
        a[0] = -_G * lift * dx + rnd.span(1.5)
        a[1] = -_G * lift * dy + rnd.span(1.5)
        a[2] = -_G * lift * dz + rnd.span(1.5)


def _fly_both(sets, seconds, loop_hz=1000, every=4, check=None):
    m, att, s, fx, on = _stages(sets, every, loop_hz)
    assert on
    mf = Mahony()
    p = Params()
    for name, value in sets:
        p.set(name, value)
    mf.configure(p)
    attf = Attitude()
    fl = _Flight(5)
    dt_us = 1000000 // loop_hz
    gsum = [0.0, 0.0, 0.0]
    gavg = array("f", [0.0, 0.0, 0.0])
    # the rotation between the estimates, the roll, pitch and yaw differences (roll and yaw times cos
    # pitch: the rotation they make), degrees; the tilt cosine's difference
    worst = [0.0, 0.0, 0.0, 0.0, 0.0]
    n_up = 0
    for n in range(seconds * loop_hz):
        fl.sample(n, dt_us * 1e-6)
        armed = n >= 10 * loop_hz
        for i in range(3):
            s.gyro_rad_s[i] = fl.gyro[i]
            s.accel_m_s2[i] = fl.accel[i]
            gsum[i] += s.gyro_rad_s[i]
        fx.step(dt_us, armed)
        if n % every == every - 1:  # Flight.step's average for the float stage
            for i in range(3):
                gavg[i] = gsum[i] / every
                gsum[i] = 0.0
            mf.update(gavg, s.accel_m_s2, every * dt_us * 1e-6, armed, attf)
            n_up += 1
            worst[0] = max(worst[0], _angle_deg(att.q, attf.q))
            cp = math.cos(attf.pitch_rad)
            if cp > 0.05:  # roll and yaw are not defined at +-90 degrees of pitch
                worst[1] = max(worst[1], abs(_wrap(att.roll_rad - attf.roll_rad)) / _DEG * cp)
                worst[3] = max(worst[3], abs(_wrap(att.yaw_rad - attf.yaw_rad)) / _DEG * cp)
            worst[2] = max(worst[2], abs(att.pitch_rad - attf.pitch_rad) / _DEG)
            worst[4] = max(worst[4], abs(att.cos_tilt - attf.cos_tilt))
            if check is not None:
                check(m, mf, att, attf)
    assert n_up == seconds * loop_hz // every
    return worst, m, mf


def test_the_fixed_estimator_follows_the_float_mahony_over_a_minute():
    # default gains (the accelerometer's kp 0.03, x10 disarmed; no bias integral), then a tune with
    # a strong correction and the bias integral on
    for sets in ((), (("imu_dcm_kp", 5000), ("imu_dcm_ki", 2000))):
        worst, m, mf = _fly_both(sets, 60)
        # Q16 gyro samples (1.5e-5 rad/s), Q14/Q15 directions (6e-5 rad) and Q28 steps against
        # float32: the estimates stay within a hundredth of a degree through the flips (0.008 seen)
        assert worst[0] < 0.02, (sets, worst)
        assert worst[1] < 0.02 and worst[2] < 0.02 and worst[3] < 0.02, (sets, worst)
        assert worst[4] < 2e-4, (sets, worst)
        assert worst[0] > 0.0  # the two really are different arithmetic
        for i in range(3):
            assert abs(m.bias_rad_s[i] - mf.bias_rad_s[i]) < 1e-4, (sets, i, m.bias_rad_s[i], mf.bias_rad_s[i])
        if sets:
            assert not m._bias_zero and max(abs(m.bias_rad_s[i]) for i in range(3)) > 1e-4


def test_every_pass_and_a_slower_rate_follow_the_float_mahony_too():
    for loop_hz, every in ((1000, 1), (2000, 40)):  # 1 kHz every pass; 2 kHz at 50 Hz (20 ms steps)
        worst = _fly_both((("imu_dcm_ki", 500),), 15, loop_hz, every)[0]
        assert worst[0] < 0.02 and worst[4] < 2e-4, (loop_hz, every, worst)


def _update_at(q, gyro=(0.0, 0.0, 0.0), accel=(0.0, 0.0, 0.0), dt_us=0):
    """One update from quaternion q (no gravity reference unless given); returns the fixed stage's attitude."""
    m, att, s, fx, on = _stages(every=1)
    for i in range(4):
        att.q[i] = q[i]
    for i in range(3):
        s.gyro_rad_s[i] = gyro[i]
        s.accel_m_s2[i] = accel[i]
    fx.step(dt_us, True)
    return att


def test_the_angles_are_the_float_stages_for_the_same_quaternion():
    rnd = Lcg(21)
    qs = [(1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0, -1.0),
          (math.cos(0.3), 0.0, math.sin(0.3), 0.0), (math.cos(0.785), 0.0, math.sin(0.785), 0.0),
          (math.cos(-0.785), 0.0, math.sin(-0.785), 0.0), (0.5, 0.5, 0.5, 0.5), (0.5, -0.5, 0.5, -0.5)]
    for _ in range(300):
        v = [rnd.span(1.0) for _ in range(4)]
        k = 1.0 / math.sqrt(sum(c * c for c in v))
        qs.append([c * k for c in v])
    ref = Attitude()
    for q in qs:
        att = _update_at(q)
        assert abs(sum(att.q[i] * att.q[i] for i in range(4)) - 1.0) < 1e-6
        ref.set_from(att.q[0], att.q[1], att.q[2], att.q[3])
        a = att.angles
        # near +-90 degrees asin(s) turns the quaternion's float32 rounding into 1e-4 rad: compare s there
        assert abs(math.sin(a[PITCH]) - math.sin(ref.pitch_rad)) < 1e-6, (q, a[PITCH], ref.pitch_rad)
        if math.cos(ref.pitch_rad) > 0.05:
            assert abs(a[PITCH] - ref.pitch_rad) < 2e-6, (q, a[PITCH], ref.pitch_rad)
        assert abs(a[COS_TILT] - ref.cos_tilt) < 2e-7, (q, a[COS_TILT], ref.cos_tilt)
        if math.cos(ref.pitch_rad) > 1e-3:  # roll and yaw are not defined at +-90 degrees of pitch
            assert abs(_wrap(a[ROLL] - ref.roll_rad)) < 2e-6, (q, a[ROLL], ref.roll_rad)
            assert abs(_wrap(a[YAW] - ref.yaw_rad)) < 2e-6, (q, a[YAW], ref.yaw_rad)
        # the attributes carry the same values (angle_floats, for the readers of the float stage's names)
        assert (att.roll_rad, att.pitch_rad, att.yaw_rad, att.cos_tilt) == (a[0], a[1], a[2], a[3])


def test_a_gyro_rate_turns_the_quaternion_as_the_float_stage_does():
    for gyro in ((1.0, 0.0, 0.0), (0.0, -2.0, 0.0), (0.0, 0.0, 30.0), (-20.0, 10.0, 5.0)):
        att = _update_at((1.0, 0.0, 0.0, 0.0), gyro, dt_us=4000)
        m = Mahony()
        ref = Attitude()
        m.update(array("f", gyro), array("f", [0.0, 0.0, 0.0]), 0.004, True, ref)
        assert _angle_deg(att.q, ref.q) < 1e-4, (gyro, list(att.q), list(ref.q))


def test_the_bias_integral_takes_out_a_gyro_bias():
    m, att, s, fx, on = _stages((("imu_dcm_ki", 2000), ("imu_dcm_kp", 2000)), every=4)
    s.gyro_rad_s[0] = 0.5 * _DEG
    s.gyro_rad_s[1] = -0.3 * _DEG
    for _ in range(60000):
        fx.step(1000, True)
    assert abs(m.bias_rad_s[0] - 0.5 * _DEG) < 0.05 * _DEG
    assert abs(m.bias_rad_s[1] + 0.3 * _DEG) < 0.05 * _DEG
    assert abs(att.roll_rad) < 0.1 * _DEG and abs(att.pitch_rad) < 0.1 * _DEG
    assert not m._bias_zero


def test_a_quaternion_written_between_updates_is_the_next_updates_start():
    m, att, s, fx, on = _stages(every=1)
    accel = array("f", [_G * math.sin(0.2), 0.0, -_G * math.cos(0.2)])  # 0.2 rad nose up
    m.level_from_accel(accel, att)
    s.accel_m_s2[0] = accel[0]
    s.accel_m_s2[2] = accel[2]
    fx.step(1000, True)
    assert abs(att.pitch_rad - 0.2) < 1e-4 and abs(att.angles[PITCH] - 0.2) < 1e-4
    # a quaternion no update writes (here: none at all) starts level
    for i in range(4):
        att.q[i] = 0.0
    s.accel_m_s2[0] = 0.0
    s.accel_m_s2[2] = -_G
    fx.step(1000, True)
    assert list(att.q) == [1.0, 0.0, 0.0, 0.0]


_ODD = (float("nan"), float("inf"), -float("inf"), 1e30, -1e30, -0.0, 1e-40, 63.99, -64.5, 255.9, -300.0,
        1.0000001, 0.9999999, 2.0 ** -17, -(2.0 ** -31), 9.80665, -9.80665 * 1.07)


def _odd_inputs(rnd, n, ios):
    """The same inputs into each io: flight-like, and every fifth pass some not numbers, infinite or huge
    (the quaternion and the bias too, now and then)."""
    odd = n % 5 == 4
    vals = []
    for _ in range(3):
        vals.append(rnd.span(40.0))
    for k in range(3):
        vals.append(rnd.span(12.0) - (9.8 if k == 2 else 0.0))
    for k in range(6):
        if odd and rnd.unit() < 0.4:
            vals[k] = _ODD[int(rnd.unit() * len(_ODD))]
    for io in ios:
        for k in range(3):
            io[0][k] = vals[k]
            io[1][k] = vals[3 + k]
    if n % 37 == 36:  # a bad state from outside
        j = int(rnd.unit() * 7)
        v = _ODD[int(rnd.unit() * len(_ODD))]
        for io in ios:
            if j < 4:
                io[2][j] = v
            else:
                io[4][j - 4] = v


def _io():
    return (array("f", [0.0] * 3), array("f", [0.0, 0.0, -_G]), array("f", [1.0, 0.0, 0.0, 0.0]),
            array("f", [0.0, 0.0, 0.0, 1.0]), array("f", [0.0] * 3))


_TWIN_SETS = (
    ((), 4),
    ((("imu_dcm_kp", 50000), ("imu_dcm_ki", 50000)), 1),
    ((("imu_dcm_kp", 1), ("imu_dcm_ki", 1)), 3),
    ((("imu_dcm_kp", 0), ("imu_dcm_ki", 3000)), 255),
)


def test_bad_inputs_never_raise_and_leave_a_unit_quaternion():
    for sets, every in _TWIN_SETS:
        m, att, s, fx, on = _stages(sets, every)
        rnd = Lcg(17)
        for n in range(1200):
            _odd_inputs(rnd, n, (fx._io,))
            fx.step(int(rnd.span(30000.0)) if n % 7 == 0 else 1000, n % 3 != 0)
            if fx.st[fixedatt.S_N] == 0:  # an update ran
                assert abs(sum(att.q[i] * att.q[i] for i in range(4)) - 1.0) < 1e-5, (sets, n, list(att.q))
                a = att.angles
                assert -3.1416 < a[ROLL] <= 3.1416 and -1.5709 <= a[PITCH] <= 1.5709, (sets, n, list(a))
                assert -3.1416 < a[YAW] <= 3.1416 and -1.0 <= a[COS_TILT] <= 1.0, (sets, n, list(a))


def _bits(arr):
    return bytes(arr)


def test_the_viper_twin_gives_the_python_twins_bits():
    if not IS_MICROPYTHON:
        assert fixedatt.FixedAttitude.step is fixedatt.step_python  # no viper: the Python twin runs
        return
    assert fixedatt.FixedAttitude.step is att_viper.step
    for sets, every in _TWIN_SETS:
        ma, atta, sa, fxa, on = _stages(sets, every)
        mb, attb, sb, fxb, on = _stages(sets, every)
        fxb.angle_floats = False  # one twin sets the float attributes, the other not: both ways checked
        rnd = Lcg(11)
        updates = 0
        for n in range(3000):
            _odd_inputs(rnd, n, (fxa._io, fxb._io))
            dt_us = 1000 if n % 11 else int(rnd.span(40000.0))
            armed = n % 3 != 0
            ra = fixedatt.step_python(fxa, dt_us, armed)
            rb = fxb.step(dt_us, armed)
            assert ra == rb, (sets, n, ra, rb)
            updates += 1 if ra else 0
            for k in range(5):
                assert fxa.st[k] == fxb.st[k], (sets, n, "st", k, fxa.st[k], fxb.st[k])
            for k in (2, 3, 4):
                assert _bits(fxa._io[k]) == _bits(fxb._io[k]), (sets, n, k, list(fxa._io[k]), list(fxb._io[k]))
            assert ma._bias_zero == mb._bias_zero, (sets, n)
            if ra:
                assert atta.roll_rad == attb.angles[ROLL] and atta.cos_tilt == attb.angles[COS_TILT], (sets, n)
        assert updates == 3000 // every
    # the viper twin sets the float attributes as the Python twin does
    assert attb.roll_rad == 0.0
    fxb.angle_floats = True
    sb.gyro_rad_s[0] = 1.0
    for _ in range(every):
        fxb.step(1000, True)
    assert attb.roll_rad == attb.angles[ROLL] and attb.roll_rad != 0.0


def test_a_fixed_step_allocates_nothing_on_micropython():
    if not IS_MICROPYTHON:
        return
    m, att, s, fx, on = _stages((("imu_dcm_ki", 100),), every=1)
    fx.angle_floats = False
    s.accel_m_s2[0] = 0.3
    s.gyro_rad_s[0] = 0.2
    fx.step(4000, True)
    assert heap_bytes(lambda: fx.step(4000, True), 50) == 0
    assert heap_bytes(lambda: fx.step(4000, False), 50) == 0
    m, att, s, fx, on = _stages(every=4)
    fx.angle_floats = False
    assert heap_bytes(lambda: fx.step(1000, True), 200) == 0  # the gyro sum, and every fourth the update


def test_a_flight_takes_the_fixed_estimator_with_the_fixed_rate_loop_and_goes_on_from_it():
    from configfakes import FakeBoard

    from hoverfly.core.flight import Flight

    class RollingBoard(FakeBoard):
        def read_imu(self, gyro_rad_s, accel_m_s2):
            ok = FakeBoard.read_imu(self, gyro_rad_s, accel_m_s2)
            gyro_rad_s[0] = 0.5  # a steady roll rate (the gyro calibration needs a second: not yet)
            gyro_rad_s[1] = 0.0
            gyro_rad_s[2] = 0.0
            return ok

    def fly(pid_math, passes, f=None, t=1000):
        if f is None:
            f = Flight(RollingBoard())
            f.params.set("pid_math", pid_math)
            f.start(t)
        for _ in range(passes):
            t += 1000
            f.step(t)
        return f, t

    fx, t = fly("fixed", 400)
    fl, _ = fly("float", 400)
    assert fx._fixed_att_on and fx.fixed_att.active and not fl._fixed_att_on
    ax = fx.signals.attitude
    af = fl.signals.attitude
    assert ax.roll_rad > 0.05  # it rolled (against the accelerometer's pull to level)
    # the same flight through either estimator (their IMU filters differ by Q16 steps too)
    assert abs(ax.roll_rad - af.roll_rad) < 1e-4 and abs(ax.cos_tilt - af.cos_tilt) < 1e-4
    assert list(ax.angles) == [ax.roll_rad, ax.pitch_rad, ax.yaw_rad, ax.cos_tilt]
    # the float stage takes over from the quaternion the fixed one left: no jump
    roll = ax.roll_rad
    fx.params.set("pid_math", "float")
    fx.configure()
    assert not fx._fixed_att_on and not fx.fixed_att.active
    fly("float", 1, fx, t)
    assert abs(ax.roll_rad - roll) < 0.5 * 0.001 + 1e-4
