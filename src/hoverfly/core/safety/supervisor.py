"""The supervisor: may the craft fly? Arming, the 100 Hz safety task, the failsafe's stages, the battery.

Beside the pass, not in it. core/safety/arming.py holds the rules (the reasons, the arm sources, the disarm rule);
this stage feeds them and makes every arming decision that is not the pilot's switch or the autopilot's
request: it disarms for an IMU fault, a crash, a loop overload or the failsafe switch, works the arming
reasons out (every 100 Hz run while disarmed, again at once after a disarm and at an arm request), runs
the failsafe's stages from the link watch and the failsafe switch, and watches the battery. Takes its
inputs from the signals and the stages it is wired to; the flight loop (`flight`) gives it the link state
(rx_ok, last_frame_us, fs_switch: the receiver task's), the configuration sessions (config_session, the
links'), the last IMU sample's time, and the restarts only the loop can do (estimation, configure).
"""

from hoverfly.compat import ticks_diff
from hoverfly.core.command.autopilot import AP_ENABLED
from hoverfly.core.config.params import FS_SWITCH_MODES
from hoverfly.core.events import DISARM_CRASH, DISARM_FS_SWITCH, DISARM_IMU, DISARM_LOAD, EV_CRASH, EV_IMU_FAULT
from hoverfly.core.safety.arming import (
    AUTOPILOT,
    BATTERY_CRITICAL,
    BIT_FAILED,
    BOXFAILSAFE,
    CRASH_DETECTED,
    FAILSAFE,
    MOTOR_TEST,
    RPMFILTER,
    session_flags,
)
from hoverfly.core.safety.failsafe import (
    CAUSE_NO_FRAMES,
    CAUSE_SWITCH,
    FAULT_IMU_NONFINITE,
    FAULT_NONE,
    IDLE,
    SWITCH_STAGE2,
)
from hoverfly.core.scheduler import PS_PASSES


class Supervisor:
    def __init__(self, flight):
        self.flight = flight
        self.board = flight.board
        self.signals = flight.signals
        self.events = flight.events
        self.rc = flight.rc
        self.arming = flight.arming
        self.failsafe = flight.failsafe
        self.faults = flight.faults
        self.bit = flight.bit
        self.autopilot = flight.autopilot
        self.motor_test = flight.motor_test
        self.calibration = flight.calibration
        self.commander = flight.commander
        self.scheduler = flight.scheduler
        self.params = flight.params
        # The disable reasons again the moment it disarms, and at an arm request as they stand at that frame.
        self.arming.on_reasons = self.reasons_now
        self.imu_ok = True
        self.overloaded = False
        self.battery_cells = 0  # detected from the first voltage read (4.3 V per cell at most)
        self.fs_switch_mode = 0  # FS_SWITCH_MODES: what the failsafe switch does (kill, stage1, stage2)
        self._vbat_min_cell_v = 3.3
        self._imu_stale_us = 20000
        self._last_us = 0  # task()'s last run
        self._crash_latched = False
        self._task_broken = False  # task() raised on its last run (task_failed): BIT blocks arming
        # params.changed and config_session as _config_check saw them last: a change of either since is a
        # configuration change (arming's toggle rule).
        self._changed_seen = -1
        self._session_seen = 0

    def configure(self, params):
        self.arming.configure(params)
        self.failsafe.configure(params)
        self.faults.configure(params)
        self._vbat_min_cell_v = params.get("vbat_min_cell")
        self._imu_stale_us = params.get("imu_stale_ms") * 1000
        self.fs_switch_mode = FS_SWITCH_MODES.index(params.get("fs_switch_mode"))

    # ------------------------------------------------------- the receiver task
    def on_frame(self, now_us, fs_kill):
        """A new pilot frame taken (the failsafe switch off, or in kill mode): the failsafe switch's kill, and the
        arm switch."""
        arming = self.arming
        if fs_kill:
            # SAFETY: failsafe switch, kill: disarm on this frame; BOXFAILSAFE blocks the arm
            # switch from this frame on (task() keeps it while the switch stays on).
            arming.disarm(now_us, DISARM_FS_SWITCH)
            arming.flags |= 1 << BOXFAILSAFE
        if self.failsafe.state == IDLE:
            arming.on_switch(now_us, self.rc.arm_switch)

    # ------------------------------------------------------------- 100 Hz task
    def task(self, now_us):
        """Faults, built-in test, arming reasons, failsafe stages; then the commander's slow part (100 Hz)."""
        f = self.flight
        s = self.signals
        rc = self.rc
        arming = self.arming
        fw = self.faults
        ap = self.autopilot
        fs = self.failsafe
        dt_s = ticks_diff(now_us, self._last_us) * 1e-6
        self._last_us = now_us
        if dt_s < 0.0 or dt_s > 0.1:
            dt_s = 0.01
        armed = arming.armed
        # IMU: no new samples for imu_stale_ms, or new samples frozen, saturated or not finite
        # 0 <=: a sample more than half the tick period old (about 9 minutes) reads negative, and is stale
        imu_ok = 0 <= ticks_diff(now_us, f.imu_us) <= self._imu_stale_us
        fault = fw.check_imu(s.gyro_raw_rad_s, s.accel_raw_m_s2) if imu_ok else FAULT_NONE
        if fault == FAULT_NONE and imu_ok and not f.state_finite():
            fault = FAULT_IMU_NONFINITE  # a bad sample between two checks, held in the filters' state
        if fault != FAULT_NONE:
            imu_ok = False
        if self.imu_ok and not imu_ok:
            self.events.record(now_us, EV_IMU_FAULT, fault)
            # SAFETY: no attitude without the IMU: nothing can fly or land it, so stop the motors.
            arming.disarm(now_us, DISARM_IMU)
        if fault == FAULT_IMU_NONFINITE or (imu_ok and not self.imu_ok and fw.fault_before != FAULT_NONE):
            # A NaN or inf left in the filters, estimator or controller would stay there: they start again
            # (while the values are not finite, and once the fault clears), disarmed by then.
            f.restart_estimation()
        fw.fault_before = fault
        self.imu_ok = imu_ok
        if self.params.changed != self._changed_seen or f.config_session != self._session_seen:
            self._config_check()
        self.bit.tasks_ok = self.scheduler.errors == 0  # every boundary counts there (Scheduler.caught, Logger)
        # loop rate: a storm of overruns while armed disarms; any overrun blocks arming (LOAD)
        sched = self.scheduler
        if fw.check_load(now_us, sched.stats[PS_PASSES], sched.overruns, armed):
            arming.disarm(now_us, DISARM_LOAD)
        self.overloaded = fw.overloaded
        # whose throttle counts: the autopilot's when it holds the privilege (the pilot's is its cap)
        throttle_low = ap.throttle_low() if ap.state == AP_ENABLED else rc.throttle_low()
        if fw.check_crash(now_us, arming.armed, throttle_low, s.attitude.cos_tilt, s.gyro_rad_s, s.accel_m_s2):
            self.events.record(now_us, EV_CRASH, 0)
            arming.disarm(now_us, DISARM_CRASH)
            self._crash_latched = True
        if self._crash_latched and not rc.arm_switch:
            self._crash_latched = False
        battery_ok = self._battery_ok(s.battery_v)
        self.bit.update(imu_ok, f.rx_ok, not self.overloaded, battery_ok, self.calibration.calibrated)
        if not arming.armed:
            # As Betaflight: the disable reasons are worked out only while disarmed (armed, nothing reads
            # them to decide anything), and at once on a disarm (Arming.on_reasons), so an arm request right
            # after a disarm never meets the reasons of before the arming.
            self._arming_flags(now_us, throttle_low, battery_ok)
        fs.observe(dt_s, s.attitude.q, s.accel_m_s2, s.setpoint.throttle_norm, s.attitude.cos_tilt,
                   arming.armed and self.commander.throttle_was_up)
        # The failsafe switch in stage2 mode: lost from the first dropped frame, straight to stage 2.
        switch_stage2 = f.fs_switch and self.fs_switch_mode == SWITCH_STAGE2
        link_lost = not f.rx_ok or switch_stage2
        # With no failsafe running and the link up (the usual call) Failsafe.update changes nothing.
        if link_lost or fs.state != IDLE:
            sticks_moved = (abs(rc.stick_raw[0]) > 0.3 or abs(rc.stick_raw[1]) > 0.3)
            fs.update(now_us, link_lost, f.last_frame_us, arming.armed, sticks_moved, arming,
                      CAUSE_SWITCH if f.fs_switch else CAUSE_NO_FRAMES, switch_stage2)
        self.commander.task(now_us, arming.armed, s.attitude.yaw_rad)
        if not arming.armed:
            f.configure_if_changed()
        self._task_broken = False  # ran through

    def task_failed(self, task, exc):
        """Scheduler.on_error: a task raised. SAFETY: the arming task's reasons are not to be trusted after it
        raised part-way: an arm request meets BIT until it runs through again."""
        if task.name == "arming":
            self._task_broken = True
            self.arming.flags |= 1 << BIT_FAILED

    # --------------------------------------------------------- arming reasons
    def _config_check(self):
        """Parameters, mode ranges or sessions changed since the last look (any surface: CLI, MSP, maintenance,
        storage; two int compares): the arm switch must be toggled (Arming.config_changed). True if they did."""
        changed = self.params.changed
        session = self.flight.config_session
        if changed == self._changed_seen and session == self._session_seen:
            return False
        self._changed_seen = changed
        self._session_seen = session
        self.arming.config_changed()
        return True

    def reasons_now(self, now_us, request):
        """Arming.on_reasons: after a disarm (request False), and at an arm request before it is decided."""
        if request:
            self._arm_request(now_us)
        else:
            self._flags_on_disarm(now_us)

    def _arm_request(self, now_us):
        """An arm request (the switch's rising edge, the autopilot's try_arm) meets the reasons as they stand at
        this frame, not the 100 Hz task's of up to 10 ms ago (seed 000's throttle rule when throttle and switch
        move together); a configuration change not yet looked at, or not yet applied (configure runs in the
        100 Hz task), needs the switch toggled. The reasons the 100 Hz task found stay: this only adds (a link
        restored by this very frame still counts as lost until the task has seen it)."""
        arming = self.arming
        before = arming.flags
        self._config_check()
        if self.flight.configure_pending():
            arming.config_changed()
        self._flags_on_disarm(now_us)
        arming.flags |= before

    def _flags_on_disarm(self, now_us):
        """The reasons from the state at a disarm (the 100 Hz task's are from before it)."""
        ap = self.autopilot
        throttle_low = ap.throttle_low() if ap.state == AP_ENABLED else self.rc.throttle_low()
        self._arming_flags(now_us, throttle_low, self._battery_ok(self.signals.battery_v))

    def _arming_flags(self, now_us, throttle_low, battery_ok):
        """The arming-disable reasons now (Arming.check, with the reasons of the stages it does not see)."""
        f = self.flight
        more = session_flags(f.config_session)
        if self.motor_test.active:
            more |= 1 << MOTOR_TEST
        if not battery_ok:
            more |= 1 << BATTERY_CRITICAL
        if self.bit.blocks_arming() or self._task_broken:
            more |= 1 << BIT_FAILED
        if self.failsafe.state != IDLE:
            more |= 1 << FAILSAFE
        if f.fs_switch:
            more |= 1 << BOXFAILSAFE
        if self._crash_latched:
            more |= 1 << CRASH_DETECTED
        if self.autopilot.switch_on():
            more |= 1 << AUTOPILOT
        rpm = f.rpm_filter
        if rpm is not None and (rpm.refused or rpm.lost):  # Betaflight's RPMFILTER: it cannot see the motors
            more |= 1 << RPMFILTER
        self.arming.check(now_us, self.imu_ok, self.calibration.calibrated, f.rx_ok, throttle_low,
                          self.signals.attitude.cos_tilt, self.overloaded, more)

    # ---------------------------------------------------------------- battery
    def task_battery(self, now_us):
        """50 Hz: the board's battery reading into the signals (task() judges it), and a plane's pitot: the
        airspeed is for the links and the log, so it is read here at its sensor's rate, never in the pass."""
        s = self.signals
        self.board.read_battery(s)
        v = self.board.read_airspeed()
        if v is None:
            s.airspeed_valid = False
        else:
            s.airspeed_m_s = v
            s.airspeed_valid = True

    def _battery_ok(self, battery_v):
        """False below vbat_min_cell per cell; True when off or not measured."""
        if self._vbat_min_cell_v <= 0.0 or battery_v < 1.0:
            return True
        if self.battery_cells == 0:
            self.battery_cells = int(battery_v / 4.3) + 1
        return battery_v >= self._vbat_min_cell_v * self.battery_cells
