"""Boot and main loop on the Pico: board set-up, the flight pass at loop_hz, GC in the slack.

`main()` builds the Rp2Board (pins.py), loads the stored parameters (core/config/storage.py: the
two-slot image in the board's flash file), starts every device and prints one status line,
builds the Flight, attaches the configuration links (core/links/task.py: CLI, MSP and the maintenance
protocol on USB, the maintenance protocol on the HC-05 UART, a task at serial_update_hz; MSP_REBOOT
resets the board once its reply is out) and runs the pass at `loop_hz` on the
tick clock; with `rx_core1` the serial receiver is read and parsed on core 1 (core/stages/rxcore.py).
After each pass it collects garbage only when the time left before the next
pass is larger than a collection costs and the free heap is getting low — never
mid-pass (core/scheduler.py `HeapWatch`: gc.mem_free() walks the whole heap, so it is asked
only when the allocation rate measured so far says the threshold may be near). It measures
the loop: pass time, jitter against the period, overruns, GC runs
(`LoopStats`, printed when the loop ends).

Bad input never spins a motor: a missing or unsupported IMU, an IMU bus error in flight
or a silent receiver each set a board fault (blink code on the LED, a status line) and
the core refuses to arm (no IMU, no link) or disarms (IMU stale); the board stops the
motors itself for any IMU or output fault, and its output timer disarms every line
when the loop stops writing (the output failsafe). No link can stop the loop: what a slow task (the
configuration links, the battery, the arming task), the receiver telemetry or the log raises is caught at
that boundary inside the flight core (core/scheduler.py, Flight, core/log/logger.py), counted, shown in the
built-in test and the CLI status, and the pass goes on. An exception in the pass itself stops the motors,
prints the status, what the boundaries caught and the exception, and returns to the REPL. MicroPython-only.
"""

import gc

from hoverfly.compat import print_exception, ticks_add, ticks_diff
from hoverfly.core.scheduler import HeapWatch

# A collection of the Pico's ~200 KB heap takes milliseconds on an RP2040
# (reference/micropython.md §2.5): start one only when the slack left before the next pass
# is longer than the last collection took (this guess until one has been measured).
GC_GUESS_US = 1000
GC_FREE_FRACTION = 2  # and only once half of what the last collection freed is used up (core/scheduler.py HeapWatch)
REBOOT_DELAY_US = 50000  # MSP_REBOOT: time for the reply to leave (a USB frame is 1 ms, 10 bytes at 115200 baud ~1 ms)


class LoopStats:
    """What the loop cost: pass time, jitter and overruns, garbage collections."""

    def __init__(self):
        self.passes = 0
        self.pass_us = 0
        self.pass_max_us = 0
        self.jitter_max_us = 0
        self.overruns = 0
        self.gc_runs = 0
        self.gc_max_us = 0
        self.gc_skipped = 0

    def line(self):
        return "loop: %d passes, pass %d us (max %d), jitter max %d us, %d overruns, %d gc (max %d us)" % (
            self.passes, self.pass_us, self.pass_max_us, self.jitter_max_us, self.overruns, self.gc_runs,
            self.gc_max_us)


def _board_choices(board, params):
    """IMU type and receiver protocol from the parameters, where the rows exist (the outputs
    read `motor_protocol` themselves, in configure_outputs)."""
    for attr, name in (("imu_type", "imu_type"), ("rx_type", "rx_provider")):
        try:
            setattr(board, attr, params.get(name))
        except KeyError:
            pass


def make_board(imu="mpu6050", rx="crsf", motors="dshot600", **kw):
    from hoverfly.boards.rp2.board import Rp2Board

    return Rp2Board(imu, rx, motors, **kw)


def main(board=None, params=None, passes=-1, on_pass=None, overrides=()):
    """Boot and fly: returns (flight, stats) when `passes` ran out (tests) or the loop stopped."""
    from hoverfly.core.config.params import Params
    from hoverfly.core.config.storage import Storage
    from hoverfly.core.flight import Flight
    from hoverfly.core.links.task import attach

    chosen = board is not None  # a board built by the caller keeps its own IMU/receiver/motor choice
    if board is None:
        board = make_board()
    storage = Storage(board)
    if params is None:
        params = Params()
        storage.load(params)
    for name, value in overrides:
        err = params.set(name, value)
        if err:
            print("hoverfly: parameter %s" % err)
    if chosen:
        if params.get("motor_protocol") != board.motor_protocol:
            err = params.set("motor_protocol", board.motor_protocol)
            if err:
                print("hoverfly: parameter %s" % err)
    else:
        _board_choices(board, params)
    board.setup(params)
    print("hoverfly: parameters %s" % storage.summary())  # with any stored value skipped, and why
    flight = Flight(board, params)
    flight.storage = storage
    # SAFETY: a lost parameter set (defaults in use) blocks arming through the built-in test.
    flight.bit.storage_ok = not storage.failed
    board.flight = flight
    board.storage = storage
    links = attach(flight, storage)
    links.config.msp.on_reboot = lambda: reboot(board)  # MSP_REBOOT: a reset once the reply is written
    stats = LoopStats()
    stats.links = links
    try:
        run(board, flight, stats, passes, on_pass)
    except KeyboardInterrupt:
        board.stop_motors()
        print("hoverfly: stopped")
    except Exception as exc:  # SAFETY: whatever failed, the motors stop before anything else
        board.stop_motors()
        print(board.status_line())
        print(flight.loop_errors_line())
        print_exception(exc)
    board.stop_rx_core1()
    board.restore_ctrl_c()  # back at the REPL, Ctrl-C must work again
    print(stats.line())
    if flight.loop_errors():
        print("hoverfly: " + flight.loop_errors_line())
    return flight, stats


def reboot(board):
    """MSP_REBOOT (refused while armed): motors stopped, the reply given REBOOT_DELAY_US to leave over
    USB or the UART, then a reset: the board boots with the stored parameters, as after power-up."""
    import machine

    board.stop_motors()
    board.wait_until(ticks_add(board.now_us(), REBOOT_DELAY_US))
    machine.reset()


def run(board, flight, stats, passes=-1, on_pass=None):
    """The loop: one flight pass per period on the tick clock; GC only in the slack."""
    now = board.now_us()
    flight.start(now)
    # rx_core1: the receiver's codec (made by flight.start's configure) moves to core 1 before the first pass.
    if flight.params.get("rx_core1") and not board.start_rx_core1(flight.receiver):
        print("hoverfly: rx_core1 needs a serial receiver (crsf, sbus, ibus): parsed on core 0")
    period = 1000000 // flight.loop_hz
    next_us = ticks_add(now, period)
    mem_free = getattr(gc, "mem_free", None)
    collect = gc.collect
    # gc.mem_free() walks the whole heap: the watch asks it only when a collection may be near.
    watch = HeapWatch(mem_free, GC_FREE_FRACTION) if mem_free is not None else None
    if watch is not None:
        collect()
        watch.collected()
    step = flight.step
    gc_cost_us = GC_GUESS_US
    while passes != 0:
        if passes > 0:
            passes -= 1
        start = board.now_us()
        late = ticks_diff(start, ticks_add(next_us, -period))
        if late < 0:
            late = -late
        if late > stats.jitter_max_us:
            stats.jitter_max_us = late
        step(start)
        end = board.now_us()
        took = ticks_diff(end, start)
        stats.passes += 1
        stats.pass_us = took
        if took > stats.pass_max_us:
            stats.pass_max_us = took
        if on_pass is not None:
            on_pass(flight)
        # GC in the slack: only if it fits before the next pass, and only when needed.
        if watch is not None and watch.due():
            if ticks_diff(next_us, board.now_us()) > gc_cost_us:
                t0 = board.now_us()
                if watch.need():
                    collect()
                    watch.collected()
                    g = ticks_diff(board.now_us(), t0)
                    gc_cost_us = g
                    stats.gc_runs += 1
                    if g > stats.gc_max_us:
                        stats.gc_max_us = g
            else:
                stats.gc_skipped += 1  # a look at the heap (and maybe a collection) was due: no slack for it
        board.wait_until(next_us)
        next_us = ticks_add(next_us, period)
        if ticks_diff(board.now_us(), next_us) > 0:
            # A pass ran over a whole period: restart the schedule from now, no catch-up burst.
            stats.overruns += 1
            next_us = ticks_add(board.now_us(), period)
    return stats
