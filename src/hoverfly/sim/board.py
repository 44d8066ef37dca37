"""The simulator board: the flight core's Board, served by the physics and a pilot.

In lockstep the runner advances the physics, samples the IMU model into this board,
lets the pilot set the transmitter's channels, then calls Flight.step(now_us). The
receiver bytes or edges for those channels arrive through sim/rxlink.py with the wire's
timing. Its I2C bus 0 (the maintenance protocol's commands 22-23: `i2c_read` / `i2c_write`) holds
the MPU-6050's register model (sim/regmodels.py) at 0x68, its data registers fed from the IMU
sample the core last got. Motor commands the core writes cross the wire: the board's output codec
(core/stages/output.py) encodes them for `motor_protocol`, simulated ESCs (sim/esc.py) decode them
into what the physics spins next step (one loop of latency, as on hardware), and the output
timer (`output_tick`) keeps the output failsafe.
"""

import random
from array import array

from hoverfly.core.board import BOOT_TICKS_US, SampledBoard
from hoverfly.core.config.params import Params
from hoverfly.core.stages.output import OutputEncoder, dshot_speed_kbit
from hoverfly.protocols.pulsetrain import ReplyPulseDecoder, render_analog, render_dshot, render_reply
from hoverfly.sim.esc import SimEsc, SimServo
from hoverfly.sim.regmodels import MPU6050Model
from hoverfly.sim.rxlink import RxLink
from hoverfly.sim.storagefile import load_storage_file, save_storage_file

_TELEMETRY_KEEP = 65536  # bytes of CRSF telemetry kept for tests and tools
# A hobby pitot (an MS4525DO-class differential-pressure sensor) reads within a few tenths of a m/s at cruise
# once zeroed; 0.3 m/s of white noise a 50 Hz sample is that, not a sensor model.
PITOT_NOISE_M_S = 0.3


class SimBoard(SampledBoard):
    name = "sim"

    def __init__(self, motor_count, rx="crsf", rx_pwm_channels=6):
        SampledBoard.__init__(self)
        # Receiver wire: the pilot writes channels_us, the transmitter/receiver model turns them
        # into real frames (sim/rxlink.py); rx_alive is the scenario's switch for the radio link.
        self.channels_us = array("H", [1500] * 18)
        self.rx_alive = True
        self.rx_link = RxLink(rx, self.channels_us, rx_pwm_channels)
        self.telemetry_out = bytearray()  # what the flight core sent to the receiver (CRSF telemetry)
        self.telemetry_bytes = 0
        self.motor_cmd = [0.0] * motor_count  # what the ESCs drive the motors to: the physics reads it
        self.servo_cmd = [0.0] * 4
        self._init_escs(motor_count)
        self.battery_v = 0.0
        self.current_a = 0.0
        self.led = False
        self.motor_writes = 0
        self.pitot_plane = None  # a plane's JSBSim model (sim/plane.py) when a pitot is fitted: fit_pitot
        self._pitot_rng = None
        # The IMU's registers on I2C bus 0, awake as a driver leaves it at boot (PWR_MGMT_1 = 0).
        self.i2c_devices = {0: [MPU6050Model()], 1: []}
        self.i2c_devices[0][0].write(0x6B, b"\x00")

    def read_rx(self, buf):
        link = self.rx_link
        link.advance(self.sim_us, self.rx_alive)
        return link.take_bytes(buf)

    def read_rx_edges(self, edges):
        link = self.rx_link
        link.advance(self.sim_us, self.rx_alive)
        return link.take_edges(edges, BOOT_TICKS_US)

    def write_rx(self, data, n):
        out = self.telemetry_out
        out += data[:n]
        self.telemetry_bytes += n
        if len(out) > _TELEMETRY_KEEP:
            del out[:len(out) - _TELEMETRY_KEEP]

    # --- motor and servo outputs: the core's output codec -> the wire -> simulated ESCs (sim/esc.py)
    def _init_escs(self, motor_count):
        self.motor_count = motor_count
        self.output = OutputEncoder()  # the board's output codec, configured by Flight.configure
        self.esc_protocol = "dshot600"
        self.esc_line = False  # True: every frame crosses the pulse-train model (slow; tests)
        self.escs = [SimEsc("dshot600") for _ in range(motor_count)]
        self.servos = [SimServo() for _ in range(4)]
        self.rotor_omega_rad_s = None  # the physics' rotor speeds (a list), for the eRPM replies
        self.motor_telemetry = [0] * motor_count  # latest reply line codes, motor order
        self._telemetry_new = False
        self.output.configure(Params(), motor_count, 0, self.now_us())

    def set_escs(self, protocol, motor_poles=14, line=False, mode_3d=False):
        """Fit ESCs that speak `protocol` (a motor_protocol name), with the motors' pole count."""
        self.esc_protocol = protocol
        self.esc_line = line
        if line and dshot_speed_kbit(protocol):
            self._reply_decoder = ReplyPulseDecoder(dshot_speed_kbit(protocol))
        self.escs = [SimEsc(protocol, motor_poles, mode_3d=mode_3d) for _ in range(self.motor_count)]

    def configure_outputs(self, params, motor_count, servo_count):
        self.output.configure(params, motor_count, servo_count, self.now_us())
        self._send_lines()

    def write_motors(self, motor_out, count):
        self.output.write(motor_out, count, self.now_us())
        self.motor_writes += 1
        self._send_lines()

    def write_servos(self, servo_us, count):
        out = self.output
        out.write_servos(servo_us, count, self.now_us())
        for i in range(out.servo_count):  # the servos read their new pulse now, not at the next motor write
            self.servo_cmd[i] = self.servos[i].receive_pulse_us(out.servo_us[i])

    def output_tick(self):
        """The board's output timer, run every simulated loop period whatever the flight core does:
        the output failsafe's watchdog. True while it holds the outputs at their disarmed values."""
        if self.output.tick(self.now_us()):
            self._send_lines()
            return True
        return False

    def read_motor_telemetry(self, codes, count):
        if not self._telemetry_new:
            return False
        src = self.motor_telemetry
        for i in range(min(count, len(src))):
            codes[i] = src[i]
        self._telemetry_new = False
        return True

    def _send_lines(self):
        """Put every output line on the wire once; the ESCs decode it into the motor commands."""
        out = self.output
        escs = self.escs
        cmd = self.motor_cmd
        line = self.esc_line
        if out.dshot and not out.bidir and not line:
            # The usual wire (DShot words, no replies), taken without the per-line choices below.
            words = out.words
            motor_of_line = out.motor_of_line
            for ln in range(out.motor_count):
                esc = escs[ln]
                if esc.dshot:
                    cmd[motor_of_line[ln]] = esc.receive_word(words[ln])
                else:
                    cmd[motor_of_line[ln]] = esc.throttle_norm  # an analog ESC cannot read DShot: it holds
                    esc.errors += 1
            for i in range(out.servo_count):
                self.servo_cmd[i] = self.servos[i].receive_pulse_us(out.servo_us[i])
            return
        omega = self.rotor_omega_rad_s
        for ln in range(out.motor_count):
            m = out.motor_of_line[ln]
            esc = escs[ln]
            if esc.dshot != out.dshot:
                cmd[m] = esc.throttle_norm  # an ESC cannot read the other family's signal: it holds
                esc.errors += 1
                continue
            if esc.dshot:
                w = out.words[ln]
                if line:
                    cmd[m] = esc.receive_line(render_dshot(w, esc.speed_kbit, out.bidir))
                else:
                    cmd[m] = esc.receive_word(w)
                if esc.bidir:
                    w_rad_s = omega[m] if omega is not None else 0.0
                    if line:  # the reply crosses the line too: GCR levels at 5/4 of the bit rate
                        code = self._reply_decoder.decode_code(render_reply(esc.reply_word(w_rad_s), esc.speed_kbit))
                        self.motor_telemetry[m] = 0 if code is None else code
                    else:
                        self.motor_telemetry[m] = esc.reply_code(w_rad_s)
                    self._telemetry_new = True
            elif line:
                period_ns = 1_000_000_000 // out.rate_hz
                cmd[m] = esc.receive_analog_line(render_analog(int(out.pulse_us[ln] * 1000 + 0.5), period_ns))
            else:
                cmd[m] = esc.receive_pulse_us(out.pulse_us[ln])
        for i in range(out.servo_count):
            self.servo_cmd[i] = self.servos[i].receive_pulse_us(out.servo_us[i])

    # --- maintenance I2C (seed 001 commands 22-23) against the register models
    def _i2c_device(self, bus, address):
        for d in self.i2c_devices.get(bus, ()):
            if d.address == address and not d.absent:
                return d
        return None

    def i2c_read(self, bus, address, register):
        """One register byte of the model at `address`, or the reason there is none (a str)."""
        d = self._i2c_device(bus, address)
        if d is None:
            return "I2C%d 0x%02x: no device answers" % (bus, address)
        d.set_motion(self.gyro, self.accel)
        buf = bytearray(1)
        try:
            d.read_into(register, buf, 1)
        except OSError as exc:
            return "I2C%d 0x%02x register 0x%02x: no answer (%s)" % (bus, address, register, exc)
        return buf[0]

    def i2c_write(self, bus, address, register, value):
        """Write one register byte of the model: None, or the reason it failed (a str)."""
        d = self._i2c_device(bus, address)
        if d is None:
            return "I2C%d 0x%02x: no device answers" % (bus, address)
        try:
            d.check()
            d.write(register, bytes((value & 0xFF,)))
        except OSError as exc:
            return "I2C%d 0x%02x register 0x%02x: write not acknowledged (%s)" % (bus, address, register, exc)
        return None

    def read_battery(self, signals):
        signals.battery_v = self.battery_v
        signals.current_a = self.current_a

    def fit_pitot(self, plane, seed):
        """A pitot on this plane: read_airspeed gives its airspeed with noise from the run's seed."""
        self.pitot_plane = plane
        self._pitot_rng = random.Random(seed * 7919 + 23)

    def read_airspeed(self):
        plane = self.pitot_plane
        if plane is None:
            return None  # a quad: no pitot
        # JSBSim's true airspeed: up to the 300 m the scenarios fly at, indicated is within 2 % of it.
        v = plane.airspeed_m_s + self._pitot_rng.gauss(0.0, PITOT_NOISE_M_S)
        return v if v > 0.0 else 0.0

    def set_led(self, on):
        self.led = on

    # --- configuration links: storage file and serial ports (sim/server.py serves them over TCP)
    storage_path = None  # `hoverfly sim --storage PATH`: the parameter image lives in this file
    serial = None  # a sim.server.TcpPorts (or any object with read(port, buf) / write(port, data, n))

    def load_storage(self):
        return load_storage_file(self.storage_path)

    def save_storage(self, image):
        return save_storage_file(self.storage_path, image)

    def serial_read(self, port, buf):
        return 0 if self.serial is None else self.serial.read(port, buf)

    def serial_write(self, port, data, n=-1):
        return 0 if self.serial is None else self.serial.write(port, data, n)
