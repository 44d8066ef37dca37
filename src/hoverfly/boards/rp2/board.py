"""The Raspberry Pi Pico board: the flight core's Board on real rp2 peripherals.

Takes the pin map (pins.py), a configuration (which IMU and receiver protocol) and the
parameters; gives the core its IMU samples (drivers over machine.I2C / SPI), receiver bytes
or pulse edges (machine.UART; hard pin IRQs storing edge timestamps), motor outputs, a
servo, battery voltage and current (ADC), the status LED, parameter storage in a flash file
(written whole to a temporary file, then renamed over the old one) and two serial ports:
USB (SERIAL_CONFIG: CLI + MSP) and UART0 (SERIAL_MAINT: the HC-05 maintenance link).
MicroPython-only: this is the one place that imports `machine`.

Outputs go through the core's output codec (core/stages/output.py `OutputEncoder`, set up by
`configure_outputs` from `motor_protocol`, `motor_order`, `output_fs_ms` ...): DShot words
into one PIO state machine per output line (dshot_pio.py), or PWM/OneShot/Multishot widths
as machine.PWM duty. A machine.Timer (OUTPUT_TIMER_MS) runs the encoder's output failsafe
whatever the loop does: once no fresh command came for `output_fs_ms` it puts the disarmed
values on every line, each tick, until commands resume.

Faults are a bit field (`faults`, FAULT_*; `fault_names()`), the board's built-in-test
record: IMU missing or unsupported at boot, IMU bus errors in flight, receiver silent,
receiver bytes that never make a frame, motor outputs that failed to start or a set-up they
cannot drive, the receiver's loop on core 1 stopped (rx_core1). Each shows as a blink code
on the LED (`led_pattern`) and in `status_line()`, printed whenever the set changes (not
while a USB configuration session is open: it would land in the MSP stream). A fault that
blinds the flight (no IMU) or breaks the outputs also stops the motors here, under the
core's own disarm.

Ctrl-C: MicroPython turns a 0x03 byte on USB into KeyboardInterrupt, and MSP frames carry
0x03 bytes (MSP_FC_VERSION is command 3). From the first byte a configurator sends, the board
turns that off (`micropython.kbd_intr(-1)`) and turns it back on once the flight is disarmed,
no session is open and USB has been quiet for USB_IDLE_MS (docs/pico.md).

The clock is injectable (`clock=`: an object with ticks_us() and sleep_us(us)), and so is the
USB port (`usb=`: True for stdin/stdout, or an object with read(buf) / write(data, n)), so
the very same board runs off-hardware under MicroPython against the fakes of tests/rp2fakes.
"""

import sys
from array import array

import machine

from hoverfly.boards.rp2 import pins as P
from hoverfly.compat import ticks_diff
from hoverfly.core.board import SERIAL_CONFIG, SERIAL_MAINT, Board
from hoverfly.core.stages.output import MAX_SERVOS, OutputEncoder

FAULT_IMU_ABSENT = 1  # no IMU answered at boot, wrong chip, or an IMU type this board does not know
FAULT_IMU_BUS = 2  # the IMU stopped answering in flight (consecutive bus errors)
FAULT_RX_SILENT = 4  # not one byte / edge on the receiver input since boot: wrong pin, no power
FAULT_RX_GARBAGE = 8  # bytes arrive but never a valid frame: wrong protocol, baud or inversion
FAULT_OUTPUT = 16  # the motor outputs could not be started, or cannot drive this set-up
FAULT_RX_CORE = 32  # rx_core1: the receiver's loop on core 1 stopped on an error (the link falls silent)
FAULT_NAMES = ("imu_absent", "imu_bus_error", "rx_silent", "rx_no_frames", "output_failed", "rx_core1_stopped")
# SAFETY: with any of these standing, write_motors sends stop values whatever the core asks.
STOP_FAULTS = FAULT_IMU_ABSENT | FAULT_IMU_BUS | FAULT_OUTPUT

IMU_TYPES = ("mpu6050", "bno055", "lsm9ds1", "icm42688", "auto")
RX_TYPES = ("crsf", "sbus", "ibus", "ppm", "pwm")

# The output failsafe's timer: 10 ms, so the outputs are disarmed at most output_fs_ms + 10 ms
# after the last command (seed 002's 100 ms becomes <= 110 ms).
OUTPUT_TIMER_MS = 10
# USB quiet this long (and no session, disarmed): Ctrl-C interrupts again. A configurator polls
# several times a second while it is connected, so 3 s of silence means it went away.
USB_IDLE_MS = 3000

IMU_BUS_ERRORS_FAULT = 5  # consecutive failed reads before the IMU counts as lost (5 ms at 1 kHz)
RX_SILENT_MS = 1000  # no byte this long after boot: the receiver is not where we listen
_EDGE_RING = 128  # edge ring: 64 (code, t_us) pairs; 6 PWM channels × 2 edges × 50 Hz = 600 edges/s


def led_pattern(faults, t_ms):
    """Blink code of the lowest fault: n flashes of 100 ms, 200 ms apart, then 1.2 s dark.

    1 IMU absent, 2 IMU bus error, 3 receiver silent, 4 receiver bytes without frames,
    5 outputs failed, 6 the receiver loop on core 1 stopped. Without a fault the flight's own
    pattern shows (seed 000: blink once a second disarmed, steady armed).
    """
    n = 0
    f = faults
    while f:
        n += 1
        if f & 1:
            break
        f >>= 1
    slot = (t_ms // 100) % (3 * n + 12)
    return slot < 3 * n and slot % 3 == 0


class _TimeClock:
    """The hardware clock (MicroPython `time`)."""

    def __init__(self):
        import time

        self.ticks_us = time.ticks_us
        self.sleep_us = time.sleep_us


class UsbStdio:
    """USB CDC through MicroPython's stdin/stdout: non-blocking reads by select.poll.

    read(buf) -> bytes copied (0 when none); write(data, n) -> bytes taken. The rp2 port's
    stdout drops output while no host has the port open; while one has, a full buffer waits
    (the port's own short timeout), so replies stay small (MSP, CLI lines)."""

    def __init__(self):
        import select

        self._poll = select.poll()
        self._poll.register(sys.stdin, select.POLLIN)
        self._in = sys.stdin.buffer
        self._out = sys.stdout.buffer
        self._one = bytearray(1)

    def read(self, buf):
        n = 0
        one = self._one
        poll = self._poll.poll
        read = self._in.readinto
        size = len(buf)
        while n < size and poll(0):
            if not read(one):
                break
            buf[n] = one[0]
            n += 1
        return n

    def write(self, data, n):
        self._out.write(data if n >= len(data) else memoryview(data)[:n])
        return n


class Rp2Board(Board):
    """See the module docstring. `setup(params)` at boot, then the Board methods."""

    name = "rp2"

    def __init__(self, imu="mpu6050", rx="crsf", motors="dshot600", motor_count=4, clock=None,
                 storage_path="/hoverfly.params", usb=True, maint=True, imu_orientation=None):
        self.imu_type = imu
        self.rx_type = rx
        self.motor_protocol = motors  # only for setup() without parameters; else `motor_protocol`
        self.motor_count = motor_count
        self.clock = clock if clock is not None else _TimeClock()
        self._ticks_us = self.clock.ticks_us
        self.storage_path = storage_path
        self.use_usb = usb
        self.use_maint = maint
        self.imu_orientation = imu_orientation
        self.faults = 0
        self.flight = None  # main() attaches it: the health check reads its receiver counters
        self.storage = None  # main() attaches it: the health check feeds `failed` to the built-in test
        self.status = ""
        self.imu = None
        self.imu_status = "not started"
        self._i2c = None  # the IMU's machine.I2C (bus P.I2C_ID): the maintenance I2C commands use it too
        self.i2c_errors = 0
        self.imu_read_errors = 0
        self._imu_error_run = 0
        self._uart = None
        self.rx_ok_type = False  # a supported receiver was set up (the flight's receiver decodes it)
        self.rx_status = "not started"
        # Receiver bytes read, all told, in an array word: with rx_core1 core 1 counts them (a word store,
        # not an attribute store into the board's table while core 0 may grow it).
        self.rx_counts = array("i", [0])
        self.rx_edges = 0
        self._rx_link = None  # rxcore.RxLink while core 1 parses the receiver (start_rx_core1)
        self._edges = array("i", [0] * _EDGE_RING)
        self._edge_head = 0
        self._edge_tail = 0
        self._edge_pins = []
        self._maint = None
        self._usb = None
        # outputs: the core's codec, and what carries its lines
        self.output = OutputEncoder()
        self.output_status = "not started"
        self._output_fault = False  # the last configure_outputs could not start or drive the set-up
        self._output_key = None  # (protocol, lines, rate): rebuild the hardware only when it changes
        self._dshot = None
        self._pwms = []
        self._stop_ns = 0  # the protocol's disarmed pulse, precomputed: the timer allocates nothing
        self._servos = []  # machine.PWM per servo line (pins.SERVOS), at servo_pwm_rate
        self._zeros = array("f", [0.0] * len(P.MOTORS))
        self._timer = None
        self.timer_ticks = 0
        self._adc_v = None
        self._adc_a = None
        self._led = None
        self._boot_us = 0
        self._rx_watch = False  # the receiver checks start RX_SILENT_MS after boot (latched: ticks wrap)
        self._printed_faults = -1
        self.print_status = True
        # Ctrl-C on USB (see the module docstring)
        self.ctrl_c_enabled = True
        self._usb_seen = False
        self._usb_last_us = 0
        import micropython  # after hoverfly.compat: CPython's stub has no kbd_intr

        self._kbd_intr = getattr(micropython, "kbd_intr", None)

    # --------------------------------------------------------------------- boot
    def setup(self, params=None):
        """Start every peripheral; returns the fault bits (0 = all well). Never raises on a
        missing device: the fault is recorded and the board keeps the motors stopped.
        With params the outputs start too (Flight.configure calls configure_outputs again)."""
        self._boot_us = self._ticks_us()
        try:
            self._led = machine.Pin(P.LED, machine.Pin.OUT)
        except (ValueError, OSError):
            self._led = None
        self._setup_imu()
        self._setup_rx()
        if params is None:
            from hoverfly.core.config.params import Params

            params = Params()
            err = params.set("motor_protocol", self.motor_protocol)
            if err:
                self.faults |= FAULT_OUTPUT
                self.output_status = "unsupported motor protocol '%s'" % self.motor_protocol
                self._output_fault = True
        if not self._output_fault:
            self.configure_outputs(params, self.motor_count, 0)
        try:
            self._adc_v = machine.ADC(machine.Pin(P.ADC_BATTERY))
            self._adc_a = machine.ADC(machine.Pin(P.ADC_CURRENT))
        except (ValueError, OSError):
            self._adc_v = self._adc_a = None
        if self.use_maint:
            self._maint = machine.UART(P.MAINT_UART_ID, P.MAINT_BAUD, tx=machine.Pin(P.MAINT_TX),
                                       rx=machine.Pin(P.MAINT_RX))
        usb = self.use_usb
        if usb is True:
            self._usb = UsbStdio()
        elif usb:
            self._usb = usb  # an injected port (tests): read(buf), write(data, n)
        self._report()
        return self.faults

    def _setup_imu(self):
        from hoverfly.drivers.orientation import Orientation

        orient = self.imu_orientation if self.imu_orientation is not None else Orientation()
        kind = self.imu_type
        delay = self.clock.sleep_us
        imu = None
        try:
            if kind == "icm42688":
                from hoverfly.drivers.icm42688 import ICM42688

                spi = machine.SPI(P.SPI_ID, baudrate=P.SPI_BAUD_HZ, polarity=1, phase=1,
                                  sck=machine.Pin(P.SPI_SCK), mosi=machine.Pin(P.SPI_MOSI),
                                  miso=machine.Pin(P.SPI_MISO))
                imu = ICM42688(_SpiDevice(spi, machine.Pin(P.SPI_CS, machine.Pin.OUT, value=1)), orient, delay)
                ok = imu.configure()
            elif kind in IMU_TYPES:
                i2c = machine.I2C(P.I2C_ID, scl=machine.Pin(P.I2C_SCL), sda=machine.Pin(P.I2C_SDA),
                                  freq=P.I2C_FREQ_HZ)
                self._i2c = i2c
                if kind == "auto":
                    from hoverfly.drivers.detect import detect_i2c

                    imu = detect_i2c(i2c, orient, delay)
                    ok = imu is not None
                else:
                    if kind == "mpu6050":
                        from hoverfly.drivers.mpu6050 import MPU6050 as Cls
                    elif kind == "bno055":
                        from hoverfly.drivers.bno055 import BNO055 as Cls
                    else:
                        from hoverfly.drivers.lsm9ds1 import LSM9DS1 as Cls
                    imu = Cls(i2c, orient, delay_us=delay)
                    ok = imu.configure()
            else:
                self.imu_status = "unsupported IMU '%s' (one of %s)" % (kind, ", ".join(IMU_TYPES))
                self.faults |= FAULT_IMU_ABSENT
                return
        except OSError as exc:  # a bus that cannot even be opened
            self.imu_status = "%s: bus error %s" % (kind, exc)
            self.faults |= FAULT_IMU_ABSENT
            return
        if not ok:
            what = imu.status_name() if imu is not None else "absent"
            self.imu_status = "%s %s on %s" % (kind, what, self._imu_where())
            self.faults |= FAULT_IMU_ABSENT
            self.imu = None
            return
        self.imu = imu
        self.imu_status = "%s ok" % imu.name

    def _imu_where(self):
        if self.imu_type == "icm42688":
            return "spi%d (cs GP%d)" % (P.SPI_ID, P.SPI_CS)
        return "i2c%d (sda GP%d, scl GP%d)" % (P.I2C_ID, P.I2C_SDA, P.I2C_SCL)

    def _setup_rx(self):
        kind = self.rx_type
        if kind not in RX_TYPES:
            self.faults |= FAULT_RX_SILENT
            self.rx_status = "unsupported receiver '%s'" % kind
            return
        self.rx_ok_type = True
        U = machine.UART
        if kind == "crsf":
            self._uart = U(P.RX_UART_ID, 420000, tx=machine.Pin(P.RX_TX), rx=machine.Pin(P.RX_RX),
                           rxbuf=P.RX_BUF_BYTES)
        elif kind == "sbus":
            # 8E2, and the inverted line turned upright by the pad's input override (no inverter).
            self._uart = U(P.RX_UART_ID, 100000, bits=8, parity=0, stop=2, tx=machine.Pin(P.RX_TX),
                           rx=machine.Pin(P.RX_RX), invert=U.INV_RX, rxbuf=P.RX_BUF_BYTES)
        elif kind == "ibus":
            self._uart = U(P.RX_UART_ID, 115200, tx=machine.Pin(P.RX_TX), rx=machine.Pin(P.RX_RX),
                           rxbuf=P.RX_BUF_BYTES)
        else:
            pins = P.RX_PWM[:1] if kind == "ppm" else P.RX_PWM
            Pin = machine.Pin
            for ch in range(len(pins)):
                p = Pin(pins[ch], Pin.IN, Pin.PULL_DOWN)
                p.irq(self._edge_handler(ch), Pin.IRQ_RISING | Pin.IRQ_FALLING, hard=True)
                self._edge_pins.append(p)
        self.rx_status = "%s on %s" % (kind, self._rx_where())

    def _rx_where(self):
        if self.rx_type in ("ppm", "pwm"):
            n = 1 if self.rx_type == "ppm" else len(P.RX_PWM)
            return "GP" + ",GP".join([str(p) for p in P.RX_PWM[:n]])
        return "uart%d rx GP%d" % (P.RX_UART_ID, P.RX_RX)

    def _edge_handler(self, channel):
        ring = self._edges
        size = len(ring)
        ticks = self._ticks_us
        code_base = channel * 2
        board = self

        # Hard IRQ: no allocation, no floats: two small ints into the preallocated ring.
        def on_edge(pin):
            i = board._edge_head
            ring[i] = code_base + pin.value()
            ring[i + 1] = ticks()
            i += 2
            if i >= size:
                i = 0
            board._edge_head = i

        return on_edge

    # ------------------------------------------------------------- Board: clock
    def now_us(self):
        return self._ticks_us()

    def wait_until(self, deadline_us):
        """Sleep until the tick clock reaches deadline_us (the main loop's pacing)."""
        left = ticks_diff(deadline_us, self._ticks_us())
        if left > 0:
            self.clock.sleep_us(left)

    # --------------------------------------------------------------- Board: IMU
    def read_imu(self, gyro_rad_s, accel_m_s2):
        imu = self.imu
        if imu is None:
            return False
        errors = imu.bus_errors
        if imu.read(gyro_rad_s, accel_m_s2):
            self._imu_error_run = 0
            return True
        if imu.bus_errors != errors:  # a failed transfer, not just "no new sample"
            self.imu_read_errors += 1
            self._imu_error_run += 1
            if self._imu_error_run >= IMU_BUS_ERRORS_FAULT:
                self.faults |= FAULT_IMU_BUS
        return False

    def read_attitude(self, q_out):
        imu = self.imu
        if imu is None or not hasattr(imu, "read_attitude"):
            return False
        return imu.read_attitude(q_out)

    # ---------------------------------------------------------- Board: receiver
    def read_rx(self, buf):
        """Receiver UART bytes since the last call into buf; their count."""
        u = self._uart
        if u is None:
            return 0
        n = u.readinto(buf) if u.any() else 0
        if not n:
            return 0
        c = self.rx_counts
        c[0] = (c[0] + n) & 0x3FFFFFFF
        return n

    def start_rx_core1(self, receiver, start=None):
        """rx_core1: the serial receiver's UART and codec move to core 1 (core/stages/rxcore.py); the flight's
        receiver task takes the frames it publishes. `start(fn, args)` starts core 1 (_thread's
        start_new_thread). False, and nothing changes, for a pin-edge receiver or no receiver."""
        if self._uart is None:
            return False
        from hoverfly.core.stages.rxcore import RxLink

        link = RxLink()
        core = receiver.use_core1(link)
        if core is None:
            return False
        if start is None:
            import _thread

            start = _thread.start_new_thread
        self._rx_link = link
        start(core.run, (self,))
        self.rx_status = "%s on %s, parsed on core 1" % (self.rx_type, self._rx_where())
        return True

    def stop_rx_core1(self):
        """Core 1's receiver loop returns (main() on its way back to the REPL); True once it has, within
        50 of its idle rests."""
        link = self._rx_link
        if link is None:
            return True
        from hoverfly.compat import sleep_us
        from hoverfly.core.stages.rxcore import IDLE_US, W_RUNNING, W_STOP

        w = link.words
        w[W_STOP] = 1
        for _ in range(50):
            if not w[W_RUNNING]:
                return True
            sleep_us(IDLE_US)
        return False

    def read_rx_edges(self, edges):
        """PWM/PPM edges captured by the pin IRQs: (channel*2 + level, t_us) pairs; their count."""
        ring = self._edges
        size = len(ring)
        tail = self._edge_tail
        head = self._edge_head
        n = 0
        limit = len(edges) - 1
        while tail != head and n < limit:
            edges[n] = ring[tail]
            edges[n + 1] = ring[tail + 1]
            n += 2
            tail += 2
            if tail >= size:
                tail = 0
        self._edge_tail = tail
        self.rx_edges += n >> 1
        return n >> 1

    def write_rx(self, data, n):
        if self._uart is not None and n > 0:
            self._uart.write(data[:n] if n < len(data) else data)

    # ------------------------------------------------------------ Board: motors
    def configure_outputs(self, params, motor_count, servo_count):
        """Boot, and while disarmed after a parameter change: the codec reads the output
        parameters; the PIO state machines / PWM slices are rebuilt only when the protocol,
        line count or rate changed. Every line starts at its disarmed value."""
        enc = self.output
        lines = len(P.MOTORS)
        notes = []
        if motor_count > lines:
            notes.append("%d motors, %d output pins" % (motor_count, lines))
        enc.configure(params, motor_count if motor_count < lines else lines, servo_count, self._ticks_us())
        if enc.error:
            notes.append(enc.error)
        n = enc.motor_count
        self._output_fault = False
        if motor_count > lines:
            self._output_fault = True
        # bidir picks the PIO program (inverted line + reply receiver, dshot_pio.py): a change rebuilds
        key = (enc.protocol, n, enc.rate_hz, enc.servo_count, enc.servo_rate_hz, enc.bidir)
        try:
            if key != self._output_key:
                self._stop_hardware()
                if enc.dshot:
                    from hoverfly.boards.rp2.dshot_pio import DshotPio

                    self._dshot = DshotPio(P.MOTORS[:n], enc.speed_kbit, bidir=enc.bidir)
                else:
                    for line in range(n):
                        self._pwms.append(machine.PWM(machine.Pin(P.MOTORS[line]), freq=enc.rate_hz,
                                                      duty_ns=int(enc.min_us * 1000.0)))
                for i in range(enc.servo_count if enc.servo_count < len(P.SERVOS) else len(P.SERVOS)):
                    self._servos.append(machine.PWM(machine.Pin(P.SERVOS[i]), freq=enc.servo_rate_hz,
                                                    duty_ns=enc.servo_mid[i] * 1000))
                self._output_key = key
            self._stop_ns = int(enc.min_us * 1000.0)
            self._send_lines()
            self._start_timer()
        except (OSError, ValueError, RuntimeError) as exc:
            self._stop_hardware()
            self._output_key = None
            notes.append("failed: %s" % exc)
            self._output_fault = True
        if self._output_fault:
            self.faults |= FAULT_OUTPUT
        else:
            self.faults &= ~FAULT_OUTPUT
        where = "GP" + ",GP".join([str(p) for p in P.MOTORS[:n]])
        if self._servos:
            where += ", servos GP" + ",GP".join([str(p) for p in P.SERVOS[:len(self._servos)]])
        self.output_status = "%s on %s%s" % (enc.protocol, where, ("; " + "; ".join(notes)) if notes else "")
        return self.faults & FAULT_OUTPUT == 0

    def _stop_hardware(self):
        if self._dshot is not None:
            self._dshot.stop()
            self._dshot = None
        for p in self._pwms:
            p.deinit()
        for p in self._servos:
            p.deinit()
        self._pwms = []
        self._servos = []

    def _start_timer(self):
        if self._timer is None:
            self._timer = machine.Timer(-1, mode=machine.Timer.PERIODIC, period=OUTPUT_TIMER_MS,
                                        callback=self._output_tick)

    def _output_tick(self, timer):
        """The output timer (OUTPUT_TIMER_MS), whatever the loop does: the output failsafe.

        # SAFETY: while the codec's tick says no fresh command came for output_fs_ms, every
        # line gets its disarmed value again, each tick (DShot 0 keeps the ESCs fed with stops).
        Precomputed ints only: nothing here allocates."""
        self.timer_ticks += 1
        if not self.output.tick(self._ticks_us()):
            return
        if self._dshot is not None:
            self._dshot.put(self.output.words, self.output.motor_count)
        else:
            ns = self._stop_ns
            for p in self._pwms:
                p.duty_ns(ns)
        mid = self.output.servo_mid  # ints: the timer allocates nothing
        servos = self._servos
        for i in range(len(servos)):
            servos[i].duty_ns(mid[i] * 1000)

    def _send_lines(self):
        """Every line's current value from the codec onto its state machine / PWM slice."""
        enc = self.output
        if self._dshot is not None:
            self._dshot.put(enc.words, enc.motor_count)
        else:
            pulse = enc.pulse_us
            pwms = self._pwms
            for line in range(len(pwms)):
                pwms[line].duty_ns(int(pulse[line] * 1000.0))

    def write_motors(self, motor_out, count):
        # SAFETY: with no IMU the flight is blind, and a broken output set-up may drive the wrong
        # signal: whatever the core asks, every motor gets its stop value (a fresh command, so the
        # output failsafe does not also trip).
        if self.faults & STOP_FAULTS:
            motor_out = self._zeros
        self.output.write(motor_out, count, self._ticks_us())
        self._send_lines()

    def stop_motors(self):
        """Every motor line to its stop value now (DShot 0 / the protocol's minimum pulse)."""
        if self._output_key is None:
            return
        self.output.write(self._zeros, self.output.motor_count, self._ticks_us())
        self._send_lines()

    def write_servos(self, servo_us, count):
        enc = self.output
        enc.write_servos(servo_us, count, self._ticks_us())
        widths = enc.servo_us
        servos = self._servos
        for i in range(len(servos) if len(servos) < MAX_SERVOS else MAX_SERVOS):
            servos[i].duty_ns(widths[i] * 1000)

    def read_motor_telemetry(self, codes, count):
        """Bidirectional DShot replies, motor order: the PIO side keeps them per line.

        poll() drains the state machines' RX FIFOs without blocking; a line whose ESC did not
        answer its last frame reads 0 (no start bit: the decoder counts it), counted in
        `_dshot.missed`."""
        d = self._dshot
        if d is None or not d.poll():
            return False
        d.fresh = False
        replies = d.replies
        lines = self.output.line_of_motor
        n = count if count < self.output.motor_count else self.output.motor_count
        for m in range(n):
            codes[m] = replies[lines[m]]
        return True

    # ------------------------------------------------------------ Board: others
    def read_battery(self, signals):
        if self._adc_v is None:
            return
        # read_u16 spans 0..65535 over 0..3.3 V.
        signals.battery_v = self._adc_v.read_u16() * (3.3 / 65535.0) * P.BATTERY_DIVIDER
        signals.current_a = self._adc_a.read_u16() * (3.3 / 65535.0) * P.CURRENT_A_PER_V

    def set_led(self, on):
        """Called by the flight's LED task (10 Hz): also the board's health check."""
        self._health()
        if self.faults:
            on = led_pattern(self.faults, self._ticks_us() // 1000)
        if self._led is not None:
            self._led.value(1 if on else 0)

    def _health(self):
        now = self._ticks_us()
        if not self._rx_watch:
            # Latched once on: the tick clock wraps every 2**30 us, and the time since boot would read small
            # again every 18 minutes.
            self._rx_watch = ticks_diff(now, self._boot_us) > RX_SILENT_MS * 1000
        flight = self.flight
        receiver = getattr(flight, "receiver", None)
        if self.rx_ok_type and receiver is not None and self._rx_watch:
            got = self.rx_counts[0] + self.rx_edges
            frames = receiver.frames
            f = self.faults & ~(FAULT_RX_SILENT | FAULT_RX_GARBAGE)
            if got == 0:
                f |= FAULT_RX_SILENT
            elif frames == 0:
                f |= FAULT_RX_GARBAGE
            self.faults = f
        link = self._rx_link
        if link is not None and link.fault is not None and not self.faults & FAULT_RX_CORE:
            self.faults |= FAULT_RX_CORE
            self.rx_status = "%s on %s, core 1 stopped: %r" % (self.rx_type, self._rx_where(), link.fault)
        bit = getattr(flight, "bit", None)
        if bit is not None:
            # The built-in test's storage check follows the store (a good save clears it).
            if self.storage is not None:
                bit.storage_ok = not self.storage.failed
            if hasattr(bit, "board_faults"):
                bit.board_faults = self.faults
        self._ctrl_c(now)
        if self.faults != self._printed_faults:
            self._report()

    def _ctrl_c(self, now):
        """Ctrl-C back on once disarmed, no session open and USB quiet for USB_IDLE_MS."""
        if self.ctrl_c_enabled:
            return
        f = self.flight
        if f is not None and (f.arming.armed or f.config_session):
            return
        # A negative difference is a last byte more than half the tick period (about 9 minutes) ago: quiet.
        if 0 <= ticks_diff(now, self._usb_last_us) < USB_IDLE_MS * 1000:
            return
        self._set_ctrl_c(True)

    def restore_ctrl_c(self):
        """Ctrl-C interrupts again (main() on its way back to the REPL)."""
        if not self.ctrl_c_enabled:
            self._set_ctrl_c(True)

    def _set_ctrl_c(self, on):
        self.ctrl_c_enabled = on
        if self._kbd_intr is not None:
            self._kbd_intr(3 if on else -1)

    def _report(self):
        self._printed_faults = self.faults
        self.status = self.status_line()
        # Not while a USB session is open: the line would land inside the configurator's MSP stream.
        if self.print_status and self.ctrl_c_enabled:
            print(self.status)

    def fault_names(self):
        out = []
        for i in range(len(FAULT_NAMES)):
            if self.faults & (1 << i):
                out.append(FAULT_NAMES[i])
        return out

    def status_line(self):
        """One line: each device and the faults (boot, every change, CLI `status`)."""
        faults = self.fault_names()
        return "hoverfly rp2: imu %s | rx %s | motors %s | faults %s" % (
            self.imu_status, getattr(self, "rx_status", "-"), getattr(self, "output_status", "-"),
            ",".join(faults) if faults else "none")

    # ----------------------------------------------------------- Board: storage
    def load_storage(self):
        """The parameter image from the flash file; None when nothing was ever saved. A save cut
        between removing the old file and the rename (file systems without an atomic rename
        over an existing file) leaves the new image whole in the temporary file: load that."""
        for path in (self.storage_path, self.storage_path + ".tmp"):
            try:
                with open(path, "rb") as f:
                    return f.read()
            except OSError:
                pass
        return None

    def save_storage(self, image):
        """Write the whole image to a temporary file, then rename it over the old one: a cut
        write leaves the previous file whole (littlefs, the rp2 port's file system, renames
        atomically). Flash writes stall the chip for milliseconds: the core saves only while
        disarmed. True when written."""
        import os

        path = self.storage_path
        tmp = path + ".tmp"
        try:
            with open(tmp, "wb") as f:
                f.write(image)
            try:
                os.rename(tmp, path)
            except OSError:  # a file system that will not rename over an existing file
                os.remove(path)
                os.rename(tmp, path)
        except OSError:
            return False
        return True

    # ------------------------------------------------------------ Board: serial
    def serial_read(self, port, buf):
        if port == SERIAL_MAINT:  # the HC-05 UART
            u = self._maint
            if u is None or not u.any():
                return 0
            return u.readinto(buf) or 0
        if port != SERIAL_CONFIG or self._usb is None:
            return 0
        n = self._usb.read(buf)
        if n > 0:
            # A configurator is talking: from its first byte a 0x03 inside an MSP frame must not
            # become a KeyboardInterrupt (which would end the loop).
            self._usb_seen = True
            self._usb_last_us = self._ticks_us()
            if self.ctrl_c_enabled:
                self._set_ctrl_c(False)
        return n

    def serial_write(self, port, data, n=-1):
        if n < 0 or n > len(data):
            n = len(data)
        if port == SERIAL_MAINT:
            if self._maint is None:
                return 0
            return self._maint.write(data if n == len(data) else memoryview(data)[:n]) or 0
        if port != SERIAL_CONFIG or self._usb is None:
            return 0
        return self._usb.write(data, n)

    # ------------------------------------------------------------ maintenance: I2C (seed 001 commands 22-23)
    def _i2c_bus(self, bus):
        """The machine.I2C of `bus`, or the reason there is none. Only the IMU's bus has pins on this board."""
        if bus != P.I2C_ID:
            return None, "I2C%d has no pins on this board: the IMU bus is I2C%d" % (bus, P.I2C_ID)
        if self._i2c is None:  # an SPI IMU: the I2C pads are free, open the bus on them
            try:
                self._i2c = machine.I2C(P.I2C_ID, scl=machine.Pin(P.I2C_SCL), sda=machine.Pin(P.I2C_SDA),
                                        freq=P.I2C_FREQ_HZ)
            except (ValueError, OSError) as exc:
                return None, "I2C%d cannot be opened: %s" % (bus, exc)
        return self._i2c, None

    def i2c_read(self, bus, address, register):
        """One register byte (0..255) read through machine.I2C, or the reason it could not be (a str).
        The maintenance server calls it only while disarmed (it shares the IMU's bus)."""
        i2c, why = self._i2c_bus(bus)
        if i2c is None:
            return why
        try:
            return i2c.readfrom_mem(address, register, 1)[0]
        except OSError as exc:
            self.i2c_errors += 1
            return "I2C%d 0x%02x register 0x%02x: no answer (%s)" % (bus, address, register, exc)

    def i2c_write(self, bus, address, register, value):
        """Write one register byte through machine.I2C: None, or the reason it failed (a str)."""
        i2c, why = self._i2c_bus(bus)
        if i2c is None:
            return why
        try:
            i2c.writeto_mem(address, register, bytes((value & 0xFF,)))
        except OSError as exc:
            self.i2c_errors += 1
            return "I2C%d 0x%02x register 0x%02x: write not acknowledged (%s)" % (bus, address, register, exc)
        return None


class _SpiDevice:
    """The drivers' small SPI bus (`transfer(tx, rx)`, docs/drivers.md) on machine.SPI + a CS pin."""

    def __init__(self, spi, cs):
        self.spi = spi
        self.cs = cs

    def transfer(self, tx, rx):
        self.cs.value(0)
        try:
            self.spi.write_readinto(tx, rx)
        finally:
            self.cs.value(1)
