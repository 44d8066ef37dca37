"""Hardware-in-the-loop on the Pico: the firmware bridge served on USB serial (or a UART).

Takes the bridge frames (protocols/bridge.py) that `hoverfly fly --hil PORT` sends from the
host's simulator; gives back, per step, what the flight core on this chip commanded
(boards/bridge_fw.py does the work). The flight runs on `BridgeBoard`, not on the Rp2Board:
IMU sample, receiver bytes, battery and clock come from the simulator each step, and the
motor outputs go back to it; only the on-board LED is driven, so the flight's blink codes show
on the chip. Nothing drives a motor pin. Sessions follow one another: a host run ends with
QUIT (or dies; its next run's HELLO starts afresh) and the chip waits for the next.

Start it from the host (docs/hil.md):
    mpremote connect PORT exec --no-follow "from hoverfly.boards.rp2.hil import main; main()"
then `hoverfly fly --hil PORT`. Ctrl-C is off while it serves (0x03 is an ordinary frame
byte): press reset or replug the board to leave; main.py then boots the flight as usual.
MicroPython-only.
"""

import sys

from hoverfly.boards.bridge_fw import BridgeBoard, Firmware, serve

DEFAULT_UART_BAUD = 921600


class LedBridgeBoard(BridgeBoard):
    """The bridge's board with the flight's LED on the chip's own LED pin."""

    def __init__(self, led_pin=None):
        BridgeBoard.__init__(self)
        self.led_pin = led_pin

    def set_led(self, on):
        self.led = on
        if self.led_pin is not None:
            self.led_pin.value(1 if on else 0)


class UartStream:
    """A machine.UART as the blocking stream serve() wants: readinto waits for a byte
    (the port returns None when nothing is waiting; serve() takes 0/None as end of stream)."""

    def __init__(self, uart):
        self.uart = uart

    def readinto(self, buf, n=-1):
        u = self.uart
        while True:
            k = u.readinto(buf) if n < 0 else u.readinto(buf, n)
            if k:
                return k

    def write(self, buf, n=-1):
        if n < 0:
            return self.uart.write(buf)
        return self.uart.write(memoryview(buf)[:n])


def _led():
    """The on-board LED pin, or None where there is none (the LED only mirrors the flight's)."""
    try:
        import machine

        from hoverfly.boards.rp2 import pins

        try:
            return machine.Pin(pins.LED, machine.Pin.OUT)
        except (ValueError, TypeError):
            return machine.Pin("LED", machine.Pin.OUT)  # Pico W: the LED sits on the radio chip
    except Exception:  # no machine.Pin (the unix port): serve without it
        return None


def main(uart_id=None, baud=DEFAULT_UART_BAUD, tx=None, rx=None, sessions=-1, led=True):
    """Serve bridge sessions on USB serial (stdin/stdout), or on UART `uart_id` at `baud` on
    pins tx/rx; `sessions` < 0 serves until reset. Returns the number of sessions served."""
    try:
        import micropython

        micropython.kbd_intr(-1)  # a 0x03 byte in a frame must not raise KeyboardInterrupt
    except (ImportError, AttributeError):
        pass
    if uart_id is None:
        stream_in = sys.stdin.buffer
        stream_out = sys.stdout.buffer
    else:
        import machine

        kw = {"rxbuf": 2048, "timeout": 1000}
        if tx is not None:
            kw["tx"] = machine.Pin(tx)
        if rx is not None:
            kw["rx"] = machine.Pin(rx)
        stream_in = stream_out = UartStream(machine.UART(uart_id, baud, **kw))
    pin = _led() if led else None
    served = 0
    while sessions < 0 or served < sessions:
        fw = Firmware(LedBridgeBoard(pin))
        serve(stream_in, stream_out, fw)
        served += 1
        if not fw.done:
            break  # the stream ended (a host-side pipe closed): nothing more will come
    return served
