"""IMU drivers against their register models: read-back, configuration, faults, calibration.

Portable: pytest runs them on CPython and tests/portable/mprun.py under MicroPython.
Each driver is fed body-frame motion through its chip's register model (tests/rp2fakes)
and must read the same values back within one LSB, for several mountings.
"""

import math
import sys
from array import array

_here = __file__.rsplit("/", 1)[0] if "/" in __file__ else "."
_tests = _here.rsplit("/", 1)[0] if "/" in _here else ".."
if _tests not in sys.path:
    sys.path.append(_tests)

from hoverfly.drivers import imu as imu_mod  # noqa: E402
from hoverfly.drivers.bno055 import BNO055, MODE_IMU, roll_pitch_from_quaternion  # noqa: E402
from hoverfly.drivers.detect import detect_i2c  # noqa: E402
from hoverfly.drivers.icm42688 import ICM42688  # noqa: E402
from hoverfly.drivers.lsm9ds1 import LSM9DS1  # noqa: E402
from hoverfly.drivers.mpu6050 import MPU6050  # noqa: E402
from hoverfly.drivers.orientation import (  # noqa: E402
    CW0,
    CW0_FLIP,
    CW90,
    CW90_FLIP,
    CW180,
    CW180_FLIP,
    CW270,
    CW270_FLIP,
    Orientation,
)
from rp2fakes.regmodels import (  # noqa: E402
    BNO055Model,
    FakeI2C,
    ICM42688Model,
    LSM9DS1AGModel,
    LSM9DS1MagModel,
    MPU6050Model,
)

G = 9.80665
DEG = math.pi / 180.0
GYRO = (0.4, -1.1, 2.3)  # rad/s, body FRD
ACCEL = (1.5, -2.5, -9.3)  # m/s², body FRD
MOUNTS = (
    Orientation(CW0),
    Orientation(CW90),
    Orientation(CW180_FLIP),
    Orientation(CW270_FLIP),
    Orientation(CW0, 0.1, -0.2, 0.7),  # tilted board: a general rotation, not an axis map
)


def _no_wait(us):
    pass


def _vec():
    return array("f", [0.0, 0.0, 0.0])


def _close(got, want, tol):
    for i in range(len(want)):
        assert abs(got[i] - want[i]) <= tol, "axis %d: got %r want %r (tol %r)" % (i, got[i], want[i], tol)


def _mpu(mount=None, **kw):
    mount = mount or Orientation()
    model = MPU6050Model(mount, **kw)
    bus = FakeI2C(model)
    drv = MPU6050(bus, mount, delay_us=_no_wait)
    return model, bus, drv


# --- orientation ------------------------------------------------------------------------
def test_axis_maps_match_betaflight_names_in_flu():
    # Betaflight boardalignment.c, dest in its board frame (x fwd, y left, z up) for chip (x, y, z).
    x, y, z = 1, 2, 3
    expected = {
        CW0: (x, y, z), CW90: (y, -x, z), CW180: (-x, -y, z), CW270: (-y, x, z),
        CW0_FLIP: (-x, y, -z), CW90_FLIP: (y, x, -z), CW180_FLIP: (x, -y, -z), CW270_FLIP: (-y, -x, -z),
    }
    for mount in expected:
        out = [0.0, 0.0, 0.0]
        Orientation(mount).rotate(x, y, z, out)
        flu = (out[0], -out[1], -out[2])  # FRD -> FLU
        assert flu == tuple(float(v) for v in expected[mount]), (mount, flu)


def test_level_chip_at_cw0_reads_gravity_as_minus_z_in_frd():
    out = [0.0, 0.0, 0.0]
    Orientation(CW0).rotate(0.0, 0.0, G, out)  # chip z up reads +1 g at rest
    _close(out, (0.0, 0.0, -G), 1e-9)


def test_alignment_yaw_turns_board_x_onto_body_y_and_unrotate_inverts():
    o = Orientation(CW0, 0.0, 0.0, math.pi / 2)
    out = [0.0, 0.0, 0.0]
    o.rotate(1.0, 0.0, 0.0, out)  # chip x = FLU x: board forward, turned 90° right
    _close(out, (0.0, 1.0, 0.0), 1e-9)
    back = [0.0, 0.0, 0.0]
    o2 = Orientation(CW90_FLIP, 0.3, -0.4, 1.0)
    o2.rotate(0.2, -0.5, 0.9, out)
    o2.unrotate(out[0], out[1], out[2], back)
    _close(back, (0.2, -0.5, 0.9), 1e-9)


def test_rotate_scaled_axis_map_equals_matrix_path():
    for mount in range(8):
        fast = Orientation(mount)
        a = [0.0, 0.0, 0.0]
        b = [0.0, 0.0, 0.0]
        fast.rotate_scaled(123, -456, 789, 0.5, a)
        fast.rotate(123 * 0.5, -456 * 0.5, 789 * 0.5, b)
        _close(a, b, 1e-9)


def test_orientation_from_name_and_unknown_name():
    assert Orientation.from_name("CW270_DEG_FLIP").mount == CW270_FLIP
    try:
        Orientation.from_name("cw45")
        raise AssertionError("no error")
    except ValueError:
        pass


# --- read-back per driver ---------------------------------------------------------------
def test_mpu6050_reads_back_body_motion_for_each_mounting():
    for mount in MOUNTS:
        for dps, g_range in ((2000, 16), (500, 4)):
            model, bus, drv = _mpu(mount)
            assert drv.configure(gyro_range_dps=dps, accel_range_g=g_range)
            gyro = (0.4, -1.1, 0.9) if dps == 500 else GYRO
            accel = (1.5, -2.5, -9.3) if g_range >= 16 else (0.5, -1.0, -9.3)
            model.set_motion(gyro, accel)
            g = _vec()
            a = _vec()
            assert drv.read(g, a)
            _close(g, gyro, DEG / (131.0 * 250.0 / dps) + 1e-6)  # one LSB
            _close(a, accel, G * g_range / 32768.0 + 1e-6)
    assert drv.samples == 1 and drv.bus_errors == 0


def test_mpu6050_level_at_rest_reads_minus_g_on_z():
    model, bus, drv = _mpu()
    assert drv.configure()
    model.set_motion((0.0, 0.0, 0.0), (0.0, 0.0, -G))
    g = _vec()
    a = _vec()
    assert drv.read(g, a)
    assert abs(a[2] + G) < 0.005 and abs(a[0]) < 0.005 and abs(g[0]) < 0.002


def test_lsm9ds1_reads_back_body_motion_and_field_for_each_mounting():
    for mount in MOUNTS:
        ag = LSM9DS1AGModel(mount)
        mag = LSM9DS1MagModel(mount)
        drv = LSM9DS1(FakeI2C(ag, mag), mount, delay_us=_no_wait)
        assert drv.configure(gyro_range_dps=2000, accel_range_g=16)
        assert drv.mag_present
        ag.set_motion(GYRO, ACCEL)
        mag.set_field((21.0, -4.0, 43.0))
        g = _vec()
        a = _vec()
        m = _vec()
        assert drv.read(g, a)
        _close(g, GYRO, 0.070 * DEG)  # 70 mdps/LSB
        _close(a, ACCEL, 0.732e-3 * G)  # 0.732 mg/LSB
        assert drv.read_mag(m)
        _close(m, (21.0, -4.0, 43.0), 0.014)  # 0.14 mgauss/LSB = 0.014 µT


def test_icm42688_fifo_and_data_registers_read_back_for_each_mounting():
    for mount in MOUNTS:
        for fifo in (True, False):
            model = ICM42688Model(mount)
            drv = ICM42688(model, mount, delay_us=_no_wait)
            assert drv.configure(gyro_range_dps=2000, accel_range_g=16, odr_hz=1000, fifo=fifo)
            model.set_motion(GYRO, ACCEL)
            model.tick()
            g = _vec()
            a = _vec()
            assert drv.read(g, a)
            _close(g, GYRO, DEG / 16.4)
            _close(a, ACCEL, G / 2048.0)


def test_bno055_reads_back_gyro_accel_for_each_mounting():
    for mount in MOUNTS:
        model = BNO055Model(mount)
        drv = BNO055(FakeI2C(model), mount, delay_us=_no_wait)
        assert drv.configure()
        model.set_motion(GYRO, ACCEL)
        g = _vec()
        a = _vec()
        assert drv.read(g, a)
        _close(g, GYRO, 1.0 / 900.0)
        _close(a, ACCEL, 0.01)


def _quat_from_euler(roll, pitch, yaw):
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def _same_rotation(q, p, tol):
    dot = q[0] * p[0] + q[1] * p[1] + q[2] * p[2] + q[3] * p[3]
    assert abs(abs(dot) - 1.0) < tol, (q, p)


def test_bno055_attitude_is_body_to_ned_for_each_mounting():
    for mount in MOUNTS:
        model = BNO055Model(mount)
        drv = BNO055(FakeI2C(model), mount, delay_us=_no_wait, capture_offset=False)
        assert drv.configure(mode=MODE_IMU)
        for roll, pitch, yaw in ((0.0, 0.0, 0.0), (0.3, 0.0, 0.0), (0.0, -0.4, 0.0), (0.2, 0.5, -2.0)):
            want = _quat_from_euler(roll, pitch, yaw)
            model.set_attitude(want)
            q = [0.0, 0.0, 0.0, 0.0]
            assert drv.read_attitude(q)
            assert q[0] >= 0.0
            _same_rotation(q, want, 2e-6)
            r, p = roll_pitch_from_quaternion(q[0], q[1], q[2], q[3])
            assert abs(r - roll) < 1e-3 and abs(p - pitch) < 1e-3


def test_bno055_first_roll_pitch_becomes_the_offset_and_yaw_is_kept():
    mount = Orientation(CW90)
    model = BNO055Model(mount)
    drv = BNO055(FakeI2C(model), mount, delay_us=_no_wait)
    assert drv.configure()
    model.set_attitude(_quat_from_euler(0.05, -0.03, 1.0))  # board sits a little tilted at boot
    q = [0.0, 0.0, 0.0, 0.0]
    assert drv.read_attitude(q)
    assert abs(drv.offset_roll_rad - 0.05) < 1e-3 and abs(drv.offset_pitch_rad + 0.03) < 1e-3
    _same_rotation(q, _quat_from_euler(0.0, 0.0, 1.0), 1e-5)
    drv.reset_offset()
    model.set_attitude(_quat_from_euler(0.2, 0.1, 0.0))
    assert drv.read_attitude(q)
    _same_rotation(q, (1.0, 0.0, 0.0, 0.0), 1e-5)


def test_bno055_no_quaternion_yet_reads_false():
    model = BNO055Model()
    drv = BNO055(FakeI2C(model), Orientation(), delay_us=_no_wait)
    assert drv.configure()
    model.freeze()
    for i in range(0x20, 0x28):
        model.regs[i] = 0
    q = [9.0, 9.0, 9.0, 9.0]
    assert not drv.read_attitude(q)
    assert q[0] == 9.0 and drv.bad_quaternions == 1


# --- configuration writes the documented registers --------------------------------------
def test_mpu6050_configure_writes_the_register_map_values():
    model, bus, drv = _mpu()
    assert drv.configure(gyro_range_dps=2000, accel_range_g=16, dlpf_hz=98, rate_hz=1000)
    assert model.written(0x6B) == [0x80, 0x01]  # DEVICE_RESET, then wake on PLL X gyro
    assert model.written(0x19) == [0]  # 1 kHz / (1 + 0)
    assert model.written(0x1A) == [2]  # DLPF_CFG 2 = 98 Hz
    assert model.written(0x1B) == [0x18]  # FS_SEL 3 = ±2000 °/s
    assert model.written(0x1C) == [0x18]  # AFS_SEL 3 = ±16 g
    model2, bus2, drv2 = _mpu()
    assert drv2.configure(gyro_range_dps=500, accel_range_g=4, dlpf_hz=42, rate_hz=500)
    assert model2.written(0x1B) == [0x08] and model2.written(0x1C) == [0x08]
    assert model2.written(0x1A) == [3] and model2.written(0x19) == [1]


def test_mpu6050_unsupported_range_is_a_value_error():
    model, bus, drv = _mpu()
    try:
        drv.configure(gyro_range_dps=300)
        raise AssertionError("no error")
    except ValueError:
        pass
    assert model.writes == []


def test_icm42688_configure_writes_fifo_1khz_packet3():
    model = ICM42688Model()
    drv = ICM42688(model, Orientation(), delay_us=_no_wait)
    assert drv.configure(gyro_range_dps=2000, accel_range_g=16, odr_hz=1000, fifo=True)
    assert model.written(0x11) == [0x01]  # soft reset
    assert model.written(0x4F) == [0x06]  # GYRO_FS_SEL 0 (±2000), ODR 0110 = 1 kHz
    assert model.written(0x50) == [0x06]  # ACCEL_FS_SEL 0 (±16 g), 1 kHz
    assert model.written(0x5F) == [0x07]  # FIFO accel + gyro + temp = packet 3
    assert model.written(0x16) == [0x40]  # stream-to-FIFO
    assert model.written(0x4E) == [0x0F]  # gyro + accel low-noise
    assert model.written(0x4B) == [0x02]  # FIFO flush
    model2 = ICM42688Model()
    drv2 = ICM42688(model2, Orientation(), delay_us=_no_wait)
    assert drv2.configure(gyro_range_dps=500, accel_range_g=4, odr_hz=500, fifo=False)
    assert model2.written(0x4F) == [0x4F] and model2.written(0x50) == [0x4F]


def test_lsm9ds1_configure_writes_ctrl_registers():
    ag = LSM9DS1AGModel()
    mag = LSM9DS1MagModel()
    drv = LSM9DS1(FakeI2C(ag, mag), Orientation(), delay_us=_no_wait)
    assert drv.configure(gyro_range_dps=2000, accel_range_g=16, odr_hz=952, mag_range_gauss=4)
    assert ag.written(0x22) == [0x05, 0x44]  # SW_RESET, then BDU + IF_ADD_INC
    assert ag.written(0x10) == [0xD8]  # ODR_G 110 = 952 Hz, FS_G 11 = 2000 dps
    assert ag.written(0x20) == [0xC8]  # ODR_XL 110, FS_XL 01 = ±16 g
    assert mag.written(0x22) == [0x00]  # continuous conversion
    assert mag.written(0x21)[-1] == 0x00  # FS 00 = ±4 gauss


def test_bno055_configure_goes_through_config_mode_to_fusion():
    model = BNO055Model()
    drv = BNO055(FakeI2C(model), Orientation(), delay_us=_no_wait)
    assert drv.configure()
    ops = model.written(0x3D)
    assert ops[0] == 0x00 and ops[-1] == 0x0C  # CONFIGMODE first, NDOF last
    assert model.written(0x3F) == [0x20]  # RST_SYS
    assert model.written(0x3B) == [0x06]  # m/s², rad/s, radians, Windows
    assert drv.read_status() == (5, 0, 0xFF)


# --- probing ----------------------------------------------------------------------------
def test_wrong_who_am_i_fails_configure_with_wrong_id():
    model, bus, drv = _mpu(who_am_i=0x70)
    assert not drv.configure()
    assert drv.status_name() == "wrong_id" and drv.who_am_i == 0x70
    assert model.writes == []
    lsm = LSM9DS1(FakeI2C(LSM9DS1AGModel(who_am_i=0x69)), Orientation(), delay_us=_no_wait)
    assert not lsm.configure() and lsm.status_name() == "wrong_id"
    bno = BNO055(FakeI2C(BNO055Model(chip_id=0xA1)), Orientation(), delay_us=_no_wait)
    assert not bno.configure() and bno.status_name() == "wrong_id"
    icm = ICM42688(ICM42688Model(who_am_i=0x98), Orientation(), delay_us=_no_wait)
    assert not icm.configure() and icm.status_name() == "wrong_id"


def test_absent_chip_is_reported_not_raised():
    model, bus, drv = _mpu()
    model.absent = True
    assert not drv.probe() and drv.status_name() == "absent" and drv.bus_errors == 1
    empty = MPU6050(FakeI2C(), Orientation(), delay_us=_no_wait)
    assert not empty.configure() and empty.status_name() == "absent"
    icm_model = ICM42688Model()
    icm_model.absent = True  # SPI: nobody drives MISO, it reads 0xFF
    icm = ICM42688(icm_model, Orientation(), delay_us=_no_wait)
    assert not icm.configure() and icm.status_name() == "absent"


def test_lsm9ds1_without_magnetometer_still_configures():
    drv = LSM9DS1(FakeI2C(LSM9DS1AGModel()), Orientation(), delay_us=_no_wait)
    assert drv.configure()
    assert not drv.mag_present and not drv.read_mag([0.0, 0.0, 0.0])


def test_detect_i2c_finds_the_chip_on_the_bus():
    bus = FakeI2C(BNO055Model(address=0x29))
    found = detect_i2c(bus, Orientation(), delay_us=_no_wait)
    assert found is not None and found.name == "bno055" and found.address == 0x29
    assert detect_i2c(FakeI2C(), Orientation(), delay_us=_no_wait) is None


# --- faults -----------------------------------------------------------------------------
def test_bus_error_mid_flight_is_counted_and_read_returns_false():
    model, bus, drv = _mpu()
    assert drv.configure()
    model.set_motion(GYRO, ACCEL)
    g = _vec()
    a = _vec()
    assert drv.read(g, a)
    before = (g[0], a[2])
    model.fail_next(2)
    model.set_motion((0.0, 0.0, 0.0), (0.0, 0.0, -G))
    assert not drv.read(g, a)
    assert not drv.read(g, a)
    assert drv.bus_errors == 2 and (g[0], a[2]) == before  # caller's arrays untouched
    assert drv.read(g, a) and abs(g[0]) < 0.01


def test_bus_errors_on_every_driver_never_raise():
    g = _vec()
    a = _vec()
    model, bus, mpu = _mpu()
    ag = LSM9DS1AGModel()
    lsm = LSM9DS1(FakeI2C(ag), Orientation(), delay_us=_no_wait)
    bm = BNO055Model()
    bno = BNO055(FakeI2C(bm), Orientation(), delay_us=_no_wait)
    im = ICM42688Model()
    icm = ICM42688(im, Orientation(), delay_us=_no_wait)
    for drv, m in ((mpu, model), (lsm, ag), (bno, bm), (icm, im)):
        assert drv.configure()
        m.fail_next(1)
        assert not drv.read(g, a)
        assert drv.bus_errors == 1, drv.name
    bm.fail_next(1)
    assert not bno.read_attitude([0.0, 0.0, 0.0, 0.0])


def test_configure_bus_error_reports_bus_error_status():
    model, bus, drv = _mpu()
    assert drv.probe()
    bus.fail_next(0)
    model.fail_next(0)
    # WHO_AM_I answers, then the reset write fails.
    model.on_read = None
    orig = model.write

    def failing_write(reg, data):
        raise OSError(5)

    model.write = failing_write
    assert not drv.configure()
    assert drv.status_name() == "bus_error"
    model.write = orig


def test_frozen_sensor_is_detected_and_clears_when_it_moves_again():
    model, bus, drv = _mpu(noise_lsb=4)
    assert drv.configure()
    model.set_motion(GYRO, ACCEL)
    g = _vec()
    a = _vec()
    for _ in range(20):
        assert drv.read(g, a)
    assert not drv.frozen and drv.frozen_count == 0
    model.freeze()
    for _ in range(20):
        drv.read(g, a)
    assert drv.frozen and drv.frozen_count == 20 - drv.frozen_samples + 1
    model.unfreeze()
    drv.read(g, a)
    assert not drv.frozen


def test_saturated_samples_are_counted():
    model, bus, drv = _mpu()
    assert drv.configure(gyro_range_dps=250)
    g = _vec()
    a = _vec()
    model.set_motion((0.5, 0.0, 0.0), (0.0, 0.0, -G))
    assert drv.read(g, a) and drv.saturated_count == 0
    model.set_motion((10.0, 0.0, 0.0), (0.0, 0.0, -G))  # 573 °/s on a ±250 °/s gyro
    assert drv.read(g, a)
    assert drv.saturated and drv.saturated_count == 1
    assert abs(g[0] - 32767 / 131.0 * DEG) < 1e-3


# --- calibration (seed 000) --------------------------------------------------------------
def test_mpu6050_calibration_averages_out_a_bias():
    bias = (0.02, -0.015, 0.011)  # rad/s, ~1 °/s, as an MPU-6050 zero-rate offset
    for mount in (Orientation(CW0), Orientation(CW270_FLIP)):
        model, bus, drv = _mpu(mount, noise_lsb=6, seed=3)
        assert drv.configure(gyro_range_dps=2000)
        model.set_motion(bias, (0.0, 0.0, -G))
        assert drv.calibrate(samples=500, discard=500, still_dps=4.0)
        _close(drv.gyro_bias_rad_s, bias, 0.5 * DEG / 16.4)  # within 0.5 LSB (0.03 °/s) of a 1 °/s bias
        model.set_motion((bias[0] + 1.0, bias[1], bias[2]), (0.0, 0.0, -G))
        g = _vec()
        a = _vec()
        total = [0.0, 0.0, 0.0]
        for _ in range(200):
            drv.read(g, a)
            for i in range(3):
                total[i] += g[i]
        _close([t / 200 for t in total], (1.0, 0.0, 0.0), 0.8 * DEG / 16.4)


def test_mpu6050_calibration_reports_motion_and_keeps_old_bias():
    model, bus, drv = _mpu(noise_lsb=2)
    assert drv.configure()
    model.set_motion((0.0, 0.0, 0.0), (0.0, 0.0, -G))
    reads = [0]

    def wobble(m):
        reads[0] += 1
        m.gyro_rad_s[1] = 0.3 * math.sin(reads[0] * 0.05)  # ±17 °/s: someone moves the craft

    model.on_read = wobble
    assert not drv.calibrate(samples=100, discard=10)
    assert drv.gyro_bias_rad_s == [0.0, 0.0, 0.0]


def test_bias_averager_rounds_to_sixteenth_lsb():
    acc = imu_mod.GyroBiasAverager()
    for v in (3, 4, 4, 4):
        acc.add(v, -v, 0)
    assert acc.mean16(0) == 60 and acc.mean16(1) == -60 and acc.mean16(2) == 0  # 3.75 LSB
    assert acc.spread_lsb() == 1
    assert imu_mod.signed16(0xFF, 0xFF) == -1 and imu_mod.signed16(0x7F, 0xFF) == 32767


# --- ICM-42688-P FIFO --------------------------------------------------------------------
def _icm(max_packets=8):
    model = ICM42688Model()
    drv = ICM42688(model, Orientation(), delay_us=_no_wait, max_packets=max_packets)
    assert drv.configure()
    return model, drv


def test_icm42688_fifo_returns_newest_and_counts_drops():
    model, drv = _icm(max_packets=8)
    g = _vec()
    a = _vec()
    model.set_motion((0.0, 0.0, 0.0), (0.0, 0.0, -G))
    model.tick(19)
    model.set_motion((1.0, 0.0, 0.0), (0.0, 0.0, -G))
    model.tick(1)  # 20 packets queued: read in chunks of 8, 8, 4
    assert drv.read_fifo(g, a)
    assert abs(g[0] - 1.0) < 0.002
    assert drv.packets == 20 and drv.dropped_packets == 19 and model.fifo_packets() == 0
    assert not drv.read_fifo(g, a) and drv.empty_reads == 1


def test_icm42688_fifo_overflow_is_counted():
    model, drv = _icm()
    g = _vec()
    a = _vec()
    model.tick(200)  # 2 KB holds 128 packets
    assert drv.read_fifo(g, a)
    assert drv.overflows == 1 and model.lost_packets == 72
    model.tick(1)
    assert drv.read_fifo(g, a) and drv.overflows == 1


def test_icm42688_fifo_garbage_header_flushes():
    model, drv = _icm()
    g = _vec()
    a = _vec()
    model.poke_fifo(bytes(range(0x90, 0xA0)))  # header 0x90: 20-bit flag, no accel/gyro
    assert not drv.read_fifo(g, a)
    assert drv.bad_packets == 1 and model.fifo_packets() == 0
    model.tick(1)
    assert drv.read_fifo(g, a)


def test_icm42688_invalid_marker_is_not_a_sample():
    model = ICM42688Model()
    drv = ICM42688(model, Orientation(), delay_us=_no_wait)
    assert drv.configure(fifo=False)
    model.write_reg(0x4E, 0x00)  # sensors off: data registers read -32768
    model._write_data_off()
    g = _vec()
    a = _vec()
    assert not drv.read(g, a)
    assert drv.bad_packets == 1 and drv.samples == 0
