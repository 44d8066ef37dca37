"""The controller: angle loop (where the mode asks for it) and the three rate PIDs.

Takes the setpoint (mode, stick-derived rates and angles, throttle), the attitude and
the filtered gyro; gives the normalised torque per axis for the mixer. Angle mode is the
PIFF shape of seed 002: P on the angle error plus feed-forward of the angle setpoint's
speed gives a rate setpoint, which the rate PID (with its own feed-forward) follows.
Horizon blends angle and rate by stick deflection. Step 4 of the pass.
"""

import math
from array import array

from hoverfly.compat import const
from hoverfly.core.stages.pid import AxisPid

MODE_ACRO = const(0)
MODE_ANGLE = const(1)
MODE_HORIZON = const(2)
MODE_MANUAL = const(3)  # planes only: sticks to surfaces (core/stages/fwcontrol.py)
MODE_NAMES = ("acro", "angle", "horizon", "manual")

_DEG = math.pi / 180.0


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
        self.angle_rate_limit = 500.0 * _DEG
        self.horizon_strength = 0.5
        self.tpa_rate = 0.65
        self.tpa_breakpoint = 0.35
        self._last_roll_sp = 0.0
        self._last_pitch_sp = 0.0
        self.tpa = 1.0
        self._dt_s = 0.0
        self._inv_dt = 0.0

    def configure(self, params, loop_hz):
        self.roll.configure(params, "roll", loop_hz, "pidsum_limit")
        self.pitch.configure(params, "pitch", loop_hz, "pidsum_limit")
        self.yaw.configure(params, "yaw", loop_hz, "pidsum_limit_yaw")
        self.angle_gain = params.get("angle_p_gain") * 0.1
        self.angle_ff = params.get("angle_ff") * 0.01
        self.angle_rate_limit = params.get("angle_rate_limit") * _DEG
        self.horizon_strength = params.get("horizon_level") * 0.01
        self.tpa_rate = params.get("tpa_rate") * 0.01
        self.tpa_breakpoint = (params.get("tpa_breakpoint") - 1000) * 0.001

    def reset(self):
        self.roll.reset()
        self.pitch.reset()
        self.yaw.reset()

    def _level_rate(self, angle_sp_rad, angle_rad, last_sp, inv_dt):
        rate = (angle_sp_rad - angle_rad) * self.angle_gain + (angle_sp_rad - last_sp) * inv_dt * self.angle_ff
        lim = self.angle_rate_limit
        if rate > lim:
            return lim
        if rate < -lim:
            return -lim
        return rate

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
            level_roll = self._level_rate(roll_sp, attitude.roll_rad, self._last_roll_sp, inv_dt)
            level_pitch = self._level_rate(pitch_sp, attitude.pitch_rad, self._last_pitch_sp, inv_dt)
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
        torque_norm[0] = self.roll.update(rate[0], gyro_rad_s[0], dt_s, tpa, i_active, saturated)
        torque_norm[1] = self.pitch.update(rate[1], gyro_rad_s[1], dt_s, tpa, i_active, saturated)
        torque_norm[2] = self.yaw.update(rate[2], gyro_rad_s[2], dt_s, 1.0, i_active, saturated)
