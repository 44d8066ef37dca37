"""Events: arming, disarming, mode changes, failsafe stages — each with a reason code.

A preallocated ring of (time_us, event, detail) integers, so recording one allocates
nothing; hosts (simulator, logs, telemetry) drain it and turn codes into words with
EVENT_NAMES and the detail table of each event.
"""

from array import array

from hoverfly.compat import const

EV_ARMED = const(0)
EV_DISARMED = const(1)
EV_ARMING_BLOCKED = const(2)
EV_MODE = const(3)
EV_RX_LOST = const(4)
EV_RX_RESTORED = const(5)
EV_FAILSAFE_STAGE1 = const(6)
EV_FAILSAFE_STAGE2 = const(7)
EV_LANDED = const(8)
EV_GYRO_CALIBRATED = const(9)
EV_IMU_FAULT = const(10)
EV_CRASH = const(11)
EV_FAILSAFE_END = const(12)
EV_AIRMODE = const(13)
EV_AUTOPILOT_ENABLED = const(14)
EV_AUTOPILOT_OVERRIDE = const(15)
EV_AUTOPILOT_DISABLED = const(16)
EV_OUTPUT_FAILSAFE = const(17)
EV_RPM_LOST = const(18)  # a motor's eRPM telemetry stopped: its RPM-filter notches fade out (detail: motor 1..n)
EV_RPM_RESTORED = const(19)  # ... and came back
EV_LAUNCH = const(20)  # a plane's hand launch: waiting, thrown, motor, ended (core/command/launch.py LAUNCH_EVENTS)

EVENT_NAMES = (
    "armed",
    "disarmed",
    "arming_blocked",
    "mode",
    "rx_lost",
    "rx_restored",
    "failsafe_stage1",
    "failsafe_stage2",
    "landed",
    "gyro_calibrated",
    "imu_fault",
    "crash",
    "failsafe_end",
    "airmode",
    "autopilot_enabled",
    "autopilot_override",
    "autopilot_disabled",
    "output_failsafe",
    "rpm_lost",
    "rpm_restored",
    "launch",
)

# Why a disarm happened (detail of EV_DISARMED).
DISARM_SWITCH = const(0)
DISARM_FAILSAFE = const(1)
DISARM_LANDED = const(2)
DISARM_CRASH = const(3)
DISARM_IMU = const(4)
DISARM_COMMAND = const(5)  # an MSP command: the autopilot's arm channel off
DISARM_LOAD = const(6)  # loop overrun storm while armed
DISARM_FS_SWITCH = const(7)  # the failsafe switch (AUX fs_switch_ch) in kill mode
DISARM_REASONS = ("switch", "failsafe", "landed", "crash", "imu_fault", "command", "load", "fs_switch")


class EventLog:
    def __init__(self, size=64):
        self.size = size
        self.t_us = array("l", [0] * size)
        self.event = array("h", [0] * size)
        self.detail = array("l", [0] * size)
        self.head = 0  # next write
        self.count = 0  # total ever recorded
        self.dropped = 0

    def record(self, t_us, event, detail=0):
        i = self.head
        self.t_us[i] = t_us
        self.event[i] = event
        self.detail[i] = detail
        i += 1
        if i >= self.size:
            i = 0
        self.head = i
        self.count += 1

    def drain(self, since_count, fn):
        """Call fn(t_us, event, detail) for events recorded after `since_count`; returns the new count."""
        missed = self.count - since_count
        if missed > self.size:
            self.dropped += missed - self.size
            since_count = self.count - self.size
        n = self.count - since_count
        start = self.head - n
        if start < 0:
            start += self.size
        for k in range(n):
            i = start + k
            if i >= self.size:
                i -= self.size
            fn(self.t_us[i], self.event[i], self.detail[i])
        return self.count
