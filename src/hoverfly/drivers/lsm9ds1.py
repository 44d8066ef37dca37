"""LSM9DS1 over I2C: gyro + accel from the AG part in one burst, optional magnetometer.

Takes a `machine.I2C`-style bus and an Orientation (AG chip axes to body FRD); gives
body FRD gyro in rad/s and accel in m/s² (`read`), magnetic field in µT (`read_mag`).
Seed 001 lists it beside the BNO055 and MPU6050.

One burst per sample: 22 bytes from OUT_X_L_G (0x18) to OUT_Z_H_XL (0x2D) with
IF_ADD_INC, gyro at bytes 0-5 and accel at bytes 16-21 (the 10 control/status bytes in
between are read and ignored: one transfer is cheaper than two on I2C). With the gyro
on, the accelerometer runs at the gyro's ODR (datasheet: CTRL_REG6_XL / gyro+accel operating mode), so
both halves belong to the same sample; BDU keeps high and low bytes together.

Numbers: ST LSM9DS1 datasheet DocID025715 (rev 3): Table 3 sensitivities, §6.1.1 I2C
addresses/auto-increment, AG and magnetometer register descriptions.
"""

from hoverfly.compat import const
from hoverfly.drivers.imu import (
    GRAVITY_M_S2,
    STATUS_ABSENT,
    STATUS_BUS_ERROR,
    STATUS_OK,
    STATUS_WRONG_ID,
    Imu,
)

AG_ADDRESS = 0x6B  # SDO_A/G high (§6.1.1); 0x6A with it low
AG_ADDRESS_ALT = 0x6A
MAG_ADDRESS = 0x1E  # SDO_M high; 0x1C with it low
MAG_ADDRESS_ALT = 0x1C
WHO_AM_I_AG_VALUE = 0x68  # AG register WHO_AM_I (0x0F) value
WHO_AM_I_M_VALUE = 0x3D  # magnetometer WHO_AM_I_M (0x0F) value

_WHO_AM_I = const(0x0F)  # same address on both parts
_CTRL_REG1_G = const(0x10)  # ODR_G 7:5, FS_G 4:3, BW_G 1:0
_OUT_X_L_G = const(0x18)
_CTRL_REG4 = const(0x1E)  # gyro Z/Y/X enable bits 5:3
_CTRL_REG5_XL = const(0x1F)  # accel Z/Y/X enable bits 5:3
_CTRL_REG6_XL = const(0x20)  # ODR_XL 7:5, FS_XL 4:3
_CTRL_REG8 = const(0x22)  # BOOT 7, BDU 6, IF_ADD_INC 2, SW_RESET 0
_OUT_X_L_XL = const(0x28)
_ACCEL_OFFSET = const(0x10)  # OUT_X_L_XL - OUT_X_L_G inside the burst
_BURST = const(22)  # 0x18 .. 0x2D

_CTRL_REG1_M = const(0x20)  # TEMP_COMP 7, OM 6:5, DO 4:2
_CTRL_REG2_M = const(0x21)  # FS 6:5, SOFT_RST 2
_CTRL_REG3_M = const(0x22)  # MD 1:0 (00 = continuous conversion)
_CTRL_REG4_M = const(0x23)  # OMZ 3:2
_CTRL_REG5_M = const(0x24)  # BDU 6
_OUT_X_L_M = const(0x28)
_MAG_AUTO_INC = const(0x80)  # §6.1.1: sub-address MSB set = auto-increment (magnetometer)

_SW_RESET_AG = const(0x05)  # SW_RESET + keep IF_ADD_INC
_BDU_ADD_INC = const(0x44)  # BDU + IF_ADD_INC
_XYZ_ON = const(0x38)
_RESET_WAIT_US = const(10000)
_MAG_SOFT_RST = const(0x0C)  # SOFT_RST (bit 2) + REBOOT (bit 3)
_MAG_UHP_80HZ = const(0xFC)  # TEMP_COMP, X/Y ultra-high-performance, 80 Hz
_MAG_Z_UHP = const(0x0C)
_MAG_BDU = const(0x40)

GYRO_RANGES_DPS = (245, 500, 2000)
_FS_G_CODE = (0, 1, 3)  # FS_G 10 is "not available"
GYRO_MDPS_PER_LSB = (8.75, 17.5, 70.0)  # Table 3, G_So
ACCEL_RANGES_G = (2, 4, 8, 16)
_FS_XL_CODE = (0, 2, 3, 1)  # FS_XL: 00 ±2 g, 10 ±4 g, 11 ±8 g, 01 ±16 g
ACCEL_MG_PER_LSB = (0.061, 0.122, 0.244, 0.732)  # Table 3, LA_So
MAG_RANGES_GAUSS = (4, 8, 12, 16)
MAG_MGAUSS_PER_LSB = (0.14, 0.29, 0.43, 0.58)  # Table 3, M_GN
# CTRL_REG1_G ODR_G codes 1..6 (CTRL_REG1_G description).
ODR_HZ = (14.9, 59.5, 119, 238, 476, 952)
# The magnetometer x axis points against the AG x axis (Figure 1, pin-indicator axes);
# y and z agree. Applied before the orientation so read_mag() is in the AG/body frame.
MAG_AXIS_SIGNS = (-1, 1, 1)


def _index(table, value, what):
    for i in range(len(table)):
        if table[i] == value:
            return i
    raise ValueError("%s %r not supported (one of %r)" % (what, value, table))


class LSM9DS1(Imu):
    """ST LSM9DS1 9-axis IMU over I2C (see the module docstring)."""

    name = "lsm9ds1"

    def __init__(self, bus, orientation, address=AG_ADDRESS, mag_address=MAG_ADDRESS, delay_us=None):
        Imu.__init__(self, orientation, delay_us)
        self._bus = bus
        self.address = address
        self.mag_address = mag_address
        self._buf = bytearray(_BURST)
        self._gbuf = bytearray(6)
        self._mbuf = bytearray(6)
        self._one = bytearray(1)
        self.mag_present = False
        self.mag_who_am_i = -1
        self.odr_hz = 0
        self._mag_k = 0.0
        self._raw_gx = self._raw_gy = self._raw_gz = 0

    def _who(self, address):
        self._bus.readfrom_mem_into(address, _WHO_AM_I, self._one)
        return self._one[0]

    def probe(self):
        """True if the AG part answers WHO_AM_I 0x68 (the magnetometer is optional)."""
        try:
            self.who_am_i = self._who(self.address)
        except OSError:
            self.bus_errors += 1
            self.status = STATUS_ABSENT
            return False
        if self.who_am_i != WHO_AM_I_AG_VALUE:
            self.status = STATUS_WRONG_ID
            return False
        self.status = STATUS_OK
        return True

    def register_plan(self, gyro_range_dps=2000, accel_range_g=16, odr_hz=952):
        """AG (register, value) writes after the reset, in order."""
        fs = _FS_G_CODE[_index(GYRO_RANGES_DPS, gyro_range_dps, "gyro range (dps)")]
        afs = _FS_XL_CODE[_index(ACCEL_RANGES_G, accel_range_g, "accel range (g)")]
        odr = _index(ODR_HZ, odr_hz, "ODR (Hz)") + 1
        return (
            (_CTRL_REG8, _BDU_ADD_INC),
            (_CTRL_REG4, _XYZ_ON),
            (_CTRL_REG5_XL, _XYZ_ON),
            (_CTRL_REG6_XL, (odr << 5) | (afs << 3)),
            (_CTRL_REG1_G, (odr << 5) | (fs << 3)),
        )

    def mag_register_plan(self, mag_range_gauss=4):
        fs = _index(MAG_RANGES_GAUSS, mag_range_gauss, "mag range (gauss)")
        return (
            (_CTRL_REG1_M, _MAG_UHP_80HZ),
            (_CTRL_REG2_M, fs << 5),
            (_CTRL_REG4_M, _MAG_Z_UHP),
            (_CTRL_REG5_M, _MAG_BDU),
            (_CTRL_REG3_M, 0x00),
        )

    def configure(self, gyro_range_dps=2000, accel_range_g=16, odr_hz=952, mag=True, mag_range_gauss=4):
        """Reset the AG part, set ranges/ODR with BDU; set up the magnetometer if it answers.

        False if the AG part is absent/wrong or a transfer fails. A missing magnetometer
        only leaves `mag_present` False.
        """
        plan = self.register_plan(gyro_range_dps, accel_range_g, odr_hz)
        mplan = self.mag_register_plan(mag_range_gauss)
        if not self.probe():
            return False
        bus = self._bus
        a = self.address
        try:
            bus.writeto_mem(a, _CTRL_REG8, bytes((_SW_RESET_AG,)))
            self._delay_us(_RESET_WAIT_US)
            for reg, value in plan:
                bus.writeto_mem(a, reg, bytes((value,)))
        except OSError:
            self.bus_errors += 1
            self.status = STATUS_BUS_ERROR
            return False
        gi = _index(GYRO_RANGES_DPS, gyro_range_dps, "")
        ai = _index(ACCEL_RANGES_G, accel_range_g, "")
        self.gyro_range_dps = gyro_range_dps
        self.accel_range_g = accel_range_g
        self.odr_hz = odr_hz
        self._gyro_k16 = GYRO_MDPS_PER_LSB[gi] * 0.001 * 0.017453292519943295 / 16.0
        self._accel_k = ACCEL_MG_PER_LSB[ai] * 0.001 * GRAVITY_M_S2
        self.set_gyro_bias16(self._bias16_x, self._bias16_y, self._bias16_z)
        self.mag_present = False
        if mag:
            self._configure_mag(mplan, mag_range_gauss)
        self.status = STATUS_OK
        return True

    def _configure_mag(self, mplan, mag_range_gauss):
        bus = self._bus
        m = self.mag_address
        try:
            self.mag_who_am_i = self._who(m)
        except OSError:
            return  # no magnetometer fitted/answering: optional, not a bus error
        if self.mag_who_am_i != WHO_AM_I_M_VALUE:
            return
        try:
            bus.writeto_mem(m, _CTRL_REG2_M, bytes((_MAG_SOFT_RST,)))
            self._delay_us(_RESET_WAIT_US)
            for reg, value in mplan:
                bus.writeto_mem(m, reg, bytes((value,)))
        except OSError:
            self.bus_errors += 1
            return
        # mgauss/LSB -> µT/LSB: 1 gauss = 100 µT.
        self._mag_k = MAG_MGAUSS_PER_LSB[_index(MAG_RANGES_GAUSS, mag_range_gauss, "")] * 0.1
        self.mag_present = True

    def read(self, gyro_rad_s, accel_m_s2):
        """One 22-byte burst from OUT_X_L_G, decoded by hand, into FRD rad/s and m/s²."""
        buf = self._buf
        try:
            self._bus.readfrom_mem_into(self.address, _OUT_X_L_G, buf)
        except OSError:
            self.bus_errors += 1
            return False
        # Little-endian signed 16-bit (_L register first).
        gx = (buf[1] << 8) | buf[0]
        if gx & 0x8000:
            gx -= 0x10000
        gy = (buf[3] << 8) | buf[2]
        if gy & 0x8000:
            gy -= 0x10000
        gz = (buf[5] << 8) | buf[4]
        if gz & 0x8000:
            gz -= 0x10000
        ax = (buf[17] << 8) | buf[16]
        if ax & 0x8000:
            ax -= 0x10000
        ay = (buf[19] << 8) | buf[18]
        if ay & 0x8000:
            ay -= 0x10000
        az = (buf[21] << 8) | buf[20]
        if az & 0x8000:
            az -= 0x10000
        self._watch(gx, gy, gz, ax, ay, az)
        o = self._orientation
        o.rotate_scaled(gx * 16 - self._bias16_x, gy * 16 - self._bias16_y, gz * 16 - self._bias16_z,
                        self._gyro_k16, gyro_rad_s)
        o.rotate_scaled(ax, ay, az, self._accel_k, accel_m_s2)
        self.samples += 1
        return True

    def read_mag(self, mag_ut):
        """Magnetic field in µT, body frame, into mag_ut[0..2]; False if absent or on a bus error."""
        if not self.mag_present:
            return False
        b = self._mbuf
        try:
            self._bus.readfrom_mem_into(self.mag_address, _OUT_X_L_M | _MAG_AUTO_INC, b)
        except OSError:
            self.bus_errors += 1
            return False
        x = (b[1] << 8) | b[0]
        if x & 0x8000:
            x -= 0x10000
        y = (b[3] << 8) | b[2]
        if y & 0x8000:
            y -= 0x10000
        z = (b[5] << 8) | b[4]
        if z & 0x8000:
            z -= 0x10000
        s = MAG_AXIS_SIGNS
        self._orientation.rotate_scaled(s[0] * x, s[1] * y, s[2] * z, self._mag_k, mag_ut)
        return True

    def _read_gyro_raw(self):
        b = self._gbuf
        try:
            self._bus.readfrom_mem_into(self.address, _OUT_X_L_G, b)
        except OSError:
            self.bus_errors += 1
            return False
        v = (b[1] << 8) | b[0]
        self._raw_gx = v - 0x10000 if v & 0x8000 else v
        v = (b[3] << 8) | b[2]
        self._raw_gy = v - 0x10000 if v & 0x8000 else v
        v = (b[5] << 8) | b[4]
        self._raw_gz = v - 0x10000 if v & 0x8000 else v
        return True
