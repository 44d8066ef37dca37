"""BNO055 over I2C: the chip's own fusion (NDOF / IMU mode), raw gyro/accel and attitude.

Takes a `machine.I2C`-style bus and an Orientation (chip axes to body FRD); gives body
FRD gyro in rad/s and accel in m/s² (`read`), and the attitude quaternion body -> NED
(`read_attitude(q_out)`, w x y z) for estimator = external. Seed 001: the first roll and
pitch measured are taken as the IMU offset so the frame reads level at boot;
`reset_offset()` re-arms that (maintenance command 24).

Attitude mapping (why the maths in read_attitude looks the way it does): the BNO055's
fusion quaternion q_ws turns chip-frame vectors into its own earth frame, which is z up
(gravity along -z, the same sense as its accelerometer). We read that frame as
world-up = (N, -E, -D) with an arbitrary heading origin (magnetic north in NDOF, the
start heading in IMU mode), so F = 180° about x takes it to NED, and
q_body_to_NED = qF ⊗ q_ws ⊗ conj(q_mount) ⊗ conj(q_offset). Only roll and pitch are made
relative by the offset; heading keeps the chip's reference. We use the quaternion, not
the chip's Euler registers: those follow the Windows/Android sign choice of UNIT_SEL
and limit roll to ±90°.

Register numbers and scales: Bosch BST-BNO055-DS000 (datasheet rev 1.4/1.8) §4.3
register map, §3.6.4 unit tables, §3.3 operating modes (mode switching times).
"""

import math

from hoverfly.compat import const
from hoverfly.drivers.imu import (
    STATUS_ABSENT,
    STATUS_BUS_ERROR,
    STATUS_NOT_READY,
    STATUS_OK,
    STATUS_WRONG_ID,
    Imu,
)

ADDRESS = 0x28  # COM3 low (datasheet §4.6 I2C address selection)
ADDRESS_ALT = 0x29  # COM3 high (the Adafruit breakout default)
CHIP_ID_VALUE = 0xA0  # register map (§4.3) CHIP_ID reset value

MODE_CONFIG = 0x00  # §3.3 OPR_MODE values
MODE_IMU = 0x08  # fusion of accel + gyro, relative heading
MODE_NDOF = 0x0C  # fusion of accel + gyro + magnetometer, absolute heading

_CHIP_ID = const(0x00)  # register map (§4.3)
_PAGE_ID = const(0x07)  # register map (§4.3)
# register map (§4.3): ACC 0x08-0x0D, MAG 0x0E-0x13, GYR 0x14-0x19, little-endian
_ACC_DATA_X_LSB = const(0x08)
_QUA_DATA_W_LSB = const(0x20)  # register map (§4.3): w, x, y, z 0x20-0x27
_CALIB_STAT = const(0x35)  # register map (§4.3)
_SYS_STATUS = const(0x39)  # register map (§4.3): 5 = sensor fusion algorithm running
_SYS_ERR = const(0x3A)  # register map (§4.3)
_UNIT_SEL = const(0x3B)  # register map (§4.3)
_OPR_MODE = const(0x3D)  # register map (§4.3)
_PWR_MODE = const(0x3E)  # register map (§4.3): 0 = normal
_SYS_TRIGGER = const(0x3F)  # register map (§4.3): RST_SYS bit 5

_RST_SYS = const(0x20)
# UNIT_SEL: accel m/s² (bit0 = 0), gyro rad/s (bit1 = 1), Euler radians (bit2 = 1),
# temperature °C (bit4 = 0), Windows orientation (bit7 = 0).
_UNIT_SEL_SI = const(0x06)
_SYS_RUNNING_FUSION = const(5)

_TO_CONFIG_US = const(19000)  # §3.3 mode switching times: any mode -> CONFIGMODE 19 ms
_FROM_CONFIG_US = const(7000)  # §3.3 mode switching times: CONFIGMODE -> any mode 7 ms
_POR_US = const(650000)  # §1 (electrical characteristics): power-on / reset to config mode 650 ms

_ACCEL_M_S2_PER_LSB = 0.01  # §3.6.4 units: 1 m/s² = 100 LSB
_GYRO_RAD_S_PER_LSB = 1.0 / 900.0  # §3.6.4 units: 1 rps = 900 LSB
_MAG_UT_PER_LSB = 1.0 / 16.0  # §3.6.4 units: 1 µT = 16 LSB
_QUAT_PER_LSB = 1.0 / 16384.0  # §3.6.5 quaternion output: 1 quaternion unit = 2^14 LSB


class BNO055(Imu):
    """Bosch BNO055 absolute-orientation IMU over I2C (see the module docstring)."""

    name = "bno055"

    def __init__(self, bus, orientation, address=ADDRESS, delay_us=None, capture_offset=True):
        Imu.__init__(self, orientation, delay_us)
        self._bus = bus
        self.address = address
        self._buf = bytearray(18)
        self._qbuf = bytearray(8)
        self._one = bytearray(1)
        self.mode = MODE_CONFIG
        self.bad_quaternions = 0
        self.mag_ut = [0.0, 0.0, 0.0]  # body frame, filled by read()
        # The chip range in fusion modes is fixed by the chip (gyro 2000 dps, accel 4 g auto).
        self.gyro_range_dps = 2000
        self.accel_range_g = 16
        self._gyro_k16 = _GYRO_RAD_S_PER_LSB / 16.0
        self._accel_k = _ACCEL_M_S2_PER_LSB
        qm = orientation.quaternion()
        # conj(q_mount): body -> chip.
        self._mw = qm[0]
        self._mx = -qm[1]
        self._my = -qm[2]
        self._mz = -qm[3]
        self.capture_offset = capture_offset
        self.offset_roll_rad = 0.0
        self.offset_pitch_rad = 0.0
        self._offset_pending = capture_offset
        self._set_right(1.0, 0.0, 0.0, 0.0)

    def _set_right(self, ow, ox, oy, oz):
        """r = conj(q_mount) ⊗ conj(q_offset), given q_offset = (ow, ox, oy, oz)."""
        aw, ax, ay, az = self._mw, self._mx, self._my, self._mz
        bw, bx, by, bz = ow, -ox, -oy, -oz
        self._rw = aw * bw - ax * bx - ay * by - az * bz
        self._rx = aw * bx + ax * bw + ay * bz - az * by
        self._ry = aw * by - ax * bz + ay * bw + az * bx
        self._rz = aw * bz + ax * by - ay * bx + az * bw

    def probe(self):
        """True if CHIP_ID reads 0xA0; otherwise False with status ABSENT / WRONG_ID."""
        try:
            self._bus.readfrom_mem_into(self.address, _CHIP_ID, self._one)
        except OSError:
            self.bus_errors += 1
            self.status = STATUS_ABSENT
            return False
        self.who_am_i = self._one[0]
        if self.who_am_i != CHIP_ID_VALUE:
            self.status = STATUS_WRONG_ID
            return False
        self.status = STATUS_OK
        return True

    def register_plan(self, mode=MODE_NDOF):
        """The (register, value) writes after the reset, in order (OPR_MODE last)."""
        if mode not in (MODE_IMU, MODE_NDOF):
            raise ValueError("BNO055 mode must be MODE_IMU (0x08) or MODE_NDOF (0x0C)")
        return ((_PWR_MODE, 0x00), (_PAGE_ID, 0x00), (_UNIT_SEL, _UNIT_SEL_SI), (_OPR_MODE, mode))

    def configure(self, mode=MODE_NDOF, reset=True):
        """CONFIGMODE, optional system reset, normal power, SI units, then the fusion mode.

        False if the chip is absent/wrong, a transfer fails, or fusion does not report
        running (SYS_STATUS != 5, status NOT_READY). Blocks ~0.7 s with reset (boot only).
        """
        plan = self.register_plan(mode)
        if not self.probe():
            return False
        bus = self._bus
        a = self.address
        try:
            bus.writeto_mem(a, _OPR_MODE, bytes((MODE_CONFIG,)))
            self._delay_us(_TO_CONFIG_US)
            if reset:
                bus.writeto_mem(a, _SYS_TRIGGER, bytes((_RST_SYS,)))
                self._delay_us(_POR_US)
                if not self._wait_chip_id():
                    return False
            for i in range(len(plan)):
                reg, value = plan[i]
                bus.writeto_mem(a, reg, bytes((value,)))
            self._delay_us(_FROM_CONFIG_US)
            bus.readfrom_mem_into(a, _SYS_STATUS, self._one)
        except OSError:
            self.bus_errors += 1
            self.status = STATUS_BUS_ERROR
            return False
        if self._one[0] != _SYS_RUNNING_FUSION:
            self.status = STATUS_NOT_READY
            return False
        self.mode = mode
        self.status = STATUS_OK
        return True

    def _wait_chip_id(self):
        # After RST_SYS the chip does not answer until it has booted; poll for up to ~1 s more.
        for _ in range(100):
            try:
                self._bus.readfrom_mem_into(self.address, _CHIP_ID, self._one)
                if self._one[0] == CHIP_ID_VALUE:
                    return True
            except OSError:
                pass
            self._delay_us(10000)
        self.status = STATUS_NOT_READY
        return False

    def read_status(self):
        """(SYS_STATUS, SYS_ERR, CALIB_STAT) bytes for the built-in test; None on a bus error."""
        try:
            s = self._bus.readfrom_mem(self.address, _SYS_STATUS, 2)
            c = self._bus.readfrom_mem(self.address, _CALIB_STAT, 1)
        except OSError:
            self.bus_errors += 1
            return None
        return (s[0], s[1], c[0])

    def read(self, gyro_rad_s, accel_m_s2):
        """One 18-byte burst (accel, mag, gyro) into FRD rad/s and m/s²; mag into self.mag_ut.

        False (arrays untouched) on a bus error, counted in bus_errors.
        """
        buf = self._buf
        try:
            self._bus.readfrom_mem_into(self.address, _ACC_DATA_X_LSB, buf)
        except OSError:
            self.bus_errors += 1
            return False
        # Little-endian signed 16-bit (LSB register first).
        ax = (buf[1] << 8) | buf[0]
        if ax & 0x8000:
            ax -= 0x10000
        ay = (buf[3] << 8) | buf[2]
        if ay & 0x8000:
            ay -= 0x10000
        az = (buf[5] << 8) | buf[4]
        if az & 0x8000:
            az -= 0x10000
        mx = (buf[7] << 8) | buf[6]
        if mx & 0x8000:
            mx -= 0x10000
        my = (buf[9] << 8) | buf[8]
        if my & 0x8000:
            my -= 0x10000
        mz = (buf[11] << 8) | buf[10]
        if mz & 0x8000:
            mz -= 0x10000
        gx = (buf[13] << 8) | buf[12]
        if gx & 0x8000:
            gx -= 0x10000
        gy = (buf[15] << 8) | buf[14]
        if gy & 0x8000:
            gy -= 0x10000
        gz = (buf[17] << 8) | buf[16]
        if gz & 0x8000:
            gz -= 0x10000
        self._watch(gx, gy, gz, ax, ay, az)
        o = self._orientation
        o.rotate_scaled(gx * 16 - self._bias16_x, gy * 16 - self._bias16_y, gz * 16 - self._bias16_z,
                        self._gyro_k16, gyro_rad_s)
        o.rotate_scaled(ax, ay, az, _ACCEL_M_S2_PER_LSB, accel_m_s2)
        o.rotate_scaled(mx, my, mz, _MAG_UT_PER_LSB, self.mag_ut)
        self.samples += 1
        return True

    def read_attitude(self, q_out):
        """Fusion quaternion as body -> NED (w, x, y, z, w >= 0) into q_out[0..3].

        False (q_out untouched) on a bus error, or while the chip reports no quaternion
        (all zero, or a norm off by more than 2 %: counted in bad_quaternions).
        """
        b = self._qbuf
        try:
            self._bus.readfrom_mem_into(self.address, _QUA_DATA_W_LSB, b)
        except OSError:
            self.bus_errors += 1
            return False
        w = (b[1] << 8) | b[0]
        if w & 0x8000:
            w -= 0x10000
        x = (b[3] << 8) | b[2]
        if x & 0x8000:
            x -= 0x10000
        y = (b[5] << 8) | b[4]
        if y & 0x8000:
            y -= 0x10000
        z = (b[7] << 8) | b[6]
        if z & 0x8000:
            z -= 0x10000
        k = _QUAT_PER_LSB
        qw = w * k
        qx = x * k
        qy = y * k
        qz = z * k
        n2 = qw * qw + qx * qx + qy * qy + qz * qz
        if n2 < 0.96 or n2 > 1.04:
            self.bad_quaternions += 1
            return False
        if self._offset_pending:
            self._capture(qw, qx, qy, qz)
        # p = q_ws ⊗ r
        rw = self._rw
        rx = self._rx
        ry = self._ry
        rz = self._rz
        pw = qw * rw - qx * rx - qy * ry - qz * rz
        px = qw * rx + qx * rw + qy * rz - qz * ry
        py = qw * ry - qx * rz + qy * rw + qz * rx
        pz = qw * rz + qx * ry - qy * rx + qz * rw
        # qF ⊗ p with qF = (0, 1, 0, 0): (-px, pw, -pz, py)
        inv = 1.0 / math.sqrt(n2)
        if px > 0.0:
            inv = -inv  # keep w >= 0
        q_out[0] = -px * inv
        q_out[1] = pw * inv
        q_out[2] = -pz * inv
        q_out[3] = py * inv
        return True

    def _capture(self, qw, qx, qy, qz):
        """Seed 001: take the present roll/pitch as the mounting offset (boot only)."""
        # Attitude without offset: qF ⊗ q_ws ⊗ conj(q_mount).
        aw, ax, ay, az = self._mw, self._mx, self._my, self._mz
        pw = qw * aw - qx * ax - qy * ay - qz * az
        px = qw * ax + qx * aw + qy * az - qz * ay
        py = qw * ay - qx * az + qy * aw + qz * ax
        pz = qw * az + qx * ay - qy * ax + qz * aw
        w, x, y, z = -px, pw, -pz, py
        roll, pitch = roll_pitch_from_quaternion(w, x, y, z)
        self.offset_roll_rad = roll
        self.offset_pitch_rad = pitch
        # q_offset = Ry(pitch) ⊗ Rx(roll)
        cr = math.cos(roll * 0.5)
        sr = math.sin(roll * 0.5)
        cp = math.cos(pitch * 0.5)
        sp = math.sin(pitch * 0.5)
        self._set_right(cp * cr, cp * sr, sp * cr, -sp * sr)
        self._offset_pending = False

    def reset_offset(self):
        """Take the next attitude's roll/pitch as the new offset (seed 001 'Reset IMU offset')."""
        self._set_right(1.0, 0.0, 0.0, 0.0)
        self.offset_roll_rad = 0.0
        self.offset_pitch_rad = 0.0
        self._offset_pending = True

    def clear_offset(self):
        """No offset at all: the chip's attitude as mounted."""
        self._set_right(1.0, 0.0, 0.0, 0.0)
        self.offset_roll_rad = 0.0
        self.offset_pitch_rad = 0.0
        self._offset_pending = False

    def _read_gyro_raw(self):
        b = self._buf
        try:
            self._bus.readfrom_mem_into(self.address, _ACC_DATA_X_LSB, b)
        except OSError:
            self.bus_errors += 1
            return False
        v = (b[13] << 8) | b[12]
        self._raw_gx = v - 0x10000 if v & 0x8000 else v
        v = (b[15] << 8) | b[14]
        self._raw_gy = v - 0x10000 if v & 0x8000 else v
        v = (b[17] << 8) | b[16]
        self._raw_gz = v - 0x10000 if v & 0x8000 else v
        return True


def roll_pitch_from_quaternion(w, x, y, z):
    """ZYX Euler roll and pitch (radians) of a body -> NED quaternion."""
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    s = 2.0 * (w * y - z * x)
    if s > 1.0:
        s = 1.0
    elif s < -1.0:
        s = -1.0
    return roll, math.asin(s)
