"""Arming: may the motors spin? Named disable reasons, arm sources, disarm rules.

Takes the state of every stage once per slow-task pass (`check`) and each new arm-switch
reading (`on_switch`); gives `armed`, the disable-reason bitfield `flags` and an event for
every decision. Sits beside the pass: the outputs stage reads `armed` as its last word.

Each reason is a bit (Betaflight 4.5's numbering for the ones Betaflight has, so MSP
clients read them right; hoverfly's own follow from 26) with a plain-language sentence.
Arm sources:
- the pilot's arm switch (`arm_source` = range: AUX `arm_ch` inside arm_min_us..arm_max_us;
  seed001: channel `arm_ch` above 1500 µs, seed 001's rule). The switch arms on its rising
  edge only when no reason is set; a switch found on at boot, or on when arming was refused,
  must be toggled (ARM_SWITCH), and so must one that reads on after a configuration change
  (`config_changed`: Betaflight's rule, a switch moved under by a new ARM range must be seen off first);
- the autopilot over MSP (seed 004), through `try_arm` with the autopilot's own throttle,
  only when the enabling procedure allows it (core/command/autopilot.py decides).
An arm request meets the reasons as they stand at that frame: on the switch's rising edge (and
in try_arm) `on_reasons` lets the flight work them out again first (adding to the slow task's, never
clearing one), so a throttle raised in the same frame as the switch is refused (THROTTLE), not met by
the slow task's flags of up to 10 ms ago.
Seed 000's rules hold for every source: throttle must be low to arm, and the switch must read
"disarm" on `disarm_frames` consecutive frames before a disarm, so one bad frame cannot drop
a flying craft (the receiver keeps the last good values on an invalid frame).
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
RPMFILTER = const(20)
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
    CRASH_DETECTED: ("CRASH", "a crash was detected: switch the arm switch off"),
    THROTTLE: ("THROTTLE", "throttle is not low"),
    ANGLE: ("ANGLE", "not level: tilted beyond small_angle"),
    BOOT_GRACE_TIME: ("BOOTGRACE", "still booting"),
    LOAD: ("LOAD", "the flight loop is overrunning (CPU load)"),
    CALIBRATING: ("CALIB", "gyro not calibrated yet: keep the craft still"),
    CLI: ("CLI", "a configuration session (CLI) is open"),
    MSP: ("MSP", "a configurator (MSP) session is open, or arming was disabled over MSP"),
    RPMFILTER: ("RPMFILTER", "RPM filter on (rpm_harmonics) but a motor's eRPM is missing: dshot_bidir off, or an ESC "
                             "not answering"),
    REBOOT_REQUIRED: ("REBOOT_REQD", "a changed setting needs a reboot"),
    ACC_CALIBRATION: ("NO_ACC_CAL", "accelerometer not calibrated"),
    MOTOR_PROTOCOL: ("MOTOR_PROTO", "no motor protocol configured"),
    ARM_SWITCH: ("ARMSWITCH", "arm switch was on: switch it off, then on"),
    MOTOR_TEST: ("MOTOR_TEST", "motor test is active"),
    BATTERY_CRITICAL: ("BATTERY", "battery critical: below vbat_min_cell per cell"),
    BIT_FAILED: ("BIT", "built-in test failed (see the BIT status)"),
    MAINTENANCE: ("MAINTENANCE", "a maintenance session is open"),
    AUTOPILOT: ("AUTOPILOT", "autopilot mode: only the autopilot may arm"),
}

# flight.config_session bits (set by the configuration links) -> the reason each one raises.
SESSION_CLI = const(1)
SESSION_MSP = const(2)
SESSION_MAINTENANCE = const(4)
SESSION_MAINTENANCE_USB = const(8)  # a second maintenance session, on the config (USB) port

# Who armed (detail of the `armed` event).
SOURCE_SWITCH = const(0)
SOURCE_AUTOPILOT = const(1)
SOURCE_NAMES = ("switch", "autopilot")

ARM_SOURCES = ("range", "seed001")


def session_flags(config_session):
    """Disable bits for an open configuration session bitmask (1 CLI, 2 MSP, 4 maintenance)."""
    f = 0
    if config_session & SESSION_CLI:
        f |= 1 << CLI
    if config_session & SESSION_MSP:
        f |= 1 << MSP
    if config_session & (SESSION_MAINTENANCE | SESSION_MAINTENANCE_USB):
        f |= 1 << MAINTENANCE
    return f


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


def reason_bit(name):
    """The bit of a reason name (as REASONS spells it), or -1."""
    for bit in REASONS:
        if REASONS[bit][0] == name:
            return bit
    return -1


class Arming:
    def __init__(self, events):
        self.events = events
        self.armed = False
        self.armed_by = SOURCE_SWITCH
        self.flags = 0  # arming-disable reasons now
        self.extra_flags = 0  # reasons set by other stages through set_flag (MSP_SET_ARMING_DISABLED ...)
        self.armed_at_us = 0
        self.boot_us = 0
        self.gate = None  # an object with pilot_may_arm() (the autopilot): False = the switch may not arm
        # Called with (now_us, request) right after a disarm (request False) and on an arm request before it is
        # decided (True): Flight works the reasons out again. (One hook, not two: the pass reads `armed` in this
        # table, 16 of 17 slots.)
        self.on_reasons = None
        self._switch_was_on = False
        self._need_toggle = True  # until the switch has been seen off once
        self._disarm_frames = 0
        self.disarm_frames_needed = 5
        self.small_angle_cos = 0.906
        self.boot_grace_us = 0
        self.booting = True  # until boot_grace_us has passed once (see check)
        self.source = ARM_SOURCES[0]

    def configure(self, params):
        self.small_angle_cos = math.cos(params.get("small_angle") * math.pi / 180.0)
        self.disarm_frames_needed = params.get("disarm_frames")
        self.boot_grace_us = params.get("boot_grace_ms") * 1000
        self.source = params.get("arm_source")

    def config_changed(self):
        """Parameters, mode ranges or a session changed: SAFETY: a switch that reads on now (perhaps only because
        its range moved under it) must be seen off before it arms. A switch that is off loses nothing: its
        next frame clears this again."""
        if not self.armed:
            self._need_toggle = True

    def set_flag(self, bit, on):
        if on:
            self.extra_flags |= 1 << bit
        else:
            self.extra_flags &= ~(1 << bit)

    def check(self, now_us, gyro_ok, calibrated, rx_ok, throttle_low, cos_tilt, overloaded, more=0):
        """Recompute the disable reasons (slow task). `more`: bits the caller computed (sessions,
        motor test, battery, BIT, failsafe, crash, autopilot)."""
        f = self.extra_flags | more
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
        if self.booting:
            # Latched over once passed: the tick clock wraps every 2**30 us, so after about 9 minutes the time
            # since boot would read negative again, and a craft left on that long would be "still booting".
            if ticks_diff(now_us, self.boot_us) < self.boot_grace_us:
                f |= 1 << BOOT_GRACE_TIME
            else:
                self.booting = False
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
                if self.on_reasons is not None:
                    # SAFETY: the reasons as they stand at this frame (the slow task's may be 10 ms old);
                    # a configuration change it finds sets _need_toggle. (No local for the hook: this frame
                    # stays at 11 words, on the C stack, at every frame; tests/test_perf_rules.py.)
                    self.on_reasons(now_us, True)
                    if self._need_toggle:
                        return
                gate = self.gate
                if gate is not None and not gate.pilot_may_arm():
                    # Seed 004: in autopilot mode the switch grants the autopilot its privilege
                    # instead of arming; the autopilot records that. Not a refusal.
                    return
                blocked = self.flags & ~(1 << ARM_SWITCH)
                if blocked:
                    self._need_toggle = True
                    self.events.record(now_us, EV_ARMING_BLOCKED, first_reason(blocked))
                else:
                    self.arm(now_us, SOURCE_SWITCH)
        else:
            self._switch_was_on = False
            self._need_toggle = False
            if self.armed:
                self._disarm_frames += 1
                if self._disarm_frames >= self.disarm_frames_needed:
                    self.disarm(now_us, DISARM_SWITCH)

    def try_arm(self, now_us, source=SOURCE_AUTOPILOT, ignore=0):
        """Arm from a source other than the switch; returns the blocking flags (0 = armed).

        `ignore`: reasons that do not apply to this source (the autopilot passes AUTOPILOT).
        ARM_SWITCH never applies: it is the switch's own toggle rule."""
        if self.armed:
            return 0
        if self.on_reasons is not None:
            self.on_reasons(now_us, True)  # SAFETY: the reasons as they stand now, as for the switch
        blocked = self.flags & ~((1 << ARM_SWITCH) | ignore)
        if blocked:
            self.events.record(now_us, EV_ARMING_BLOCKED, first_reason(blocked))
            return blocked
        self.arm(now_us, source)
        return 0

    def arm(self, now_us, source=SOURCE_SWITCH):
        if not self.armed:
            self.armed = True
            self.armed_by = source
            self.armed_at_us = now_us
            self._disarm_frames = 0
            self.events.record(now_us, EV_ARMED, source)

    def disarm(self, now_us, reason):
        if self.armed:
            # SAFETY: the flight pass zeroes the motors on the next pass after this flag drops.
            self.armed = False
            self._disarm_frames = 0
            self._need_toggle = True  # a disarm by anything must be followed by a switch toggle
            if reason == DISARM_SWITCH:
                self._need_toggle = False
            self.events.record(now_us, EV_DISARMED, reason)
            if self.on_reasons is not None:
                self.on_reasons(now_us, False)
