"""The simulator board: the flight core's Board, served by the physics and a pilot.

In lockstep the runner advances the physics, samples the IMU model into this board,
sets the receiver channels from the pilot, then calls Flight.step(now_us). Motor
commands the core writes are what the physics spins next step (one loop of latency,
as on hardware).
"""

from array import array

from hoverfly.compat import TICKS_PERIOD, ticks_add
from hoverfly.core.board import Board

# Start the board clock 3 s before the tick wrap, so every simulated flight crosses it.
BOOT_TICKS_US = TICKS_PERIOD - 3_000_000


class SimBoard(Board):
    name = "sim"

    def __init__(self, motor_count, rx_rate_hz=250):
        self.sim_us = 0
        self.gyro = array("f", [0.0, 0.0, 0.0])
        self.accel = array("f", [0.0, 0.0, -9.80665])
        self.quaternion = array("f", [1.0, 0.0, 0.0, 0.0])
        self.imu_fresh = False
        self.channels_us = array("H", [1500] * 18)
        self.rx_period_us = 1_000_000 // rx_rate_hz
        self._next_frame_us = 0
        self.rx_alive = True
        self.motor_cmd = [0.0] * motor_count
        self.servo_cmd = [0.0] * 4
        self.battery_v = 0.0
        self.current_a = 0.0
        self.led = False
        self.motor_writes = 0

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
        for i in range(4):
            q_out[i] = q[i]
        return True

    def read_rc(self, channels_us):
        if not self.rx_alive or self.sim_us < self._next_frame_us:
            return False
        self._next_frame_us = self.sim_us + self.rx_period_us
        src = self.channels_us
        for i in range(len(channels_us)):
            channels_us[i] = src[i]
        return True

    def write_motors(self, motor_out, count):
        m = self.motor_cmd
        for i in range(count):
            m[i] = motor_out[i]
        self.motor_writes += 1

    def write_servos(self, servo_norm, count):
        for i in range(count):
            self.servo_cmd[i] = servo_norm[i]

    def read_battery(self, signals):
        signals.battery_v = self.battery_v
        signals.current_a = self.current_a

    def set_led(self, on):
        self.led = on
