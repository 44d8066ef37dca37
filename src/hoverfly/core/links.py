"""Configuration links: the board's serial ports served by MSP + CLI and the maintenance protocol.

Takes the Flight, its Board's serial seam (`serial_read(port, buf)`, `serial_write(port, data, n)`)
and a Storage; gives one scheduler task (`ConfigLinks.task(now_us)`, 100 Hz by `attach`) that
moves waiting bytes into the servers and their replies out. Port SERIAL_CONFIG carries MSP and
the CLI as Betaflight does (a `#` between MSP frames enters the CLI, `exit` returns to MSP); port
SERIAL_MAINT carries the seed-001 maintenance protocol. A read of -1 means the peer went away:
that port's session closes (CLI left, MSP arming lock and maintenance motor control released).
Sits beside the flight pass as a slow task; a pass never waits on a port.
"""

from hoverfly.core.board import SERIAL_CONFIG, SERIAL_MAINT
from hoverfly.core.cliserver import CliServer
from hoverfly.core.maintserver import MaintServer
from hoverfly.core.mspserver import MspServer

LINKS_HZ = 100
_READ_BYTES = 512
_HASH = 0x23  # '#'


class ConfigPort:
    """MSP and the CLI sharing one byte stream."""

    def __init__(self, flight, storage=None):
        self.msp = MspServer(flight, storage)
        self.cli = CliServer(flight, storage)

    def feed(self, data, n, write):
        mv = memoryview(data)
        i = 0
        while i < n:
            if self.cli.active:
                self.cli.feed(mv[i:n], n - i, write)
                return  # bytes typed after 'exit' in the same chunk are dropped, as a reboot would
            # MSP until a '#' arrives while no frame is half received.
            j = i
            while j < n and data[j] != _HASH:
                j += 1
            if j > i:
                self.msp.feed(mv[i:j], j - i, write)
            if j >= n:
                return
            if self.msp.in_frame():
                self.msp.feed(mv[j:j + 1], 1, write)  # a '#' inside a frame's payload
                i = j + 1
                continue
            self.cli.enter(write)
            i = j + 1

    def close(self):
        self.cli.close()
        self.msp.close()


class ConfigLinks:
    def __init__(self, flight, storage=None):
        self.flight = flight
        self.board = flight.board
        self.storage = storage
        self.config = ConfigPort(flight, storage)
        self.maint = MaintServer(flight, storage)
        self._buf = bytearray(_READ_BYTES)
        self.dropped_bytes = 0  # replies the port had no room for
        self._writers = (self._write_config, self._write_maint)
        self._servers = ((SERIAL_CONFIG, self.config), (SERIAL_MAINT, self.maint))  # built once: no tuples per run

    def _write(self, port, data):
        n = len(data)
        took = self.board.serial_write(port, data, n)
        if took < n:
            self.dropped_bytes += n - took

    def _write_config(self, data):
        self._write(SERIAL_CONFIG, data)

    def _write_maint(self, data):
        self._write(SERIAL_MAINT, data)

    def task(self, now_us):
        board = self.board
        buf = self._buf
        if self.storage is not None:  # the built-in test follows the storage: a good save clears it
            self.flight.bit.storage_ok = not self.storage.failed
        for port, server in self._servers:
            for _ in range(4):  # at most 2 KiB per port per run: a flood cannot hog the task
                n = board.serial_read(port, buf)
                if n < 0:
                    server.close()
                    break
                if n == 0:
                    break
                server.feed(buf, n, self._writers[port])


def attach(flight, storage=None, rate_hz=LINKS_HZ):
    """Add the links task to the flight's scheduler; returns the ConfigLinks."""
    links = ConfigLinks(flight, storage)
    flight.scheduler.add("links", rate_hz, links.task)  # due at once if the scheduler already started
    return links
