"""Rate PID for one axis, Betaflight-shaped: P on error, I with limit and anti-windup,
D on measurement through a low-pass, D-min, feed-forward on the setpoint's change, static
feed-forward (the PIFF of seed 002), TPA, and the anti-gravity boost the controller hands it.

D-min (Betaflight 4.x): D rests at d_min (`d_min_roll`...) and rises towards D max (`d_roll`...) while
the gyro moves fast (propwash, a hit) or the stick does (`d_min_advance` of that, so the damping is
there before the overshoot): little D, little motor noise, in a hover; full damping in a flip.
The boost is Betaflight's: |gyro acceleration| through a PT2 at 85 Hz, or |setpoint acceleration|,
times d_min_gain * 0.00008 / 35 (per deg/s²), smoothed by a PT2 at 35 Hz, capped at D max.

Gains are given in Betaflight's units and converted once in configure(): P, I, D
and F scale factors are Betaflight's (PTERM_SCALE 0.032029, ITERM_SCALE 0.244381,
DTERM_SCALE 0.000529, FEEDFORWARD_SCALE 0.013754 / 100) against an error in deg/s,
giving a PID sum in units of 1/1000 of the mixer range. Here the error is in rad/s and
the output is the mixer's normalised torque (1.0 = full range), so each scale is
multiplied by (180/pi)/1000.
"""

import math
from array import array

from hoverfly.core.stages.filters import LowPass, Pt1, Pt2

_RAD_TO_DEG = 180.0 / math.pi
_P_SCALE = 0.032029 * _RAD_TO_DEG * 1e-3
_I_SCALE = 0.244381 * _RAD_TO_DEG * 1e-3
_D_SCALE = 0.000529 * _RAD_TO_DEG * 1e-3
_F_SCALE = 0.013754 * 0.01 * _RAD_TO_DEG * 1e-3
# I-term relax: no integration while the setpoint moves faster than this (Betaflight's 30 deg/s threshold).
RELAX_THRESHOLD_RAD_S = 30.0 / _RAD_TO_DEG
# D-min (Betaflight's pid_init): the boost's input filter, its smoothing, and its gain per deg/s²
DMIN_RANGE_HZ = 85.0
DMIN_LOWPASS_HZ = 35.0
DMIN_GAIN_PER_DPS2 = 0.00008 / DMIN_LOWPASS_HZ
# The boost before its smoothing is capped at 2x: past 1 it only holds D max a little longer, and the
# fixed-point pass keeps it within its bits.
DMIN_BOOST_MAX = 2.0
# Anti-gravity boosts are capped at 31x (the fixed-point pass's Q10 factor below 2**15)
AG_BOOST_MAX = 31.0


class AxisPid:
    """One axis. The terms of the last pass go into `terms` (p[3], i[3], d[3], f[3] of the three
    axes, this one at index `k`: the controller's shared array, which the flight log records whole);
    `p`, `i`, `d`, `f` read them back."""

    def __init__(self, terms=None, k=0):
        self.terms = terms if terms is not None else array("f", [0.0] * 12)
        self.k = k
        self.kp = 0.0
        self.ki = 0.0
        self.kd = 0.0
        self.kf = 0.0
        self.k_static = 0.0
        self.i_limit = 0.4
        self.sum_limit = 0.5
        self.dterm_filter = LowPass()
        self.tpa_on_p = False
        self.relax = True
        self.relax_filter = Pt1()
        # D-min: off (D = d_<axis> always) unless 0 < d_min < d max
        self.dmin_on = False
        self.dmin_pct = 1.0
        self.dmin_gyro_gain = 0.0
        self.dmin_sp_gain = 0.0
        self.dmin_range = Pt2()
        self.dmin_lowpass = Pt2()
        self.dmin_factor = 1.0  # the last pass's D factor (d_min/d_max .. 1)
        # anti-gravity, set by the controller each pass while it is on: I and P multiplied by these
        self.i_boost = 1.0
        self.p_boost = 1.0
        # state and the terms of the last pass (read by telemetry and logs)
        self.i = 0.0  # the integrator's state
        self.error_rad_s = 0.0
        self.out = 0.0
        self._last_gyro = 0.0
        self._last_setpoint = 0.0
        self._prepare()

    def configure(self, params, axis, loop_hz, sum_limit_name):
        self.kp = params.get("p_" + axis) * _P_SCALE
        self.ki = params.get("i_" + axis) * _I_SCALE
        d_max = params.get("d_" + axis)
        d_min = params.get("d_min_" + axis)
        self.kd = d_max * _D_SCALE
        self.dmin_on = 0 < d_min < d_max
        self.dmin_pct = d_min / d_max if self.dmin_on else 1.0
        gain = params.get("d_min_gain") * DMIN_GAIN_PER_DPS2 * _RAD_TO_DEG  # per rad/s²
        self.dmin_gyro_gain = gain
        self.dmin_sp_gain = gain * params.get("d_min_advance") * 0.01
        self.dmin_range.configure(DMIN_RANGE_HZ, loop_hz)
        self.dmin_lowpass.configure(DMIN_LOWPASS_HZ, loop_hz)
        self.kf = params.get("f_" + axis) * _F_SCALE
        self.k_static = params.get("ff_static_pct") * 0.01 * self.kp
        self.i_limit = params.get("iterm_limit") * 1e-3
        self.sum_limit = params.get(sum_limit_name) * 1e-3
        self.tpa_on_p = params.get("tpa_mode") == "pd"
        self.dterm_filter.configure(params.get("dterm_lpf1_type"), params.get("dterm_lpf1_hz"), loop_hz)
        relax = params.get("iterm_relax")
        self.relax = relax == "rpy" or (relax == "rp" and axis != "yaw")
        self.relax_filter.configure(params.get("iterm_relax_hz"), loop_hz)
        self._prepare()

    def _prepare(self):
        # Pass-invariant products and the filter's bound update, worked out once: on MicroPython
        # every float result is a heap object and every attribute lookup a hash probe.
        self._neg_kd = -self.kd
        self._d_update = self.dterm_filter.update
        self._dt_s = 0.0
        self._inv_dt = 0.0

    def _dmin(self, gyro_accel, sp_accel):
        """D-min's factor for this pass (d_min/d_max .. 1) from the filtered gyro's and the setpoint's
        acceleration (rad/s²)."""
        g = self.dmin_range.update(gyro_accel)
        if g < 0:
            g = -g
        g *= self.dmin_gyro_gain
        a = sp_accel if sp_accel >= 0 else -sp_accel
        a *= self.dmin_sp_gain
        if a > g:
            g = a
        if g > DMIN_BOOST_MAX:
            g = DMIN_BOOST_MAX
        pct = self.dmin_pct
        f = self.dmin_lowpass.update(pct + (1.0 - pct) * g)
        if f > 1.0:
            f = 1.0
        self.dmin_factor = f
        return f

    def p(self):
        return self.terms[self.k]

    def d(self):
        return self.terms[self.k + 6]

    def f(self):
        return self.terms[self.k + 9]

    def reset(self):
        self.i = 0.0
        t = self.terms
        k = self.k
        t[k] = 0.0
        t[k + 3] = 0.0
        t[k + 6] = 0.0
        t[k + 9] = 0.0
        self.out = 0.0
        self.dterm_filter.reset(0.0)
        self.dmin_range.reset(0.0)
        self.dmin_lowpass.reset(0.0)
        self.dmin_factor = 1.0

    def update(self, setpoint_rad_s, gyro_rad_s, dt_s, tpa, i_active, saturated):
        """One pass; returns the normalised torque for this axis."""
        err = setpoint_rad_s - gyro_rad_s
        self.error_rad_s = err
        p = self.kp * err
        if self.tpa_on_p and tpa != 1.0:
            p *= tpa
        if self.p_boost != 1.0:
            p *= self.p_boost
        # Anti-windup: stop integrating toward the side the mixer can no longer deliver.
        if i_active:
            i = self.i
            step = self.ki * err * dt_s
            if self.relax:
                # I-term relax: while the stick moves, the error is the response still coming,
                # not a steady offset; integrating it now only comes back as overshoot.
                # (The relax Pt1 inlined: y += k * (x - y).)
                rf = self.relax_filter
                y = rf.y
                y = y + rf.k * (setpoint_rad_s - y)
                rf.y = y
                hp = setpoint_rad_s - y
                if hp < 0:
                    hp = -hp
                factor = 1.0 - hp / RELAX_THRESHOLD_RAD_S
                if factor <= 0.0:
                    step = 0.0
                elif factor != 1.0:
                    step *= factor
            if self.i_boost != 1.0:
                # anti-gravity: I catches up while the throttle moves fast (a step of over half the range
                # is a stall's, not a flight's: capped there first, as the fixed-point pass must)
                if step > 0.5:
                    step = 0.5
                elif step < -0.5:
                    step = -0.5
                step *= self.i_boost
            if not saturated or (step > 0) != (self.out > 0):
                i += step
            lim = self.i_limit
            if i > lim:
                i = lim
            elif i < -lim:
                i = -lim
            self.i = i
        else:
            i = 0.0
            self.i = i
        # 1/dt once per new dt (the loop's dt repeats pass after pass).
        if dt_s != self._dt_s:
            self._dt_s = dt_s
            self._inv_dt = 1.0 / dt_s
        inv_dt = self._inv_dt
        # D on measurement: a setpoint step kicks nothing, a gyro spike is damped.
        nkd = self._neg_kd
        if nkd != 0.0:
            if tpa != 1.0:
                nkd *= tpa
            dg = self._d_update((gyro_rad_s - self._last_gyro) * inv_dt)
            if self.dmin_on:
                nkd *= self._dmin(dg, (setpoint_rad_s - self._last_setpoint) * inv_dt)
            d = nkd * dg
        else:  # no D gain: keep the filter running so a live D change starts from its state
            self._d_update((gyro_rad_s - self._last_gyro) * inv_dt)
            d = 0.0
        self._last_gyro = gyro_rad_s
        f = self.kf * (setpoint_rad_s - self._last_setpoint) * inv_dt
        if self.k_static != 0.0:
            f += self.k_static * setpoint_rad_s
        self._last_setpoint = setpoint_rad_s
        t = self.terms
        k = self.k
        t[k] = p
        t[k + 3] = i
        t[k + 6] = d
        t[k + 9] = f
        out = p + i + d + f
        lim = self.sum_limit
        if out > lim:
            out = lim
        elif out < -lim:
            out = -lim
        self.out = out
        return out
