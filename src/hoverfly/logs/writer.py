"""Host side of the flight log: a file fed from the logger's ring, for the simulator and Linux.

`attach(run_or_flight, path)` opens `path`, gives the flight's logger a RingSink and returns a
`FileLog`; a write that leaves the ring a quarter full writes the ring out to the file then and
there (RingSink's spill), so nothing has to be called between passes (the
logger writes once a batch, so the passes in between cost nothing here). `close()` at the end writes
out the rest and closes the file. `SimRun(log_path=...)` (and so `hoverfly fly --log`) does exactly
that; `hoverfly sim --log` and anything else that steps a Flight can use it the same way.
"""

import os

from hoverfly.errors import UserError
from hoverfly.protocols.ulog import RingSink

RING_BYTES = 256 * 1024  # > definitions (~6 kB) + a quarter of a ring between drains at 1 kHz


class FileLog:
    """A ULog file being written from a flight's logger ring."""

    def __init__(self, flight, path, ring_bytes=RING_BYTES):
        self.flight = flight
        self.path = os.fspath(path)
        try:
            self.file = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        except OSError as exc:
            raise UserError("--log %s: cannot write (%s)" % (self.path, exc.strerror or exc)) from None
        # The logger's sink: a ring that writes itself out to the file once a quarter full.
        self.ring = RingSink(ring_bytes, self._write, ring_bytes // 4)
        self._threshold = ring_bytes // 4
        self.bytes_written = 0
        self.closed = False
        flight.logger.open(self.ring)

    def _write(self, mv):
        self.file.write(mv)
        self.bytes_written += len(mv)
        return None

    def drain(self, force=False):
        """Write the ring out to the file once it holds a quarter of its size (or always, with force).
        The ring's writes do this on their own; this is for a caller that wants the file current now."""
        if force or self.ring.used >= self._threshold:
            self.ring.drain(self._write)

    def close(self):
        """End the log, write out the rest and close the file; returns the file's size in bytes."""
        if self.closed:
            return self.bytes_written
        self.flight.logger.close()
        self.ring.drain(self._write)
        self.file.close()
        self.closed = True
        return self.bytes_written

    def stats(self):
        lg = self.flight.logger
        return {"path": self.path, "bytes": self.bytes_written, "frames": lg.frames, "dropped": lg.dropped,
                "rc_frames": lg.rc_frames, "events": lg.events, "param_changes": lg.param_changes,
                "rate_hz": lg.rate_hz, "ring_high_water": self.ring.high_water}


def attach(run_or_flight, path, ring_bytes=RING_BYTES):
    """Start logging a SimRun's (or a Flight's) flight to `path`; returns the FileLog."""
    flight = getattr(run_or_flight, "flight", run_or_flight)
    if getattr(flight, "logger", None) is None:
        raise UserError("--log: this flight has no logger (firmware outside this process?)")
    return FileLog(flight, path, ring_bytes)
