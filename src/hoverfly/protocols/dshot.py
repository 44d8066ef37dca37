"""DShot codec: motor commands in, 16-bit frames out; bidirectional eRPM / EDT replies in, values out.

Sits at the end of the pass (the output codec between the mixer/output stage and
`board.write_motors`) and, for bidirectional DShot, at the start of the RPM filter path.
It never touches a pin: the rp2 board pushes the words this module builds into a PIO
state machine (`sm.put(word, PIO_SHIFT)`), the simulator's ESC model reads them back.
Facts and vectors: reference/protocols.md §4; PIO numbers: reference/micropython.md §3.1.

Gives:
- `dshot_frame(value, telemetry=0, bidir=False)`: the 16-bit word `vvvvvvvvvvv t cccc`
  (11-bit value, telemetry bit, nibble-XOR CRC, inverted for bidirectional). Values
  outside 0..2047 are clamped (never wrapped) and counted in `frame_clamped()`.
- `DshotEncoder(motor_count, bidir, idle_pct, stop_at_zero)`: `throttle_to_value` and
  `encode_motors(motor_norm, armed, out_words)` into a preallocated array('H').
- Special commands 1..47 (`COMMAND_NAMES`, `command_repeats`, `command_delay_us`) and
  `DshotCommandQueue`, which repeats a command with the required gaps, then hands the
  line back to throttle; refuses values outside 1..47 and anything while armed.
- Bit timings for DShot150/300/600/1200 and the PIO constants (`dshot_timing`).
- Bidirectional reply: GCR line code <-> 16-bit word (`gcr_encode`, `gcr_decode`,
  `levels_to_code`, `code_to_levels`), reply CRC, period <-> eRPM <-> RPM, Extended
  DShot Telemetry kinds (`ErpmDecoder`, `decode_reply`), and the encoders a simulated
  ESC needs (`erpm_reply_word`, `period_reply_word`, `edt_reply_word`).

Throttle mapping (Betaflight `motorInitEndpoints` + `dshotWrite`): armed output runs from
`low = 48 + 1999 * idle_pct / 100` to 2047, `value = round(low + (2047 - low) * throttle_norm)`;
disarmed (and, with `stop_at_zero`, a motor command of exactly 0 or below) is 0 = motor stop.
"""

from array import array

from hoverfly.compat import IS_MICROPYTHON, const, ticks_add, ticks_diff

VALUE_MAX = const(2047)
THROTTLE_MIN = const(48)  # 1..47 are commands; 48..2047 is the 2000-step throttle range
THROTTLE_RANGE = const(1999)  # 2047 - 48
COMMAND_MIN = const(1)
COMMAND_MAX = const(47)

# ---------------------------------------------------------------------------------------------
# Frame


_frame_clamped = [0]  # values outside 0..2047 handed to dshot_frame (clamped, never wrapped)


def frame_clamped():
    """How many out-of-range values `dshot_frame` has clamped since import (or reset)."""
    return _frame_clamped[0]


def reset_frame_clamped():
    _frame_clamped[0] = 0


def dshot_frame(value, telemetry=0, bidir=False):
    """16-bit DShot word for an 11-bit `value`; out-of-range values clamp to 0..2047 and count."""
    if value < 0:
        value = 0
        _frame_clamped[0] += 1
    elif value > VALUE_MAX:
        value = VALUE_MAX
        _frame_clamped[0] += 1
    w = (value << 1) | (1 if telemetry else 0)
    c = w ^ (w >> 4) ^ (w >> 8)
    if bidir:
        c = ~c
    return (w << 4) | (c & 0xF)


def frame_value(word):
    """The 11-bit value of a 16-bit DShot word."""
    return (word >> 5) & 0x7FF


def frame_telemetry(word):
    return (word >> 4) & 1


def frame_crc_ok(word, bidir=False):
    """True when the word's CRC nibble matches (inverted CRC for bidirectional DShot)."""
    w = (word >> 4) & 0xFFF
    c = w ^ (w >> 4) ^ (w >> 8)
    if bidir:
        c = ~c
    return (c & 0xF) == (word & 0xF)


def value_from_external(x):
    """Betaflight's external motor scale (MSP motor test, `motor` CLI) to a DShot value.

    1000 (or less) -> 0 stop; 1001..2000 -> 48..2047, `48 + (x - 1001) * 1999 / 999`
    truncated as Betaflight's uint16 cast does (1500 -> 1046).
    """
    if x <= 1000:
        return 0
    if x >= 2000:
        return VALUE_MAX
    return THROTTLE_MIN + (x - 1001) * THROTTLE_RANGE // 999


def pio_word(frame):
    """The 32-bit word a PIO state machine with out_shiftdir left and autopull 16 takes.

    On the rp2 prefer `sm.put(frame, PIO_SHIFT)`: the shift then happens in C, while
    `frame << 16` is above 2**30 (a heap int on the rp2) for frames >= 0x4000.
    """
    return frame << 16


# ---------------------------------------------------------------------------------------------
# Bit timing and the PIO program's constants (reference/protocols.md §4.1, micropython.md §3.1)

SPEEDS_KBIT = (150, 300, 600, 1200)
FRAME_BITS = const(16)
PIO_CYCLES_PER_BIT = const(8)
PIO_CYCLES_HIGH_1 = const(6)  # 6/8 = 75 % of the bit: nominal T1H
PIO_CYCLES_HIGH_0 = const(3)  # 3/8 = 37.5 %: nominal T0H
PIO_SHIFT = const(16)  # sm.put(frame, PIO_SHIFT): the word sits in the OSR's top 16 bits
REPLY_DELAY_US = const(30)  # ESC answers ~30 us after the frame, whatever the speed


def dshot_timing(speed_kbit):
    """(bit_ns, t0h_ns, t1h_ns, frame_ns, sm_freq_hz, reply_bit_ns) for 150/300/600/1200; None otherwise.

    ns values are rounded to whole ns (DShot150 bit 6666.7 -> 6667). The reply runs at
    5/4 of the command bit rate.
    """
    if speed_kbit not in SPEEDS_KBIT:
        return None
    bit_ns = (1000000 + speed_kbit // 2) // speed_kbit
    t0h_ns = (1000000 * 3 + speed_kbit * 4) // (speed_kbit * 8)
    t1h_ns = (1000000 * 6 + speed_kbit * 4) // (speed_kbit * 8)
    frame_ns = (1000000 * FRAME_BITS + speed_kbit // 2) // speed_kbit
    sm_freq_hz = PIO_CYCLES_PER_BIT * speed_kbit * 1000
    reply_bit_ns = (800000 + speed_kbit // 2) // speed_kbit
    return (bit_ns, t0h_ns, t1h_ns, frame_ns, sm_freq_hz, reply_bit_ns)


# ---------------------------------------------------------------------------------------------
# Special commands (reference/protocols.md §4.2). Values 1..47, sent with t = 1.

CMD_MOTOR_STOP = const(0)
CMD_BEEP1 = const(1)
CMD_BEEP2 = const(2)
CMD_BEEP3 = const(3)
CMD_BEEP4 = const(4)
CMD_BEEP5 = const(5)
CMD_ESC_INFO = const(6)
CMD_SPIN_DIRECTION_1 = const(7)
CMD_SPIN_DIRECTION_2 = const(8)
CMD_3D_MODE_OFF = const(9)
CMD_3D_MODE_ON = const(10)
CMD_SETTINGS_REQUEST = const(11)
CMD_SAVE_SETTINGS = const(12)
CMD_EXTENDED_TELEMETRY_ENABLE = const(13)
CMD_EXTENDED_TELEMETRY_DISABLE = const(14)
CMD_SPIN_DIRECTION_NORMAL = const(20)
CMD_SPIN_DIRECTION_REVERSED = const(21)
CMD_LED0_ON = const(22)
CMD_LED0_OFF = const(26)
CMD_AUDIO_STREAM_MODE = const(30)
CMD_SILENT_MODE = const(31)

REPEAT_GAP_US = const(1000)  # Betaflight spaces repeats ~1 ms apart

# value, name, repeats, wait after the last repeat (ms).
# Repeats: Betaflight's figure where it has one (1 or 10). Rows it does not send ("—" in
# the reference) get 6, the count AM32 and the EDT spec need before they act. Waits: the
# ESC-side minimums (beacon 260 ms, where Betaflight waits 100 ms; ESC info 12 ms; save 35 ms).
_COMMAND_ROWS = (
    (1, "BEEP1", 1, 260),
    (2, "BEEP2", 1, 260),
    (3, "BEEP3", 1, 260),
    (4, "BEEP4", 1, 260),
    (5, "BEEP5", 1, 260),
    (6, "ESC_INFO", 1, 12),
    (7, "SPIN_DIRECTION_1", 10, 0),
    (8, "SPIN_DIRECTION_2", 10, 0),
    (9, "3D_MODE_OFF", 10, 0),
    (10, "3D_MODE_ON", 10, 0),
    (11, "SETTINGS_REQUEST", 6, 0),
    (12, "SAVE_SETTINGS", 10, 35),
    (13, "EXTENDED_TELEMETRY_ENABLE", 10, 0),
    (14, "EXTENDED_TELEMETRY_DISABLE", 10, 0),
    (20, "SPIN_DIRECTION_NORMAL", 10, 0),
    (21, "SPIN_DIRECTION_REVERSED", 10, 0),
    (22, "LED0_ON", 1, 0),
    (23, "LED1_ON", 1, 0),
    (24, "LED2_ON", 1, 0),
    (25, "LED3_ON", 1, 0),
    (26, "LED0_OFF", 1, 0),
    (27, "LED1_OFF", 1, 0),
    (28, "LED2_OFF", 1, 0),
    (29, "LED3_OFF", 1, 0),
    (30, "AUDIO_STREAM_MODE", 1, 0),
    (31, "SILENT_MODE", 1, 0),
    (32, "SIGNAL_LINE_TELEMETRY_DISABLE", 6, 0),
    (33, "SIGNAL_LINE_TELEMETRY_ENABLE", 6, 0),
    (34, "SIGNAL_LINE_CONTINUOUS_ERPM", 6, 0),
    (35, "SIGNAL_LINE_CONTINUOUS_ERPM_PERIOD", 6, 0),
    (36, "AM32_PROGRAMMING_MODE", 6, 0),
    (42, "SIGNAL_LINE_TEMPERATURE", 6, 0),
    (43, "SIGNAL_LINE_VOLTAGE", 6, 0),
    (44, "SIGNAL_LINE_CURRENT", 6, 0),
    (45, "SIGNAL_LINE_CONSUMPTION", 6, 0),
    (46, "SIGNAL_LINE_ERPM", 6, 0),
    (47, "SIGNAL_LINE_ERPM_PERIOD", 6, 0),
)


def _command_tables():
    names = ["MOTOR_STOP"] + ["UNASSIGNED"] * COMMAND_MAX
    repeats = bytearray(COMMAND_MAX + 1)
    delay_ms = array("H", [0] * (COMMAND_MAX + 1))
    for i in range(1, COMMAND_MAX + 1):
        repeats[i] = 6  # unassigned values: as the "—" rows
    for value, name, rep, wait_ms in _COMMAND_ROWS:
        names[value] = name
        repeats[value] = rep
        delay_ms[value] = wait_ms
    return tuple(names), bytes(repeats), delay_ms


COMMAND_NAMES, COMMAND_REPEATS, _COMMAND_DELAY_MS = _command_tables()


def command_repeats(value):
    """How many identical frames to send for command `value` (0 outside 1..47)."""
    if value < COMMAND_MIN or value > COMMAND_MAX:
        return 0
    return COMMAND_REPEATS[value]


def command_delay_us(value):
    """How long to wait after the last repeat before the next command (0 outside 1..47)."""
    if value < COMMAND_MIN or value > COMMAND_MAX:
        return 0
    return _COMMAND_DELAY_MS[value] * 1000


def command_value(name):
    """Command number for a name (`BEEP1`, Betaflight's `BEACON1`, `DSHOT_CMD_...`); -1 if unknown."""
    name = name.upper()
    if name.startswith("DSHOT_CMD_"):
        name = name[10:]
    if name.startswith("BEACON"):
        name = "BEEP" + name[6:]
    for i in range(len(COMMAND_NAMES)):
        if COMMAND_NAMES[i] == name and name != "UNASSIGNED":
            return i
    return -1


# ---------------------------------------------------------------------------------------------
# Motor encoder


def _fixed_point_range(idle_pct):
    """(low + 0.5, span) of the armed range in 1/65536 steps: value = (low_fp + span_fp * t) >> 16."""
    if not (idle_pct >= 0.0):
        idle_pct = 0.0
    elif idle_pct > 100.0:
        idle_pct = 100.0
    low = THROTTLE_MIN + THROTTLE_RANGE * idle_pct * 0.01
    low_fp = int((low + 0.5) * 65536.0)  # + 0.5: round half up
    return low_fp, int((VALUE_MAX - low) * 65536.0)


class DshotEncoder:
    """Normalised motor commands -> DShot words, one per motor, without allocating words or arrays.

    idle_pct: armed output floor as Betaflight's `dshot_idle_value` (percent of the 1999-step
    range above 48). Leave it 0 when the output stage has already applied idle (the Board
    contract: 0 = stop, otherwise idle..1).
    stop_at_zero: an armed motor command <= 0 gives 0 (stop) instead of the idle value — the
    Board contract's "0 = stop". Betaflight's own behaviour is stop_at_zero=False.
    telemetry_motor: index of the motor whose frame carries t = 1 this time (-1 = none);
    KISS/BLHeli_32 serial telemetry asks one motor at a time.
    """

    def __init__(self, motor_count, bidir=False, idle_pct=0.0, stop_at_zero=True):
        self.motor_count = motor_count
        self.bidir = bool(bidir)
        self.stop_at_zero = bool(stop_at_zero)
        self.telemetry_motor = -1
        self.clamped = 0  # motor commands outside 0..1 (or NaN) clamped
        self.idle_pct = 0.0
        self._low_fp = 0
        self._span_fp = 0
        self.set_idle_pct(idle_pct)

    def set_idle_pct(self, idle_pct):
        """Configure-time: the armed floor; out-of-range idle is clamped to 0..100 %."""
        if not (idle_pct >= 0.0):
            idle_pct = 0.0
        elif idle_pct > 100.0:
            idle_pct = 100.0
        self.idle_pct = idle_pct
        self._low_fp, self._span_fp = _fixed_point_range(idle_pct)

    def throttle_to_value(self, throttle_norm, idle_pct=None, armed=True):
        """11-bit DShot value for a motor command 0..1: disarmed -> 0, armed -> 48 + idle .. 2047."""
        if not armed:
            return 0
        if idle_pct is None:
            return self._value(throttle_norm, self._low_fp, self._span_fp)
        low_fp, span_fp = _fixed_point_range(idle_pct)
        return self._value(throttle_norm, low_fp, span_fp)

    def _value(self, t, low_fp, span_fp):
        # Fixed point, 16 fraction bits: one float product per motor (each float result is a
        # heap object on MicroPython), the rest small-int arithmetic below 2**30.
        if t > 1.0:
            t = 1.0
            self.clamped += 1
        elif not (t >= 0.0):  # below 0, or NaN
            self.clamped += 1
            if self.stop_at_zero:
                return 0
            t = 0.0
        elif t == 0.0 and self.stop_at_zero:
            return 0
        v = (low_fp + int(span_fp * t)) >> 16
        if v > VALUE_MAX:
            v = VALUE_MAX
        return v

    def encode_motors(self, motor_norm, armed, out_words):
        """Write one DShot word per motor into out_words (array('H'), len >= motor_count).

        Returns how many words differ from the stop word (0: every motor stopped).
        # SAFETY: disarmed writes the stop word for every motor whatever motor_norm holds.
        """
        bidir = self.bidir
        n = self.motor_count
        if not armed:
            stop = dshot_frame(0, 0, bidir)
            for i in range(n):
                out_words[i] = stop
            return 0
        # The board codec's own encode with motor k on line k (a plan made per call: tools and tests use
        # this method; OutputEncoder.write keeps its plan).
        r = encode_planned(motor_norm, n, self.plan(range(n)), out_words)
        if r > 0xFF:
            self.clamped += r >> 8
        return r & 0xFF

    def plan(self, lines):
        """The array('i') `encode_planned` follows for this encoder, motor k on line lines[k]."""
        flags = (PLAN_STOP_AT_ZERO if self.stop_at_zero else 0) | (PLAN_BIDIR if self.bidir else 0)
        tm = self.telemetry_motor
        p = array("i", [self.motor_count, self._low_fp, self._span_fp, flags, tm + 1 if 0 <= tm else 0]
                  + [0] * self.motor_count)
        for k in range(self.motor_count):
            p[PLAN_LINES + k] = lines[k]
        return p

    def encode_values(self, values, out_words):
        """Integer path: 11-bit values (already mapped) -> words; clamps and counts like dshot_frame."""
        bidir = self.bidir
        tm = self.telemetry_motor
        for i in range(self.motor_count):
            v = values[i]
            if v < 0:
                v = 0
                self.clamped += 1
            elif v > VALUE_MAX:
                v = VALUE_MAX
                self.clamped += 1
            w = (v << 1) | (1 if i == tm else 0)
            c = w ^ (w >> 4) ^ (w >> 8)
            if bidir:
                c = ~c
            out_words[i] = (w << 4) | (c & 0xF)


# The plan `encode_planned` follows (array('i'), DshotEncoder.plan): the motor count, the fixed-point
# range, the flags, the telemetry motor + 1, then each motor's output line.
PLAN_STOP_AT_ZERO = const(1)
PLAN_BIDIR = const(2)
PLAN_LINES = const(5)


# fastpass: encode_planned motor_norm:f plan:i out_words:H
def encode_planned(motor_norm, count, plan, out_words):
    """DshotEncoder.encode_motors' armed loop, planned: motor k's word goes to out_words[line k].

    motor_norm[0..count-1] (clamped to the plan's motor count) -> 16-bit words; returns
    moving | clamped << 8 (moving: words that are not the stop word; clamped: commands outside
    0..1 or NaN). The same words as encode_motors for the same encoder. Its viper twin (accel/dshot.py,
    generated from it by hoverfly.fastgen) reads an array('f')'s float32 bits and makes no float:
    `int(span_fp * t)` is worked out on integers as this port's float product is (span_fp < 2**27,
    t within 0..1 here); tests/portable/test_dshot_planned.py holds the two equal.
    """
    n = plan[0]
    if count < n:
        n = count
    low_fp = plan[1]
    span_fp = plan[2]
    flags = plan[3]
    tm = plan[4] - 1
    stop_at_zero = flags & PLAN_STOP_AT_ZERO
    bidir = flags & PLAN_BIDIR
    moving = 0
    clamped = 0
    for i in range(n):
        t = motor_norm[i]
        v = -1
        if t > 1.0:
            t = 1.0
            clamped += 1
        elif not (t >= 0.0):  # below 0, or NaN
            clamped += 1
            if stop_at_zero:
                v = 0
            else:
                t = 0.0
        elif t == 0.0 and stop_at_zero:
            v = 0
        if v < 0:
            v = (low_fp + int(span_fp * t)) >> 16
            if v > VALUE_MAX:
                v = VALUE_MAX
        w = (v << 1) | (1 if i == tm else 0)
        if w:
            moving += 1
        c = w ^ (w >> 4) ^ (w >> 8)
        if bidir:
            c = ~c
        out_words[plan[PLAN_LINES + i]] = (w << 4) | (c & 0xF)
    return moving | (clamped << 8)


# The board codec's whole encode (OutputEncoder.write): on MicroPython the viper generated from
# encode_planned, for an array('f') of commands; None elsewhere (encode_planned runs).
encode_planned_f32 = None
if IS_MICROPYTHON:
    try:  # absent (never generated) or a port without viper: OutputEncoder.write runs the Python
        from hoverfly.accel.dshot import encode_planned as encode_planned_f32  # noqa: F401 (output.py's)
    except (ImportError, SyntaxError, NameError, ValueError, TypeError):  # TypeError: ViperTypeError
        pass

# ---------------------------------------------------------------------------------------------
# Command queue

_IDLE = const(0)
_ACTIVE = const(1)
_POSTDELAY = const(2)


class DshotCommandQueue:
    """Special commands, repeated as the ESCs need, then back to throttle.

    `push(command, armed, motor=-1)` queues a command for one motor or all (-1); it returns
    True, or an error string (counted in `refused`) for values outside 1..47, while armed,
    or when the queue is full. Each frame call `apply(now_us, armed, out_words)` after the
    encoder (it overwrites the target motors' words when a repeat is due) or
    `word(now_us, armed, throttle_word)` for one line. The first repeat goes out at once,
    the next ones `REPEAT_GAP_US` apart; between repeats and during the wait after the last
    one the caller's own word (stop, while disarmed) goes out.
    # SAFETY: arming drops every queued command (counted in `aborted`): a command frame is
    # never sent to an armed ESC, and throttle is never replaced by a command.
    """

    def __init__(self, bidir=False, capacity=8):
        self.bidir = bool(bidir)
        self._cmds = bytearray(capacity)
        self._motors = array("b", [0] * capacity)
        self._head = 0
        self._count = 0
        self._state = _IDLE
        self._cmd = 0
        self._motor = -1
        self._word = 0
        self._left = 0
        self._next_us = 0
        self.refused = 0
        self.aborted = 0
        self.sent = 0  # command frames handed out
        self.last_error = ""
        self.pending = False  # busy(), kept as a plain attribute: the encoder's every pass reads it

    def busy(self):
        return self._state != _IDLE or self._count > 0

    def _refuse(self, why):
        self.refused += 1
        self.last_error = why
        return why

    def push(self, command, armed, motor=-1):
        if not isinstance(command, int) or command < COMMAND_MIN or command > COMMAND_MAX:
            return self._refuse("dshot command %r outside 1..47" % (command,))
        if armed:
            return self._refuse("dshot command %d refused while armed" % command)
        cap = len(self._cmds)
        if self._count >= cap:
            return self._refuse("dshot command queue full (%d)" % cap)
        i = (self._head + self._count) % cap
        self._cmds[i] = command
        self._motors[i] = motor
        self._count += 1
        self.pending = True
        return True

    def clear(self):
        if self.busy():
            self.aborted += 1
        self._count = 0
        self._state = _IDLE
        self.pending = False

    def _step(self, now_us, armed):
        """The command word due this frame, or -1."""
        if armed:
            if self._state != _IDLE or self._count:
                self.aborted += 1
                self._count = 0
                self._state = _IDLE
                self.pending = False
            return -1
        state = self._state
        if state == _POSTDELAY:
            if ticks_diff(now_us, self._next_us) < 0:
                return -1
            self._state = state = _IDLE
        if state == _IDLE:
            if not self._count:
                self.pending = False
                return -1
            h = self._head
            self._cmd = self._cmds[h]
            self._motor = self._motors[h]
            self._head = (h + 1) % len(self._cmds)
            self._count -= 1
            self._word = dshot_frame(self._cmd, 1, self.bidir)
            self._left = COMMAND_REPEATS[self._cmd]
            self._state = _ACTIVE
        elif ticks_diff(now_us, self._next_us) < 0:  # _ACTIVE, between repeats
            return -1
        self._left -= 1
        self.sent += 1
        if self._left > 0:
            self._next_us = ticks_add(now_us, REPEAT_GAP_US)
        else:
            self._next_us = ticks_add(now_us, _COMMAND_DELAY_MS[self._cmd] * 1000)
            self._state = _POSTDELAY
        return self._word

    def word(self, now_us, armed, throttle_word):
        """The word to send on one line this frame."""
        w = self._step(now_us, armed)
        return throttle_word if w < 0 else w

    def apply(self, now_us, armed, out_words):
        """Overwrite the target motor words with the command when one is due; True if it did."""
        if armed and self._state == _IDLE and not self._count:
            return False  # the flight's every pass: nothing queued, nothing to abort (_step's answer)
        w = self._step(now_us, armed)
        if w < 0:
            return False
        m = self._motor
        if m < 0:
            for i in range(len(out_words)):
                out_words[i] = w
        elif m < len(out_words):
            out_words[m] = w
        return True


# ---------------------------------------------------------------------------------------------
# Bidirectional reply: GCR line code, CRC, period / eRPM / RPM, Extended DShot Telemetry

# nibble -> 5-bit GCR quintet (reference/protocols.md §4.3)
GCR_ENCODE = bytes(
    (0x19, 0x1B, 0x12, 0x13, 0x1D, 0x15, 0x16, 0x17, 0x1A, 0x09, 0x0A, 0x0B, 0x1E, 0x0D, 0x0E, 0x0F)
)


def _gcr_decode_table():
    t = bytearray(b"\xff" * 32)
    for n in range(16):
        t[GCR_ENCODE[n]] = n
    return bytes(t)


GCR_DECODE = _gcr_decode_table()  # quintet -> nibble, 0xFF = not a GCR code
_START = const(0x100000)  # bit 20 of the 21-bit line code: the start bit (always a toggle)
_MASK21 = const(0x1FFFFF)

STOPPED = const(0xFFF)  # 12-bit reply value for "motor stopped"
# 511 << 7: the longest period a reply can carry, and it is the stop code itself, so the
# slowest motor a reply can show runs at 60e6 / 65407 = 918 eRPM; slower reads as stopped.
PERIOD_MAX_US = const(65408)

KIND_INVALID = const(-1)
KIND_ERPM = const(0)
KIND_TEMPERATURE = const(1)  # prefix 0010, °C
KIND_VOLTAGE = const(2)  # prefix 0100, 0.25 V per LSB
KIND_CURRENT = const(3)  # prefix 0110, A
KIND_DEBUG1 = const(4)  # prefix 1000
KIND_DEBUG2 = const(5)  # prefix 1010
KIND_STRESS = const(6)  # prefix 1100
KIND_STATUS = const(7)  # prefix 1110: status/events; 0xE00|version answers command 13, 0xEFF command 14
KIND_NAMES = ("erpm", "temperature", "voltage", "current", "debug1", "debug2", "stress", "status")


def reply_word(value12):
    """16-bit reply word for a 12-bit value: the CRC is the inverted nibble XOR."""
    v = value12 & 0xFFF
    return (v << 4) | (~(v ^ (v >> 4) ^ (v >> 8)) & 0xF)


def reply_crc_ok(word):
    """Receiver check: the XOR of all four nibbles of a valid reply is 0xF."""
    return ((word ^ (word >> 4) ^ (word >> 8) ^ (word >> 12)) & 0xF) == 0xF


def period_reply_word(period_us):
    """Reply word for an electrical period: smallest exponent with mantissa <= 511 (as ESCs pick)."""
    if period_us >= PERIOD_MAX_US:
        return reply_word(STOPPED)
    if period_us < 1:
        period_us = 1
    e = 0
    m = period_us
    while m > 511:
        m >>= 1
        e += 1
    return reply_word((e << 9) | m)


def erpm_reply_word(erpm):
    """Reply word a (simulated) ESC sends at `erpm`; 0 or below -> the stopped code."""
    if erpm <= 0:
        return reply_word(STOPPED)
    return period_reply_word((60000000 + (erpm >> 1)) // erpm)


def edt_reply_word(kind, raw):
    """Extended DShot Telemetry reply word: kind 1..7 (KIND_*), raw 8-bit value in the kind's unit."""
    if raw < 0:
        raw = 0
    elif raw > 255:
        raw = 255
    return reply_word(((kind << 1) << 8) | raw)


def reply_period_us(word):
    """Electrical period (us) of an eRPM reply word, `m << e`; 0 for the stopped code."""
    v = (word >> 4) & 0xFFF
    if v == STOPPED:
        return 0
    return (v & 0x1FF) << (v >> 9)


def period_to_erpm(period_us):
    """eRPM from the period, rounded; 0 when stopped (period 0)."""
    if period_us <= 0:
        return 0
    return (60000000 + (period_us >> 1)) // period_us


def erpm_to_period_us(erpm):
    if erpm <= 0:
        return 0
    return (60000000 + (erpm >> 1)) // erpm


def erpm_to_rpm(erpm, pole_count):
    """Mechanical RPM = eRPM / (poles / 2), rounded."""
    pairs = pole_count >> 1
    if pairs < 1:
        return 0
    return (erpm + (pairs >> 1)) // pairs


def rpm_to_erpm(rpm, pole_count):
    return rpm * (pole_count >> 1)


def gcr_encode(word):
    """16-bit reply word -> 21-bit line code: start bit, then 4 GCR quintets (1 = the line toggles)."""
    g = 0
    for shift in (12, 8, 4, 0):
        g = (g << 5) | GCR_ENCODE[(word >> shift) & 0xF]
    return _START | g


def gcr_decode(code21):
    """21-bit line code -> 16-bit word, or -1 (no start bit, or a quintet that is not GCR)."""
    if not code21 & _START:
        return -1
    word = 0
    for shift in (15, 10, 5, 0):
        n = GCR_DECODE[(code21 >> shift) & 0x1F]
        if n == 0xFF:
            return -1
        word = (word << 4) | n
    return word


def levels_to_code(levels21):
    """21 sampled line levels (MSB first, the line idles high before them) -> 21-bit line code."""
    levels = (1 << 21) | (levels21 & _MASK21)
    return (levels ^ (levels >> 1)) & _MASK21


def code_to_levels(code21):
    """21-bit line code -> the 21 line levels it produces after the high idle."""
    level = 1
    out = 0
    for i in range(20, -1, -1):
        if (code21 >> i) & 1:
            level ^= 1
        out = (out << 1) | level
    return out


def reply_kind(word, edt=True):
    """KIND_* of a CRC-valid reply word. With EDT off everything is eRPM except a status frame."""
    v = (word >> 4) & 0xFFF
    prefix = v >> 8
    if prefix == 0 or (prefix & 1) or v == STOPPED:
        return KIND_ERPM
    kind = prefix >> 1
    if edt or kind == KIND_STATUS:
        return kind
    return KIND_ERPM


def decode_reply(word, pole_count=14, edt=True):
    """One reply word -> (kind, value) for tools: eRPM -> (KIND_ERPM, (period_us, erpm, rpm));
    EDT -> (kind, value in the kind's unit: °C, V, A, raw); bad CRC -> (KIND_INVALID, None)."""
    if not reply_crc_ok(word):
        return KIND_INVALID, None
    kind = reply_kind(word, edt)
    if kind == KIND_ERPM:
        period_us = reply_period_us(word)
        erpm = period_to_erpm(period_us)
        return kind, (period_us, erpm, erpm_to_rpm(erpm, pole_count))
    raw = (word >> 4) & 0xFF
    if kind == KIND_VOLTAGE:
        return kind, raw * 0.25
    return kind, raw


class ErpmDecoder:
    """Bidirectional DShot replies for one motor -> eRPM, RPM and EDT values, counting bad frames.

    `decode_code(code21)` takes the 21-bit line code, `decode_levels(levels21)` the sampled
    levels, `decode_word(word)` the 16-bit word; each returns the KIND_* it decoded
    (KIND_INVALID for a GCR or CRC error) and updates the attributes below. Nothing allocates
    on the eRPM path except the float voltage.
    EDT: frames are classified with EDT rules once `edt` is True — set it from config, or it
    turns on by itself when a status frame (0xE00|version, the reply to command 13) arrives and
    off on 0xEFF (the reply to command 14). A canonical eRPM frame never has a status prefix.
    """

    def __init__(self, pole_count=14, edt=False):
        self.pole_count = pole_count
        self.edt = edt
        self.frames = 0
        self.crc_errors = 0
        self.gcr_errors = 0
        self.edt_frames = 0
        self.kind = KIND_INVALID
        self.period_us = 0
        self.erpm = 0
        self.rpm = 0
        self.temperature_c = 0
        self.voltage_v = 0.0
        self.current_a = 0
        self.debug1 = 0
        self.debug2 = 0
        self.stress = 0
        self.status = 0

    def decode_levels(self, levels21):
        return self.decode_code(levels_to_code(levels21))

    def decode_code(self, code21):
        word = gcr_decode(code21)
        if word < 0:
            self.gcr_errors += 1
            self.kind = KIND_INVALID
            return KIND_INVALID
        return self.decode_word(word)

    def decode_word(self, word):
        if ((word ^ (word >> 4) ^ (word >> 8) ^ (word >> 12)) & 0xF) != 0xF:
            self.crc_errors += 1
            self.kind = KIND_INVALID
            return KIND_INVALID
        self.frames += 1
        kind = reply_kind(word, self.edt)
        self.kind = kind
        if kind == KIND_ERPM:
            v = (word >> 4) & 0xFFF
            if v == STOPPED:
                p = 0
            else:
                p = (v & 0x1FF) << (v >> 9)
            self.period_us = p
            e = (60000000 + (p >> 1)) // p if p > 0 else 0
            self.erpm = e
            pairs = self.pole_count >> 1
            self.rpm = (e + (pairs >> 1)) // pairs if pairs > 0 else 0
            return kind
        self.edt_frames += 1
        raw = (word >> 4) & 0xFF
        if kind == KIND_TEMPERATURE:
            self.temperature_c = raw
        elif kind == KIND_VOLTAGE:
            self.voltage_v = raw * 0.25
        elif kind == KIND_CURRENT:
            self.current_a = raw
        elif kind == KIND_DEBUG1:
            self.debug1 = raw
        elif kind == KIND_DEBUG2:
            self.debug2 = raw
        elif kind == KIND_STRESS:
            self.stress = raw
        else:
            self.status = raw
            self.edt = raw != 0xFF
        return kind
