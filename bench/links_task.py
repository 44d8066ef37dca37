"""Cost of one run of the configuration links task (core/links/task.py), the work serial_update_hz schedules.

Runs under CPython and MicroPython; prints one JSON object: idle_us_per_run (both ports polled, no byte
waiting: what every pass pays when serial_update_hz >= loop_hz), companion_us_per_run (one SET_RAW_RC and
one MSP_ATTITUDE + MSP_RAW_IMU poll waiting: seed 004's 400 Hz companion, one run each 2.5 ms), and the
heap bytes a run allocates (gc.mem_alloc deltas with the GC off; 0 on CPython). The flight is built and
started on a board whose serial ports are in memory; the pass itself is not run (bench/core_loop.py).

    python3 bench/links_task.py
    MICROPYPATH=src:.frozen micropython -X heapsize=2m bench/links_task.py   (the servers compiled from source need it)
"""

import sys

if sys.implementation.name == "micropython":
    import gc

    for _name in ("core.config.params", "core.stages.control", "core.scheduler", "core.flight", "protocols.msp",
                  "protocols.maintenance", "core.links.mspserver", "core.links.maintserver", "core.links.cliserver",
                  "core.links.task"):
        gc.collect()
        try:
            __import__("hoverfly." + _name)
        except (SyntaxError, ImportError):
            pass
    gc.collect()

from hoverfly.compat import collect_garbage, disable_gc, enable_gc, mem_alloc, ticks_diff, ticks_us
from hoverfly.core.board import Board
from hoverfly.core.flight import Flight
from hoverfly.core.links.task import ConfigLinks
from hoverfly.protocols import msp


class MemBoard(Board):
    """Serial ports in memory: port 0 hands out `waiting` once per run; writes are counted."""

    name = "bench"

    def __init__(self):
        self.t_us = 1000
        self.waiting = None
        self.written = 0

    def now_us(self):
        return self.t_us

    def read_imu(self, gyro_rad_s, accel_m_s2):
        accel_m_s2[2] = -9.80665
        return True

    def write_motors(self, motor_out, count):
        pass

    def serial_read(self, port, buf):
        w = self.waiting
        if port != 0 or w is None:
            return 0
        self.waiting = None
        n = len(w)
        buf[:n] = w
        return n

    def serial_write(self, port, data, n=-1):
        self.written += len(data) if n < 0 else n
        return len(data) if n < 0 else n


def _time(links, board, runs, load):
    best = None
    alloc = 0
    for _ in range(3):
        collect_garbage()
        disable_gc()
        a0 = mem_alloc()
        t0 = ticks_us()
        for _ in range(runs):
            board.waiting = load
            links.task(board.t_us)
        us = ticks_diff(ticks_us(), t0) / runs
        alloc = (mem_alloc() - a0) / runs
        enable_gc()
        if best is None or us < best:
            best = us
    return best, alloc


def main():
    board = MemBoard()
    flight = Flight(board)
    flight.start(board.t_us)
    links = ConfigLinks(flight)
    rc = msp.encode_request(msp.MSP_SET_RAW_RC, msp.pack_set_raw_rc([1500, 1500, 1500, 1000, 1000, 1000, 1000, 1000]))
    companion = rc + msp.encode_request(msp.MSP_ATTITUDE) + msp.encode_request(msp.MSP_RAW_IMU)
    idle_us, idle_bytes = _time(links, board, 2000, None)
    comp_us, comp_bytes = _time(links, board, 500, companion)
    print('{"runtime": "%s", "idle_us_per_run": %.2f, "idle_bytes_per_run": %.1f, "companion_us_per_run": %.2f, '
          '"companion_bytes_per_run": %.1f, "requests": %d}'
          % (sys.implementation.name, idle_us, idle_bytes, comp_us, comp_bytes, links.config.msp.requests))


main()
