"""Register models of the IMU chips, behind a fake I2C bus and a fake SPI device.

Takes body-frame motion (`set_motion(gyro_rad_s, accel_m_s2)`, FRD, SI) and a mounting
(an Orientation: chip axes to body); gives the raw register bytes the real chip would
hold, at the range the driver configured in the model's own registers, so a driver
reads them back through its normal burst read. Portable (CPython and MicroPython): the
simulator board's I2C (maintenance commands 22-23, sim/board.py), tests/rp2fakes (re-exported
there as `regmodels`), tests/portable and the benchmarks use it.

Each model: registers in a bytearray with the datasheet reset values, WHO_AM_I, every
written byte recorded in `writes` as (register, value), burst reads with the chip's
auto-increment rule, and fault injection: `fail_next(n)` -> the next n transfers raise
OSError(5) (EIO), `freeze()` -> output registers stop changing, `absent = True` -> no
ACK (I2C raises OSError(19), ENODEV; SPI reads 0xFF, as a floating MISO with pull-up).

The scale tables here are written out again from the datasheets on purpose, so the
tests compare two independent readings of the same numbers.
"""

import math

from hoverfly.drivers.orientation import Orientation

EIO = 5
ENODEV = 19
G = 9.80665
DEG = math.pi / 180.0


def _quant(value):
    """Nearest int, clamped to signed 16-bit (what a saturating ADC output does)."""
    r = int(math.floor(value + 0.5))
    if r > 32767:
        return 32767
    if r < -32768:
        return -32768
    return r


class _Lcg:
    """Tiny deterministic noise source (no `random` needed under MicroPython)."""

    def __init__(self, seed):
        self.state = (seed * 2654435761 + 1) & 0x7FFFFFFF

    def uniform_int(self, amplitude):
        self.state = (1103515245 * self.state + 12345) & 0x7FFFFFFF
        if amplitude <= 0:
            return 0
        return (self.state >> 8) % (2 * amplitude + 1) - amplitude


class RegisterDevice:
    """Common part of a chip model: registers, write log, faults, burst access."""

    name = "device"
    size = 128

    def __init__(self, address, mounting=None, noise_lsb=0, seed=1):
        self.address = address
        self.mounting = mounting if mounting is not None else Orientation()
        self.regs = bytearray(self.size)
        self.writes = []
        self.absent = False
        self.frozen = False
        self.transfers = 0
        self.noise_lsb = noise_lsb
        self._rng = _Lcg(seed)
        self._fail = 0
        self.on_read = None  # callable(model) before each data read: tests script motion
        self.gyro_rad_s = [0.0, 0.0, 0.0]
        self.accel_m_s2 = [0.0, 0.0, -G]
        self.temp_c = 25.0
        self.reset()

    # --- faults ---------------------------------------------------------------------
    def fail_next(self, n=1):
        self._fail = n

    def freeze(self):
        self.frozen = True

    def unfreeze(self):
        self.frozen = False

    def check(self):
        """Called by the bus once per transfer: raise the injected fault, if any."""
        if self.absent:
            raise OSError(ENODEV)
        if self._fail > 0:
            self._fail -= 1
            raise OSError(EIO)
        self.transfers += 1

    # --- to override ------------------------------------------------------------------
    def reset(self):
        for i in range(self.size):
            self.regs[i] = 0

    def write_reg(self, reg, value):
        self.regs[reg] = value

    def read_reg(self, reg):
        return self.regs[reg]

    def next_reg(self, reg, first):
        return (reg + 1) % self.size

    def refresh(self):
        """Recompute the output registers from the stored motion."""

    # --- bus side ---------------------------------------------------------------------
    def read_into(self, reg, buf, n):
        if not self.frozen:
            if self.on_read is not None:
                self.on_read(self)
            self.refresh()
        first = reg
        r = self.start_reg(reg)
        for i in range(n):
            buf[i] = self.read_reg(r)
            r = self.next_reg(r, first)

    def start_reg(self, reg):
        return reg % self.size

    def write(self, reg, data):
        r = self.start_reg(reg)
        for b in data:
            self.writes.append((r, b))
            self.write_reg(r, b)
            r = self.next_reg(r, reg)

    def written(self, reg):
        """Values written to one register, in order."""
        return [v for (r, v) in self.writes if r == reg]

    # --- motion -----------------------------------------------------------------------
    def set_motion(self, gyro_rad_s, accel_m_s2, temp_c=25.0):
        """Body-frame (FRD) rate and specific force; the model turns them into chip LSBs."""
        for i in range(3):
            self.gyro_rad_s[i] = gyro_rad_s[i]
            self.accel_m_s2[i] = accel_m_s2[i]
        self.temp_c = temp_c
        if not self.frozen:
            self.refresh()

    def _chip(self, v):
        out = [0.0, 0.0, 0.0]
        self.mounting.unrotate(v[0], v[1], v[2], out)
        return out

    def _noise(self):
        # Uniform in ±noise_lsb with 1/16 LSB steps: non-integer, so it dithers the rounding.
        if self.noise_lsb <= 0:
            return 0
        return self._rng.uniform_int(self.noise_lsb * 16) / 16.0

    def _put_be(self, reg, v):
        v &= 0xFFFF
        self.regs[reg] = v >> 8
        self.regs[reg + 1] = v & 0xFF

    def _put_le(self, reg, v):
        v &= 0xFFFF
        self.regs[reg] = v & 0xFF
        self.regs[reg + 1] = v >> 8


class FakeI2C:
    """machine.I2C stand-in serving register-model devices by 7-bit address."""

    def __init__(self, *devices):
        self.devices = list(devices)
        self._fail = 0
        self.transfers = 0

    def add(self, device):
        self.devices.append(device)

    def fail_next(self, n=1):
        """Bus-wide fault: the next n transfers to any address raise OSError(EIO)."""
        self._fail = n

    def _device(self, addr):
        for d in self.devices:
            if d.address == addr:
                if d.absent:
                    raise OSError(ENODEV)
                if self._fail > 0:
                    self._fail -= 1
                    raise OSError(EIO)
                d.check()
                self.transfers += 1
                return d
        raise OSError(ENODEV)

    def scan(self):
        return [d.address for d in self.devices if not d.absent]

    def readfrom_mem_into(self, addr, memaddr, buf, addrsize=8):
        self._device(addr).read_into(memaddr, buf, len(buf))

    def readfrom_mem(self, addr, memaddr, nbytes, addrsize=8):
        buf = bytearray(nbytes)
        self._device(addr).read_into(memaddr, buf, nbytes)
        return bytes(buf)

    def writeto_mem(self, addr, memaddr, buf, addrsize=8):
        self._device(addr).write(memaddr, buf)


# ======================================================================================
# MPU-6050 (RM-MPU-6000A-00 rev 4.2)
# ======================================================================================
class MPU6050Model(RegisterDevice):
    name = "mpu6050"
    GYRO_LSB_PER_DPS = (131.0, 65.5, 32.8, 16.4)  # PS-MPU-6000A §6.1, FS_SEL 0..3
    ACCEL_LSB_PER_G = (16384.0, 8192.0, 4096.0, 2048.0)  # PS §6.2, AFS_SEL 0..3

    def __init__(self, mounting=None, address=0x68, noise_lsb=0, seed=1, who_am_i=0x68):
        self.who_am_i = who_am_i
        RegisterDevice.__init__(self, address, mounting, noise_lsb, seed)

    def reset(self):
        RegisterDevice.reset(self)
        self.regs[0x6B] = 0x40  # PWR_MGMT_1 reset value: SLEEP
        self.regs[0x75] = self.who_am_i

    def write_reg(self, reg, value):
        if reg == 0x6B and value & 0x80:
            self.reset()  # DEVICE_RESET; the bit reads back 0
            return
        if reg == 0x75:
            return  # read-only
        self.regs[reg] = value

    @property
    def asleep(self):
        return bool(self.regs[0x6B] & 0x40)

    def gyro_lsb_per_rad_s(self):
        return self.GYRO_LSB_PER_DPS[(self.regs[0x1B] >> 3) & 3] / DEG

    def accel_lsb_per_m_s2(self):
        return self.ACCEL_LSB_PER_G[(self.regs[0x1C] >> 3) & 3] / G

    def refresh(self):
        if self.asleep:
            return  # a sleeping chip does not convert: outputs keep their old value
        g = self._chip(self.gyro_rad_s)
        a = self._chip(self.accel_m_s2)
        kg = self.gyro_lsb_per_rad_s()
        ka = self.accel_lsb_per_m_s2()
        for i in range(3):
            self._put_be(0x3B + 2 * i, _quant(a[i] * ka + self._noise()))
            self._put_be(0x43 + 2 * i, _quant(g[i] * kg + self._noise()))
        self._put_be(0x41, _quant((self.temp_c - 36.53) * 340.0))  # RM §4.18


# ======================================================================================
# BNO055 (Bosch BST-BNO055-DS000)
# ======================================================================================
def _quat_to_matrix(w, x, y, z):
    return [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]


def _matrix_to_quat(m):
    # Largest-component method, written independently of the driver's helper.
    w2 = 1 + m[0][0] + m[1][1] + m[2][2]
    x2 = 1 + m[0][0] - m[1][1] - m[2][2]
    y2 = 1 - m[0][0] + m[1][1] - m[2][2]
    z2 = 1 - m[0][0] - m[1][1] + m[2][2]
    big = max(w2, x2, y2, z2)
    if big == w2:
        w = math.sqrt(w2) / 2
        q = (w, (m[2][1] - m[1][2]) / (4 * w), (m[0][2] - m[2][0]) / (4 * w), (m[1][0] - m[0][1]) / (4 * w))
    elif big == x2:
        x = math.sqrt(x2) / 2
        q = ((m[2][1] - m[1][2]) / (4 * x), x, (m[0][1] + m[1][0]) / (4 * x), (m[0][2] + m[2][0]) / (4 * x))
    elif big == y2:
        y = math.sqrt(y2) / 2
        q = ((m[0][2] - m[2][0]) / (4 * y), (m[0][1] + m[1][0]) / (4 * y), y, (m[1][2] + m[2][1]) / (4 * y))
    else:
        z = math.sqrt(z2) / 2
        q = ((m[1][0] - m[0][1]) / (4 * z), (m[0][2] + m[2][0]) / (4 * z), (m[1][2] + m[2][1]) / (4 * z), z)
    return q


def _mat_mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


class BNO055Model(RegisterDevice):
    """Page 0 of the BNO055 register map; fusion outputs appear once OPR_MODE leaves CONFIG.

    `set_attitude(q)` takes the body-to-NED quaternion (w, x, y, z). The chip's fusion
    frame is modelled as z up (gravity along -z), x along the NED north axis:
    world-up = (N, -E, -D).
    """

    name = "bno055"

    def __init__(self, mounting=None, address=0x28, noise_lsb=0, seed=1, chip_id=0xA0):
        self.chip_id = chip_id
        self.q_nb = (1.0, 0.0, 0.0, 0.0)
        self.mag_ut = [20.0, 0.0, 45.0]
        RegisterDevice.__init__(self, address, mounting, noise_lsb, seed)

    def reset(self):
        RegisterDevice.reset(self)
        r = self.regs
        r[0x00] = self.chip_id  # CHIP_ID (register map reset values)
        r[0x01] = 0xFB  # ACC_ID
        r[0x02] = 0x32  # MAG_ID
        r[0x03] = 0x0F  # GYR_ID
        r[0x3B] = 0x80  # UNIT_SEL: Android orientation, m/s², dps, degrees
        r[0x3D] = 0x00  # OPR_MODE: CONFIGMODE
        r[0x41] = 0x24  # AXIS_MAP_CONFIG
        r[0x35] = 0xFF  # CALIB_STAT: all calibrated (model)

    def write_reg(self, reg, value):
        if reg == 0x3F and value & 0x20:  # SYS_TRIGGER RST_SYS
            self.reset()
            return
        if reg in (0x00, 0x01, 0x02, 0x03):
            return
        self.regs[reg] = value
        if reg == 0x3D:
            self.regs[0x39] = 5 if (value & 0x0F) >= 0x08 else (6 if value & 0x0F else 0)  # SYS_STATUS

    @property
    def mode(self):
        return self.regs[0x3D] & 0x0F

    def set_attitude(self, q_nb):
        self.q_nb = (q_nb[0], q_nb[1], q_nb[2], q_nb[3])
        if not self.frozen:
            self.refresh()

    def refresh(self):
        if self.mode == 0:
            return  # CONFIGMODE: no sensor data
        unit = self.regs[0x3B]
        a = self._chip(self.accel_m_s2)
        g = self._chip(self.gyro_rad_s)
        m = self._chip(self.mag_ut)
        ka = 100.0 if not unit & 0x01 else 1000.0 / G  # §3.6.4 units: 1 m/s² = 100 LSB, 1 mg = 1 LSB
        kg = 16.0 / DEG if not unit & 0x02 else 900.0  # §3.6.4 units: 1 dps = 16 LSB, 1 rps = 900 LSB
        for i in range(3):
            self._put_le(0x08 + 2 * i, _quant(a[i] * ka + self._noise()))
            self._put_le(0x0E + 2 * i, _quant(m[i] * 16.0))  # §3.6.4 units: 1 µT = 16 LSB
            self._put_le(0x14 + 2 * i, _quant(g[i] * kg + self._noise()))
        if self.mode >= 0x08:
            # R_ws = F^T R_nb M_bs; F = diag(1, -1, -1) turns world-up into NED.
            r_nb = _quat_to_matrix(*self.q_nb)
            f = [[1, 0, 0], [0, -1, 0], [0, 0, -1]]
            r_ws = _mat_mul(_mat_mul(f, r_nb), self.mounting.matrix())
            q = _matrix_to_quat(r_ws)
            for i in range(4):
                self._put_le(0x20 + 2 * i, _quant(q[i] * 16384.0))  # §3.6.5: 1 = 2^14 LSB


# ======================================================================================
# LSM9DS1 (ST DocID025715)
# ======================================================================================
class LSM9DS1AGModel(RegisterDevice):
    """Accelerometer + gyroscope part. Auto-increment follows CTRL_REG8 IF_ADD_INC."""

    name = "lsm9ds1_ag"
    GYRO_LSB_PER_DPS = (1000 / 8.75, 1000 / 17.5, 1000 / 8.75, 1000 / 70.0)  # Table 3, FS_G 00/01/(10)/11
    ACCEL_LSB_PER_G = (1000 / 0.061, 1000 / 0.732, 1000 / 0.122, 1000 / 0.244)  # Table 3, FS_XL 00/01/10/11

    def __init__(self, mounting=None, address=0x6B, noise_lsb=0, seed=1, who_am_i=0x68):
        self.who_am_i = who_am_i
        RegisterDevice.__init__(self, address, mounting, noise_lsb, seed)

    def reset(self):
        RegisterDevice.reset(self)
        self.regs[0x0F] = self.who_am_i
        self.regs[0x1E] = 0x38  # CTRL_REG4: gyro X/Y/Z enabled
        self.regs[0x1F] = 0x38  # CTRL_REG5_XL: accel X/Y/Z enabled
        self.regs[0x22] = 0x04  # CTRL_REG8: IF_ADD_INC

    def start_reg(self, reg):
        return reg & 0x7F

    def next_reg(self, reg, first):
        return (reg + 1) & 0x7F if self.regs[0x22] & 0x04 else reg

    def write_reg(self, reg, value):
        if reg == 0x22 and value & 0x01:  # SW_RESET
            self.reset()
            return
        if reg == 0x0F:
            return
        self.regs[reg] = value

    def refresh(self):
        gyro_on = self.regs[0x10] >> 5
        accel_on = gyro_on or self.regs[0x20] >> 5
        if gyro_on:
            g = self._chip(self.gyro_rad_s)
            kg = self.GYRO_LSB_PER_DPS[(self.regs[0x10] >> 3) & 3] / DEG
            for i in range(3):
                self._put_le(0x18 + 2 * i, _quant(g[i] * kg + self._noise()))
        if accel_on:
            a = self._chip(self.accel_m_s2)
            ka = self.ACCEL_LSB_PER_G[(self.regs[0x20] >> 3) & 3] / G
            for i in range(3):
                self._put_le(0x28 + 2 * i, _quant(a[i] * ka + self._noise()))


# The magnetometer's x axis points the opposite way to the accel/gyro x axis
# (LSM9DS1 datasheet Figure 1, pin-indicator axes) -- the same assumption as the driver.
MAG_AXIS_SIGNS = (-1, 1, 1)


class LSM9DS1MagModel(RegisterDevice):
    """Magnetometer part: multi-byte reads auto-increment only with the sub-address MSB set."""

    name = "lsm9ds1_m"
    LSB_PER_GAUSS = (1000 / 0.14, 1000 / 0.29, 1000 / 0.43, 1000 / 0.58)  # Table 3, FS 00..11

    def __init__(self, mounting=None, address=0x1E, seed=1, who_am_i=0x3D):
        self.who_am_i = who_am_i
        self.mag_ut = [20.0, 0.0, 45.0]
        RegisterDevice.__init__(self, address, mounting, 0, seed)

    def reset(self):
        RegisterDevice.reset(self)
        self.regs[0x0F] = self.who_am_i
        self.regs[0x22] = 0x03  # CTRL_REG3_M: power-down

    def start_reg(self, reg):
        return reg & 0x7F

    def next_reg(self, reg, first):
        return (reg + 1) & 0x7F if first & 0x80 else reg

    def write_reg(self, reg, value):
        if reg == 0x21 and value & 0x04:  # CTRL_REG2_M SOFT_RST
            self.reset()
            return
        if reg == 0x0F:
            return
        self.regs[reg] = value

    def set_field(self, mag_ut):
        for i in range(3):
            self.mag_ut[i] = mag_ut[i]
        if not self.frozen:
            self.refresh()

    def refresh(self):
        if self.regs[0x22] & 0x03:
            return  # not in continuous-conversion mode
        m = self._chip(self.mag_ut)
        k = self.LSB_PER_GAUSS[(self.regs[0x21] >> 5) & 3] / 100.0  # 1 gauss = 100 µT
        for i in range(3):
            self._put_le(0x28 + 2 * i, _quant(MAG_AXIS_SIGNS[i] * m[i] * k))


# ======================================================================================
# ICM-42688-P over SPI (TDK DS-000347)
# ======================================================================================
class ICM42688Model(RegisterDevice):
    """Bank 0 registers, the data registers and the FIFO with 16-byte packet-3 records.

    It is its own SPI bus object: `transfer(tx, rx)` full duplex with chip select held for
    the whole transfer; tx[0] = register | 0x80 for a read. `tick(n)` pushes n samples
    into the FIFO at the configured ODR (the simulator calls it once per 1/ODR).
    """

    name = "icm42688"
    size = 128
    FIFO_BYTES = 2048  # DS-000347 2 KB FIFO
    GYRO_LSB_PER_DPS = (16.4, 32.8, 65.5, 131.0, 262.0, 524.3, 1048.6, 2097.2)  # §3.1, GYRO_FS_SEL 0..7
    ACCEL_LSB_PER_G = (2048.0, 4096.0, 8192.0, 16384.0)  # §3.2 ACCEL_FS_SEL 0..3

    def __init__(self, mounting=None, noise_lsb=0, seed=1, who_am_i=0x47):
        self.who_am_i = who_am_i
        self.fifo = bytearray()
        self.lost_packets = 0
        self._tmst = 0
        RegisterDevice.__init__(self, None, mounting, noise_lsb, seed)

    def reset(self):
        RegisterDevice.reset(self)
        r = self.regs
        r[0x75] = self.who_am_i
        r[0x4C] = 0x30  # INTF_CONFIG0: FIFO count and sensor data big-endian
        r[0x4F] = 0x06  # GYRO_CONFIG0: ±2000 dps, 1 kHz
        r[0x50] = 0x06  # ACCEL_CONFIG0: ±16 g, 1 kHz
        r[0x16] = 0x00  # FIFO_CONFIG: bypass
        self.fifo = bytearray()
        self._write_data_off()

    def _write_data_off(self):
        for reg in range(0x1F, 0x2B, 2):
            self._put_be(reg, -32768)  # data registers read -32768 while the sensor is off

    def write_reg(self, reg, value):
        if reg == 0x11 and value & 0x01:  # DEVICE_CONFIG SOFT_RESET_CONFIG
            self.reset()
            return
        if reg == 0x4B and value & 0x02:  # SIGNAL_PATH_RESET FIFO_FLUSH
            self.fifo = bytearray()
            return
        if reg == 0x75:
            return
        self.regs[reg] = value

    @property
    def big_endian(self):
        return bool(self.regs[0x4C] & 0x10)

    def _sensors_on(self):
        p = self.regs[0x4E]
        return (p & 0x0C) == 0x0C and (p & 0x03) == 0x03  # GYRO_MODE and ACCEL_MODE low-noise

    def _raw(self):
        g = self._chip(self.gyro_rad_s)
        a = self._chip(self.accel_m_s2)
        kg = self.GYRO_LSB_PER_DPS[self.regs[0x4F] >> 5] / DEG
        ka = self.ACCEL_LSB_PER_G[(self.regs[0x50] >> 5) & 3] / G
        out = []
        for i in range(3):
            v = _quant(a[i] * ka + self._noise())
            out.append(-32767 if v == -32768 else v)  # -32768 is the "invalid" marker
        for i in range(3):
            v = _quant(g[i] * kg + self._noise())
            out.append(-32767 if v == -32768 else v)
        return out

    def refresh(self):
        if not self._sensors_on():
            return
        raw = self._raw()
        put = self._put_be if self.big_endian else self._put_le
        for i in range(6):
            put(0x1F + 2 * i, raw[i])
        put(0x1D, _quant((self.temp_c - 25.0) * 132.48))  # TEMP_DATA / 132.48 + 25

    def tick(self, n=1):
        """n new samples at the ODR: into the FIFO when it is streaming."""
        if self.frozen:
            return
        self.refresh()
        mode = self.regs[0x16] >> 6
        if mode == 0 or not self._sensors_on() or (self.regs[0x5F] & 0x03) != 0x03:
            return
        for _ in range(n):
            raw = self._raw()
            pkt = bytearray(16)
            pkt[0] = 0x68  # header: accel + gyro, ODR timestamp (FIFO header, §6)
            for i in range(6):
                v = raw[i] & 0xFFFF
                if self.big_endian:
                    pkt[1 + 2 * i] = v >> 8
                    pkt[2 + 2 * i] = v & 0xFF
                else:
                    pkt[1 + 2 * i] = v & 0xFF
                    pkt[2 + 2 * i] = v >> 8
            pkt[13] = _quant((self.temp_c - 25.0) * 2.07) & 0xFF  # FIFO temp / 2.07 + 25
            self._tmst = (self._tmst + 1000) & 0xFFFF
            pkt[14] = self._tmst >> 8
            pkt[15] = self._tmst & 0xFF
            if len(self.fifo) + 16 > self.FIFO_BYTES:
                self.regs[0x2D] |= 0x02  # INT_STATUS FIFO_FULL_INT
                self.lost_packets += 1
                if mode >= 2:
                    continue  # STOP-ON-FULL: new data dropped
                self.fifo = self.fifo[16:]  # stream: oldest dropped
            self.fifo.extend(pkt)

    def fifo_packets(self):
        return len(self.fifo) // 16

    def poke_fifo(self, data):
        """Append raw bytes to the FIFO (fuzz/robustness tests)."""
        self.fifo.extend(data)

    # --- SPI ------------------------------------------------------------------------
    def transfer(self, tx, rx):
        n = len(tx)
        if self.absent:
            for i in range(n):
                rx[i] = 0xFF
            return
        self.check()
        first = tx[0]
        reg = first & 0x7F
        rx[0] = 0
        if first & 0x80:
            if reg <= 0x2F and reg + n - 1 > 0x2A and not self.frozen:
                self.refresh()
            # FIFO_COUNT is latched when the transfer starts.
            count = len(self.fifo)
            be = self.regs[0x4C] & 0x20
            self.regs[0x2E] = (count >> 8) if be else (count & 0xFF)
            self.regs[0x2F] = (count & 0xFF) if be else (count >> 8)
            clear_status = False
            for i in range(1, n):
                if reg == 0x30:
                    if len(self.fifo):
                        rx[i] = self.fifo[0]
                        self.fifo = self.fifo[1:]
                    else:
                        rx[i] = 0xFF  # empty FIFO reads 0xFF (header bit 7: FIFO empty)
                    continue  # FIFO_DATA does not increment
                rx[i] = self.regs[reg]
                if reg == 0x2D:
                    clear_status = True
                reg = (reg + 1) & 0x7F
            if clear_status:
                self.regs[0x2D] = 0  # INT_STATUS clears on read
        else:
            for i in range(1, n):
                self.writes.append((reg, tx[i]))
                self.write_reg(reg, tx[i])
                reg = (reg + 1) & 0x7F
                rx[i] = 0
