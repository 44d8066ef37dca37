"""What flows between the stages of the pass: the map of the system.

One instance per flight, preallocated; every name carries its unit and frame. Stages
read and write these arrays and attributes, never each other.
"""

from array import array

from hoverfly.core.log.logframe import PassRecord
from hoverfly.core.stages.control import MODE_ANGLE
from hoverfly.core.stages.estimator import Attitude
from hoverfly.core.stages.mixer import MAX_MOTORS
from hoverfly.core.stages.servos import MAX_SERVOS


class Setpoint:
    """What the pilot (or failsafe, or autopilot) asks for this pass."""

    def __init__(self, record=None):
        self.mode = MODE_ANGLE
        self.stick_norm = array("f", [0.0, 0.0, 0.0])  # roll, pitch, yaw in -1..1 after smoothing
        zeros = (0.0, 0.0, 0.0)
        # body rates FRD (in the log's pass record when there is one)
        self.rate_rad_s = record.floats("rate_rad_s", zeros) if record is not None else array("f", zeros)
        self.roll_angle_rad = 0.0
        self.pitch_angle_rad = 0.0
        self.throttle_norm = 0.0  # collective, 0..1


class Signals:
    """The pass's signals. The arrays the flight log records at every pass (core/log/logframe.py)
    live in `record`, one block laid out as the log frame, where the runtime allows it."""

    def __init__(self):
        rec = self.record = PassRecord()
        f = rec.floats
        # 1. IMU, body frame FRD
        self.gyro_raw_rad_s = f("gyro_raw_rad_s", (0.0, 0.0, 0.0))  # as the board gave it, aligned
        self.accel_raw_m_s2 = f("accel_raw_m_s2", (0.0, 0.0, -9.80665))
        self.gyro_rad_s = f("gyro_rad_s", (0.0, 0.0, 0.0))  # bias removed, filtered: what the PID sees
        self.accel_m_s2 = array("f", [0.0, 0.0, -9.80665])  # filtered: what the estimator sees
        self.external_q = array("f", [1.0, 0.0, 0.0, 0.0])  # an IMU's own fusion, when it has one
        # 2. estimator
        self.attitude = Attitude()
        self.attitude.q = f("q", self.attitude.q)
        # 3. commander
        self.rc_channels_us = array("H", [1500] * 18)
        self.setpoint = Setpoint(rec)
        # 4. controller
        self.torque_norm = f("torque_norm", (0.0, 0.0, 0.0))
        self.pid_terms = f("pid_terms", [0.0] * 12)  # p[3], i[3], d[3], f[3]: the controller's terms
        # 5. mixer and outputs
        self.motor_norm = array("f", [0.0] * MAX_MOTORS)  # mixer demand 0..1
        self.motor_out = f("motor_out", [0.0] * MAX_MOTORS)  # to the ESC: 0 = stop, idle..1 when armed
        self.motor_erpm = array("i", [0] * MAX_MOTORS)  # bidirectional DShot replies, 0 = stopped
        self.motor_rpm = array("i", [0] * MAX_MOTORS)  # mechanical: eRPM / (motor_poles / 2)
        self.servo_norm = array("f", [0.0, 0.0, 0.0, 0.0])  # -1..1: a tricopter's tail from the motor mixer
        self.servo_us = array("H", [1500] * MAX_SERVOS)  # the servo mixer's pulse widths (core/stages/servos.py)
        # power
        self.battery_v = 0.0
        self.current_a = 0.0
        self.mah_drawn = 0.0
        # pitot (a plane's): indicated airspeed, 0.0 with airspeed_valid False when the board has none
        self.airspeed_m_s = 0.0
        self.airspeed_valid = False
