"""The world around a fake Pico: physics, pilot, IMU register model, receiver bytes, ESCs.

Tests only (runs under MicroPython and CPython). It is the rp2 board's clock (`ticks_us`,
`sleep_us`): whenever the firmware waits, simulated time runs — the physics steps at
1 kHz, each step's body rates and specific force go into the MPU-6050 register model on
the fake I2C bus, the pilot's channels go out as CRSF frames on the fake receiver UART
every 4 ms (250 Hz), the board's machine.Timers fire (the output failsafe), and the newest
DShot word in each PIO state machine's FIFO drives that motor (`world.board`: the state
machines the board has now). So the board's own main loop flies, reading registers and
writing words. `stall(s)` (from a pass hook) is a loop that hangs: time runs, no pass.

Bidirectional DShot: an `EscLine` sits on each motor pin (`rp2.attach_line`; `world.escs`).
The fake state machine clocks the board's bidirectional program against it: the ESC reads
the frame off the driven line (idle high, low pulses, inverted CRC, decoded with timing
tolerance as protocols.pulsetrain does) and answers ~30 µs later with the GCR line code of
its rotor's eRPM, which the program samples. With a bidirectional board the motors run on
what the ESCs decoded from the line, not on the FIFO words.

Judging (`stats`): tilt RMS and max after `judge_from_s`, altitude, crash, whether any
motor ever got a non-stop word (`spun`), and after a stall the time every motor's newest word
became a stop (`stall_stop_s`, from the stall's start).
"""

import math

import machine
import rp2
from regmodels import MPU6050Model

from hoverfly.boards.rp2 import pins as P
from hoverfly.compat import TICKS_PERIOD, ticks_add
from hoverfly.protocols.crsf import RC_FRAME_LEN, encode_rc_frame
from hoverfly.protocols.dshot import (
    SPEEDS_KBIT,
    code_to_levels,
    erpm_reply_word,
    frame_crc_ok,
    frame_value,
    gcr_encode,
)
from hoverfly.protocols.pulsetrain import DshotPulseDecoder
from hoverfly.sim.physics import Vehicle
from hoverfly.sim.pilot import Pilot

BOOT_TICKS_US = TICKS_PERIOD - 3000000  # cross the tick wrap during the run, as the sim does
PHYSICS_US = 1000
RX_PERIOD_US = 4000
_RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)


class EscLine:
    """A bidirectional DShot ESC on one motor line, as a fake rp2 state machine sees it.

    `receive(pulses, freq_hz)` takes what the state machine drove before letting go of the
    pin ([level, cycles] runs). Like a BLHeli_32 / AM32 ESC it wants the line idling high (an
    idle-low line is normal DShot: no reply, counted in `idle_low`), finds the speed from
    the first bit's period, decodes the bits with DshotPulseDecoder's tolerance and accepts
    only the inverted CRC (`errors`, `crc_errors` otherwise; the last command holds). Then,
    with `reply` on, it answers: `delay_us` after the frame's end, 21 GCR levels at 5/4 of
    the bit rate on its own clock (`clock_error`: 0.01 = bits 1 % long), the eRPM of rotor
    `motor` in `omega` (rad/s, the physics' list) or, without one, `erpm`.
    `level(t_cycles)`: the line while the state machine does not drive it (1: pulled up).
    """

    def __init__(self, omega=None, motor=0, poles=14, reply=True, delay_us=30.0, clock_error=0.0):
        self.omega = omega
        self.motor = motor
        self.poles = poles
        self.reply = reply
        self.delay_us = delay_us
        self.clock_error = clock_error
        self.erpm = 0
        self.value = -1  # last command decoded off the line (-1: none yet)
        self.word = -1
        self.speed_kbit = 0
        self.frames = 0
        self.errors = 0
        self.crc_errors = 0
        self.idle_low = 0
        self.replies = 0
        self.code = 0  # the last reply's 21-bit line code
        self._decoders = {}
        self._start_ns = -1.0
        self._ns_per_cycle = 1.0
        self._bit_ns = 1.0
        self._levels = 0

    def reply_erpm(self):
        if self.omega is None:
            return self.erpm
        return int(self.omega[self.motor] * _RPM_PER_RAD_S * (self.poles // 2) + 0.5)

    def receive(self, pulses, freq_hz):
        self._start_ns = -1.0
        if not pulses or pulses[0][0] != 1:
            self.idle_low += 1
            return
        ns_per = 1e9 / freq_hz
        if len(pulses) < 3:
            self.errors += 1
            return
        bit_ns = (pulses[1][1] + pulses[2][1]) * ns_per
        speed = SPEEDS_KBIT[0]
        for s in SPEEDS_KBIT:
            if abs(1e6 / s - bit_ns) < abs(1e6 / speed - bit_ns):
                speed = s
        dec = self._decoders.get(speed)
        if dec is None:
            dec = DshotPulseDecoder(speed, bidir=True)
            self._decoders[speed] = dec
        word = dec.decode([(p[0], int(p[1] * ns_per + 0.5)) for p in pulses[1:]])
        if word is None:
            self.errors += 1
            return
        if not frame_crc_ok(word, True):
            self.crc_errors += 1
            return
        self.frames += 1
        self.word = word
        self.speed_kbit = speed
        self.value = frame_value(word)
        if not self.reply:
            return
        self.code = gcr_encode(erpm_reply_word(self.reply_erpm()))
        self._levels = code_to_levels(self.code)
        self._ns_per_cycle = ns_per
        self._bit_ns = 800000.0 / speed * (1.0 + self.clock_error)  # 5/4 the rate (protocols.md §4.3)
        frame_end_ns = pulses[0][1] * ns_per + 16 * 1e6 / speed
        self._start_ns = frame_end_ns + self.delay_us * 1000.0 * (1.0 + self.clock_error)
        self.replies += 1

    def level(self, t_cycles):
        if self._start_ns < 0.0:
            return 1
        d = t_cycles * self._ns_per_cycle - self._start_ns
        if d < 0.0:
            return 1
        k = int(d / self._bit_ns)
        if k >= 21:
            return 1
        return (self._levels >> (20 - k)) & 1


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
        self.escs = []
        for i in range(self.n):
            esc = EscLine(self.vehicle.omega, i)
            self.escs.append(esc)
            if i < len(P.MOTORS):
                rp2.attach_line(P.MOTORS[i], esc)
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
        bidir = False
        if b is not None:
            sms = b._dshot.sms if b._dshot is not None else []
            bidir = b._dshot is not None and b._dshot.bidir
        for i in range(len(sms)):
            fifo = sms[i].take()
            if fifo:
                self.words_seen += len(fifo)
                # bidirectional: what the ESC read off the line (its last good frame)
                v = self.escs[i].value if bidir else frame_value(fifo[-1] >> 16)
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
