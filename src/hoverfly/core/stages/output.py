"""The output stage: mixer demand in, motor and servo commands out, and the board's output codec.

Step 6 of the pass, in two halves on either side of `board.write_motors`:

- `OutputStage` (in `Flight`): motor demand 0..1 from the mixer -> `motor_out`, the Board
  contract's scale (0 = stop, otherwise idle..max): `motor_idle_pct` is the armed floor,
  `motor_max_pct` the ceiling. Per motor (seed 001's motor parameters, commands 8-11):
  `motorN_min_us` raises that motor's floor and `motorN_max_us` lowers its ceiling, both on the
  PWM scale (1000 us = 0, 2000 us = 1 of motor_out; the encoder scales them to OneShot's widths
  or DShot's throttle range like every command), and a cleared `motor_enable` bit keeps the
  motor at 0 (stop) even armed. Disarmed gives 0 whatever the mixer says. Demand outside 0..1
  (or NaN) is clamped and counted. hoverfly has no 3D mode: 0..1 runs one way only. A
  tricopter's tail position passes through, centred while disarmed (a plane's surfaces are the
  servo mixer's, core/stages/servos.py). With bidirectional DShot it decodes the ESCs' eRPM
  replies (21-bit GCR line codes from the board) into eRPM and RPM per motor, rejecting
  corrupted replies by their GCR and CRC checks.
- `OutputEncoder` (held by a board): `motor_out` -> what the wire carries, for the protocol
  picked by `motor_protocol`: DShot150/300/600/1200 16-bit frames (`words`) or OneShot125,
  OneShot42, Multishot, PWM pulse widths in µs (`pulse_us`); servos as the servo mixer's
  widths in µs (`servo_us`, core/stages/servos.py). It maps motors to output lines
  (`motor_order`), sends the DShot boot commands while every motor is stopped (3D mode off;
  spin direction for `motor_reversed`), and keeps the OUTPUT FAILSAFE: the board's output
  timer calls `tick(now_us)`; when no fresh command came for `output_fs_ms` (100 ms, seed 002)
  every output goes to its disarmed value (DShot 0, the protocol's minimum pulse, each servo at
  its `servoN_mid_us`) until commands resume.

Portable: runs on the Pico (MicroPython) and in the simulator. Nothing here allocates per pass
except float results. With the fixed rate loop (`pid_math`, core/fastpass/fixedrate.py) the motor commands
are worked out in fixed point instead (`OutputStage.update_fixed`, `motors_fixed`): the demand
truncated to Q16, idle + span * demand in Q16 with the span Q14, so a command is within 2**-14 of
the float stage's (a DShot step is 5e-4); its viper twin (accel/output.py) makes no float at all.
"""

from array import array

from hoverfly.compat import IS_MICROPYTHON, const, ticks_diff
from hoverfly.core.config.params import row
from hoverfly.core.stages.mixer import MAX_MOTORS
from hoverfly.protocols import analog
from hoverfly.protocols.dshot import (
    CMD_3D_MODE_OFF,
    CMD_SPIN_DIRECTION_NORMAL,
    CMD_SPIN_DIRECTION_REVERSED,
    KIND_ERPM,
    DshotCommandQueue,
    DshotEncoder,
    ErpmDecoder,
    dshot_frame,
    encode_planned,
)

# The `motor_protocol` choices: dshot150, dshot300, dshot600, dshot1200, oneshot125, oneshot42,
# multishot, pwm (the table row holds the list; the maps below follow its order).
PROTOCOLS = row("motor_protocol")[4]
_DSHOT_KBIT = (150, 300, 600, 1200)
_ANALOG = (analog.ONESHOT125, analog.ONESHOT42, analog.MULTISHOT, analog.PWM)
MAX_SERVOS = 4  # servo lines a board drives (the servo mixer's signals hold 8: core/stages/servos.py)
_INV16 = 1.0 / 65536.0

_viper = None
if IS_MICROPYTHON:
    try:  # generated from motors_fixed and encode_words below by hoverfly.fastgen; absent, or no viper: the Python
        from hoverfly.accel import output as _viper
    except (ImportError, SyntaxError, NameError, ValueError, TypeError):  # TypeError: ViperTypeError
        pass
HAS_ACCEL = _viper is not None
_SERVO_MIN_US = const(500)  # analog.SERVO_LIMIT_MIN_US: the widest range any common servo takes
_SERVO_MAX_US = const(2500)
_CLAMPED_MAX = const(0x3FFFFFFF)  # update_fixed's count saturates here: a 32-bit word in the viper twin


# fastpass: OutputStage.update_fixed norm:f@ out:f@ plan:i@
def motors_fixed(norm, out, plan):
    """out[i] = idle_i + span_i * clamp(norm[i], 0, 1) for i < n in fixed point (plan: array('i') of n,
    then per motor its floor Q16 and span Q14; the demand truncated to Q16); returns how many demands
    were clamped (outside 0..1 or NaN). accel/output.py is generated from it (docs/fastpass.md)."""
    n = plan[0]
    clamped = 0
    for i in range(n):
        idle = plan[1 + 2 * i]
        span = plan[2 + 2 * i]
        m = norm[i]
        if m > 1.0:
            v = 65536
            clamped += 1
        elif not (m >= 0.0):
            v = 0
            clamped += 1
        else:
            v = int(m * 65536.0)
        out[i] = (idle + ((span * v + 8192) >> 14)) * _INV16
    return clamped


# fastpass: OutputEncoder.write motor_out:f@ plan:i@ words:H@
def encode_words(motor_out, count, plan, words):
    """OutputEncoder.write's DShot encode (protocols/dshot.py encode_planned): returns its moving | clamped << 8.
    The viper write generated from the method and this (accel/output.py `write`) reads motor_out's float32 bits
    and makes no float; tests/portable/test_output.py holds the two writes equal."""
    return encode_planned(motor_out, count, plan, words)


def protocol_index(name):
    """Index into PROTOCOLS, -1 if unknown."""
    for i in range(len(PROTOCOLS)):
        if PROTOCOLS[i] == name:
            return i
    return -1


def dshot_speed_kbit(name):
    """150/300/600/1200 for a DShot protocol name, 0 for an analog one (or unknown)."""
    i = protocol_index(name)
    return _DSHOT_KBIT[i] if 0 <= i < 4 else 0


def analog_protocol(name):
    """analog.PWM/ONESHOT125/... for an analog protocol name, -1 for DShot (or unknown)."""
    i = protocol_index(name)
    return _ANALOG[i - 4] if i >= 4 else -1


def parse_motor_order(value, count):
    """`motor_order` (decimal digits: digit k = output line of motor k, 0 = in order) -> (bytes, error).

    2143 on a quad: motor 1 on output 2, motor 2 on 1, motor 3 on 4, motor 4 on 3. The result
    maps motor index -> line index (0-based). A value that is not a permutation of 1..count
    gives the identity and an error string naming the problem.
    """
    ident = bytes(range(count))
    if value == 0:
        return ident, ""
    digits = []
    v = value
    while v > 0:
        digits.append(v % 10)
        v //= 10
    digits.reverse()
    if len(digits) != count:
        return ident, "motor_order %d needs %d digits, one per motor" % (value, count)
    seen = 0
    for d in digits:
        if d < 1 or d > count or seen & (1 << d):
            return ident, "motor_order %d is not an order of outputs 1..%d" % (value, count)
        seen |= 1 << d
    return bytes([d - 1 for d in digits]), ""


class OutputStage:
    """Mixer demand -> motor_out (0 stop, idle..max), servo pass-through, eRPM replies -> RPM."""

    def __init__(self):
        self.motor_count = 4
        self.idle = 0.055
        self.motor_max = 1.0
        self._span = 1.0 - 0.055
        self._idle_q16 = 3604
        self._span_q14 = 15483
        # Per motor (motor_enable, motorN_min_us/_max_us): the armed floor and span, and motors_fixed's
        # plan: motors, then per motor floor Q16, span Q14. A disabled motor: floor and span 0 (stop).
        self.floor = [0.055] * MAX_MOTORS
        self.span = [0.945] * MAX_MOTORS
        self._fixed_plan = array("i", [4] + [3604, 15483] * MAX_MOTORS)
        self.clamped = 0  # motor demand outside 0..1 or NaN
        self.bidir = False
        self.error = ""  # a configuration the board's encoder will also refuse (e.g. motor_order)
        self.decoders = [ErpmDecoder(14) for _ in range(MAX_MOTORS)]
        self.reply_codes = array("i", [0] * MAX_MOTORS)  # filled by board.read_motor_telemetry
        self.replies = 0
        self.reply_errors = 0  # GCR or CRC failures: the value is kept from the last good reply

    def configure(self, params, motor_count):
        self.motor_count = motor_count
        self.idle = params.get("motor_idle_pct") * 0.01
        self.motor_max = params.get("motor_max_pct") * 0.01
        if self.motor_max < self.idle:
            self.motor_max = self.idle
        self._span = self.motor_max - self.idle  # once here, not a float per pass
        self._idle_q16 = int(self.idle * 65536.0 + 0.5)  # update_fixed's
        self._span_q14 = int(self._span * 16384.0 + 0.5)
        plan = self._fixed_plan
        plan[0] = motor_count
        enable = params.get("motor_enable")
        for i in range(MAX_MOTORS):
            lo = self.idle
            hi = self.motor_max
            if i < 4:
                # seed 001's per-motor pulse range on the PWM scale: 1000 us is motor_out 0, 2000 us is 1
                lo_us = params.get("motor%d_min_us" % (i + 1))
                hi_us = params.get("motor%d_max_us" % (i + 1))
                if (lo_us - 1000) * 0.001 > lo:
                    lo = (lo_us - 1000) * 0.001
                if (hi_us - 1000) * 0.001 < hi:
                    hi = (hi_us - 1000) * 0.001
                if hi < lo:
                    hi = lo
            # SAFETY: a disabled motor gets 0 (stop) whatever the mixer asks, armed or not.
            if not enable & (1 << i):
                lo = 0.0
                hi = 0.0
            self.floor[i] = lo
            self.span[i] = hi - lo
            plan[1 + 2 * i] = self._idle_q16 if lo == self.idle else int(lo * 65536.0 + 0.5)
            plan[2 + 2 * i] = self._span_q14 if hi - lo == self._span else int((hi - lo) * 16384.0 + 0.5)
        self.bidir = dshot_speed_kbit(params.get("motor_protocol")) > 0 and params.get("dshot_bidir") == 1
        poles = params.get("motor_poles")
        for d in self.decoders:
            d.pole_count = poles
        self.error = parse_motor_order(params.get("motor_order"), motor_count)[1]

    def update(self, motor_norm, armed, motor_out):
        """motor_out[i] = floor_i + span_i * demand while armed (floor idle, span max - idle unless the
        motor's own range or motor_enable says otherwise), 0 (stop) while disarmed."""
        n = self.motor_count
        if not armed:
            for i in range(n):
                motor_out[i] = 0.0
            return
        floor = self.floor
        span = self.span
        for i in range(n):
            m = motor_norm[i]
            if m > 1.0:
                m = 1.0
                self.clamped += 1
            elif not (m >= 0.0):  # below 0, or NaN: the floor, never a wrap to full
                m = 0.0
                self.clamped += 1
            motor_out[i] = floor[i] + span[i] * m

    def update_fixed(self, motor_norm, armed, motor_out):
        """`update` in fixed point (with the fixed rate loop): the same clamps and counts (saturating
        at 2**30), commands within 2**-14 of update's. On MicroPython the viper twin
        (accel/output.py `update_fixed`, generated from motors_fixed) stands in for this method and makes
        no float; `update_fixed_python` keeps it."""
        # Few locals (see OutputEncoder.write): the pass's every call stays off the heap.
        if not armed:
            self._stop(motor_out)
            return
        c = motors_fixed(motor_norm, motor_out, self._fixed_plan)
        if c:
            self._count_clamped(c)

    update_fixed_python = update_fixed

    def _count_clamped(self, c):
        """update_fixed's clamps, counted (saturating at 2**30: a 32-bit word in the viper twin)."""
        if self.clamped < _CLAMPED_MAX:
            self.clamped += c

    def _stop(self, motor_out):
        for i in range(self.motor_count):
            motor_out[i] = 0.0

    def servos(self, servo_in, count, armed, servo_out):
        """Servo positions -1..1 (clamped, counted); centre while disarmed."""
        for i in range(count):
            s = servo_in[i] if armed else 0.0
            if s > 1.0:
                s = 1.0
                self.clamped += 1
            elif s < -1.0:
                s = -1.0
                self.clamped += 1
            elif s != s:
                s = 0.0
                self.clamped += 1
            servo_out[i] = s

    def decode_replies(self, count, erpm_out, rpm_out):
        """Decode `reply_codes[0..count-1]` (21-bit GCR line codes, motor order) into eRPM and RPM.

        A reply that fails its GCR or CRC check leaves that motor's values as they were and
        counts in `reply_errors`; Extended DShot Telemetry frames update only the decoder.
        """
        decoders = self.decoders
        codes = self.reply_codes
        for i in range(count):
            d = decoders[i]
            kind = d.decode_code(codes[i])
            if kind == KIND_ERPM:
                erpm_out[i] = d.erpm
                rpm_out[i] = d.rpm
                self.replies += 1
            elif kind < 0:
                self.reply_errors += 1

    def decode_reply(self, m, erpm_out, rpm_out):
        """`decode_replies` for motor m alone (the RPM filter takes one motor a pass, round-robin, and a decode
        is a good part of MicroPython's pass: bench/stage_instructions.py output.decode_replies). True if the
        reply was valid (eRPM or Extended DShot Telemetry)."""
        d = self.decoders[m]
        kind = d.decode_code(self.reply_codes[m])
        if kind == KIND_ERPM:
            erpm_out[m] = d.erpm
            rpm_out[m] = d.rpm
            self.replies += 1
        elif kind < 0:
            self.reply_errors += 1
        return kind >= 0


if HAS_ACCEL:
    OutputStage.update_fixed = _viper.update_fixed


class OutputEncoder:
    """motor_out / servo positions -> DShot words or pulse widths per output line, with the output failsafe.

    A board holds one: `configure(params, motor_count, servo_count, now_us)` at boot,
    `write(motor_out, count, now_us)` from `write_motors`, `write_servos(...)` from
    `write_servos`, and `tick(now_us)` from its output timer (whatever the flight pass does).
    Lines are in output order: `words[line]` (DShot), `pulse_us[line]` (analog),
    `servo_us[i]`. `line_of_motor[m]` / `motor_of_line[line]` give the wiring.
    """

    def __init__(self):
        self.protocol = "dshot600"
        self.speed_kbit = 600
        self.analog = -1
        self.dshot = True
        self.bidir = False
        self.motor_count = 0
        self.servo_count = 0
        self.words = array("H", [0] * MAX_MOTORS)
        self.pulse_us = array("f", [0.0] * MAX_MOTORS)
        self.servo_us = array("H", [1500] * MAX_SERVOS)
        self.servo_mid = array("H", [1500] * MAX_SERVOS)  # each line's disarmed and failsafe width
        self.line_of_motor = bytes(range(MAX_MOTORS))
        self.motor_of_line = bytes(range(MAX_MOTORS))
        self.reversed_mask = 0
        self.rate_hz = 480
        self.min_us = 1000.0
        self.len_us = 1000.0
        self.servo_rate_hz = 50
        self.timeout_us = 100000
        self.error = ""
        self.clamped = 0  # commands outside their range, clamped (never wrapped)
        self.writes = 0
        self.failsafe = False  # outputs held at their disarmed values: no fresh command
        self.failsafe_trips = 0
        self.failsafe_at_us = 0
        self._last_us = 0
        self._writes_at_configure = 0  # writes == this: nothing written since configure
        self._stop_word = 0
        self._dshot_enc = DshotEncoder(MAX_MOTORS, False, 0.0, True)
        self._plan = self._dshot_enc.plan(self.line_of_motor)
        self._f32 = None  # the last motor_out seen to be an array('f'): the viper encode reads its bits
        self.commands = DshotCommandQueue(False, 2 + MAX_MOTORS)

    # ------------------------------------------------------------------ set-up
    def configure(self, params, motor_count, servo_count=0, now_us=0):
        """Read the output parameters (at boot, or while disarmed); outputs start disarmed."""
        if motor_count > MAX_MOTORS:
            motor_count = MAX_MOTORS
        if servo_count > MAX_SERVOS:
            servo_count = MAX_SERVOS
        self.motor_count = motor_count
        self.servo_count = servo_count
        name = params.get("motor_protocol")
        self.protocol = name
        self.speed_kbit = dshot_speed_kbit(name)
        self.dshot = self.speed_kbit > 0
        self.analog = analog_protocol(name)
        self.bidir = self.dshot and params.get("dshot_bidir") == 1
        errors = []
        order, err = parse_motor_order(params.get("motor_order"), motor_count)
        if err:
            errors.append(err)
        self.line_of_motor = order
        inv = bytearray(range(MAX_MOTORS))
        for m in range(motor_count):
            inv[order[m]] = m
        self.motor_of_line = bytes(inv)
        self.reversed_mask = params.get("motor_reversed") & ((1 << motor_count) - 1)
        self.timeout_us = params.get("output_fs_ms") * 1000
        self.rate_hz = params.get("motor_pwm_rate")
        if self.dshot:
            self._dshot_enc = DshotEncoder(motor_count, self.bidir, 0.0, True)
            self._plan = self._dshot_enc.plan(order)
            self._stop_word = dshot_frame(0, 0, self.bidir)
        else:
            err = analog.validate_rate(self.analog, self.rate_hz)
            if err:
                errors.append(err)
                lo, hi = analog.rate_limits_hz(self.analog)
                self.rate_hz = lo if self.rate_hz < lo else hi
            self.min_us, hi_us = analog.pulse_range_us(self.analog)
            self.len_us = hi_us - self.min_us
        self.servo_rate_hz = params.get("servo_pwm_rate")
        for i in range(MAX_SERVOS):
            s_min = params.get("servo%d_min_us" % i)
            s_mid = params.get("servo%d_mid_us" % i)
            s_max = params.get("servo%d_max_us" % i)
            err = analog.validate_servo(self.servo_rate_hz, s_min, s_mid, s_max) if i < servo_count else None
            if err:
                errors.append("servo %d: %s" % (i, err))
            # SAFETY: the failsafe width is the servo's own mid, always inside 500..2500 (the row's range)
            self.servo_mid[i] = s_mid
        self.error = "; ".join(errors)
        self.commands = DshotCommandQueue(self.bidir, 2 + MAX_MOTORS)
        if self.dshot:
            self._queue_boot_commands()
        self._last_us = now_us
        self._writes_at_configure = self.writes
        self._f32 = None
        self.failsafe = False
        self._set_disarmed()

    def _queue_boot_commands(self):
        # 3D off first: hoverfly maps 0..1 one way; an ESC left in 3D mode by another controller
        # would read 48 as full reverse. Then spin direction, only when some motor is reversed
        # (SPIN_DIRECTION_NORMAL / _REVERSED are relative to the ESC's own setting, not saved).
        self.commands.push(CMD_3D_MODE_OFF, False, -1)
        mask = self.reversed_mask
        if mask:
            for m in range(self.motor_count):
                cmd = CMD_SPIN_DIRECTION_REVERSED if mask & (1 << m) else CMD_SPIN_DIRECTION_NORMAL
                self.commands.push(cmd, False, self.line_of_motor[m])

    def _set_disarmed(self):
        # SAFETY: the disarmed value of every line: DShot 0 (stop), the minimum pulse, each servo's mid.
        if self.dshot:
            w = self._stop_word
            words = self.words
            for i in range(self.motor_count):
                words[i] = w
        else:
            p = self.pulse_us
            lo = self.min_us
            for i in range(self.motor_count):
                p[i] = lo
        s = self.servo_us
        mid = self.servo_mid
        for i in range(self.servo_count):
            s[i] = mid[i]

    # ---------------------------------------------------------------- the pass
    def write(self, motor_out, count, now_us):
        """Encode motor_out[0..count-1] (0 = stop, otherwise idle..1) onto the lines; a fresh command. On
        MicroPython the viper generated from this method and encode_words (accel/output.py `write`) stands
        in for it; `write_python` keeps it."""
        # One call encodes every motor onto its line (DshotEncoder.plan), from an array('f') seen before
        # (_f32: DShot only); anything else takes _write_other.
        if motor_out is not self._f32 and not (self.dshot and self._takes_bits(motor_out)):
            self._write_other(motor_out, count, now_us)
            return
        r = encode_words(motor_out, count, self._plan, self.words)
        if r > 0xFF:
            self._count_clamped(r >> 8)
        # DShot commands go out only while every motor is stopped; a spinning motor drops them.
        # Idle (the flight's every pass) there is nothing to send or abort: not even the call.
        if self.commands.pending:
            self.commands.apply(now_us, r & 0xFF != 0, self.words)
        self._last_us = now_us
        self.failsafe = False
        self.writes += 1

    def _write_other(self, motor_out, count, now_us):
        """write() for what its encode does not read: an analog protocol's pulse widths, or DShot from a
        list or an array('d') (the Python encode; the same words and counts as write's)."""
        if self.dshot:
            r = encode_planned(motor_out, count, self._plan, self.words)
            if r > 0xFF:
                self._count_clamped(r >> 8)
            if self.commands.pending:
                self.commands.apply(now_us, r & 0xFF != 0, self.words)
        else:
            self._write_analog(motor_out, count)
        self._last_us = now_us
        self.failsafe = False
        self.writes += 1

    def _count_clamped(self, n):
        self._dshot_enc.clamped += n
        self.clamped += n

    def _write_analog(self, motor_out, count):
        n = self.motor_count
        if count < n:
            n = count
        lines = self.line_of_motor
        p = self.pulse_us
        lo = self.min_us
        span = self.len_us
        for m in range(n):
            t = motor_out[m]
            if t > 1.0:
                t = 1.0
                self.clamped += 1
            elif not (t >= 0.0):
                t = 0.0
                self.clamped += 1
            p[lines[m]] = lo + span * t

    def _takes_bits(self, motor_out):
        """True (and remembered) when the viper write may read motor_out's bits: an array of 4-byte
        floats. Anything else (a list, array('d')) takes the Python encode. Without viper the Python
        encode takes anything, so the first motor_out is remembered at once."""
        if _viper is None:
            self._f32 = motor_out
            return True
        if type(motor_out) is not array:
            return False
        n = len(motor_out)
        if n < self.motor_count or len(bytes(motor_out)) != 4 * n or (n and type(motor_out[0]) is not float):
            return False
        self._f32 = motor_out
        return True

    def write_servos(self, servo_us, count, now_us):
        """The servo mixer's widths (µs) onto the servo lines, clamped to what a servo takes (500..2500)."""
        n = self.servo_count
        if count < n:
            n = count
        s = self.servo_us
        for i in range(n):
            w = servo_us[i]  # whole µs (the servo mixer's array('H')), or a float from a bridge
            if w > _SERVO_MAX_US:
                w = _SERVO_MAX_US
                self.clamped += 1
            elif not (w >= _SERVO_MIN_US):  # below the range, or NaN: never a wrap
                w = _SERVO_MIN_US if w < _SERVO_MIN_US else self.servo_mid[i]
                self.clamped += 1
            s[i] = int(w)

    def tick(self, now_us):
        """The output timer's check; True while the output failsafe holds every line at its disarmed value.

        # SAFETY: a pass that stops writing (stalled, crashed, stuck in a loop) must not leave the
        # motors at its last command: after `output_fs_ms` without a write every output is disarmed.
        """
        if self.failsafe:
            return True
        if ticks_diff(now_us, self._last_us) > self.timeout_us:
            self.failsafe = True
            if self.writes != self._writes_at_configure:
                self.failsafe_trips += 1
                self.failsafe_at_us = now_us
            self._set_disarmed()
            return True
        return False


write_python = OutputEncoder.write
if HAS_ACCEL:
    OutputEncoder.write = _viper.write
