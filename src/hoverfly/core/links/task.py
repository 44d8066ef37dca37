"""Configuration links: the board's serial ports served by MSP, the CLI and the maintenance protocol.

Takes the Flight, its Board's serial seam (`serial_read(port, buf)`, `serial_write(port, data, n)`)
and a Storage; gives one scheduler task (`ConfigLinks.task(now_us)`, by `attach`, at the parameter
`serial_update_hz`: Betaflight's serial_update_rate_hz, a name the CLI also takes) that moves waiting
bytes into the servers and their replies out.
Port SERIAL_CONFIG (USB on the Pico, TCP 5761 in the sim) carries MSP, the CLI and the seed-001
maintenance protocol, told apart by their first bytes as Betaflight tells MSP from the CLI: `$`
starts an MSP frame, `#` between frames enters the CLI (`exit` returns), 0xFF starts a maintenance
frame. Port SERIAL_MAINT (the HC-05 UART, TCP 5762) carries the maintenance protocol alone.

No request is dropped: each server's parser is fed only as many bytes as its queue holds and every
request is answered (or refused with a reason) in order. A port gets at most REQUESTS_PER_RUN
answers per run, so one flooding client cannot hold up the other port's replies for more than a
run; bytes it sent beyond that wait in the port's buffer (one read, bounded) and the board's own
buffer (the OS socket, the UART FIFO) until the next run, and the wait is counted (`held_back`).
A frame left half received for PARTIAL_FRAME_US of silence is dropped (counted), so it cannot
swallow the next requests. A read of -1 means the peer went away or was replaced: that port's
session closes (CLI left, props-off acknowledgement, motor test and arming locks released, parsers
and held bytes cleared) before any byte of the next client is read.
Sits beside the flight pass as a scheduler task; a pass never waits on a port.
"""

from hoverfly.compat import const, ticks_diff
from hoverfly.core.board import SERIAL_CONFIG, SERIAL_MAINT
from hoverfly.core.links.cliserver import CliServer
from hoverfly.core.links.maintserver import MaintServer
from hoverfly.core.links.mspserver import CONFIG_MAINT_USB, MspServer

LINKS_HZ = 100  # serial_update_hz's default (Betaflight's serial_update_rate_hz)
REQUESTS_PER_RUN = const(16)  # per port: 1 600 requests/s at 100 Hz, 16 000 at 1 kHz
READS_PER_RUN = const(4)  # per port: a flood of garbage still lets the task end
PARTIAL_FRAME_US = const(100000)  # a frame half received and then this long quiet is dropped
_READ_BYTES = 512
_HASH = const(0x23)  # '#': the CLI
_MAINT_SYNC = const(0xFF)  # a maintenance frame's first byte (protocols/maintenance.py SYNC)


class ConfigPort:
    """MSP, the CLI and the maintenance protocol sharing one byte stream."""

    def __init__(self, flight, storage=None):
        self.msp = MspServer(flight, storage)
        self.cli = CliServer(flight, storage)
        self.maint = MaintServer(flight, storage)
        self.maint.session_bit = CONFIG_MAINT_USB
        self.served = 0

    def feed(self, data, n, write):
        """Answer everything in data[:n], in order."""
        i = 0
        while True:
            i = self.serve(data, i, n, write, 64)
            if i >= n and not self.pending():
                return

    def serve(self, data, start, n, write, budget):
        """Answer up to `budget` requests from data[start:n]; return where it stopped (n: all taken)."""
        msp = self.msp
        maint = self.maint
        i = start
        done = 0
        while done < budget:
            if msp.pending():  # parsed in an earlier run, left by its budget
                msp.serve(data, i, i, write, budget - done)
                done += msp.served
                continue
            if maint.pending():
                maint.serve(data, i, i, write, budget - done)
                done += maint.served
                continue
            if i >= n:
                break
            if self.cli.active:
                self.cli.feed(memoryview(data)[i:n], n - i, write)
                i = n  # bytes typed after 'exit' in the same chunk are dropped, as a reboot would
                break
            if maint.in_frame():
                # A maintenance frame under way: a byte at a time, so it takes nothing past its end.
                while i < n and maint.in_frame() and not maint.pending():
                    i = maint.parser.feed_some(data, i, i + 1)
                continue
            # MSP (or bytes between frames) up to the next byte that can start another protocol.
            j = i
            while j < n and data[j] != _HASH and data[j] != _MAINT_SYNC:
                j += 1
            if j > i:
                r = msp.serve(data, i, j, write, budget - done)
                done += msp.served
                i = r
                if r < j:
                    break  # this run's share is used up
                continue
            if msp.in_frame():
                i = msp.serve(data, i, i + 1, write, budget - done)  # a '#' or 0xFF inside an MSP payload
                done += msp.served
            elif data[i] == _HASH:
                self.cli.enter(write)
                i += 1
            else:
                i = maint.parser.feed_some(data, i, i + 1)
        self.served = done
        return i

    def pending(self):
        return self.msp.pending() or self.maint.pending()

    def in_frame(self):
        return self.msp.in_frame() or self.maint.in_frame()

    def idle(self):
        self.msp.idle()
        self.maint.idle()

    def dropped(self):
        """Frames the parsers overwrote (a rescan that found more than the queue held): 0 in practice."""
        return self.msp.parser.dropped + self.maint.parser.dropped

    def close(self):
        self.cli.close()
        self.msp.close()
        self.maint.close()


class ConfigLinks:
    def __init__(self, flight, storage=None):
        self.flight = flight
        self.board = flight.board
        self.storage = storage
        self.config = ConfigPort(flight, storage)
        self.maint = MaintServer(flight, storage)
        self.config.cli.links = self  # CLI `status` shows the links' counters
        self.dropped_bytes = 0  # reply bytes the port had no room for
        self.held_back = 0  # runs that left a port's requests for the next run (its share used up)
        self.partial_timeouts = 0  # half frames dropped after PARTIAL_FRAME_US of silence
        self.sessions_closed = 0
        self.server_errors = 0  # requests whose server raised (the port's session was closed)
        self.last_server_error = None
        self._writers = (self._write_config, self._write_maint)
        self._servers = ((SERIAL_CONFIG, self.config), (SERIAL_MAINT, self.maint))  # built once: no tuples per run
        # Per port: the bytes read and not yet taken (a run's share ran out), and when bytes last came.
        self._bufs = (bytearray(_READ_BYTES), bytearray(_READ_BYTES))
        self._start = [0, 0]
        self._end = [0, 0]
        self._last_rx_us = [0, 0]

    def _write(self, port, data):
        n = len(data)
        took = self.board.serial_write(port, data, n)
        if took < n:
            self.dropped_bytes += n - took

    def _write_config(self, data):
        self._write(SERIAL_CONFIG, data)

    def _write_maint(self, data):
        self._write(SERIAL_MAINT, data)

    def close(self, port):
        """End the session on `port`: its server's state and any byte of it still held."""
        self._servers[port][1].close()
        self._start[port] = 0
        self._end[port] = 0
        self.sessions_closed += 1

    def task(self, now_us):
        if self.storage is not None:  # the built-in test follows the storage: a good save clears it
            self.flight.bit.storage_ok = not self.storage.failed
        for port, server in self._servers:
            try:
                self._serve(port, server, now_us)
            except Exception as exc:  # a link's fault must not cost the other port or the loop
                # A request that raised would be served again on every run (its bytes are still held) and
                # wedge the port: the session ends, its held bytes and half frames go, the error is counted.
                self.server_errors += 1
                self.last_server_error = exc
                self.close(port)
                self.flight.scheduler.caught("links", exc)  # the loop's error count: built-in test, CLI status

    def _serve(self, port, server, now_us):
        board = self.board
        buf = self._bufs[port]
        write = self._writers[port]
        budget = REQUESTS_PER_RUN
        reads = 0
        while True:
            start = self._start[port]
            end = self._end[port]
            if start < end or server.pending():
                start = server.serve(buf, start, end, write, budget)
                budget -= server.served
                self._start[port] = start
                if start < end or server.pending():
                    self.held_back += 1  # the rest waits for the next run: the other port's turn
                    return
            if budget <= 0 or reads >= READS_PER_RUN:
                return
            n = board.serial_read(port, buf)
            reads += 1
            if n < 0:
                self.close(port)
                return
            if n == 0:
                if server.in_frame() and ticks_diff(now_us, self._last_rx_us[port]) > PARTIAL_FRAME_US:
                    server.idle()  # a half frame and then silence: it will never complete
                    self.partial_timeouts += 1
                self._start[port] = 0
                self._end[port] = 0
                return
            self._start[port] = 0
            self._end[port] = n
            self._last_rx_us[port] = now_us

    def status_line(self):
        c = self.config
        last = "" if self.last_server_error is None else " (last %r)" % (self.last_server_error,)
        return ("Links: MSP %d requests, maintenance %d (USB %d), held for a later run %d, "
                "partial frames timed out %d, frames dropped %d, reply bytes dropped %d, sessions closed %d, "
                "server errors %d%s"
                % (c.msp.requests, self.maint.requests, c.maint.requests, self.held_back, self.partial_timeouts,
                   c.dropped() + self.maint.parser.dropped, self.dropped_bytes, self.sessions_closed,
                   self.server_errors, last))


def attach(flight, storage=None, rate_hz=None):
    """Add the links task to the flight's scheduler at `rate_hz` (default: the parameter
    serial_update_hz); returns the ConfigLinks."""
    links = ConfigLinks(flight, storage)
    if rate_hz is None:
        try:
            rate_hz = flight.params.get("serial_update_hz")
        except KeyError:
            rate_hz = LINKS_HZ
    flight.scheduler.add("links", rate_hz, links.task)  # due at once if the scheduler already started
    return links
