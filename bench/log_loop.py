"""Cost of flight logging at 1 kHz: the flight pass with and without the logger, and the log task alone.

Run: `.venv/bin/python bench/log_loop.py` and
`MICROPYPATH=src:.frozen .venv/bin/micropython -X heapsize=1m bench/log_loop.py` (the
whole core imported from source needs more than a Pico's heap).
Prints one JSON object: us_per_pass without and with logging (the fastest 100-pass batch of each;
blackbox_rate_hz = loop_hz = 1000: every pass writes the six fast topics, input_rc on each
receiver frame, the slow topics ten times a second). The log goes where `hoverfly fly --log`
sends it: on CPython through hoverfly.logs.writer.FileLog into a file (os.devnull), the logger's
sink: its ring written out a quarter at a time by the write that fills it, file writes included; on
MicroPython into a 24 KiB RingSink written out to a counting writer by the same rule.
The two flights run batch for batch in turn, and each logged batch is paired with the unlogged
batch run just before it: a shared host slows whole stretches, and both batches of a pair see the
same stretch. A batch is 100 passes, so every batch holds the same logging work: two staged
batches handed to the sink on CPython (50 frames each; twenty of 5 on MicroPython), one write of
the slow topics and 25 input_rc samples.
log_pct (the goal, <= 10 on CPython) is the median over all pairs of the logged batch's time against
its unlogged partner's, less one: a slow stretch stretches both batches of a pair alike, so their
ratio keeps. log_us_per_pass is the median paired difference, per pass; log_pct_of_best (the
figure this bench gave before) puts that median difference over the fastest unlogged batch, which
mixes a typical stretch with the quietest one and so reads high whenever the host is busy.
log_us_best_diff is the difference of the two fastest batches, log_us_mean the difference over all
batches, task_us Logger.update timed alone (its writes included) and bytes_per_s what the log
wrote; on MicroPython also alloc_off/alloc_on, heap bytes allocated per pass without and with
logging. Armed, angle mode, a CRSF frame every 4th pass.
`--same-flight` times one logged flight instead, its logging call set and cleared batch by batch (the same
objects and code on both sides): {runtime, method, us_per_pass_off, log_us_per_pass, log_pct}, the
same statistics.
"""

import sys

if sys.implementation.name == "micropython":
    import gc

    for _name in ("config.params", "events", "stages.filters", "stages.control", "stages.estimator",
                  "stages.mixer", "safety.arming", "safety.failsafe", "stages.rc", "scheduler", "signals",
                  "stages.output", "stages.receiver", "log.logger", "command.commander", "safety.supervisor",
                  "flight"):
        gc.collect()
        try:
            __import__("hoverfly.core." + _name)
        except ImportError:
            pass
    gc.collect()

from hoverfly.compat import IS_MICROPYTHON, collect_garbage, disable_gc, enable_gc, ticks_diff, ticks_us
from hoverfly.core.board import Board
from hoverfly.core.flight import Flight
from hoverfly.protocols.ulog import RingSink

if IS_MICROPYTHON:  # no host log writer: a ring drained by the same rule (_RingLog)
    FileLog = None
else:
    import os

    from hoverfly.logs.writer import FileLog

try:
    from hoverfly.protocols.crsf import encode_rc_frame
except ImportError:  # pragma: no cover
    encode_rc_frame = None

RUNS = 3 if IS_MICROPYTHON else 5
PASSES = 500 if IS_MICROPYTHON else 4000
BATCH = 100  # passes: two 50-frame log batches, one slow-topic write, 25 receiver frames


class _Board(Board):
    def __init__(self):
        self.k = 0
        self.polls = 0
        self.frames = []
        for arm_us, roll_us in ((1000, 1500), (2000, 1500), (2000, 1507)):
            ch = [roll_us, 1500, 1400, 1500, arm_us, 2000] + [1500] * 10
            self.frames.append(bytes(encode_rc_frame(ch)) if encode_rc_frame else b"")

    def now_us(self):
        return 0

    def read_imu(self, gyro, accel):
        k = self.k % 3
        gyro[0] = 0.01 * (k - 1)
        gyro[1] = 0.02
        gyro[2] = -0.005 * k
        accel[0] = 0.1
        accel[1] = -0.1
        accel[2] = -9.8
        return True

    def read_rx(self, buf):
        self.polls += 1
        if self.polls & 1:
            return 0
        f = self.frames[0] if self.polls < 800 else self.frames[1 + ((self.polls >> 1) & 1)]
        n = len(f)
        buf[0:n] = f
        return n

    def write_motors(self, out, n):
        pass


class _RingLog:
    """FileLog's policy without a file (MicroPython): a ring that writes itself out a quarter at a time,
    to a counter."""

    def __init__(self, flight):
        self.ring = RingSink(24 * 1024, self._write, 6 * 1024)
        self._threshold = self.ring.size // 4
        self.bytes_written = 0
        flight.logger.open(self.ring)

    def _write(self, mv):
        self.bytes_written += len(mv)
        return None

    def drain(self, force=False):
        if force or self.ring.used >= self._threshold:
            self.ring.drain(self._write)


def _flight(log_on):
    board = _Board()
    f = Flight(board)
    f.params.set("gyro_cal_ms", 100)
    f.params.set("boot_grace_ms", 0)
    f.params.set("min_check", 1500)
    f.params.set("blackbox_rate_hz", 1000)
    log = None
    if log_on:
        log = FileLog(f, os.devnull) if FileLog is not None else _RingLog(f)
    f.start(0)
    t = 0
    for _ in range(2000):  # calibrate, arm
        t += 1000
        board.k += 1
        f.step(t)
    assert f.arming.armed, "bench flight did not arm"
    return f, board, log, t


def _batch(f, board, t):
    t0 = ticks_us()
    for _ in range(BATCH):
        t += 1000
        board.k += 1
        f.step(t)
    return ticks_diff(ticks_us(), t0), t


def run_pair():
    """The same flight with and without logging, batch for batch in turn; the fastest batch of each
    (a busy host slows some batches, never speeds one up)."""
    f0, b0, _, t0 = _flight(False)
    f1, b1, log, t1 = _flight(True)
    log.drain(True)
    written0 = log.bytes_written
    best_off = None
    best_on = None
    sum_off = 0
    sum_on = 0
    diffs = []
    ratios = []
    for i in range(RUNS * PASSES // BATCH):
        if i % 8 == 0:
            collect_garbage()
        us_off, t0 = _batch(f0, b0, t0)
        sum_off += us_off
        best_off = us_off if best_off is None or us_off < best_off else best_off
        us, t1 = _batch(f1, b1, t1)
        sum_on += us
        best_on = us if best_on is None or us < best_on else best_on
        if i % 8:  # the pair right after a collection starts cold (its first batch most): flown, not paired
            diffs.append(us - us_off)
            ratios.append(us / us_off - 1.0)
    passes = RUNS * PASSES
    f1.logger.flush()
    log.drain(True)
    rate = (log.bytes_written - written0) / (passes / 1000.0)
    alloc = ""
    if IS_MICROPYTHON:  # heap bytes per pass, from one batch with the collector off
        per = []
        for f, board, t in ((f0, b0, t0), (f1, b1, t1)):
            collect_garbage()
            disable_gc()
            m0 = gc.mem_alloc()
            _batch(f, board, t)
            per.append((gc.mem_alloc() - m0) // BATCH)
            enable_gc()
        alloc = ', "alloc_off": %d, "alloc_on": %d' % (per[0], per[1])
    return (best_off / BATCH, best_on / BATCH, _median(diffs) / BATCH, 100.0 * _median(ratios),
            (sum_on - sum_off) / passes, rate, alloc)


def _median(values):
    values.sort()
    return values[len(values) // 2]


def run_same_flight():
    """One logged flight, its logging call set and cleared batch by batch (Flight.log_pass and log_rc, as the
    logger sets them): the same objects and code on both sides, so only the logging differs. Returns the
    fastest unlogged batch, the median paired difference per pass and the median paired ratio (in %)."""
    f, board, log, t = _flight(True)
    on_pass, on_rc = f.log_pass, f.log_rc
    best_off = None
    diffs = []
    ratios = []
    for i in range(RUNS * PASSES // BATCH):
        if i % 8 == 0:
            collect_garbage()
        f.log_pass = f.log_rc = None
        us_off, t = _batch(f, board, t)
        f.log_pass, f.log_rc = on_pass, on_rc
        us_on, t = _batch(f, board, t)
        best_off = us_off if best_off is None or us_off < best_off else best_off
        if i % 8:
            diffs.append(us_on - us_off)
            ratios.append(us_on / us_off - 1.0)
    return best_off / BATCH, _median(diffs) / BATCH, 100.0 * _median(ratios)


def task_alone():
    f, board, log, t = _flight(True)
    task = f.logger.update
    best = None
    for _ in range(RUNS):
        collect_garbage()
        total = 0
        for _ in range(PASSES // BATCH):
            t0 = ticks_us()
            for _ in range(BATCH):
                t += 1000
                task(t)
            total += ticks_diff(ticks_us(), t0)
        us = total / PASSES
        best = us if best is None or us < best else best
    return best


def main():
    if "--same-flight" in sys.argv:
        off, median, pct = run_same_flight()
        print('{"runtime": "%s", "method": "same-flight", "us_per_pass_off": %.2f, "log_us_per_pass": %.2f, '
              '"log_pct": %.1f, "log_pct_of_best": %.1f}'
              % (sys.implementation.name, off, median, pct, 100.0 * median / off))
        return
    off, on, median, pct, mean, rate, alloc = run_pair()
    collect_garbage()
    alone = task_alone()
    runtime = "micropython" if IS_MICROPYTHON else "cpython"
    print('{"runtime": "%s", "us_per_pass_off": %.2f, "us_per_pass_on": %.2f, "log_us_per_pass": %.2f, '
          '"log_pct": %.1f, "log_pct_of_best": %.1f, "log_us_best_diff": %.2f, "log_us_mean": %.2f, '
          '"task_us": %.2f, "bytes_per_s": %d, "passes": %d%s}'
          % (runtime, off, on, median, pct, 100.0 * median / off, on - off, mean, alone, rate, RUNS * PASSES,
             alloc))


if __name__ == "__main__":
    main()
    sys.stdout.flush()
