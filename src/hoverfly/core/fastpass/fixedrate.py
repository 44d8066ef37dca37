"""The rate loop in fixed point: the controller's PIDs and the mixer as integers (zero allocation).

On MicroPython every float result is a new heap object; the float controller and mixer make about
4.3 kB of them a pass (bench/core_stages.py). `FixedRate` runs the same arithmetic on small integers:
`rate_pass` below is its one source. On MicroPython its viper twin (accel/rate.py, generated from it by
hoverfly.fastgen, docs/fastpass.md) stands in for `update`; tests/portable/test_fixedrate.py holds the
two equal bit for bit. The float stages
(core/stages/control.py, core/stages/pid.py, core/stages/mixer.py) stay the reference for what the numbers mean: the
coefficients here are worked out from their configured values, and the results agree with theirs
within the rounding the formats below allow (the same test).

Chosen by `pid_math`: "auto" uses it on MicroPython where the viper twin loads, "fixed" anywhere
(CPython then runs the Python twin: slower, for comparison flights), "float" never. Not for a D-term
biquad or a servo-yaw frame (tri): those keep the float stages.

Formats (value = integer / 2**q):
- rates, torques, PID terms, throttle, motor commands: Q16, inputs clamped to +-128 (2**23;
  gyros saturate near 35 rad/s) and throttle to 0..1; sticks and TPA: Q15; angles: Q24, clamped
  to +-4 rad (angle mode feeds their change forward at the loop rate: Q16 would step it by 8 mrad/s);
- the I-term: Q26 (steps of 1.5e-8 of the mixer range); rate derivatives: Q7 (rad/s^2), clamped
  to 2**26;
- D-min's boost and factor: Q15 (the boost capped at 2); anti-gravity's throttle speed: Q12 (1/s), its
  boost Q10 (capped at 31), an I step capped at half the range before it is boosted;
- gains and filter coefficients: a 15-bit mantissa m and a shift s, value = m / 2**s.
A product is `floor(c * x / 2**s)` with |c| < 2**15 and |x| < 2**31; the viper twin splits x in
16-bit halves (`_mul`) so no partial product passes 2**31 on a 32-bit port, and every sum stays below
2**31 by the bounds above (tests/portable/test_fixedrate.py drives extreme inputs through a
checked product). The pass's dt is clamped to 64..20000 µs (a derivative over less than 64 µs
would need more bits; a gap over 20 ms is a stall, not a pass).
Inputs that are not numbers (NaN) read as 0, infinities as the clamp.
"""

from array import array

from hoverfly.compat import IS_MICROPYTHON, const
from hoverfly.core.fastpass.fixedmath import dec as _dec
from hoverfly.core.fastpass.fixedmath import mul as _mul
from hoverfly.core.stages.control import MODE_ACRO, MODE_ANGLE
from hoverfly.core.stages.estimator import PITCH, ROLL
from hoverfly.core.stages.pid import RELAX_THRESHOLD_RAD_S

# ---- coefficient layout (co, array "i")
ANG_GAIN_M = const(0)
ANG_GAIN_S = const(1)
ANG_FF_M = const(2)
ANG_FF_S = const(3)
ANG_LIM = const(4)
HORIZON = const(5)
TPA_ON = const(6)
TPA_BP = const(7)
TPA_M = const(8)
TPA_S = const(9)
TPA_P = const(10)
MOTORS = const(11)
DT_NOMINAL = const(12)
TERMS_EVERY = const(13)  # the PID terms and torques written out every this many passes (0 or 1: every pass)
AXIS = const(16)  # three axes of AX_SIZE from here
AX_SIZE = const(20)
KP_M = const(0)
KP_S = const(1)
KI_M = const(2)
KI_S = const(3)
KD_M = const(4)  # the D gain negated: D on measurement damps
KD_S = const(5)
KF_M = const(6)
KF_S = const(7)
KST_M = const(8)
KST_S = const(9)
ILIM = const(10)
SLIM = const(11)
RELAX = const(12)
RK_M = const(13)
RK_S = const(14)
RT_M = const(15)
RT_S = const(16)
DK_M = const(17)
DK_S = const(18)
DPT2 = const(19)
MIX = const(76)  # roll, pitch, yaw weights per motor (Q14), eight motors
AG_ON = const(100)  # anti-gravity
AG_K_M = const(101)  # its PT2's stage gain
AG_K_S = const(102)
AG_G_M = const(103)  # ag_gain: the smoothed throttle speed (Q12, 1/s) to the boost (Q10)
AG_G_S = const(104)
AG_P = const(105)  # P's share of the boost, Q10 (at most 0.85)
DM_RK_M = const(107)  # D-min's range PT2 (85 Hz) and its smoothing PT2 (35 Hz): stage gains
DM_RK_S = const(108)
DM_LK_M = const(109)
DM_LK_S = const(110)
DM = const(111)  # per axis, DM_SIZE from here: D-min
DM_SIZE = const(5)
DM_PCT = const(0)  # d_min / d_max, Q15; 0: D-min off on this axis
DM_G_M = const(1)  # gyro acceleration (Q7) to the boost (Q15)
DM_G_S = const(2)
DM_S_M = const(3)  # setpoint acceleration (Q7) to the boost (Q15)
DM_S_S = const(4)
TRIM_ROLL = const(126)  # the accelerometer trims (Controller.trim_*_rad), Q24 rad
TRIM_PITCH = const(127)
CO_SIZE = const(128)

# ---- state layout (st, array "i")
ST_AX = const(8)  # per axis: I (Q26), OUT, last gyro, last setpoint, relax y, D stage 1, D stage 2
S_I = const(0)
S_OUT = const(1)
S_LG = const(2)
S_LS = const(3)
S_RY = const(4)
S_D1 = const(5)
S_D2 = const(6)
S_LAST_ROLL = const(24)
S_LAST_PITCH = const(25)
S_DT = const(26)
S_INV_DT = const(27)
S_TPA = const(28)
S_SAT = const(29)
S_MIX = const(30)
S_TERMS_N = const(38)  # passes left until the PID terms and torques are written out again
S_DM = const(40)  # per axis, 4 words: D-min's range PT2 (Q7) and smoothing PT2 (Q15) stages
S_AG1 = const(52)  # anti-gravity's PT2 stages (Q12, 1/s) and the last throttle (Q24)
S_AG2 = const(53)
S_AG_THR = const(54)
ST_SIZE = const(80)

# flags argument
F_MODE = const(3)
F_I_ACTIVE = const(4)
F_AIRMODE = const(8)

# fin: the set point's scalars, stored by FixedRate.update (a float store allocates nothing). The estimate's
# angles are read from the Attitude's own array (attitude.angles, ROLL and PITCH), bound at configure.
IN_THR = const(0)
IN_ROLL_SP = const(1)
IN_PITCH_SP = const(2)

_ONE16 = const(65536)
_LIM16 = const(0x800000)  # 2**23
_LIM24 = const(0x4000000)  # 2**26: +-4 rad in Q24
_ONE15 = const(32768)
_ONE24 = const(0x1000000)
_DERIV_LIM = const(0x4000000)  # 2**26
_DSP_LIM = const(0x2000000)  # 2**25: 2 rad in Q24, the most an angle setpoint may move in a pass
_FFA_LIM = const(0x800000)  # 2**23: the angle setpoint's speed, Q16
_DT_MIN = const(64)
_DT_MAX = const(20000)
_INV16 = 1.0 / 65536.0
_INV24 = 1.0 / 16777216.0
_INV26 = 1.0 / 67108864.0
_INV15 = 1.0 / 32768.0
_HALF26 = const(0x2000000)  # 0.5 in Q26: an I step is capped here before anti-gravity boosts it
_AG_MAX = const(31744)  # 31 in Q10 (pid.AG_BOOST_MAX)
_DM_MAX = const(65536)  # 2 in Q15 (pid.DMIN_BOOST_MAX)

_viper = None
if IS_MICROPYTHON:
    try:  # generated from rate_pass below by hoverfly.fastgen; absent, or a port without viper: the Python runs
        from hoverfly.accel import rate as _viper
    except (ImportError, SyntaxError, NameError, ValueError, TypeError):  # TypeError: ViperTypeError
        pass
HAS_ACCEL = _viper is not None


def coef(value, cap=40):
    """(m, s) with value ~ m / 2**s, 2**14 <= |m| < 2**15 (smaller only where s would pass `cap`).
    Raises ValueError for a value of 2**15 or more."""
    if value == 0:
        return 0, 0
    a = value if value > 0 else -value
    s = 0
    while a * (1 << s) < 16384.0 and s < cap:
        s += 1
    m = int(a * (1 << s) + 0.5)
    if m >= 32768:
        if s == 0:
            raise ValueError("coefficient out of range")
        s -= 1
        m = int(a * (1 << s) + 0.5)
    return (m if value > 0 else -m), s


def _level_rate(co, st, last, angle_sp, angle, inv_dt):
    """Angle mode's rate setpoint for one axis (Q16) from its angle setpoint and angle (Q24)."""
    v = angle_sp - st[last]
    if v > _DSP_LIM:  # 2 rad in a pass: even at 64 Hz, past the speed clamp below
        v = _DSP_LIM
    elif v < -_DSP_LIM:
        v = -_DSP_LIM
    v = _mul(inv_dt, v, 8)
    if v > _FFA_LIM:
        v = _FFA_LIM
    elif v < -_FFA_LIM:
        v = -_FFA_LIM
    rate = _mul(co[ANG_GAIN_M], angle_sp - angle, co[ANG_GAIN_S] + 8) + _mul(co[ANG_FF_M], v, co[ANG_FF_S])
    lim = co[ANG_LIM]
    if rate > lim:
        return lim
    if rate < -lim:
        return -lim
    return rate


# fastpass: FixedRate.update co:i st:i fin:f gyro:f rate:f stick:f terms:f torque:f motor:f angles:f
def rate_pass(co, st, io, flags, dt_us):
    """One pass of the angle loop, the three rate PIDs and the mixer. io = (fin, gyro, rate, stick,
    terms, torque, motor, angles): float arrays, read and written as core/stages/control.py and
    core/stages/mixer.py do (angles: the estimate, Attitude.angles).
    Returns bit 0: saturated, bit 1: the TPA factor changed (st[S_TPA], Q15)."""
    fin, gyro, rate, stick, terms, torque, motor, angles = io
    mul = _mul
    # The PID terms and the torques are outputs for the log and the maintenance telemetry only: written
    # every co[TERMS_EVERY] passes (FixedRate.terms_every: every pass while a log runs).
    terms_now = True
    every = co[TERMS_EVERY]
    if every > 1:
        c = st[S_TERMS_N] - 1
        if c <= 0:
            c = every
        else:
            terms_now = False
        st[S_TERMS_N] = c
    # dt: clamped, 1/dt worked out when it changes
    if dt_us <= 0:
        dt_us = co[DT_NOMINAL]
    if dt_us < _DT_MIN:
        dt_us = _DT_MIN
    elif dt_us > _DT_MAX:
        dt_us = _DT_MAX
    if dt_us != st[S_DT]:
        st[S_DT] = dt_us
        st[S_INV_DT] = 1000000 // dt_us
    inv_dt = st[S_INV_DT]
    mode = flags & F_MODE
    thr = _dec(fin[IN_THR], 65536.0, _LIM16)
    if thr < 0:
        thr = 0
    elif thr > _ONE16:
        thr = _ONE16
    sp0 = _dec(rate[0], 65536.0, _LIM16)
    sp1 = _dec(rate[1], 65536.0, _LIM16)
    sp2 = _dec(rate[2], 65536.0, _LIM16)
    # the angle loop: P on the angle error plus feed-forward of the angle setpoint's speed
    roll_sp = _dec(fin[IN_ROLL_SP], 16777216.0, _LIM24)
    pitch_sp = _dec(fin[IN_PITCH_SP], 16777216.0, _LIM24)
    if mode != MODE_ACRO:
        lr = _level_rate(co, st, S_LAST_ROLL, roll_sp, _dec(angles[ROLL], 16777216.0, _LIM24) - co[TRIM_ROLL], inv_dt)
        lp = _level_rate(co, st, S_LAST_PITCH, pitch_sp, _dec(angles[PITCH], 16777216.0, _LIM24) - co[TRIM_PITCH],
                         inv_dt)
        if mode == MODE_ANGLE:
            sp0 = lr
            sp1 = lp
        else:  # horizon: full levelling at centre stick, none at full deflection
            d0 = _dec(stick[0], 32768.0, _ONE15)
            if d0 < 0:
                d0 = -d0
            d1 = _dec(stick[1], 32768.0, _ONE15)
            if d1 < 0:
                d1 = -d1
            if d1 > d0:
                d0 = d1
            w = (co[HORIZON] * (_ONE15 - d0)) >> 15
            if w >= _ONE15:
                sp0 = lr
                sp1 = lp
            elif w > 0:
                sp0 += mul(w, lr - sp0, 15)
                sp1 += mul(w, lp - sp1, 15)
        rate[0] = sp0 * _INV16
        rate[1] = sp1 * _INV16
    st[S_LAST_ROLL] = roll_sp
    st[S_LAST_PITCH] = pitch_sp
    # TPA: the gain cut above the breakpoint
    tpa = _ONE15
    if co[TPA_ON] and thr > co[TPA_BP]:
        tpa = _ONE15 - mul(co[TPA_M], thr - co[TPA_BP], co[TPA_S])
    changed = 2 if tpa != st[S_TPA] else 0
    st[S_TPA] = tpa
    i_active = flags & F_I_ACTIVE
    # anti-gravity: the throttle's speed, weighted to low throttle, through a PT2: I and P boosted by it
    # (from rest where I starts, as core/stages/control.py's)
    ag = 0
    if co[AG_ON] and not i_active:
        t24 = _dec(fin[IN_THR], 16777216.0, _ONE24)
        st[S_AG_THR] = t24 if t24 > 0 else 0
        st[S_AG1] = 0
        st[S_AG2] = 0
    elif co[AG_ON]:
        # the throttle's change in Q24: a hovering pilot's throttle moves by less than Q16's step in a pass,
        # and the speed's absolute value would not average that rounding out
        t24 = _dec(fin[IN_THR], 16777216.0, _ONE24)
        if t24 < 0:
            t24 = 0
        x = t24 - st[S_AG_THR]
        st[S_AG_THR] = t24
        rising = x > 0
        if x < 0:
            x = -x
        x = mul(inv_dt, x, 12)  # Q12: at most 2**24 * 15625 / 4096, below 2**26
        w = (_ONE16 - thr) >> 1  # 1 - throttle, Q15: a coefficient, so below 2**15
        if w > 32767:
            w = 32767
        x = mul((w * w) >> 15, x, 15)  # (1 - throttle)**2: w * w below 2**30
        if rising:
            x = mul(w, x, 16)
        y = st[S_AG1]
        y += mul(co[AG_K_M], x - y, co[AG_K_S])
        st[S_AG1] = y
        y2 = st[S_AG2]
        y2 += mul(co[AG_K_M], y - y2, co[AG_K_S])
        st[S_AG2] = y2
        ag = mul(co[AG_G_M], y2, co[AG_G_S])
        if ag > _AG_MAX:
            ag = _AG_MAX
        elif ag < 0:
            ag = 0
    sat = st[S_SAT]
    for k in range(3):
        b = AXIS + k * AX_SIZE
        sb = k * ST_AX
        sp = sp0 if k == 0 else (sp1 if k == 1 else sp2)
        g = _dec(gyro[k], 65536.0, _LIM16)
        t = tpa if k != 2 else _ONE15
        err = sp - g
        p = mul(co[b + KP_M], err, co[b + KP_S])
        if co[TPA_P] and t != _ONE15:
            p = mul(t, p, 15)
        if ag and k != 2:
            p += mul((ag * co[AG_P]) >> 10, p, 10)  # ag below 2**15, the share below 2**10
        if i_active:
            i = st[sb + S_I]
            step = mul(co[b + KI_M], mul(dt_us, err, 8), co[b + KI_S])
            if co[b + RELAX]:
                y = st[sb + S_RY]
                y += mul(co[b + RK_M], sp - y, co[b + RK_S])
                st[sb + S_RY] = y
                hp = sp - y
                if hp < 0:
                    hp = -hp
                factor = _ONE15 - mul(co[b + RT_M], hp, co[b + RT_S])
                if factor <= 0:
                    step = 0
                elif factor != _ONE15:
                    step = mul(factor, step, 15)
            if ag:
                if step > _HALF26:
                    step = _HALF26
                elif step < -_HALF26:
                    step = -_HALF26
                step += mul(ag, step, 10)
            if not sat or (step > 0) != (st[sb + S_OUT] > 0):
                i += step
            lim = co[b + ILIM]
            if i > lim:
                i = lim
            elif i < -lim:
                i = -lim
        else:
            i = 0
        st[sb + S_I] = i
        # D on measurement through its low-pass (PT1, or PT2 as two stages)
        x = mul(inv_dt, g - st[sb + S_LG], 9)
        if x > _DERIV_LIM:
            x = _DERIV_LIM
        elif x < -_DERIV_LIM:
            x = -_DERIV_LIM
        st[sb + S_LG] = g
        y = st[sb + S_D1]
        y += mul(co[b + DK_M], x - y, co[b + DK_S])
        st[sb + S_D1] = y
        if co[b + DPT2]:
            y2 = st[sb + S_D2]
            y2 += mul(co[b + DK_M], y - y2, co[b + DK_S])
            st[sb + S_D2] = y2
            y = y2
        # the setpoint's acceleration (Q7): D-min's advance and the feed-forward
        x = mul(inv_dt, sp - st[sb + S_LS], 9)
        if x > _DERIV_LIM:
            x = _DERIV_LIM
        elif x < -_DERIV_LIM:
            x = -_DERIV_LIM
        dm = DM + k * DM_SIZE
        pct = co[dm + DM_PCT]
        if pct:
            # D-min: D at pct of D max at rest, raised by the gyro's or the stick's acceleration
            sd = S_DM + k * 4
            r = st[sd]
            r += mul(co[DM_RK_M], y - r, co[DM_RK_S])
            st[sd] = r
            r2 = st[sd + 1]
            r2 += mul(co[DM_RK_M], r - r2, co[DM_RK_S])
            st[sd + 1] = r2
            if r2 < 0:
                r2 = -r2
            g = mul(co[dm + DM_G_M], r2, co[dm + DM_G_S])
            a = x if x >= 0 else -x
            a = mul(co[dm + DM_S_M], a, co[dm + DM_S_S])
            if a > g:
                g = a
            if g > _DM_MAX:
                g = _DM_MAX
            g = pct + (((_ONE15 - pct) * g) >> 15)  # below 2**15 * 2**16
            q = st[sd + 2]
            q += mul(co[DM_LK_M], g - q, co[DM_LK_S])
            st[sd + 2] = q
            q2 = st[sd + 3]
            q2 += mul(co[DM_LK_M], q - q2, co[DM_LK_S])
            st[sd + 3] = q2
            if q2 < _ONE15:
                y = mul(q2, y, 15)
        d = mul(co[b + KD_M], y, co[b + KD_S])
        if t != _ONE15:
            d = mul(t, d, 15)
        # feed-forward of the setpoint's change, and the static feed-forward (PIFF)
        f = mul(co[b + KF_M], x, co[b + KF_S]) + mul(co[b + KST_M], sp, co[b + KST_S])
        st[sb + S_LS] = sp
        out = p + (i >> 10) + d + f
        lim = co[b + SLIM]
        if out > lim:
            out = lim
        elif out < -lim:
            out = -lim
        st[sb + S_OUT] = out
        if terms_now:
            terms[k] = p * _INV16
            terms[k + 3] = i * _INV26
            terms[k + 6] = d * _INV16
            terms[k + 9] = f * _INV16
            torque[k] = out * _INV16
    # the mixer: torques to motors, desaturated as core/stages/mixer.py does
    r = st[S_OUT]
    pt = st[ST_AX + S_OUT]
    yw = st[2 * ST_AX + S_OUT]
    n = co[MOTORS]
    lo = 0x40000000
    hi = -0x40000000
    for m in range(n):
        w = MIX + 3 * m
        v = mul(co[w], r, 14) + mul(co[w + 1], pt, 14) + mul(co[w + 2], yw, 14)
        st[S_MIX + m] = v
        if v < lo:
            lo = v
        if v > hi:
            hi = v
    span = hi - lo
    sat = 0
    airmode = flags & F_AIRMODE
    throttle = thr
    if span > _ONE16:
        scale = 0x40000000 // span
        for m in range(n):
            st[S_MIX + m] = mul(scale, st[S_MIX + m], 14)
        lo = mul(scale, lo, 14)
        hi = mul(scale, hi, 14)
        if airmode:
            throttle = _ONE16 >> 1
        sat = 1
    if airmode or span > _ONE16:
        if throttle + hi > _ONE16:
            throttle = _ONE16 - hi
        if throttle + lo < 0:
            throttle = -lo
    for m in range(n):
        v = throttle + st[S_MIX + m]
        if v < 0:
            v = 0
            sat = 1
        elif v > _ONE16:
            v = _ONE16
            sat = 1
        motor[m] = v * _INV16
    st[S_SAT] = sat
    return sat | changed


def _q(value, one):
    """A configured float as fixed point (rounded), for limits and thresholds."""
    return int(value * one + (0.5 if value >= 0 else -0.5))


class FixedRate:
    """The controller and mixer of a flight as one fixed-point pass (see the module docstring).

    `configure(controller, mixer, loop_hz, pid_math, signals)` returns whether the fixed pass runs: it reads
    the float stages' configured gains and filters, and takes over their state (I-terms, filters,
    last samples) so a switch mid-session starts where they were. `update()` then stands in for
    `Controller.update` plus `Mixer.update`; `release()` hands the state back to the float stages."""

    def __init__(self):
        self.co = array("i", [0] * CO_SIZE)
        self.st = array("i", [0] * ST_SIZE)
        self.fin = array("f", [0.0] * 3)
        self.active = False
        self._io = None
        # the viper twin's table of the arrays' addresses (accel/rate.py), written by configure
        self._tab = array("i", [0] * _viper.TAB_SIZE) if HAS_ACCEL else None
        self._controller = None
        self._mixer = None

    def terms_every(self, passes):
        """Write the PID terms and torques (signals.pid_terms, torque_norm) out every `passes` passes; 1:
        every pass, as a log needs them. Only outputs: the controller and the mixer do not read them."""
        self.co[TERMS_EVERY] = passes

    def configure(self, controller, mixer, loop_hz, pid_math, signals):
        supported = not mixer.servo_yaw and mixer.n <= 8
        for pid in (controller.roll, controller.pitch, controller.yaw):
            if pid.dterm_filter._active is pid.dterm_filter._biquad:
                supported = False
        want = pid_math == "fixed" or (pid_math == "auto" and HAS_ACCEL)
        if not (want and supported):
            self.release()
            return False
        self._controller = controller
        self._mixer = mixer
        sp = signals.setpoint
        self._io = (self.fin, signals.gyro_rad_s, sp.rate_rad_s, sp.stick_norm, signals.pid_terms,
                    signals.torque_norm, signals.motor_norm, signals.attitude.angles)
        co = self.co
        c = controller
        co[ANG_GAIN_M], co[ANG_GAIN_S] = coef(c.angle_gain)
        co[ANG_FF_M], co[ANG_FF_S] = coef(c.angle_ff)
        co[ANG_LIM] = _q(c.angle_rate_limit, _ONE16)
        co[TRIM_ROLL] = _q(c.trim_roll_rad, 16777216.0)
        co[TRIM_PITCH] = _q(c.trim_pitch_rad, 16777216.0)
        co[HORIZON] = _q(c.horizon_strength, _ONE15)
        bp = c.tpa_breakpoint
        co[TPA_ON] = 1 if bp < 1.0 else 0
        co[TPA_BP] = _q(bp, _ONE16)
        # tpa = 1 - rate * (thr - bp) / (1 - bp): Q16 throttle in, Q15 cut out
        co[TPA_M], co[TPA_S] = coef(c.tpa_rate / (1.0 - bp) * 0.5) if bp < 1.0 else (0, 0)
        co[TPA_P] = 1 if c.roll.tpa_on_p else 0
        co[MOTORS] = mixer.n
        co[DT_NOMINAL] = 1000000 // loop_hz
        for k, pid in enumerate((c.roll, c.pitch, c.yaw)):
            b = AXIS + k * AX_SIZE
            co[b + KP_M], co[b + KP_S] = coef(pid.kp)
            co[b + KI_M], co[b + KI_S] = coef(pid.ki * 0.262144)  # Q8 rad*µs in, Q26 out: 2**18 / 1e6
            co[b + KD_M], co[b + KD_S] = coef(-pid.kd * 512.0)  # Q7 derivative in, Q16 out
            co[b + KF_M], co[b + KF_S] = coef(pid.kf * 512.0)
            co[b + KST_M], co[b + KST_S] = coef(pid.k_static)
            co[b + ILIM] = _q(pid.i_limit, 1 << 26)
            co[b + SLIM] = _q(pid.sum_limit, _ONE16)
            co[b + RELAX] = 1 if pid.relax else 0
            co[b + RK_M], co[b + RK_S] = coef(pid.relax_filter.k)
            # factor = 1 - |hp| / threshold: Q16 in, Q15 out
            co[b + RT_M], co[b + RT_S] = coef(0.5 / RELAX_THRESHOLD_RAD_S)
            lp = pid.dterm_filter
            pt2 = lp._active is lp._pt2
            co[b + DK_M], co[b + DK_S] = coef(lp._pt2.k if pt2 else lp._pt1.k)
            co[b + DPT2] = 1 if pt2 else 0
            dm = DM + k * DM_SIZE
            co[dm + DM_PCT] = _q(pid.dmin_pct, _ONE15) if pid.dmin_on else 0
            co[dm + DM_G_M], co[dm + DM_G_S] = coef(pid.dmin_gyro_gain * 256.0)  # Q7 in, Q15 out
            co[dm + DM_S_M], co[dm + DM_S_S] = coef(pid.dmin_sp_gain * 256.0)
        co[DM_RK_M], co[DM_RK_S] = coef(c.roll.dmin_range.k)
        co[DM_LK_M], co[DM_LK_S] = coef(c.roll.dmin_lowpass.k)
        co[AG_ON] = 1 if c.ag_gain != 0.0 else 0
        co[AG_K_M], co[AG_K_S] = coef(c.ag_filter.k)
        co[AG_G_M], co[AG_G_S] = coef(c.ag_gain * 0.25)  # Q12 in, Q10 out
        co[AG_P] = _q(c.ag_p_share, 1024)
        for m in range(8):
            w = MIX + 3 * m
            if m < mixer.n:
                co[w] = _q(mixer.roll_w[m], 16384)
                co[w + 1] = _q(mixer.pitch_w[m], 16384)
                co[w + 2] = _q(mixer.yaw_w[m], 16384)
            else:
                co[w] = co[w + 1] = co[w + 2] = 0
        if HAS_ACCEL:
            tab = self._tab
            _viper.bind(tab, 0, co)
            _viper.bind(tab, 1, self.st)
            for k in range(8):
                _viper.bind(tab, 2 + k, self._io[k])
            _viper.bind(tab, 10, _viper.LOG2)
        if not self.active:
            self._take_state()
        self.active = True
        return True

    def _take_state(self):
        c = self._controller
        st = self.st
        for k, pid in enumerate((c.roll, c.pitch, c.yaw)):
            sb = k * ST_AX
            st[sb + S_I] = _q(pid.i, 1 << 26)
            st[sb + S_OUT] = _q(pid.out, _ONE16)
            st[sb + S_LG] = _dec(pid._last_gyro, 65536.0, _LIM16)
            st[sb + S_LS] = _dec(pid._last_setpoint, 65536.0, _LIM16)
            st[sb + S_RY] = _dec(pid.relax_filter.y, 65536.0, _LIM16)
            lp = pid.dterm_filter
            if lp._active is lp._pt2:
                st[sb + S_D1] = _dec(lp._pt2.s1, 128.0, _DERIV_LIM)
                st[sb + S_D2] = _dec(lp._pt2.y, 128.0, _DERIV_LIM)
            else:
                st[sb + S_D1] = _dec(lp._pt1.y, 128.0, _DERIV_LIM)
                st[sb + S_D2] = 0
            sd = S_DM + k * 4
            st[sd] = _dec(pid.dmin_range.s1, 128.0, _DERIV_LIM)
            st[sd + 1] = _dec(pid.dmin_range.y, 128.0, _DERIV_LIM)
            st[sd + 2] = _dec(pid.dmin_lowpass.s1, 32768.0, _DM_MAX)
            st[sd + 3] = _dec(pid.dmin_lowpass.y, 32768.0, _DM_MAX)
        st[S_AG1] = _dec(c.ag_filter.s1, 4096.0, _DERIV_LIM)
        st[S_AG2] = _dec(c.ag_filter.y, 4096.0, _DERIV_LIM)
        st[S_AG_THR] = _dec(c._ag_last_thr, 16777216.0, _ONE24)
        st[S_LAST_ROLL] = _dec(c._last_roll_sp, 16777216.0, _LIM24)
        st[S_LAST_PITCH] = _dec(c._last_pitch_sp, 16777216.0, _LIM24)
        st[S_DT] = 0
        st[S_TPA] = _q(c.tpa, _ONE15)
        st[S_SAT] = 1 if self._mixer.saturated else 0

    def release(self):
        """Give the state back to the float stages (the fixed pass stops)."""
        if self.active:
            self.give_state()
            self.active = False

    def give_state(self):
        """Write the fixed pass's state into the float stages (release; tests compare a pass from it)."""
        c = self._controller
        st = self.st
        for k, pid in enumerate((c.roll, c.pitch, c.yaw)):
            sb = k * ST_AX
            pid.i = st[sb + S_I] * _INV26
            pid.out = st[sb + S_OUT] * _INV16
            pid._last_gyro = st[sb + S_LG] * _INV16
            pid._last_setpoint = st[sb + S_LS] * _INV16
            pid.relax_filter.y = st[sb + S_RY] * _INV16
            lp = pid.dterm_filter
            if lp._active is lp._pt2:
                lp._pt2.s1 = st[sb + S_D1] / 128.0
                lp._pt2.y = st[sb + S_D2] / 128.0
            else:
                lp._pt1.y = st[sb + S_D1] / 128.0
            sd = S_DM + k * 4
            pid.dmin_range.s1 = st[sd] / 128.0
            pid.dmin_range.y = st[sd + 1] / 128.0
            pid.dmin_lowpass.s1 = st[sd + 2] * _INV15
            pid.dmin_lowpass.y = st[sd + 3] * _INV15
        c.ag_filter.s1 = st[S_AG1] / 4096.0
        c.ag_filter.y = st[S_AG2] / 4096.0
        c._ag_last_thr = st[S_AG_THR] * _INV24
        c._last_roll_sp = st[S_LAST_ROLL] * _INV24
        c._last_pitch_sp = st[S_LAST_PITCH] * _INV24
        c.tpa = st[S_TPA] * _INV15
        self._mixer.saturated = st[S_SAT] != 0

    def _tpa_changed(self):
        """The controller's TPA factor from the pass's (the viper twin calls this only when it changed)."""
        self._controller.tpa = self.st[S_TPA] * _INV15

    def update(self, sp, dt_us, i_active, airmode_active):
        """The controller and mixer for this pass (Flight.step's steps 4 and 5), on the estimate in
        signals.attitude.angles (configure's signals: every writer of the Attitude writes the array with its
        attributes). On MicroPython the viper twin (accel/rate.py `update`) stands in for this method;
        `update_python` keeps it."""
        fin = self.fin
        fin[0] = sp.throttle_norm
        fin[1] = sp.roll_angle_rad
        fin[2] = sp.pitch_angle_rad
        flags = sp.mode
        if i_active:
            flags |= F_I_ACTIVE
        if airmode_active:
            flags |= F_AIRMODE
        r = rate_pass(self.co, self.st, self._io, flags, dt_us)
        self._mixer.saturated = (r & 1) != 0
        if r & 2:
            self._tpa_changed()


update_python = FixedRate.update
if HAS_ACCEL:
    FixedRate.update = _viper.update

