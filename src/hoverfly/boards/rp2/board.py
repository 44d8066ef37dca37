"""The Raspberry Pi Pico board: the flight core's Board on real rp2 peripherals.

Takes the pin map (pins.py), a configuration (which IMU, receiver protocol and motor
protocol) and the parameters; gives the core its IMU samples (drivers over machine.I2C /
SPI), receiver bytes or pulse edges (machine.UART; hard pin IRQs storing edge
timestamps), motor outputs (DShot through PIO state machines, PWM/OneShot through
machine.PWM), a servo, battery voltage and current (ADC), the status LED, parameter
storage in a flash file, and two serial ports: USB (CLI/MSP) and UART0 (HC-05
maintenance link). MicroPython-only: this is the one place that imports `machine`.

Faults are a bit field (`faults`, FAULT_*; `fault_names()`), the board's built-in-test
record: IMU missing or unsupported at boot, IMU bus errors in flight, receiver silent,
receiver bytes that never make a frame, motor outputs that failed to start. Each shows as
a blink code on the LED (`led_pattern`) and in `status_line()`, printed whenever the set
changes. A fault that blinds the flight (no IMU) also stops the motors here, under the
core's own disarm.

The clock is injectable (`clock=`: an object with ticks_us() and sleep_us(us)), so the
very same board runs off-hardware under MicroPython against the fakes of tests/rp2fakes.
"""

import sys
from array import array

import machine

from hoverfly.boards.rp2 import pins as P
from hoverfly.compat import ticks_diff
from hoverfly.core.board import Board
from hoverfly.protocols import analog
from hoverfly.protocols.dshot import DshotEncoder

FAULT_IMU_ABSENT = 1  # no IMU answered at boot, wrong chip, or an IMU type this board does not know
FAULT_IMU_BUS = 2  # the IMU stopped answering in flight (consecutive bus errors)
FAULT_RX_SILENT = 4  # not one byte / edge on the receiver input since boot: wrong pin, no power
FAULT_RX_GARBAGE = 8  # bytes arrive but never a valid frame: wrong protocol, baud or inversion
FAULT_OUTPUT = 16  # the motor outputs could not be started
FAULT_NAMES = ("imu_absent", "imu_bus_error", "rx_silent", "rx_no_frames", "output_failed")

IMU_TYPES = ("mpu6050", "bno055", "lsm9ds1", "icm42688", "auto")
RX_TYPES = ("crsf", "sbus", "ibus", "ppm", "pwm")
DSHOT_KBIT = {"dshot150": 150, "dshot300": 300, "dshot600": 600, "dshot1200": 1200}
ANALOG = {"pwm": analog.PWM, "oneshot125": analog.ONESHOT125, "oneshot42": analog.ONESHOT42,
          "multishot": analog.MULTISHOT}
ANALOG_RATE_HZ = {"pwm": 490, "oneshot125": 2000, "oneshot42": 4000, "multishot": 8000}

IMU_BUS_ERRORS_FAULT = 5  # consecutive failed reads before the IMU counts as lost (5 ms at 1 kHz)
RX_SILENT_MS = 1000  # no byte this long after boot: the receiver is not where we listen
_EDGE_RING = 128  # edge ring: 64 (code, t_us) pairs; 6 PWM channels × 2 edges × 50 Hz = 600 edges/s


def led_pattern(faults, t_ms):
    """Blink code of the lowest fault: n flashes of 100 ms, 200 ms apart, then 1.2 s dark.

    1 IMU absent, 2 IMU bus error, 3 receiver silent, 4 receiver bytes without frames,
    5 outputs failed. Without a fault the flight's own pattern shows (seed 000: blink
    once a second disarmed, steady armed).
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


class Rp2Board(Board):
    """See the module docstring. `setup(params)` at boot, then the Board methods."""

    name = "rp2"

    def __init__(self, imu="mpu6050", rx="crsf", motors="dshot600", motor_count=4, clock=None,
                 storage_path="/hoverfly.params", usb=True, maint=True, imu_orientation=None):
        self.imu_type = imu
        self.rx_type = rx
        self.motor_protocol = motors
        self.motor_count = motor_count
        self.clock = clock if clock is not None else _TimeClock()
        self._ticks_us = self.clock.ticks_us
        self.storage_path = storage_path
        self.use_usb = usb
        self.use_maint = maint
        self.imu_orientation = imu_orientation
        self.faults = 0
        self.flight = None  # main() attaches it: the health check reads its receiver counters
        self.status = ""
        self.imu = None
        self.imu_status = "not started"
        self.imu_read_errors = 0
        self._imu_error_run = 0
        self._uart = None
        self.rx_ok_type = False  # a supported receiver was set up (the flight's receiver decodes it)
        self._rx_frames = 0
        self.rx_bytes = 0
        self.rx_edges = 0
        self._edges = array("i", [0] * _EDGE_RING)
        self._edge_head = 0
        self._edge_tail = 0
        self._edge_pins = []
        self._maint = None
        self._poll = None
        self._dshot = None
        self._words = array("H", [0] * 8)
        self._encoder = None
        self._pwms = []
        self._analog = -1
        self._servo = None
        self._adc_v = None
        self._adc_a = None
        self._led = None
        self._boot_us = 0
        self._printed_faults = -1
        self.print_status = True

    # --------------------------------------------------------------------- boot
    def setup(self, params=None):
        """Start every peripheral; returns the fault bits (0 = all well). Never raises on a
        missing device: the fault is recorded and the board keeps the motors stopped."""
        self._boot_us = self._ticks_us()
        try:
            self._led = machine.Pin(P.LED, machine.Pin.OUT)
        except (ValueError, OSError):
            self._led = None
        self._setup_imu()
        self._setup_rx()
        self._setup_outputs()
        try:
            self._adc_v = machine.ADC(machine.Pin(P.ADC_BATTERY))
            self._adc_a = machine.ADC(machine.Pin(P.ADC_CURRENT))
        except (ValueError, OSError):
            self._adc_v = self._adc_a = None
        if self.use_maint:
            self._maint = machine.UART(P.MAINT_UART_ID, P.MAINT_BAUD, tx=machine.Pin(P.MAINT_TX),
                                       rx=machine.Pin(P.MAINT_RX))
        if self.use_usb:
            import select

            self._poll = select.poll()
            self._poll.register(sys.stdin, select.POLLIN)
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
                if kind == "auto":
                    from hoverfly.drivers.imu import detect_i2c

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
            what = imu.status_name if imu is not None else "absent"
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

    def _setup_outputs(self):
        proto = self.motor_protocol
        n = self.motor_count
        try:
            if proto in DSHOT_KBIT:
                from hoverfly.boards.rp2.dshot_pio import DshotPio

                self._encoder = DshotEncoder(n, stop_at_zero=True)
                self._dshot = DshotPio(P.MOTORS[:n], DSHOT_KBIT[proto])
            elif proto in ANALOG:
                self._analog = ANALOG[proto]
                stop_ns = analog.pulse_ns(self._analog, 0.0)
                for i in range(n):
                    self._pwms.append(machine.PWM(machine.Pin(P.MOTORS[i]), freq=ANALOG_RATE_HZ[proto],
                                                  duty_ns=stop_ns))
            else:
                self.faults |= FAULT_OUTPUT
                self.output_status = "unsupported motor protocol '%s'" % proto
                return
            self._servo = machine.PWM(machine.Pin(P.SERVO), freq=50, duty_ns=1500000)
        except (OSError, ValueError) as exc:
            self.faults |= FAULT_OUTPUT
            self.output_status = "%s failed: %s" % (proto, exc)
            return
        self.output_status = "%s on GP%s" % (proto, ",GP".join([str(p) for p in P.MOTORS[:n]]))
        self.stop_motors()

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
        self.rx_bytes += n
        return n

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
    def write_motors(self, motor_out, count):
        # SAFETY: with no IMU the flight is blind; whatever the core asks, the motors stop.
        if self.faults & (FAULT_IMU_ABSENT | FAULT_IMU_BUS | FAULT_OUTPUT):
            self.stop_motors()
            return
        if self._dshot is not None:
            words = self._words
            self._encoder.encode_motors(motor_out, True, words)
            self._dshot.put(words, count)
        elif self._analog >= 0:
            pwms = self._pwms
            proto = self._analog
            for i in range(count if count < len(pwms) else len(pwms)):
                pwms[i].duty_ns(analog.pulse_ns(proto, motor_out[i]))

    def stop_motors(self):
        """Every motor line to its stop value (DShot 0 / the protocol's minimum pulse)."""
        if self._dshot is not None:
            words = self._words
            self._encoder.encode_motors(words, False, words)
            self._dshot.put(words, self.motor_count)
        elif self._analog >= 0:
            stop_ns = analog.pulse_ns(self._analog, 0.0)
            for p in self._pwms:
                p.duty_ns(stop_ns)

    def write_servos(self, servo_norm, count):
        if self._servo is not None and count > 0:
            self._servo.duty_ns(int(analog.servo_pulse_us(servo_norm[0]) * 1000.0))

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
        since_boot_ms = ticks_diff(self._ticks_us(), self._boot_us) // 1000
        receiver = getattr(self.flight, "receiver", None)
        if self.rx_ok_type and receiver is not None and since_boot_ms > RX_SILENT_MS:
            got = self.rx_bytes + self.rx_edges
            frames = receiver.frames
            f = self.faults & ~(FAULT_RX_SILENT | FAULT_RX_GARBAGE)
            if got == 0:
                f |= FAULT_RX_SILENT
            elif frames == 0:
                f |= FAULT_RX_GARBAGE
            self.faults = f
        if self.faults != self._printed_faults:
            self._report()

    def _report(self):
        self._printed_faults = self.faults
        self.status = self.status_line()
        if self.print_status:
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
        try:
            with open(self.storage_path, "rb") as f:
                return f.read()
        except OSError:
            return None

    def save_storage(self, image):
        """Write the image to a temporary file, then rename it over the old one: a cut
        write leaves the previous file whole (littlefs renames atomically)."""
        import os

        tmp = self.storage_path + ".tmp"
        try:
            with open(tmp, "wb") as f:
                f.write(image)
            os.rename(tmp, self.storage_path)
        except OSError:
            return False
        return True

    # ------------------------------------------------------------ Board: serial
    def serial_read(self, port, buf):
        if port == 1:  # SERIAL_MAINT: the HC-05 UART
            u = self._maint
            if u is None or not u.any():
                return 0
            return u.readinto(buf) or 0
        if self._poll is None:
            return 0
        n = 0
        read = sys.stdin.buffer.readinto
        one = self._one if hasattr(self, "_one") else self._new_one()
        while n < len(buf) and self._poll.poll(0):
            if not read(one, 1):
                break
            buf[n] = one[0]
            n += 1
        return n

    def _new_one(self):
        self._one = bytearray(1)
        return self._one

    def serial_write(self, port, data, n=-1):
        if n < 0 or n > len(data):
            n = len(data)
        if port == 1:
            if self._maint is None:
                return 0
            return self._maint.write(data[:n] if n < len(data) else data) or 0
        if not self.use_usb:
            return 0
        sys.stdout.buffer.write(data[:n] if n < len(data) else data)
        return n


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
