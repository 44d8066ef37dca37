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

from hoverfly.compat import IS_MICROPYTHON, const
from hoverfly.drivers.imu import (
    DEG_TO_RAD,
    GRAVITY_M_S2,
    STATUS_ABSENT,
    STATUS_BUS_ERROR,
    STATUS_OK,
    STATUS_WRONG_ID,
    Imu,
)

# The burst decode of read()'s axis-map path: a viper twin on MicroPython (accel/mpu6050.py),
# else the Python lines in read(); tested equal. The float scaling stays Python either way.
_decode = None
_viper_plan = None
if IS_MICROPYTHON:
    try:
        from hoverfly.accel.mpu6050 import decode as _decode
        from hoverfly.accel.mpu6050 import plan as _viper_plan
    except (SyntaxError, ImportError, NameError, ValueError):
        _decode = None

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
        self._raw = array("i", [0] * 13)  # the viper decode's output (accel/mpu6050.py decode)
        self._vplan = None
        self._plan_decode()

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
        self._gyro_k16 = DEG_TO_RAD / GYRO_LSB_PER_DPS[fs] / 16.0
        self._accel_k = GRAVITY_M_S2 / ACCEL_LSB_PER_G[afs]
        self.set_gyro_bias16(self._bias16_x, self._bias16_y, self._bias16_z)
        self.status = STATUS_OK
        return True

    def set_gyro_bias16(self, bx16, by16, bz16):
        Imu.set_gyro_bias16(self, bx16, by16, bz16)
        self._plan_decode()

    def _plan_decode(self):
        """read()'s table for a pure axis map (no alignment angles): per body axis, the byte offset
        of its chip axis in the burst, the sign (an int, as Orientation.rotate_scaled applies it)
        and that chip axis's gyro bias. The scales are read at each read(); the rest changes only
        here (construction, configure, a new bias)."""
        o = self._orientation
        self._direct = o.axis_map_only
        self._vplan = None
        if not self._direct:
            return
        m = o.matrix()
        bias = (self._bias16_x, self._bias16_y, self._bias16_z)
        plan = []
        for i in range(3):
            row = m[i]
            j = 0 if row[0] != 0 else (1 if row[1] != 0 else 2)
            plan.append(2 * j)  # accel X/Y/Z_OUT_H at burst bytes 0, 2, 4; gyro 8 bytes on (RM §4.17/4.19)
            plan.append(1 if row[j] > 0 else -1)
            plan.append(bias[j])
        self._plan = tuple(plan)
        if _decode is not None:
            self._vplan = _viper_plan((plan[0], plan[3], plan[6]), (plan[1], plan[4], plan[7]),
                                      (plan[2], plan[5], plan[8]))

    def read(self, gyro_rad_s, accel_m_s2):
        """One 14-byte burst from ACCEL_XOUT_H, decoded by hand, into FRD rad/s and m/s².

        False (arrays untouched) on a bus error, which is counted in bus_errors.
        """
        buf = self._buf
        try:
            self._bus.readfrom_mem_into(self.address, _ACCEL_XOUT_H, buf)
        except OSError:
            self.bus_errors += 1
            return False
        vplan = self._vplan
        if vplan is not None:
            # The viper twin of the lines below: the same ints, into self._raw (accel/mpu6050.py).
            r = self._raw
            _decode(buf, vplan, r)
            self.temp_raw = r[6]
            self._watch(r[3], r[4], r[5], r[0], r[1], r[2])
            k = self._gyro_k16
            gyro_rad_s[0] = r[7] * k
            gyro_rad_s[1] = r[8] * k
            gyro_rad_s[2] = r[9] * k
            k = self._accel_k
            accel_m_s2[0] = r[10] * k
            accel_m_s2[1] = r[11] * k
            accel_m_s2[2] = r[12] * k
            self.samples += 1
            return True
        if self._direct:
            # A pure axis map: each body axis is read from its chip axis's bytes and signed as an int,
            # then scaled: the numbers rotate_scaled gives, without its calls and selections.
            # Big-endian signed 16-bit (RM §4.17-4.19: _H register first): (v ^ 0x8000) - 0x8000.
            o0, s0, b0, o1, s1, b1, o2, s2, b2 = self._plan
            a0 = (((buf[o0] << 8) | buf[o0 + 1]) ^ 0x8000) - 0x8000
            a1 = (((buf[o1] << 8) | buf[o1 + 1]) ^ 0x8000) - 0x8000
            a2 = (((buf[o2] << 8) | buf[o2 + 1]) ^ 0x8000) - 0x8000
            g0 = (((buf[o0 + 8] << 8) | buf[o0 + 9]) ^ 0x8000) - 0x8000
            g1 = (((buf[o1 + 8] << 8) | buf[o1 + 9]) ^ 0x8000) - 0x8000
            g2 = (((buf[o2 + 8] << 8) | buf[o2 + 9]) ^ 0x8000) - 0x8000
            self.temp_raw = (((buf[6] << 8) | buf[7]) ^ 0x8000) - 0x8000
            # Body order: the frozen and saturated tests are the same for any fixed order of the six.
            self._watch(g0, g1, g2, a0, a1, a2)
            k = self._gyro_k16
            gyro_rad_s[0] = s0 * (g0 * 16 - b0) * k
            gyro_rad_s[1] = s1 * (g1 * 16 - b1) * k
            gyro_rad_s[2] = s2 * (g2 * 16 - b2) * k
            k = self._accel_k
            accel_m_s2[0] = s0 * a0 * k
            accel_m_s2[1] = s1 * a1 * k
            accel_m_s2[2] = s2 * a2 * k
            self.samples += 1
            return True
        # Big-endian signed 16-bit (RM §4.17-4.19: _H register first).
        ax = (buf[0] << 8) | buf[1]
        if ax & 0x8000:
            ax -= 0x10000
        ay = (buf[2] << 8) | buf[3]
        if ay & 0x8000:
            ay -= 0x10000
        az = (buf[4] << 8) | buf[5]
        if az & 0x8000:
            az -= 0x10000
        t = (buf[6] << 8) | buf[7]
        if t & 0x8000:
            t -= 0x10000
        gx = (buf[8] << 8) | buf[9]
        if gx & 0x8000:
            gx -= 0x10000
        gy = (buf[10] << 8) | buf[11]
        if gy & 0x8000:
            gy -= 0x10000
        gz = (buf[12] << 8) | buf[13]
        if gz & 0x8000:
            gz -= 0x10000
        self.temp_raw = t
        self._watch(gx, gy, gz, ax, ay, az)
        o = self._orientation
        # Bias in 1/16 LSB keeps sub-LSB calibration without floats; |gx*16| < 2**20.
        o.rotate_scaled(gx * 16 - self._bias16_x, gy * 16 - self._bias16_y, gz * 16 - self._bias16_z,
                        self._gyro_k16, gyro_rad_s)
        o.rotate_scaled(ax, ay, az, self._accel_k, accel_m_s2)
        self.samples += 1
        return True

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
