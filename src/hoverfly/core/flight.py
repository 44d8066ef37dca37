"""The flight pass: IMU -> filters -> estimator -> commander -> controller -> mixer -> outputs.

`Flight.step(now_us)` runs one pass at the loop rate and then the slow tasks that are
due (receiver, arming, failsafe, battery, LED). Stages are built once; `configure()`
reads the parameters into every stage (again whenever they change while disarmed).
"""

import math

from hoverfly.compat import ticks_diff
from hoverfly.core.arming import Arming
from hoverfly.core.control import MODE_ANGLE, Controller
from hoverfly.core.estimator import BoardAlignment, ExternalAttitude, GyroCalibration, Mahony
from hoverfly.core.events import (
    DISARM_IMU,
    EV_AIRMODE,
    EV_GYRO_CALIBRATED,
    EV_IMU_FAULT,
    EV_MODE,
    EV_RX_LOST,
    EV_RX_RESTORED,
    EventLog,
)
from hoverfly.core.failsafe import IDLE, PROC_DROP, PROC_GLIDE, STAGE2, Failsafe
from hoverfly.core.filters import Biquad, LowPass, Pt1, Pt2
from hoverfly.core.mixer import Mixer
from hoverfly.core.params import Params
from hoverfly.core.rc import RcInput
from hoverfly.core.scheduler import Scheduler
from hoverfly.core.signals import Signals


class GyroFilter:
    """Per-axis gyro chain: low-pass 1 (type by parameter), low-pass 2 (PT1), notch."""

    def __init__(self):
        self.lpf1 = (LowPass(), LowPass(), LowPass())
        self.lpf2 = (Pt1(), Pt1(), Pt1())
        self.notch = (Biquad(), Biquad(), Biquad())
        self.notch_on = False
        self.lpf2_on = False

    def configure(self, params, loop_hz):
        kind = params.get("gyro_lpf1_type")
        for i in range(3):
            self.lpf1[i].configure(kind, params.get("gyro_lpf1_hz"), loop_hz)
            self.lpf2[i].configure(params.get("gyro_lpf2_hz"), loop_hz)
            self.notch[i].configure_notch(params.get("gyro_notch1_hz"), params.get("gyro_notch1_cut"), loop_hz)
        self.notch_on = params.get("gyro_notch1_hz") > 0 and params.get("gyro_notch1_cut") > 0
        self.lpf2_on = 0 < params.get("gyro_lpf2_hz") < loop_hz // 2

    def update(self, raw, bias, out):
        lpf1 = self.lpf1
        lpf2 = self.lpf2
        if self.notch_on:  # the full chain
            notch = self.notch
            for i in range(3):
                out[i] = notch[i].update(lpf2[i].update(lpf1[i].update(raw[i] - bias[i])))
        elif self.lpf2_on:
            for i in range(3):
                out[i] = lpf2[i].update(lpf1[i].update(raw[i] - bias[i]))
        else:
            for i in range(3):
                out[i] = lpf1[i].update(raw[i] - bias[i])


class AccelFilter:
    def __init__(self):
        self.f = (Pt2(), Pt2(), Pt2())

    def configure(self, params, loop_hz):
        for f in self.f:
            f.configure(params.get("acc_lpf_hz"), loop_hz)
            f.reset(0.0)
        self.f[2].reset(-9.80665)

    def update(self, raw, out):
        f = self.f
        out[0] = f[0].update(raw[0])
        out[1] = f[1].update(raw[1])
        out[2] = f[2].update(raw[2])


class Flight:
    def __init__(self, board, params=None):
        self.board = board
        self.params = params if params is not None else Params()
        self.signals = Signals()
        self.events = EventLog()
        self.alignment = BoardAlignment()
        self.calibration = GyroCalibration()
        self.gyro_filter = GyroFilter()
        self.accel_filter = AccelFilter()
        self.mahony = Mahony()
        self.external = ExternalAttitude()
        self.rc = RcInput()
        self.controller = Controller()
        self.mixer = Mixer()
        self.arming = Arming(self.events)
        self.failsafe = Failsafe(self.events)
        self.scheduler = Scheduler()
        self.loop_hz = 1000
        self.motor_count = 4
        self.idle = 0.055
        self.motor_max = 1.0
        self._configured_at = -1
        self._last_us = 0
        self._imu_us = 0
        self._imu_stale_us = 20000
        self.imu_ok = True
        self.rx_ok = False
        self.last_frame_us = 0
        self._rx_timeout_us = 100000
        self._airmode_thr = 0.25
        self.airmode_active = False
        self.i_active = False
        self._throttle_was_up = False
        self._mode = -1
        self._use_external = False
        self._first_imu = True
        self.overloaded = False
        self.pass_us = 0
        self.scheduler.add("rx", 500, self.task_rx)
        self.scheduler.add("arming", 100, self.task_arming)
        self.scheduler.add("battery", 50, self.task_battery)
        self.scheduler.add("led", 10, self.task_led)

    # ----------------------------------------------------------------- set-up
    def configure(self):
        p = self.params
        self.loop_hz = p.get("loop_hz")
        hz = self.loop_hz
        self.alignment.configure(p)
        self.calibration.configure(p, hz)
        self.gyro_filter.configure(p, hz)
        self.accel_filter.configure(p, hz)
        self.mahony.configure(p)
        self._use_external = p.get("estimator") == "external"
        self.rc.configure(p, hz)
        self.controller.configure(p, hz)
        self.mixer.configure(p)
        self.motor_count = self.mixer.n
        self.arming.configure(p)
        self.failsafe.configure(p)
        self.idle = p.get("motor_idle_pct") * 0.01
        self.motor_max = p.get("motor_max_pct") * 0.01
        self._imu_stale_us = p.get("imu_stale_ms") * 1000
        self._rx_timeout_us = p.get("rx_timeout_ms") * 1000
        self._airmode_thr = p.get("airmode_thr_pct") * 0.01
        self._configured_at = p.changed

    def start(self, now_us):
        """Boot: configure, start the clocks and the gyro calibration."""
        self.configure()
        self._last_us = now_us
        self._imu_us = now_us
        self.last_frame_us = now_us
        self.arming.boot_us = now_us
        self.calibration.reset()
        self.scheduler.start(now_us, self.loop_hz)

    # ------------------------------------------------------------------ the pass
    def step(self, now_us):
        s = self.signals
        board = self.board
        dt_s = ticks_diff(now_us, self._last_us) * 1e-6
        if dt_s <= 0.0:
            dt_s = 1.0 / self.loop_hz
        self._last_us = now_us
        self.scheduler.pass_started(now_us)

        # 1. IMU and filters
        if board.read_imu(s.gyro_raw_rad_s, s.accel_raw_m_s2):
            self._imu_us = now_us
            self.alignment.apply(s.gyro_raw_rad_s)
            self.alignment.apply(s.accel_raw_m_s2)
            if not self.calibration.calibrated:
                if self.calibration.update(s.gyro_raw_rad_s):
                    self.events.record(now_us, EV_GYRO_CALIBRATED, 0)
            self.gyro_filter.update(s.gyro_raw_rad_s, self.calibration.bias_rad_s, s.gyro_rad_s)
            self.accel_filter.update(s.accel_raw_m_s2, s.accel_m_s2)
        # 2. estimator
        if self._use_external:
            if board.read_attitude(s.external_q):
                self.external.update_from_quaternion(s.external_q, s.attitude)
        elif self._first_imu:
            self.mahony.level_from_accel(s.accel_raw_m_s2, s.attitude)
            self._first_imu = False
        else:
            self.mahony.update(s.gyro_rad_s, s.accel_m_s2, dt_s, self.arming.armed, s.attitude)
        # 3. commander: the pilot's sticks, or the failsafe's
        sp = s.setpoint
        self.rc.update(sp)
        self.command(sp)
        # 4. controller
        armed = self.arming.armed
        self.controller.update(sp, s.attitude, s.gyro_rad_s, dt_s, self.i_active, self.mixer.saturated,
                               s.torque_norm)
        # 5. mixer
        self.mixer.update(sp.throttle_norm, s.torque_norm, self.airmode_active, s.motor_norm)
        # 6. outputs
        # SAFETY: last word on the motors, after every stage: no mode, scenario or protocol
        # spins a disarmed motor.
        out = s.motor_out
        n = self.motor_count
        if armed:
            idle = self.idle
            span = self.motor_max - idle
            for i in range(n):
                out[i] = idle + span * s.motor_norm[i]
        else:
            for i in range(n):
                out[i] = 0.0
        board.write_motors(out, n)
        if self.mixer.servo_yaw:
            s.servo_norm[0] = self.mixer.servo_norm[0] if armed else 0.0
            board.write_servos(s.servo_norm, 1)
        self.scheduler.run(now_us)

    def command(self, sp):
        """Who flies: the pilot, or the failsafe; and whether I-term and air mode may act."""
        rc = self.rc
        mode = rc.mode
        fs = self.failsafe
        if fs.state != IDLE:
            mode = MODE_ANGLE
            sp.stick_norm[0] = 0.0
            sp.stick_norm[1] = 0.0
            sp.stick_norm[2] = 0.0
            if fs.state == STAGE2:
                if fs.procedure == PROC_GLIDE or fs.procedure == PROC_DROP:
                    sp.throttle_norm = 0.0
                else:
                    sp.throttle_norm = fs.throttle_norm
            rc.fill_setpoint(sp)
        if mode != self._mode:
            self._mode = mode
            self.events.record(self._last_us, EV_MODE, mode)
        sp.mode = mode
        armed = self.arming.armed
        if not armed:
            self._throttle_was_up = False
        elif sp.throttle_norm > self._airmode_thr and not self._throttle_was_up:
            self._throttle_was_up = True
            self.events.record(self._last_us, EV_AIRMODE, 1)
        # Until the throttle has been raised once after arming the craft sits on the ground:
        # no I-term wind-up against the ground, no air-mode spin-up (Betaflight's airmode start).
        self.i_active = armed and self._throttle_was_up
        self.airmode_active = armed and self._throttle_was_up and self.mixer.airmode
        if not self.i_active:
            self.controller.roll.i = 0.0
            self.controller.pitch.i = 0.0
            self.controller.yaw.i = 0.0

    # -------------------------------------------------------------- slow tasks
    def task_rx(self, now_us):
        s = self.signals
        if self.board.read_rc(s.rc_channels_us):
            self.last_frame_us = now_us
            self.rc.new_frame(s.rc_channels_us)
            if not self.rx_ok:
                self.rx_ok = True
                self.events.record(now_us, EV_RX_RESTORED, 0)
            if self.failsafe.state == IDLE:
                self.arming.on_switch(now_us, self.rc.arm_switch)
        elif self.rx_ok and ticks_diff(now_us, self.last_frame_us) > self._rx_timeout_us:
            self.rx_ok = False
            self.events.record(self.last_frame_us, EV_RX_LOST, 0)

    def task_arming(self, now_us):
        s = self.signals
        imu_age = ticks_diff(now_us, self._imu_us)
        imu_ok = imu_age <= self._imu_stale_us
        if self.imu_ok and not imu_ok:
            self.events.record(now_us, EV_IMU_FAULT, 0)
            self.arming.disarm(now_us, DISARM_IMU)
        self.imu_ok = imu_ok
        self.arming.check(now_us, imu_ok, self.calibration.calibrated, self.rx_ok, self.rc.throttle_low(),
                          s.attitude.cos_tilt, self.overloaded)
        a = s.accel_raw_m_s2
        accel_norm = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
        sticks_moved = (abs(self.rc.stick_raw[0]) > 0.3 or abs(self.rc.stick_raw[1]) > 0.3)
        self.failsafe.update(now_us, not self.rx_ok, self.last_frame_us, self.arming.armed, sticks_moved,
                             accel_norm, self.arming)
        if self.params.changed != self._configured_at and not self.arming.armed:
            self.configure()

    def task_battery(self, now_us):
        self.board.read_battery(self.signals)

    def task_led(self, now_us):
        # Seed 000: blink once a second while disarmed, steady while armed.
        if self.arming.armed:
            self.board.set_led(True)
        else:
            self.board.set_led((now_us // 500000) & 1 == 0)
