"""Analog ESC and servo output codec: normalised commands in, pulse widths and timer counts out.

The output codec for PWM, OneShot125, OneShot42 and Multishot ESCs and for PWM servos,
between the output stage and `board.write_motors` (reference/protocols.md §5). It never
touches a timer: it gives pulse widths (µs float, ns int) and, for a timer clocked at
`timer_clock_hz` and updated at `rate_hz`, the period and compare counts the board loads
(`timer_clock_hz=1_000_000_000` gives ns, e.g. for rp2 `machine.PWM.duty_ns`).

Mapping (Betaflight): `width_us = min_us + len_us * throttle_norm`, i.e. its
`min + len * (x - 1000) / 1000` for a motor value x in 1000..2000:
PWM 1000 + 1000, OneShot125 125 + 125, OneShot42 42 + 42, Multishot 5 + 20 µs.
Disarmed output is the minimum width (Betaflight `mincommand`). Servos map stick_norm
−1..1 to min..centre..max µs (each side linear, configurable). Inputs outside their range
are clamped and counted, never wrapped; `validate_rate` / `validate_servo` return an error
string for settings an ESC or servo cannot take.
"""

from array import array

from hoverfly.compat import const

PWM = const(0)
ONESHOT125 = const(1)
ONESHOT42 = const(2)
MULTISHOT = const(3)
SERVO = const(4)
PROTOCOL_NAMES = ("pwm", "oneshot125", "oneshot42", "multishot", "servo")

# min_us, len_us, lowest rate Hz, highest rate Hz.
# Highest: PWM 490 Hz (classic ESCs and servos: 50..490); the one-shot family is limited by
# its longest pulse (1 / 250 µs = 4 kHz, 1 / 84 µs = 11.9 kHz, 1 / 25 µs = 40 kHz). Lowest:
# 50 Hz for all, the classic servo frame rate (hoverfly's floor; nothing slower is in use).
# Servo: 1000 + 1000 µs by default at 50..333 Hz (333 Hz is the fast digital servo rate).
_TABLE = (
    (1000.0, 1000.0, 50, 490),
    (125.0, 125.0, 50, 4000),
    (42.0, 42.0, 50, 11904),
    (5.0, 20.0, 50, 40000),
    (1000.0, 1000.0, 50, 333),
)
SERVO_LIMIT_MIN_US = const(500)  # widest range any common servo accepts
SERVO_LIMIT_MAX_US = const(2500)

_pulse_clamped = [0]


def pulse_clamped():
    """Inputs `pulse_us`/`pulse_ns`/`servo_pulse_us` clamped since import (or reset)."""
    return _pulse_clamped[0]


def reset_pulse_clamped():
    _pulse_clamped[0] = 0


def protocol_id(name):
    """PWM/ONESHOT125/... for a name ("pwm", "oneshot125", ...), -1 if unknown."""
    name = name.lower()
    for i in range(len(PROTOCOL_NAMES)):
        if PROTOCOL_NAMES[i] == name:
            return i
    return -1


def pulse_range_us(protocol):
    """(min_us, max_us) of a protocol's pulse."""
    row = _TABLE[protocol]
    return row[0], row[0] + row[1]


def rate_limits_hz(protocol):
    row = _TABLE[protocol]
    return row[2], row[3]


def validate_rate(protocol, rate_hz):
    """None when `rate_hz` suits the protocol, else an error string naming the range."""
    if not isinstance(protocol, int) or protocol < 0 or protocol >= len(_TABLE):
        return "unknown analog protocol %r" % (protocol,)
    lo, hi = _TABLE[protocol][2], _TABLE[protocol][3]
    if not (rate_hz >= lo and rate_hz <= hi):
        return "%s rate %g Hz outside %d..%d Hz" % (PROTOCOL_NAMES[protocol], rate_hz, lo, hi)
    return None


def validate_servo(rate_hz, min_us=1000, centre_us=1500, max_us=2000):
    """None when the servo settings are usable, else an error string."""
    err = validate_rate(SERVO, rate_hz)
    if err:
        return err
    if not (SERVO_LIMIT_MIN_US <= min_us < centre_us < max_us <= SERVO_LIMIT_MAX_US):
        return "servo needs %d <= min_us < centre_us < max_us <= %d us, got %s/%s/%s" % (
            SERVO_LIMIT_MIN_US, SERVO_LIMIT_MAX_US, min_us, centre_us, max_us)
    if max_us * rate_hz > 1000000:
        return "servo max_us %s does not fit a %s Hz frame" % (max_us, rate_hz)
    return None


def _clamp01(t):
    if t > 1.0:
        _pulse_clamped[0] += 1
        return 1.0
    if not (t >= 0.0):  # below 0 or NaN
        _pulse_clamped[0] += 1
        return 0.0
    return t


def pulse_us(protocol, throttle_norm):
    """Pulse width (µs, float) for a motor command 0..1 (clamped and counted)."""
    row = _TABLE[protocol]
    return row[0] + row[1] * _clamp01(throttle_norm)


def pulse_ns(protocol, throttle_norm):
    """Pulse width (ns, int, rounded) for a motor command 0..1."""
    return int(pulse_us(protocol, throttle_norm) * 1000.0 + 0.5)


def pulse_us_from_external(protocol, x):
    """Betaflight motor value x (1000..2000) -> width: `min + len * (x - 1000) / 1000`."""
    return pulse_us(protocol, (x - 1000) / 1000.0)


def servo_pulse_us(stick_norm, min_us=1000.0, centre_us=1500.0, max_us=2000.0):
    """Servo width (µs) for stick_norm −1..1: each side linear to its end point."""
    s = stick_norm
    if s > 1.0:
        s = 1.0
        _pulse_clamped[0] += 1
    elif s < -1.0:
        s = -1.0
        _pulse_clamped[0] += 1
    elif s != s:  # NaN -> centre
        s = 0.0
        _pulse_clamped[0] += 1
    if s >= 0.0:
        return centre_us + (max_us - centre_us) * s
    return centre_us + (centre_us - min_us) * s


def counts_of_us(width_us, timer_clock_hz):
    """Timer counts (rounded) for a width at a timer clock."""
    return int(width_us * timer_clock_hz * 1e-6 + 0.5)


def period_counts(timer_clock_hz, rate_hz):
    """Timer period counts (rounded) for an update rate."""
    return int(timer_clock_hz / rate_hz + 0.5)


class AnalogEncoder:
    """Motor commands 0..1 -> compare counts for one analog ESC protocol, nothing allocated but floats.

    protocol: PWM, ONESHOT125, ONESHOT42 or MULTISHOT. rate_hz: update rate (the PWM frame
    rate, or the loop rate for the one-shot family). An unusable rate is clamped into the
    protocol's limits and the reason kept in `error` ("" when fine) — a codec never raises.
    idle_pct / stop_at_zero: as DshotEncoder (armed floor as % of the pulse range; an armed
    command <= 0 gives the minimum pulse when stop_at_zero). Disarmed is the minimum pulse.
    """

    def __init__(self, protocol, rate_hz, timer_clock_hz, motor_count=4, idle_pct=0.0, stop_at_zero=True):
        self.protocol = protocol
        self.motor_count = motor_count
        self.stop_at_zero = bool(stop_at_zero)
        self.clamped = 0
        self.error = validate_rate(protocol, rate_hz) or ""
        if not (0 <= protocol < SERVO):
            self.error = "analog motor protocol must be pwm/oneshot125/oneshot42/multishot, got %r" % (
                protocol,)
            self.protocol = protocol = PWM
        lo, hi = rate_limits_hz(protocol)
        if not (rate_hz >= lo):
            rate_hz = lo
        elif rate_hz > hi:
            rate_hz = hi
        self.rate_hz = rate_hz
        self.timer_clock_hz = timer_clock_hz
        self.period_counts = period_counts(timer_clock_hz, rate_hz)
        self.min_us, self.max_us = pulse_range_us(protocol)
        k = timer_clock_hz * 1e-6  # counts per µs
        self._min_c = self.min_us * k
        self._len_c = (self.max_us - self.min_us) * k
        self.min_counts = counts_of_us(self.min_us, timer_clock_hz)
        self.max_counts = counts_of_us(self.max_us, timer_clock_hz)
        self._low_c = self._min_c
        self._span_c = self._len_c
        self.set_idle_pct(idle_pct)

    def set_idle_pct(self, idle_pct):
        if not (idle_pct >= 0.0):
            idle_pct = 0.0
        elif idle_pct > 100.0:
            idle_pct = 100.0
        self.idle_pct = idle_pct
        self._low_c = self._min_c + self._len_c * idle_pct * 0.01
        self._span_c = self._min_c + self._len_c - self._low_c

    def new_output(self):
        """A zeroed array wide enough for the counts ('H' up to 65535, else 'I')."""
        return array("H" if self.period_counts <= 0xFFFF else "I", [0] * self.motor_count)

    def compare_counts(self, throttle_norm, armed=True):
        """Compare counts for one motor command."""
        if not armed:
            return self.min_counts
        return self._counts(throttle_norm)

    def _counts(self, t):
        if t > 1.0:
            t = 1.0
            self.clamped += 1
        elif not (t >= 0.0):
            self.clamped += 1
            if self.stop_at_zero:
                return self.min_counts
            t = 0.0
        elif t == 0.0 and self.stop_at_zero:
            return self.min_counts
        return int(self._low_c + self._span_c * t + 0.5)

    def pulse_us_of_counts(self, counts):
        return counts * 1e6 / self.timer_clock_hz

    def encode_motors(self, motor_norm, armed, out_counts):
        """Compare counts per motor into out_counts (see new_output).

        # SAFETY: disarmed writes the minimum pulse (mincommand) whatever motor_norm holds.
        """
        n = self.motor_count
        if not armed:
            c = self.min_counts
            for i in range(n):
                out_counts[i] = c
            return
        for i in range(n):
            out_counts[i] = self._counts(motor_norm[i])


class ServoEncoder:
    """Servo commands −1..1 -> compare counts at a timer clock; bad settings fall back to 1000/1500/2000."""

    def __init__(self, rate_hz, timer_clock_hz, min_us=1000, centre_us=1500, max_us=2000, count=1):
        self.error = validate_servo(rate_hz, min_us, centre_us, max_us) or ""
        lo, hi = rate_limits_hz(SERVO)
        if not (rate_hz >= lo):
            rate_hz = lo
        elif rate_hz > hi:
            rate_hz = hi
        if validate_servo(rate_hz, min_us, centre_us, max_us):
            min_us, centre_us, max_us = 1000, 1500, 2000
        self.rate_hz = rate_hz
        self.count = count
        self.clamped = 0
        self.min_us = min_us
        self.centre_us = centre_us
        self.max_us = max_us
        self.timer_clock_hz = timer_clock_hz
        self.period_counts = period_counts(timer_clock_hz, rate_hz)
        k = timer_clock_hz * 1e-6
        self._centre_c = centre_us * k
        self._up_c = (max_us - centre_us) * k
        self._down_c = (centre_us - min_us) * k

    def compare_counts(self, stick_norm):
        s = stick_norm
        if s > 1.0:
            s = 1.0
            self.clamped += 1
        elif s < -1.0:
            s = -1.0
            self.clamped += 1
        elif s != s:
            s = 0.0
            self.clamped += 1
        if s >= 0.0:
            return int(self._centre_c + self._up_c * s + 0.5)
        return int(self._centre_c + self._down_c * s + 0.5)

    def encode(self, stick_norm, out_counts):
        for i in range(self.count):
            out_counts[i] = self.compare_counts(stick_norm[i])
