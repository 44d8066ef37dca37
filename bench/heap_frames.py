"""Which bytecode functions get their frame from the heap on MicroPython, and how big it is.

MicroPython gives a bytecode function's frame (its locals plus its value stack, `n_state` words, and
two words per exception handler) a place on the C stack when it fits 11 machine words
(`VM_MAX_STATE_ON_STACK` in py/objfun.c); a larger frame is taken from the GC heap on every call and
given back on return. gc.mem_alloc() deltas around a call never see it, but the allocator does: a frame
needs several free blocks in a row, so its search walks past the small holes floats leave, and on a
board that collects in the loop's slack (boards/rp2/main.run) those searches are a good part of a pass's
allocation cost (docs/pico.md). Native code (`hoverfly flash` compiles core/flight.py to machine code)
keeps its frames on the C stack whatever their size.

Compiles each module with the MicroPython VM's `-v -v` dump (no import, nothing runs) and prints one JSON
object: {modules: {path: {function: n_state}}} for every function whose frame goes on the heap, and
`pass` for the functions the flight pass calls every pass (the list below), with their n_state and
whether they fit.

    .venv/bin/python bench/heap_frames.py [FILE.py ...]
"""

import json
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.join(os.path.dirname(HERE), "src", "hoverfly")
STACK_WORDS = 11  # VM_MAX_STATE_ON_STACK, in machine words

# Called on every pass of bench/core_loop.py's armed flight (module, function).
PASS_FUNCTIONS = (
    ("core/flight.py", "step"),
    ("core/flight.py", "command"),
    ("core/autopilot.py", "apply"),
    ("core/scheduler.py", "pass_started"),
    ("core/motortest.py", "update"),
)


def _micropython():
    mp = os.path.join(os.path.dirname(sys.executable), "micropython")
    if os.path.exists(mp):
        return mp
    import shutil

    return shutil.which("micropython")


def frames(path, mp=None):
    """{function: (n_state, words)} for every code block of the file at path (`<module>` left out)."""
    mp = mp or _micropython()
    src = "compile(open(%r).read(), %r, 'exec')" % (path, path)
    out = subprocess.run([mp, "-v", "-v", "-c", src], capture_output=True, text=True, check=True).stdout
    result = {}
    name = None
    n_state = 0
    for line in out.splitlines():
        m = re.search(r"code block '([^']*)'", line)
        if m:
            name = m.group(1)
            continue
        m = re.match(r"\(N_STATE (\d+)\)", line)
        if m:
            n_state = int(m.group(1))
            continue
        m = re.match(r"\(N_EXC_STACK (\d+)\)", line)
        if m and name is not None and name != "<module>":
            words = n_state + 2 * int(m.group(1))
            # The same name twice in one file (methods of two classes): keep the larger.
            if name not in result or result[name][1] < words:
                result[name] = (n_state, words)
    return result


def main(argv):
    mp = _micropython()
    if mp is None:
        print(json.dumps({"error": "no micropython VM"}))
        return 1
    paths = argv or sorted(os.path.join(d, f) for d, _, fs in os.walk(SRC) for f in fs if f.endswith(".py")
                           and "/sim" not in d and "/gcs" not in d and "/logs" not in d and not f.startswith("cli"))
    modules = {}
    for p in paths:
        heap = {fn: w for fn, (_, w) in frames(p, mp).items() if w > STACK_WORDS}
        if heap:
            modules[os.path.relpath(p, SRC)] = dict(sorted(heap.items()))
    hot = {}
    for rel, fn in PASS_FUNCTIONS:
        words = frames(os.path.join(SRC, rel), mp).get(fn, (0, 0))[1]
        hot[rel + ":" + fn] = {"words": words, "on_stack": words <= STACK_WORDS}
    print(json.dumps({"stack_words": STACK_WORDS, "pass": hot, "modules": modules}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
