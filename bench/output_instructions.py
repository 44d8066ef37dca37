"""The pass's output path counted by callgrind on the MicroPython VM: instructions a call of each of
the three calls Flight.step makes at step 6, on bench/core_loop.py's armed flight.

Run: `.venv/bin/python bench/output_instructions.py` (needs `valgrind` on PATH and `.venv/bin/micropython`;
about two minutes). Compare two versions of the tree by running it in each (e.g. a `git worktree` of the
old commit). Each child flies core_loop's armed flight, then makes one call CALLS times with the
collector off: `board.write_motors(motor_out, n)` (the board codec: DShot words), the motor commands
(`OutputStage.update_fixed`, or `update` on the float path) or `MotorTest.update` (armed: nothing to do);
each run twice, CALLS and 2 * CALLS times: a call's count is the difference over CALLS (the loop's
own few instructions included).
Prints one JSON object: {calls, write_motors, motor_commands, motor_test, total} in instructions a call.
"""

import sys

CALLS = 2000


def _child(mode, calls):
    from core_loop import armed_flight
    from hoverfly.compat import collect_garbage, disable_gc

    board, f, t = armed_flight()
    s = f.signals
    out = s.motor_out
    n = f.motor_count
    armed = f.arming.armed
    output = f.output
    test = f.motor_test
    fixed = f._fixed_out_on
    arm_switch = f.rc.arm_switch
    rx_ok = f.rx_ok
    collect_garbage()
    disable_gc()
    if mode == "write_motors":
        for _ in range(calls):
            board.write_motors(out, n)
    elif mode == "motor_commands":
        if fixed:
            for _ in range(calls):
                output.update_fixed(s.motor_norm, armed, out)
        else:
            for _ in range(calls):
                output.update(s.motor_norm, armed, out)
    elif mode == "motor_test":
        for _ in range(calls):
            test.update(t, armed, arm_switch, rx_ok, out)


def main():
    import json
    import os
    import shutil

    from core_instructions import callgrind_total as _count
    from core_instructions import micropython_vm

    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    mp = micropython_vm()
    if shutil.which("valgrind") is None or mp is None:
        print(json.dumps({"error": "needs valgrind and the micropython VM"}))
        return 1
    env = dict(os.environ, MICROPYPATH="%s:%s:%s" % (os.path.join(root, "src"), here, os.path.join(root, ".frozen")))
    cmd = [mp, "-X", "heapsize=8m", os.path.abspath(__file__), "--child"]
    result = {"calls": CALLS}
    total = 0
    for mode in ("write_motors", "motor_commands", "motor_test"):
        # CALLS more calls, the rest of the run the same: what a run does once (imports, the flight) cancels
        per = round((_count(cmd + [mode, str(2 * CALLS)], env) - _count(cmd + [mode, str(CALLS)], env)) / CALLS)
        result[mode] = per
        total += per
    result["total"] = total
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--child":
        _child(sys.argv[2], int(sys.argv[3]))
    else:
        sys.exit(main())
