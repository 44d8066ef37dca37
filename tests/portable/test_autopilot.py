"""Seed 004's autopilot enabling procedure, overrides and privilege (portable)."""

from array import array

from hoverfly.core.command.autopilot import (
    AP_ENABLED,
    AP_OFF,
    AP_SILENT,
    AP_WAIT,
    PRIV_IN_CONTROL,
    PRIV_RC,
    PRIV_THROTTLE_LATCH,
    Autopilot,
)
from hoverfly.core.config.params import Params
from hoverfly.core.events import EventLog
from hoverfly.core.safety.arming import Arming
from hoverfly.core.signals import Setpoint


def _setup():
    p = Params()
    p.set("boot_grace_ms", 0)
    ev = EventLog()
    arming = Arming(ev)
    arming.configure(p)
    ap = Autopilot(ev)
    ap.configure(p)
    chans = array("H", [1500] * 18)
    ap.pilot_channels = chans
    arming.gate = ap
    arming.check(0, True, True, True, True, 1.0, False, 0)
    return ap, arming, chans


def _frame(ap, arming, chans, now_us, ap_sw, arm_sw, n=1):
    chans[6] = 2000 if ap_sw else 1000
    for k in range(n):
        arming.on_switch(now_us + k, arm_sw)
        ap.on_pilot_frame(now_us + k, arm_sw, arming.armed)


def _msp(throttle_us=1000, arm=False, roll_us=1500):
    return [roll_us, 1500, throttle_us, 1500, 2000 if arm else 1000, 1500, 1500, 1500]


def _enable(ap, arming, chans):
    _frame(ap, arming, chans, 0, False, False, 6)
    _frame(ap, arming, chans, 10, True, False, 6)
    _frame(ap, arming, chans, 20, True, True)
    assert ap.state == AP_ENABLED


def test_msp_rc_before_the_procedure_is_refused_and_changes_nothing():
    ap, arming, chans = _setup()
    _frame(ap, arming, chans, 0, False, False, 6)
    for k in range(1000):
        assert ap.on_msp_rc(100 + k, _msp(1800, arm=(k & 1) == 1), 8, arming) is not None
    assert not arming.armed and ap.frames == 0 and ap.rejected == 1000 and ap.throttle_norm == 0.0
    assert ap.privilege() == 0


def test_arm_switch_before_the_autopilot_switch_does_not_enable():
    ap, arming, chans = _setup()
    _frame(ap, arming, chans, 0, False, False, 6)
    _frame(ap, arming, chans, 10, False, True)
    assert arming.armed  # autopilot switch off: the switch arms as ever
    _frame(ap, arming, chans, 20, True, True, 3)
    assert ap.state == AP_WAIT
    assert ap.on_msp_rc(30, _msp(), 8, arming) is not None


def test_procedure_enables_and_the_switch_then_does_not_arm():
    ap, arming, chans = _setup()
    _enable(ap, arming, chans)
    assert not arming.armed
    assert ap.privilege() & PRIV_RC
    assert ap.on_msp_rc(100, _msp(arm=True), 8, arming) is None  # arm seen on first: not a rising edge
    assert not arming.armed
    assert ap.on_msp_rc(110, _msp(arm=False), 8, arming) is None
    assert ap.on_msp_rc(120, _msp(arm=True), 8, arming) is None
    assert arming.armed and arming.armed_by == 1
    assert ap.privilege() & PRIV_IN_CONTROL


def test_autopilot_arming_refused_when_its_throttle_is_not_low():
    ap, arming, chans = _setup()
    _enable(ap, arming, chans)
    arming.check(0, True, True, True, False, 1.0, False, 1 << 30)
    ap.on_msp_rc(100, _msp(1500, arm=False), 8, arming)
    reason = ap.on_msp_rc(110, _msp(1500, arm=True), 8, arming)
    assert reason is not None and "throttle" in reason and not arming.armed


def test_arm_switch_off_in_autopilot_mode_disarms_and_withdraws():
    ap, arming, chans = _setup()
    _enable(ap, arming, chans)
    ap.on_msp_rc(100, _msp(), 8, arming)
    ap.on_msp_rc(110, _msp(arm=True), 8, arming)
    assert arming.armed
    _frame(ap, arming, chans, 200, True, False, 5)
    assert not arming.armed and ap.state == AP_WAIT


def test_soft_override_caps_throttle_and_pilot_roll_replaces():
    ap, arming, chans = _setup()
    _enable(ap, arming, chans)
    ap.on_msp_rc(100, _msp(1600, roll_us=1750), 8, arming)
    sp = Setpoint()
    sp.throttle_norm = 0.9  # the pilot's stick: a ceiling above the autopilot
    assert ap.apply(200, sp, [0.0, 0.0, 0.0], 0.9)
    assert abs(sp.throttle_norm - 0.6) < 1e-6 and abs(sp.stick_norm[0] - 0.5) < 1e-6
    sp.throttle_norm = 0.3
    sp.stick_norm[0] = -0.4
    ap.apply(300, sp, [-0.4, 0.0, 0.0], 0.3)
    assert abs(sp.throttle_norm - 0.3) < 1e-6 and abs(sp.stick_norm[0] + 0.4) < 1e-6


def test_hard_override_latches_throttle_until_the_stick_comes_down():
    ap, arming, chans = _setup()
    _enable(ap, arming, chans)
    ap.on_msp_rc(100, _msp(1000, arm=False), 8, arming)
    ap.on_msp_rc(110, _msp(1000, arm=True), 8, arming)
    ap.on_msp_rc(120, _msp(1450), 8, arming)
    _frame(ap, arming, chans, 200, False, True)
    assert ap.state == AP_OFF and arming.armed and ap.privilege() & PRIV_THROTTLE_LATCH
    sp = Setpoint()
    sp.throttle_norm = 0.9
    assert not ap.apply(300, sp, [0.0, 0.0, 0.0], 0.9)
    assert abs(sp.throttle_norm - 0.45) < 1e-6
    sp.throttle_norm = 0.5
    ap.apply(310, sp, [0.0, 0.0, 0.0], 0.44)  # brought down to the latch: released
    assert ap.latch_norm < 0.0
    sp.throttle_norm = 0.8
    ap.apply(320, sp, [0.0, 0.0, 0.0], 0.8)
    assert sp.throttle_norm == 0.8


def test_silent_autopilot_loses_privilege_and_never_holds_its_command():
    ap, arming, chans = _setup()
    _enable(ap, arming, chans)
    ap.on_msp_rc(100, _msp(), 8, arming)
    ap.on_msp_rc(110, _msp(arm=True), 8, arming)
    ap.on_msp_rc(120, _msp(1500, arm=True), 8, arming)
    ap.update(120 + 199000, True)
    assert ap.state == AP_ENABLED
    ap.update(120 + 201000, True)
    assert ap.state == AP_SILENT and not ap.in_control() and ap.latch_norm == 0.5
    assert ap.on_msp_rc(400000, _msp(1500, arm=True), 8, arming) is not None  # no silent take-back
