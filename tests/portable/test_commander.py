"""The commander on its own: who flies (the pilot, the failsafe, the autopilot) and with what set point, its
source word written where each source's say starts and ends, and the I-term and air-mode start. Real stages
around it (RcInput, Arming, Failsafe, Autopilot, Controller), time injected. Portable."""

from hoverfly.core.command.autopilot import AP_ENABLED, AP_SILENT, AP_WAIT, Autopilot
from hoverfly.core.command.commander import (
    FLIER_AUTOPILOT,
    FLIER_FAILSAFE,
    FLIER_MOTOR_TEST,
    FLIER_NOBODY,
    FLIER_PILOT,
    SOURCE_AUTOPILOT,
    SOURCE_FAILSAFE,
    Commander,
)
from hoverfly.core.config.params import Params
from hoverfly.core.events import EV_AIRMODE, EV_MODE, EventLog
from hoverfly.core.safety.arming import Arming
from hoverfly.core.safety.failsafe import IDLE, STAGE1, STAGE2, Failsafe
from hoverfly.core.signals import Signals
from hoverfly.core.stages.control import MODE_ACRO, MODE_ANGLE, Controller
from hoverfly.core.stages.rc import RcInput

T0 = 1000000


class Rig:
    """A commander wired as Flight wires it, on stages of its own."""

    def __init__(self, **params):
        p = Params()
        for name in params:
            p.set(name, params[name])
        self.params = p
        self.signals = Signals()
        self.sp = self.signals.setpoint
        self.events = EventLog()
        self.rc = RcInput()
        self.rc.configure(p, 1000)
        self.arming = Arming(self.events)
        self.failsafe = Failsafe(self.events)
        self.failsafe.configure(p)
        self.autopilot = Autopilot(self.events)
        self.autopilot.pilot_channels = self.signals.rc_channels_us
        self.controller = Controller(self.signals.pid_terms)
        self.cm = Commander(self.events, self.rc, self.arming, self.failsafe, self.autopilot, self.controller,
                            self.signals.accel_raw_m_s2)
        self.failsafe.commander = self.cm
        self.cm.configure(p, True)
        self.seen = 0

    def pilot(self, roll, throttle_norm, mode=MODE_ACRO):
        """The pilot's smoothed sticks, as RcInput.update leaves them in the set point."""
        self.rc.stick_raw[0] = roll
        self.rc.throttle_raw = throttle_norm
        self.rc.mode = mode
        sp = self.sp
        sp.stick_norm[0] = roll
        sp.stick_norm[1] = 0.0
        sp.stick_norm[2] = 0.0
        sp.throttle_norm = throttle_norm
        self.rc.fill_setpoint(sp)

    def frame(self, t, arm, ap):
        self.rc.arm_switch = arm
        self.rc.ap_switch = ap
        self.cm.pilot_frame(t, self.arming.armed)

    def events_of(self, kind):
        """The events of this kind recorded since the last look."""
        out = []
        self.seen = self.events.drain(self.seen, lambda t, e, d: out.append((e, d)) if e == kind else None)
        return out


def _enable_autopilot(r, t):
    """The seed-004 procedure: the autopilot switch on, the arm switch seen off, then on."""
    r.frame(t, False, True)
    for k in range(6):
        r.frame(t + 4000 * (k + 1), False, True)
    assert r.autopilot.state == AP_WAIT
    r.frame(t + 40000, True, True)
    assert r.autopilot.state == AP_ENABLED
    return t + 40000


def _msp(r, t, throttle_us):
    ch = [1500] * 8
    ch[2] = throttle_us  # AETR: throttle on channel 3
    ch[4] = 1000  # its arm channel off
    return r.autopilot.on_msp_rc(t, ch, 8, r.arming)


def test_the_pilot_flies_while_nothing_else_has_a_say():
    r = Rig()
    r.pilot(0.5, 0.4, MODE_ACRO)
    r.cm.update(r.sp, T0)
    assert r.cm.source == 0
    assert abs(r.sp.stick_norm[0] - 0.5) < 1e-6 and abs(r.sp.throttle_norm - 0.4) < 1e-6
    assert r.sp.mode == MODE_ACRO
    assert r.events_of(EV_MODE) == [(EV_MODE, MODE_ACRO)]  # the first pass names its mode, once
    r.cm.update(r.sp, T0 + 1000)
    assert r.events_of(EV_MODE) == []


def test_the_failsafe_takes_the_setpoint_from_stage_1_and_hands_it_back_when_the_link_returns():
    r = Rig()
    r.arming.arm(T0)
    r.failsafe.update(T0, True, T0 - 100000, True, False, r.arming)
    assert r.failsafe.state == STAGE1 and r.cm.source == SOURCE_FAILSAFE
    r.pilot(0.8, 0.6, MODE_ACRO)  # the pilot's last sticks, stale
    r.cm.update(r.sp, T0 + 1000)
    assert r.sp.stick_norm[0] == 0.0 and r.sp.rate_rad_s[0] == 0.0 and r.sp.roll_angle_rad == 0.0
    assert r.sp.mode == MODE_ANGLE  # levelled
    r.failsafe.update(T0 + 10000, False, T0 + 10000, True, False, r.arming)
    assert r.failsafe.state == IDLE and r.cm.source == 0
    r.pilot(0.8, 0.6, MODE_ACRO)
    r.cm.update(r.sp, T0 + 11000)
    assert abs(r.sp.stick_norm[0] - 0.8) < 1e-6 and r.sp.mode == MODE_ACRO


def test_failsafe_stage_2_flies_its_landing_throttle_or_cuts_it_for_drop():
    for procedure in ("land", "drop"):
        r = Rig(fs_procedure=procedure)
        r.arming.arm(T0)
        r.failsafe.update(T0, True, T0 - 200000, True, False, r.arming, 0, True)  # straight to stage 2
        assert r.failsafe.state == STAGE2 and r.cm.source == SOURCE_FAILSAFE
        r.pilot(0.0, 0.7)
        r.cm.update(r.sp, T0 + 1000)
        if procedure == "land":
            assert abs(r.sp.throttle_norm - r.failsafe.land_throttle_norm) < 1e-6
        else:  # drop disarms on entering stage 2; the set point's throttle is cut as well
            assert not r.arming.armed and r.sp.throttle_norm == 0.0


def test_the_failsafe_outranks_an_autopilot_that_flies():
    r = Rig()
    t = _enable_autopilot(r, T0)
    r.arming.arm(t)
    assert _msp(r, t, 1300) is None
    r.pilot(0.0, 0.9)
    r.cm.update(r.sp, t + 1000)
    assert abs(r.sp.throttle_norm - 0.3) < 1e-3  # the autopilot's throttle (the pilot's 0.9 is only its cap)
    r.failsafe.update(t + 2000, True, t, True, False, r.arming)
    assert r.cm.source == SOURCE_FAILSAFE | SOURCE_AUTOPILOT
    r.pilot(0.0, 0.9)
    r.cm.update(r.sp, t + 3000)
    assert r.sp.mode == MODE_ANGLE and r.sp.stick_norm[0] == 0.0
    assert r.cm.flier(False) == FLIER_FAILSAFE


def test_an_autopilot_silent_while_disarmed_hands_back_at_once_with_no_latch():
    r = Rig(ap_timeout_ms=200)
    t = _enable_autopilot(r, T0)
    assert r.cm.source == SOURCE_AUTOPILOT
    assert _msp(r, t, 1000) is None
    r.cm.task(t + 100000, False, 0.0)
    assert r.cm.source == SOURCE_AUTOPILOT  # not silent yet
    r.cm.task(t + 300000, False, 0.0)
    assert r.autopilot.state == AP_SILENT and r.autopilot.latch_norm < 0.0
    assert r.cm.source == 0


def test_a_hard_override_holds_the_throttle_latch_until_the_pilots_stick_comes_down_to_it():
    r = Rig()
    t = _enable_autopilot(r, T0)
    r.arming.arm(t)
    assert _msp(r, t, 1400) is None
    r.frame(t + 4000, True, False)  # the autopilot switch off while it flies: hard override
    assert r.autopilot.latch_norm >= 0.0 and r.cm.source == SOURCE_AUTOPILOT
    r.pilot(0.0, 0.9)
    r.cm.update(r.sp, t + 5000)
    assert abs(r.sp.throttle_norm - 0.4) < 1e-3  # held at the autopilot's last
    assert r.cm.source == SOURCE_AUTOPILOT
    r.pilot(0.0, 0.35)  # the stick comes down past the latch: released in this very pass
    r.cm.update(r.sp, t + 6000)
    assert r.autopilot.latch_norm < 0.0 and r.cm.source == 0
    assert abs(r.sp.throttle_norm - 0.35) < 1e-6


def test_no_i_term_and_no_air_mode_on_the_ground_until_the_throttle_is_raised_after_arming():
    r = Rig(airmode_thr_pct=25)
    r.arming.arm(T0)
    r.controller.roll.i = 0.2
    r.pilot(0.0, 0.1)
    r.cm.update(r.sp, T0 + 1000)
    assert not r.cm.i_active and not r.cm.airmode_active and r.controller.roll.i == 0.0
    r.pilot(0.0, 0.3)
    r.cm.update(r.sp, T0 + 2000)
    assert r.cm.i_active and r.cm.airmode_active and r.cm.throttle_was_up
    assert r.events_of(EV_AIRMODE) == [(EV_AIRMODE, 1)]
    r.controller.roll.i = 0.2
    r.pilot(0.0, 0.0)  # throttle cut in flight: the I-term and air mode stay
    r.cm.update(r.sp, T0 + 3000)
    assert r.cm.i_active and r.controller.roll.i == 0.2
    r.arming.disarm(T0 + 4000, 0)
    r.cm.update(r.sp, T0 + 4000)
    assert not r.cm.i_active and not r.cm.throttle_was_up and r.controller.roll.i == 0.0


def test_the_airmode_switch_is_read_on_each_frame_where_a_channel_is_set():
    r = Rig(airmode_ch=6)
    assert r.rc.airmode_box and not r.cm.airmode_enabled
    r.rc.airmode_switch = True
    r.frame(T0, False, False)
    assert r.cm.airmode_enabled
    r2 = Rig(airmode=0)
    r2.cm.configure(r2.params, False)
    assert not r2.cm.airmode_enabled  # no channel: the parameter


def test_flier_names_who_flies_for_the_msp_status():
    r = Rig()
    assert r.cm.flier(False) == FLIER_NOBODY
    assert r.cm.flier(True) == FLIER_MOTOR_TEST
    r.arming.arm(T0)
    assert r.cm.flier(False) == FLIER_PILOT
    t = _enable_autopilot(r, T0)
    assert r.cm.flier(False) == FLIER_PILOT  # enabled, but nothing sent yet
    assert _msp(r, t, 1300) is None
    assert r.cm.flier(False) == FLIER_AUTOPILOT
