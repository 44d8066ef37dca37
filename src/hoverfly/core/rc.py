"""Pilot input: receiver channels in µs to sticks, throttle, switches and the setpoint.

A new frame (`new_frame`) maps channels (AETR by default), applies the deadband and
reads the AUX mode ranges (Betaflight style: channel plus µs range per mode, channel 0 =
none): ARM, ANGLE, HORIZON and AIRMODE; the FAILSAFE box is read from the raw frame
(`fs_switch_in`) before it is taken, because with it on the frame counts as lost. Every
pass (`update`) smooths the sticks (rc_smooth_type: PT2 or PT1 at rc_smoothing_hz, or
seed 001's alpha-beta; throttle_norm is the raw stick or, with thr_mode = bands, seed
001's DESCEND/HOVERING/CLIMB value for the stick's third) and turns them into the
setpoint: rates through the "actual" curve, angles through angle_limit. Stage 3 of the
pass, with the commander choosing whose input it is.
"""

import math

from hoverfly.core.control import MODE_ACRO, MODE_ANGLE, MODE_HORIZON
from hoverfly.core.filters import AlphaBeta, Pt1, Pt2
from hoverfly.core.rates import ActualRates

_DEG = math.pi / 180.0

_MAPS = {"AETR": (0, 1, 3, 2), "TAER": (1, 2, 3, 0), "RETA": (3, 2, 1, 0)}  # roll, pitch, yaw, throttle


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
        self.airmode_switch = False
        self.frames = 0
        self._arm = (5, 1700, 2100)
        self._angle = (6, 1300, 2100)
        self._horizon = (6, 1300, 1700)
        self._airmode = (0, 1700, 2100)
        self._fs_switch = (0, 1700, 2100)
        self._smooth_type = "pt2"
        self._thr_bands = None  # seed 001: (DESCEND, HOVERING, CLIMB) µs, or None for the raw stick
        # update()'s PT2 fast path, per filter (roll, pitch, yaw, throttle): `_still[i]` when its last
        # update changed neither state with input `_held[i]`, so the same input gives the same output
        # again (test_rc_fast_path checks this against the plain Pt2). Then the smoothed value
        # `_out[i]`, its rate `_rate_rad_s[i]` (sticks) and angle `_angle_rad[i]` (roll, pitch) are reused.
        self._still = [False, False, False, False]
        self._held = [0.0, 0.0, 0.0, 0.0]
        self._out = [0.0, 0.0, 0.0, 0.0]
        self._rate_rad_s = [0.0, 0.0, 0.0]
        self._angle_rad = [0.0, 0.0]

    def configure(self, params, loop_hz):
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
        for f in self.filters:
            if kind == "alphabeta":
                f.configure(params.get("rc_ab_alpha"), params.get("rc_ab_beta"), loop_hz)
            else:
                f.configure(params.get("rc_smoothing_hz"), loop_hz)
        if params.get("thr_mode") == "bands":
            self._thr_bands = (params.get("thr_descend_us"), params.get("thr_hover_us"), params.get("thr_climb_us"))
        else:
            self._thr_bands = None
        m = _MAPS[params.get("map_aetr")]
        self.roll_ch = m[0]
        self.pitch_ch = m[1]
        self.yaw_ch = m[2]
        self.throttle_ch = m[3]
        self.deadband_us = params.get("deadband")
        self.yaw_deadband_us = params.get("yaw_deadband")
        self.min_check_us = params.get("min_check")
        self.angle_limit_rad = params.get("angle_limit") * _DEG
        self._arm = (params.get("arm_ch"), params.get("arm_min_us"), params.get("arm_max_us"))
        self._angle = (params.get("angle_ch"), params.get("angle_min_us"), params.get("angle_max_us"))
        self._horizon = (params.get("horizon_ch"), params.get("horizon_min_us"), params.get("horizon_max_us"))
        self._airmode = (params.get("airmode_ch"), params.get("airmode_min_us"), params.get("airmode_max_us"))
        self.airmode_box = self._airmode[0] > 0
        self._fs_switch = (params.get("fs_switch_ch"), params.get("fs_switch_min_us"), params.get("fs_switch_max_us"))
        self._forget()

    def _forget(self):
        """Drop update()'s reused results (the filters, curves or angle limit changed)."""
        for i in range(4):
            self._still[i] = False

    def set_arm_range(self, ch, min_us, max_us):
        """Arm when channel `ch` (1-based, 0 = never) reads min_us <= µs < max_us. configure()
        sets it from arm_ch/arm_min_us/arm_max_us; an arm source with its own rule (seed 001:
        above 1500 µs) sets it after that."""
        self._arm = (ch, min_us, max_us)

    def fs_switch_in(self, channels_us):
        """True when the failsafe switch (fs_switch_ch, 0 = none) is in range in this raw frame."""
        f = self._fs_switch
        return _in_range(channels_us, f[0], f[1], f[2])

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

    def new_frame(self, channels_us):
        """Take one receiver frame (µs per channel)."""
        self.stick_raw[0] = self._stick(channels_us[self.roll_ch], self.deadband_us)
        # Pitch stick forward (more µs) means nose down: negative pitch in FRD.
        self.stick_raw[1] = -self._stick(channels_us[self.pitch_ch], self.deadband_us)
        self.stick_raw[2] = self._stick(channels_us[self.yaw_ch], self.yaw_deadband_us)
        t = channels_us[self.throttle_ch]
        self.throttle_us = t
        b = self._thr_bands
        if b is not None:
            # Seed 001: the stick's third (1000-1332, 1333-1665, 1666-2000 µs) picks a stored value.
            t = b[0] if t < 1333 else (b[1] if t < 1666 else b[2])
        thr = (t - 1000) * 0.001
        self.throttle_raw = 0.0 if thr < 0.0 else (1.0 if thr > 1.0 else thr)
        # The mode ranges: _in_range() inline (four calls a frame otherwise).
        n = len(channels_us)
        ch, lo, hi = self._arm
        self.arm_switch = 0 < ch <= n and lo <= channels_us[ch - 1] < hi
        ch, lo, hi = self._horizon
        if 0 < ch <= n and lo <= channels_us[ch - 1] < hi:
            self.mode = MODE_HORIZON
        else:
            ch, lo, hi = self._angle
            self.mode = MODE_ANGLE if 0 < ch <= n and lo <= channels_us[ch - 1] < hi else MODE_ACRO
        ch, lo, hi = self._airmode
        self.airmode_switch = 0 < ch <= n and lo <= channels_us[ch - 1] < hi
        self.frames += 1

    def throttle_low(self):
        return self.throttle_us < self.min_check_us

    def reset_smoothing(self):
        for axis in range(3):
            self.filters[axis].reset(self.stick_raw[axis])
        self.filters[3].reset(self.throttle_raw)
        self._forget()

    def update(self, sp):
        """Smooth the latest frame into the setpoint (every pass)."""
        f = self.filters
        if self._smooth_type != "pt2":
            s = sp.stick_norm
            s[0] = f[0].update(self.stick_raw[0])
            s[1] = f[1].update(self.stick_raw[1])
            s[2] = f[2].update(self.stick_raw[2])
            sp.throttle_norm = f[3].update(self.throttle_raw)
            self.fill_setpoint(sp)
            return
        # PT2 (the default): Pt2.update's arithmetic inline on the same filter objects, and a filter
        # that sits still on an unchanged input is not run at all: sticks at rest cost no floats
        # (each float result is a heap object on MicroPython). See __init__ for the bookkeeping.
        still = self._still
        held = self._held
        out = self._out
        s = sp.stick_norm
        r = sp.rate_rad_s
        raw = self.stick_raw
        for i in range(4):  # roll, pitch, yaw, throttle
            x = raw[i] if i < 3 else self.throttle_raw
            moved = not (still[i] and x == held[i])
            if moved:
                flt = f[i]
                k = flt.k
                s1 = flt.s1
                y = flt.y
                s1_new = s1 + k * (x - s1)
                y_new = y + k * (s1_new - y)
                flt.s1 = s1_new
                flt.y = y_new
                still[i] = s1_new == s1 and y_new == y
                held[i] = x
                out[i] = y_new
            if i == 3:
                sp.throttle_norm = out[3]
            else:
                s[i] = out[i]
                if moved:
                    v = s[i]  # the stored (float32) value, as fill_setpoint reads it
                    self._rate_rad_s[i] = self.rates[i].rate_rad_s(v)
                    if i < 2:
                        self._angle_rad[i] = v * self.angle_limit_rad
                r[i] = self._rate_rad_s[i]
        sp.roll_angle_rad = self._angle_rad[0]
        sp.pitch_angle_rad = self._angle_rad[1]

    def fill_setpoint(self, sp):
        s = sp.stick_norm
        r = sp.rate_rad_s
        rates = self.rates
        r[0] = rates[0].rate_rad_s(s[0])
        r[1] = rates[1].rate_rad_s(s[1])
        r[2] = rates[2].rate_rad_s(s[2])
        sp.roll_angle_rad = s[0] * self.angle_limit_rad
        sp.pitch_angle_rad = s[1] * self.angle_limit_rad
