"""MPU-6050 over I2C: probe, configure, one 14-byte burst per sample, boot gyro calibration.

Takes a `machine.I2C`-style bus (readfrom_mem_into / writeto_mem / readfrom_mem) and an
Orientation; gives body-frame FRD gyro in rad/s and accel in m/s² (level at rest:
accel z ≈ -9.81) into the caller's arrays. Seed 000: 400 kHz, address 0x68, reset via
PWR_MGMT_1 (0x6B), calibration = discard 500 samples then average 500.

Register numbers and values: InvenSense "MPU-6000 and MPU-6050 Register Map and
Descriptions" RM-MPU-6000A-00 rev 4.2 (section numbers below); sensitivities from the
product specification PS-MPU-6000A-00 rev 3.4 §6.1/6.2.
"""

from array import array
from struct import pack, unpack

from hoverfly.compat import IS_MICROPYTHON, const
from hoverfly.core.fastpass.fixedmath import float32_of
from hoverfly.drivers.imu import (
    DEG_TO_RAD,
    GRAVITY_M_S2,
    STATUS_ABSENT,
    STATUS_BUS_ERROR,
    STATUS_OK,
    STATUS_WRONG_ID,
    Imu,
)

# read()'s state: one array('i') holding the plan (configure-time) and the frozen/saturated watch.
ST_OFF = const(0)  # 0..2: body axis k's chip axis as a byte offset in the burst (0/2/4)
ST_FLIP = const(3)  # 3..5: 1 if body axis k is that chip axis negated
ST_BIAS = const(6)  # 6..8: that chip axis's gyro bias in 1/16 LSB, plus BIAS_OFFSET
ST_GYRO_M = const(9)  # gyro scale (rad/s per 1/16 LSB) as float32: mantissa with its hidden bit
ST_GYRO_E = const(10)  # ... and biased exponent
ST_ACCEL_M = const(11)  # accel scale (m/s² per LSB) as float32: mantissa
ST_ACCEL_E = const(12)  # ... and biased exponent
ST_SCALED = const(13)  # 1: the twin writes the floats (axis map); 0: it leaves chip-frame counts in ST_RAW
ST_LAST = const(14)  # 14..19: the last sample's six raw words, chip order (accel x y z, gyro x y z)
ST_SAME = const(20)  # consecutive samples equal to the one before, at most SAME_CAP
ST_PREV = const(21)  # the last read's flags: non-zero if it left frozen/saturated flags to clear
ST_TEMP = const(22)  # TEMP_OUT, signed
ST_RAW = const(23)  # 23..28: signed chip-frame counts, accel x y z, gyro x y z (ST_SCALED 0 only)
ST_SIZE = const(29)
BIAS_OFFSET = const(1048576)  # the plan takes a bias within +-2**20 (calibration gives +-2**19)
SAME_CAP = const(16777216)  # 2**24
# read_burst's result: 0 = nothing to do; else bit 0 = clear the flags, bit 1 = ST_RAW holds
# the counts (Python scales them), bit 2 = saturated, bits 3.. = the same-sample count.
_R_COUNTS = const(2)
_R_SATURATED = const(4)
# The plan's scales as float32 must stay normal and their products finite: 2**-100 .. 2**100.
_K_MIN = 2.0 ** -100
_K_MAX = 2.0 ** 100


# fastpass: MPU6050.read buf:B st:i gyro_rad_s:f@ accel_m_s2:f@
def read_burst(buf, st, gyro_rad_s, accel_m_s2):
    """The burst's watch and decode, MPU6050.read's arithmetic. On MicroPython MPU6050.read is the viper
    generated from read() with this written out in it (accel/mpu6050.py, hoverfly.fastgen): no bytecode
    frame, no float object; tests/portable/test_mpu6050_twins.py holds the two equal bit for bit.

    buf: the 14-byte burst from ACCEL_XOUT_H (big-endian int16, RM §4.17-4.19: _H register first).
    st: MPU6050's array('i') of ST_SIZE (plan, then the watch state). Updates the watch (the same
    six values as the sample before: ST_SAME counts up; a value at +32767 or <= -32767: saturated)
    and ST_TEMP. With ST_SCALED 1 writes body-frame FRD gyro (rad/s) and accel (m/s²): each value
    an integer n times the plan's float32 scale k, n * k rounded once to float32 on every port
    (|n| < 2**21 and k's 24-bit mantissa: a float64 product is exact); with ST_SCALED 0 leaves the
    chip-frame counts in ST_RAW. Returns the flags above (0 on a plain sample).
    """
    same = 1
    sat = 0
    j = ST_LAST
    for i in (0, 2, 4, 8, 10, 12):
        v = (buf[i] << 8) | buf[i + 1]
        if 0x7FFF <= v <= 0x8001:  # +32767, -32768, -32767: pinned at a rail
            sat = 1
        if v != st[j]:
            same = 0
            st[j] = v
        j += 1
    n = 0
    if same:
        n = st[ST_SAME] + 1
        if n > SAME_CAP:
            n = SAME_CAP
    st[ST_SAME] = n
    flags = (n << 3) | (sat << 2)
    st[ST_TEMP] = (((buf[6] << 8) | buf[7]) ^ 0x8000) - 0x8000
    if st[ST_SCALED] == 0:
        j = ST_RAW
        for i in (0, 2, 4, 8, 10, 12):
            st[j] = (((buf[i] << 8) | buf[i + 1]) ^ 0x8000) - 0x8000
            j += 1
        flags |= _R_COUNTS
    else:
        kg = float32_of(st[ST_GYRO_M], st[ST_GYRO_E])
        ka = float32_of(st[ST_ACCEL_M], st[ST_ACCEL_E])
        for axis in range(3):
            off = st[ST_OFF + axis]
            a = (((buf[off] << 8) | buf[off + 1]) ^ 0x8000) - 0x8000
            g = ((((buf[off + 8] << 8) | buf[off + 9]) ^ 0x8000) - 0x8000) * 16 - (st[ST_BIAS + axis] - BIAS_OFFSET)
            if st[ST_FLIP + axis]:
                a = -a
                g = -g
            accel_m_s2[axis] = a * ka
            gyro_rad_s[axis] = g * kg
    if flags == 0 and st[ST_PREV] != 0:
        st[ST_PREV] = 0
        return 1
    st[ST_PREV] = flags
    return flags


def float32_parts(k):
    """(mantissa with its hidden bit, biased exponent) of float32(k); None unless _K_MIN < k < _K_MAX."""
    if not (_K_MIN < k < _K_MAX):  # NaN too
        return None
    b = unpack("<I", pack("<f", k))[0]
    return (b & 0x7FFFFF) | 0x800000, (b >> 23) & 0xFF




def float32(x):
    """x rounded to float32 (the identity on a float32 port)."""
    return array("f", (x,))[0]


# On MicroPython the viper MPU6050.read generated from read() and read_burst (accel/mpu6050.py) and its
# address table's writer; else None and the Python read below. Tested equal.
_viper = None
if IS_MICROPYTHON:
    try:  # absent (never generated) or a port without viper: the Python read runs
        from hoverfly.accel import mpu6050 as _viper
    except (ImportError, SyntaxError, NameError, ValueError, TypeError):  # TypeError: ViperTypeError
        pass
_read = _viper.read if _viper is not None else None
_bind = _viper.bind if _viper is not None else None

ADDRESS = 0x68  # AD0 low (RM §4.32 WHO_AM_I note; seed 000)
ADDRESS_ALT = 0x69  # AD0 high
WHO_AM_I_VALUE = 0x68  # RM §4.32: bits 6:1 = 0x34, reads 0x68 regardless of AD0

_SMPLRT_DIV = const(0x19)  # RM §4.2, 25
_CONFIG = const(0x1A)  # RM §4.3, 26: DLPF_CFG bits 2:0
_GYRO_CONFIG = const(0x1B)  # RM §4.4, 27: FS_SEL bits 4:3
_ACCEL_CONFIG = const(0x1C)  # RM §4.5, 28: AFS_SEL bits 4:3
_ACCEL_XOUT_H = const(0x3B)  # RM §4.17, 59: accel X/Y/Z, TEMP, gyro X/Y/Z = 14 bytes to 0x48
_GYRO_XOUT_H = const(0x43)  # RM §4.19, 67
_PWR_MGMT_1 = const(0x6B)  # RM §4.28, 107: DEVICE_RESET bit 7, SLEEP bit 6, CLKSEL 2:0
_WHO_AM_I = const(0x75)  # RM §4.32, 117

_DEVICE_RESET = const(0x80)  # RM §4.28: resets all registers; bit clears itself
_CLKSEL_PLL_XGYRO = const(0x01)  # RM §4.28: PLL with X gyro reference (recommended over 8 MHz RC), SLEEP = 0
_RESET_WAIT_US = const(100000)  # RM §4.28/PS: wait 100 ms after DEVICE_RESET before the next write

# RM §4.4 FS_SEL 0..3 and PS §6.1 sensitivity (seed 000's table): LSB per °/s.
GYRO_RANGES_DPS = (250, 500, 1000, 2000)
GYRO_LSB_PER_DPS = (131.0, 65.5, 32.8, 16.4)
# RM §4.5 AFS_SEL 0..3 and PS §6.2: LSB per g.
ACCEL_RANGES_G = (2, 4, 8, 16)
ACCEL_LSB_PER_G = (16384.0, 8192.0, 4096.0, 2048.0)
# RM §4.3 DLPF_CFG 0..6: gyro bandwidth in Hz (accel 260/184/94/44/21/10/5).
# Gyro output rate is 8 kHz with DLPF_CFG 0 (or 7), 1 kHz otherwise; accel is always 1 kHz.
DLPF_HZ = (256, 188, 98, 42, 20, 10, 5)


def _index(table, value, what):
    for i in range(len(table)):
        if table[i] == value:
            return i
    raise ValueError("%s %r not supported (one of %r)" % (what, value, table))


class MPU6050(Imu):
    """InvenSense MPU-6050 over I2C (see the module docstring)."""

    name = "mpu6050"

    def __init__(self, bus, orientation, address=ADDRESS, delay_us=None):
        Imu.__init__(self, orientation, delay_us)
        self._bus = bus
        self.address = address
        self._buf = bytearray(14)
        self._gbuf = bytearray(6)
        self._one = bytearray(1)
        self.temp_raw = 0
        self.rate_hz = 0
        self._raw_gx = self._raw_gy = self._raw_gz = 0
        self._st = array("i", [0] * ST_SIZE)  # read_burst's plan and watch state (ST_*)
        if _bind is not None:
            # the viper read's table of _buf's and _st's addresses: MicroPython's collector never
            # moves an object, and these two are never replaced or resized while the driver lives
            self._tab = array("i", [0] * _viper.TAB_SIZE)
            _bind(self._tab, 0, self._buf)
            _bind(self._tab, 1, self._st)
            _bind(self._tab, 2, _viper.LOG2)
        self._plan()

    def probe(self):
        """True if an MPU-6050 answers WHO_AM_I; otherwise False with status ABSENT / WRONG_ID."""
        try:
            self._bus.readfrom_mem_into(self.address, _WHO_AM_I, self._one)
        except OSError:
            self.bus_errors += 1
            self.status = STATUS_ABSENT
            return False
        self.who_am_i = self._one[0]
        if self.who_am_i != WHO_AM_I_VALUE:
            self.status = STATUS_WRONG_ID
            return False
        self.status = STATUS_OK
        return True

    def register_plan(self, gyro_range_dps=2000, accel_range_g=16, dlpf_hz=98, rate_hz=1000):
        """The (register, value) writes configure() makes after the reset, in order."""
        fs = _index(GYRO_RANGES_DPS, gyro_range_dps, "gyro range (dps)")
        afs = _index(ACCEL_RANGES_G, accel_range_g, "accel range (g)")
        cfg = _index(DLPF_HZ, dlpf_hz, "DLPF bandwidth (Hz)")
        base_hz = 8000 if cfg == 0 else 1000  # RM §4.2: gyro output rate
        if rate_hz <= 0 or base_hz % rate_hz or base_hz // rate_hz > 256:
            raise ValueError("rate_hz must divide %d Hz (DLPF %d Hz)" % (base_hz, dlpf_hz))
        div = base_hz // rate_hz - 1  # RM §4.2: rate = gyro output rate / (1 + SMPLRT_DIV)
        return (
            (_PWR_MGMT_1, _CLKSEL_PLL_XGYRO),
            (_SMPLRT_DIV, div),
            (_CONFIG, cfg),
            (_GYRO_CONFIG, fs << 3),
            (_ACCEL_CONFIG, afs << 3),
        )

    def configure(self, gyro_range_dps=2000, accel_range_g=16, dlpf_hz=98, rate_hz=1000):
        """Reset, wake on the PLL clock, set rate, DLPF and ranges. False if the chip is not there.

        ValueError for a range/bandwidth the chip does not have (a programming error).
        """
        plan = self.register_plan(gyro_range_dps, accel_range_g, dlpf_hz, rate_hz)
        if not self.probe():
            return False
        try:
            self._bus.writeto_mem(self.address, _PWR_MGMT_1, bytes((_DEVICE_RESET,)))
            self._delay_us(_RESET_WAIT_US)
            for reg, value in plan:
                self._bus.writeto_mem(self.address, reg, bytes((value,)))
        except OSError:
            self.bus_errors += 1
            self.status = STATUS_BUS_ERROR
            return False
        fs = _index(GYRO_RANGES_DPS, gyro_range_dps, "")
        afs = _index(ACCEL_RANGES_G, accel_range_g, "")
        self.gyro_range_dps = gyro_range_dps
        self.accel_range_g = accel_range_g
        self.rate_hz = rate_hz
        # The scales as float32, what the chip's floats hold: a count times them is then exact in a
        # float64, so the arrays get the same one rounding on every port (read_burst).
        self._gyro_k16 = float32(DEG_TO_RAD / GYRO_LSB_PER_DPS[fs] / 16.0)
        self._accel_k = float32(GRAVITY_M_S2 / ACCEL_LSB_PER_G[afs])
        self.set_gyro_bias16(self._bias16_x, self._bias16_y, self._bias16_z)
        self.status = STATUS_OK
        return True

    def set_gyro_bias16(self, bx16, by16, bz16):
        Imu.set_gyro_bias16(self, bx16, by16, bz16)
        self._plan()

    def _plan(self):
        """read_burst's plan (ST_OFF..ST_SCALED), from the orientation, the scales and the bias:
        construction, configure and a new bias set it; the watch state is kept. For a pure axis
        map (no alignment angles), per body axis the byte offset of its chip axis in the burst, its
        sign and that chip axis's bias, and the scales as float32 parts: the twin writes the floats.
        Otherwise, or for a scale or bias the plan cannot hold, it leaves the counts and read()
        scales them through Orientation.rotate_scaled."""
        st = self._st
        st[ST_SCALED] = 0
        o = self._orientation
        if not o.axis_map_only:
            return
        gk = float32_parts(self._gyro_k16)
        ak = float32_parts(self._accel_k)
        bias = (self._bias16_x, self._bias16_y, self._bias16_z)
        if gk is None or ak is None:
            return
        for b in bias:
            if not isinstance(b, int) or b <= -BIAS_OFFSET or b >= BIAS_OFFSET:
                return
        m = o.matrix()
        for i in range(3):
            row = m[i]
            j = 0 if row[0] != 0 else (1 if row[1] != 0 else 2)
            st[ST_OFF + i] = 2 * j  # accel X/Y/Z_OUT_H at burst bytes 0, 2, 4 (RM §4.17)
            st[ST_FLIP + i] = 1 if row[j] < 0 else 0
            st[ST_BIAS + i] = bias[j] + BIAS_OFFSET
        st[ST_GYRO_M] = gk[0]
        st[ST_GYRO_E] = gk[1]
        st[ST_ACCEL_M] = ak[0]
        st[ST_ACCEL_E] = ak[1]
        st[ST_SCALED] = 1

    def read(self, gyro_rad_s, accel_m_s2):
        """One 14-byte burst from ACCEL_XOUT_H into FRD rad/s and m/s² (array('f')s of 3).

        False (arrays untouched) on a bus error, which is counted in bus_errors.
        """
        # On MicroPython the viper generated from this method and read_burst (accel/mpu6050.py `read`)
        # stands in for it (no bytecode frame: this one's 12 words would be taken from the heap at every
        # call, py/objfun.c VM_MAX_STATE_ON_STACK); `read_python` keeps it.
        try:
            self._bus.readfrom_mem_into(self.address, _ACCEL_XOUT_H, self._buf)
        except OSError:
            self.bus_errors += 1
            return False
        if read_burst(self._buf, self._st, gyro_rad_s, accel_m_s2):
            self._finish(gyro_rad_s, accel_m_s2)
        self.temp_raw = self._st[ST_TEMP]
        self.samples += 1
        return True

    def _finish(self, gyro_rad_s, accel_m_s2):
        """read()'s rare half: the flags of a frozen, saturated or just-recovered sample, and the
        scaling read_burst left to Python (a general alignment, or a plan it could not hold)."""
        st = self._st
        r = st[ST_PREV]  # read_burst's flags (0 when it asked for the flags to be cleared)
        if r & _R_COUNTS:
            o = self._orientation
            # Bias in 1/16 LSB keeps sub-LSB calibration without floats; |gx*16| < 2**20.
            o.rotate_scaled(st[ST_RAW + 3] * 16 - self._bias16_x, st[ST_RAW + 4] * 16 - self._bias16_y,
                            st[ST_RAW + 5] * 16 - self._bias16_z, self._gyro_k16, gyro_rad_s)
            o.rotate_scaled(st[ST_RAW], st[ST_RAW + 1], st[ST_RAW + 2], self._accel_k, accel_m_s2)
        same = r >> 3
        frozen = same > 0 and same >= self.frozen_samples
        self.frozen = frozen
        if frozen:
            self.frozen_count += 1
        saturated = (r & _R_SATURATED) != 0
        self.saturated = saturated
        if saturated:
            self.saturated_count += 1

    def temperature_c(self):
        """Die temperature of the newest sample: RM §4.18, TEMP_OUT / 340 + 36.53."""
        return self.temp_raw / 340.0 + 36.53

    def _read_gyro_raw(self):
        b = self._gbuf
        try:
            self._bus.readfrom_mem_into(self.address, _GYRO_XOUT_H, b)
        except OSError:
            self.bus_errors += 1
            return False
        v = (b[0] << 8) | b[1]
        self._raw_gx = v - 0x10000 if v & 0x8000 else v
        v = (b[2] << 8) | b[3]
        self._raw_gy = v - 0x10000 if v & 0x8000 else v
        v = (b[4] << 8) | b[5]
        self._raw_gz = v - 0x10000 if v & 0x8000 else v
        return True

    def calibrate(self, samples=500, discard=500, still_dps=4.0, sample_delay_us=1000):
        """Seed 000 boot calibration; see Imu.calibrate_gyro. True if it stayed still."""
        return self.calibrate_gyro(samples, discard, still_dps, sample_delay_us)


read_python = MPU6050.read
if _read is not None:
    MPU6050.read = _read
