"""What logging at 1 kHz adds to a CPython flight pass, counted by callgrind instead of timed.

Run: `.venv/bin/python bench/log_instructions.py` (needs `valgrind` on PATH; about two minutes).
The timed figure (bench/log_loop.py) moves by ±0.5 µs on this shared host; instruction, cache
miss and branch mispredict counts do not move at all, so they show what a change to the logger
did. Each figure is per pass: a flight stepped 0 and 1000 passes after the same set-up (the one
bench/log_loop.py flies, logging through FileLog into os.devnull), the difference divided by
1000. Prints one JSON object: for the pass without logging (`off`) and with it (`on`): `ir`
(instructions), `i1_miss`, `d1_miss` (level-1 instruction and data cache misses, callgrind's
cache model of this host) and `mispredicts`; then `log_ir_pct`, logging's instructions against the
pass's. Instruction counts are not time: a miss or a mispredict costs tens of instructions' time,
and logging's share of those is larger than its share of instructions (docs/logs.md).
"""

import json
import os
import re
import shutil
import subprocess
import sys

PASSES = 1000
_FIELDS = (("ir", r"I\s+refs"), ("i1_miss", r"I1\s+misses"), ("d1_miss", r"D1\s+misses"),
           ("mispredicts", r"Mispredicts"))


def _child(log_on, passes):
    sys.argv = [sys.argv[0]]
    here = os.path.dirname(os.path.abspath(__file__))
    sys.path.insert(0, here)
    import log_loop  # the bench module: its flights (main() runs only as a script)

    f, board, log, t = log_loop._flight(log_on)
    for _ in range(passes):
        t += 1000
        board.k += 1
        f.step(t)


def _counts(log_on, passes):
    cmd = ["valgrind", "--tool=callgrind", "--cache-sim=yes", "--branch-sim=yes", "--callgrind-out-file=/dev/null",
           sys.executable, os.path.abspath(__file__), "--child", "on" if log_on else "off", str(passes)]
    # One string hash seed for every child: dict and set layouts (so cache misses) follow it.
    env = dict(os.environ, PYTHONHASHSEED="0")
    out = subprocess.run(cmd, capture_output=True, text=True, check=True, env=env).stderr
    counts = {}
    for name, pattern in _FIELDS:
        m = re.search(pattern + r":\s+([\d,]+)", out)
        counts[name] = int(m.group(1).replace(",", ""))
    return counts


def main():
    if len(sys.argv) == 4 and sys.argv[1] == "--child":
        _child(sys.argv[2] == "on", int(sys.argv[3]))
        return 0
    if shutil.which("valgrind") is None:
        print(json.dumps({"error": "valgrind is not on PATH"}))
        return 1
    result = {"runtime": "cpython", "passes": PASSES}
    for label, log_on in (("off", False), ("on", True)):
        base = _counts(log_on, 0)
        run = _counts(log_on, PASSES)
        result[label] = {k: round((run[k] - base[k]) / PASSES) for k, _ in _FIELDS}
    result["log_ir_pct"] = round(100.0 * (result["on"]["ir"] - result["off"]["ir"]) / result["off"]["ir"], 1)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
