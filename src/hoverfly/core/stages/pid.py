"""Rate PID for one axis, Betaflight-shaped: P on error, I with limit and anti-windup,
D on measurement through a low-pass, feed-forward on the setpoint's change, static
feed-forward (the PIFF of seed 002) and TPA.

Gains are given in Betaflight's units and converted once in configure(): P, I, D
and F scale factors are Betaflight's (PTERM_SCALE 0.032029, ITERM_SCALE 0.244381,
DTERM_SCALE 0.000529, FEEDFORWARD_SCALE 0.013754 / 100) against an error in deg/s,
giving a PID sum in units of 1/1000 of the mixer range. Here the error is in rad/s and
the output is the mixer's normalised torque (1.0 = full range), so each scale is
multiplied by (180/pi)/1000.
"""

import math
from array import array

from hoverfly.core.stages.filters import LowPass, Pt1

_RAD_TO_DEG = 180.0 / math.pi
_P_SCALE = 0.032029 * _RAD_TO_DEG * 1e-3
_I_SCALE = 0.244381 * _RAD_TO_DEG * 1e-3
_D_SCALE = 0.000529 * _RAD_TO_DEG * 1e-3
_F_SCALE = 0.013754 * 0.01 * _RAD_TO_DEG * 1e-3
# I-term relax: no integration while the setpoint moves faster than this (Betaflight's 30 deg/s threshold).
RELAX_THRESHOLD_RAD_S = 30.0 / _RAD_TO_DEG


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
        self.kd = params.get("d_" + axis) * _D_SCALE
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

    def update(self, setpoint_rad_s, gyro_rad_s, dt_s, tpa, i_active, saturated):
        """One pass; returns the normalised torque for this axis."""
        err = setpoint_rad_s - gyro_rad_s
        self.error_rad_s = err
        p = self.kp * err
        if self.tpa_on_p and tpa != 1.0:
            p *= tpa
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
            d = nkd * self._d_update((gyro_rad_s - self._last_gyro) * inv_dt)
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
