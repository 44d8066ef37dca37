"""The RPM filter: notches at each motor's rotation frequency and its harmonics, from bidirectional DShot eRPM.

Takes the motors' RPM (signals.motor_rpm, decoded by Flight._motor_telemetry from the ESCs' replies) and
the filtered gyro (rad/s, three axes); gives the gyro with every motor's vibration notched out, in place.
It runs in step 1 of the pass, after the gyro low-pass filters (the filters are linear: their order does
not change what passes), while `rpm_harmonics` > 0 and bidirectional DShot is on.

As Betaflight's rpm_filter: one notch per motor per harmonic on each gyro axis (`rpm_harmonics` 1..3), Q
`rpm_filter_q` / 100, each notch's depth scaled by its harmonic's weight (`rpm_weightN_pct`) and faded in
linearly from `rpm_min_hz` to `rpm_min_hz + rpm_fade_hz`: a notch below rpm_min_hz, or above 0.48 of the
loop rate (it cannot sit at its harmonic's true frequency there), passes the gyro through. A notch's
output is `x + weight * (notch(x) - x)`, so a weight of 0 is an exact pass-through and a changing weight
never steps the output. Each pass recomputes one motor's notches (all its harmonics from one sin/cos),
round-robin, as Betaflight spreads its updates: on a quad every notch is at most four passes old.

Flight decodes one ESC reply a pass, the motor whose notches the next pass recomputes (a reply's decode is
most of what bidirectional DShot costs MicroPython's pass), so a motor's RPM is at most four passes old
on a quad when its notches move.

Lost telemetry: a motor with no valid eRPM reply for RPM_LOST_MS (no reply, or the ESC's replies fail
their GCR or CRC check) has its notches faded to pass-through (a notch left at the last frequency is
wrong as soon as the motor changes speed), records EV_RPM_LOST and sets `lost`; the supervisor refuses
to arm (RPMFILTER, Betaflight's reason) while a motor is lost or the filter has no telemetry to run on.

The fixed-point form, for MicroPython's zero-allocation pass, is `rpm_pass` / `rpm_coefficients`
in core/fastpass/fixedrpm.py: the same notches on integers.
"""

import math

from hoverfly.compat import const
from hoverfly.core.events import EV_RPM_LOST, EV_RPM_RESTORED
from hoverfly.core.stages.mixer import MAX_MOTORS

MAX_HARMONICS = const(3)
RPM_LOST_MS = const(20)  # 20 replies missed in a row at 1 kHz: a glitch is shorter, a dead ESC longer
# A weight moves at most this much per update of its motor: a notch fades in or out over about ten
# updates (40 ms on a quad at 1 kHz), so losing telemetry is not a step in the gyro.
WEIGHT_STEP = 0.1
PASS_MASK = const(0x3FFFFFFF)  # the pass count wraps here: a small int on every VM
MAX_HZ_OF_LOOP = 0.48  # Betaflight's: a notch stays below this fraction of the sample rate

_TWO_PI = 2.0 * math.pi


class RpmFilter:
    """The notch bank (see the module docstring). `configure(params, loop_hz, motor_count, bidir)`,
    `update(gyro, rpm, now_us)` every pass, then `reply_ok(m)` for the motor `due()` names when its reply
    was valid (or `telemetry(decoders, count)` after a batch of them)."""

    def __init__(self, events=None):
        self.events = events
        self.active = False  # running: harmonics > 0 and bidirectional DShot on
        self.refused = ""  # why the configured filter cannot run (the arming reason's detail), else ""
        self.harmonics = 0
        self.motor_count = 4
        self.loop_hz = 1000
        # per notch k = motor * harmonics + h: centre (Hz), weight (0..1), coefficients b0, b1 (= a1), a2;
        # per axis per notch: x1, x2, y1, y2 (direct form 1: the state is the signal's own samples). Made
        # by configure for the notches asked for: a board that never turns the filter on keeps the heap.
        self.hz = self.weight = self.b0 = self.b1 = self.a2 = self.state = ()
        self.weights = [1.0, 1.0, 1.0]  # per harmonic
        self.min_hz = 100.0
        self.fade_hz = 50.0
        self.max_hz = 480.0
        self.q = 5.0
        self.lost = 0  # bit m set: motor m's telemetry is lost
        self.lost_passes = 20
        self.last_ok = [0] * MAX_MOTORS  # the pass of each motor's last valid reply
        self.passes = 0
        self.next_motor = 0

    def configure(self, params, loop_hz, motor_count, bidir):
        h = params.get("rpm_harmonics")
        self.loop_hz = loop_hz
        self.motor_count = motor_count
        self.harmonics = h
        self.refused = ""
        if h > 0 and not bidir:
            self.refused = ("rpm_harmonics = %d needs the motors' RPM: bidirectional DShot (a dshot motor_protocol "
                            "and dshot_bidir = 1), or rpm_harmonics = 0" % h)
        self.active = h > 0 and bidir
        n = motor_count * h if self.active else 0
        if len(self.weight) != n:
            self.hz = [0.0] * n
            self.weight = [0.0] * n
            self.b0 = [1.0] * n
            self.b1 = [0.0] * n
            self.a2 = [0.0] * n
            self.state = [0.0] * (3 * n * 4)
        self.min_hz = float(params.get("rpm_min_hz"))
        self.fade_hz = float(params.get("rpm_fade_hz"))
        self.max_hz = MAX_HZ_OF_LOOP * loop_hz
        self.q = params.get("rpm_filter_q") * 0.01
        for i in range(MAX_HARMONICS):
            self.weights[i] = params.get("rpm_weight%d_pct" % (i + 1)) * 0.01
        lost = loop_hz * RPM_LOST_MS // 1000
        self.lost_passes = lost if lost > 2 else 2
        self.reset()

    def reset(self):
        """Every notch to pass-through at rest (weight 0, state 0), every motor's telemetry counted fresh."""
        # Each notch starts as a notch at rpm_min_hz (weight 0: not heard), so the state it builds is a
        # notch's when the weight rises, not a transient.
        w = _TWO_PI * self.min_hz / self.loop_hz
        c = math.cos(w)
        s = math.sin(w)
        for k in range(len(self.weight)):
            self.weight[k] = 0.0
            self._set(k, self.min_hz, c, s)
        st = self.state
        for i in range(len(st)):
            st[i] = 0.0
        self.passes = 0
        self.lost = 0
        for m in range(MAX_MOTORS):
            self.last_ok[m] = 0
        self.next_motor = 0

    def due(self):
        """The motor whose notches the next pass recomputes: the one reply Flight._motor_telemetry decodes."""
        return self.next_motor

    def reply_ok(self, m):
        """Motor m's reply was valid (an eRPM or an Extended DShot Telemetry frame: the ESC answers)."""
        self.last_ok[m] = self.passes

    def telemetry(self, decoders, count):
        """After a batch of replies was decoded: the motors whose reply was valid."""
        for m in range(count):
            if decoders[m].kind >= 0:
                self.last_ok[m] = self.passes

    def target_weight(self, hz, harmonic):
        """The depth a notch at `hz` should have: its harmonic's weight, faded in above min_hz and out
        towards max_hz, 0 outside."""
        lo = self.min_hz
        hi = self.max_hz
        if not (lo < hz < hi):
            return 0.0
        w = self.weights[harmonic]
        fade = self.fade_hz
        if fade > 0.0:
            if hz < lo + fade:
                w *= (hz - lo) / fade
            if hz > hi - fade:
                w *= (hi - hz) / fade
        return w

    def _motor(self, m, rpm_m, now_us):
        """Motor m's notches from its RPM: centre, weight (toward its target, a step at most), coefficients."""
        lost = (self.passes - self.last_ok[m]) & PASS_MASK > self.lost_passes
        bit = 1 << m
        if lost != bool(self.lost & bit):
            self.lost ^= bit
            if self.events is not None:
                self.events.record(now_us, EV_RPM_LOST if lost else EV_RPM_RESTORED, m + 1)
        h_count = self.harmonics
        f1 = rpm_m * (1.0 / 60.0)
        c1 = s1 = 0.0
        if not lost:
            w1 = _TWO_PI * f1 / self.loop_hz
            c1 = math.cos(w1)
            s1 = math.sin(w1)
        c = 1.0
        s = 0.0
        for h in range(h_count):
            k = m * h_count + h
            # cos and sin of (h + 1) * w1, by the angle-sum rule (one sin and cos a motor)
            c, s = c * c1 - s * s1, s * c1 + c * s1
            hz = f1 * (h + 1)
            target = 0.0 if lost else self.target_weight(hz, h)
            w = self.weight[k]
            if target > w + WEIGHT_STEP:
                w += WEIGHT_STEP
            elif target < w - WEIGHT_STEP:
                w -= WEIGHT_STEP
            else:
                w = target
            self.weight[k] = w
            if w > 0.0 and target > 0.0:  # a notch fading out keeps its last centre: its frequency is unknown
                self._set(k, hz, c, s)

    def _set(self, k, hz, cos_w, sin_w):
        """Notch k's RBJ coefficients (normalised by a0) for centre hz, from cos and sin of its angle."""
        alpha = sin_w / (2.0 * self.q)
        inv = 1.0 / (1.0 + alpha)
        self.hz[k] = hz
        self.b0[k] = inv
        self.b1[k] = -2.0 * cos_w * inv
        self.a2[k] = (1.0 - alpha) * inv

    def update(self, gyro, rpm, now_us):
        """One pass: one motor's notches recomputed, then every notch on each axis of `gyro` (in place)."""
        self.passes = (self.passes + 1) & PASS_MASK
        m = self.next_motor
        self._motor(m, rpm[m], now_us)
        m += 1
        self.next_motor = m if m < self.motor_count else 0
        n = self.motor_count * self.harmonics
        st = self.state
        b0 = self.b0
        b1 = self.b1
        a2 = self.a2
        weight = self.weight
        for axis in range(3):
            x = gyro[axis]
            o = axis * n * 4
            for k in range(n):
                x1 = st[o]
                x2 = st[o + 1]
                y1 = st[o + 2]
                y2 = st[o + 3]
                y = b0[k] * (x + x2) + b1[k] * (x1 - y1) - a2[k] * y2
                st[o] = x
                st[o + 1] = x1
                st[o + 2] = y
                st[o + 3] = y1
                x = x + weight[k] * (y - x)
                o += 4
            gyro[axis] = x

    def centres_hz(self, out):
        """The notches' centres now, 0 for one that is off (logs and tests): out[k], k = motor * harmonics + h."""
        for k in range(self.motor_count * self.harmonics):
            out[k] = self.hz[k] if self.weight[k] > 0.0 else 0.0
