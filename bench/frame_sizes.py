"""Which functions of the flight core get their frame from the heap at every call on MicroPython.

MicroPython's VM keeps a bytecode function's frame (its locals and value stack, N_STATE words,
plus three words per nested try block, N_EXC_STACK) on the C stack only up to 11 machine words
(py/objfun.c VM_MAX_STATE_ON_STACK); a bigger frame is taken from the heap and freed again at
every call: a gc_alloc and a gc_free that gc.mem_alloc() deltas do not show (the block is back
before the pass ends). A `try: ... except OSError:` alone sets the stack to at least 6 words.

Run: `.venv/bin/python bench/frame_sizes.py` (needs the MicroPython VM, `.venv/bin/micropython`).
Prints one JSON object: {"limit_words": 11, "heap_frames": [[module, function, words], ...]} for
the modules bench/core_loop.py flies (words = N_STATE + 3 * N_EXC_STACK, as the VM's `-v -v`
bytecode dump gives them). With `--per-pass` it also counts, under callgrind, how many heap frames
one pass of bench/core_loop.py's armed flight takes (a run of 300 passes less a run of none):
"heap_frames_per_pass". Which of the listed functions run every pass is for the reader to judge.
"""

import json
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SRC = os.path.join(ROOT, "src")
LIMIT_WORDS = 11
MODULES = ("drivers/orientation", "drivers/imu", "drivers/mpu6050", "core/config/params", "core/events",
           "core/stages/filters", "core/fastpass/fixedimu", "core/stages/control", "core/stages/estimator",
           "core/stages/mixer", "core/stages/pid", "core/fastpass/fixedrate", "core/safety/arming",
           "core/safety/failsafe", "core/stages/rc", "core/command/commander", "core/safety/supervisor",
           "core/scheduler", "core/signals", "core/stages/output", "core/stages/receiver", "core/log/logger",
           "core/flight", "core/command/motortest", "protocols/crsf", "protocols/dshot")
PASSES = 300


def _micropython():
    from core_instructions import micropython_vm

    return micropython_vm() or "micropython"


def frames(path):
    """[(function, words)] of every code block the VM compiles for `path` itself."""
    env = dict(os.environ, MICROPYPATH="%s:.frozen" % SRC)
    out = subprocess.run([_micropython(), "-v", "-v", path], capture_output=True, text=True, env=env).stdout
    found = []
    in_file = False
    name = None
    n_state = 0
    for line in out.splitlines():
        m = re.match(r"File (.*), code block '([^']*)'", line)
        if m:
            in_file = os.path.abspath(m.group(1)) == os.path.abspath(path)
            name = m.group(2)
            continue
        m = re.match(r"\(N_STATE (\d+)\)", line)
        if m:
            n_state = int(m.group(1))
            continue
        m = re.match(r"\(N_EXC_STACK (\d+)\)", line)
        if m and in_file:
            found.append((name, n_state + 3 * int(m.group(1))))
    return found


def heap_frames_per_pass():
    counts = []
    script = ("import sys\nsys.path.insert(0, %r)\nfrom core_loop import armed_flight\n"
              "from hoverfly.compat import collect_garbage, disable_gc\n"
              "board, f, t = armed_flight()\ncollect_garbage()\ndisable_gc()\n"
              "for _ in range(int(sys.argv[1])):\n    t += 1000\n    board.t = t\n    f.step(t)\n") % HERE
    tmp = os.path.join(HERE, ".frame_sizes_child.py")
    with open(tmp, "w") as f:
        f.write(script)
    try:
        for n in (PASSES, 0):
            out_file = tmp + ".cg"
            env = dict(os.environ, MICROPYPATH="%s:.frozen" % SRC)
            subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=" + out_file, _micropython(),
                            "-X", "heapsize=8m", tmp, str(n)], capture_output=True, env=env, check=True)
            # --threshold=100: by default the annotation lists only the functions that make 99 % of the
            # cost, and the allocator's own entry falls below that
            ann = subprocess.run(["callgrind_annotate", "--tree=caller", "--threshold=100", out_file],
                                 capture_output=True, text=True).stdout
            os.remove(out_file)
            calls = 0
            lines = ann.splitlines()
            for i, line in enumerate(lines):
                if re.search(r"\*\s+\S*malloc\.c:m_malloc_maybe ", line):
                    j = i - 1
                    while j >= 0 and lines[j].strip():  # its callers: the block of `<` lines above it
                        m = re.search(r"fun_bc_call\S* \(([\d,]+)x\)", lines[j])
                        if m:
                            calls += int(m.group(1).replace(",", ""))
                        j -= 1
                    break
            counts.append(calls)
    finally:
        os.remove(tmp)
    return round((counts[0] - counts[1]) / PASSES, 2)


def main():
    heap = []
    for mod in MODULES:
        path = os.path.join(SRC, "hoverfly", mod + ".py")
        for name, words in frames(path):
            if words > LIMIT_WORDS and name != "<module>":
                heap.append([mod.replace("/", "."), name, words])
    result = {"limit_words": LIMIT_WORDS, "heap_frames": heap}
    if "--per-pass" in sys.argv:
        result["heap_frames_per_pass"] = heap_frames_per_pass()
    print(json.dumps(result))


if __name__ == "__main__":
    main()
