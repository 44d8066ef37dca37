"""The Board: the flight core's one seam to the world.

`sim`, `linux` and `rp2` boards implement these methods; the core never asks which
board it runs on. Values cross the seam in SI units in the body frame FRD.
"""


class Board:
    name = "board"

    def now_us(self):
        """Microsecond tick clock (compat ticks: compare only with ticks_diff)."""
        raise NotImplementedError

    def read_imu(self, gyro_rad_s, accel_m_s2):
        """Write the newest sample (FRD, rad/s and m/s²); True if it is new since the last call."""
        raise NotImplementedError

    def read_attitude(self, q_out):
        """An IMU's own fusion (w, x, y, z; body to NED), for estimator = external. False if none."""
        return False

    def read_rc(self, channels_us):
        """Write receiver channels in µs; True when a new valid frame arrived since the last call."""
        return False

    def write_motors(self, motor_out, count):
        """Send motor commands: 0 = stop, otherwise idle..1 (the board's output codec encodes them)."""
        raise NotImplementedError

    def write_servos(self, servo_norm, count):
        """Servo positions in -1..1."""

    def read_battery(self, signals):
        """Set signals.battery_v and signals.current_a (0 when not measured)."""

    def set_led(self, on):
        """Status LED."""
