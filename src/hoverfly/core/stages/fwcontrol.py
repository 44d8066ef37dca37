"""The fixed-wing controller: MANUAL, ANGLE (seed 002's PIFF), HORIZON and ACRO for a plane.

Takes the set point (mode, smoothed sticks, throttle), the attitude and the filtered gyro; gives the
stabilised roll, pitch and yaw commands in -1..1 (+ = roll right, nose up, nose right) in the same
`torque_norm` array the quad controller fills, for the servo mixer. Step 4 of the pass when the
airframe is a plane (`is_plane(mixer_type)`); the quad's Controller is not run then.

The law is INAV's fixed-wing PIFF, so an INAV tune carries over:
- ANGLE: the angle error times `fw_p_level` is the rate set point (INAV's level P: deg/s per deg over
  6.56), limited to the axis's rate (`fw_roll_dps` ...). The angle set point is the stick times the bank
  or pitch limit (`fw_max_bank_deg`, `fw_max_pitch_deg`: INAV's max_angle_inclination_rll/pit), plus
  `pitch_offset_rad`, which the commander sets while the failsafe glides or a hand launch climbs.
- Per axis: feed-forward of the rate set point (`fw_ff_*`, most of the deflection for a commanded rate),
  P and I on the rate error (`fw_p_*`, `fw_i_*`). INAV's scales: PID units of 500 = full throw, P and FF
  per deg/s over 31, I per deg over 4. The I-term is held within `fw_iterm_limit` (INAV's
  fw_iterm_throw_limit, a third of the throw by default: a plane on the ground or in the hand cannot
  wind it into a full deflection at the throw) and is zero whenever `i_active` is false: disarmed
  (seed 002: "the integrator resets when the plane is disarmed"), before the launch's motor start, and
  in MANUAL.
- Turn coordination in ANGLE and HORIZON (INAV's turn assist): the yaw and pitch body rates of a
  coordinated turn at the bank flown, g/V sin(phi) cos(theta) and g/V sin(phi) tan(phi) cos(theta),
  from the attitude quaternion, at the reference airspeed `fw_ref_speed_m_s` (no pitot needed), scaled
  by `fw_turn_yaw_gain` and `fw_turn_pit_gain`. The rudder then follows the turn instead of fighting
  it, and the elevator holds the nose up in a bank.
- TPA on throttle, INAV's fixed-wing form (throttle as an airspeed proxy): factor = 0.5 + bp / thr / 2
  held to 0.3..2 (1 at the breakpoint `fw_tpa_bp_us`, more below it, less above), blended by
  `fw_tpa_rate` %, on roll and pitch P, I and FF.
- MANUAL: the sticks straight to the surfaces through an expo curve (`manual_rc_expo`: x (1 - e + e x^2),
  as INAV's rc expo) and a rate % per axis (`manual_roll_pct` ...: INAV's manual_roll_rate).
- ACRO: the stick times the axis's rate is the rate set point; HORIZON blends ACRO and ANGLE by stick
  deflection (`horizon_level` at centre stick) as the quad controller does.
"""

import math
from array import array

from hoverfly.compat import const
from hoverfly.core.stages.control import MODE_ACRO, MODE_ANGLE, MODE_MANUAL

_DEG = math.pi / 180.0
_G_M_S2 = 9.80665
# INAV's fixed-wing scales (src/main/flight/pid.c): P and FF per deg/s / 31, I / 4, level P / 6.56;
# their PID sum is in units where 500 is full throw.
_P_DIV = 31.0
_I_DIV = 4.0
_FF_DIV = 31.0
_LEVEL_DIV = 6.56
_THROW = 500.0
# Turn coordination: no more bank than this counts (tan grows without bound), and cos(bank) cos(pitch)
# below _TC_COS_MIN (past 60 degrees) is held there.
_TC_COS_MIN = 0.5
# TPA's factor stays within INAV's 0.3..2.
_TPA_MIN = 0.3
_TPA_MAX = 2.0

# The axes' gains in `k` (array "f"): per axis P, I, FF (per rad/s of rate, as a share of full throw)
K_P = const(0)
K_I = const(1)
K_FF = const(2)
K_AXIS = const(3)  # roll at 0, pitch at 3, yaw at 6


def manual_curve(stick, expo):
    """INAV's rc expo on a stick in -1..1: x (1 - e + e x^2)."""
    return stick * (1.0 - expo + expo * stick * stick)


def tpa_factor(throttle_norm, breakpoint_norm, rate):
    """INAV's fixed-wing TPA: 0.5 + bp / thr / 2 within 0.3..2 (2 at zero throttle), blended by rate (0..1)."""
    if throttle_norm > 0.0:
        f = 0.5 + breakpoint_norm / throttle_norm * 0.5
        if f < _TPA_MIN:
            f = _TPA_MIN
        elif f > _TPA_MAX:
            f = _TPA_MAX
    else:
        f = _TPA_MAX
    return 1.0 + (f - 1.0) * rate


class FwController:
    """`terms`: where the three axes put their P, I, D and F terms (p[3], i[3], d[3], f[3], as the quad
    controller: the flight passes the signals' array, which the log records whole)."""

    def __init__(self, terms=None):
        self.terms = terms if terms is not None else array("f", [0.0] * 12)
        self.k = array("f", [0.0] * 9)
        self.i = array("f", [0.0, 0.0, 0.0])  # the integrators, as a share of full throw
        self.rate_max_rad_s = array("f", [180.0 * _DEG, 90.0 * _DEG, 60.0 * _DEG])
        self.manual = array("f", [1.0, 1.0, 1.0])
        self.expo = 0.7
        self.level_gain = 20.0 / _LEVEL_DIV
        self.bank_max_rad = 45.0 * _DEG
        self.pitch_max_rad = 20.0 * _DEG
        self.i_limit = 165.0 / _THROW
        self.turn_yaw = 1.0
        self.turn_pitch = 1.0
        self.g_per_v = _G_M_S2 / 15.0
        self.tpa_bp = 0.5
        self.tpa_rate = 0.0
        self.horizon_strength = 0.5
        self.pitch_offset_rad = 0.0  # the commander's pitch target in ANGLE (failsafe glide, launch climb)
        self.tpa = 1.0
        self._last_thr = -1.0

    def configure(self, params):
        k = self.k
        # per rad/s of rate, as a share of full throw: INAV's gain / its divisor, deg/s, / 500
        s = 1.0 / (_DEG * _THROW)
        for a, axis in enumerate(("roll", "pitch", "yaw")):
            k[a * K_AXIS + K_P] = params.get("fw_p_" + axis) / _P_DIV * s
            k[a * K_AXIS + K_I] = params.get("fw_i_" + axis) / _I_DIV * s
            k[a * K_AXIS + K_FF] = params.get("fw_ff_" + axis) / _FF_DIV * s
            self.rate_max_rad_s[a] = params.get("fw_" + axis + "_dps") * _DEG
            self.manual[a] = params.get("manual_" + axis + "_pct") * 0.01
        self.expo = params.get("manual_rc_expo") * 0.01
        self.level_gain = params.get("fw_p_level") / _LEVEL_DIV
        self.bank_max_rad = params.get("fw_max_bank_deg") * _DEG
        self.pitch_max_rad = params.get("fw_max_pitch_deg") * _DEG
        self.i_limit = params.get("fw_iterm_limit") / _THROW
        self.turn_yaw = params.get("fw_turn_yaw_gain")
        self.turn_pitch = params.get("fw_turn_pit_gain")
        self.g_per_v = _G_M_S2 / params.get("fw_ref_speed_m_s")
        self.tpa_bp = (params.get("fw_tpa_bp_us") - 1000) * 0.001
        self.tpa_rate = params.get("fw_tpa_rate") * 0.01
        self.horizon_strength = params.get("horizon_level") * 0.01
        self._last_thr = -1.0

    def reset(self):
        i = self.i
        i[0] = i[1] = i[2] = 0.0

    # ------------------------------------------------------------------ the pass
    def update(self, sp, attitude, gyro_rad_s, dt_s, i_active, torque_norm):
        """Fill torque_norm[0..2] and sp.rate_rad_s[0..2] (the rate set point flown; MANUAL leaves it)."""
        mode = sp.mode
        if mode == MODE_MANUAL:
            self._manual(sp.stick_norm, torque_norm)
            return
        rate = sp.rate_rad_s
        s = sp.stick_norm
        rm = self.rate_max_rad_s
        rate[0] = s[0] * rm[0]
        rate[1] = s[1] * rm[1]
        rate[2] = s[2] * rm[2]
        if mode != MODE_ACRO:
            self._level(sp, attitude, rate)
        thr = sp.throttle_norm
        if thr != self._last_thr:  # the throttle stands still for most passes
            self._last_thr = thr
            self.tpa = tpa_factor(thr, self.tpa_bp, self.tpa_rate)
        tpa = self.tpa
        torque_norm[0] = self._axis(0, rate[0], gyro_rad_s[0], dt_s, tpa, i_active)
        torque_norm[1] = self._axis(1, rate[1], gyro_rad_s[1], dt_s, tpa, i_active)
        torque_norm[2] = self._axis(2, rate[2], gyro_rad_s[2], dt_s, 1.0, i_active)

    def _manual(self, s, torque_norm):
        """MANUAL: sticks through the expo curve and the manual rates; no integrator."""
        e = self.expo
        m = self.manual
        torque_norm[0] = manual_curve(s[0], e) * m[0]
        torque_norm[1] = manual_curve(s[1], e) * m[1]
        torque_norm[2] = manual_curve(s[2], e) * m[2]
        self.reset()
        t = self.terms
        for j in range(12):
            t[j] = 0.0

    def _level(self, sp, attitude, rate):
        """ANGLE (and HORIZON's levelling): the rate set points from the angle errors, and the turn's."""
        s = sp.stick_norm
        rm = self.rate_max_rad_s
        lr = (s[0] * self.bank_max_rad - attitude.roll_rad) * self.level_gain
        lp = (s[1] * self.pitch_max_rad + self.pitch_offset_rad - attitude.pitch_rad) * self.level_gain
        if sp.mode == MODE_ANGLE:
            rate[0] = lr
            rate[1] = lp
        else:  # horizon: full levelling at centre stick fading to pure rate at full deflection
            d = s[0] if s[0] >= 0.0 else -s[0]
            d1 = s[1] if s[1] >= 0.0 else -s[1]
            if d1 > d:
                d = d1
            w = self.horizon_strength * (1.0 - d)
            rate[0] += (lr - rate[0]) * w
            rate[1] += (lp - rate[1]) * w
        rate[0] = _clamp(rate[0], rm[0])
        rate[1] = _clamp(rate[1], rm[1])
        self._turn(attitude.q, rate)

    def _turn(self, q, rate):
        """Turn coordination: add the body rates of a coordinated turn at the bank flown."""
        w = q[0]
        x = q[1]
        y = q[2]
        z = q[3]
        sc = 2.0 * (w * x + y * z)  # sin(bank) cos(pitch)
        cc = 1.0 - 2.0 * (x * x + y * y)  # cos(bank) cos(pitch)
        if cc < _TC_COS_MIN:
            cc = _TC_COS_MIN
        k = self.g_per_v
        rate[2] = _clamp(rate[2] + k * sc * self.turn_yaw, self.rate_max_rad_s[2])
        rate[1] = _clamp(rate[1] + k * sc * sc / cc * self.turn_pitch, self.rate_max_rad_s[1])

    def _axis(self, a, sp_rad_s, gyro_rad_s, dt_s, tpa, i_active):
        """PIFF on one axis: FF on the rate set point, P and I on the rate error; returns -1..1."""
        k = self.k
        b = a * K_AXIS
        err = sp_rad_s - gyro_rad_s
        p = k[b + K_P] * tpa * err
        f = k[b + K_FF] * tpa * sp_rad_s
        ii = self.i
        if i_active:
            lim = self.i_limit
            i = _clamp(ii[a] + k[b + K_I] * tpa * err * dt_s, lim)
        else:
            i = 0.0
        ii[a] = i
        t = self.terms
        t[a] = p
        t[a + 3] = i
        t[a + 6] = 0.0
        t[a + 9] = f
        return _clamp(p + i + f, 1.0)


def _clamp(v, lim):
    if v > lim:
        return lim
    if v < -lim:
        return -lim
    return v
