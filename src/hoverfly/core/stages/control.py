"""The controller: angle loop (where the mode asks for it) and the three rate PIDs.

Takes the setpoint (mode, stick-derived rates and angles, throttle), the attitude and
the filtered gyro; gives the normalised torque per axis for the mixer. Angle mode is the
PIFF shape of seed 002: P on the angle error plus feed-forward of the angle setpoint's
speed gives a rate setpoint, which the rate PID (with its own feed-forward) follows.
Horizon blends angle and rate by stick deflection. Anti-gravity (Betaflight 4.3's): while the
throttle moves fast the thrust change tips the craft, so I (and P on roll and pitch) are boosted by
the throttle's speed, weighted to low throttle, smoothed by a PT2. Step 4 of the pass.
"""

import math
from array import array

from hoverfly.compat import const
from hoverfly.core.stages.filters import Pt2
from hoverfly.core.stages.pid import AG_BOOST_MAX, AxisPid

MODE_ACRO = const(0)
MODE_ANGLE = const(1)
MODE_HORIZON = const(2)
MODE_MANUAL = const(3)  # planes only: sticks to surfaces (core/stages/fwcontrol.py)
MODE_NAMES = ("acro", "angle", "horizon", "manual")

_DEG = math.pi / 180.0
AG_P_SHARE = 0.34  # Betaflight's ANTIGRAVITY_KP: P's boost per unit of I's, at ag_p_gain 100 %


class Controller:
    """`terms`: where the three axes put their P, I, D and F terms (p[3], i[3], d[3], f[3]; the
    flight passes the signals' array, which the log records whole)."""

    def __init__(self, terms=None):
        self.terms = terms if terms is not None else array("f", [0.0] * 12)
        self.roll = AxisPid(self.terms, 0)
        self.pitch = AxisPid(self.terms, 1)
        self.yaw = AxisPid(self.terms, 2)
        self.angle_gain = 5.0
        self.angle_ff = 0.5
        # The accelerometer trims (MSP_ACC_CALIBRATION on level ground stores the estimate's lean there):
        # angle and horizon level to the trimmed attitude, as Betaflight's pidLevel subtracts its angle trim.
        self.trim_roll_rad = 0.0
        self.trim_pitch_rad = 0.0
        self.angle_rate_limit = 500.0 * _DEG
        self.horizon_strength = 0.5
        self.tpa_rate = 0.65
        self.tpa_breakpoint = 0.35
        self._last_roll_sp = 0.0
        self._last_pitch_sp = 0.0
        self.tpa = 1.0
        self._dt_s = 0.0
        self._inv_dt = 0.0
        self.ag_gain = 0.0  # 0: anti-gravity off
        self.ag_p_share = 0.0
        self.ag_filter = Pt2()
        self.ag_boost = 0.0  # the last pass's boost (I is multiplied by 1 + this)
        self._ag_last_thr = 0.0

    def configure(self, params, loop_hz):
        self.roll.configure(params, "roll", loop_hz, "pidsum_limit")
        self.pitch.configure(params, "pitch", loop_hz, "pidsum_limit")
        self.yaw.configure(params, "yaw", loop_hz, "pidsum_limit_yaw")
        self.angle_gain = params.get("angle_p_gain") * 0.1
        self.angle_ff = params.get("angle_ff") * 0.01
        self.trim_roll_rad = params.get("acc_trim_roll") * _DEG
        self.trim_pitch_rad = params.get("acc_trim_pitch") * _DEG
        self.angle_rate_limit = params.get("angle_rate_limit") * _DEG
        self.horizon_strength = params.get("horizon_level") * 0.01
        self.tpa_rate = params.get("tpa_rate") * 0.01
        self.tpa_breakpoint = (params.get("tpa_breakpoint") - 1000) * 0.001
        self.ag_gain = params.get("ag_gain") * 0.1
        self.ag_p_share = AG_P_SHARE * params.get("ag_p_gain") * 0.01
        self.ag_filter.configure(params.get("ag_cutoff_hz"), loop_hz)
        if self.ag_gain == 0.0:
            self._anti_gravity_off()

    def _anti_gravity_off(self):
        self.ag_boost = 0.0
        for pid in (self.roll, self.pitch, self.yaw):
            pid.i_boost = 1.0
            pid.p_boost = 1.0

    def reset(self):
        self.roll.reset()
        self.pitch.reset()
        self.yaw.reset()
        self.ag_filter.reset(0.0)
        self._anti_gravity_off()

    def _level_rate(self, angle_sp_rad, angle_rad, last_sp, inv_dt):
        rate = (angle_sp_rad - angle_rad) * self.angle_gain + (angle_sp_rad - last_sp) * inv_dt * self.angle_ff
        lim = self.angle_rate_limit
        if rate > lim:
            return lim
        if rate < -lim:
            return -lim
        return rate

    def _anti_gravity(self, thr, dt_s, i_active):
        """The boost from the throttle's speed (Betaflight 4.3's pidUpdateAntiGravityThrottleFilter)."""
        if thr < 0.0:
            thr = 0.0
        elif thr > 1.0:
            thr = 1.0
        if not i_active:
            # No I to boost, and the throttle's jump to take-off is no punch: the boost starts from rest
            # where I starts (airmode_thr_pct), else it winds I up on the ground and tips the lift-off.
            self._ag_last_thr = thr
            self.ag_filter.reset(0.0)
            self._anti_gravity_off()
            return
        if dt_s != self._dt_s:
            self._dt_s = dt_s
            self._inv_dt = 1.0 / dt_s
        d = thr - self._ag_last_thr
        self._ag_last_thr = thr
        inv = 1.0 - thr
        x = (d if d >= 0.0 else -d) * self._inv_dt * inv * inv
        if d > 0.0:  # rising: the low-throttle end matters most (a punch out of a dive)
            x *= inv * 0.5
        b = self.ag_filter.update(x) * self.ag_gain
        if b > AG_BOOST_MAX:
            b = AG_BOOST_MAX
        self.ag_boost = b
        ib = 1.0 + b
        pb = 1.0 + b * self.ag_p_share
        self.roll.i_boost = ib
        self.pitch.i_boost = ib
        self.yaw.i_boost = ib
        self.roll.p_boost = pb
        self.pitch.p_boost = pb

    def update(self, sp, attitude, gyro_rad_s, dt_s, i_active, saturated, torque_norm):
        """Fill torque_norm[0..2] (roll, pitch, yaw) and sp.rate_rad_s[0..2] (the rate setpoint used)."""
        rate = sp.rate_rad_s
        mode = sp.mode
        roll_sp = sp.roll_angle_rad
        pitch_sp = sp.pitch_angle_rad
        if mode != MODE_ACRO:
            # 1/dt once per new dt (the loop's dt repeats pass after pass).
            if dt_s != self._dt_s:
                self._dt_s = dt_s
                self._inv_dt = 1.0 / dt_s
            inv_dt = self._inv_dt
            level_roll = self._level_rate(roll_sp, attitude.roll_rad - self.trim_roll_rad, self._last_roll_sp, inv_dt)
            level_pitch = self._level_rate(pitch_sp, attitude.pitch_rad - self.trim_pitch_rad, self._last_pitch_sp,
                                           inv_dt)
            if mode == MODE_ANGLE:
                rate[0] = level_roll
                rate[1] = level_pitch
            else:
                # Horizon: full levelling at centre stick fading to pure rate at full deflection.
                s = sp.stick_norm
                defl = s[0]
                if defl < 0:
                    defl = -defl
                d2 = s[1]
                if d2 < 0:
                    d2 = -d2
                if d2 > defl:
                    defl = d2
                w = self.horizon_strength * (1.0 - defl)
                rate[0] = rate[0] * (1.0 - w) + level_roll * w
                rate[1] = rate[1] * (1.0 - w) + level_pitch * w
        self._last_roll_sp = roll_sp
        self._last_pitch_sp = pitch_sp
        # TPA: cut gain above the breakpoint, linearly to tpa_rate at full throttle.
        thr = sp.throttle_norm
        tpa = 1.0
        bp = self.tpa_breakpoint
        if thr > bp and bp < 1.0:
            tpa = 1.0 - self.tpa_rate * (thr - bp) / (1.0 - bp)
        self.tpa = tpa
        if self.ag_gain != 0.0:
            self._anti_gravity(thr, dt_s, i_active)
        torque_norm[0] = self.roll.update(rate[0], gyro_rad_s[0], dt_s, tpa, i_active, saturated)
        torque_norm[1] = self.pitch.update(rate[1], gyro_rad_s[1], dt_s, tpa, i_active, saturated)
        torque_norm[2] = self.yaw.update(rate[2], gyro_rad_s[2], dt_s, 1.0, i_active, saturated)
