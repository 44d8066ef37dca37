"""Pilot input: receiver channels in µs to sticks, throttle, switches and the setpoint.

A new frame (`new_frame`) maps channels (rc_map, Betaflight's `map`: any order of the four
sticks and AUX1..4 on channels 1..8, AETR1234 by default), applies the deadband and
reads the AUX mode ranges (Betaflight style: channel plus µs range per mode, channel 0 =
none): ARM, ANGLE, HORIZON and AIRMODE; the FAILSAFE box is read from the raw frame
(`fs_switch_in`) before it is taken, because with it on the frame counts as lost. Every
pass (`update`) smooths the sticks (rc_smooth_type: PT2 or PT1 at rc_smoothing_hz, or
seed 001's alpha-beta with a gain pair per stick, ab_<stick>_alpha/_beta; throttle_norm is
the raw stick or, with thr_mode = bands, seed 001's DESCEND/HOVERING/CLIMB value for the
stick's third) and turns them into the setpoint: rates through the "actual" curve, angles
through angle_limit. With yaw_hold a heading hold (`hold_heading`, from the 100 Hz task)
gives the yaw rate while the yaw stick is centred. Stage 3 of the pass, with the commander
choosing whose input it is.

In fixed point (with the PT2, where `pid_math` runs the rate loop in fixed point: "auto" on
MicroPython where the viper twin accel/rc.py loads, "fixed" anywhere) `update` runs `rc_pass`
below on integers: each float result is a heap object on MicroPython, and the float smoothing and
curves made 12 of them a pass with one stick moving. The frame's sticks and throttle go in as Q20
(new_frame rounds the same µs arithmetic), the PT2 runs on Q20 states with the float stage's gain in
Q15, the curve on the stick in Q16 and gives Q16 rad/s; the angle and throttle floats are made only
when their value changed.
tests/portable/test_rc_fixed.py holds it to the float stage within a stated bound. Only the PT2 has
a fixed-point form: with pt1 or alphabeta smoothing `update` runs the float stage on every Python.
"""

import math
from array import array

from hoverfly.compat import IS_MICROPYTHON, const
from hoverfly.core.stages.control import MODE_ACRO, MODE_ANGLE, MODE_HORIZON
from hoverfly.core.stages.filters import AlphaBeta, Pt1, Pt2
from hoverfly.core.stages.rates import ActualRates
from hoverfly.protocols.rxcodec import CHANNELS

_DEG = math.pi / 180.0
_INV16 = 1.0 / 65536.0
_INV20 = 1.0 / 1048576.0
_ONE = const(65536)  # 1.0 in Q16
_ONE20 = const(0x100000)  # 1.0 in Q20

# rc_pass's coefficients (array "i"): the PT2 stage gain (Q15), then per axis (roll, pitch, yaw) the
# curve's centre rate and travel (Q16 rad/s, below 2**22: 2550 deg/s is 2.9e6) and expo (Q16, 0..1)
CO_K = const(0)
CO_C = const(1)
CO_T = const(4)
CO_E = const(7)
CO_SIZE = const(10)
# its state (array "i"): the inputs (roll, pitch, yaw -2**20..2**20, throttle 0..2**20), the PT2s'
# first stages and outputs, all Q20
S_X = const(0)
S_S1 = const(4)
S_Y = const(8)
ST_SIZE = const(12)

_viper = None
if IS_MICROPYTHON:
    try:  # generated from update/rc_pass and rc_frame below by hoverfly.fastgen; absent, or no viper: the Python runs
        from hoverfly.accel import rc as _viper
    except (ImportError, SyntaxError, NameError, ValueError, TypeError):  # TypeError: ViperTypeError
        pass
HAS_ACCEL = _viper is not None


def _step(k, x, y):
    """One PT1 step with a Q15 gain: y + floor((k * (x - y) + 2**14) / 2**15), at least one LSB towards
    x (a fixed PT1 would otherwise stop short of its input: a centred stick must give 0). The product on
    the difference's 16-bit halves (|x - y| <= 2**21, k <= 2**15: every part below 2**31)."""
    d = x - y
    if d == 0:
        return y
    p = (k * (d >> 16) << 1) + ((k * (d & 0xFFFF) + 16384) >> 15)
    if p == 0:
        p = 1 if d > 0 else -1
    return y + p


def _mul16(x, y):
    """floor(x * y / 2**16) for 0 <= x, y <= 2**16, on y's bytes (parts below 2**25)."""
    t = x * (y >> 8)
    return (t >> 8) + ((((t & 255) << 8) + x * (y & 255)) >> 16)


def _mul_rate(a, c):
    """floor(a * c / 2**16) for 0 <= a <= 2**16, 0 <= c < 2**22, on c's 11-bit halves (parts below 2**28)."""
    t = a * (c >> 11)
    return (t >> 5) + ((((t & 31) << 11) + a * (c & 0x7FF)) >> 16)


# fastpass: RcInput.update co:i st:i stick:f@ rate:f@
def rc_pass(co, st, stick, rate):
    """One pass of the stick shaping in fixed point (RcInput.update's; on MicroPython the viper update
    generated from it and the method, accel/rc.py, stands in for the method): the four PT2s
    (roll, pitch, yaw, throttle) on st's Q20 inputs, the smoothed sticks into stick[0..2] and their
    rates through the "actual" curve into rate[0..2] (floats). Returns which outputs changed: bit i
    for st[S_Y + i]. A PT2 sitting on its input is not run. Bounds: inputs within +-2**20, so the
    states are (a step never passes its input); the curve takes a = |stick| in Q16, rounded, <= 2**16,
    so a2, a4, a6 and the curve are <= 2**16; the rate is below centre + travel < 2**23."""
    k = co[CO_K]
    changed = 0
    for i in range(4):
        x = st[S_X + i]
        s1 = st[S_S1 + i]
        y = st[S_Y + i]
        if s1 != x or y != x:
            s1 = _step(k, x, s1)
            st[S_S1 + i] = s1
            y1 = _step(k, s1, y)
            if y1 != y:
                y = y1
                st[S_Y + i] = y
                changed |= 1 << i
        if i < 3:
            a = ((-y if y < 0 else y) + 8) >> 4
            a2 = _mul16(a, a)
            e = co[CO_E + i]
            if e == 0:
                curve = a2
            else:
                # a * (a**5 * e + a * (1 - e)), as ActualRates.rate_rad_s (Betaflight's actual rates)
                a6 = _mul16(_mul16(a2, a2), a2)
                curve = _mul16(a6, e) + _mul16(a2, _ONE - e)
            r = _mul_rate(a, co[CO_C + i]) + _mul_rate(curve, co[CO_T + i])
            stick[i] = y * _INV20
            rate[i] = (-r if y < 0 else r) * _INV16
    return changed


# new_frame's table (RcInput._fco, from configure): the sticks' channels (0-based), their deadbands,
# whether the fixed-point stage takes the sticks, and the ARM, HORIZON, ANGLE, AIRMODE and autopilot (seed
# 004's switch: ap_ch, ap_min_us, ap_max_us) ranges (channel 1-based, 0 = none; lo <= µs < hi).
FC_CH = const(0)  # roll, pitch, yaw, throttle
FC_DB = const(4)
FC_YAW_DB = const(5)
FC_FIXED = const(6)
FC_SW = const(7)  # three words a switch
FC_SIZE = const(22)
# rc_frame's answer: bits 0..3 the sticks that moved (roll, pitch, yaw, throttle), then the switches in range
RF_ARM = const(16)
RF_HORIZON = const(32)
RF_ANGLE = const(64)
RF_AIRMODE = const(128)
RF_AP = const(256)


# fastpass: rc_frame fco:i last:i channels_us:H st:i src_us:H
def rc_frame(fco, last, channels_us, st, src_us):
    """new_frame's integer part, in one call: the receiver's 16 channels src_us copied into channels_us
    (onto themselves when they are the same array), which sticks moved since the last frame (their µs into
    `last`), in fixed point their Q20 into st[S_X..] (roll, pitch, yaw: _stick_q, pitch negated: stick
    forward is nose down in FRD; the throttle is left to RcInput._throttle), and which mode switches are in
    range. Its viper twin, generated from it (accel/rc.py), stands in for it on MicroPython (test_rc_fixed
    checks both)."""
    for i in range(CHANNELS):
        channels_us[i] = src_us[i]
    r = 0
    for i in range(4):
        us = channels_us[fco[FC_CH + i]]
        if us != last[i]:
            last[i] = us
            r |= 1 << i
            if fco[FC_FIXED] and i < 3:
                q = _stick_q(us, fco[FC_YAW_DB] if i == 2 else fco[FC_DB])
                st[S_X + i] = -q if i == 1 else q
    n = len(channels_us)
    bit = RF_ARM
    k = FC_SW
    while k < FC_SIZE:
        ch = fco[k]
        if 0 < ch <= n and fco[k + 1] <= channels_us[ch - 1] < fco[k + 2]:
            r |= bit
        bit <<= 1
        k += 3
    return r


_rc_frame = _viper.rc_frame if HAS_ACCEL else rc_frame


def _q(x, scale, lo, hi):
    """A float in fixed point (x * scale), rounded, clamped to lo..hi; NaN as 0."""
    if not (x == x):
        return 0
    v = x * scale
    if v >= hi:
        return hi
    if v <= lo:
        return lo
    return int(v + 0.5) if v >= 0 else -int(0.5 - v)


def _stick_q(us, deadband):
    """RcInput._stick in Q20, rounded: the same µs arithmetic, an integer division."""
    d = us - 1500
    if d > deadband:
        d -= deadband
    elif d < -deadband:
        d += deadband
    else:
        return 0
    den = 500 - deadband
    a = d if d > 0 else -d
    if a >= den:
        q = _ONE20
    else:
        q = (a * 0x200000 + den) // (2 * den)  # a < 500: below 2**30
    return q if d > 0 else -q


def _throttle_q(t):
    """The throttle stick's (t - 1000) * 0.001, clamped to 0..1, in Q20, rounded."""
    if t <= 1000:
        return 0
    if t >= 2000:
        return _ONE20
    return ((t - 1000) * 0x100000 + 500) // 1000  # below 2**30

# Betaflight's `map` (CLI `map AETR1234`): one letter per receiver channel 1..8 naming its function. The
# rc_map parameter keeps the same mapping the other way round, as Betaflight's rcmap does: a digit per
# function in this order (roll, pitch, yaw, throttle, AUX1..4) giving its receiver channel (1..8).
MAP_LETTERS = "AERT1234"


def map_channels(rc_map):
    """rc_map (a permutation of 12345678, params.rc_map_error) as a list of 0-based receiver channels, one
    per function in MAP_LETTERS' order."""
    out = [0] * 8
    for i in range(7, -1, -1):
        out[i] = rc_map % 10 - 1
        rc_map //= 10
    return out


def aux_channel(chmap, ch):
    """The receiver channel (1-based) that carries channel setting `ch`: AUX1..4 (5..8) where the map puts
    them (Betaflight moves AUX letters too), any other channel (and 0 = none) as it is."""
    if 5 <= ch <= 8:
        return chmap[ch - 1] + 1
    return ch


def map_text(rc_map):
    """rc_map as Betaflight prints it: a letter per receiver channel ("AETR1234")."""
    m = map_channels(rc_map)
    out = ["?"] * 8
    for f in range(8):
        out[m[f]] = MAP_LETTERS[f]
    return "".join(out)


def map_value(text):
    """(rc_map, None) for a Betaflight map ("TAER1234", any case: each of A E R T 1 2 3 4 once), else (None,
    the one-line reason)."""
    s = text.strip().upper()
    if len(s) != 8:
        return None, "map takes 8 letters, one per receiver channel (each of A E R T 1 2 3 4 once), e.g. AETR1234"
    digits = [0] * 8
    for ch in range(8):
        f = MAP_LETTERS.find(s[ch])
        if f < 0:
            return None, "map: '%s' is not one of A E R T 1 2 3 4" % s[ch]
        if digits[f]:
            return None, "map: '%s' appears twice; each of A E R T 1 2 3 4 once" % s[ch]
        digits[f] = ch + 1
    v = 0
    for d in digits:
        v = v * 10 + d
    return v, None



# the alpha-beta filters' parameters, in the filters' order (roll, pitch, yaw, throttle)
_AB_NAMES = (("ab_roll_alpha", "ab_roll_beta"), ("ab_pitch_alpha", "ab_pitch_beta"), ("ab_yaw_alpha", "ab_yaw_beta"),
             ("ab_thr_alpha", "ab_thr_beta"))


def _gain(k):
    """A PT1 gain (0 < k <= 1) in Q15, rounded."""
    g = int(k * 32768 + 0.5)
    if g > 32768:
        return 32768
    return g if g > 0 else 0


def _in_range(channels_us, ch, lo, hi):
    if ch <= 0 or ch > len(channels_us):
        return False
    v = channels_us[ch - 1]
    return lo <= v < hi


class RcInput:
    def __init__(self):
        self.rates = (ActualRates(), ActualRates(), ActualRates())
        self.filters = (Pt2(), Pt2(), Pt2(), Pt2())
        self.roll_ch = 0
        self.pitch_ch = 1
        self.yaw_ch = 3
        self.throttle_ch = 2
        self.map_ch = map_channels(12435678)  # receiver channel per function (MAP_LETTERS' order): AETR1234
        self.deadband_us = 5
        self.yaw_deadband_us = 5
        self.min_check_us = 1050
        self.angle_limit_rad = 60.0 * _DEG
        # latest frame, before smoothing
        self.stick_raw = [0.0, 0.0, 0.0]
        self.throttle_raw = 0.0
        self.throttle_us = 1000
        self.arm_switch = False
        self.mode = MODE_ACRO
        self.airmode_box = False  # an AIRMODE channel is set: the switch, not the airmode parameter, decides
        self.fs_switch_box = False  # a FAILSAFE channel is set (fs_switch_in can read on)
        self.airmode_switch = False
        self.ap_switch = False  # the autopilot switch in the latest frame
        self.frames = 0
        self._arm = (5, 1700, 2100)
        self._angle = (6, 1300, 2100)
        self._horizon = (6, 1300, 1700)
        self._airmode = (0, 1700, 2100)
        self._ap = (0, 1700, 2100)  # the autopilot switch (Autopilot reads its own copy for its other uses)
        self._fs_switch = (0, 1700, 2100)
        self._smooth_type = "pt2"
        self._thr_bands = None  # seed 001: (DESCEND, HOVERING, CLIMB) µs, or None for the raw stick
        # The fixed-point stick shaping (rc_pass; see the module docstring): its coefficients and state,
        # and the floats it last made for the angles and the throttle (remade only when they change).
        self.fixed = False
        self._co = array("i", [0] * CO_SIZE)
        self._st = array("i", [0] * ST_SIZE)
        # the viper update's table of the two arrays' addresses (accel/rc.py): neither is ever replaced
        self._tab = None
        if HAS_ACCEL:
            self._tab = array("i", [0] * _viper.TAB_SIZE)
            _viper.bind(self._tab, 0, self._co)
            _viper.bind(self._tab, 1, self._st)
            _viper.bind(self._tab, 2, _viper.LOG2)
        self._angle_per_q = 0.0
        self._roll_angle_rad = 0.0
        self._pitch_angle_rad = 0.0
        self._throttle_norm = 0.0
        # new_frame: the µs each stick (roll, pitch, yaw, throttle) read last; a stick that did not move
        # keeps its float (-1: none yet, or the configuration changed). Its table: FC_* above.
        self._last_us = array("i", [-1, -1, -1, -1])
        self._fco = array("i", [0] * FC_SIZE)
        # Yaw heading hold (yaw_hold; hold_heading below): the heading to hold, the yaw rate setpoint that
        # holds it (worked out at 100 Hz), whether it stands in for the yaw stick's rate now, its gain and cap.
        self.yaw_hold = False
        self.holding = False
        self.heading_rad = 0.0
        self.hold_rate_rad_s = 0.0
        self._hold_k = 2.0
        self._hold_max_rad_s = 0.0

    def configure(self, params, loop_hz):
        self._set_fixed(False)  # the float filters hold the state while they are configured
        rc = (("roll_rc_rate", "roll_srate", "roll_expo"), ("pitch_rc_rate", "pitch_srate", "pitch_expo"),
              ("yaw_rc_rate", "yaw_srate", "yaw_expo"))
        for axis in range(3):
            names = rc[axis]
            self.rates[axis].configure(params.get(names[0]), params.get(names[1]), params.get(names[2]))
        kind = params.get("rc_smooth_type")
        if kind != self._smooth_type:
            cls = AlphaBeta if kind == "alphabeta" else (Pt1 if kind == "pt1" else Pt2)
            self.filters = (cls(), cls(), cls(), cls())
            self._smooth_type = kind
        for i in range(4):
            if kind == "alphabeta":
                names = _AB_NAMES[i]
                self.filters[i].configure(params.get(names[0]), params.get(names[1]), loop_hz)
            else:
                self.filters[i].configure(params.get("rc_smoothing_hz"), loop_hz)
        if params.get("thr_mode") == "bands":
            self._thr_bands = (params.get("thr_descend_us"), params.get("thr_hover_us"), params.get("thr_climb_us"))
        else:
            self._thr_bands = None
        m = self.map_ch = map_channels(params.get("rc_map"))
        self.roll_ch = m[0]
        self.pitch_ch = m[1]
        self.yaw_ch = m[2]
        self.throttle_ch = m[3]
        self.deadband_us = params.get("deadband")
        self.yaw_deadband_us = params.get("yaw_deadband")
        self.min_check_us = params.get("min_check")
        self.angle_limit_rad = params.get("angle_limit") * _DEG
        # The switches' channels as the receiver sends them: AUX1..4 where the map put them.
        self._arm = (aux_channel(m, params.get("arm_ch")), params.get("arm_min_us"), params.get("arm_max_us"))
        self._angle = (aux_channel(m, params.get("angle_ch")), params.get("angle_min_us"), params.get("angle_max_us"))
        self._horizon = (aux_channel(m, params.get("horizon_ch")), params.get("horizon_min_us"),
                         params.get("horizon_max_us"))
        self._airmode = (aux_channel(m, params.get("airmode_ch")), params.get("airmode_min_us"),
                         params.get("airmode_max_us"))
        self.airmode_box = self._airmode[0] > 0
        self._ap = (aux_channel(m, params.get("ap_ch")), params.get("ap_min_us"), params.get("ap_max_us"))
        self._fs_switch = (aux_channel(m, params.get("fs_switch_ch")), params.get("fs_switch_min_us"),
                           params.get("fs_switch_max_us"))
        self._configure_yaw_hold(params)
        math_kind = params.get("pid_math")
        self._set_fixed(kind == "pt2" and (math_kind == "fixed" or (math_kind == "auto" and HAS_ACCEL)))
        self.frame_table()
        self._forget()

    def frame_table(self):
        """new_frame's table (FC_*) from the channel map, the deadbands, the stage and the mode ranges, and
        fs_switch_box (configure calls it; so must anything that changes those afterwards)."""
        t = self._fco
        t[FC_CH] = self.roll_ch
        t[FC_CH + 1] = self.pitch_ch
        t[FC_CH + 2] = self.yaw_ch
        t[FC_CH + 3] = self.throttle_ch
        t[FC_DB] = self.deadband_us
        t[FC_YAW_DB] = self.yaw_deadband_us
        t[FC_FIXED] = 1 if self.fixed else 0
        self.fs_switch_box = self._fs_switch[0] > 0
        k = FC_SW
        for sw in (self._arm, self._horizon, self._angle, self._airmode, self._ap):
            t[k] = sw[0]
            t[k + 1] = sw[1]
            t[k + 2] = sw[2]
            k += 3

    def _forget(self):
        """Drop new_frame()'s reused results (the filters, curves, limits or deadbands changed)."""
        for i in range(4):
            self._last_us[i] = -1
        if self.fixed:
            self._refresh()

    def _set_fixed(self, on):
        """Run update() in fixed point (on) or float: the coefficients from the configured float stages,
        the state handed over between the PT2 filters and rc_pass's state words."""
        st = self._st
        f = self.filters
        if on:
            co = self._co
            co[CO_K] = _gain(f[0].k)
            for axis in range(3):
                r = self.rates[axis]
                co[CO_C + axis] = _q(r.centre_rad_s, 65536.0, 0, 0x3FFFFF)
                co[CO_T + axis] = _q(r.travel_rad_s, 65536.0, 0, 0x3FFFFF)
                co[CO_E + axis] = _q(r.expo, 65536.0, 0, _ONE)
            self._angle_per_q = self.angle_limit_rad * _INV20
            if not self.fixed:  # take over from the float filters
                raw = self.stick_raw
                for i in range(4):
                    lo = 0 if i == 3 else -_ONE20
                    st[S_X + i] = _q(raw[i] if i < 3 else self.throttle_raw, 1048576.0, lo, _ONE20)
                    st[S_S1 + i] = _q(f[i].s1, 1048576.0, lo, _ONE20)
                    st[S_Y + i] = _q(f[i].y, 1048576.0, lo, _ONE20)
        elif self.fixed:  # hand back
            for i in range(4):
                f[i].s1 = st[S_S1 + i] * _INV20
                f[i].y = st[S_Y + i] * _INV20
        self.fixed = on

    def _refresh(self):
        """The angle and throttle floats from rc_pass's outputs (after they changed other than by a pass)."""
        st = self._st
        self._roll_angle_rad = st[S_Y] * self._angle_per_q
        self._pitch_angle_rad = st[S_Y + 1] * self._angle_per_q
        self._throttle_norm = st[S_Y + 3] * _INV20

    def set_arm_range(self, ch, min_us, max_us):
        """Arm when channel `ch` (1-based, 0 = never) reads min_us <= µs < max_us. configure()
        sets it from arm_ch/arm_min_us/arm_max_us; an arm source with its own rule (seed 001:
        above 1500 µs) sets it after that."""
        self._arm = (aux_channel(self.map_ch, ch), min_us, max_us)
        self.frame_table()

    def _configure_yaw_hold(self, params):
        """Heading hold on or off. On, update() is the hold's (an instance attribute over the method): the
        pass with yaw_hold off runs the plain update() with not even a test added."""
        self.yaw_hold = params.get("yaw_hold") == 1
        self._hold_k = params.get("yaw_hold_p")
        self._hold_max_rad_s = self.rates[2].rate_rad_s(1.0)  # no faster than the yaw stick's full rate
        self.holding = False
        self.hold_rate_rad_s = 0.0
        if self.yaw_hold:
            self.update = self._update_holding
        else:
            try:
                del self.update  # the class's update() again
            except AttributeError:
                pass

    def hold_heading(self, armed, yaw_rad):
        """Heading hold, at 100 Hz (Commander.task; seed 001 holds yaw at its zero): with the yaw stick
        centred (in its deadband) the yaw rate setpoint steers back to the heading the stick was centred at,
        yaw_hold_p rad/s per radian of error, capped at the stick's full rate. Disarmed, or with the stick
        off centre, nothing is held: arming, or centring the stick, takes the heading of that moment."""
        if not armed or self.stick_raw[2] != 0.0:
            self.holding = False
            return
        if not self.holding:  # just armed, or the stick just centred: hold this heading
            self.heading_rad = yaw_rad
        err = self.heading_rad - yaw_rad
        if err > math.pi:
            err -= 2.0 * math.pi
        elif err < -math.pi:
            err += 2.0 * math.pi
        rate = err * self._hold_k
        lim = self._hold_max_rad_s
        self.hold_rate_rad_s = lim if rate > lim else (-lim if rate < -lim else rate)
        self.holding = True

    def _update_holding(self, sp):
        """update() with the heading hold on: the stick shaping, then the hold's yaw rate while it holds."""
        RcInput.update(self, sp)
        if self.holding:
            sp.rate_rad_s[2] = self.hold_rate_rad_s

    def fs_switch_in(self, channels_us):
        """True when the failsafe switch (fs_switch_ch, 0 = none) is in range in this raw frame."""
        ch, lo, hi = self._fs_switch  # _in_range() inline: a call a frame fewer
        return 0 < ch <= len(channels_us) and lo <= channels_us[ch - 1] < hi

    def _stick(self, us, deadband):
        d = us - 1500
        if d > deadband:
            d -= deadband
        elif d < -deadband:
            d += deadband
        else:
            return 0.0
        v = d / (500.0 - deadband)
        if v > 1.0:
            return 1.0
        if v < -1.0:
            return -1.0
        return v

    def new_frame(self, channels_us, src_us=None):
        """Take one receiver frame (µs per channel, an array("H")); src_us: the receiver's 16 channels, copied
        into channels_us first (the Flight's rc_channels_us, the pilot's frame) in the same call."""
        # One call (rc_frame, viper on MicroPython) for the copy, the sticks that moved, their fixed-point
        # inputs and the mode switches; the floats here only for the sticks that moved.
        r = _rc_frame(self._fco, self._last_us, channels_us, self._st, channels_us if src_us is None else src_us)
        if r & 15:
            self._sticks(channels_us, r)
        self.arm_switch = (r & RF_ARM) != 0
        self.mode = MODE_HORIZON if r & RF_HORIZON else (MODE_ANGLE if r & RF_ANGLE else MODE_ACRO)
        self.airmode_switch = (r & RF_AIRMODE) != 0
        self.ap_switch = (r & RF_AP) != 0
        self.frames += 1

    def _sticks(self, channels_us, r):
        """The floats of the sticks that moved (r: rc_frame's mask). In fixed point from the Q20 rc_frame
        made (within 2**-21 of _stick's; one float object a moving stick); else _stick's."""
        raw = self.stick_raw
        if self.fixed:
            st = self._st
            if r & 1:
                raw[0] = st[S_X] * _INV20
            if r & 2:
                raw[1] = st[S_X + 1] * _INV20
            if r & 4:
                raw[2] = st[S_X + 2] * _INV20
        else:
            if r & 1:
                raw[0] = self._stick(channels_us[self.roll_ch], self.deadband_us)
            if r & 2:
                raw[1] = -self._stick(channels_us[self.pitch_ch], self.deadband_us)  # forward: nose down (FRD)
            if r & 4:
                raw[2] = self._stick(channels_us[self.yaw_ch], self.yaw_deadband_us)
        if r & 8:
            self._throttle(channels_us[self.throttle_ch])

    def _throttle(self, t):
        self.throttle_us = t
        b = self._thr_bands
        if b is not None:
            # Seed 001: the stick's third (1000-1332, 1333-1665, 1666-2000 µs) picks a stored value.
            t = b[0] if t < 1333 else (b[1] if t < 1666 else b[2])
        thr = (t - 1000) * 0.001
        self.throttle_raw = 0.0 if thr < 0.0 else (1.0 if thr > 1.0 else thr)
        if self.fixed:
            self._st[S_X + 3] = _throttle_q(t)

    def throttle_low(self):
        return self.throttle_us < self.min_check_us

    def reset_smoothing(self):
        for axis in range(3):
            self.filters[axis].reset(self.stick_raw[axis])
        self.filters[3].reset(self.throttle_raw)
        if self.fixed:
            st = self._st
            for i in range(4):
                st[S_S1 + i] = st[S_Y + i] = st[S_X + i]
        self._forget()

    def update(self, sp):
        """Smooth the latest frame into the setpoint (every pass). On MicroPython the viper generated from
        this method and rc_pass (accel/rc.py `update`) stands in for it; `update_python` keeps it."""
        # Few locals on purpose: a bytecode function whose frame (locals and value stack) passes 11
        # machine words takes it from the heap on every call on MicroPython (docs/pico.md).
        if not self.fixed:
            self._update_float(sp)
            return
        changed = rc_pass(self._co, self._st, sp.stick_norm, sp.rate_rad_s)
        if changed:
            st = self._st
            if changed & 1:
                self._roll_angle_rad = st[S_Y] * self._angle_per_q
            if changed & 2:
                self._pitch_angle_rad = st[S_Y + 1] * self._angle_per_q
            if changed & 8:
                self._throttle_norm = st[S_Y + 3] * _INV20
        sp.roll_angle_rad = self._roll_angle_rad
        sp.pitch_angle_rad = self._pitch_angle_rad
        sp.throttle_norm = self._throttle_norm

    def _update_float(self, sp):
        """update() in float: each stick and the throttle through its filter, then the rates and angles."""
        f = self.filters
        s = sp.stick_norm
        raw = self.stick_raw
        if self._smooth_type != "pt2":
            # Alpha-beta overshoots a step (its velocity term): held to the sticks' range, so a full stick
            # never asks for more than angle_limit or the full rate.
            for i in range(3):
                v = f[i].update(raw[i])
                s[i] = 1.0 if v > 1.0 else (-1.0 if v < -1.0 else v)
            v = f[3].update(self.throttle_raw)
            sp.throttle_norm = 1.0 if v > 1.0 else (0.0 if v < 0.0 else v)
        else:
            s[0] = f[0].update(raw[0])
            s[1] = f[1].update(raw[1])
            s[2] = f[2].update(raw[2])
            sp.throttle_norm = f[3].update(self.throttle_raw)
        self.fill_setpoint(sp)

    def fill_setpoint(self, sp):
        s = sp.stick_norm
        r = sp.rate_rad_s
        rates = self.rates
        r[0] = rates[0].rate_rad_s(s[0])
        r[1] = rates[1].rate_rad_s(s[1])
        r[2] = rates[2].rate_rad_s(s[2])
        sp.roll_angle_rad = s[0] * self.angle_limit_rad
        sp.pitch_angle_rad = s[1] * self.angle_limit_rad


update_python = RcInput.update
if HAS_ACCEL:
    RcInput.update = _viper.update
