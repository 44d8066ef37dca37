"""Unit tests of the flight-core stages: filters, rates curve, PID, mixer, estimator.

Portable: pytest runs them on CPython and tests/portable/mprun.py under MicroPython.
"""

import math
from array import array

from hoverfly.core.config.params import PARAMS, Params, check_value
from hoverfly.core.signals import Setpoint
from hoverfly.core.stages.control import MODE_ACRO, MODE_ANGLE, Controller
from hoverfly.core.stages.estimator import Attitude, GyroCalibration, Mahony
from hoverfly.core.stages.filters import AlphaBeta, Biquad, LowPass, Pt1, Pt2
from hoverfly.core.stages.mixer import MIXER_TABLES, Mixer
from hoverfly.core.stages.pid import AxisPid
from hoverfly.core.stages.rates import ActualRates

DEG = math.pi / 180.0


def _gain_at(f, hz, fs=1000.0, n=3000):
    """Amplitude of a sine at hz after the filter, in steady state."""
    peak = 0.0
    for k in range(n):
        y = f.update(math.sin(2 * math.pi * hz * k / fs))
        if k > n // 2 and abs(y) > peak:
            peak = abs(y)
    return peak


def test_pt1_passes_dc_and_is_3db_down_at_cutoff():
    f = Pt1(50.0, 1000.0)
    for _ in range(2000):
        y = f.update(1.0)
    assert abs(y - 1.0) < 1e-6
    g = _gain_at(Pt1(50.0, 1000.0), 50.0)
    assert 0.62 < g < 0.76  # -3 dB = 0.707; the discrete PT1 (Betaflight's form) sits a little lower


def test_pt2_is_3db_down_at_its_cutoff_and_steeper_than_pt1():
    g = _gain_at(Pt2(50.0, 1000.0), 50.0)
    assert 0.58 < g < 0.78
    assert _gain_at(Pt2(50.0, 1000.0), 300.0) < _gain_at(Pt1(50.0, 1000.0), 300.0)


def test_biquad_lowpass_and_notch():
    lp = Biquad()
    lp.configure_lowpass(100.0, 1000.0)
    assert 0.66 < _gain_at(lp, 100.0) < 0.75
    lp2 = Biquad()
    lp2.configure_lowpass(100.0, 1000.0)
    assert _gain_at(lp2, 400.0) < 0.1
    notch = Biquad()
    notch.configure_notch(200.0, 160.0, 1000.0)
    assert _gain_at(notch, 200.0) < 0.05
    far = Biquad()
    far.configure_notch(200.0, 160.0, 1000.0)
    assert _gain_at(far, 30.0) > 0.95


def test_lowpass_picks_the_named_type_and_zero_cutoff_passes_through():
    f = LowPass()
    f.configure("biquad", 0.0, 1000.0)
    assert f.update(0.3) == 0.3
    f.configure("pt2", 20.0, 1000.0)
    assert f.update(1.0) < 0.1


def test_alpha_beta_tracks_a_ramp_without_lag_and_passes_with_alpha_one():
    ab = AlphaBeta(0.5, 0.1, 100.0)
    x = 0.0
    for k in range(400):
        x = ab.update(k * 0.01)  # a ramp of 1 unit per second
    assert abs(x - 3.99) < 0.01
    assert AlphaBeta(1.0, 0.0, 100.0).update(0.7) == 0.7


def test_actual_rates_centre_max_and_inverse():
    r = ActualRates()
    r.configure(7, 67, 0)
    assert abs(r.rate_rad_s(1.0) - 670 * DEG) < 1e-3
    assert abs(r.rate_rad_s(-1.0) + 670 * DEG) < 1e-3
    # centre sensitivity: the slope at centre is 70 deg/s per unit of stick
    assert abs(r.rate_rad_s(0.001) / 0.001 - 70 * DEG) < 0.02
    s = r.stick_for_rate(400 * DEG)
    assert abs(r.rate_rad_s(s) - 400 * DEG) < 1e-3
    r.configure(7, 67, 50)
    linear = ActualRates()
    linear.configure(7, 67, 0)
    assert r.rate_rad_s(0.5) < linear.rate_rad_s(0.5)  # expo softens mid-stick
    assert abs(r.rate_rad_s(1.0) - 670 * DEG) < 1e-3


def test_pid_p_term_uses_betaflight_scale():
    p = Params()
    pid = AxisPid()
    pid.configure(p, "roll", 1000, "pidsum_limit")
    out = pid.update(100 * DEG, 0.0, 0.001, 1.0, False, False)
    # Betaflight: P 45 x 0.032029 x 100 deg/s = 144 PID-sum units of 1000
    assert abs(pid.p() - 45 * 0.032029 * 100 / 1000.0) < 1e-4
    assert out > 0


def test_i_term_holds_while_mixer_saturated_and_resets_when_inactive():
    p = Params()
    p.set("iterm_relax", "off")
    pid = AxisPid()
    pid.configure(p, "roll", 1000, "pidsum_limit")
    for _ in range(100):
        pid.update(50 * DEG, 0.0, 0.001, 1.0, True, False)
    i_before = pid.i
    assert i_before > 0
    for _ in range(100):
        pid.update(50 * DEG, 0.0, 0.001, 1.0, True, True)
    assert pid.i == i_before
    pid.update(50 * DEG, 0.0, 0.001, 1.0, False, False)
    assert pid.i == 0.0


def test_i_term_is_limited():
    p = Params()
    p.set("iterm_relax", "off")
    pid = AxisPid()
    pid.configure(p, "pitch", 1000, "pidsum_limit")
    for _ in range(20000):
        pid.update(500 * DEG, 0.0, 0.001, 1.0, True, False)
    assert abs(pid.i - p.get("iterm_limit") / 1000.0) < 1e-6


def test_d_term_is_on_measurement_so_a_setpoint_step_does_not_kick_it():
    p = Params()
    pid = AxisPid()
    pid.configure(p, "roll", 1000, "pidsum_limit")
    pid.update(0.0, 0.0, 0.001, 1.0, False, False)
    pid.update(300 * DEG, 0.0, 0.001, 1.0, False, False)
    assert pid.d() == 0.0
    pid.update(300 * DEG, 50 * DEG, 0.001, 1.0, False, False)
    assert pid.d() < 0.0  # opposes the gyro's movement


def test_angle_mode_turns_angle_error_into_a_rate_setpoint():
    p = Params()
    c = Controller()
    c.configure(p, 1000)
    sp = Setpoint()
    sp.mode = MODE_ANGLE
    sp.roll_angle_rad = 20 * DEG
    att = Attitude()
    torque = array("f", [0.0, 0.0, 0.0])
    gyro = array("f", [0.0, 0.0, 0.0])
    for _ in range(3):  # past the feed-forward of the setpoint's jump
        c.update(sp, att, gyro, 0.001, False, False, torque)
    assert abs(sp.rate_rad_s[0] - 20 * DEG * p.get("angle_p_gain") * 0.1) < 1e-4
    assert torque[0] > 0
    sp.mode = MODE_ACRO
    sp.rate_rad_s[0] = 0.0
    c.update(sp, att, gyro, 0.001, False, False, torque)
    assert sp.rate_rad_s[0] == 0.0


def _geometry(row):
    """Position (x forward, y right) implied by a mixer row's roll and pitch weights."""
    return row[2], -row[1]


def test_mixer_signs_match_the_geometry_on_every_frame():
    for frame in MIXER_TABLES:
        p = Params()
        p.set("mixer_type", frame)
        m = Mixer()
        m.configure(p)
        out = array("f", [0.0] * 8)
        table = MIXER_TABLES[frame]
        for axis in range(2):
            torque = array("f", [0.0, 0.0, 0.0])
            torque[axis] = 0.1
            m.update(0.5, torque, True, out)
            for i in range(m.n):
                x, y = _geometry(table[i])
                if axis == 0 and abs(y) > 1e-6:
                    # roll right: motors on the left (y < 0) push harder
                    assert (out[i] > 0.5) == (y < 0), (frame, i)
                if axis == 1 and abs(x) > 1e-6:
                    # pitch up: front motors (x > 0) push harder
                    assert (out[i] > 0.5) == (x > 0), (frame, i)
        if frame != "tri":
            torque = array("f", [0.0, 0.0, 0.1])
            m.update(0.5, torque, True, out)
            for i in range(m.n):
                assert (out[i] > 0.5) == (table[i][3] > 0), (frame, i)
            assert abs(sum(table[i][3] for i in range(m.n))) < 1e-6  # yaw balanced
        else:
            m.update(0.5, array("f", [0.0, 0.0, 0.2]), True, out)
            assert m.servo_norm[0] > 0


def test_quadx_is_betaflight_order_and_seed000_is_the_picoflight_table():
    bf = MIXER_TABLES["quadx"]
    assert [r[1] for r in bf] == [-1.0, -1.0, 1.0, 1.0]  # 1 rear right, 2 front right, 3 rear left, 4 front left
    assert [r[2] for r in bf] == [-1.0, 1.0, -1.0, 1.0]
    seed = MIXER_TABLES["quadx_seed000"]
    assert [tuple(r) for r in seed] == [(1, -1, 1, -1), (1, -1, -1, 1), (1, 1, 1, 1), (1, 1, -1, -1)]


def test_desaturation_keeps_the_torque_ratio_when_asked_for_too_much():
    p = Params()
    m = Mixer()
    m.configure(p)
    out = array("f", [0.0] * 8)
    m.update(0.9, array("f", [0.8, 0.4, 0.0]), True, out)
    assert m.saturated
    for v in out[:4]:
        assert 0.0 <= v <= 1.0
    roll = (out[2] + out[3] - out[0] - out[1]) / 4.0
    pitch = (out[1] + out[3] - out[0] - out[2]) / 4.0
    assert abs(roll / pitch - 2.0) < 1e-3


def test_air_mode_keeps_authority_at_zero_throttle():
    p = Params()
    m = Mixer()
    m.configure(p)
    out = array("f", [0.0] * 8)
    m.update(0.0, array("f", [0.2, 0.0, 0.0]), True, out)
    assert min(out[:4]) >= 0.0 and (out[2] - out[0]) > 0.39
    m.update(0.0, array("f", [0.2, 0.0, 0.0]), False, out)
    assert (out[2] - out[0]) < 0.25  # without air mode the low side clips at zero


def test_mahony_converges_from_a_tilted_start():
    p = Params()
    est = Mahony()
    est.configure(p)
    att = Attitude()
    est.reset(att)
    g = 9.80665
    roll = 20 * DEG
    accel = array("f", [0.0, -g * math.sin(roll), -g * math.cos(roll)])
    gyro = array("f", [0.0, 0.0, 0.0])
    for _ in range(20000):
        est.update(gyro, accel, 0.001, False, att)
    assert abs(att.roll_rad - roll) < 0.5 * DEG
    assert abs(att.pitch_rad) < 0.5 * DEG


def test_mahony_pitch_sign_nose_up_is_positive():
    p = Params()
    est = Mahony()
    est.configure(p)
    att = Attitude()
    g = 9.80665
    pitch = 15 * DEG
    accel = array("f", [g * math.sin(pitch), 0.0, -g * math.cos(pitch)])
    est.level_from_accel(accel, att)
    assert abs(att.pitch_rad - pitch) < 1e-3


def test_mahony_bias_integral_rejects_a_gyro_bias():
    p = Params()
    p.set("imu_dcm_ki", 2000)
    p.set("imu_dcm_kp", 2000)
    est = Mahony()
    est.configure(p)
    att = Attitude()
    est.reset(att)
    accel = array("f", [0.0, 0.0, -9.80665])
    gyro = array("f", [0.5 * DEG, -0.3 * DEG, 0.0])
    for _ in range(60000):
        est.update(gyro, accel, 0.001, True, att)
    assert abs(est.bias_rad_s[0] - 0.5 * DEG) < 0.05 * DEG
    assert abs(est.bias_rad_s[1] + 0.3 * DEG) < 0.05 * DEG
    assert abs(att.roll_rad) < 0.1 * DEG


def test_gyro_calibration_averages_and_restarts_on_motion():
    p = Params()
    cal = GyroCalibration()
    cal.configure(p, 1000)
    g = array("f", [0.01, -0.02, 0.005])
    for _ in range(500):
        cal.update(g)
    g[0] = 1.0  # picked up: motion restarts it
    cal.update(g)
    assert not cal.calibrated and cal.restarts == 1
    g[0] = 0.01
    done = False
    for _ in range(1000):
        done = cal.update(g) or done
    assert done and cal.calibrated
    assert abs(cal.bias_rad_s[1] + 0.02) < 1e-6


def test_parameter_names_are_short_and_ranges_hold():
    for r in PARAMS:
        assert len(r[0]) <= 16, r[0]
    p = Params()
    assert p.set("p_roll", 999) is not None
    assert p.get("p_roll") == 45
    assert p.set("p_roll", "60") is None and p.get("p_roll") == 60
    assert check_value("mixer_type", "HEXX")[0] == "hexx"
    assert check_value("nope", 1)[1] is not None
