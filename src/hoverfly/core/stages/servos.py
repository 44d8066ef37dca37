"""The servo mixer: stabilised commands and RC channels in, servo pulse widths out, as INAV's `smix` and `servo`.

Step 5 of the pass for a plane (and a tricopter's tail), beside the motor mixer. In: the controller's
`torque_norm` (stabilised roll, pitch, yaw in -1..1, + = roll right, nose up, nose right),
`setpoint.throttle_norm` (0..1) and the receiver's `rc_channels_us`. Out: `servo_us` (array('H'), µs per
servo), which the board turns into PWM.

A rule (`smixN_servo`, `_input`, `_rate`, `_speed`) takes one input on INAV's scale (±500 for full travel:
a stabilised axis at ±1, an RC channel at 1000/2000 µs, the throttle 0..1 as -500..+500), limits how fast it
may move (`speed` x 10 µs/s, 0 = no limit: INAV's), weighs it by `rate` % and adds it to its servo. Each
servo then scales the sum by `servoN_rate` % (negative = reversed), adds its centre `servoN_mid_us` (the
trim, as INAV's mid) and clips to `servoN_min_us..servoN_max_us`. So a servo at rate +100 whose rule has
rate +100 moves towards max on a positive command, the direction the simulator's wiring expects
(docs/fixed-wing.md). A rule with rate 0 is unused; with every rule's rate 0 the mixer_type's preset
(PRESETS, INAV's platform defaults) applies, so a plane always has its surfaces.

Disarmed, every servo sits at its centre and the speed limits start again from centre, so arming never
throws a surface. INAV moves surfaces disarmed in MANUAL for a preflight check; hoverfly keeps them
centred until armed (docs/fixed-wing.md).

The pass's arithmetic is in integers (milli-µs, ±500 000 for full travel), so the only floats a pass
makes on MicroPython are the four inputs read from the controller's float arrays; see
docs/fixed-wing.md for why it has no generated fixed-point twin.
"""

from array import array

from hoverfly.compat import const
from hoverfly.core.stages.rc import map_channels

MAX_SERVOS = const(8)  # servo_us's length, and the servoN_* rows (0..7)
MAX_RULES = const(16)  # smixN_* rows (0..15), INAV's MAX_SERVO_RULES

# INAV's input source ids (docs/Mixer.md); 12, 13 (gimbal) and 14 (flaps) are not supported.
SRC_ROLL = const(0)
SRC_PITCH = const(1)
SRC_YAW = const(2)
SRC_THROTTLE = const(3)
SRC_RC_ROLL = const(4)  # 4..7 RC roll, pitch, yaw, throttle (where rc_map puts them)
SRC_RC_AUX1 = const(8)  # 8..11 RC channels 5..8 (AUX1..4, where rc_map puts them)
SRC_RC_CH9 = const(15)  # 15..22 RC channels 9..16
SRC_ROLL_PLUS = const(23)  # 23..28 stabilised roll+, roll-, pitch+, pitch-, yaw+, yaw-: one side each
SRC_MAX = const(28)
INPUT_NAMES = (
    "Stabilised Roll", "Stabilised Pitch", "Stabilised Yaw", "Stabilised Throttle",
    "RC Roll", "RC Pitch", "RC Yaw", "RC Throttle", "RC Channel 5", "RC Channel 6", "RC Channel 7", "RC Channel 8",
    "Gimbal Pitch", "Gimbal Roll", "Flaps",
    "RC Channel 9", "RC Channel 10", "RC Channel 11", "RC Channel 12", "RC Channel 13", "RC Channel 14",
    "RC Channel 15", "RC Channel 16",
    "Stabilised Roll+", "Stabilised Roll-", "Stabilised Pitch+", "Stabilised Pitch-", "Stabilised Yaw+",
    "Stabilised Yaw-",
)

# INAV's platform presets, each rule (servo, input, rate %, speed). The signs follow the simulator's
# wiring contract: a servo towards max raises its elevon's or ruddervator's trailing edge, so roll right
# lowers the left elevon and yaw right lowers the left ruddervator.
PRESETS = {
    "airplane": ((0, SRC_ROLL, 100, 0), (1, SRC_PITCH, 100, 0), (2, SRC_YAW, 100, 0)),
    "flying_wing": ((0, SRC_PITCH, 50, 0), (0, SRC_ROLL, -50, 0), (1, SRC_PITCH, 50, 0), (1, SRC_ROLL, 50, 0)),
    "vtail": ((0, SRC_ROLL, 100, 0), (1, SRC_PITCH, 50, 0), (1, SRC_YAW, -50, 0), (2, SRC_PITCH, 50, 0),
              (2, SRC_YAW, 50, 0)),
}

# How a rule reads its input (configure works it out once): an index into the pass's stabilised inputs
# (roll, pitch, yaw, throttle), one side of one of them, or a receiver channel.
_K_STAB = const(0)
_K_PLUS = const(1)
_K_MINUS = const(2)
_K_RC = const(3)

_FULL = const(500000)  # full travel of an input, milli-µs (INAV's ±500 µs)
_SUM_MAX = const(2000000)  # a servo's sum is clipped here before its rate: the product stays a small int


def rule_rows(i):
    """The four parameter names of rule i."""
    return ("smix%d_servo" % i, "smix%d_input" % i, "smix%d_rate" % i, "smix%d_speed" % i)


def servo_rows(i):
    """The four parameter names of servo i: min, mid, max, rate."""
    return ("servo%d_min_us" % i, "servo%d_mid_us" % i, "servo%d_max_us" % i, "servo%d_rate" % i)


def stored_rules(params):
    """The rules as stored: (index, servo, input, rate, speed) of each rule whose rate is not 0."""
    out = []
    for i in range(MAX_RULES):
        n = rule_rows(i)
        rate = params.stored(n[2])
        if rate != 0:
            out.append((i, params.stored(n[0]), params.stored(n[1]), rate, params.stored(n[3])))
    return out


def rules_of(params, mixer_type=None):
    """The rules the mixer runs, as (index, servo, input, rate, speed): the stored ones, or with none stored
    the mixer_type's preset (numbered from 0)."""
    rules = stored_rules(params)
    if rules:
        return rules
    frame = mixer_type if mixer_type is not None else params.get("mixer_type")
    preset = PRESETS.get(frame, ())
    return [(i, r[0], r[1], r[2], r[3]) for i, r in enumerate(preset)]


def servo_error(lo_us, mid_us, hi_us):
    """None when a servo's end points are usable (min <= mid <= max), else why not."""
    if not (lo_us <= mid_us <= hi_us):
        return "servo min %d, mid %d, max %d: needs min <= mid <= max" % (lo_us, mid_us, hi_us)
    return None


def rule_pairs(params, index, servo, source, rate, speed, servo_count=MAX_SERVOS):
    """The (name, value) writes that set rule `index` (the preset copied in first when no rule is stored,
    so editing one rule keeps the others), or (None, the one-line reason) when the rule is not valid."""
    if not (0 <= index < MAX_RULES):
        return None, "smix rule %s does not exist: rules are 0..%d" % (index, MAX_RULES - 1)
    if not (0 <= servo < servo_count):
        return None, "smix: servo %s does not exist: servos are 0..%d" % (servo, servo_count - 1)
    if not (0 <= source <= SRC_MAX) or 12 <= source <= 14:
        return None, "smix: input %s is not one hoverfly has: 0..11 and 15..28 (see docs/fixed-wing.md)" % source
    if not (-125 <= rate <= 125):
        return None, "smix: rate %s is out of range -125..125" % rate
    if not (0 <= speed <= 255):
        return None, "smix: speed %s is out of range 0..255 (0 = no limit)" % speed
    pairs = []
    if not stored_rules(params):
        for r in rules_of(params):
            n = rule_rows(r[0])
            pairs.extend(((n[0], r[1]), (n[1], r[2]), (n[2], r[3]), (n[3], r[4])))
    n = rule_rows(index)
    pairs.extend(((n[0], servo), (n[1], source), (n[2], rate), (n[3], speed)))
    return pairs, None


def reset_pairs():
    """The writes that clear every stored rule (the mixer_type's preset applies again: INAV's `smix reset`)."""
    pairs = []
    for i in range(MAX_RULES):
        n = rule_rows(i)
        pairs.extend(((n[0], 0), (n[1], 0), (n[2], 0), (n[3], 0)))
    return pairs


def servo_pairs(index, lo_us, hi_us, mid_us, rate, servo_count=MAX_SERVOS):
    """INAV's `servo N min max mid rate` as parameter writes, or (None, the one-line reason)."""
    if not (0 <= index < servo_count):
        return None, "servo %s does not exist: servos are 0..%d" % (index, servo_count - 1)
    for v in (lo_us, hi_us, mid_us):
        if not (500 <= v <= 2500):
            return None, "servo %d: %s us is out of range 500..2500" % (index, v)
    err = servo_error(lo_us, mid_us, hi_us)
    if err is not None:
        return None, "servo %d: %s" % (index, err[6:])
    if not (-125 <= rate <= 125):
        return None, "servo %d: rate %s is out of range -125..125" % (index, rate)
    n = servo_rows(index)
    return [(n[0], lo_us), (n[1], mid_us), (n[2], hi_us), (n[3], rate)], None


class ServoMixer:
    """The rules and servo settings from the parameters (configure), applied every pass (update)."""

    def __init__(self):
        self.count = 0  # servos driven: the highest rule target + 1 (0: no servo mix, a multirotor)
        self.rules = 0
        self.error = ""  # a servo whose end points are not min <= mid <= max (it then stays at its mid)
        # per rule: servo, kind, index (stabilised input or receiver channel), rate %, speed step
        self._plan = array("i", [0] * (5 * MAX_RULES))
        self._state = array("i", [0] * MAX_RULES)  # each rule's speed-limited input, milli-µs
        self._servo = array("i", [1000, 1500, 2000, 100] * MAX_SERVOS)  # min, mid, max, rate per servo
        self._sum = array("i", [0] * MAX_SERVOS)
        self._in = array("i", [0, 0, 0, 0])  # this pass's stabilised roll, pitch, yaw, throttle, milli-µs
        self._was_armed = False

    def configure(self, params, mixer_type=None):
        """The rules the mixer runs (rules_of) and every servo's end points; a servo with min > mid or
        mid > max is named in `error` and held at its mid."""
        frame = mixer_type if mixer_type is not None else params.get("mixer_type")
        errors = []
        sv = self._servo
        for i in range(MAX_SERVOS):
            n = servo_rows(i)
            lo = params.get(n[0])
            mid = params.get(n[1])
            hi = params.get(n[2])
            err = servo_error(lo, mid, hi)
            if err is not None:
                errors.append("servo %d: %s" % (i, err[6:]))
                lo = hi = mid
            sv[4 * i] = lo
            sv[4 * i + 1] = mid
            sv[4 * i + 2] = hi
            sv[4 * i + 3] = params.get(n[3])
        chans = map_channels(params.get("rc_map"))  # 0-based receiver channel of roll, pitch, yaw, throttle, AUX1..4
        plan = self._plan
        count = 0
        k = 0
        rules = rules_of(params, frame) if frame in PRESETS or stored_rules(params) else []
        for r in rules:
            servo, source, rate, speed = r[1], r[2], r[3], r[4]
            if source <= SRC_THROTTLE:
                kind, idx = _K_STAB, source
            elif source < SRC_RC_AUX1:
                kind, idx = _K_RC, chans[source - SRC_RC_ROLL]
            elif source < 12:
                kind, idx = _K_RC, chans[4 + source - SRC_RC_AUX1]
            elif SRC_RC_CH9 <= source < SRC_ROLL_PLUS:
                kind, idx = _K_RC, 8 + source - SRC_RC_CH9
            elif SRC_ROLL_PLUS <= source <= SRC_MAX:
                d = source - SRC_ROLL_PLUS
                kind, idx = (_K_PLUS if d % 2 == 0 else _K_MINUS), d // 2
            else:
                continue  # a source the parameter check refuses: never stored
            plan[5 * k] = servo
            plan[5 * k + 1] = kind
            plan[5 * k + 2] = idx
            plan[5 * k + 3] = rate
            plan[5 * k + 4] = speed  # x 10 µs/s: speed * dt_us / 100 milli-µs a pass
            k += 1
            if servo + 1 > count:
                count = servo + 1
        self.rules = k
        self.count = count
        self.error = "; ".join(errors)
        self.reset()

    def reset(self):
        """Speed limits start again from centre (disarmed, and after configure)."""
        st = self._state
        for i in range(MAX_RULES):
            st[i] = 0

    def update(self, torque_norm, throttle_norm, channels_us, dt_us, armed, servo_us):
        """servo_us[0..count-1] from this pass's commands; every servo at its mid while disarmed."""
        if not armed:
            self.centre(servo_us)
            if self._was_armed:
                self.reset()
                self._was_armed = False
            return
        self._was_armed = True
        self._inputs(torque_norm, throttle_norm)
        self._mix(channels_us, dt_us)
        self._output(servo_us)

    def _inputs(self, torque_norm, throttle_norm):
        """The stabilised inputs as milli-µs on INAV's scale, clamped to full travel (a NaN reads as 0)."""
        inp = self._in
        for i in range(3):
            inp[i] = _scaled(torque_norm[i], _FULL)
        inp[3] = _scaled(throttle_norm * 2.0 - 1.0, _FULL)

    def _mix(self, channels_us, dt_us):
        """Each rule's input, speed-limited and weighed, summed per servo."""
        plan = self._plan
        st = self._state
        inp = self._in
        acc = self._sum
        for i in range(MAX_SERVOS):
            acc[i] = 0
        nch = len(channels_us)
        for r in range(self.rules):
            b = 5 * r
            kind = plan[b + 1]
            idx = plan[b + 2]
            if kind == _K_STAB:
                v = inp[idx]
            elif kind == _K_RC:
                v = (channels_us[idx] - 1500) * 1000 if idx < nch else 0
                if v > _FULL:
                    v = _FULL
                elif v < -_FULL:
                    v = -_FULL
            elif kind == _K_PLUS:
                v = inp[idx] if inp[idx] > 0 else 0
            else:
                v = inp[idx] if inp[idx] < 0 else 0
            speed = plan[b + 4]
            if speed:
                step = speed * dt_us // 100  # speed x 10 µs/s over dt_us, in milli-µs
                last = st[r]
                if v > last + step:
                    v = last + step
                elif v < last - step:
                    v = last - step
            st[r] = v
            acc[plan[b]] += v * plan[b + 3] // 100

    def _output(self, servo_us):
        """Each servo's sum times its rate, about its mid, clipped to its end points, in µs."""
        acc = self._sum
        sv = self._servo
        for i in range(self.count):
            v = acc[i]
            if v > _SUM_MAX:
                v = _SUM_MAX
            elif v < -_SUM_MAX:
                v = -_SUM_MAX
            b = 4 * i
            us = sv[b + 1] + (v * sv[b + 3] // 100 + 500) // 1000
            if us < sv[b]:
                us = sv[b]
            elif us > sv[b + 2]:
                us = sv[b + 2]
            servo_us[i] = us

    def centre(self, servo_us):
        """Every servo at its mid (disarmed; the output failsafe's position)."""
        sv = self._servo
        for i in range(MAX_SERVOS):
            servo_us[i] = sv[4 * i + 1]

    def from_norm(self, servo_norm, count, servo_us):
        """A position -1..1 per servo (a tricopter's tail from the motor mixer) as µs: each side of mid linear
        to its end point, times the servo's rate (negative reverses)."""
        sv = self._servo
        for i in range(count):
            b = 4 * i
            x = servo_norm[i] * sv[b + 3] * 0.01
            mid = sv[b + 1]
            if x >= 0.0:
                us = mid + (sv[b + 2] - mid) * x
            else:
                us = mid + (mid - sv[b]) * x
            if not (us >= sv[b]):  # below min, or NaN
                us = sv[b] if us < sv[b] else mid
            elif us > sv[b + 2]:
                us = sv[b + 2]
            servo_us[i] = int(us + 0.5)


def _scaled(x, full):
    """x (-1..1, a float) times full as an int, clamped to ±full; NaN reads as 0."""
    if x > 1.0:
        return full
    if x < -1.0:
        return -full
    if x != x:
        return 0
    return int(x * full)
