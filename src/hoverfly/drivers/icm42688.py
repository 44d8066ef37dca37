"""ICM-42688-P over SPI: FIFO at 1 kHz (seed 002), or the data registers.

Takes a small SPI bus object (docs/drivers.md): `transfer(tx, rx)` does one full-duplex
transfer of len(tx) bytes with chip select held low for all of it (the rp2 board wraps
machine.SPI.write_readinto + a CS Pin); tx[0] = register | 0x80 reads, register & 0x7F
writes. Gives body FRD gyro in rad/s and accel in m/s² from the newest FIFO packet
(`read_fifo`) or from the data registers (`read`, which uses the FIFO when configured so).

FIFO contract: each read takes INT_STATUS + FIFO_COUNT in one transfer, then all queued
packets (in chunks of `max_packets`), decodes only the newest and counts the rest in
`dropped_packets`; a FIFO_FULL flag counts in `overflows`; a bad header or the -32768
"invalid sample" marker counts in `bad_packets` and flushes the FIFO. An empty FIFO
returns False (`empty_reads`): no new sample.

Numbers: TDK InvenSense DS-000347 (ICM-42688-P datasheet rev 1.x): §14 register map
(bank 0), §3.1/3.2 sensitivities, §6 FIFO (packet 3 = 16 bytes: header, accel XYZ,
gyro XYZ big-endian, temperature, 2-byte timestamp).
"""

from hoverfly.compat import const
from hoverfly.drivers.imu import (
    DEG_TO_RAD,
    GRAVITY_M_S2,
    STATUS_ABSENT,
    STATUS_BUS_ERROR,
    STATUS_OK,
    STATUS_WRONG_ID,
    Imu,
)

WHO_AM_I_VALUE = 0x47  # register map: WHO_AM_I reset value

_DEVICE_CONFIG = const(0x11)  # reg map: SOFT_RESET_CONFIG bit 0
_FIFO_CONFIG = const(0x16)  # reg map: FIFO_MODE bits 7:6 (00 bypass, 01 stream-to-FIFO, 1x stop-on-full)
_TEMP_DATA1 = const(0x1D)  # reg map
_ACCEL_DATA_X1 = const(0x1F)  # reg map: accel X/Y/Z then gyro X/Y/Z (0x25), 12 bytes to 0x2A
_INT_STATUS = const(0x2D)  # reg map: FIFO_FULL_INT bit 1, clear on read
_FIFO_COUNTH = const(0x2E)  # reg map: count in bytes (FIFO_COUNT_REC = 0), big-endian by default
_FIFO_DATA = const(0x30)  # reg map
_SIGNAL_PATH_RESET = const(0x4B)  # reg map: FIFO_FLUSH bit 1
_INTF_CONFIG0 = const(0x4C)  # reg map: FIFO_COUNT_ENDIAN bit 5, SENSOR_DATA_ENDIAN bit 4
_PWR_MGMT0 = const(0x4E)  # reg map: GYRO_MODE 3:2, ACCEL_MODE 1:0 (11 = low noise)
_GYRO_CONFIG0 = const(0x4F)  # reg map: GYRO_FS_SEL 7:5, GYRO_ODR 3:0
_ACCEL_CONFIG0 = const(0x50)  # reg map: ACCEL_FS_SEL 7:5, ACCEL_ODR 3:0
_FIFO_CONFIG1 = const(0x5F)  # reg map: TEMP_EN bit 2, GYRO_EN bit 1, ACCEL_EN bit 0
_WHO_AM_I = const(0x75)  # reg map
_REG_BANK_SEL = const(0x76)  # reg map: bank 0 for all of the above

_READ = const(0x80)
_SOFT_RESET = const(0x01)
_FIFO_STREAM = const(0x40)
_FIFO_ACCEL_GYRO_TEMP = const(0x07)  # accel + gyro (+ temperature): packet 3, 16 bytes
_FIFO_FLUSH = const(0x02)
_INTF_BIG_ENDIAN = const(0x30)  # reset value: count and data big-endian (stated explicitly)
_PWR_GYRO_ACCEL_LN = const(0x0F)
_RESET_WAIT_US = const(1000)  # reg map: wait 1 ms after soft reset
_POWER_ON_WAIT_US = const(200)  # PWR_MGMT0 description: no register write for 200 µs after turning sensors on
_FIFO_FULL = const(0x02)
_PACKET = const(16)

GYRO_RANGES_DPS = (2000, 1000, 500, 250, 125)  # GYRO_FS_SEL 0..4
GYRO_LSB_PER_DPS = (16.4, 32.8, 65.5, 131.0, 262.0)  # §3.1
ACCEL_RANGES_G = (16, 8, 4, 2)  # ACCEL_FS_SEL 0..3
ACCEL_LSB_PER_G = (2048.0, 4096.0, 8192.0, 16384.0)  # §3.2
# reg map ODR codes (gyro and accel share them for these rates).
ODR_HZ = (32000, 16000, 8000, 4000, 2000, 1000, 500, 200, 100, 50, 25)
ODR_CODE = (1, 2, 3, 4, 5, 6, 15, 7, 8, 9, 10)


def _index(table, value, what):
    for i in range(len(table)):
        if table[i] == value:
            return i
    raise ValueError("%s %r not supported (one of %r)" % (what, value, table))


class ICM42688(Imu):
    """TDK ICM-42688-P over SPI (see the module docstring)."""

    name = "icm42688"

    def __init__(self, spi, orientation, delay_us=None, max_packets=8):
        Imu.__init__(self, orientation, delay_us)
        self._spi = spi
        self.use_fifo = False
        self.odr_hz = 0
        self.max_packets = max_packets
        # Preallocated transfers: 1 register byte + payload.
        self._tx13 = bytearray(13)
        self._tx13[0] = _READ | _ACCEL_DATA_X1
        self._rx13 = bytearray(13)
        self._tx4 = bytearray(4)
        self._tx4[0] = _READ | _INT_STATUS
        self._rx4 = bytearray(4)
        self._tx7 = bytearray(7)
        self._tx7[0] = _READ | 0x25  # GYRO_DATA_X1, for calibration
        self._rx7 = bytearray(7)
        n = 1 + _PACKET * max_packets
        self._txf = bytearray(n)
        self._txf[0] = _READ | _FIFO_DATA
        self._rxf = bytearray(n)
        txv = memoryview(self._txf)
        rxv = memoryview(self._rxf)
        # One view per packet count, made once: slicing in the hot path would allocate.
        self._txf_views = [txv[:1 + _PACKET * k] for k in range(1, max_packets + 1)]
        self._rxf_views = [rxv[:1 + _PACKET * k] for k in range(1, max_packets + 1)]
        self._two = bytearray(2)
        self._two_rx = bytearray(2)
        self.temp_raw = 0
        self.timestamp_raw = 0
        self.packets = 0
        self.dropped_packets = 0
        self.overflows = 0
        self.bad_packets = 0
        self.empty_reads = 0
        self._raw_gx = self._raw_gy = self._raw_gz = 0

    # --- register access (boot time) ---------------------------------------------------
    def _write(self, reg, value):
        t = self._two
        t[0] = reg & 0x7F
        t[1] = value
        self._spi.transfer(t, self._two_rx)

    def _read_reg(self, reg):
        t = self._two
        t[0] = _READ | reg
        t[1] = 0
        self._spi.transfer(t, self._two_rx)
        return self._two_rx[1]

    def probe(self):
        """True if WHO_AM_I reads 0x47. An absent SPI chip reads 0x00/0xFF -> WRONG_ID."""
        try:
            self._write(_REG_BANK_SEL, 0)
            self.who_am_i = self._read_reg(_WHO_AM_I)
        except OSError:
            self.bus_errors += 1
            self.status = STATUS_ABSENT
            return False
        if self.who_am_i != WHO_AM_I_VALUE:
            self.status = STATUS_ABSENT if self.who_am_i in (0x00, 0xFF) else STATUS_WRONG_ID
            return False
        self.status = STATUS_OK
        return True

    def register_plan(self, gyro_range_dps=2000, accel_range_g=16, odr_hz=1000, fifo=True):
        """The (register, value) writes configure() makes after the soft reset, in order."""
        fs = _index(GYRO_RANGES_DPS, gyro_range_dps, "gyro range (dps)")
        afs = _index(ACCEL_RANGES_G, accel_range_g, "accel range (g)")
        odr = ODR_CODE[_index(ODR_HZ, odr_hz, "ODR (Hz)")]
        plan = [
            (_REG_BANK_SEL, 0),
            (_INTF_CONFIG0, _INTF_BIG_ENDIAN),
            (_GYRO_CONFIG0, (fs << 5) | odr),
            (_ACCEL_CONFIG0, (afs << 5) | odr),
        ]
        if fifo:
            plan.append((_FIFO_CONFIG1, _FIFO_ACCEL_GYRO_TEMP))
            plan.append((_FIFO_CONFIG, _FIFO_STREAM))
        else:
            plan.append((_FIFO_CONFIG, 0x00))
        plan.append((_PWR_MGMT0, _PWR_GYRO_ACCEL_LN))
        return plan

    def configure(self, gyro_range_dps=2000, accel_range_g=16, odr_hz=1000, fifo=True):
        """Soft reset, ranges and ODR (seed 002: 1 kHz), FIFO stream mode, sensors on, flush."""
        plan = self.register_plan(gyro_range_dps, accel_range_g, odr_hz, fifo)
        if not self.probe():
            return False
        try:
            self._write(_DEVICE_CONFIG, _SOFT_RESET)
            self._delay_us(_RESET_WAIT_US)
            for reg, value in plan:
                self._write(reg, value)
            self._delay_us(_POWER_ON_WAIT_US)
            if fifo:
                self._write(_SIGNAL_PATH_RESET, _FIFO_FLUSH)
        except OSError:
            self.bus_errors += 1
            self.status = STATUS_BUS_ERROR
            return False
        fs = _index(GYRO_RANGES_DPS, gyro_range_dps, "")
        afs = _index(ACCEL_RANGES_G, accel_range_g, "")
        self.gyro_range_dps = gyro_range_dps
        self.accel_range_g = accel_range_g
        self.odr_hz = odr_hz
        self.use_fifo = fifo
        self._gyro_k16 = DEG_TO_RAD / GYRO_LSB_PER_DPS[fs] / 16.0
        self._accel_k = GRAVITY_M_S2 / ACCEL_LSB_PER_G[afs]
        self.set_gyro_bias16(self._bias16_x, self._bias16_y, self._bias16_z)
        self.status = STATUS_OK
        return True

    # --- hot path -------------------------------------------------------------------------
    def read(self, gyro_rad_s, accel_m_s2):
        """Newest sample into FRD rad/s, m/s²: FIFO if configured, else one 12-byte data burst."""
        if self.use_fifo:
            return self.read_fifo(gyro_rad_s, accel_m_s2)
        rx = self._rx13
        try:
            self._spi.transfer(self._tx13, rx)
        except OSError:
            self.bus_errors += 1
            return False
        return self._decode(rx, 1, gyro_rad_s, accel_m_s2)

    def read_fifo(self, gyro_rad_s, accel_m_s2):
        """Drain the FIFO, decode the newest packet; False if none (see module docstring)."""
        spi = self._spi
        st = self._rx4
        try:
            spi.transfer(self._tx4, st)
        except OSError:
            self.bus_errors += 1
            return False
        if st[1] & _FIFO_FULL:
            self.overflows += 1
        count = (st[2] << 8) | st[3]
        n = count >> 4
        if n == 0:
            self.empty_reads += 1
            return False
        maxp = self.max_packets
        k = 0
        left = n
        try:
            while left > 0:
                k = left if left < maxp else maxp
                spi.transfer(self._txf_views[k - 1], self._rxf_views[k - 1])
                left -= k
        except OSError:
            self.bus_errors += 1
            self._flush()
            return False
        self.packets += n
        self.dropped_packets += n - 1
        off = 1 + _PACKET * (k - 1)
        rx = self._rxf
        h = rx[off]
        # FIFO header (§6): bit 7 = FIFO empty, 6 = accel, 5 = gyro, 4 = 20-bit; packet 3 is 0b0110xxxx.
        if (h & 0xF0) != 0x60:
            self.bad_packets += 1
            self._flush()
            return False
        self.temp_raw = rx[off + 13]
        self.timestamp_raw = (rx[off + 14] << 8) | rx[off + 15]
        return self._decode(rx, off + 1, gyro_rad_s, accel_m_s2)

    def _decode(self, b, i, gyro_rad_s, accel_m_s2):
        ax = (b[i] << 8) | b[i + 1]
        if ax & 0x8000:
            ax -= 0x10000
        ay = (b[i + 2] << 8) | b[i + 3]
        if ay & 0x8000:
            ay -= 0x10000
        az = (b[i + 4] << 8) | b[i + 5]
        if az & 0x8000:
            az -= 0x10000
        gx = (b[i + 6] << 8) | b[i + 7]
        if gx & 0x8000:
            gx -= 0x10000
        gy = (b[i + 8] << 8) | b[i + 9]
        if gy & 0x8000:
            gy -= 0x10000
        gz = (b[i + 10] << 8) | b[i + 11]
        if gz & 0x8000:
            gz -= 0x10000
        # FIFO / data register description: -32768 marks an invalid sample (sensor off or not yet settled).
        if ax == -32768 or ay == -32768 or az == -32768 or gx == -32768 or gy == -32768 or gz == -32768:
            self.bad_packets += 1
            return False
        self._watch(gx, gy, gz, ax, ay, az)
        o = self._orientation
        o.rotate_scaled(gx * 16 - self._bias16_x, gy * 16 - self._bias16_y, gz * 16 - self._bias16_z,
                        self._gyro_k16, gyro_rad_s)
        o.rotate_scaled(ax, ay, az, self._accel_k, accel_m_s2)
        self.samples += 1
        return True

    def _flush(self):
        try:
            self._write(_SIGNAL_PATH_RESET, _FIFO_FLUSH)
        except OSError:
            self.bus_errors += 1

    def _read_gyro_raw(self):
        rx = self._rx7
        try:
            self._spi.transfer(self._tx7, rx)
        except OSError:
            self.bus_errors += 1
            return False
        v = (rx[1] << 8) | rx[2]
        self._raw_gx = v - 0x10000 if v & 0x8000 else v
        v = (rx[3] << 8) | rx[4]
        self._raw_gy = v - 0x10000 if v & 0x8000 else v
        v = (rx[5] << 8) | rx[6]
        self._raw_gz = v - 0x10000 if v & 0x8000 else v
        return self._raw_gx != -32768

    def temperature_c(self):
        """Die temperature of the newest FIFO packet: FIFO section, FIFO_TEMP_DATA / 2.07 + 25."""
        t = self.temp_raw - 256 if self.temp_raw & 0x80 else self.temp_raw
        return t / 2.07 + 25.0
