"""Shared IMU driver base: status codes, health counters, gyro-bias calibration, bus probe.

Takes a bus object (MicroPython `machine.I2C` API, or the small SPI bus of
docs/drivers.md) and gives what every driver shares: the `probe()` contract, the
counters the safety code reads (`bus_errors`, `frozen_count`, `saturated_count`,
`samples`), frozen/saturated watching on raw counts, and the boot gyro calibration of
seed 000 (discard N samples, average N more) as a pure accumulator. Sits under the
board: board.read_imu() -> driver.read() -> flight pass.

Failure contract (one rule for every driver): the constructor never touches the bus;
`probe()` and `configure()` return False on a missing, silent or wrong chip and say why
in `status` (STATUS_*), `read()` returns False on a bus error. Only a programming error
(an unsupported range) raises ValueError, at boot.
"""

from hoverfly.compat import sleep_us

STATUS_UNKNOWN = 0
STATUS_OK = 1
STATUS_ABSENT = 2  # no answer on the bus (I2C NACK / OSError while reading WHO_AM_I)
STATUS_WRONG_ID = 3  # something answered, but not this chip
STATUS_BUS_ERROR = 4  # the chip answered WHO_AM_I, then a configuration transfer failed
STATUS_NOT_READY = 5  # the chip answered but did not come up (BNO055 fusion not running)
STATUS_NAMES = ("unknown", "ok", "absent", "wrong_id", "bus_error", "not_ready")

GRAVITY_M_S2 = 9.80665  # standard gravity (CGPM 1901): datasheets give accel sensitivity in LSB/g
DEG_TO_RAD = 0.017453292519943295

# Consecutive identical raw samples before the sensor counts as frozen. At 1 kHz with
# datasheet noise (MPU-6050 0.05 °/s-rms, 400 µg/√Hz) six 16-bit values repeating even
# twice is rare; 8 in a row is a stuck bus or a dead chip.
FROZEN_SAMPLES_DEFAULT = 8


def signed16(hi, lo):
    """Two bytes to a signed 16-bit int (reference twin of the drivers' inline decode)."""
    v = (hi << 8) | lo
    if v & 0x8000:
        v -= 0x10000
    return v


class GyroBiasAverager:
    """Pure accumulator of raw gyro counts for boot calibration (seed 000: average 500 at rest).

    `add(x, y, z)` takes raw chip-frame counts. `mean16(axis)` is the mean in 1/16 LSB
    (an int, so the driver subtracts it without floats); `spread_lsb()` is the largest
    max-min over the axes, the stillness test.
    """

    def __init__(self):
        self.reset()

    def reset(self):
        self.count = 0
        self.sum_x = 0
        self.sum_y = 0
        self.sum_z = 0
        self.min_x = self.min_y = self.min_z = 32767
        self.max_x = self.max_y = self.max_z = -32768

    def add(self, x, y, z):
        self.count += 1
        self.sum_x += x
        self.sum_y += y
        self.sum_z += z
        if x < self.min_x:
            self.min_x = x
        if x > self.max_x:
            self.max_x = x
        if y < self.min_y:
            self.min_y = y
        if y > self.max_y:
            self.max_y = y
        if z < self.min_z:
            self.min_z = z
        if z > self.max_z:
            self.max_z = z

    def spread_lsb(self):
        if self.count == 0:
            return 0
        s = self.max_x - self.min_x
        if self.max_y - self.min_y > s:
            s = self.max_y - self.min_y
        if self.max_z - self.min_z > s:
            s = self.max_z - self.min_z
        return s

    def mean16(self, axis):
        """Mean of one axis (0, 1, 2) in 1/16 LSB, rounded to nearest."""
        if self.count == 0:
            return 0
        total = self.sum_x if axis == 0 else (self.sum_y if axis == 1 else self.sum_z)
        n = self.count
        # round(total * 16 / n) in integers
        num = total * 16
        if num >= 0:
            return (num + n // 2) // n
        return -((-num + n // 2) // n)


class Imu:
    """Base of the register-level IMU drivers (single inheritance; see the module docstring)."""

    name = "imu"

    def __init__(self, orientation, delay_us=None):
        self._orientation = orientation
        self._delay_us = delay_us if delay_us is not None else sleep_us
        self.status = STATUS_UNKNOWN
        self.who_am_i = -1
        # Health counters the safety code reads (never reset by the driver).
        self.bus_errors = 0
        self.frozen_count = 0
        self.saturated_count = 0
        self.samples = 0
        # Flags of the newest sample.
        self.frozen = False
        self.saturated = False
        self.frozen_samples = FROZEN_SAMPLES_DEFAULT
        self._same = 0
        self._l0 = self._l1 = self._l2 = self._l3 = self._l4 = self._l5 = 0
        # Gyro bias in 1/16 LSB, chip frame (set by calibrate_gyro).
        self._bias16_x = 0
        self._bias16_y = 0
        self._bias16_z = 0
        self.gyro_bias_rad_s = [0.0, 0.0, 0.0]  # body frame, for reports
        self.gyro_range_dps = 0
        self.accel_range_g = 0
        self._gyro_k16 = 0.0  # rad/s per 1/16 LSB
        self._accel_k = 0.0  # m/s² per LSB

    def status_name(self):
        return STATUS_NAMES[self.status]

    def healthy(self):
        return self.status == STATUS_OK and not self.frozen

    def _watch(self, g0, g1, g2, a0, a1, a2):
        """Frozen and saturated bookkeeping on raw counts (ints only, no allocation)."""
        if (g0 == self._l0 and g1 == self._l1 and g2 == self._l2
                and a0 == self._l3 and a1 == self._l4 and a2 == self._l5):
            self._same += 1
            if self._same >= self.frozen_samples:
                self.frozen = True
                self.frozen_count += 1
        else:
            self._same = 0
            self.frozen = False
            self._l0 = g0
            self._l1 = g1
            self._l2 = g2
            self._l3 = a0
            self._l4 = a1
            self._l5 = a2
        # A 16-bit output pinned at either rail means the true value is off the scale.
        if (g0 >= 32767 or g0 <= -32767 or g1 >= 32767 or g1 <= -32767 or g2 >= 32767 or g2 <= -32767
                or a0 >= 32767 or a0 <= -32767 or a1 >= 32767 or a1 <= -32767
                or a2 >= 32767 or a2 <= -32767):
            self.saturated = True
            self.saturated_count += 1
        else:
            self.saturated = False

    # --- boot gyro calibration (seed 000) ---------------------------------------------
    def _read_gyro_raw(self):
        """Drivers: one sample into self._raw_gx/_raw_gy/_raw_gz (chip frame); False on bus error."""
        raise NotImplementedError

    def calibrate_gyro(self, samples=500, discard=500, still_dps=4.0, sample_delay_us=1000):
        """Seed 000: read and drop `discard` samples, then average `samples` at rest.

        The bias (chip frame, 1/16 LSB) is applied to every later read() only if the gyro
        stayed still (max-min of every axis within `still_dps`); returns that verdict.
        Bus errors skip a sample (and count); if more than half fail, returns False.
        Boot only: it blocks for (samples + discard) * sample_delay_us.
        """
        if self._gyro_k16 == 0.0:
            return False
        delay = self._delay_us
        failures = 0
        i = 0
        while i < discard:
            if not self._read_gyro_raw():
                failures += 1
            i += 1
            delay(sample_delay_us)
        acc = GyroBiasAverager()
        tries = 0
        while acc.count < samples and tries < 2 * samples:
            tries += 1
            if self._read_gyro_raw():
                acc.add(self._raw_gx, self._raw_gy, self._raw_gz)
            else:
                failures += 1
            delay(sample_delay_us)
        self.calibration_failures = failures
        if acc.count < samples:
            return False
        # still_dps in LSB: k16 is rad/s per 1/16 LSB, so one LSB is 16 * k16 rad/s.
        limit_lsb = still_dps * DEG_TO_RAD / (16.0 * self._gyro_k16)
        self.calibration_spread_lsb = acc.spread_lsb()
        if self.calibration_spread_lsb > limit_lsb:
            return False
        self.set_gyro_bias16(acc.mean16(0), acc.mean16(1), acc.mean16(2))
        return True

    def set_gyro_bias16(self, bx16, by16, bz16):
        """Gyro bias in 1/16 LSB, chip frame (calibrate_gyro's result, or a stored one)."""
        self._bias16_x = bx16
        self._bias16_y = by16
        self._bias16_z = bz16
        self._orientation.rotate_scaled(bx16, by16, bz16, self._gyro_k16, self.gyro_bias_rad_s)

