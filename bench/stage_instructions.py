"""Where the pass's instructions go on MicroPython: callgrind counts of each stage of bench/core_loop.py's flight.

Run: `.venv/bin/python bench/stage_instructions.py [STAGE ...]` (needs `valgrind` and the MicroPython VM,
`.venv/bin/micropython` or `micropython` on PATH; about a minute and a half for the default stages on two cores).

A stage is a method of the flight or of an object it holds, named by its path from the Flight
(`fixed.update`, `rc.new_frame`, `board.imu.read`; `step` is the whole pass), or a scheduler task
(`task.rx`). Each stage is counted in a run of its own: bench/core_loop.py's armed flight (armed_flight())
flies PASSES passes with garbage collected as the rp2 main loop collects it, the stage's method replaced on
its instance by a wrapper that makes the real call from inside the builtin `map`'s iterator, and callgrind
collects only while inside that iterator (`--toggle-collect=map_iternext`). So a count is the stage's own
call with everything under it (the call, its frames, its allocations, what it calls), less nothing else in
the pass, and no behaviour changes: the stage runs as it always does. The iterator's own step and the
call from C (about 1.6k instructions; `step` less the sum of its stages shows the glue) are in every figure.
Collections and looks at the free heap (gc_collect, gc_info) are taken out, as in
bench/core_instructions.py. Figures are per pass: a stage that runs every fourth pass (a new receiver frame)
shows a quarter of its cost a call.

A name prefixed `core1:` (`core1:step`) counts the stage with the receiver parsed on core 1 (`rx_core1`,
bench/core_loop.py --rx-core1): the codec's RxCore polls the board before every other pass, outside the count.

Prints one JSON object: {passes, stages: {name: ir_per_pass}}.
"""

import sys

PASSES = 600
# The pass (Flight.step's stages) and the slow tasks and their large parts. (The pass
# statistics are a viper function Flight.step calls directly, scheduler.fast_pass_stats: no method to wrap.)
DEFAULT = ("step", "_sense", "board.read_imu", "board.imu.read", "fixed_imu.update",
           "fixed_att.step", "rc.update", "commander.update", "fixed.update", "_outputs", "output.update_fixed",
           "board.write_motors", "scheduler.run", "task.rx", "receiver.update", "_rx_frame", "rc.new_frame",
           "commander.pilot_frame", "task.arming", "faults.check_imu", "failsafe.observe")


def _wrap(obj, name):
    real = getattr(obj, name)

    def stage(*args):
        if args:
            for r in map(real, *[[a] for a in args]):
                return r
        for r in map(lambda _: real(), [0]):
            return r

    setattr(obj, name, stage)


def _child(name, passes):
    from core_instructions import fly
    from core_loop import armed_flight, rx_core1

    board, f, t = armed_flight()
    core1 = None
    if name.startswith("core1:"):
        name = name[6:]
        core1 = rx_core1(f)
    parts = name.split(".")
    if parts[0] == "task":
        for task in f.scheduler.tasks:
            if task.name == parts[1]:
                _wrap(task, "fn")
    else:
        obj = f
        for p in parts[:-1]:
            obj = getattr(obj, p)
        _wrap(obj, parts[-1])
    fly(board, f, t, passes, core1)


def _count(cmd, env):
    """Instructions `cmd` executes inside map's iterator, less collections and looks at the free heap."""
    import os
    import re
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        out_file = os.path.join(tmp, "callgrind.out")
        subprocess.run(["valgrind", "--tool=callgrind", "--toggle-collect=map_iternext",
                        "--callgrind-out-file=" + out_file] + cmd, capture_output=True, text=True, env=env, check=True)
        report = subprocess.run(["callgrind_annotate", "--inclusive=yes", out_file],
                                capture_output=True, text=True, check=True).stdout
    m = re.search(r"([\d,]+)\s+\(100\.0%\)\s+PROGRAM TOTALS", report)
    total = int(m.group(1).replace(",", "")) if m else 0
    for fn in ("gc_collect", "gc_info"):
        m = re.search(r"^\s*([\d,]+)\s.*:%s \[" % fn, report, re.M)
        if m:
            total -= int(m.group(1).replace(",", ""))
    return total


def child_counts(script, child_args):
    """Each child run of `script` (`VM script --child ARGS...`, one per entry of child_args) counted by _count
    under callgrind, on all cores: (counts, None); or (None, reason) without valgrind or the MicroPython VM."""
    import os
    import shutil
    from concurrent.futures import ThreadPoolExecutor

    from core_instructions import micropython_vm

    if shutil.which("valgrind") is None:
        return None, "valgrind is not on PATH"
    mp = micropython_vm()
    if mp is None:
        return None, "no micropython VM"
    here = os.path.dirname(os.path.abspath(__file__))
    env = dict(os.environ, MICROPYPATH="%s:%s" % (os.path.join(os.path.dirname(here), "src"), here))
    with ThreadPoolExecutor(os.cpu_count() or 2) as ex:
        runs = [ex.submit(_count, [mp, "-X", "heapsize=640k", os.path.abspath(script), "--child"] + list(a), env)
                for a in child_args]
        return [r.result() for r in runs], None


def main():
    import json

    names = sys.argv[1:] or list(DEFAULT)
    counts, error = child_counts(__file__, [(n, str(PASSES)) for n in names])
    if error:
        print(json.dumps({"error": error}))
        return 1
    print(json.dumps({"passes": PASSES, "stages": {n: round(c / PASSES) for n, c in zip(names, counts, strict=True)}}))
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--child":
        _child(sys.argv[2], int(sys.argv[3]))
    else:
        sys.exit(main())
