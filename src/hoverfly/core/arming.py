"""Arming: may the motors spin? Named disable reasons, arm-switch handling, disarm rules.

Each reason is a bit (Betaflight 4.5's numbering for the ones Betaflight has, so MSP
clients read them right; hoverfly's own follow) with a plain-language sentence. The
arm switch arms on its rising edge only when no reason is set; a switch found on at
boot, or on when arming was refused, must be toggled (ARM_SWITCH). Seed 000's rules:
throttle must be low to arm, and the switch must read "disarm" on `disarm_frames`
consecutive frames before a disarm, so one bad frame cannot drop a flying craft.
"""

import math

from hoverfly.compat import const, ticks_diff
from hoverfly.core.events import (
    DISARM_SWITCH,
    EV_ARMED,
    EV_ARMING_BLOCKED,
    EV_DISARMED,
)

NO_GYRO = const(0)
FAILSAFE = const(1)
RX_FAILSAFE = const(2)
NOT_DISARMED = const(3)
BOXFAILSAFE = const(4)
CRASH_DETECTED = const(6)
THROTTLE = const(7)
ANGLE = const(8)
BOOT_GRACE_TIME = const(9)
LOAD = const(11)
CALIBRATING = const(12)
CLI = const(13)
MSP = const(16)
REBOOT_REQUIRED = const(21)
ACC_CALIBRATION = const(23)
MOTOR_PROTOCOL = const(24)
ARM_SWITCH = const(25)
MOTOR_TEST = const(26)
BATTERY_CRITICAL = const(27)
BIT_FAILED = const(28)
MAINTENANCE = const(29)
AUTOPILOT = const(30)

# bit -> (name, sentence). Bits Betaflight 4.5 has keep its names.
REASONS = {
    NO_GYRO: ("NOGYRO", "no gyro: the IMU is missing or has stopped"),
    FAILSAFE: ("FAILSAFE", "failsafe is active"),
    RX_FAILSAFE: ("RXLOSS", "receiver lost: no valid frames"),
    NOT_DISARMED: ("NOT_DISARMED", "disarm first: the craft is still armed by another source"),
    BOXFAILSAFE: ("BOXFAILSAFE", "the failsafe switch is on"),
    CRASH_DETECTED: ("CRASH", "a crash was detected: disarm and re-arm"),
    THROTTLE: ("THROTTLE", "throttle is not low"),
    ANGLE: ("ANGLE", "not level: tilted beyond small_angle"),
    BOOT_GRACE_TIME: ("BOOTGRACE", "still booting"),
    LOAD: ("LOAD", "the flight loop is overrunning (CPU load)"),
    CALIBRATING: ("CALIB", "gyro not calibrated yet: keep the craft still"),
    CLI: ("CLI", "a configuration session (CLI) is open"),
    MSP: ("MSP", "arming disabled over MSP"),
    REBOOT_REQUIRED: ("REBOOT_REQD", "a changed setting needs a reboot"),
    ACC_CALIBRATION: ("NO_ACC_CAL", "accelerometer not calibrated"),
    MOTOR_PROTOCOL: ("MOTOR_PROTO", "no motor protocol configured"),
    ARM_SWITCH: ("ARMSWITCH", "arm switch was on: switch it off, then on"),
    MOTOR_TEST: ("MOTOR_TEST", "motor test is active"),
    BATTERY_CRITICAL: ("BATTERY", "battery critical"),
    BIT_FAILED: ("BIT", "built-in test failed"),
    MAINTENANCE: ("MAINTENANCE", "a maintenance session is open"),
    AUTOPILOT: ("AUTOPILOT", "autopilot mode: only the autopilot may arm"),
}


def reason_names(flags):
    """Names of the set bits, lowest bit first."""
    out = []
    for bit in range(32):
        if flags & (1 << bit):
            out.append(REASONS[bit][0] if bit in REASONS else "BIT%d" % bit)
    return out


def reason_sentences(flags):
    out = []
    for bit in range(32):
        if flags & (1 << bit):
            out.append(REASONS[bit][1] if bit in REASONS else "reason %d" % bit)
    return out


def first_reason(flags):
    for bit in range(32):
        if flags & (1 << bit):
            return bit
    return -1


class Arming:
    def __init__(self, events):
        self.events = events
        self.armed = False
        self.flags = 0  # arming-disable reasons now
        self.extra_flags = 0  # reasons set by other stages (cli, msp, motor test ...)
        self.armed_at_us = 0
        self.boot_us = 0
        self._switch_was_on = False
        self._need_toggle = True  # until the switch has been seen off once
        self._disarm_frames = 0
        self.disarm_frames_needed = 5
        self.small_angle_cos = 0.906
        self.boot_grace_us = 0

    def configure(self, params):
        self.small_angle_cos = math.cos(params.get("small_angle") * math.pi / 180.0)
        self.disarm_frames_needed = params.get("disarm_frames")
        self.boot_grace_us = params.get("boot_grace_ms") * 1000

    def set_flag(self, bit, on):
        if on:
            self.extra_flags |= 1 << bit
        else:
            self.extra_flags &= ~(1 << bit)

    def check(self, now_us, gyro_ok, calibrated, rx_ok, throttle_low, cos_tilt, overloaded):
        """Recompute the disable reasons (slow task)."""
        f = self.extra_flags
        if not gyro_ok:
            f |= 1 << NO_GYRO
        if not calibrated:
            f |= 1 << CALIBRATING
        if not rx_ok:
            f |= 1 << RX_FAILSAFE
        if not throttle_low:
            f |= 1 << THROTTLE
        if cos_tilt < self.small_angle_cos:
            f |= 1 << ANGLE
        if overloaded:
            f |= 1 << LOAD
        if ticks_diff(now_us, self.boot_us) < self.boot_grace_us:
            f |= 1 << BOOT_GRACE_TIME
        if self._need_toggle and self._switch_was_on:
            f |= 1 << ARM_SWITCH
        self.flags = f
        return f

    def on_switch(self, now_us, switch_on):
        """The arm switch as read from one new receiver frame."""
        if switch_on:
            self._disarm_frames = 0
            if not self._switch_was_on and not self.armed:
                self._switch_was_on = True
                if self._need_toggle:
                    return
                blocked = self.flags & ~(1 << ARM_SWITCH)
                if blocked:
                    self._need_toggle = True
                    self.events.record(now_us, EV_ARMING_BLOCKED, first_reason(blocked))
                else:
                    self.arm(now_us)
        else:
            self._switch_was_on = False
            self._need_toggle = False
            if self.armed:
                self._disarm_frames += 1
                if self._disarm_frames >= self.disarm_frames_needed:
                    self.disarm(now_us, DISARM_SWITCH)

    def try_arm(self, now_us):
        """Arm from a source other than the switch (autopilot); returns the blocking flags or 0."""
        blocked = self.flags & ~(1 << ARM_SWITCH)
        if blocked:
            self.events.record(now_us, EV_ARMING_BLOCKED, first_reason(blocked))
            return blocked
        self.arm(now_us)
        return 0

    def arm(self, now_us):
        if not self.armed:
            self.armed = True
            self.armed_at_us = now_us
            self.events.record(now_us, EV_ARMED, 0)

    def disarm(self, now_us, reason):
        if self.armed:
            # SAFETY: the flight pass zeroes the motors on the next pass after this flag drops.
            self.armed = False
            self._disarm_frames = 0
            self._need_toggle = True  # a disarm by anything must be followed by a switch toggle
            if reason == DISARM_SWITCH:
                self._need_toggle = False
            self.events.record(now_us, EV_DISARMED, reason)
