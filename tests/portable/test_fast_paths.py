"""The hot pass's fast paths equal the plain formulas they replace.

The speed work (filters, estimator, PID, controller, mixer, rates) saves calls, lookups and
float boxing on MicroPython but must not move a number: each stage here is driven with the
same varied inputs as a reference written the plain way (the shapes the stages had before),
and the outputs must match exactly (same operations in the same order; array('f') where the
stage stores float32). Portable: runs under pytest and tests/portable/mprun.py.
"""

import math
from array import array

from fastpathkit import Rand as _Rand
from fastpathkit import params as _params

from hoverfly.core.signals import Setpoint
from hoverfly.core.stages.control import MODE_ACRO, MODE_ANGLE, MODE_HORIZON, Controller
from hoverfly.core.stages.estimator import Attitude, Mahony
from hoverfly.core.stages.filters import AccelFilter, Biquad, GyroFilter, LowPass, Pt1, Pt2
from hoverfly.core.stages.mixer import MIXER_TABLES, Mixer
from hoverfly.core.stages.pid import AxisPid
from hoverfly.core.stages.rates import ActualRates

_G = 9.80665


def test_gyro_filter_equals_the_per_axis_chain_for_every_filter_choice():
    for kw in ({}, {"gyro_lpf1_type": "pt2"}, {"gyro_lpf1_type": "biquad", "gyro_lpf1_hz": 120},
               {"gyro_lpf2_hz": 300}, {"gyro_notch1_hz": 200, "gyro_notch1_cut": 150, "gyro_lpf2_hz": 300},
               {"gyro_lpf1_hz": 0}):
        p = _params(**kw)
        gf = GyroFilter()
        gf.configure(p, 1000)
        lpf1 = [LowPass() for _ in range(3)]
        lpf2 = [Pt1() for _ in range(3)]
        notch = [Biquad() for _ in range(3)]
        for i in range(3):
            lpf1[i].configure(p.get("gyro_lpf1_type"), p.get("gyro_lpf1_hz"), 1000)
            lpf2[i].configure(p.get("gyro_lpf2_hz"), 1000)
            notch[i].configure_notch(p.get("gyro_notch1_hz"), p.get("gyro_notch1_cut"), 1000)
        lpf2_on = 0 < p.get("gyro_lpf2_hz") < 500
        notch_on = p.get("gyro_notch1_hz") > 0
        rnd = _Rand(3)
        raw = array("f", [0.0, 0.0, 0.0])
        bias = array("f", [0.01, -0.02, 0.005])
        out = array("f", [0.0, 0.0, 0.0])
        ref = array("f", [0.0, 0.0, 0.0])
        for k in range(300):
            for i in range(3):
                raw[i] = math.sin(k * (0.1 + i)) + 0.2 * rnd()
            gf.update(raw, bias, out)
            for i in range(3):
                y = lpf1[i].update(raw[i] - bias[i])
                if lpf2_on or notch_on:
                    y = lpf2[i].update(y)
                if notch_on:
                    y = notch[i].update(y)
                ref[i] = y
            assert list(out) == list(ref), (kw, k)


def test_accel_filter_equals_three_pt2_starting_level():
    p = _params(acc_lpf_hz=25)
    af = AccelFilter()
    af.configure(p, 1000)
    ref = [Pt2(25, 1000), Pt2(25, 1000), Pt2(25, 1000)]
    ref[2].reset(-_G)
    rnd = _Rand(5)
    raw = array("f", [0.0, 0.0, 0.0])
    out = array("f", [0.0, 0.0, 0.0])
    for _ in range(300):
        raw[0] = rnd() * 3.0
        raw[1] = rnd() * 3.0
        raw[2] = -_G + rnd() * 3.0
        af.update(raw, out)
        assert out[0] == array("f", [ref[0].update(raw[0])])[0]
        assert out[1] == array("f", [ref[1].update(raw[1])])[0]
        assert out[2] == array("f", [ref[2].update(raw[2])])[0]


def _rate_ref(r, stick):
    a = abs(stick)
    if a > 1.0:
        a = 1.0
    e = r.expo
    a2 = a * a
    curve = a * (a2 * a2 * a * e + a * (1.0 - e))
    v = a * r.centre_rad_s + curve * r.travel_rad_s
    return v if stick >= 0 else -v


def test_rates_curve_equals_the_general_formula_with_and_without_expo():
    rnd = _Rand(7)
    for expo in (0.0, 30.0, 100.0):
        r = ActualRates()
        r.configure(1.0, 67.0, expo)
        for _ in range(200):
            s = rnd() * 1.2
            assert r.rate_rad_s(s) == _rate_ref(r, s)


class _PidRef:
    """The rate PID written the plain way (the shape before the speed work)."""

    def __init__(self, pid):
        self.pid = pid  # gains and filters configured like the one under test, state of its own
        self.i = 0.0
        self.out = 0.0
        self.last_gyro = 0.0
        self.last_sp = 0.0
        self.relax_y = 0.0
        self.dterm = LowPass()

    def update(self, sp, gyro, dt_s, tpa, i_active, saturated):
        q = self.pid
        err = sp - gyro
        p = q.kp * err
        if q.tpa_on_p:
            p *= tpa
        i = self.i
        if i_active:
            step = q.ki * err * dt_s
            if q.relax:
                self.relax_y = self.relax_y + q.relax_filter.k * (sp - self.relax_y)
                hp = abs(sp - self.relax_y)
                factor = 1.0 - hp / (30.0 / (180.0 / math.pi))
                step *= factor if factor > 0.0 else 0.0
            if not saturated or (step > 0) != (self.out > 0):
                i += step
            i = max(-q.i_limit, min(q.i_limit, i))
        else:
            i = 0.0
        self.i = i
        inv_dt = 1.0 / dt_s
        d = -q.kd * tpa * self.dterm.update((gyro - self.last_gyro) * inv_dt)
        self.last_gyro = gyro
        f = q.kf * (sp - self.last_sp) * inv_dt + q.k_static * sp
        self.last_sp = sp
        out = max(-q.sum_limit, min(q.sum_limit, p + i + d + f))
        self.out = out
        return out, p, d, f


def _f32(x):
    return array("f", [x])[0]


def test_rate_pid_equals_the_plain_formula_for_every_option():
    variants = ({}, {"tpa_mode": "pd", "iterm_relax": "rpy", "ff_static_pct": 30.0, "dterm_lpf1_type": "biquad"},
                {"iterm_relax": "off", "dterm_lpf1_type": "pt2", "d_yaw": 0}, {"d_roll": 0, "f_roll": 0})
    for kw in variants:
        p = _params(**kw)
        for axis in ("roll", "yaw"):
            pid = AxisPid()
            pid.configure(p, axis, 1000, "pidsum_limit")
            ref = _PidRef(pid)
            ref.dterm.configure(p.get("dterm_lpf1_type"), p.get("dterm_lpf1_hz"), 1000)
            rnd = _Rand(11)
            for k in range(500):
                sp = rnd() * 8.0
                gyro = rnd() * 8.0
                dt = 0.001 if k % 13 else 0.0013
                tpa = 1.0 if k % 3 else 0.7
                i_active = k % 7 != 0
                sat = k % 5 == 0
                out = pid.update(sp, gyro, dt, tpa, i_active, sat)
                r_out, r_p, r_d, r_f = ref.update(sp, gyro, dt, tpa, i_active, sat)
                assert out == r_out, (kw, axis, k)
                # the terms as kept for the log and telemetry: float32 (the controller's array)
                assert pid.i == ref.i and pid.p() == _f32(r_p) and pid.f() == _f32(r_f), (kw, axis, k)
                assert pid.d() == _f32(r_d) or (pid.d() == 0.0 and r_d == 0.0), (kw, axis, k)


def _mahony_ref(est, bias, q, gyro, accel, dt_s, armed):
    """The Mahony step written the plain way; q and bias are array('f') of its own."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    gx, gy, gz = gyro[0], gyro[1], gyro[2]
    ax, ay, az = accel[0], accel[1], accel[2]
    norm = math.sqrt(ax * ax + ay * ay + az * az)
    kp = est.kp
    if not armed:
        kp *= est.boost
    if norm > 0.1:
        dev = abs(norm / _G - 1.0)
        trust = 1.0 if dev < 0.05 else (0.0 if dev > 0.1 else (0.1 - dev) * 20.0)
        inv = -1.0 / norm
        ax *= inv
        ay *= inv
        az *= inv
        vx = 2.0 * (x * z - w * y)
        vy = 2.0 * (w * x + y * z)
        vz = w * w - x * x - y * y + z * z
        ex = (ay * vz - az * vy) * trust
        ey = (az * vx - ax * vz) * trust
        ez = (ax * vy - ay * vx) * trust
        if est.ki > 0:
            bias[0] -= est.ki * ex * dt_s
            bias[1] -= est.ki * ey * dt_s
            bias[2] -= est.ki * ez * dt_s
        gx += kp * ex - bias[0]
        gy += kp * ey - bias[1]
        gz += kp * ez - bias[2]
    else:
        gx -= bias[0]
        gy -= bias[1]
        gz -= bias[2]
    h = 0.5 * dt_s
    gx *= h
    gy *= h
    gz *= h
    nw = w - x * gx - y * gy - z * gz
    nx = x + w * gx + y * gz - z * gy
    ny = y + w * gy - x * gz + z * gx
    nz = z + w * gz + x * gy - y * gx
    inv = 1.0 / math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
    q[0] = nw * inv
    q[1] = nx * inv
    q[2] = ny * inv
    q[3] = nz * inv
    w, x, y, z = q[0], q[1], q[2], q[3]
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    s = max(-1.0, min(1.0, 2.0 * (w * y - z * x)))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, math.asin(s), yaw, 1.0 - 2.0 * (x * x + y * y)


def test_mahony_equals_the_plain_formula_in_and_out_of_trust_with_and_without_bias_integral():
    for ki in (0, 3000):
        p = _params(imu_dcm_ki=ki)
        est = Mahony()
        est.configure(p)
        att = Attitude()
        est.reset(att)
        q = array("f", [1.0, 0.0, 0.0, 0.0])
        bias = array("f", [0.0, 0.0, 0.0])
        rnd = _Rand(13)
        gyro = array("f", [0.0, 0.0, 0.0])
        acc = array("f", [0.0, 0.0, 0.0])
        for k in range(600):
            for i in range(3):
                gyro[i] = rnd() * 0.5
            acc[0] = rnd() * 2.0
            acc[1] = rnd() * 2.0
            acc[2] = -9.8 + rnd() * (3.0 if k % 50 < 25 else 0.3)  # in, fading and out of trust
            if k % 97 == 5:
                acc[0] = acc[1] = acc[2] = 0.0  # free fall: no gravity reference
            dt = 0.001 if k % 13 else 0.0013
            armed = k > 300
            est.update(gyro, acc, dt, armed, att)
            roll, pitch, yaw, cos_tilt = _mahony_ref(est, bias, q, gyro, acc, dt, armed)
            assert list(att.q) == list(q), (ki, k)
            assert list(est.bias_rad_s) == list(bias), (ki, k)
            assert (att.roll_rad, att.pitch_rad, att.yaw_rad, att.cos_tilt) == (roll, pitch, yaw, cos_tilt), (ki, k)


def test_controller_angle_and_horizon_equal_the_plain_formula():
    p = _params()
    c = Controller()
    c.configure(p, 1000)
    att = Attitude()
    sp = Setpoint()
    rnd = _Rand(17)
    gyro = array("f", [0.0, 0.0, 0.0])
    torque = array("f", [0.0, 0.0, 0.0])
    last_r = 0.0
    last_p = 0.0
    for k in range(300):
        mode = (MODE_ACRO, MODE_ANGLE, MODE_HORIZON)[(k // 50) % 3]
        sp.mode = mode
        for i in range(3):
            sp.stick_norm[i] = rnd()
            sp.rate_rad_s[i] = rnd() * 8.0
            gyro[i] = rnd()
        sp.roll_angle_rad = rnd()
        sp.pitch_angle_rad = rnd()
        sp.throttle_norm = (rnd() + 1.0) * 0.5
        att.roll_rad = rnd()
        att.pitch_rad = rnd()
        dt = 0.001 if k % 13 else 0.0013
        want = array("f", list(sp.rate_rad_s))
        if mode != MODE_ACRO:
            lim = c.angle_rate_limit
            lr = ((sp.roll_angle_rad - att.roll_rad) * c.angle_gain
                  + (sp.roll_angle_rad - last_r) * (1.0 / dt) * c.angle_ff)
            lp = ((sp.pitch_angle_rad - att.pitch_rad) * c.angle_gain
                  + (sp.pitch_angle_rad - last_p) * (1.0 / dt) * c.angle_ff)
            lr = max(-lim, min(lim, lr))
            lp = max(-lim, min(lim, lp))
            if mode == MODE_ANGLE:
                want[0] = lr
                want[1] = lp
            else:
                defl = max(abs(sp.stick_norm[0]), abs(sp.stick_norm[1]))
                w = c.horizon_strength * (1.0 - defl)
                want[0] = want[0] * (1.0 - w) + lr * w
                want[1] = want[1] * (1.0 - w) + lp * w
        last_r = sp.roll_angle_rad
        last_p = sp.pitch_angle_rad
        c.update(sp, att, gyro, dt, True, False, torque)
        assert list(sp.rate_rad_s) == list(want), k


def test_mixer_equals_the_weight_table_sum_on_every_frame():
    rnd = _Rand(19)
    for frame in MIXER_TABLES:
        for rev in (0, 1):
            mx = Mixer()
            mx.configure(_params(mixer_type=frame, yaw_motors_rev=rev))
            n = mx.n
            torque = array("f", [0.0, 0.0, 0.0])
            out = array("f", [0.0] * 8)
            mix = array("f", [0.0] * 8)
            for k in range(200):
                torque[0] = rnd() * 0.8
                torque[1] = rnd() * 0.8
                torque[2] = rnd() * 0.4
                thr = (rnd() + 1.0) * 0.5
                air = k % 3 != 0
                mx.update(thr, torque, air, out)
                sums = [torque[0] * mx.roll_w[i] + torque[1] * mx.pitch_w[i] + torque[2] * mx.yaw_w[i]
                        for i in range(n)]
                for i in range(n):
                    mix[i] = sums[i]
                lo = min(sums)
                hi = max(sums)
                span = hi - lo
                throttle = thr
                sat = False
                if span > 1.0:
                    for i in range(n):
                        mix[i] *= 1.0 / span
                    lo *= 1.0 / span
                    hi *= 1.0 / span
                    throttle = 0.5 if air else thr
                    sat = True
                if air or span > 1.0:
                    if throttle + hi > 1.0:
                        throttle = 1.0 - hi
                    if throttle + lo < 0.0:
                        throttle = -lo
                for i in range(n):
                    m = throttle + mix[i]
                    if m < 0.0 or m > 1.0:
                        sat = True
                    assert out[i] == array("f", [max(0.0, min(1.0, m))])[0], (frame, k, i)
                assert mx.saturated == sat, (frame, k)
