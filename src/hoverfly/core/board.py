"""The Board: the flight core's one seam to the world.

`sim`, `linux` and `rp2` boards implement these methods; the core never asks which
board it runs on. Values cross the seam in SI units in the body frame FRD.
"""

from array import array

from hoverfly.compat import TICKS_PERIOD, ticks_add


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

    def read_rx(self, buf):
        """Receiver UART (CRSF, SBUS, iBUS): copy up to len(buf) bytes received since the last
        call into buf, oldest first; return how many (0 if none). Allocates nothing. The line
        settings (baud, parity, inversion) are the board's business, from `rx_provider`."""
        return 0

    def read_rx_edges(self, edges):
        """Receiver pins (PPM, PWM): pulse edges captured since the last call, oldest first, as
        pairs edges[2k] = channel_index * 2 + level (1 rising, 0 falling; PPM: channel 0) and
        edges[2k + 1] = compat ticks µs of the edge; at most len(edges) // 2 of them. Returns
        the number of edges written (0 if none)."""
        return 0

    def write_rx(self, data, n):
        """Send the first n bytes of data to the receiver on the same UART (CRSF telemetry).
        May drop them when the transmit buffer is full; never blocks the loop."""

    def write_motors(self, motor_out, count):
        """Send motor commands: 0 = stop, otherwise idle..1 (the board's output codec encodes them).

        The board owns its codec (core.stages.output.OutputEncoder: protocol, motor order, DShot
        commands) and its output timer, which calls the encoder's `tick(now_us)` whatever the
        pass does: a pass that stops calling this for `output_fs_ms` finds every output
        disarmed (the output failsafe)."""
        raise NotImplementedError

    def configure_outputs(self, params, motor_count, servo_count):
        """Boot (and while disarmed): read the output parameters into the board's output codec."""

    def read_motor_telemetry(self, codes, count):
        """Bidirectional DShot: the ESCs' latest replies as 21-bit GCR line codes (start bit
        included), codes[m] for motor m (motor order, not output order). True when new replies
        arrived since the last call; False (codes untouched) otherwise or without bidir."""
        return False

    def write_servos(self, servo_us, count):
        """Servo pulse widths in µs, servo_us[0..count-1] (the servo mixer's, core/stages/servos.py); the
        codec's output failsafe puts each at its servoN_mid_us when they stop coming."""

    def read_battery(self, signals):
        """Set signals.battery_v and signals.current_a (0 when not measured)."""

    def read_airspeed(self):
        """A pitot's indicated airspeed in m/s (a plane's differential-pressure sensor), or None when the
        board has no airspeed sensor (a quad, a plane flying without one)."""
        return None

    def set_led(self, on):
        """Status LED."""

    # --- configuration links: parameter storage and serial ports (core/config/storage.py, core/links/task.py)
    def load_storage(self):
        """The stored parameter image (bytes), or None when nothing was ever saved."""
        return None

    def save_storage(self, image):
        """Write the whole parameter image in place (bytes the storage did not change stay as
        they were, so a cut write damages one slot only); True when written."""
        return False

    def serial_read(self, port, buf):
        """Copy bytes waiting on serial port `port` (SERIAL_CONFIG = CLI + MSP, SERIAL_MAINT =
        maintenance protocol) into buf; return the count, 0 when none, -1 once when the peer went
        away (the session on that port ends). Never blocks."""
        return 0

    def serial_write(self, port, data, n=-1):
        """Queue the first n bytes (all if n < 0) of data for `port`; return how many were taken
        (fewer when the port's buffer is full: the caller drops the rest). Never blocks."""
        return 0


SERIAL_CONFIG = 0
SERIAL_MAINT = 1


# A board fed from outside starts its clock 3 s before the tick wrap (2**30 on rp2), so every
# simulated or bridged flight crosses the wrap.
BOOT_TICKS_US = TICKS_PERIOD - 3000000


class SampledBoard(Board):
    """A board whose clock and IMU samples are pushed in from outside: the simulator's physics
    (sim/board.py) or the firmware bridge's step frames (boards/bridge_fw.py)."""

    def __init__(self):
        self.sim_us = 0
        self.gyro = array("f", [0.0, 0.0, 0.0])
        self.accel = array("f", [0.0, 0.0, -9.80665])
        self.quaternion = array("f", [1.0, 0.0, 0.0, 0.0])
        self.imu_fresh = False

    def now_us(self):
        return ticks_add(BOOT_TICKS_US, self.sim_us)

    def read_imu(self, gyro_rad_s, accel_m_s2):
        if not self.imu_fresh:
            return False
        g = self.gyro
        a = self.accel
        gyro_rad_s[0] = g[0]
        gyro_rad_s[1] = g[1]
        gyro_rad_s[2] = g[2]
        accel_m_s2[0] = a[0]
        accel_m_s2[1] = a[1]
        accel_m_s2[2] = a[2]
        self.imu_fresh = False
        return True

    def read_attitude(self, q_out):
        q = self.quaternion
        q_out[0] = q[0]
        q_out[1] = q[1]
        q_out[2] = q[2]
        q_out[3] = q[3]
        return True
