"""Property tests of the IMU drivers (CPython only: hypothesis).

Random raw register/FIFO contents must never make read() raise, and what comes out stays
within the configured range (per axis for axis-map mountings, by norm for a general
alignment). An independent struct-based decode checks the hand-written one.
"""

import math
import struct
from array import array

from hypothesis import given, settings
from hypothesis import strategies as st

from hoverfly.drivers.bno055 import BNO055
from hoverfly.drivers.icm42688 import ICM42688
from hoverfly.drivers.lsm9ds1 import LSM9DS1
from hoverfly.drivers.mpu6050 import MPU6050
from hoverfly.drivers.orientation import Orientation
from rp2fakes.regmodels import BNO055Model, FakeI2C, ICM42688Model, LSM9DS1AGModel, MPU6050Model

G = 9.80665
DEG = math.pi / 180.0
SETTINGS = settings(max_examples=300, derandomize=True, deadline=None)
mounts = st.one_of(
    st.integers(0, 7).map(Orientation),
    st.tuples(st.floats(-3.1, 3.1), st.floats(-1.5, 1.5), st.floats(-3.1, 3.1)).map(
        lambda a: Orientation(0, a[0], a[1], a[2])
    ),
)


def _no_wait(us):
    pass


def _within(v, limit, axis_map):
    if axis_map:
        return all(abs(x) <= limit * (1 + 1e-6) for x in v)
    return math.sqrt(sum(x * x for x in v)) <= limit * math.sqrt(3) * (1 + 1e-6)


@SETTINGS
@given(raw=st.binary(min_size=14, max_size=14), mount=mounts,
       ranges=st.sampled_from([(250, 2), (500, 4), (1000, 8), (2000, 16)]))
def test_mpu6050_random_registers_never_raise_and_stay_in_range(raw, mount, ranges):
    model = MPU6050Model(mount)
    drv = MPU6050(FakeI2C(model), mount, delay_us=_no_wait)
    assert drv.configure(gyro_range_dps=ranges[0], accel_range_g=ranges[1])
    model.freeze()
    model.regs[0x3B:0x49] = raw
    g = array("f", [0, 0, 0])
    a = array("f", [0, 0, 0])
    assert drv.read(g, a)
    # 32768 counts at the datasheet sensitivity is the range (±250 °/s at 131 LSB/°/s ...).
    lsb_per_dps = {250: 131.0, 500: 65.5, 1000: 32.8, 2000: 16.4}[ranges[0]]  # PS-MPU-6000A §6.1
    gyro_limit = 32768 / lsb_per_dps * DEG
    accel_limit = 32768 / (16384.0 * 2 / ranges[1]) * G
    assert _within(g, gyro_limit, mount.axis_map_only)
    assert _within(a, accel_limit, mount.axis_map_only)
    # Independent decode: struct big-endian, then the orientation matrix.
    ax, ay, az, _t, gx, gy, gz = struct.unpack(">7h", raw)
    want = [0.0, 0.0, 0.0]
    mount.rotate(gx, gy, gz, want)
    k = DEG / lsb_per_dps
    for i in range(3):
        assert abs(g[i] - want[i] * k) <= 1e-5 * max(1.0, abs(want[i] * k))
    assert drv.saturated == any(v in (32767, -32767, -32768) for v in (ax, ay, az, gx, gy, gz))


@SETTINGS
@given(raw=st.binary(min_size=22, max_size=22), mount=mounts)
def test_lsm9ds1_random_registers_never_raise_and_stay_in_range(raw, mount):
    ag = LSM9DS1AGModel(mount)
    drv = LSM9DS1(FakeI2C(ag), mount, delay_us=_no_wait)
    assert drv.configure(gyro_range_dps=500, accel_range_g=4)
    ag.freeze()
    ag.regs[0x18:0x2E] = raw
    g = [0.0, 0.0, 0.0]
    a = [0.0, 0.0, 0.0]
    assert drv.read(g, a)
    assert _within(g, 32768 * 17.5e-3 * DEG, mount.axis_map_only)
    assert _within(a, 32768 * 0.122e-3 * G, mount.axis_map_only)


@SETTINGS
@given(raw=st.binary(min_size=18, max_size=18), quat=st.binary(min_size=8, max_size=8), mount=mounts)
def test_bno055_random_registers_never_raise(raw, quat, mount):
    model = BNO055Model(mount)
    drv = BNO055(FakeI2C(model), mount, delay_us=_no_wait)
    assert drv.configure()
    model.freeze()
    model.regs[0x08:0x1A] = raw
    model.regs[0x20:0x28] = quat
    g = [0.0, 0.0, 0.0]
    a = [0.0, 0.0, 0.0]
    q = [0.0, 0.0, 0.0, 0.0]
    assert drv.read(g, a)
    assert _within(g, 32768 / 900.0, mount.axis_map_only)
    assert _within(a, 327.68, mount.axis_map_only)
    if drv.read_attitude(q):
        assert abs(sum(x * x for x in q) - 1.0) < 1e-6 and q[0] >= 0.0


@SETTINGS
@given(fifo=st.binary(min_size=0, max_size=400), mount=mounts, max_packets=st.integers(1, 8))
def test_icm42688_random_fifo_never_raises_and_stays_in_range(fifo, mount, max_packets):
    model = ICM42688Model(mount)
    drv = ICM42688(model, mount, delay_us=_no_wait, max_packets=max_packets)
    assert drv.configure(gyro_range_dps=1000, accel_range_g=8)
    model.poke_fifo(fifo)
    g = [0.0, 0.0, 0.0]
    a = [0.0, 0.0, 0.0]
    for _ in range(3):
        if drv.read(g, a):
            assert _within(g, 32768 / 32.8 * DEG, mount.axis_map_only)
            assert _within(a, 32768 / 4096.0 * G, mount.axis_map_only)
    assert drv.packets + drv.empty_reads + drv.bad_packets >= 1


@SETTINGS
@given(gyro=st.tuples(*[st.floats(-30.0, 30.0)] * 3), accel=st.tuples(*[st.floats(-150.0, 150.0)] * 3),
       mount=mounts)
def test_mpu6050_round_trip_within_one_lsb_or_saturated(gyro, accel, mount):
    model = MPU6050Model(mount)
    drv = MPU6050(FakeI2C(model), mount, delay_us=_no_wait)
    assert drv.configure()
    model.set_motion(gyro, accel)
    g = [0.0, 0.0, 0.0]
    a = [0.0, 0.0, 0.0]
    assert drv.read(g, a)
    if not drv.saturated:
        for i in range(3):
            assert abs(g[i] - gyro[i]) <= DEG / 16.4
            assert abs(a[i] - accel[i]) <= G / 2048.0
