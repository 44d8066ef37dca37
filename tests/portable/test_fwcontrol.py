"""The fixed-wing control law (core/stages/fwcontrol.py), the plane's failsafe glide and the hand launch
(core/command/launch.py), each against what seed 002 and INAV say it is, time injected. Portable."""

import math

from hoverfly.core.command.autopilot import Autopilot
from hoverfly.core.command.commander import SOURCE_FAILSAFE, SOURCE_LAUNCH, Commander
from hoverfly.core.command.launch import LAUNCH_CLIMB, LAUNCH_OFF, LAUNCH_THROWN, LAUNCH_WAIT, Launch
from hoverfly.core.config.params import Params
from hoverfly.core.events import EV_FAILSAFE_STAGE2, EventLog
from hoverfly.core.safety.arming import Arming
from hoverfly.core.safety.failsafe import PROC_GLIDE, PROC_LAND, STAGE1, STAGE2, Failsafe
from hoverfly.core.signals import Signals
from hoverfly.core.stages.control import MODE_ACRO, MODE_ANGLE, MODE_HORIZON, MODE_MANUAL, Controller
from hoverfly.core.stages.fwcontrol import FwController, manual_curve, tpa_factor
from hoverfly.core.stages.rc import RcInput
from hoverfly.core.stages.receiver import flight_mode_text

DEG = math.pi / 180.0
G = 9.80665
DT = 0.001


def _params(**kw):
    p = Params()
    assert p.set("mixer_type", "airplane") is None
    for k in kw:
        assert p.set(k, kw[k]) is None, k
    return p


def _fw(**kw):
    s = Signals()
    fw = FwController(s.pid_terms)
    fw.configure(_params(**kw))
    return fw, s


def _level(s, roll_rad=0.0, pitch_rad=0.0):
    """The attitude at this bank and pitch (yaw 0): quaternion and angles."""
    a = s.attitude
    cr = math.cos(roll_rad / 2)
    sr = math.sin(roll_rad / 2)
    cp = math.cos(pitch_rad / 2)
    spp = math.sin(pitch_rad / 2)
    a.q[0] = cr * cp
    a.q[1] = sr * cp
    a.q[2] = cr * spp
    a.q[3] = -sr * spp
    a.set_from_quaternion()


def _inav(gain, div):
    """An INAV fixed-wing gain as a share of full throw per rad/s: gain / div per deg/s, 500 = full throw."""
    return gain / div / 500.0 / DEG


def test_angle_mode_is_seed_002s_piff_with_inavs_scales():
    # given a plane in ANGLE, banked 10 degrees right, rolling left at 5 deg/s, the stick centred
    fw, s = _fw(fw_turn_yaw_gain=0.0, fw_turn_pit_gain=0.0)
    sp = s.setpoint
    sp.mode = MODE_ANGLE
    sp.throttle_norm = 0.5  # at the TPA breakpoint (and fw_tpa_rate 0: no TPA at all)
    _level(s, 10 * DEG)
    s.gyro_rad_s[0] = -5 * DEG
    # when one pass runs with the integrator on
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, True, s.torque_norm)
    # then the angle error x P is the rate set point, FF on it plus PI on the rate error the output
    rate_sp = (0.0 - 10 * DEG) * 20 / 6.56  # fw_p_level 20
    assert abs(sp.rate_rad_s[0] - rate_sp) < 1e-5
    err = rate_sp - (-5 * DEG)
    want = _inav(50, 31) * rate_sp + _inav(5, 31) * err + _inav(7, 4) * err * DT
    assert abs(s.torque_norm[0] - want) < 1e-5, (s.torque_norm[0], want)
    assert s.torque_norm[0] < 0.0  # aileron left, back to level
    # and the terms the log records add up to it
    t = s.pid_terms
    assert abs(t[0] + t[3] + t[9] - s.torque_norm[0]) < 1e-6


def test_bank_and_pitch_follow_the_stick_within_their_limits():
    fw, s = _fw(fw_max_bank_deg=40, fw_max_pitch_deg=15, fw_turn_yaw_gain=0.0, fw_turn_pit_gain=0.0)
    sp = s.setpoint
    sp.mode = MODE_ANGLE
    sp.throttle_norm = 0.5
    # full right stick at 40 degrees of bank: no more roll asked; full back stick at 15 degrees: no more pitch
    _level(s, 40 * DEG, 15 * DEG)
    sp.stick_norm[0] = 1.0
    sp.stick_norm[1] = 1.0
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, False, s.torque_norm)
    assert abs(sp.rate_rad_s[0]) < 1e-3
    assert abs(sp.rate_rad_s[1]) < 1e-3
    # half stick from level: half the bank
    _level(s)
    sp.stick_norm[0] = 0.5
    sp.stick_norm[1] = 0.0
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, False, s.torque_norm)
    assert abs(sp.rate_rad_s[0] - 20 * DEG * 20 / 6.56) < 1e-4


def test_the_angle_loops_rate_is_held_to_the_axis_rate():
    fw, s = _fw(fw_roll_dps=90, fw_p_level=200)
    sp = s.setpoint
    sp.mode = MODE_ANGLE
    _level(s, -60 * DEG)
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, False, s.torque_norm)
    assert abs(sp.rate_rad_s[0] - 90 * DEG) < 1e-5


def test_turn_coordination_adds_the_turns_yaw_rate_and_a_nose_up_rate_in_a_bank():
    fw, s = _fw(fw_ref_speed_m_s=12.0)
    sp = s.setpoint
    sp.mode = MODE_ANGLE
    sp.stick_norm[0] = 30.0 / 45.0  # 30 degrees asked, and flown
    _level(s, 30 * DEG)
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, False, s.torque_norm)
    # a coordinated turn at 30 degrees and 12 m/s: psi' = g tan(phi) / V; body r = psi' cos(phi), q = psi' sin(phi)
    psi = G * math.tan(30 * DEG) / 12.0
    assert abs(sp.rate_rad_s[2] - psi * math.cos(30 * DEG)) < 1e-4, sp.rate_rad_s[2]
    assert abs(sp.rate_rad_s[1] - psi * math.sin(30 * DEG)) < 1e-4, sp.rate_rad_s[1]
    # banked left: yaw left, and still nose up
    sp.stick_norm[0] = -30.0 / 45.0
    _level(s, -30 * DEG)
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, False, s.torque_norm)
    assert abs(sp.rate_rad_s[2] + psi * math.cos(30 * DEG)) < 1e-4
    assert sp.rate_rad_s[1] > 0.0
    # the gains scale it; 0 turns it off; ACRO has none
    fw2, s2 = _fw(fw_ref_speed_m_s=12.0, fw_turn_yaw_gain=0.0, fw_turn_pit_gain=0.5)
    s2.setpoint.mode = MODE_ANGLE
    s2.setpoint.stick_norm[0] = 30.0 / 45.0
    _level(s2, 30 * DEG)
    fw2.update(s2.setpoint, s2.attitude, s2.gyro_rad_s, DT, False, s2.torque_norm)
    assert abs(s2.setpoint.rate_rad_s[2]) < 1e-6
    assert abs(s2.setpoint.rate_rad_s[1] - 0.5 * psi * math.sin(30 * DEG)) < 1e-4
    s2.setpoint.mode = MODE_ACRO
    s2.setpoint.stick_norm[0] = 0.0
    fw2.update(s2.setpoint, s2.attitude, s2.gyro_rad_s, DT, False, s2.torque_norm)
    assert s2.setpoint.rate_rad_s[1] == 0.0


def test_tpa_follows_inavs_fixed_wing_curve():
    # at the breakpoint the gains are as set; above it less, below it more, held to 0.3..2
    assert tpa_factor(0.5, 0.5, 1.0) == 1.0
    assert abs(tpa_factor(1.0, 0.5, 1.0) - 0.75) < 1e-9
    assert abs(tpa_factor(0.25, 0.5, 1.0) - 1.5) < 1e-9
    assert tpa_factor(0.05, 0.5, 1.0) == 2.0
    assert tpa_factor(0.0, 0.5, 1.0) == 2.0
    # blended by tpa_rate: 50 % is halfway to 1; 0 % is off
    assert abs(tpa_factor(1.0, 0.5, 0.5) - 0.875) < 1e-9
    assert tpa_factor(1.0, 0.5, 0.0) == 1.0
    # and it scales roll and pitch, not yaw
    fw, s = _fw(fw_tpa_rate=100, fw_tpa_bp_us=1500)
    sp = s.setpoint
    sp.mode = MODE_ACRO
    sp.stick_norm[0] = 0.5
    sp.stick_norm[2] = 0.5
    sp.throttle_norm = 0.5
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, False, s.torque_norm)
    at_bp = (s.torque_norm[0], s.torque_norm[2])
    sp.throttle_norm = 1.0
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, False, s.torque_norm)
    assert abs(s.torque_norm[0] - 0.75 * at_bp[0]) < 1e-5
    assert s.torque_norm[2] == at_bp[1]


def test_the_integrator_resets_when_disarmed_and_stays_within_its_limit():
    fw, s = _fw(fw_i_roll=100, fw_iterm_limit=100)
    sp = s.setpoint
    sp.mode = MODE_ACRO
    sp.stick_norm[0] = 0.5  # a rate asked and not flown (the plane held)
    for _ in range(2000):
        fw.update(sp, s.attitude, s.gyro_rad_s, DT, True, s.torque_norm)
    assert abs(fw.i[0] - 100 / 500.0) < 1e-6  # wound to fw_iterm_limit, no further
    # disarmed (the commander's i_active goes off): zero at once, and the output is P + FF alone
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, False, s.torque_norm)
    assert fw.i[0] == 0.0
    assert s.pid_terms[3] == 0.0
    assert abs(s.torque_norm[0] - (s.pid_terms[0] + s.pid_terms[9])) < 1e-6


def test_manual_sends_the_sticks_through_expo_and_rates_and_holds_no_integrator():
    fw, s = _fw(manual_rc_expo=50, manual_roll_pct=80, manual_pitch_pct=100, manual_yaw_pct=40)
    sp = s.setpoint
    sp.mode = MODE_ACRO
    sp.stick_norm[0] = 0.5
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, True, s.torque_norm)
    assert fw.i[0] != 0.0
    sp.mode = MODE_MANUAL
    sp.stick_norm[1] = -1.0
    sp.stick_norm[2] = 1.0
    _level(s, 40 * DEG)  # the attitude plays no part
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, True, s.torque_norm)
    assert abs(s.torque_norm[0] - 0.8 * 0.5 * (1 - 0.5 + 0.5 * 0.25)) < 1e-6
    assert abs(s.torque_norm[1] + 1.0) < 1e-6
    assert abs(s.torque_norm[2] - 0.4) < 1e-6
    assert fw.i[0] == 0.0
    assert manual_curve(0.0, 0.7) == 0.0 and abs(manual_curve(1.0, 0.7) - 1.0) < 1e-9


def test_horizon_levels_at_centre_stick_and_flies_rate_at_full_stick():
    fw, s = _fw(horizon_level=100, fw_turn_yaw_gain=0.0, fw_turn_pit_gain=0.0)
    sp = s.setpoint
    sp.mode = MODE_HORIZON
    _level(s, 20 * DEG)
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, False, s.torque_norm)
    assert abs(sp.rate_rad_s[0] + 20 * DEG * 20 / 6.56) < 1e-4
    sp.stick_norm[0] = 1.0
    fw.update(sp, s.attitude, s.gyro_rad_s, DT, False, s.torque_norm)
    assert abs(sp.rate_rad_s[0] - 180 * DEG) < 1e-4


# ------------------------------------------------------------------ the commander, failsafe and launch
class Rig:
    """The commander wired as Flight wires it for a plane, on stages of its own."""

    def __init__(self, mixer="airplane", **kw):
        p = Params()
        assert p.set("mixer_type", mixer) is None
        for k in kw:
            assert p.set(k, kw[k]) is None, k
        self.signals = Signals()
        s = self.signals
        self.sp = s.setpoint
        self.events = EventLog()
        self.rc = RcInput()
        self.rc.configure(p, 1000)
        self.arming = Arming(self.events)
        self.failsafe = Failsafe(self.events)
        self.failsafe.configure(p)
        self.fw = FwController(s.pid_terms)
        self.fw.configure(p)
        self.launch = Launch(self.events)
        self.cm = Commander(self.events, self.rc, self.arming, self.failsafe, Autopilot(self.events),
                            Controller(s.pid_terms), s.accel_raw_m_s2)
        self.failsafe.commander = self.cm
        self.cm.plane_parts(self.fw, self.launch, s.attitude, s.accel_m_s2, s.rc_channels_us)
        self.cm.configure(p, True)


def test_rc_loss_glides_wings_level_at_the_glide_pitch_from_500_ms_with_the_motor_off():
    # given a plane cruising in ANGLE at 40 % throttle; its last frame at t0
    r = Rig(fs_glide_pitch=-4.0)
    assert r.failsafe.procedure == PROC_GLIDE  # a plane's "land" is its glide
    r.arming.armed = True
    t0 = 1000000
    r.sp.throttle_norm = 0.4
    # when the link is lost (100 ms) and the supervisor's 100 Hz task runs on
    t = t0
    stage2_at = None
    while t < t0 + 800000:
        lost = t - t0 > 100000
        r.failsafe.update(t, lost, t0, True, False, r.arming)
        if r.failsafe.state == STAGE2 and stage2_at is None:
            stage2_at = t
        t += 10000
    # then stage 2 starts 500 ms after the last frame (seed 002), within one 10 ms task period
    assert 500000 <= stage2_at - t0 <= 510000, stage2_at - t0
    assert r.events.event[(r.events.head - 1) % r.events.size] == EV_FAILSAFE_STAGE2
    # the set point: ANGLE, sticks centred, motor off, the controller holding the glide pitch
    r.sp.stick_norm[0] = 0.7
    r.cm.update(r.sp, t)
    assert r.sp.mode == MODE_ANGLE
    assert r.sp.stick_norm[0] == 0.0 and r.sp.throttle_norm == 0.0
    assert abs(r.fw.pitch_offset_rad + 4.0 * DEG) < 1e-9
    # and the wings level: a bank is rolled out towards 0, the nose held at -4 degrees
    s = r.signals
    _level(s, 25 * DEG, 0.0)
    r.fw.update(r.sp, s.attitude, s.gyro_rad_s, DT, True, s.torque_norm)
    assert r.sp.rate_rad_s[0] < 0.0 and r.sp.rate_rad_s[1] < 0.0
    # the receiver back and the sticks moved: the pilot flies, the pitch target is the stick's again
    r.failsafe.update(t + 10000, False, t + 10000, True, True, r.arming)
    assert r.cm.source & SOURCE_FAILSAFE == 0
    assert r.fw.pitch_offset_rad == 0.0


def test_stage1_holds_level_at_the_last_throttle():
    r = Rig()
    r.arming.armed = True
    r.failsafe.update(1200000, True, 1000000, True, False, r.arming)
    assert r.failsafe.state == STAGE1
    r.sp.throttle_norm = 0.45  # the last frame's throttle, as RcInput leaves it
    r.cm.update(r.sp, 1200000)
    assert r.sp.mode == MODE_ANGLE and r.sp.throttle_norm == 0.45 and r.fw.pitch_offset_rad == 0.0


def test_glide_on_a_multirotor_is_refused_with_a_plain_reason_and_a_stored_one_lands():
    p = Params()
    err = p.set("fs_procedure", "glide")
    assert err is not None and "plane" in err and "land or drop" in err and "\n" not in err
    assert p.get("fs_procedure") == "land"  # nothing changed
    assert p.set("failsafe_procedure", "glide") is not None  # Betaflight's/INAV's name too
    assert p.set("mixer_type", "flying_wing") is None and p.set("fs_procedure", "glide") is None
    # a stored glide loaded on a multirotor (Params.update, as Storage loads) lands it
    q = Params()
    assert q.update((("fs_procedure", "glide"),)) is None
    fs = Failsafe(EventLog())
    fs.configure(q)
    assert fs.procedure == PROC_LAND


def test_crsf_telemetry_names_manual_as_inav_does():
    assert flight_mode_text(MODE_MANUAL, False, False, True, 0) == b"MANU"
    assert flight_mode_text(MODE_MANUAL, False, True, True, 0) == b"!FS!"


def test_the_manual_switch_selects_manual_on_a_plane_only():
    for mixer, want in (("airplane", MODE_MANUAL), ("quadx", MODE_ANGLE)):
        r = Rig(mixer=mixer, manual_ch=7)  # AUX3
        ch = r.signals.rc_channels_us
        ch[5] = 2000  # AUX2: the angle switch on
        ch[6] = 2000  # AUX3: MANUAL
        r.rc.new_frame(ch)
        r.cm.pilot_frame(1000000, False)
        assert r.rc.mode == want, (mixer, r.rc.mode)


# ------------------------------------------------------------------ hand launch
def _launch(**kw):
    ev = EventLog()
    la = Launch(ev)
    la.configure(_params(fw_autolaunch=1, **kw), True)
    return la


def _push(la, t, forward_m_s2, ms, throttle_low=False, cos_tilt=1.0, sticks=False):
    """The 100 Hz task while the arm pushes forward at forward_m_s2 for ms; returns the time after."""
    acc = [forward_m_s2, 0.0, -9.8]
    stick = [0.0, 0.3 if sticks else 0.05, 0.0]  # 0.05: within the centre the pilot's hand leaves
    for _ in range(ms // 10):
        t += 10000
        la.update(t, True, acc, cos_tilt, throttle_low, stick)
    return t


def test_a_throw_is_detected_the_motor_starts_after_the_delay_and_the_climb_ends_on_the_sticks():
    la = _launch()
    t = 1000000
    la.arm(t)
    assert la.state == LAUNCH_WAIT and la.throttle_norm() == 0.0  # idle on the ground
    t = _push(la, t, 0.0, 500)  # held still, throttle up
    assert la.state == LAUNCH_WAIT
    t = _push(la, t, 40.0, 300)  # the throw: 4 g for 0.3 s
    assert la.state == LAUNCH_THROWN
    thrown_at = la.since_us
    assert thrown_at - 1500000 <= 100000  # within 100 ms of the push's start
    t = _push(la, t, 0.0, 200)
    assert la.state == LAUNCH_THROWN and la.throttle_norm() == 0.0
    while la.state == LAUNCH_THROWN:
        t = _push(la, t, 0.0, 10)
    assert 500000 <= t - thrown_at <= 510000  # launch_delay_ms
    assert la.state == LAUNCH_CLIMB and abs(la.throttle_norm() - 0.7) < 1e-9
    t = _push(la, t, 0.0, 1000)
    assert la.state == LAUNCH_CLIMB
    _push(la, t, 0.0, 10, sticks=True)
    assert la.state == LAUNCH_OFF


def test_a_bump_a_slow_push_or_a_tilted_shake_is_not_a_throw():
    la = _launch()
    t = 1000000
    la.arm(t)
    t = _push(la, t, 60.0, 20)  # a knock: 6 g for 20 ms
    t = _push(la, t, 0.0, 100)
    assert la.state == LAUNCH_WAIT
    t = _push(la, t, 12.0, 1000)  # a long push below launch_acc_m_s2
    assert la.state == LAUNCH_WAIT
    t = _push(la, t, 40.0, 300, cos_tilt=0.5)  # pointed 60 degrees off level
    assert la.state == LAUNCH_WAIT
    t = _push(la, t, 40.0, 300, throttle_low=True)  # the throttle not raised yet: INAV waits for it
    assert la.state == LAUNCH_WAIT
    # two knocks in a row: the push restarts from zero between them
    for _ in range(5):
        t = _push(la, t, 30.0, 30)
        t = _push(la, t, 0.0, 30)
    assert la.state == LAUNCH_WAIT


def test_the_launch_ends_at_its_timeout_and_when_disarmed():
    la = _launch(launch_time_ms=2000)
    t = 1000000
    la.arm(t)
    t = _push(la, t, 40.0, 300)
    assert la.state == LAUNCH_THROWN
    thrown_at = la.since_us
    while la.state != LAUNCH_OFF and t < 5000000:
        t = _push(la, t, 0.0, 10)
    assert la.state == LAUNCH_OFF
    assert 2000000 <= t - thrown_at <= 2010000  # launch_time_ms from the throw
    la.arm(t)
    la.update(t + 10000, False, [0.0, 0.0, -9.8], 1.0, False, [0.0, 0.0, 0.0])
    assert la.state == LAUNCH_OFF


def test_the_commander_flies_the_launch_climb_with_the_integrator_held_until_the_motor():
    r = Rig(fw_autolaunch=1, launch_climb_deg=15)
    t = 1000000
    r.arming.armed = True
    r.rc.throttle_us = 1800  # the pilot's throttle up
    r.cm.task(t, True, 0.0)  # the 100 Hz task sees the arming
    assert r.cm.source & SOURCE_LAUNCH
    assert abs(r.fw.pitch_offset_rad - 15 * DEG) < 1e-9
    r.sp.throttle_norm = 0.8
    r.cm.update(r.sp, t)
    assert r.sp.mode == MODE_ANGLE and r.sp.throttle_norm == 0.0 and not r.cm.i_active
    # the throw
    r.signals.accel_m_s2[0] = 40.0
    for _ in range(30):
        t += 10000
        r.cm.task(t, True, 0.0)
    r.signals.accel_m_s2[0] = 0.0
    while r.launch.state != LAUNCH_CLIMB:
        t += 10000
        r.cm.task(t, True, 0.0)
    r.cm.update(r.sp, t)
    assert abs(r.sp.throttle_norm - 0.7) < 1e-6 and r.cm.i_active
    # the pilot's stick ends it: the pilot's set point, level again
    r.rc.stick_raw[1] = 0.3
    r.cm.task(t + 10000, True, 0.0)
    assert r.cm.source & SOURCE_LAUNCH == 0 and r.fw.pitch_offset_rad == 0.0
