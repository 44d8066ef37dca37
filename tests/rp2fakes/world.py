"""The world around a fake Pico: physics, pilot, IMU register model, receiver bytes, ESCs.

Tests only (runs under MicroPython and CPython). It is the rp2 board's clock (`ticks_us`,
`sleep_us`): whenever the firmware waits, simulated time runs — the physics steps at
1 kHz, each step's body rates and specific force go into the MPU-6050 register model on
the fake I2C bus, the pilot's channels go out as CRSF frames on the fake receiver UART
every 4 ms (250 Hz), the board's machine.Timers fire (the output failsafe), and the newest
DShot word in each PIO state machine's FIFO drives that motor (`world.board`: the state
machines the board has now). So the board's own main loop flies, reading registers and
writing words. `stall(s)` (from a pass hook) is a loop that hangs: time runs, no pass.

Judging (`stats`): tilt RMS and max after `judge_from_s`, altitude, crash, whether any
motor ever got a non-stop word (`spun`), and after a stall the time every motor's newest word
became a stop (`stall_stop_s`, from the stall's start).
"""

import math

import machine
from regmodels import MPU6050Model

from hoverfly.compat import TICKS_PERIOD, ticks_add
from hoverfly.protocols.crsf import RC_FRAME_LEN, encode_rc_frame
from hoverfly.protocols.dshot import frame_value
from hoverfly.sim.physics import Vehicle
from hoverfly.sim.pilot import Pilot

BOOT_TICKS_US = TICKS_PERIOD - 3000000  # cross the tick wrap during the run, as the sim does
PHYSICS_US = 1000
RX_PERIOD_US = 4000


class World:
    def __init__(self, airframe, frame="quadx", rx_uart_id=1, judge_from_s=5.0, noise_lsb=2, seed=1):
        self.t_us = 0
        self.vehicle = Vehicle(airframe, frame)
        self.n = self.vehicle.n
        self.channels = [1500] * 16
        self.channels[2] = 1000
        self.channels[4] = 1000
        self.pilot = Pilot(self.channels, "angle")
        v = self.vehicle
        omega_max = v.omega_per_volt * v.battery.voltage_v
        u = v.hover_omega() / omega_max
        self.pilot.hover_guess = max(0.05, (u - 0.055) / (1.0 - 0.055)) * 0.9
        self.mpu = MPU6050Model(noise_lsb=noise_lsb, seed=seed)
        self.mpu.set_motion((0.0, 0.0, 0.0), (0.0, 0.0, -9.80665))
        machine.attach_i2c(0, self.mpu)
        self.rx_uart_id = rx_uart_id
        self.rx_alive = True
        self._rx_frame = bytearray(RC_FRAME_LEN)
        self._next_rx_us = 0
        self.sms = []
        self.board = None  # an Rp2Board: its DShot state machines drive the motors
        self.stall_at_s = -1.0
        self.stall_stop_s = -1.0
        self.motor_cmd = [0.0] * self.n
        self.spun = False
        self.last_spin_s = -1.0
        self.words_seen = 0
        self.script = []  # (t_s, fn(world)) in time order
        self.judge_from_s = judge_from_s
        self.tilt_sq = 0.0
        self.tilt_n = 0
        self.tilt_max_deg = 0.0
        self.alt_max_m = 0.0
        self._g = [0.0, 0.0, 0.0]
        self._a = [0.0, 0.0, -9.80665]

    # ---------------------------------------------------------------- the clock
    def ticks_us(self):
        return ticks_add(BOOT_TICKS_US, self.t_us)

    def sleep_us(self, us):
        end = self.t_us + us
        while True:
            nxt = (self.t_us // PHYSICS_US + 1) * PHYSICS_US
            if nxt > end:
                break
            self.t_us = nxt
            self._physics_step()
        self.t_us = end

    # ------------------------------------------------------------- the physics
    def stall(self, seconds):
        """The firmware's loop hangs for `seconds`: simulated time (physics, timers) runs on."""
        self.stall_at_s = self.t_us * 1e-6
        self.stall_stop_s = -1.0
        self.sleep_us(int(seconds * 1e6))

    def _motors(self):
        sms = self.sms
        b = self.board
        if b is not None:
            sms = b._dshot.sms if b._dshot is not None else []
        for i in range(len(sms)):
            fifo = sms[i].take()
            if fifo:
                self.words_seen += len(fifo)
                v = frame_value(fifo[-1] >> 16)
                if v >= 48:
                    self.spun = True
                    self.last_spin_s = self.t_us * 1e-6
                    self.motor_cmd[i] = (v - 48) / 1999.0
                else:
                    self.motor_cmd[i] = 0.0  # stop (0) or a command (1..47)
        if self.stall_at_s >= 0.0 and self.stall_stop_s < 0.0 and sms:
            for c in self.motor_cmd:
                if c != 0.0:
                    return
            self.stall_stop_s = self.t_us * 1e-6 - self.stall_at_s

    def _physics_step(self):
        t_s = self.t_us * 1e-6
        while self.script and self.script[0][0] <= t_s:
            self.script.pop(0)[1](self)
        v = self.vehicle
        euler = v.euler_rad()
        dt = PHYSICS_US * 1e-6
        self.pilot.update(t_s, dt, v, euler)
        machine.run_timers(self.t_us // 1000)
        self._motors()
        v.step(dt, self.motor_cmd)
        g = self._g
        a = self._a
        g[0] = v.p
        g[1] = v.q
        g[2] = v.r
        a[0] = v.fx
        a[1] = v.fy
        a[2] = v.fz
        self.mpu.set_motion(g, a)
        if self.rx_alive and self.t_us >= self._next_rx_us:
            self._next_rx_us = self.t_us + RX_PERIOD_US
            u = machine.uart(self.rx_uart_id)
            if u is not None:
                encode_rc_frame(self.channels, self._rx_frame)
                u.inject(self._rx_frame)
        self._judge(t_s, euler)

    def _judge(self, t_s, euler):
        v = self.vehicle
        alt = v.altitude_m()
        if alt > self.alt_max_m:
            self.alt_max_m = alt
        if t_s >= self.judge_from_s and not v.on_ground:
            c = math.cos(euler[0]) * math.cos(euler[1])
            c = 1.0 if c > 1.0 else (-1.0 if c < -1.0 else c)
            tilt = math.acos(c) * 57.29577951308232
            self.tilt_sq += tilt * tilt
            self.tilt_n += 1
            if tilt > self.tilt_max_deg:
                self.tilt_max_deg = tilt

    # ---------------------------------------------------------------- scripting
    def at(self, t_s, fn):
        self.script.append((t_s, fn))
        self.script.sort(key=lambda e: e[0])

    def stats(self):
        v = self.vehicle
        return {
            "t_s": self.t_us * 1e-6,
            "tilt_rms_deg": math.sqrt(self.tilt_sq / self.tilt_n) if self.tilt_n else 0.0,
            "tilt_max_deg": self.tilt_max_deg,
            "alt_m": v.altitude_m(),
            "alt_max_m": self.alt_max_m,
            "crashed": bool(v.crashed),
            "spun": self.spun,
            "last_spin_s": self.last_spin_s,
            "words": self.words_seen,
            "stall_stop_s": self.stall_stop_s,
        }


def arm(world):
    world.pilot.arm = True


def hold(alt_m):
    def fn(world):
        world.pilot.set_hold(alt_m, world.vehicle)

    return fn
