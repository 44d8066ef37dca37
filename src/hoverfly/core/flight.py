"""The flight pass: IMU -> filters -> estimator -> commander -> controller -> mixer -> outputs.

`Flight.step(now_us)` runs one pass at the loop rate and then the slow tasks that are
due (receiver, arming, failsafe, battery, LED). Stages are built once; `configure()`
reads the parameters into every stage (again whenever they change while disarmed).
"""

from array import array

from hoverfly.compat import attr_room, const, ticks_diff
from hoverfly.core.arming import (
    AUTOPILOT,
    BATTERY_CRITICAL,
    BIT_FAILED,
    BOXFAILSAFE,
    CRASH_DETECTED,
    FAILSAFE,
    MOTOR_TEST,
    Arming,
    session_flags,
)
from hoverfly.core.autopilot import AP_ENABLED, Autopilot
from hoverfly.core.bit import BuiltInTest
from hoverfly.core.control import MODE_ANGLE, Controller
from hoverfly.core.estimator import BoardAlignment, ExternalAttitude, GyroCalibration, Mahony
from hoverfly.core.events import (
    DISARM_CRASH,
    DISARM_FS_SWITCH,
    DISARM_IMU,
    DISARM_LOAD,
    EV_AIRMODE,
    EV_CRASH,
    EV_GYRO_CALIBRATED,
    EV_IMU_FAULT,
    EV_MODE,
    EV_RX_LOST,
    EV_RX_RESTORED,
    EventLog,
)
from hoverfly.core.failsafe import (
    CAUSE_NO_FRAMES,
    CAUSE_SWITCH,
    FAULT_IMU_NONFINITE,
    FAULT_NONE,
    IDLE,
    PROC_DROP,
    PROC_GLIDE,
    PROC_LAND,
    STAGE2,
    SWITCH_KILL,
    SWITCH_STAGE2,
    Failsafe,
    FaultWatch,
)
from hoverfly.core.filters import AccelFilter, GyroFilter
from hoverfly.core.fixedatt import HAS_ACCEL as _FIXED_ATT_ACCEL
from hoverfly.core.fixedatt import FixedAttitude
from hoverfly.core.fixedimu import HAS_ACCEL as _FIXED_IMU_ACCEL
from hoverfly.core.fixedimu import FixedImuFilter
from hoverfly.core.fixedrate import FixedRate
from hoverfly.core.logger import Logger
from hoverfly.core.mixer import Mixer
from hoverfly.core.motortest import MotorTest
from hoverfly.core.output import HAS_ACCEL as _FIXED_OUT_ACCEL
from hoverfly.core.output import OutputStage
from hoverfly.core.params import FS_SWITCH_MODES, Params
from hoverfly.core.rc import RcInput
from hoverfly.core.receiver import Receiver
from hoverfly.core.scheduler import PS_PASSES, Scheduler
from hoverfly.core.scheduler import fast_pass_stats as _pass_stats
from hoverfly.core.signals import Signals

# With no log running, the fixed controller writes its PID terms and torques out every this many passes
# (the maintenance telemetry reads them: at 1 kHz, at most 8 ms old).
TERMS_IDLE_PASSES = const(8)


class Flight:
    def __init__(self, board, params=None):
        self.board = board
        self.params = params if params is not None else Params()
        self.signals = Signals()
        self._sp = self.signals.setpoint  # step's: a look-up a pass fewer each (Signals never replaces them)
        self._attitude = self.signals.attitude
        self.events = EventLog()
        self.alignment = BoardAlignment()
        self.calibration = GyroCalibration()
        self.gyro_filter = GyroFilter()
        self.accel_filter = AccelFilter()
        self.mahony = Mahony()
        self.external = ExternalAttitude()
        self.rc = RcInput()
        self.receiver = Receiver()
        self.controller = Controller(self.signals.pid_terms)
        self.mixer = Mixer()
        self.fixed = FixedRate()  # the controller and mixer in fixed point (pid_math)
        self._fixed_on = False
        self.fixed_imu = FixedImuFilter()  # the IMU filters in fixed point, with the fixed rate loop
        self._fixed_imu_on = False
        self._fixed_out_on = False  # the output stage's motor commands in fixed point, likewise
        self._out_more = False  # a yaw servo or bidirectional DShot: _outputs has more to do (configure)
        self.fixed_att = FixedAttitude()  # the estimator (Mahony) in fixed point, likewise
        self._fixed_att_on = False
        self.output = OutputStage()
        self.arming = Arming(self.events)
        self.motor_test = MotorTest(self.arming)
        self.failsafe = Failsafe(self.events)
        self.faults = FaultWatch()
        self.autopilot = Autopilot(self.events)
        self.autopilot.pilot_channels = self.signals.rc_channels_us
        self.arming.gate = self.autopilot  # in autopilot mode the pilot's switch does not arm
        # The disable reasons again the moment it disarms, and at an arm request as they stand at that frame.
        self.arming.on_reasons = self._reasons_now
        self._pilot_only = True  # command()'s short way (_who_flies)
        self.bit = BuiltInTest()
        self.config_session = 0  # 1 CLI, 2 MSP configurator, 4 maintenance, 8 maintenance on USB: any set blocks arming
        # params.changed and config_session as _config_check saw them last: a change of either since is a
        # configuration change (arming's toggle rule). Held in one list: the pass reads this instance's
        # attribute table, which compat.attr_room sizes, so it gains no attributes the pass does not need.
        self._config_seen = [-1, 0]
        self._arming_broken = False  # the arming task raised on its last run (_task_failed): BIT blocks arming
        self._arming_us = 0
        self._crash_latched = False
        self._vbat_min_cell_v = 3.3
        self.battery_cells = 0  # detected from the first voltage read (4.3 V per cell at most)
        self.scheduler = Scheduler()
        self._pass_words = self.scheduler.stats
        self.loop_hz = 1000
        self.motor_count = 4
        self.idle = 0.055
        self.motor_max = 1.0
        self._configured_at = -1
        self._last_us = 0
        self.imu_us = 0
        self._imu_stale_us = 20000
        self.imu_ok = True
        self.rx_ok = False
        self.last_frame_us = 0
        self._rx_timeout_us = 100000
        self._airmode_thr = 0.25
        self.airmode_active = False
        self.airmode_enabled = True  # the airmode parameter, or the AIRMODE switch when airmode_ch is set
        self.fs_switch = False  # the failsafe switch as read from the latest frame
        self._fs_switch_mode = 0
        self.i_active = False
        self._throttle_was_up = False
        self._mode = -1
        self._use_external = False
        self._first_imu = True
        self._imu_prepare = True  # _route() sets these two from the above
        self._att_fixed_now = False
        # The estimator every _att_every passes (att_rate_hz), fed the gyro averaged since its last
        # update: the passes counted, their gyro summed (a list: reading it back boxes nothing on
        # MicroPython) and their ticks summed (an int: no float a pass).
        self._att_every = 1
        self._att_n = 0
        self._att_sum = [0.0, 0.0, 0.0]
        self._att_us = 0
        self._att_gyro = array("f", [0.0, 0.0, 0.0])
        self.overloaded = False
        self.pass_us = 0
        self.pass_dt_us = 0  # ticks from the previous pass to this one (the logger's clock)
        self.scheduler.add("rx", 500, self.task_rx)
        self.scheduler.add("arming", 100, self.task_arming)
        self.scheduler.add("battery", 50, self.task_battery)
        self.scheduler.add("led", 10, self.task_led)
        self.scheduler.on_error = self._task_failed
        # Flight log: called last in every pass while a sink is open (not a task: a task due every
        # pass costs more to dispatch than the logging it runs; bench/log_loop.py).
        self.logger = Logger(self)

    # ----------------------------------------------------------------- set-up
    def configure(self):
        p = self.params
        self.loop_hz = p.get("loop_hz")
        hz = self.loop_hz
        self.alignment.configure(p)
        self.calibration.configure(p, hz)
        self.fixed_imu.release()  # the float filters hold the state while they are configured
        self.gyro_filter.configure(p, hz)
        self.accel_filter.configure(p, hz)
        self.mahony.configure(p)
        self._use_external = p.get("estimator") == "external"
        every = hz // p.get("att_rate_hz")
        self._att_every = every if every > 1 else 1
        self._att_restart()
        self.rc.configure(p, hz)
        self.receiver.configure(p)
        self.controller.configure(p, hz)
        self.mixer.configure(p)
        self._fixed_on = self.fixed.configure(self.controller, self.mixer, hz, p.get("pid_math"), self.signals)
        self.logging_changed()
        # The IMU filters go with the rate loop: anywhere for "fixed", on "auto" where their viper twin loads.
        self._fixed_imu_on = self.fixed_imu.configure(
            self.gyro_filter, self.accel_filter, self.signals, self.calibration.bias_rad_s,
            self._fixed_on and (p.get("pid_math") == "fixed" or _FIXED_IMU_ACCEL))
        self._fixed_out_on = self._fixed_on and (p.get("pid_math") == "fixed" or _FIXED_OUT_ACCEL)
        self._fixed_att_on = self.fixed_att.configure(
            self.mahony, self.signals.attitude, self.signals, hz, self._att_every,
            self._fixed_on and (p.get("pid_math") == "fixed" or _FIXED_ATT_ACCEL))
        self.motor_count = self.mixer.n
        self.arming.configure(p)
        if p.get("arm_source") == "seed001":
            # Seed 001: the arm channel above 1500 µs arms (the range rule, with no upper end).
            self.rc.set_arm_range(p.get("arm_ch"), 1501, 0x10000)
        self.failsafe.configure(p)
        self.faults.configure(p)
        self.autopilot.configure(p)
        self._vbat_min_cell_v = p.get("vbat_min_cell")
        self.logger.configure(p)
        self.idle = p.get("motor_idle_pct") * 0.01
        self.motor_max = p.get("motor_max_pct") * 0.01
        servo_count = 1 if self.mixer.servo_yaw else 0
        self.output.configure(p, self.motor_count)
        self.motor_test.configure(p, self.motor_count)
        self.board.configure_outputs(p, self.motor_count, servo_count)
        self._out_more = self.mixer.servo_yaw or self.output.bidir  # _outputs: a servo, or ESC replies
        self._imu_stale_us = p.get("imu_stale_ms") * 1000
        self._rx_timeout_us = p.get("rx_timeout_ms") * 1000
        self._airmode_thr = p.get("airmode_thr_pct") * 0.01
        self._fs_switch_mode = FS_SWITCH_MODES.index(p.get("fs_switch_mode"))
        self._airmode_from_switch()
        self._route()
        self._configured_at = p.changed

    def logging_changed(self):
        """The logger started or stopped its every-pass calls (Logger._hand_over; and configure): the fixed
        controller writes its PID terms and torques out every pass while a log runs, else every
        TERMS_IDLE_PASSES passes, for the maintenance telemetry that reads them (about 3k instructions
        a pass on MicroPython when written every pass)."""
        self.fixed.terms_every(1 if self.log_pass is not None else TERMS_IDLE_PASSES)

    def _att_restart(self):
        """The estimator's gyro average starts again (after an update, or a new att_rate_hz)."""
        self._att_n = 0
        acc = self._att_sum
        acc[0] = acc[1] = acc[2] = 0.0
        self._att_us = 0

    def start(self, now_us):
        """Boot: configure, start the clocks and the gyro calibration."""
        self.bit.params_ok = self.params.latch_boot()  # REBOOT rows written from here wait for a reboot
        self.configure()
        self._last_us = now_us
        self.imu_us = now_us
        self.last_frame_us = now_us
        self.receiver.start(now_us)
        self.arming.boot_us = now_us
        self.calibration.reset()
        self._route()  # the calibration runs again: the pass feeds it
        self.scheduler.start(now_us, self.loop_hz)
        self.logger.start(now_us)
        attr_room(self)  # MicroPython: the pass's many look-ups here, in a table with room (compat.attr_room)

    # ------------------------------------------------------------------ the pass
    def step(self, now_us):
        # The pass in stages of their own, each method's frame (locals and value stack) within 11
        # machine words: a bigger one is taken from the heap and freed at every call on MicroPython
        # (bench/frame_sizes.py), and with the pass's float results that costs more than the calls.
        # This one is at 11: four locals, and the fixed controller's call (seven words of stack).
        dt_us = ticks_diff(now_us, self._last_us)
        self.pass_dt_us = dt_us
        self._last_us = now_us
        _pass_stats(self._pass_words, dt_us)  # the scheduler's pass statistics (Scheduler.stats)
        self._sense(now_us, dt_us)  # 1. IMU and filters, 2. estimator
        # 3. commander: the pilot's sticks, or the failsafe's
        sp = self._sp
        self.rc.update(sp)
        self.command(sp)
        # 4. controller and 5. mixer: in fixed point (pid_math; MicroPython's zero-allocation pass), or float
        if self._fixed_on:
            self.fixed.update(sp, self._attitude, dt_us, self.i_active, self.airmode_active)
        else:
            self._control_float(dt_us, sp)
        self._outputs(now_us)  # 6. outputs
        if ticks_diff(now_us, self.scheduler.next_due_us) >= 0:  # most passes run no task: not even the call
            self.scheduler.run(now_us)
        if self.log_pass is not None:  # the logger's update while a log is open (Logger sets it)
            self.log_pass(now_us)

    def _sense(self, now_us, dt_us):
        """1. The IMU sample through the filters, 2. the estimator."""
        s = self.signals
        if self.board.read_imu(s.gyro_raw_rad_s, s.accel_raw_m_s2):
            self.imu_us = now_us
            if self._imu_prepare:  # a board not mounted square, or the gyro calibration still running
                self._prepare_imu(now_us)
            if self._fixed_imu_on:
                self.fixed_imu.update()
            else:
                self.gyro_filter.update(s.gyro_raw_rad_s, self.calibration.bias_rad_s, s.gyro_rad_s)
                self.accel_filter.update(s.accel_raw_m_s2, s.accel_m_s2)
        elif self.logger.active:  # no new sample: the log's integral_dt says so (Logger.update's full path)
            self.logger.full_pass_next()
        if self._att_fixed_now:  # the gyro average and the update every _att_every passes, as _estimate
            self.fixed_att.step(dt_us, self.arming.armed)
        else:
            self._estimate(dt_us)

    def _prepare_imu(self, now_us):
        """The sample rotated to the board's mounting, and the gyro calibration fed while it runs."""
        s = self.signals
        if not self.alignment.identity:  # a board mounted square (the usual case) needs no rotation
            self.alignment.apply(s.gyro_raw_rad_s)
            self.alignment.apply(s.accel_raw_m_s2)
        if not self.calibration.calibrated:
            if self.calibration.update(s.gyro_raw_rad_s):
                self.events.record(now_us, EV_GYRO_CALIBRATED, 0)
        self._route()

    def _route(self):
        """Which paths the pass takes, from what configure() and the first samples set."""
        self._imu_prepare = not self.alignment.identity or not self.calibration.calibrated
        self._att_fixed_now = self._fixed_att_on and not self._use_external and not self._first_imu

    def _estimate(self, dt_us):
        """2. The estimator, where FixedAttitude does not run it: the external attitude, the first level
        from the accelerometer, or the float Mahony (every pass, or on the gyro averaged below the loop rate)."""
        s = self.signals
        if self._use_external:
            if self.board.read_attitude(s.external_q):
                self.external.update_from_quaternion(s.external_q, s.attitude)
        elif self._first_imu:
            self.mahony.level_from_accel(s.accel_raw_m_s2, s.attitude)
            self._first_imu = False
            self._route()
        elif self._att_every == 1:
            self.mahony.update(s.gyro_rad_s, s.accel_m_s2, self._dt_s(dt_us), self.arming.armed, s.attitude)
        else:  # below the loop rate (Betaflight runs its attitude at 100 Hz): the gyro averaged since the last update
            g = s.gyro_rad_s
            acc = self._att_sum
            acc[0] += g[0]
            acc[1] += g[1]
            acc[2] += g[2]
            self._att_us += dt_us
            n = self._att_n + 1
            if n < self._att_every:
                self._att_n = n
            else:
                a = self._att_gyro
                a[0] = acc[0] / n
                a[1] = acc[1] / n
                a[2] = acc[2] / n
                us = self._att_us
                self.mahony.update(a, s.accel_m_s2, us * 1e-6 if us > 0 else n / self.loop_hz, self.arming.armed,
                                   s.attitude)
                self._att_restart()

    def _control_float(self, dt_us, sp):
        """4. The controller and 5. the mixer in float (pid_math float, or where the fixed stage cannot run)."""
        s = self.signals
        self.controller.update(sp, s.attitude, s.gyro_rad_s, self._dt_s(dt_us), self.i_active, self.mixer.saturated,
                               s.torque_norm)
        self.mixer.update(sp.throttle_norm, s.torque_norm, self.airmode_active, s.motor_norm)

    def _outputs(self, now_us):
        """6. Outputs: idle..max while armed, a bench motor test while disarmed, then the board's codec."""
        s = self.signals
        armed = self.arming.armed
        out = s.motor_out
        if self._fixed_out_on:
            self.output.update_fixed(s.motor_norm, armed, out)
        else:
            self.output.update(s.motor_norm, armed, out)
        if not armed or self.motor_test.active:  # armed with no test: nothing to end or write
            self._motor_test(now_us, armed, out)
        self.board.write_motors(out, self.motor_count)
        if self._out_more:  # a quad with plain DShot (the usual craft) has neither
            self._servo_and_telemetry(armed)

    def _servo_and_telemetry(self, armed):
        """_outputs' rarer part: the yaw servo (tricopter, seed 002's plane), the ESCs' DShot replies."""
        s = self.signals
        if self.mixer.servo_yaw:
            self.output.servos(self.mixer.servo_norm, 1, armed, s.servo_norm)
            self.board.write_servos(s.servo_norm, 1)
        if self.output.bidir:
            self._motor_telemetry()

    def _motor_test(self, now_us, armed, out):
        """The bench motor test (it notes its inputs once disarmed), then the motors' last word."""
        test = self.motor_test
        test.update(now_us, armed, self.rc.arm_switch, self.rx_ok, out)
        # SAFETY: last word on the motors, after every stage: no mode, scenario or protocol
        # spins a disarmed motor; only an active motor test (disarmed, props-off acknowledged,
        # refreshed every second) may.
        if not armed and not test.active:
            for i in range(self.motor_count):
                out[i] = 0.0

    def _motor_telemetry(self):
        """Bidirectional DShot: the ESCs' replies since the last pass, decoded into eRPM and RPM."""
        n = self.motor_count
        output = self.output
        if self.board.read_motor_telemetry(output.reply_codes, n):
            s = self.signals
            output.decode_replies(n, s.motor_erpm, s.motor_rpm)

    def _dt_s(self, dt_us):
        """The pass's dt in seconds, for the float stages (a float: the fixed-point pass takes dt_us)."""
        if dt_us > 0:
            return dt_us * 1e-6
        return 1.0 / self.loop_hz

    def command(self, sp):
        """Who flies: the pilot, the autopilot (seed 004) or the failsafe; and whether I-term and
        air mode may act. sp arrives holding the pilot's smoothed sticks."""
        if self._pilot_only:  # the usual pass: no failsafe, no autopilot flying or holding a latch
            mode = self.rc.mode
        else:
            mode = self._command_other(sp)
        if mode != self._mode:
            self._mode = mode
            self.events.record(self._last_us, EV_MODE, mode)
        sp.mode = mode
        if not (self.i_active and self.arming.armed and self.airmode_active == self.airmode_enabled):
            self._i_airmode(sp)  # in flight (armed, I-term on, air mode as set) nothing changes: not even the call

    def _command_other(self, sp):
        """command() when the pilot's sticks are not all: the failsafe's setpoint, or the autopilot's."""
        rc = self.rc
        if self.failsafe.state != IDLE:
            # SAFETY: the failsafe outranks the pilot's stale sticks and the autopilot.
            mode = self._failsafe_setpoint(sp)
        else:
            mode = rc.mode
            ap = self.autopilot
            if (ap.state == AP_ENABLED or ap.latch_norm >= 0.0) and ap.apply(self._last_us, sp, rc.stick_raw,
                                                                             rc.throttle_raw):
                rc.fill_setpoint(sp)
        self._who_flies()  # a latch the pilot's stick released, a failsafe that ended
        return mode

    def _who_flies(self):
        """command()'s short way when neither the failsafe nor the autopilot (enabled, or holding a throttle
        latch) has a say. SAFETY: called wherever those change, so the next pass sees it: the 100 Hz task
        (Failsafe.update, Autopilot.update), each pilot frame (Autopilot.on_pilot_frame), and command's
        own other way (Autopilot.apply)."""
        ap = self.autopilot
        self._pilot_only = self.failsafe.state == IDLE and ap.state != AP_ENABLED and ap.latch_norm < 0.0

    def _i_airmode(self, sp):
        """Whether I-term and air mode may act."""
        # Until the throttle has been raised once after arming the craft sits on the ground:
        # no I-term wind-up against the ground, no air-mode spin-up (Betaflight's airmode start).
        armed = self.arming.armed
        if armed:
            if self._throttle_was_up:
                i_active = True
            elif sp.throttle_norm > self._airmode_thr:
                self._throttle_was_up = i_active = True
            else:
                i_active = False
        else:
            self._throttle_was_up = i_active = False
        self.i_active = i_active
        # Air mode: the airmode parameter, or with an AIRMODE channel set only its switch (in range = on).
        active = i_active and self.airmode_enabled
        if active != self.airmode_active:
            self.airmode_active = active
            if armed:  # air mode starts (1) or the switch turns it off in flight (0)
                self.events.record(self._last_us, EV_AIRMODE, 1 if active else 0)
        if not i_active:
            c = self.controller
            c.roll.i = 0.0
            c.pitch.i = 0.0
            c.yaw.i = 0.0

    def _pilot_frame(self):
        """A new frame from the pilot, after arming has seen it: the autopilot's enabling procedure, the
        AIRMODE switch (here in the receiver task, not in every pass's command())."""
        rc = self.rc
        if self.autopilot.on_pilot_frame(self._last_us, rc.arm_switch, self.arming.armed, rc.ap_switch):
            self._who_flies()
        if rc.airmode_box:  # with no AIRMODE channel only configure() changes it (_airmode_from_switch)
            self.airmode_enabled = rc.airmode_switch

    def _failsafe_setpoint(self, sp):
        """The failsafe's setpoint: level (angle mode, sticks centred) and its throttle in stage 2."""
        fs = self.failsafe
        sp.stick_norm[0] = 0.0
        sp.stick_norm[1] = 0.0
        sp.stick_norm[2] = 0.0
        if fs.state == STAGE2:
            if fs.procedure == PROC_GLIDE or fs.procedure == PROC_DROP:
                sp.throttle_norm = 0.0
            else:
                sp.throttle_norm = fs.land_throttle_norm
                if fs.procedure == PROC_LAND:
                    fs.note_accel(self.signals.accel_raw_m_s2)  # every pass: a 1 ms spike counts
        self.rc.fill_setpoint(sp)
        return MODE_ANGLE

    def _airmode_from_switch(self):
        """airmode_enabled: the AIRMODE switch when a channel is set for it, else the airmode parameter
        (configure; each frame takes the switch's half itself, in _pilot_frame: nothing else changes it)."""
        rc = self.rc
        self.airmode_enabled = rc.airmode_switch if rc.airmode_box else self.mixer.airmode

    # -------------------------------------------------------------- slow tasks
    def task_rx(self, now_us):
        rx = self.receiver
        if not rx.update(now_us, self.board):
            # Most polls: no new frame (and no telemetry: it goes out only right after a frame).
            if self.rx_ok and ticks_diff(now_us, self.last_frame_us) > self._rx_timeout_us:
                self._rx_lost()
            return
        self._rx_frame(now_us, rx)

    def _rx_lost(self):
        self.rx_ok = False
        self.events.record(self.last_frame_us, EV_RX_LOST, CAUSE_SWITCH if self.fs_switch else CAUSE_NO_FRAMES)

    def _rx_frame(self, now_us, rx):
        """A new frame: the failsafe switch, the pilot's sticks and switches, arming, telemetry."""
        rc = self.rc
        fs_switch = self.fs_switch = rc.fs_switch_box and rc.fs_switch_in(rx.channels_us)  # no channel: no call
        if fs_switch and self._fs_switch_mode != SWITCH_KILL:
            # SAFETY: failsafe switch (stage1/stage2): the frame is dropped as if it never came,
            # so the link watch times out and the failsafe runs as for a lost receiver.
            if self.rx_ok and ticks_diff(now_us, self.last_frame_us) > self._rx_timeout_us:
                self._rx_lost()
        else:
            self._take_frame(now_us, rx, fs_switch)
        if rx.telemetry_due(now_us):
            self._send_telemetry(now_us, rx)

    def _take_frame(self, now_us, rx, fs_switch):
        """The frame's channels to the pilot's sticks and switches, and to arming."""
        channels = self.signals.rc_channels_us
        self.last_frame_us = now_us
        self.rc.new_frame(channels, rx.channels_us)  # the receiver's frame copied in, in the same call
        if not self.rx_ok:
            self.rx_ok = True
            self.events.record(now_us, EV_RX_RESTORED, 0)
        if fs_switch:
            # SAFETY: failsafe switch, kill: disarm on this frame; BOXFAILSAFE blocks the arm
            # switch from this frame on (task_arming keeps it while the switch stays on).
            self.arming.disarm(now_us, DISARM_FS_SWITCH)
            self.arming.flags |= 1 << BOXFAILSAFE
        if self.failsafe.state == IDLE:
            self.arming.on_switch(now_us, self.rc.arm_switch)
        self._pilot_frame()
        log_rc = self.log_rc  # the every-pass logger's input_rc for this frame, else None (Logger sets it)
        if log_rc is not None:
            log_rc()

    def _send_telemetry(self, now_us, rx):
        s = self.signals
        arming = self.arming
        try:
            rx.send_telemetry(now_us, self.board, s, s.setpoint.mode, self.airmode_enabled,
                              self.failsafe.state != IDLE, arming.armed, arming.flags)
        except Exception as exc:  # noqa: BLE001 - SAFETY: an encoder's or a port's bug ends the frame, not the loop
            self.scheduler.caught("telemetry", exc)

    def task_arming(self, now_us):
        """Faults, built-in test, arming reasons, autopilot timeout, failsafe stages (100 Hz)."""
        s = self.signals
        rc = self.rc
        arming = self.arming
        fw = self.faults
        ap = self.autopilot
        fs = self.failsafe
        dt_s = ticks_diff(now_us, self._arming_us) * 1e-6
        self._arming_us = now_us
        if dt_s < 0.0 or dt_s > 0.1:
            dt_s = 0.01
        armed = arming.armed
        # IMU: no new samples for imu_stale_ms, or new samples frozen, saturated or not finite
        imu_ok = ticks_diff(now_us, self.imu_us) <= self._imu_stale_us
        fault = fw.check_imu(s.gyro_raw_rad_s, s.accel_raw_m_s2) if imu_ok else FAULT_NONE
        if fault == FAULT_NONE and imu_ok and not (self._fixed_imu_on and self._att_fixed_now) \
                and not self._state_finite():
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
            self._restart_estimation()
        fw.fault_before = fault
        self.imu_ok = imu_ok
        seen = self._config_seen
        if self.params.changed != seen[0] or self.config_session != seen[1]:
            self._config_check()
        self.bit.tasks_ok = self.scheduler.errors == 0  # every boundary counts there (Scheduler.caught, Logger)
        # loop rate: a storm of overruns while armed disarms; any overrun blocks arming (LOAD)
        sched = self.scheduler
        if fw.check_load(now_us, sched.stats[PS_PASSES], sched.overruns, armed):
            arming.disarm(now_us, DISARM_LOAD)
        self.overloaded = fw.overloaded
        # whose throttle counts: the autopilot's when it holds the privilege (the pilot's is its cap)
        # (rc.throttle_low() inline: a call a run fewer)
        throttle_low = ap.throttle_low() if ap.state == AP_ENABLED else rc.throttle_us < rc.min_check_us
        if fw.check_crash(now_us, arming.armed, throttle_low, s.attitude.cos_tilt, s.gyro_rad_s, s.accel_m_s2):
            self.events.record(now_us, EV_CRASH, 0)
            arming.disarm(now_us, DISARM_CRASH)
            self._crash_latched = True
        if self._crash_latched and not rc.arm_switch:
            self._crash_latched = False
        battery_ok = self._battery_ok(s.battery_v)
        self.bit.update(imu_ok, self.rx_ok, not self.overloaded, battery_ok, self.calibration.calibrated)
        if not arming.armed:
            # As Betaflight: the disable reasons are worked out only while disarmed (armed, nothing reads
            # them to decide anything), and at once on a disarm (Arming.on_reasons), so an arm request right
            # after a disarm never meets the reasons of before the arming.
            self._arming_flags(now_us, throttle_low, battery_ok)
        if ap.state == AP_ENABLED:  # Autopilot.update's own first test: only an enabled autopilot can go silent
            ap.update(now_us, arming.armed)
        fs.observe(dt_s, s.attitude.q, s.accel_m_s2, s.setpoint.throttle_norm, s.attitude.cos_tilt,
                   arming.armed and self._throttle_was_up)
        # The failsafe switch in stage2 mode: lost from the first dropped frame, straight to stage 2.
        switch_stage2 = self.fs_switch and self._fs_switch_mode == SWITCH_STAGE2
        link_lost = not self.rx_ok or switch_stage2
        # With no failsafe running and the link up (the usual call) Failsafe.update changes nothing.
        if link_lost or fs.state != IDLE:
            sticks_moved = (abs(rc.stick_raw[0]) > 0.3 or abs(rc.stick_raw[1]) > 0.3)
            fs.update(now_us, link_lost, self.last_frame_us, arming.armed, sticks_moved, arming,
                      CAUSE_SWITCH if self.fs_switch else CAUSE_NO_FRAMES, switch_stage2)
        if rc.yaw_hold:  # the heading hold's yaw rate, here at 100 Hz rather than in every pass
            rc.hold_heading(arming.armed, s.attitude.yaw_rad)
        self._who_flies()
        if self.params.changed != self._configured_at and not arming.armed:
            self.configure()
        self._arming_broken = False  # ran through

    def _state_finite(self):
        """The float stages' state is finite: the filtered gyro (where the float filters run) and the attitude
        (where the float estimator runs). The fixed-point stages take a NaN as 0 and clamp an inf, so where they
        run there is nothing to look at (and no float object made on MicroPython)."""
        s = self.signals
        v = 0.0
        if not self._fixed_imu_on:
            g = s.gyro_rad_s
            v = g[0] + g[1] + g[2]
        if not self._att_fixed_now:
            q = s.attitude.q
            v += q[0] + q[1] + q[2] + q[3]
        return v - v == 0.0  # NaN and inf (inf - inf is NaN) both fail

    def _restart_estimation(self):
        """The filters, the estimator and the controller start again from the next sample (an IMU fault with
        non-finite values, and its end): the fixed stages give their state back, the float ones are reset, the
        attitude is levelled from the accelerometer again, and configure() hands the clean state back."""
        self.fixed_imu.release()
        self.fixed_att.release()
        self.fixed.release()
        gf = self.gyro_filter
        for i in range(3):
            gf.lpf1[i].reset()
            gf.lpf2[i].reset()
            gf.notch[i].reset()
        self.mahony.reset(self.signals.attitude)
        self.controller.reset()
        self._first_imu = True
        self.configure()  # the accelerometer filter's reset, the fixed stages from the clean float state

    def _config_check(self):
        """Parameters, mode ranges or sessions changed since the last look (any surface: CLI, MSP, maintenance,
        storage; two int compares): the arm switch must be toggled (Arming.config_changed). True if they did."""
        changed = self.params.changed
        session = self.config_session
        seen = self._config_seen
        if changed == seen[0] and session == seen[1]:
            return False
        seen[0] = changed
        seen[1] = session
        self.arming.config_changed()
        return True

    def _arm_request(self, now_us):
        """Arming.on_reasons(request=True): an arm request (the switch's rising edge, the autopilot's try_arm) meets the
        reasons as they stand at this frame, not the 100 Hz task's of up to 10 ms ago (seed 000's throttle rule
        when throttle and switch move together); a configuration change not yet looked at, or not yet applied
        (configure runs in the 100 Hz task), needs the switch toggled. The reasons the 100 Hz task found stay:
        this only adds (a link restored by this very frame still counts as lost until the task has seen it)."""
        arming = self.arming
        before = arming.flags
        self._config_check()
        if self.params.changed != self._configured_at:
            arming.config_changed()
        self._flags_on_disarm(now_us)
        arming.flags |= before

    def _task_failed(self, task, exc):
        """Scheduler.on_error: a task raised. SAFETY: the arming task's reasons are not to be trusted after it
        raised part-way: an arm request meets BIT until it runs through again."""
        if task.name == "arming":
            self._arming_broken = True
            self.arming.flags |= 1 << BIT_FAILED

    def loop_errors(self):
        """Calls the loop's boundaries caught: slow tasks (links included), receiver telemetry, the log."""
        return self.scheduler.errors

    def loop_errors_line(self):
        """One status line: what raised at the loop's boundaries, and the last error of each."""
        if self.loop_errors() == 0:
            return "Loop errors: none"
        parts = []
        line = self.scheduler.error_line()  # the tasks, and the receiver telemetry
        if line:
            parts.append(line)
        if self.logger.errors:
            parts.append("log %d, stopped (%s)" % (self.logger.errors, self.logger.error_text()))
        return "Loop errors: " + "; ".join(parts)

    def _arming_flags(self, now_us, throttle_low, battery_ok):
        """The arming-disable reasons now (Arming.check, with the reasons of the stages it does not see)."""
        more = session_flags(self.config_session)
        if self.motor_test.active:
            more |= 1 << MOTOR_TEST
        if not battery_ok:
            more |= 1 << BATTERY_CRITICAL
        if self.bit.blocks_arming() or self._arming_broken:
            more |= 1 << BIT_FAILED
        if self.failsafe.state != IDLE:
            more |= 1 << FAILSAFE
        if self.fs_switch:
            more |= 1 << BOXFAILSAFE
        if self._crash_latched:
            more |= 1 << CRASH_DETECTED
        if self.autopilot.switch_on():
            more |= 1 << AUTOPILOT
        self.arming.check(now_us, self.imu_ok, self.calibration.calibrated, self.rx_ok, throttle_low,
                          self.signals.attitude.cos_tilt, self.overloaded, more)

    def _reasons_now(self, now_us, request):
        """Arming.on_reasons: after a disarm, and at an arm request before it is decided."""
        if request:
            self._arm_request(now_us)
        else:
            self._flags_on_disarm(now_us)

    def _flags_on_disarm(self, now_us):
        """Arming.on_reasons after a disarm: the reasons from the state at the disarm (the 100 Hz task's are from
        before it)."""
        ap = self.autopilot
        throttle_low = ap.throttle_low() if ap.state == AP_ENABLED else self.rc.throttle_low()
        self._arming_flags(now_us, throttle_low, self._battery_ok(self.signals.battery_v))

    def _battery_ok(self, battery_v):
        """False below vbat_min_cell per cell; True when off or not measured."""
        if self._vbat_min_cell_v <= 0.0 or battery_v < 1.0:
            return True
        if self.battery_cells == 0:
            self.battery_cells = int(battery_v / 4.3) + 1
        return battery_v >= self._vbat_min_cell_v * self.battery_cells

    def on_msp_rc(self, now_us, channels_us, count):
        """MSP SET_RAW_RC from the companion computer (seed 004's autopilot source).
        None when taken; otherwise the reason it was refused (it then changes nothing)."""
        return self.autopilot.on_msp_rc(now_us, channels_us, count, self.arming)

    def task_battery(self, now_us):
        self.board.read_battery(self.signals)

    def task_led(self, now_us):
        # Seed 000: blink once a second while disarmed, steady while armed.
        if self.arming.armed:
            self.board.set_led(True)
        else:
            self.board.set_led((now_us // 500000) & 1 == 0)
