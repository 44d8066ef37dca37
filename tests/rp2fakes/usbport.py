"""A fake USB CDC port for the rp2 board's `usb=` (tests only; MicroPython and CPython).

The board's real port is stdin/stdout (board.UsbStdio); this one has the same two calls,
`read(buf)` (non-blocking, the count) and `write(data, n)`, plus `inject(data)` for the host
side's bytes and `tx` for what the board sent.
"""


class UsbPort:
    def __init__(self):
        self._rx = bytearray()
        self.tx = bytearray()
        self.reads = 0

    def inject(self, data):
        self._rx.extend(data)

    def read(self, buf):
        n = len(buf) if len(buf) < len(self._rx) else len(self._rx)
        for i in range(n):
            buf[i] = self._rx[i]
        self._rx = self._rx[n:]
        self.reads += 1
        return n

    def write(self, data, n):
        self.tx.extend(bytes(data[:n]))
        return n
