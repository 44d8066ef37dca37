"""The flight pass: IMU -> filters -> estimator -> commander -> controller -> mixer -> outputs.

`Flight` wires the stages, runs the pass and holds the task table. `Flight.step(now_us)` runs
one pass at the loop rate and then the slow tasks that are due: the receiver and its link watch
(here), the supervisor's 100 Hz safety task and battery (core/safety/supervisor.py: arming, faults, the
failsafe's stages), the LED. Who flies and with what set point is the commander's (core/command/commander.py).
Stages are built once; `configure()` reads the parameters into every stage (again whenever they
change while disarmed).
"""

from array import array

from hoverfly.compat import attr_room, const, ticks_diff
from hoverfly.core.command.autopilot import Autopilot
from hoverfly.core.command.commander import Commander
from hoverfly.core.command.motortest import MotorTest
from hoverfly.core.config.params import Params
from hoverfly.core.events import EV_GYRO_CALIBRATED, EV_RX_LOST, EV_RX_RESTORED, EventLog
from hoverfly.core.fastpass.fixedatt import HAS_ACCEL as _FIXED_ATT_ACCEL
from hoverfly.core.fastpass.fixedatt import FixedAttitude
from hoverfly.core.fastpass.fixedimu import HAS_ACCEL as _FIXED_IMU_ACCEL
from hoverfly.core.fastpass.fixedimu import FixedImuFilter
from hoverfly.core.fastpass.fixedrate import FixedRate
from hoverfly.core.log.logger import Logger
from hoverfly.core.safety.arming import Arming
from hoverfly.core.safety.bit import BuiltInTest
from hoverfly.core.safety.failsafe import CAUSE_NO_FRAMES, CAUSE_SWITCH, IDLE, SWITCH_KILL, Failsafe, FaultWatch
from hoverfly.core.safety.supervisor import Supervisor
from hoverfly.core.scheduler import Scheduler
from hoverfly.core.scheduler import fast_pass_stats as _pass_stats
from hoverfly.core.signals import Signals
from hoverfly.core.stages.control import MODE_MANUAL, Controller
from hoverfly.core.stages.estimator import BoardAlignment, ExternalAttitude, GyroCalibration, Mahony
from hoverfly.core.stages.filters import AccelFilter, GyroFilter
from hoverfly.core.stages.mixer import Mixer, is_plane
from hoverfly.core.stages.output import HAS_ACCEL as _FIXED_OUT_ACCEL
from hoverfly.core.stages.output import OutputStage
from hoverfly.core.stages.rc import RcInput
from hoverfly.core.stages.receiver import Receiver
from hoverfly.core.stages.servos import ServoMixer

# With no log running, the fixed controller writes its PID terms and torques out every this many passes
# (the maintenance telemetry reads them: at 1 kHz, at most 8 ms old).
TERMS_IDLE_PASSES = const(8)


class Flight:
    def __init__(self, board, params=None):
        self.board = board
        self.params = params if params is not None else Params()
        self.signals = Signals()
        self._sp = self.signals.setpoint  # step's own references (Signals never replaces them)
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
        # A plane's controller, its fixed-point twin and its hand launch: made by configure for a plane only
        # (_plane_stages), so a multirotor neither imports them nor holds them.
        self.fw = None
        self.fixed_fw = None
        self.launch = None
        self._plane = False
        self._fw_fixed = False
        self.mixer = Mixer()
        self.fixed = FixedRate()  # the controller and mixer in fixed point (pid_math)
        self._fixed_on = False
        self.fixed_imu = FixedImuFilter()  # the IMU filters in fixed point, with the fixed rate loop
        self._fixed_imu_on = False
        self._fixed_out_on = False  # the output stage's motor commands in fixed point, likewise
        self._out_more = False  # a yaw servo or bidirectional DShot: _outputs has more to do (configure)
        self.fixed_att = FixedAttitude()  # the estimator (Mahony) in fixed point, likewise
        self._fixed_att_on = False
        # notches at the motors' frequencies (bidirectional DShot), float and fixed point: made by the first
        # configure that asks for them (rpm_harmonics > 0), so a craft without them keeps the heap (4-8 kB)
        self.rpm_filter = None
        self._rpm_on = False
        self.fixed_rpm = None
        self._rpm_fixed = False
        self.dyn_notch = None  # notches on the gyro spectrum's peaks (dyn_notch_count), made likewise
        self._dyn_on = False
        self.fixed_dyn = None
        self._dyn_fixed = False
        self.output = OutputStage()
        self.servos = ServoMixer()  # a plane's surfaces (smix rules), read by _outputs
        self.servos.bind(self.signals.torque_norm, self.signals.rc_channels_us, self.signals.servo_us)
        self.arming = Arming(self.events)
        self.motor_test = MotorTest(self.arming)
        self.failsafe = Failsafe(self.events)
        self.faults = FaultWatch()
        self.autopilot = Autopilot(self.events)
        self.autopilot.pilot_channels = self.signals.rc_channels_us
        self.arming.gate = self.autopilot  # in autopilot mode the pilot's switch does not arm
        self.bit = BuiltInTest()
        # 3. who flies and with what set point: the pilot, the failsafe or the autopilot
        self.commander = Commander(self.events, self.rc, self.arming, self.failsafe, self.autopilot,
                                   self.controller, self.signals.accel_raw_m_s2)
        self.failsafe.commander = self.commander  # the failsafe writes its own bit of who flies
        self.config_session = 0  # 1 CLI, 2 MSP configurator, 4 maintenance, 8 maintenance on USB: any set blocks arming
        self.scheduler = Scheduler()
        self._pass_words = self.scheduler.stats
        self.loop_hz = 1000
        self.motor_count = 4
        self.idle = 0.055
        self.motor_max = 1.0
        self._configured_at = -1
        self._last_us = 0
        self.imu_us = 0  # the last IMU sample's time (the supervisor's stale-IMU watch)
        # the receiver task's link watch (the supervisor's failsafe and arming reasons read it)
        self.rx_ok = False
        self.last_frame_us = 0
        self._rx_timeout_us = 100000
        self.fs_switch = False  # the failsafe switch as read from the latest frame
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
        self.pass_us = 0
        self.pass_dt_us = 0  # ticks from the previous pass to this one (the logger's clock)
        # arming, the 100 Hz safety task, the failsafe's stages, the battery
        self.supervisor = Supervisor(self)
        # The slow tasks: name, rate (Hz), what runs. "arming" and "rx" are the names the loop's error
        # counts and tests know them by.
        self.scheduler.add("rx", 500, self.task_rx)
        self.scheduler.add("arming", 100, self.supervisor.task)
        self.scheduler.add("battery", 50, self.supervisor.task_battery)
        self.scheduler.add("led", 10, self.task_led)
        self.scheduler.on_error = self.supervisor.task_failed
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
        self._plane = is_plane(p.get("mixer_type"))
        if self._plane:  # the plane's controller runs in _control_plane; the quad's fixed pass does not
            self._plane_stages()
            self.fw.configure(p)
            self.fixed.release()
            self._fixed_on = False
            self._fw_fixed = self.fixed_fw.configure(self.fw, hz, p.get("pid_math"), self.signals)
        else:
            if self.fixed_fw is not None:
                self.fixed_fw.release()
            self._fw_fixed = False
            self._fixed_on = self.fixed.configure(self.controller, self.mixer, hz, p.get("pid_math"), self.signals)
        fast = self._fixed_on or self._fw_fixed  # the IMU filters and the estimator in fixed point with it
        self.logging_changed()
        # The IMU filters go with the rate loop: anywhere for "fixed", on "auto" where their viper twin loads.
        self._fixed_imu_on = self.fixed_imu.configure(
            self.gyro_filter, self.accel_filter, self.signals, self.calibration.bias_rad_s,
            fast and (p.get("pid_math") == "fixed" or _FIXED_IMU_ACCEL))
        self._fixed_out_on = fast and (p.get("pid_math") == "fixed" or _FIXED_OUT_ACCEL)
        self._fixed_att_on = self.fixed_att.configure(
            self.mahony, self.signals.attitude, self.signals, hz, self._att_every,
            fast and (p.get("pid_math") == "fixed" or _FIXED_ATT_ACCEL))
        self.motor_count = self.mixer.n
        if p.get("arm_source") == "seed001":
            # Seed 001: the arm channel above 1500 µs arms (the range rule, with no upper end).
            self.rc.set_arm_range(p.get("arm_ch"), 1501, 0x10000)
        self.supervisor.configure(p)
        self.commander.configure(p, self.mixer.airmode)
        self.logger.configure(p)
        self.idle = p.get("motor_idle_pct") * 0.01
        self.motor_max = p.get("motor_max_pct") * 0.01
        self.servos.configure(p)
        servo_count = self.servos.count if self.servos.count else (1 if self.mixer.servo_yaw else 0)
        self.output.configure(p, self.motor_count)
        self.motor_test.configure(p, self.motor_count)
        self.board.configure_outputs(p, self.motor_count, servo_count)
        self._out_more = self.mixer.servo_yaw or self.servos.count > 0 or self.output.bidir  # servos, ESC replies
        self._configure_rpm(p, hz)
        self._configure_dyn(p, hz)
        self._rx_timeout_us = p.get("rx_timeout_ms") * 1000
        self._route()
        self._configured_at = p.changed

    def _configure_rpm(self, p, hz):
        """The RPM filter, where rpm_harmonics asks for it (in fixed point with the fixed IMU filters)."""
        if self.rpm_filter is None:
            if p.get("rpm_harmonics") == 0:
                return
            from hoverfly.core.stages.rpmfilter import RpmFilter

            self.rpm_filter = RpmFilter(self.events)
        self.rpm_filter.configure(p, hz, self.motor_count, self.output.bidir)
        self._rpm_on = self.rpm_filter.active
        if self._rpm_on and self._fixed_imu_on and self.fixed_rpm is None:
            from hoverfly.core.fastpass.fixedrpm import FixedRpmFilter

            self.fixed_rpm = FixedRpmFilter()
        self._rpm_fixed = self.fixed_rpm is not None and self.fixed_rpm.configure(
            self.rpm_filter, self.signals, self._fixed_imu_on)

    def _configure_dyn(self, p, hz):
        """The dynamic notch, where dyn_notch_count asks for it (in fixed point with the fixed IMU filters)."""
        if self.dyn_notch is None:
            if p.get("dyn_notch_count") == 0:
                return
            from hoverfly.core.stages.dynnotch import DynNotch

            self.dyn_notch = DynNotch()
        self.dyn_notch.configure(p, hz)
        self._dyn_on = self.dyn_notch.active
        if self._dyn_on and self._fixed_imu_on and self.fixed_dyn is None:
            from hoverfly.core.fastpass.fixeddyn import FixedDynNotch

            self.fixed_dyn = FixedDynNotch()
        self._dyn_fixed = self.fixed_dyn is not None and self.fixed_dyn.configure(
            self.dyn_notch, self.signals, self._fixed_imu_on)

    def _plane_stages(self):
        """A plane's controller (float and fixed point) and hand launch, made at its first configure, and wired
        to the commander (its pitch target, the launch and what the launch reads)."""
        if self.fw is not None:
            return
        from hoverfly.core.command.launch import Launch
        from hoverfly.core.fastpass.fixedfw import FixedFw
        from hoverfly.core.stages.fwcontrol import FwController

        self.fw = FwController(self.signals.pid_terms)
        self.fixed_fw = FixedFw()
        self.launch = Launch(self.events)
        s = self.signals
        self.commander.plane_parts(self.fw, self.launch, s.attitude, s.accel_m_s2, s.rc_channels_us)

    def configure_pending(self):
        """Parameters changed since configure() last ran (it runs in the 100 Hz task, while disarmed)."""
        return self.params.changed != self._configured_at

    def configure_if_changed(self):
        """The supervisor's 100 Hz task, while disarmed: a parameter change takes effect."""
        if self.params.changed != self._configured_at:
            self.configure()

    def logging_changed(self):
        """The logger started or stopped its every-pass calls (Logger._hand_over; and configure): the fixed
        controller writes its PID terms and torques out every pass while a log runs, else every
        TERMS_IDLE_PASSES passes, for the maintenance telemetry that reads them (written every pass they
        would be a few per cent of MicroPython's pass; the telemetry reads them at most
        TERMS_IDLE_PASSES passes old)."""
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
        attr_room(self.commander)  # likewise: read every pass, and the supervisor's many at 100 Hz
        attr_room(self.supervisor)

    # ------------------------------------------------------------------ the pass
    def step(self, now_us):
        # The pass in stages of their own, each method's frame (locals and value stack) within 11
        # machine words: a bigger one is taken from the heap and freed at every call on MicroPython
        # (bench/frame_sizes.py), and with the pass's float results that costs more than the calls.
        # tests/test_perf_rules.py holds every function of the pass to it. This one is at 10: four
        # locals, and the fixed controller's call (six words of stack).
        dt_us = ticks_diff(now_us, self._last_us)
        self.pass_dt_us = dt_us
        self._last_us = now_us
        _pass_stats(self._pass_words, dt_us)  # the scheduler's pass statistics (Scheduler.stats)
        self._sense(now_us, dt_us)  # 1. IMU and filters, 2. estimator
        # 3. the pilot's sticks, and the commander: who flies (pilot, failsafe, autopilot) with what set point
        sp = self._sp
        self.rc.update(sp)
        self.commander.update(sp, now_us)
        # 4. controller and 5. mixer: in fixed point (pid_math; MicroPython's zero-allocation pass), or float
        if self._fixed_on:
            self.fixed.update(sp, dt_us, self.commander.i_active, self.commander.airmode_active)
        elif self._plane:  # a plane's controller (fixed point where pid_math asks), its one motor
            self._control_plane(dt_us, sp)
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
            if self._rpm_on:  # the motors' notches, on the previous pass's RPM (the replies come after the outputs)
                if self._rpm_fixed:
                    self.fixed_rpm.update(now_us)
                else:
                    self.rpm_filter.update(s.gyro_rad_s, s.motor_rpm, now_us)
            if self._dyn_on:  # last: it goes after what the RPM filter leaves
                if self._dyn_fixed:
                    self.fixed_dyn.update()
                else:
                    self.dyn_notch.update(s.gyro_rad_s)
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
        self.controller.update(sp, s.attitude, s.gyro_rad_s, self._dt_s(dt_us), self.commander.i_active,
                               self.mixer.saturated, s.torque_norm)
        self.mixer.update(sp.throttle_norm, s.torque_norm, self.commander.airmode_active, s.motor_norm)

    def _control_plane(self, dt_us, sp):
        """4. A plane's controller (core/stages/fwcontrol.py): stabilised roll, pitch, yaw into torque_norm for
        the servo mixer in _outputs; its one motor takes the throttle (the plane's motor table is throttle only)."""
        if self._fw_fixed:
            self.fixed_fw.update(sp, self._attitude, dt_us, self.commander.i_active)
        else:
            self._control_plane_float(dt_us, sp)
        self.signals.motor_norm[0] = sp.throttle_norm

    def _control_plane_float(self, dt_us, sp):
        """_control_plane's float law (pid_math float, or where the fixed pass does not run: CPython on auto)."""
        s = self.signals
        self.fw.update(sp, s.attitude, s.gyro_rad_s, self._dt_s(dt_us), self.commander.i_active, s.torque_norm)

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
        """_outputs' rarer part: a plane's servo mix (or a tricopter's tail), the ESCs' DShot replies."""
        s = self.signals
        n = self.servos.count
        if n:  # smix rules (core/stages/servos.py)
            sp = self._sp
            # Disarmed the surfaces sit at their mids, but follow the sticks in MANUAL for the preflight
            # check, as INAV's do (the motor stays stopped: _motor_test's SAFETY block).
            self.servos.update(self.pass_dt_us, armed or sp.mode == MODE_MANUAL, sp.throttle_norm)
            self.board.write_servos(s.servo_us, n)
        elif self.mixer.servo_yaw:
            self.output.servos(self.mixer.servo_norm, 1, armed, s.servo_norm)
            self.servos.from_norm(s.servo_norm, 1, s.servo_us)
            self.board.write_servos(s.servo_us, 1)
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
            if self._rpm_on:  # the RPM filter takes one motor a pass: that motor's reply alone is decoded
                rpm = self.fixed_rpm if self._rpm_fixed else self.rpm_filter
                m = rpm.due()
                if output.decode_reply(m, s.motor_erpm, s.motor_rpm):
                    rpm.reply_ok(m)
            else:
                output.decode_replies(n, s.motor_erpm, s.motor_rpm)

    def _dt_s(self, dt_us):
        """The pass's dt in seconds, for the float stages (a float: the fixed-point pass takes dt_us)."""
        if dt_us > 0:
            return dt_us * 1e-6
        return 1.0 / self.loop_hz

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
        if fs_switch and self.supervisor.fs_switch_mode != SWITCH_KILL:
            # SAFETY: failsafe switch (stage1/stage2): the frame is dropped as if it never came,
            # so the link watch times out and the failsafe runs as for a lost receiver.
            if self.rx_ok and ticks_diff(now_us, self.last_frame_us) > self._rx_timeout_us:
                self._rx_lost()
        else:
            self._take_frame(now_us, rx, fs_switch)
        if rx.telemetry_due(now_us):
            self._send_telemetry(now_us, rx)

    def _take_frame(self, now_us, rx, fs_switch):
        """The frame's channels to the pilot's sticks and switches, to the supervisor (arming) and the commander."""
        channels = self.signals.rc_channels_us
        self.last_frame_us = now_us
        self.rc.new_frame(channels, rx.channels_us)  # the receiver's frame copied in, in the same call
        if not self.rx_ok:
            self.rx_ok = True
            self.events.record(now_us, EV_RX_RESTORED, 0)
        self.supervisor.on_frame(now_us, fs_switch)
        self.commander.pilot_frame(now_us, self.arming.armed)
        log_rc = self.log_rc  # the every-pass logger's input_rc for this frame, else None (Logger sets it)
        if log_rc is not None:
            log_rc()

    def _send_telemetry(self, now_us, rx):
        s = self.signals
        arming = self.arming
        try:
            rx.send_telemetry(now_us, self.board, s, s.setpoint.mode, self.commander.airmode_enabled,
                              self.failsafe.state != IDLE, arming.armed, arming.flags)
        except Exception as exc:  # noqa: BLE001 - SAFETY: an encoder's or a port's bug ends the frame, not the loop
            self.scheduler.caught("telemetry", exc)

    def state_finite(self):
        """The float stages' state is finite: the filtered gyro (where the float filters run) and the attitude
        (where the float estimator runs). The fixed-point stages take a NaN as 0 and clamp an inf, so where they
        run there is nothing to look at (and no float object made on MicroPython). The supervisor's IMU watch."""
        if self._fixed_imu_on and self._att_fixed_now:
            return True
        s = self.signals
        v = 0.0
        if not self._fixed_imu_on:
            g = s.gyro_rad_s
            v = g[0] + g[1] + g[2]
        if not self._att_fixed_now:
            q = s.attitude.q
            v += q[0] + q[1] + q[2] + q[3]
        return v - v == 0.0  # NaN and inf (inf - inf is NaN) both fail

    def restart_estimation(self):
        """The filters, the estimator and the controller start again from the next sample (an IMU fault with
        non-finite values, and its end): the fixed stages give their state back, the float ones are reset, the
        attitude is levelled from the accelerometer again, and configure() hands the clean state back."""
        self.fixed_imu.release()
        self.fixed_att.release()
        self.fixed.release()
        if self.fixed_fw is not None:
            self.fixed_fw.release()
        gf = self.gyro_filter
        for i in range(3):
            gf.lpf1[i].reset()
            gf.lpf2[i].reset()
            gf.notch[i].reset()
        if self.rpm_filter is not None:
            self.rpm_filter.reset()
        if self.dyn_notch is not None:
            self.dyn_notch.reset()
        self.mahony.reset(self.signals.attitude)
        self.controller.reset()
        if self.fw is not None:
            self.fw.reset()
        self._first_imu = True
        self.configure()  # the accelerometer filter's reset, the fixed stages from the clean float state

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

    def on_msp_rc(self, now_us, channels_us, count):
        """MSP SET_RAW_RC from the companion computer (seed 004's autopilot source).
        None when taken; otherwise the reason it was refused (it then changes nothing)."""
        return self.autopilot.on_msp_rc(now_us, channels_us, count, self.arming)

    def task_led(self, now_us):
        # Seed 000: blink once a second while disarmed, steady while armed.
        if self.arming.armed:
            self.board.set_led(True)
        else:
            self.board.set_led((now_us // 500000) & 1 == 0)
