"""The flight-core pass of bench/core_loop.py counted by callgrind instead of timed, on both runtimes.

Run: `.venv/bin/python bench/core_instructions.py` (needs `valgrind` on PATH and the MicroPython VM,
`.venv/bin/micropython` or `micropython` on PATH; about three minutes).
bench/core_loop.py's µs per pass move by 10-30 % on this shared host from run to run; the number of
instructions a pass executes does not, so this is the figure to compare two versions of the core by.
Each runtime flies bench/core_loop.py's armed flight (armed_flight(): an MPU-6050 burst through the
driver, a CRSF frame every 4th pass, DShot words) and then either steps it PASSES times or only
advances its clock as often; the difference of the two runs' instruction counts, divided by
PASSES, is one pass. The collector is off for the counted passes (MicroPython gets an 8 MB heap for
their garbage), as bench/core_loop.py keeps it off inside the timed pass: allocation is counted,
collection is not. Prints one JSON object: {passes, micropython: {ir_per_pass}, cpython:
{ir_per_pass}} (a runtime that is missing is left out with the reason).
"""

import sys

PASSES = 300


def _child(mode, passes):
    from core_loop import armed_flight
    from hoverfly.compat import collect_garbage, disable_gc

    board, f, t = armed_flight()
    collect_garbage()
    disable_gc()
    if mode == "pass":
        for _ in range(passes):
            t += 1000
            board.t = t
            f.step(t)
    else:
        for _ in range(passes):
            t += 1000
            board.t = t


def _count(cmd, env):
    import re
    import subprocess

    out = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null"] + cmd,
                         capture_output=True, text=True, env=env, check=True).stderr
    return int(re.search(r"I\s+refs:\s+([\d,]+)", out).group(1).replace(",", ""))


def ir_per_pass(cmd, env, passes=PASSES):
    """Instructions of one pass: `cmd` (a runtime and this script) stepping the flight, less the same
    run only advancing its clock, over `passes`."""
    counts = {}
    for mode in ("pass", "idle"):
        counts[mode] = _count(cmd + ["--child", mode, str(passes)], env)
    return round((counts["pass"] - counts["idle"]) / passes)


def main():
    import json
    import os
    import shutil

    if shutil.which("valgrind") is None:
        print(json.dumps({"error": "valgrind is not on PATH"}))
        return 1
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    me = os.path.abspath(__file__)
    result = {"passes": PASSES}
    mp = os.path.join(os.path.dirname(sys.executable), "micropython")
    if not os.path.exists(mp):
        mp = shutil.which("micropython")
    runtimes = [("cpython", [sys.executable, me], dict(os.environ, PYTHONHASHSEED="0"))]
    if mp is None:
        result["micropython"] = {"error": "no micropython VM"}
    else:
        env = dict(os.environ, MICROPYPATH="%s:%s" % (os.path.join(root, "src"), here))
        runtimes.insert(0, ("micropython", [mp, "-X", "heapsize=8m", me], env))
    for name, cmd, env in runtimes:
        result[name] = {"ir_per_pass": ir_per_pass(cmd, env)}
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--child":
        _child(sys.argv[2], int(sys.argv[3]))
    else:
        sys.exit(main())
