"""Fake `machine` module for off-hardware rp2 runs (tests only; MicroPython and CPython).

Put tests/rp2fakes first on the path and `import machine` finds this. It keeps the rp2
port's API shape (Pin, I2C, SPI, UART, PWM, ADC, Timer, freq, unique_id) and a registry
the test wires before the board boots:

- `attach_i2c(bus_id, device)`: register models (regmodels.py) that answer on I2C bus 0/1;
  `i2c_fail(bus_id, n)` makes the next n transfers raise OSError(EIO) (a bus error).
- `uart(uart_id)`: the UART object the board opened; `inject(data)` queues bytes on its RX
  line (a receiver talking), `tx` collects what the board sent. Safe from two threads (rx_core1 reads
  it on a second thread), as the port's interrupt-fed ring buffers are.
- `Pin.fire(level, t_us)` runs the pin's IRQ handler as the hardware would on an edge.
- `PWM` records freq and duty_ns; `ADC` reads `ADC.values[pin]` (0..65535).
- `Timer`s register here; `run_timers(now_ms)` fires each one whose period came round (the
  world calls it as simulated time passes, so a timer runs whatever the firmware's loop does).

Nothing here sleeps or reads a real clock.
"""

import _thread

EIO = 5
ENODEV = 19

_i2c_devices = {0: [], 1: []}
_i2c_fail = {0: 0, 1: 0}
_uarts = {}
_pins = {}
_pwms = {}
_timers = []
_freq = [125000000]


def reset():
    """Forget every device, UART, pin and PWM (between test runs)."""
    _i2c_devices[0] = []
    _i2c_devices[1] = []
    _i2c_fail[0] = 0
    _i2c_fail[1] = 0
    _uarts.clear()
    _pins.clear()
    _pwms.clear()
    del _timers[:]


def freq(hz=None):
    if hz is None:
        return _freq[0]
    _freq[0] = hz


def unique_id():
    return b"\xe6\x61\x38\x00\x00\x00\x00\x01"


def attach_i2c(bus_id, device):
    _i2c_devices[bus_id].append(device)


def i2c_fail(bus_id, n):
    _i2c_fail[bus_id] = n


def uart(uart_id):
    return _uarts.get(uart_id)


def pin(pin_id):
    return _pins.get(pin_id)


def pwm(pin_id):
    return _pwms.get(pin_id)


class Pin:
    IN = 0
    OUT = 1
    OPEN_DRAIN = 2
    ALT = 3
    PULL_UP = 1
    PULL_DOWN = 2
    IRQ_FALLING = 4
    IRQ_RISING = 8

    def __init__(self, pin_id, mode=-1, pull=-1, value=None):
        self.id = pin_id
        self.mode = mode
        self.pull = pull
        self._value = 0 if value is None else value
        self.handler = None
        self.trigger = 0
        self.hard = False
        self.writes = 0
        _pins[pin_id] = self

    def init(self, mode=-1, pull=-1, value=None):
        self.mode = mode
        if value is not None:
            self._value = value

    def value(self, v=None):
        if v is None:
            return self._value
        self._value = 1 if v else 0
        self.writes += 1

    def on(self):
        self.value(1)

    def off(self):
        self.value(0)

    def toggle(self):
        self.value(0 if self._value else 1)

    def __call__(self, v=None):
        return self.value(v)

    def irq(self, handler=None, trigger=12, hard=False):
        self.handler = handler
        self.trigger = trigger
        self.hard = hard

    def fire(self, level):
        """An edge on this pin: set the level and run the IRQ handler if the trigger matches."""
        self._value = level
        want = self.IRQ_RISING if level else self.IRQ_FALLING
        if self.handler is not None and self.trigger & want:
            self.handler(self)


class I2C:
    def __init__(self, bus_id, scl=None, sda=None, freq=400000, timeout=50000):
        self.id = bus_id
        self.scl = scl
        self.sda = sda
        self.freq = freq
        self.transfers = 0

    def _device(self, addr):
        if _i2c_fail[self.id] > 0:
            _i2c_fail[self.id] -= 1
            raise OSError(EIO)
        for d in _i2c_devices[self.id]:
            if d.address == addr:
                d.check()  # absent -> ENODEV, injected faults -> EIO
                self.transfers += 1
                return d
        raise OSError(ENODEV)

    def scan(self):
        return [d.address for d in _i2c_devices[self.id] if not d.absent]

    def readfrom_mem_into(self, addr, memaddr, buf, addrsize=8):
        self._device(addr).read_into(memaddr, buf, len(buf))

    def readfrom_mem(self, addr, memaddr, nbytes, addrsize=8):
        buf = bytearray(nbytes)
        self._device(addr).read_into(memaddr, buf, nbytes)
        return bytes(buf)

    def writeto_mem(self, addr, memaddr, buf, addrsize=8):
        self._device(addr).write(memaddr, buf)


class SPI:
    """machine.SPI with one register-model device (its `transfer(tx, rx)`) behind it."""

    MSB = 0
    device = None

    def __init__(self, bus_id, baudrate=1000000, polarity=0, phase=0, sck=None, mosi=None, miso=None):
        self.id = bus_id
        self.baudrate = baudrate

    def write_readinto(self, tx, rx):
        if self.device is None:
            for i in range(len(rx)):
                rx[i] = 0xFF  # nothing drives MISO: the pull-up reads 0xFF
            return
        self.device.transfer(tx, rx)


class UART:
    INV_TX = 1
    INV_RX = 2
    IRQ_RXIDLE = 4096

    def __init__(self, uart_id, baudrate=115200, bits=8, parity=None, stop=1, tx=None, rx=None,
                 invert=0, rxbuf=256, timeout=0):
        self.id = uart_id
        self.baudrate = baudrate
        self.bits = bits
        self.parity = parity
        self.stop = stop
        self.tx_pin = tx
        self.rx_pin = rx
        self.invert = invert
        self.rxbuf = rxbuf
        self._rx = bytearray()
        self.tx = bytearray()
        self.overflows = 0
        self._lock = _thread.allocate_lock()
        _uarts[uart_id] = self

    def inject(self, data):
        """Bytes arriving on RX; beyond rxbuf they are lost, as in the port's ring buffer."""
        with self._lock:
            room = self.rxbuf - len(self._rx)
            if len(data) > room:
                self.overflows += 1
                data = data[:room]
            self._rx.extend(data)

    def any(self):
        return len(self._rx)

    def readinto(self, buf, nbytes=-1):
        with self._lock:
            n = len(buf) if nbytes < 0 else nbytes
            if n > len(self._rx):
                n = len(self._rx)
            if n == 0:
                return None  # the rp2 port returns None when nothing is waiting
            for i in range(n):
                buf[i] = self._rx[i]
            self._rx = self._rx[n:]
            return n

    def read(self, nbytes=-1):
        with self._lock:
            n = len(self._rx) if nbytes < 0 else min(nbytes, len(self._rx))
            if n == 0:
                return None
            out = bytes(self._rx[:n])
            self._rx = self._rx[n:]
            return out

    def write(self, data):
        with self._lock:
            self.tx.extend(data)
        return len(data)

    def irq(self, handler=None, trigger=0, hard=False):
        self.handler = handler


class PWM:
    def __init__(self, pin, freq=0, duty_ns=0, duty_u16=0):
        self.pin = pin
        self._freq = freq
        self._duty_ns = duty_ns
        self.history = []
        _pwms[pin.id if hasattr(pin, "id") else pin] = self

    def freq(self, hz=None):
        if hz is None:
            return self._freq
        self._freq = hz

    def duty_ns(self, ns=None):
        if ns is None:
            return self._duty_ns
        self._duty_ns = ns
        if len(self.history) < 64:
            self.history.append(ns)

    def duty_u16(self, v=None):
        if v is None:
            return 0
        self._duty_ns = int(v * 1000000000 // 65535 // (self._freq or 1))

    def deinit(self):
        self._duty_ns = 0


class ADC:
    values = {}

    def __init__(self, pin):
        self.pin = pin.id if hasattr(pin, "id") else pin

    def read_u16(self):
        return ADC.values.get(self.pin, 0)


def run_timers(now_ms):
    """Fire every timer whose next period started at or before now_ms (simulated time)."""
    for t in _timers:
        if t.callback is None:
            continue
        if t.next_ms is None:
            t.next_ms = now_ms + t.period_ms
            continue
        while t.callback is not None and now_ms >= t.next_ms:
            t.next_ms += t.period_ms
            t.fired += 1
            t.callback(t)


def timers():
    return _timers


class Timer:
    PERIODIC = 1
    ONE_SHOT = 0

    def __init__(self, timer_id=-1, mode=1, freq=0, period=0, callback=None, hard=False):
        self.fired = 0
        self.init(mode, freq, period, callback, hard)
        _timers.append(self)

    def init(self, mode=1, freq=0, period=0, callback=None, hard=False):
        self.callback = callback
        self.freq = freq
        self.mode = mode
        self.hard = hard
        self.period_ms = period if period else (1000 // freq if freq else 1000)
        self.next_ms = None  # armed on the first run_timers call

    def deinit(self):
        self.callback = None


class WDT:
    def __init__(self, id=0, timeout=5000):
        self.timeout = timeout
        self.feeds = 0

    def feed(self):
        self.feeds += 1
