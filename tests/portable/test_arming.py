"""Arming reasons, arm sources, failsafe stages, fault watch and the built-in test (portable)."""

from array import array

from hoverfly.compat import ticks_add
from hoverfly.core.config.params import Params
from hoverfly.core.events import DISARM_FAILSAFE, DISARM_LANDED, EventLog
from hoverfly.core.safety.arming import (
    ARM_SWITCH,
    CLI,
    MAINTENANCE,
    MSP,
    REASONS,
    THROTTLE,
    Arming,
    reason_bit,
    reason_names,
    session_flags,
)
from hoverfly.core.safety.bit import BIT_STORAGE, BuiltInTest
from hoverfly.core.safety.failsafe import (
    FAULT_IMU_FROZEN,
    FAULT_IMU_SATURATED,
    FAULT_NONE,
    IDLE,
    STAGE1,
    STAGE2,
    Failsafe,
    FaultWatch,
)


def _arming(**params):
    p = Params()
    p.set("boot_grace_ms", 0)
    for k in params:
        p.set(k, params[k])
    a = Arming(EventLog())
    a.configure(p)
    return a


def _ok(a, now_us=1000, **bad):
    args = {"gyro_ok": True, "calibrated": True, "rx_ok": True, "throttle_low": True, "cos_tilt": 1.0,
            "overloaded": False, "more": 0}
    for k in bad:
        args[k] = bad[k]
    return a.check(now_us, args["gyro_ok"], args["calibrated"], args["rx_ok"], args["throttle_low"],
                   args["cos_tilt"], args["overloaded"], args["more"])


def test_every_reason_has_a_name_and_a_sentence_and_names_round_trip():
    for bit in REASONS:
        name, sentence = REASONS[bit]
        assert name and sentence
        assert reason_bit(name) == bit


def test_each_check_input_raises_its_reason_and_blocks_the_switch():
    cases = (("gyro_ok", False, "NOGYRO"), ("calibrated", False, "CALIB"), ("rx_ok", False, "RXLOSS"),
             ("throttle_low", False, "THROTTLE"), ("cos_tilt", 0.5, "ANGLE"), ("overloaded", True, "LOAD"))
    for key, value, name in cases:
        a = _arming()
        a.on_switch(0, False)  # seen off once
        bad = {key: value}
        flags = _ok(a, **bad)
        assert reason_names(flags) == [name], (key, reason_names(flags))
        a.on_switch(2000, True)
        assert not a.armed
        assert a.events.event[0] == 2 and a.events.detail[0] == reason_bit(name)


def test_a_craft_left_on_for_twenty_minutes_is_not_still_booting():
    # given the boot grace, when the arming task checks every 10 ms for 20 minutes, then BOOTGRACE holds only for
    # the grace: the tick clock wraps every 2**30 us (about 18 minutes), so the time since boot reads negative from
    # about 9 minutes on and small again at 18; neither may bring "still booting" back
    a = _arming(boot_grace_ms=1000)
    boot = ticks_add(0, -3000000)  # boot 3 s before the clock's wrap, as a CPython run starts its clock
    a.boot_us = boot
    booting_until_ms = -1
    now = boot
    for ms in range(0, 20 * 60 * 1000, 10):  # (a step at a time: ticks_add takes deltas below 2**30 on 32 bits)
        if (1 << reason_bit("BOOTGRACE")) & _ok(a, now_us=now):
            booting_until_ms = ms
        now = ticks_add(now, 10000)
    assert booting_until_ms == 990


def test_sessions_map_to_cli_msp_and_maintenance():
    assert session_flags(1) == 1 << CLI
    assert session_flags(2) == 1 << MSP
    assert session_flags(4) == 1 << MAINTENANCE
    assert session_flags(0) == 0


def test_switch_on_at_boot_must_be_toggled_then_arms():
    a = _arming()
    _ok(a)
    a.on_switch(0, True)
    assert not a.armed
    assert _ok(a) == 1 << ARM_SWITCH
    a.on_switch(10, False)
    _ok(a)
    a.on_switch(20, True)
    assert a.armed


def test_seed000_five_disarm_frames_in_a_row_disarm():
    a = _arming()
    a.on_switch(0, False)
    _ok(a)
    a.on_switch(1, True)
    assert a.armed
    for k in range(4):
        a.on_switch(2 + k, False)
    a.on_switch(7, True)  # one good frame resets the count
    for k in range(4):
        a.on_switch(8 + k, False)
    assert a.armed
    a.on_switch(12, False)
    assert not a.armed


def test_refused_arming_needs_a_toggle():
    a = _arming()
    a.on_switch(0, False)
    _ok(a, throttle_low=False)
    a.on_switch(1, True)
    assert not a.armed
    _ok(a)
    a.on_switch(2, True)
    assert not a.armed  # still on: no new rising edge


def test_try_arm_ignores_the_switch_rule_and_named_reasons_only():
    a = _arming()
    _ok(a, more=1 << 30)  # AUTOPILOT
    assert a.try_arm(5, 1, 0) == 1 << 30
    assert a.try_arm(6, 1, 1 << 30) == 0 and a.armed and a.armed_by == 1
    b = _arming()
    _ok(b, throttle_low=False)
    assert b.try_arm(5, 1, 1 << 30) == 1 << THROTTLE and not b.armed


class _Arm:
    def __init__(self):
        self.armed = True
        self.reason = None

    def disarm(self, now_us, reason):
        self.armed = False
        self.reason = reason


def _failsafe(procedure="land"):
    p = Params()
    p.set("fs_procedure", procedure)
    fs = Failsafe(EventLog())
    fs.configure(p)
    return fs


def test_failsafe_stage_two_is_500_ms_after_the_last_frame():
    fs = _failsafe("drop")
    arm = _Arm()
    last = 1000000
    fs.update(last + 110000, True, last, True, False, arm)
    assert fs.state == STAGE1
    fs.update(last + 490000, True, last, True, False, arm)
    assert fs.state == STAGE1 and arm.armed
    fs.update(last + 500000, True, last, True, False, arm)
    assert fs.state == STAGE2 and not arm.armed and arm.reason == DISARM_FAILSAFE


def test_link_back_ends_stage_one_but_not_stage_two_until_sticks_move():
    fs = _failsafe()
    arm = _Arm()
    fs.update(110000, True, 0, True, False, arm)
    fs.update(120000, False, 115000, True, False, arm)
    assert fs.state == IDLE
    fs.update(700000, True, 150000, True, False, arm)
    fs.update(710000, True, 150000, True, False, arm)
    assert fs.state == STAGE2
    fs.update(720000, False, 715000, True, False, arm)
    assert fs.state == STAGE2
    fs.update(730000, False, 725000, True, True, arm)
    assert fs.state == IDLE


def _landing(fs, arm):
    """A failsafe that learnt a hover throttle of 0.4 in level flight, now in stage 2 (at 500 ms)."""
    q = array("f", [1.0, 0.0, 0.0, 0.0])
    level = array("f", [0.0, 0.0, -9.80665])
    for _ in range(500):
        fs.observe(0.01, q, level, 0.4, 1.0, True)
    fs.update(110000, True, 0, True, False, arm)
    fs.update(500000, True, 0, True, False, arm)
    assert fs.state == STAGE2
    return q


def _slow_passes(fs, arm, q, t_us, seconds, accel_z_m_s2):
    """The 100 Hz task for `seconds`, the accelerometer reading accel_z on every pass; the time at the end."""
    a = array("f", [0.0, 0.0, accel_z_m_s2])
    for _ in range(int(seconds * 100)):
        for _ in range(10):
            fs.note_accel(a)
        t_us += 10000
        fs.observe(0.01, q, a, 0.0, 1.0, True)
        fs.update(t_us, True, 0, arm.armed, False, arm)
        if not arm.armed:
            break
    return t_us


def test_a_touchdown_spike_then_the_ground_holding_the_craft_is_a_landing():
    # given stage 2 landing at 1 m/s, when one 1 ms spike (clipped, as an IMU clips a touchdown) is followed by the
    # craft sitting still although the landing throttle is below hover, then it disarms as landed within 0.4 s
    fs = _failsafe()
    arm = _Arm()
    q = _landing(fs, arm)
    fs.speed_down_m_s = 1.0
    fs.note_accel(array("f", [0.0, 0.0, -150.0]))
    fs.update(800000, True, 0, True, False, arm)
    assert arm.armed  # a spike alone is no landing
    _slow_passes(fs, arm, q, 800000, 0.4, -9.80665)
    assert not arm.armed and arm.reason == DISARM_LANDED


def test_a_spike_in_the_air_followed_by_falling_is_no_landing():
    # given stage 2, when rotor vibration passes the touchdown spike and the craft then accelerates down (in the
    # air, the landing throttle below hover), then it stays armed and its descent estimate gets back what it had
    fs = _failsafe()
    arm = _Arm()
    q = _landing(fs, arm)
    fs.speed_down_m_s = 1.0
    fs.note_accel(array("f", [0.0, 0.0, -40.0]))
    fs.update(800000, True, 0, True, False, arm)
    _slow_passes(fs, arm, q, 800000, 1.0, -9.80665 + 3.0)  # 3 m/s² down
    assert arm.armed
    assert fs.speed_down_m_s > 2.5  # 1 m/s before the spike, and 3 m/s² for a second since


def test_landing_throttle_never_exceeds_1_3_hover_and_descends_when_still():
    fs = _failsafe()
    q = array("f", [1.0, 0.0, 0.0, 0.0])
    level = array("f", [0.0, 0.0, -9.80665])
    for _ in range(500):
        fs.observe(0.01, q, level, 0.4, 1.0, True)
    assert abs(fs.hover_norm - 0.4) < 0.01
    fs.state = STAGE2
    fs.observe(0.01, q, level, 0.0, 1.0, True)
    assert fs.land_throttle_norm < fs.hover_norm  # not sinking yet: ask for less than hover
    fs.speed_down_m_s = 20.0
    fs.observe(0.01, q, level, 0.0, 1.0, True)
    assert fs.land_throttle_norm <= 1.3 * fs.hover_norm + 1e-6


def test_fault_watch_frozen_and_saturated_imu():
    w = FaultWatch()
    g = array("f", [0.01, 0.02, 0.03])
    a = array("f", [0.0, 0.0, -9.8])
    for _ in range(10):  # the first sample is new; nine repeats are not yet a fault
        assert w.check_imu(g, a) == FAULT_NONE
    assert w.check_imu(g, a) == FAULT_IMU_FROZEN
    w.reset_imu()
    for k in range(10):
        g[0] = 35.0 + k * 0.001
        w.check_imu(g, a)
    assert w.imu_fault == FAULT_IMU_SATURATED


def test_crash_on_the_ground_needs_tipped_still_throttle_low_for_the_time():
    w = FaultWatch()
    still = array("f", [0.0, 0.0, 0.0])
    side = array("f", [0.0, 9.8, 0.0])
    assert not w.check_crash(0, True, True, 0.0, still, side)
    assert not w.check_crash(500000, True, True, 0.0, still, side)
    assert w.check_crash(1000000, True, True, 0.0, still, side)
    assert not w.check_crash(1100000, True, False, 0.0, still, side)  # throttle up: flying


def test_bit_names_failing_checks_and_storage_blocks():
    b = BuiltInTest()
    assert b.update(True, True, True, True, True) == 0 and b.names() == []
    b.storage_ok = False
    b.update(False, True, True, True, False)
    assert b.names() == ["imu", "storage", "calibration"]
    assert b.flags & (1 << BIT_STORAGE) and b.blocks_arming()


def test_hover_learning_runs_every_other_call_over_both_calls_time():
    # while the pilot flies, Failsafe.observe learns at 50 Hz from the 100 Hz task: the second call
    # updates over both calls' dt, the first changes nothing
    fs = _failsafe()
    q = array("f", [1.0, 0.0, 0.0, 0.0])
    level = array("f", [0.0, 0.0, -9.80665])
    fs.hover_norm = 0.3
    fs.observe(0.01, q, level, 0.5, 1.0, True)
    assert fs.hover_norm == 0.3
    fs.observe(0.01, q, level, 0.5, 1.0, True)
    assert abs(fs.hover_norm - (0.3 + 0.02 / 2.0 * 0.2)) < 1e-6
    fs.observe(0.01, q, level, 0.5, 1.0, False)  # on the ground: the speed is zero, nothing held over
    fs.observe(0.01, q, level, 0.5, 1.0, True)
    assert fs.speed_down_m_s == 0.0 and abs(fs.hover_norm - 0.302) < 1e-6
