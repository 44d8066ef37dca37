"""The receiver-to-setpoint path counted by callgrind instead of timed, on the MicroPython VM (and CPython).

Run: `.venv/bin/python bench/rc_instructions.py [--cpython]` (needs `valgrind` and `.venv/bin/micropython`;
about five minutes on this 2-core host; --cpython counts the calls on CPython too). bench/rc_input.py times the
same calls, but the shared host moves its µs by tens of percent from run to run; instruction counts do not move,
so this is the figure to compare two versions by.

bench/core_loop.py's armed flight (armed_flight(): a CRSF frame on every second receiver poll, the
roll stick at 1500/1507 µs in turn, so one axis always moves) and then, CALLS times, one of:

- `task_rx`: Flight.task_rx (the 500 Hz receiver task: every second call takes a frame);
- `rx_update`: Receiver.update alone on the same polls;
- `rc_update`: RcInput.update (every pass), a new frame every 4th call, as in the flight;
- `rc_update_float`: the same with pid_math = float (the float stage);
- `new_frame`: RcInput.new_frame on the two frames in turn (the roll stick moves on each);

less the same run doing everything but the counted call (the frames still go to new_frame for rc_update),
both over 2 * CALLS calls less over CALLS, divided by CALLS. The collector is off, but both runs collect
every 16th call, as the rp2 main loop collects every dozen passes or so: with no collection the allocator's
search for a free block grows with the garbage made since the last one, and one run's garbage would change
what the other's allocations cost. Prints one JSON object:
{calls, micropython: {name: ir_per_call}, cpython: {...} (with --cpython)}.
"""

import sys
from array import array

CALLS = 2000
NAMES = ("task_rx", "rx_update", "rc_update", "rc_update_float", "new_frame")


def _child(name, mode, calls):
    from hoverfly.compat import collect_garbage, disable_gc

    run = mode == "pass"
    if name == "task_rx":
        from core_loop import armed_flight

        board, f, t = armed_flight()
        collect_garbage()
        disable_gc()
        for k in range(calls):
            if k & 15 == 0:
                collect_garbage()
            t += 2000
            board.t = t
            if run:
                f.task_rx(t)
        return
    # the stages alone: no flight to set up, so the runs' heaps (and the allocator's work) are alike
    from core_loop import BenchBoard
    from hoverfly.core.config.params import Params
    from hoverfly.core.signals import Setpoint
    from hoverfly.core.stages.rc import RcInput
    from hoverfly.core.stages.receiver import Receiver

    p = Params()
    if name == "rx_update":
        board = BenchBoard()
        board.polls = 1000  # past the bench's arming frames
        rx = Receiver()
        rx.configure(p)
        rx.start(0)
        t = 0
        collect_garbage()
        disable_gc()
        for k in range(calls):
            if k & 15 == 0:
                collect_garbage()
            t += 2000
            if run:
                rx.update(t, board)
        return
    # "fixed" is what "auto" picks on MicroPython where the viper twin loads
    p.set("pid_math", "float" if name == "rc_update_float" else "fixed")
    rc = RcInput()
    rc.configure(p, 1000)
    sp = Setpoint()
    a = [1500, 1500, 1400, 1500, 2000, 2000] + [1500] * 12  # bench/core_loop.py's frames: the roll stick moves
    b = list(a)
    b[0] = 1507
    frames = (array("H", a), array("H", b))
    collect_garbage()
    disable_gc()
    if name == "new_frame":
        for k in range(calls):
            if k & 15 == 0:
                collect_garbage()
            if run:
                rc.new_frame(frames[k & 1])
        return
    for k in range(calls):
        if k & 15 == 0:
            collect_garbage()
        if k & 3 == 0:
            rc.new_frame(frames[(k >> 2) & 1])
        if run:
            rc.update(sp)


def ir_per_call(cmd, env, name, calls=CALLS):
    """(The counted run less the idle one) over 2 * calls, less the same over calls: what the runs do
    once, set-up included, cancels even where two set-ups that should be alike are not."""
    from core_instructions import callgrind_total

    per = {}
    for mode in ("pass", "idle"):
        c = [callgrind_total(cmd + ["--child", name, mode, str(n)], env) for n in (2 * calls, calls)]
        per[mode] = c[0] - c[1]
    return round((per["pass"] - per["idle"]) / calls)


def main():
    import json
    import os
    import shutil

    from core_instructions import micropython_vm

    if shutil.which("valgrind") is None:
        print(json.dumps({"error": "valgrind is not on PATH"}))
        return 1
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    me = os.path.abspath(__file__)
    result = {"calls": CALLS}
    mp = micropython_vm()
    runtimes = []
    if mp is not None:
        env = dict(os.environ, MICROPYPATH="%s:%s" % (os.path.join(root, "src"), here))
        runtimes.append(("micropython", [mp, "-X", "heapsize=8m", me], env))
    if "--cpython" in sys.argv:
        runtimes.append(("cpython", [sys.executable, me], dict(os.environ, PYTHONHASHSEED="0")))
    for rt, cmd, env in runtimes:
        result[rt] = {name: ir_per_call(cmd, env, name) for name in NAMES}
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--child":
        _child(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    else:
        sys.exit(main())
