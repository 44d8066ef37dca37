"""The flight-core pass of bench/core_loop.py counted by callgrind instead of timed, on both runtimes.

Run: `.venv/bin/python bench/core_instructions.py [--micropython]` (needs `valgrind` on PATH and the MicroPython
VM, `.venv/bin/micropython` or `micropython` on PATH; about three minutes, --micropython: that runtime only).
bench/core_loop.py's µs per pass move by 10-30 % on this shared host from run to run; the number of
instructions a pass executes does not, so this is the figure to compare two versions of the core by.
Each runtime flies bench/core_loop.py's armed flight (armed_flight(): an MPU-6050 burst through the
driver, a CRSF frame every 4th pass, DShot words) and then steps it PASSES times, or
steps it three times as often; the difference of the two runs' instruction counts, divided by
2 * PASSES, is one pass. Garbage is collected as the rp2 main loop collects it (boards/rp2/main.run and
bench/core_loop.py's timed_passes keep the same HeapWatch): once half of what the last collection freed
is used up, with the heap bench/core_loop.py runs in (640 KB). The collections and the looks at the free
heap (callgrind's inclusive counts of gc_collect and gc_info) are taken out of both runs: a pass is counted
with the allocator working on the heap a board keeps, collection not. (Until 2026-12 the collector was off
for all the counted passes, so the allocator's free-block search grew with 300 passes of garbage and
dominated small differences.) Prints one JSON object: {passes, micropython: {ir_per_pass}, cpython:
{ir_per_pass}} (a runtime that is missing is left out with the reason).
`--rpm N` counts the flight with the RPM filter at N harmonics (bench/core_loop.py --rpm); `--plane` an
airplane's (bench/core_loop.py --plane).
"""

import sys

PASSES = 300


def fly(board, f, t, passes, core1=None):
    """Step bench/core_loop.py's armed flight `passes` times, collecting garbage as the rp2 main loop does.
    core1 (an rxcore.RxCore, bench/core_loop.py rx_core1): polled before every other pass, as core 1 would."""
    from core_loop import GC_FREE_FRACTION
    from hoverfly.compat import collect_garbage, mem_free
    from hoverfly.core.scheduler import HeapWatch

    watch = HeapWatch(mem_free, GC_FREE_FRACTION)
    collect_garbage()
    watch.collected()
    for k in range(passes):
        if watch.due() and watch.need():
            collect_garbage()
            watch.collected()
        if core1 is not None and k & 1:
            core1.poll(board)
        t += 1000
        board.t = t
        f.step(t)


def _child(passes):
    from core_loop import armed_flight

    board, f, t = armed_flight()
    fly(board, f, t, passes)


def micropython_vm():
    """The MicroPython VM the benches run (hoverfly.sim.bridge.find_micropython: on PATH, else next to this
    Python), or None when there is none."""
    from hoverfly.errors import UserError
    from hoverfly.sim.bridge import find_micropython

    try:
        return find_micropython()
    except UserError:
        return None


def callgrind_total(cmd, env):
    """All the instructions `cmd` executes under callgrind (collections included)."""
    import re
    import subprocess

    out = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null"] + cmd,
                         capture_output=True, text=True, env=env, check=True).stderr
    return int(re.search(r"I\s+refs:\s+([\d,]+)", out).group(1).replace(",", ""))


def _count(cmd, env):
    """Instructions `cmd` executes under callgrind, less its garbage collections and its looks at the free heap
    (gc_collect and gc_info, inclusive)."""
    import os
    import re
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        out_file = os.path.join(tmp, "callgrind.out")
        subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=" + out_file] + cmd,
                       capture_output=True, text=True, env=env, check=True)
        report = subprocess.run(["callgrind_annotate", "--inclusive=yes", "--threshold=100", out_file],
                                capture_output=True, text=True, check=True).stdout
    total = int(re.search(r"([\d,]+)\s+\(100\.0%\)\s+PROGRAM TOTALS", report).group(1).replace(",", ""))
    for name in ("gc_collect", "gc_info"):  # the collections, and the looks at the free heap (gc.mem_free)
        m = re.search(r"^\s*([\d,]+)\s.*:%s \[" % name, report, re.M)
        if m:
            total -= int(m.group(1).replace(",", ""))
    return total


def ir_per_pass(cmd, env, extra=(), passes=PASSES):
    """Instructions of one pass: `cmd` (a runtime and this script) stepping the flight 3 * `passes` times,
    less the same stepping it `passes` times, over 2 * `passes`. (Until 2026-12 the second run only advanced
    the clock: its start-up, identical in the two runs up to that point, still came out some 13M
    instructions apart on MicroPython, in gc_alloc, which made a pass read about 30 % light.)"""
    counts = {}
    for n in (passes, 3 * passes):
        counts[n] = _count(cmd + ["--child", str(n)] + list(extra), env)
    return round((counts[3 * passes] - counts[passes]) / (2 * passes))


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
    sys.path.insert(0, os.path.join(root, "src"))
    from hoverfly.fastgen import generate_all

    generate_all()  # the VM flies src/'s generated viper stages (docs/fastpass.md)
    result = {"passes": PASSES}
    extra = []
    if "--rpm" in sys.argv:
        extra = ["--rpm", sys.argv[sys.argv.index("--rpm") + 1]]
        result["rpm_harmonics"] = int(extra[1])
    if "--dyn" in sys.argv:  # the dynamic notch (bench/core_loop.py --dyn)
        extra += ["--dyn", sys.argv[sys.argv.index("--dyn") + 1]]
        result["dyn_notch_count"] = int(extra[-1])
    if "--plane" in sys.argv:  # an airplane's flight (bench/core_loop.py --plane)
        extra.append("--plane")
        result["plane"] = True
    mp = micropython_vm()
    runtimes = [("cpython", [sys.executable, me], dict(os.environ, PYTHONHASHSEED="0", HOVERFLY_NATIVE="0"))]
    if mp is None:
        result["micropython"] = {"error": "no micropython VM"}
    else:
        env = dict(os.environ, MICROPYPATH="%s:%s" % (os.path.join(root, "src"), here))
        runtimes.insert(0, ("micropython", [mp, "-X", "heapsize=640k", me], env))
    if "--micropython" in sys.argv:  # the Pico's figure alone, in half the time
        runtimes = [r for r in runtimes if r[0] == "micropython"]
    for name, cmd, env in runtimes:
        result[name] = {"ir_per_pass": ir_per_pass(cmd, env, extra)}
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "--child":
        _child(int(sys.argv[2]))
    else:
        sys.exit(main())
