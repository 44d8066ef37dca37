"""The fixed-point IMU filters (core/fastpass/fixedimu.py) against the float gyro and accelerometer filters, and
their viper twin.

Portable: under MicroPython (tests/portable/mprun.py) the viper twin (accel/imufilter.py) must be
the one chosen and must give the Python twin's bits on every output and state word; on both
runtimes the fixed pass must agree with the float filters it stands in for, pass by pass.
"""

from array import array

from fastpathkit import heap_bytes
from test_fixedrate import Lcg  # the same deterministic numbers on every port

from hoverfly.compat import IS_MICROPYTHON
from hoverfly.core.config.params import Params
from hoverfly.core.fastpass import fixedimu
from hoverfly.core.signals import Signals
from hoverfly.core.stages.filters import AccelFilter, GyroFilter

if IS_MICROPYTHON:
    from hoverfly.accel import imufilter as imu_viper
else:
    imu_viper = None


def _stages(sets=(), on=True):
    p = Params()
    for name, value in sets:
        p.set(name, value)
    s = Signals()
    g = GyroFilter()
    a = AccelFilter()
    g.configure(p, 1000)
    a.configure(p, 1000)
    bias = array("f", [0.01, -0.02, 0.005])
    fx = fixedimu.FixedImuFilter()
    return s, g, a, bias, fx, fx.configure(g, a, s, bias, on)


def _sample(rnd, n, s):
    """A flight-like sample: rates that swing to +-20 rad/s, an accelerometer around 1 g with vibration."""
    for k in range(3):
        s.gyro_raw_rad_s[k] = rnd.span(2.0) + (20.0 if (n // 50) % 4 == 1 else 0.0) * (k == 0)
        s.accel_raw_m_s2[k] = rnd.span(6.0) + (-9.80665 if k == 2 else 0.0)


def test_the_fixed_filters_run_for_the_default_chain_where_asked():
    assert fixedimu.HAS_ACCEL == IS_MICROPYTHON  # the unix VM has viper; CPython has not
    assert _stages(())[5]
    assert not _stages((), False)[5]
    # any other gyro chain keeps the float filters
    assert not _stages((("gyro_lpf1_type", "pt2"),))[5]
    assert not _stages((("gyro_lpf1_type", "biquad"),))[5]
    assert not _stages((("gyro_lpf2_hz", 300),))[5]
    assert not _stages((("gyro_notch1_hz", 200), ("gyro_notch1_cut", 150)))[5]
    assert _stages((("gyro_lpf1_hz", 0), ("acc_lpf_hz", 0)))[5]  # filters off: gains of one


def test_the_fixed_filters_agree_with_the_float_filters():
    for sets in ((), (("gyro_lpf1_hz", 90), ("acc_lpf_hz", 5)), (("gyro_lpf1_hz", 0), ("acc_lpf_hz", 0))):
        s, g, a, bias, fx, on = _stages(sets)
        assert on
        want_g = array("f", [0.0] * 3)
        want_a = array("f", [0.0] * 3)
        rnd = Lcg(7)
        worst_g = worst_a = 0.0
        for n in range(600):
            _sample(rnd, n, s)
            g.update(s.gyro_raw_rad_s, bias, want_g)
            a.update(s.accel_raw_m_s2, want_a)
            fx.update()
            for k in range(3):
                worst_g = max(worst_g, abs(want_g[k] - s.gyro_rad_s[k]))
                worst_a = max(worst_a, abs(want_a[k] - s.accel_m_s2[k]))
        # Q16 steps (1.5e-5) in, the fixed PT1's dead band of half an LSB over the gain, and the Q15
        # gain's rounding (6e-5 of the gain at 90 Hz) times the swing: 20 rad/s steps (0.02 deg/s, far
        # below a gyro's noise), 12 m/s^2 of vibration
        assert worst_g < 5e-4, (sets, worst_g)
        assert worst_a < 5e-4, (sets, worst_a)
        assert worst_g > 0.0 or worst_a > 0.0  # the two really are different arithmetic


def test_the_state_goes_back_to_the_float_filters_when_the_fixed_pass_stops():
    s, g, a, bias, fx, on = _stages(())
    rnd = Lcg(3)
    for n in range(80):
        _sample(rnd, n, s)
        fx.update()
    fx.release()
    assert not fx.active
    for k in range(3):
        assert abs(g.lpf1[k]._pt1.y - s.gyro_rad_s[k]) < 1e-6
        assert abs(a.f[k].y - s.accel_m_s2[k]) < 1e-5
    # the next float pass goes on from there as a fixed pass from the same state does
    twin = fixedimu.FixedImuFilter()
    assert twin.configure(g, a, s, bias, True)  # takes the state the float filters got back
    _sample(rnd, 80, s)
    want_g = array("f", [0.0] * 3)
    want_a = array("f", [0.0] * 3)
    g.update(s.gyro_raw_rad_s, bias, want_g)
    a.update(s.accel_raw_m_s2, want_a)
    twin.update()
    for k in range(3):
        assert abs(want_g[k] - s.gyro_rad_s[k]) < 5e-5, (k, want_g[k], s.gyro_rad_s[k])
        assert abs(want_a[k] - s.accel_m_s2[k]) < 5e-4, (k, want_a[k], s.accel_m_s2[k])


_ODD = (float("nan"), float("inf"), -float("inf"), 1e30, -1e30, -0.0, 1e-40, 127.99, -128.5, 255.9, -300.0,
        1.0000001, 0.9999999, 2.0 ** -17, -(2.0 ** -16))


def _odd_inputs(rnd, n, arrs):
    odd = n % 5 == 4  # every fifth pass: some inputs are not numbers, infinite or huge
    for i in range(len(arrs)):
        for k in range(3):
            v = rnd.span(150.0 if i == 2 else 40.0)
            if odd and rnd.unit() < 0.4:
                v = _ODD[int(rnd.unit() * len(_ODD))]
            for arr in arrs[i]:
                arr[k] = v


def _io():
    return (array("f", [0.0] * 3), array("f", [0.0] * 3), array("f", [0.0] * 3), array("f", [0.0] * 3),
            array("f", [0.0] * 3))


def test_the_state_stays_inside_the_32_bit_bounds_on_extreme_inputs():
    # the module docstring's bounds: every state word within 2**24, so |x - y| < 2**25
    s, g, a, bias, fx, on = _stages((("gyro_lpf1_hz", 0),))
    io = _io()
    st = array("i", fx.st)
    rnd = Lcg(13)
    for n in range(800):
        _odd_inputs(rnd, n, ((io[0],), (io[1],), (io[3],)))
        fixedimu.filter_pass(fx.co, st, io)
        for k in range(9):
            assert -(1 << 24) <= st[k] <= 1 << 24, (n, k, st[k])


def test_the_viper_twin_gives_the_python_twins_bits():
    if not IS_MICROPYTHON:
        assert fixedimu.FixedImuFilter.update is fixedimu.update_python  # no viper: the Python twin runs
        return
    assert fixedimu.FixedImuFilter.update is imu_viper.update
    for sets in ((), (("gyro_lpf1_hz", 0), ("acc_lpf_hz", 500)), (("gyro_lpf1_hz", 30), ("acc_lpf_hz", 2))):
        # two filters, each on its own signals: the Python twin's update on one, the viper twin's on the other
        sa, g, a, bias_a, fa, on = _stages(sets)
        sb, g, a, bias_b, fb, on = _stages(sets)
        fb.st[0] = fa.st[0] = 5  # a state that is not the float stages': both start from it
        rnd = Lcg(11)
        for n in range(1500):
            _odd_inputs(rnd, n, ((sa.gyro_raw_rad_s, sb.gyro_raw_rad_s), (bias_a, bias_b),
                                 (sa.accel_raw_m_s2, sb.accel_raw_m_s2)))
            fixedimu.update_python(fa)
            fb.update()
            for k in range(9):
                assert fa.st[k] == fb.st[k], (sets, n, "st", k, fa.st[k], fb.st[k])
            for k in range(3):
                assert sa.gyro_rad_s[k] == sb.gyro_rad_s[k], (sets, n, "gyro", k, sa.gyro_rad_s[k], sb.gyro_rad_s[k])
                assert sa.accel_m_s2[k] == sb.accel_m_s2[k], (sets, n, "acc", k, sa.accel_m_s2[k], sb.accel_m_s2[k])


def test_the_viper_twin_encodes_every_power_of_two_and_its_neighbours():
    # the encode's exponent comes from a byte table: every bit length of a state word, both signs
    if not IS_MICROPYTHON:
        return
    sa, g, a, bias, fa, on = _stages((("gyro_lpf1_hz", 0), ("acc_lpf_hz", 0)))  # gains of one: out = in
    sb, g, a, bias_b, fb, on = _stages((("gyro_lpf1_hz", 0), ("acc_lpf_hz", 0)))
    for p in range(0, 25):
        for d in (-1, 0, 1):
            for sign in (1.0, -1.0):
                v = sign * ((1 << p) + d) / 65536.0
                for k in range(3):
                    sa.gyro_raw_rad_s[k] = sb.gyro_raw_rad_s[k] = v
                    sa.accel_raw_m_s2[k] = sb.accel_raw_m_s2[k] = v
                    bias[k] = bias_b[k] = 0.0
                fixedimu.update_python(fa)
                fb.update()
                for k in range(3):
                    assert sa.gyro_rad_s[k] == sb.gyro_rad_s[k], (p, d, sign, sa.gyro_rad_s[k], sb.gyro_rad_s[k])
                    assert sa.accel_m_s2[k] == sb.accel_m_s2[k], (p, d, sign, sa.accel_m_s2[k], sb.accel_m_s2[k])


def test_a_fixed_filter_pass_allocates_nothing_on_micropython():
    if not IS_MICROPYTHON:
        return
    s, g, a, bias, fx, on = _stages(())
    _sample(Lcg(5), 0, s)
    fx.update()
    used = heap_bytes(fx.update, 50)
    assert used == 0, used


def test_a_flight_takes_the_fixed_filters_with_the_fixed_rate_loop_and_hands_them_back():
    from configfakes import FakeBoard

    from hoverfly.core.flight import Flight

    class TurningBoard(FakeBoard):
        def read_imu(self, gyro_rad_s, accel_m_s2):
            gyro_rad_s[0] = 0.75  # a steady roll rate the filters settle on
            gyro_rad_s[1] = -0.25
            gyro_rad_s[2] = 0.0
            return FakeBoard.read_imu(self, gyro_rad_s, accel_m_s2)

    f = Flight(TurningBoard())
    f.params.set("pid_math", "fixed")
    f.start(1000)
    assert f._fixed_on and f._fixed_imu_on
    t = 1000
    for _ in range(30):
        t += 1000
        f.step(t)
    # the fixed pass ran: its state holds the filtered gyro, and the float filters did not move
    g = f.gyro_filter.lpf1[0]._pt1
    assert f.fixed_imu.st[fixedimu.S_GYRO] != 0
    assert f.signals.gyro_rad_s[0] == f.fixed_imu.st[fixedimu.S_GYRO] / 65536.0
    assert g.y == 0.0
    # a notch is not the default chain: the float filters take over, from the fixed pass's state
    f.params.set("gyro_notch1_hz", 200)
    f.params.set("gyro_notch1_cut", 150)
    f.configure()
    assert f._fixed_on and not f._fixed_imu_on and not f.fixed_imu.active
    assert g.y == f.signals.gyro_rad_s[0] and g.y != 0.0
    f.params.set("pid_math", "float")
    f.params.set("gyro_notch1_hz", 0)
    f.configure()
    assert not f._fixed_on and not f._fixed_imu_on


def test_an_unconfigured_filter_writes_nothing():
    # the viper twin reaches its arrays through addresses that configure writes: before it, none
    if not IS_MICROPYTHON:
        return
    fx = fixedimu.FixedImuFilter()
    fx.update()
    assert list(fx.st) == [0] * fixedimu.ST_SIZE
