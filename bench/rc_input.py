"""The receiver-to-setpoint path, call by call: µs and heap bytes per call of RcInput.update (fixed point
and float, in turn), RcInput.new_frame, Receiver.update with no bytes and with one CRSF frame, and RcInput.fs_switch_in.
(Receiver.copy_channels is gone: new_frame copies the receiver's frame in, in its own call.)

The inputs are bench/core_loop.py's: the roll stick at 1500/1507 µs in turn on every frame (one axis
always moving), a frame every 4th pass. Prints one JSON object; every figure is the best of RUNS
batches, the fixed and float batches of rc.update alternating (the host is shared and noisy).

    .venv/bin/python bench/rc_input.py
    MICROPYPATH=src:.frozen .venv/bin/micropython -X heapsize=384k bench/rc_input.py
    .venv/bin/python bench/rc_input.py --passes 200   # a quick run (PASSES: 2000 on MicroPython, else 20000)
"""

import sys
from array import array

from hoverfly.compat import IS_MICROPYTHON, collect_garbage, disable_gc, enable_gc, mem_alloc, ticks_diff, ticks_us
from hoverfly.core.config.params import Params
from hoverfly.core.signals import Setpoint
from hoverfly.core.stages.rc import RcInput
from hoverfly.core.stages.receiver import Receiver
from hoverfly.protocols.crsf import encode_rc_frame

RUNS = 7
PASSES = 2000 if IS_MICROPYTHON else 20000
if "--passes" in sys.argv:  # a short run checks that the bench still runs; figures need the default
    PASSES = int(sys.argv[sys.argv.index("--passes") + 1])


def _frames():
    out = []
    for roll_us in (1500, 1507):
        # array("H"), as the Flight's rc_channels_us: the viper rc_frame reads it as 16-bit words
        out.append(array("H", [roll_us, 1500, 1400, 1500, 2000, 2000] + [1500] * 10))
    return out


def _rc(pid_math):
    p = Params()
    p.set("pid_math", pid_math)
    rc = RcInput()
    rc.configure(p, 1000)
    return rc


def _update_batch(rc, sp, frames, passes):
    """µs and bytes of `passes` rc.update calls, a new frame every 4th pass (its cost left out)."""
    update = rc.update
    us = 0
    nbytes = 0
    collect_garbage()
    disable_gc()
    for k in range(passes):
        if k & 3 == 0:
            rc.new_frame(frames[(k >> 2) & 1])
            if k & 63 == 0:
                enable_gc()
                collect_garbage()
                disable_gc()
        a0 = mem_alloc()
        t0 = ticks_us()
        update(sp)
        t1 = ticks_us()
        nbytes += mem_alloc() - a0
        us += ticks_diff(t1, t0)
    enable_gc()
    return us, nbytes


def _calls(fn, arg, passes):
    """µs and bytes per call of fn(arg), timed over `passes` calls in one window, the GC off."""
    collect_garbage()
    disable_gc()
    a0 = mem_alloc()
    t0 = ticks_us()
    for _ in range(passes):
        fn(arg)
    t1 = ticks_us()
    a1 = mem_alloc()
    enable_gc()
    return ticks_diff(t1, t0), a1 - a0


def _calls2(fn, a, b, pairs):
    """µs and bytes of `pairs` calls of fn(a) then fn(b), in one window, the GC off."""
    collect_garbage()
    disable_gc()
    a0 = mem_alloc()
    t0 = ticks_us()
    for _ in range(pairs):
        fn(a)
        fn(b)
    t1 = ticks_us()
    a1 = mem_alloc()
    enable_gc()
    return ticks_diff(t1, t0), a1 - a0


def _loop_us(passes):
    """The bare loop's own cost (subtracted from _calls)."""
    t0 = ticks_us()
    for _ in range(passes):
        pass
    return ticks_diff(ticks_us(), t0)


class _RxBoard:
    """Receiver bytes: one CRSF frame on each read while `ready`, else none."""

    def __init__(self, frame):
        self.frame = frame
        self.ready = False

    def read_rx(self, buf):
        if not self.ready:
            return 0
        f = self.frame
        n = len(f)
        buf[0:n] = f
        return n


def main():
    frames = _frames()
    fixed = _rc("fixed")
    flt = _rc("float")
    sp_fixed = Setpoint()
    sp_float = Setpoint()
    best = [1e9, 1e9]
    nbytes = [0, 0]
    for _ in range(RUNS):
        for j, rc, sp in ((0, fixed, sp_fixed), (1, flt, sp_float)):
            us, b = _update_batch(rc, sp, frames, PASSES)
            if us < best[j]:
                best[j] = us
                nbytes[j] = b
    # new_frame on the two frames in turn (a moving roll stick), for the fixed and the float stage
    nf = [1e9, 1e9]
    nf_bytes = [0, 0]
    loop = min(_loop_us(PASSES) for _ in range(3))
    for _ in range(RUNS):
        for j, rc in ((0, fixed), (1, flt)):
            us, b = _calls2(rc.new_frame, frames[0], frames[1], PASSES // 2)
            if us < nf[j]:
                nf[j] = us
                nf_bytes[j] = b
    # the receiver: a poll with no bytes, and a poll with one whole RC frame
    rx = Receiver()
    rx.configure(Params())
    rx.start(0)
    board = _RxBoard(bytes(encode_rc_frame(frames[1])))
    idle = [1e9, 0]
    frame = [1e9, 0]
    t_us = [0]

    def poll(b):
        t_us[0] += 2000
        rx.update(t_us[0], b)

    for _ in range(RUNS):
        board.ready = False
        us, b = _calls(poll, board, PASSES)
        if us < idle[0]:
            idle = [us, b]
        board.ready = True
        us, b = _calls(poll, board, PASSES)
        if us < frame[0]:
            frame = [us, b]
    ch = array("H", [1500] * 18)  # Signals.rc_channels_us
    fs = [1e9, 0]
    for _ in range(RUNS):
        us, b = _calls(fixed.fs_switch_in, ch, PASSES)
        if us < fs[0]:
            fs = [us, b]
    n = PASSES
    h = PASSES // 2 * 2
    print('{"runtime": "%s", "passes": %d, "rc_update_fixed_us": %.3f, "rc_update_fixed_bytes": %.1f, '
          '"rc_update_float_us": %.3f, "rc_update_float_bytes": %.1f, "new_frame_fixed_us": %.3f, '
          '"new_frame_fixed_bytes": %.1f, "new_frame_float_us": %.3f, "new_frame_float_bytes": %.1f, '
          '"rx_update_idle_us": %.3f, "rx_update_idle_bytes": %.1f, "rx_update_frame_us": %.3f, '
          '"rx_update_frame_bytes": %.1f, "fs_switch_in_us": %.3f}'
          % ("micropython" if IS_MICROPYTHON else "cpython", n, best[0] / n, nbytes[0] / n, best[1] / n,
             nbytes[1] / n, (nf[0] - loop / 2) / h, nf_bytes[0] / h, (nf[1] - loop / 2) / h, nf_bytes[1] / h,
             (idle[0] - loop) / n, idle[1] / n, (frame[0] - loop) / n, frame[1] / n, (fs[0] - loop) / n))


main()
sys.stdout.flush()
