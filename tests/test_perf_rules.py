"""The rules the MicroPython pass's speed rests on, as tests (the third, no properties on portable
classes, is tests/test_portable_classes.py).

1. Frame size. MicroPython keeps a bytecode function's frame (N_STATE words of locals and value stack,
   plus 3 words per nested try block) on the C stack only up to 11 machine words (py/objfun.c,
   VM_MAX_STATE_ON_STACK); a bigger one is taken from the heap and freed again at every call, an
   allocator search that gc.mem_alloc() never shows (docs/pico.md; bench/frame_sizes.py). One more
   local in a function of the pass costs that at every pass. Here: every function the pass calls each
   time, on the path a Pico flies (`pid_math` fixed, viper twins where the VM loads them), as the VM
   compiles it.
2. Allocation. Every float result is a heap object on MicroPython, and a collection takes
   milliseconds on an RP2040; the board collects in the loop's slack, and what the pass allocates sets
   how often (core/scheduler.py HeapWatch). The bench flight (bench/core_loop.py) on the VM must stay
   within the budget issue 26 set.
"""

import json
import os
import re
import subprocess
import sys

import pytest

from test_micropython import MICROPYTHON, ROOT, SRC

BENCH = ROOT / "bench"
LIMIT_WORDS = 11  # py/objfun.c VM_MAX_STATE_ON_STACK, in machine words
BYTES_PER_PASS_MAX = 256  # issue 26: bench/core_loop.py on the MicroPython VM
PASSES = 64

needs_vm = pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")


def _vm(args, timeout=300, heap="8m"):
    env = dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (SRC, BENCH))
    return subprocess.run([MICROPYTHON, "-X", "heapsize=" + heap] + args, capture_output=True, text=True,
                          timeout=timeout, cwd=str(ROOT), env=env)


def frame_words(path):
    """[(name, words, lines)] for each code block MicroPython compiles from `path`: words =
    N_STATE + 3 * N_EXC_STACK (what the VM sizes the frame by), lines = the source lines it maps."""
    out = subprocess.run([MICROPYTHON, "-v", "-v", str(path)], capture_output=True, text=True, timeout=120,
                         cwd=str(ROOT), env=dict(os.environ, MICROPYPATH="%s:.frozen" % SRC)).stdout
    blocks = []
    for line in out.splitlines():
        m = re.match(r"File (.*), code block '([^']*)'", line)
        if m:
            mine = os.path.abspath(m.group(1)) == os.path.abspath(str(path))
            blocks.append([m.group(2), 0, 0, set(), mine])
            continue
        if not blocks:
            continue
        m = re.match(r"\(N_STATE (\d+)\)", line)
        if m:
            blocks[-1][1] = int(m.group(1))
        m = re.match(r"\(N_EXC_STACK (\d+)\)", line)
        if m:
            blocks[-1][2] = int(m.group(1))
        m = re.match(r"\s+bc=\d+ line=(\d+)", line)
        if m and int(m.group(1)) > 1:
            blocks[-1][3].add(int(m.group(1)))
    return [(name, n_state + 3 * n_exc, lines) for name, n_state, n_exc, lines, mine in blocks if mine]


def _pass_functions():
    """The hoverfly functions CPython runs at every one of PASSES passes of the bench flight
    (bench/core_loop.py), switched to `pid_math` fixed as a Pico flies: {(module, qualname): (path, body
    lines)}, and who calls whom among them {(module, qualname): {(module, qualname)}}."""
    sys.path.insert(0, str(BENCH))
    try:
        from core_loop import armed_flight
    finally:
        sys.path.remove(str(BENCH))
    board, f, t = armed_flight()
    assert not f.params.set("pid_math", "fixed")
    f.configure()
    calls = {}
    edges = {}

    def profile(frame, event, arg):
        if event == "call":
            code = frame.f_code
            calls[code] = calls.get(code, 0) + 1
            if frame.f_back is not None:
                edges.setdefault(frame.f_back.f_code, set()).add(code)

    sys.setprofile(profile)
    try:
        for _ in range(PASSES):
            t += 1000
            board.t = t
            f.step(t)
    finally:
        sys.setprofile(None)
    pkg = SRC / "hoverfly"
    found = {}
    keys = {}
    for code, n in calls.items():
        if n < PASSES:
            continue
        path = os.path.abspath(code.co_filename)
        if path.startswith(str(pkg) + os.sep):
            rel = os.path.relpath(path, str(SRC))[:-3].replace(os.sep, ".")
            keys[code] = (rel.removesuffix(".__init__"), code.co_qualname)
            found[keys[code]] = (path, {ln for _, _, ln in code.co_lines() if ln and ln != code.co_firstlineno})
        else:  # the bench board's own code (read_imu, ...): passed through, it is not the flight core's
            keys[code] = ("", "%s:%d" % (path, code.co_firstlineno))
    graph = {keys[c]: {keys[d] for d in callees if d in keys} for c, callees in edges.items() if c in keys}
    return found, graph, _names_of({c: k for c, k in keys.items() if k[0]})


def _names_of(keys):
    """{(module, qualname): [(module, name)]}: every module-level name and class attribute of the loaded
    hoverfly modules that holds the function (a stage may call its twin through an alias: rc's `_rc_frame`)."""
    import inspect

    names = {key: [] for key in keys.values()}
    for modname, mod in list(sys.modules.items()):
        if not modname.startswith("hoverfly.") or mod is None:
            continue
        for name, value in vars(mod).items():
            if inspect.isfunction(value) and value.__code__ in keys:
                names[keys[value.__code__]].append((modname, name))
            elif inspect.isclass(value) and value.__module__ == modname:
                for attr, member in vars(value).items():
                    if inspect.isfunction(member) and member.__code__ in keys:
                        names[keys[member.__code__]].append((modname, name + "." + attr))
    return names


_BYTECODE = """
import sys
sys.path.insert(0, "bench")
import core_loop  # the bench's import order: the whole core fits the heap compiled from source

def _bc():
    pass

for mod, name in %r:
    try:
        obj = __import__(mod)
    except ImportError:  # host code that happens to hold the function (the simulator): not on a board
        print(mod, name, "absent")
        continue
    for part in mod.split(".")[1:] + name.split("."):
        obj = getattr(obj, part, None)
    print(mod, name, "bytecode" if type(obj) is type(_bc) else "other")
"""


def _bytecode_on_micropython(names):
    """{(module, qualname): True where MicroPython runs that function as bytecode}: False where a name
    that holds it on CPython holds something else there (a viper or native twin, or a built-in, as
    compat's ticks_diff is)."""
    wanted = sorted({ref for refs in names.values() for ref in refs})
    res = _vm(["-c", _BYTECODE % (wanted,)])
    assert res.returncode == 0, res.stdout + res.stderr
    kind = {}
    for line in res.stdout.splitlines():
        mod, name, what = line.split()
        kind[(mod, name)] = what
    assert set(kind) == set(wanted)
    return {key: all(kind[ref] != "other" for ref in refs) for key, refs in names.items()}


@needs_vm
def test_every_function_the_pass_calls_keeps_its_frame_on_the_c_stack():
    found, graph, names = _pass_functions()
    step = ("hoverfly.core.flight", "Flight.step")
    assert step in found, sorted(found)
    bytecode = _bytecode_on_micropython(names)
    # What the VM runs: from the pass down, through bytecode only (a viper twin calls no Python below it).
    runs = {step}
    todo = [step]
    while todo:
        key = todo.pop()
        if bytecode.get(key, True):
            for callee in graph.get(key, ()):
                if callee not in runs:
                    runs.add(callee)
                    todo.append(callee)
    blocks = {}
    too_big = []
    checked = set()
    for key in sorted(runs):
        if key not in found or not bytecode[key]:
            continue
        path, lines = found[key]
        if path not in blocks:
            blocks[path] = frame_words(path)
        name = key[1].rsplit(".", 1)[-1]
        same = [(len(lines & bl), words) for bn, words, bl in blocks[path] if bn == name]
        assert same, (key, "no code block of that name in MicroPython's compile")
        words = max(same)[1]  # the block whose source lines are this function's
        checked.add(key)
        if words > LIMIT_WORDS:
            too_big.append("%s.%s: %d words" % (key[0], key[1], words))
    # the pass was found, not an empty list: its own bytecode stages are among what was checked
    assert {step, ("hoverfly.core.flight", "Flight._sense"), ("hoverfly.core.flight", "Flight._outputs")} <= checked, \
        sorted(checked)
    assert not too_big, (
        "a function the pass calls every time has a frame (locals + value stack + 3 per try block) over %d machine "
        "words: on MicroPython its frame is taken from the heap and freed at every call (py/objfun.c "
        "VM_MAX_STATE_ON_STACK), a heap search per call that gc.mem_alloc() never shows. Drop a local or split "
        "the function (bench/frame_sizes.py lists every such frame): %s" % (LIMIT_WORDS, too_big))


@needs_vm
def test_the_frame_size_reading_finds_a_function_over_the_limit(tmp_path):
    # Eleven words fit (ten locals and a call's stack), a twelfth does not: what the rule above reads.
    names = ["a%d" % k for k in range(12)]
    src = ("def small(x):\n    y = x + 1\n    return y\n\n\n"
           "def big(x):\n" + "".join("    %s = x + %d\n" % (n, k) for k, n in enumerate(names))
           + "    return %s\n\n\n" % " + ".join(names)
           + "def guarded(x):\n    try:\n        return x + 1\n    except OSError:\n        return 0\n")
    path = tmp_path / "frames.py"
    path.write_text(src)
    words = {name: w for name, w, _ in frame_words(path)}
    assert words["small"] <= LIMIT_WORDS
    assert words["big"] > LIMIT_WORDS
    assert words["guarded"] >= 6  # a try block costs 3 words besides its locals and stack
    lines = {name: ls for name, _, ls in frame_words(path)}
    assert 2 in lines["small"] and 7 in lines["big"]


@needs_vm
def test_the_pass_allocates_within_its_budget_on_micropython():
    # 640 KB: the VM compiles the whole tree from source first (a Pico runs the precompiled bundle)
    res = _vm([str(BENCH / "core_loop.py")], heap="640k")
    assert res.returncode == 0, res.stdout + res.stderr
    figures = json.loads(res.stdout.strip().splitlines()[-1])
    assert figures["runtime"] == "micropython"
    assert figures["bytes_per_pass"] <= BYTES_PER_PASS_MAX, (
        "the flight pass allocates %.1f bytes a pass on MicroPython (bench/core_loop.py), over its budget of %d: "
        "every float result and every temporary is a heap block, the heap fills that much sooner, and a "
        "collection takes milliseconds on an RP2040. Keep the pass's values in preallocated arrays or in the "
        "fixed-point stages; %r" % (figures["bytes_per_pass"], BYTES_PER_PASS_MAX, figures))
