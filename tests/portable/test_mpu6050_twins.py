"""The MPU-6050 burst read (drivers/mpu6050.py read_burst) and its viper twin (accel/mpu6050.py, generated).

Portable: under MicroPython (tests/portable/mprun.py) the viper twin must be the one the driver
chose, and must give the Python twin's return value, state words and output bits on random and
edge bursts, every mounting, every range, biases to the plan's limits and scales whose products
round every way (ties included). On both runtimes the Python twin must give each value as the
float32 nearest to count * the float32 scale, within one float32 step of the old float64 product,
and the driver's read() must keep its counters; a read allocates nothing where viper runs.
"""

from array import array

from fastpathkit import heap_bytes

from hoverfly.compat import IS_MICROPYTHON
from hoverfly.drivers import mpu6050
from hoverfly.drivers.imu import DEG_TO_RAD, GRAVITY_M_S2
from hoverfly.drivers.orientation import CW0, CW90, CW180_FLIP, CW270_FLIP, Orientation

if IS_MICROPYTHON:
    from hoverfly.accel import mpu6050 as mpu_viper
else:
    mpu_viper = None

# float64 arithmetic on this port (CPython, the unix VM); the rp2 port's floats are float32
FLOAT64 = 1.0 + 2.0 ** -40 != 1.0


class Lcg:
    """Deterministic integers (the constants of tests/portable/fastpathkit.py's Rand)."""

    def __init__(self, seed):
        self.s = seed

    def below(self, n):
        self.s = (self.s * 1103515245 + 12345) & 0x7FFFFFFF
        return (self.s >> 8) % n

    def fill(self, buf, start, end):
        for k in range(start, end):
            buf[k] = self.below(256)


class _Bus:
    """One MPU-6050: WHO_AM_I answers, every burst read gets `burst`; `fail` raises OSError."""

    def __init__(self):
        self.burst = bytearray(14)
        self.fail = False

    def readfrom_mem_into(self, address, register, buf):
        if self.fail:
            raise OSError(5)
        if len(buf) == 1:
            buf[0] = mpu6050.WHO_AM_I_VALUE
        else:
            for i in range(len(buf)):
                buf[i] = self.burst[i]

    def writeto_mem(self, address, register, data):
        pass


def _driver(mount, gyro_dps=2000, accel_g=16, bias=(0, 0, 0), orientation=None):
    bus = _Bus()
    drv = mpu6050.MPU6050(bus, orientation or Orientation(mount), delay_us=lambda us: None)
    assert drv.configure(gyro_range_dps=gyro_dps, accel_range_g=accel_g)
    drv.set_gyro_bias16(bias[0], bias[1], bias[2])
    return bus, drv


def _bits(a):
    """The float32 words of an array('f') of 3, as ints (compares -0.0 and NaN by their bits)."""
    b = bytes(a)
    return [b[4 * i] | (b[4 * i + 1] << 8) | (b[4 * i + 2] << 16) | (b[4 * i + 3] << 24) for i in range(3)]


_VIPER = []  # one driver whose read (the viper method) _both runs on a copy of st


def _both(burst, st):
    """read_burst, the Python twin, on st; under MicroPython also the viper MPU6050.read on a
    driver holding a copy of st and fed the burst; asserts they agree (outputs' bits, every state
    word, the flags the driver took, temp_raw); (flags, gyro, accel) of the Python twin."""
    st_v = array("i", st)
    gp, ap = array("f", [7.0] * 3), array("f", [7.0] * 3)
    rp = mpu6050.read_burst(burst, st, gp, ap)
    if mpu_viper is not None:
        if not _VIPER:
            _VIPER.append(_driver(CW0))
        bus, drv = _VIPER[0]
        for i in range(mpu6050.ST_SIZE):
            drv._st[i] = st_v[i]
        for i in range(14):
            bus.burst[i] = burst[i]
        gv, av = array("f", [7.0] * 3), array("f", [7.0] * 3)
        assert drv.read(gv, av)
        assert list(drv._st) == list(st), (bytes(burst), list(drv._st), list(st))
        assert _bits(gv) == _bits(gp) and _bits(av) == _bits(ap), (bytes(burst), list(gv), list(gp),
                                                                   list(av), list(ap))
        assert drv.temp_raw == st[mpu6050.ST_TEMP]
        if rp:
            assert drv.saturated == ((rp & 4) != 0)
            assert drv.frozen == (rp >> 3 >= drv.frozen_samples)
    return rp, gp, ap


def _f32(x):
    return array("f", (x,))[0]


def _burst_of(words):
    """A burst from seven int16 register values (accel x y z, temp, gyro x y z)."""
    b = bytearray(14)
    for i in range(7):
        v = words[i] & 0xFFFF
        b[2 * i] = v >> 8
        b[2 * i + 1] = v & 0xFF
    return b


def _signed(hi, lo):
    v = (hi << 8) | lo
    return v - 0x10000 if v & 0x8000 else v


def _expect(drv, burst):
    """What read() must give: the orientation's axis map applied to the counts, each count (gyro:
    count * 16 - bias) times the configured float32 scale, rounded once to float32."""
    c = [_signed(burst[2 * i], burst[2 * i + 1]) for i in range(7)]
    g = array("f", [0.0] * 3)
    a = array("f", [0.0] * 3)
    drv._orientation.rotate_scaled(c[4] * 16 - drv._bias16_x, c[5] * 16 - drv._bias16_y,
                                   c[6] * 16 - drv._bias16_z, drv._gyro_k16, g)
    drv._orientation.rotate_scaled(c[0], c[1], c[2], drv._accel_k, a)
    return g, a


def test_micropython_picks_the_viper_read_and_cpython_the_python_one():
    if IS_MICROPYTHON:
        assert mpu6050.MPU6050.read is mpu_viper.read and mpu6050.read_python is not mpu_viper.read
    else:
        assert mpu6050.MPU6050.read is mpu6050.read_python


def test_twins_agree_on_random_and_edge_bursts_for_every_mount_and_range():
    rnd = Lcg(11)
    edges = (bytes(14), b"\xff" * 14, b"\x80\x00" * 7, b"\x7f\xff" * 7, b"\x80\x01" * 7, b"\x00\x01" * 7,
             b"\x7f\xfe" * 7, b"\x80\x02" * 7)
    limit = mpu6050.BIAS_OFFSET - 1
    ranges = ((250, 2), (500, 4), (1000, 8), (2000, 16))
    cases = 0
    for mount in range(8):
        for r in range(4):
            bias = ((0, 0, 0), (-1, 16, -limit), (limit, -limit, 12345), (7, -300, 5))[r]
            bus, drv = _driver(mount, ranges[r][0], ranges[r][1], bias)
            st = drv._st
            assert st[mpu6050.ST_SCALED] == 1
            for burst in edges:
                _both(burst, st)
                _both(burst, st)  # the same again: the frozen count moves
                cases += 2
            burst = bytearray(14)
            for k in range(40 if IS_MICROPYTHON else 6):
                rnd.fill(burst, 0, 14)
                if k % 5 == 0:
                    burst[2 * rnd.below(7)] = 0x80  # a rail or its neighbour now and then
                    burst[9] = rnd.below(3)
                _both(burst, st)
                cases += 1
    assert cases >= 700


def test_twins_round_to_nearest_even_for_any_scale():
    """The plan's scales set by hand to mantissas whose products drop bits every way: exact (a power
    of two), just above one, all ones, others; n (a zero gyro count less the bias) of every length,
    random, and 3 * 2**j +- 0, 1: with the mantissa 0x800001 the dropped bits are n's own, so
    3 * 2**j is an exact tie (kept part odd or even as j goes) and its neighbours just miss one."""
    rnd = Lcg(4)
    bus, drv = _driver(CW0)
    st = drv._st
    burst = bytearray(14)
    limit = mpu6050.BIAS_OFFSET
    mantissas = (0x800000, 0x800001, 0xFFFFFF, 0xC00000, 0xAAAAAB, 0x800003, 0x9E3779)
    for m in mantissas:
        for e in (24, 100, 127, 200):
            st[mpu6050.ST_GYRO_M] = m
            st[mpu6050.ST_GYRO_E] = e
            st[mpu6050.ST_ACCEL_M] = m
            st[mpu6050.ST_ACCEL_E] = e
            want = m * 2.0 ** (e - 150)
            ns = []
            for j in range(19):
                for d in (-1, 0, 1):
                    ns.append((3 << j) + d)
            for _ in range(20 if IS_MICROPYTHON else 3):
                ns.append(rnd.below(1 << (1 + rnd.below(20))))
            for n0 in ns:
                for n in (n0, -n0):
                    if n <= -limit or n >= limit:
                        continue
                    st[mpu6050.ST_BIAS] = -n + limit
                    rnd.fill(burst, 0, 8)
                    burst[8] = burst[9] = 0
                    _r, g, a = _both(burst, st)
                    assert _bits(g)[0] == _bits(array("f", (n * want, 0.0, 0.0)))[0], (m, e, n)
                    c = _signed(burst[0], burst[1])
                    assert _bits(a)[0] == _bits(array("f", (c * want, 0.0, 0.0)))[0], (m, e, c)


def test_python_twin_gives_the_float32_nearest_the_count_times_the_scale():
    rnd = Lcg(8)
    for mount in (CW0, CW90, CW180_FLIP, CW270_FLIP):
        bus, drv = _driver(mount, 500, 4, (33, -4000, 100000))
        for _ in range(30):
            rnd.fill(bus.burst, 0, 14)
            g = array("f", [0.0] * 3)
            a = array("f", [0.0] * 3)
            assert drv.read(g, a)
            wg, wa = _expect(drv, bus.burst)
            assert _bits(g) == _bits(wg) and _bits(a) == _bits(wa)
            assert drv.temp_raw == _signed(bus.burst[6], bus.burst[7])


def test_configured_scales_are_float32_within_one_step_of_the_float64_product():
    """configure() rounds the scales to float32 (what the chip holds); on a float64 port each value is
    then within one float32 step of count * the float64 scale rounded once (the driver before)."""
    assert _driver(CW0)[1]._gyro_k16 == _f32(DEG_TO_RAD / 16.4 / 16.0)
    assert _driver(CW0)[1]._accel_k == _f32(GRAVITY_M_S2 / 2048.0)
    if not FLOAT64:
        return
    rnd = Lcg(9)
    worst = 0
    for gyro_dps, accel_g, lsb_dps, lsb_g in ((250, 2, 131.0, 16384.0), (2000, 16, 16.4, 2048.0)):
        bus, drv = _driver(CW0, gyro_dps, accel_g, (5, -77, 0))
        k64 = DEG_TO_RAD / lsb_dps / 16.0
        ka64 = GRAVITY_M_S2 / lsb_g
        for _ in range(200):
            rnd.fill(bus.burst, 0, 14)
            g = array("f", [0.0] * 3)
            a = array("f", [0.0] * 3)
            drv.read(g, a)
            c = [_signed(bus.burst[2 * i], bus.burst[2 * i + 1]) for i in range(7)]
            # the driver before: body FRD = (x, -y, -z) of the chip, sign * (count * 16 - bias) * k
            old_g = array("f", ((c[4] * 16 - 5) * k64, -(c[5] * 16 + 77) * k64, -(c[6] * 16) * k64))
            old_a = array("f", (c[0] * ka64, -c[1] * ka64, -c[2] * ka64))
            for new, old in ((g, old_g), (a, old_a)):
                nb = _bits(new)
                ob = _bits(old)
                for i in range(3):
                    d = nb[i] - ob[i]
                    if d < 0:
                        d = -d
                    assert d <= 1, (list(new), list(old))  # same sign: one step is one in the bits
                    if d > worst:
                        worst = d
    assert worst == 1  # it does move some values (so this test can tell)


def _state(drv):
    return (drv.temp_raw, drv.samples, drv.bus_errors, drv.frozen, drv.frozen_count, drv.saturated,
            drv.saturated_count, list(drv._st))


def test_read_method_twins_agree_on_values_counters_and_bus_errors():
    """MPU6050.read (the viper method on MicroPython) against read_python, two drivers fed alike:
    random bursts, repeats (frozen), rails (saturated), bus errors, a general alignment."""
    rnd = Lcg(6)
    for orientation in (Orientation(CW270_FLIP), Orientation(CW0, 0.1, -0.2, 0.3)):
        bus_a, a = _driver(CW0, 1000, 8, (-77, 5, 1234), orientation)
        bus_b, b = _driver(CW0, 1000, 8, (-77, 5, 1234), orientation)
        for k in range(300):
            if k % 40 >= 12:  # else the same burst again: the frozen watch counts
                rnd.fill(bus_a.burst, 0, 14)
                if k % 7 == 0:  # a rail: 0x7FFF, 0x8000 or 0x8001
                    i = 2 * rnd.below(7)
                    bus_a.burst[i:i + 2] = (b"\x7f\xff", b"\x80\x00", b"\x80\x01")[rnd.below(3)]
            bus_b.burst[:] = bus_a.burst
            bus_a.fail = bus_b.fail = k % 53 == 5
            ga, aa = array("f", [3.0] * 3), array("f", [3.0] * 3)
            gb, ab = array("f", [3.0] * 3), array("f", [3.0] * 3)
            assert a.read(ga, aa) == mpu6050.read_python(b, gb, ab)
            assert _bits(ga) == _bits(gb) and _bits(aa) == _bits(ab), k
            assert _state(a) == _state(b), (k, _state(a), _state(b))
        assert a.frozen_count > 0 and a.saturated_count > 0 and a.bus_errors > 0


def test_read_keeps_frozen_saturated_and_bus_error_counts():
    bus, drv = _driver(CW0)
    g = array("f", [0.0] * 3)
    a = array("f", [0.0] * 3)
    bus.burst[:] = _burst_of((100, -200, 2048, 5, 10, -20, 30))
    for k in range(12):
        assert drv.read(g, a)
        assert drv.frozen == (k >= drv.frozen_samples)
    assert drv.frozen_count == 12 - drv.frozen_samples and drv.healthy() is False
    bus.burst[1] ^= 1
    assert drv.read(g, a) and not drv.frozen and drv.healthy()
    bus.burst[:] = _burst_of((100, -200, 2048, 5, 10, -32767, 30))
    assert drv.read(g, a) and drv.saturated and drv.saturated_count == 1
    bus.burst[:] = _burst_of((100, -200, 2048, 5, 10, -32766, 30))
    assert drv.read(g, a) and not drv.saturated and drv.saturated_count == 1
    before = (_bits(g), _bits(a), drv.samples)
    bus.fail = True
    assert not drv.read(g, a)
    assert drv.bus_errors == 1 and (_bits(g), _bits(a), drv.samples) == before
    bus.fail = False
    assert drv.read(g, a) and drv.samples == 12 + 3 + 1
    assert drv.status_name() == "ok"


def test_frozen_samples_is_read_at_each_read():
    bus, drv = _driver(CW0)
    g = array("f", [0.0] * 3)
    a = array("f", [0.0] * 3)
    for _ in range(4):
        drv.read(g, a)
    assert not drv.frozen
    drv.frozen_samples = 3
    drv.read(g, a)
    assert drv.frozen and drv.frozen_count == 1


def test_general_alignment_and_odd_bias_keep_the_python_scaling():
    o = Orientation(CW0, 0.1, -0.2, 0.3)
    bus, drv = _driver(CW0, orientation=o)
    assert drv._st[mpu6050.ST_SCALED] == 0
    bus2, drv2 = _driver(CW90, bias=(mpu6050.BIAS_OFFSET, 0, 0))  # outside the plan
    assert drv2._st[mpu6050.ST_SCALED] == 0
    drv2.set_gyro_bias16(0, 0, 0)
    assert drv2._st[mpu6050.ST_SCALED] == 1
    drv2.set_gyro_bias16(1 << 22, -3, 2)
    rnd = Lcg(2)
    for d, b in ((drv, bus), (drv2, bus2)):
        for _ in range(20):
            rnd.fill(b.burst, 0, 14)
            g = array("f", [0.0] * 3)
            a = array("f", [0.0] * 3)
            assert d.read(g, a)
            wg, wa = _expect(d, b.burst)
            assert _bits(g) == _bits(wg) and _bits(a) == _bits(wa)


def test_unconfigured_driver_reads_zeros_without_raising():
    bus = _Bus()
    drv = mpu6050.MPU6050(bus, Orientation(), delay_us=lambda us: None)
    bus.burst[:] = _burst_of((100, -200, 2048, 5, -10, -20, 30))
    g = array("f", [9.0] * 3)
    a = array("f", [9.0] * 3)
    assert drv.read(g, a)
    assert list(g) == [0.0, 0.0, 0.0] and list(a) == [0.0, 0.0, 0.0]


def test_a_read_allocates_nothing_where_viper_runs():
    bus, drv = _driver(CW0)
    g = array("f", [0.0] * 3)
    a = array("f", [0.0] * 3)
    bursts = [_burst_of((i, -200, 2048, -5, 10, -20, 30 + i)) for i in range(3)]
    k = [0]

    def one():
        k[0] += 1
        bus.burst = bursts[k[0] % 3]
        drv.read(g, a)

    one()
    if mpu6050.MPU6050.read is not mpu6050.read_python:
        assert heap_bytes(one, 50) == 0
        assert drv.temp_raw == -5 and drv.samples == 51
