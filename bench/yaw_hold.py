"""What the yaw heading hold (yaw_hold, issue 25) costs: µs and heap bytes per RcInput.update with the hold
off and on (holding: the yaw stick centred, armed), in the fixed-point stage MicroPython's pass runs, and per
RcInput.hold_heading (the 100 Hz task's call). With the hold off update() is the class's own method, so the
pass pays nothing for the option; on, update() is a wrapper that writes the hold's yaw rate after the stick
shaping. Prints one JSON object; every figure is the best of RUNS batches, off and on alternating (the host is
shared and noisy: the bytes are the figure that does not move).

    .venv/bin/python bench/yaw_hold.py
    MICROPYPATH=src:.frozen .venv/bin/micropython -X heapsize=384k bench/yaw_hold.py
    .venv/bin/python bench/yaw_hold.py --passes 200   # a quick run (PASSES: 2000 on MicroPython, else 20000)
"""

import sys
from array import array

from hoverfly.compat import IS_MICROPYTHON, collect_garbage, disable_gc, enable_gc, mem_alloc, ticks_diff, ticks_us
from hoverfly.core.config.params import Params
from hoverfly.core.signals import Setpoint
from hoverfly.core.stages.rc import RcInput

RUNS = 7
PASSES = 2000 if IS_MICROPYTHON else 20000
if "--passes" in sys.argv:  # a short run checks that the bench still runs; figures need the default
    PASSES = int(sys.argv[sys.argv.index("--passes") + 1])


def _rc(hold):
    p = Params()
    p.set("pid_math", "fixed")
    p.set("yaw_hold", hold)
    rc = RcInput()
    rc.configure(p, 1000)
    # bench/rc_input.py's frames: the roll stick at 1500/1507 µs in turn, the yaw stick centred
    rc.new_frame(array("H", [1507, 1500, 1400, 1500, 2000, 2000] + [1500] * 10))
    if hold:  # the Flight calls it only with the hold on (task_arming)
        rc.hold_heading(True, 0.5)
        rc.hold_heading(True, 0.6)
    return rc


def _batch(fn, arg, passes):
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


def main():
    sp = Setpoint()
    off = _rc(0)
    on = _rc(1)
    assert on.holding and not off.holding
    best = {}
    for _ in range(RUNS):
        for name, rc in (("update_off", off), ("update_on", on)):
            us, nbytes = _batch(rc.update, sp, PASSES)
            old = best.get(name)
            if old is None or us < old[0]:
                best[name] = (us, nbytes)
        us, nbytes = _batch(lambda yaw: on.hold_heading(True, yaw), 0.61, PASSES)
        old = best.get("hold_heading")
        if old is None or us < old[0]:
            best["hold_heading"] = (us, nbytes)
    runtime = "micropython" if IS_MICROPYTHON else "cpython"
    parts = ['"runtime": "%s"' % runtime, '"passes": %d' % PASSES]
    for name in ("update_off", "update_on", "hold_heading"):
        us, nbytes = best[name]
        parts.append('"%s_us": %.3f, "%s_bytes": %.1f' % (name, us / PASSES, name, nbytes / PASSES))
    print("{" + ", ".join(parts) + "}")


main()
