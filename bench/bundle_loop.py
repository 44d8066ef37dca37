"""The flight pass as a board runs it: the `hoverfly flash` bundle (precompiled .mpy, cli_flash.NATIVE_MODULES as
machine code), built for MicroPython's unix port and measured on the MicroPython VM against the same bundle all in
bytecode (`hoverfly flash --bytecode`).

Run: `.venv/bin/python bench/bundle_loop.py` (CPython: it builds the bundles with mpy-cross and runs the MicroPython
VM; valgrind for the counts; about three minutes).
Builds both bundles with cli_flash.build for chip unix-x64, runs bench/core_loop.py on each under the VM
(in core_loop's 640 KB heap; MICROPYPATH: the bundle's lib/, then bench/), RUNS times in turn, and counts a pass
of each under callgrind as bench/core_instructions.py does (counts do not move between runs; times move
10-30 % on a shared host).
Prints one JSON object: {runtime, native_modules, bytecode: {us_per_pass, bytes_per_pass, ir_per_pass,
heap_frames_per_pass}, native: {...}, bundle_bytes: {chip: {bytecode, native}}}. us_per_pass is the best of the
runs. heap_frames_per_pass: frames MicroPython took from the heap and gave back within the pass (a bytecode
function whose locals and stack pass 11 words gets one on every call; gc.mem_alloc() deltas never see them),
counted as calls of m_malloc_maybe, the allocator its frame set-up uses. bundle_bytes: the .mpy files each board
gets (what its filesystem holds, and what RAM holds of a module once it is imported).

`--each [MODULE ...]` measures instead each module alone as machine code (paths as in the bundle, `core/stages/rc.py`;
default: every portable module): {module: {ir_saved, rp2040_bytes_added}}, the instructions a pass it saves
against the bytecode bundle and what it adds to an RP2040's bundle: the table NATIVE_MODULES was chosen from
(docs/pico.md). About a minute a module.

`--profile`: where each bundle's pass goes, by VM function: {bytecode: {ir_per_pass, functions: [[name,
instructions a pass, % of the pass], ...]}, native: {...}}, the 15 largest (callgrind_annotate, each function's
own instructions, a run of 3 * PASSES passes less one of PASSES, as bench/core_instructions.py counts; the
looks at the free heap, gc_info, left out as it leaves them out).
"""

import json
import os
import re
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "src"))

from core_instructions import PASSES, ir_per_pass  # noqa: E402
from hoverfly.cli_flash import CHIPS, NATIVE_MODULES, build, bundle_sources  # noqa: E402
from hoverfly.sim.bridge import find_micropython  # noqa: E402

RUNS = 3


def _bundle(root, name, native, chip="unix-x64"):
    out = os.path.join(root, name)
    files = build(out, chip, native=native)
    return os.path.join(out, "lib"), sum(os.path.getsize(f) for f in files)


def _env(lib):
    return dict(os.environ, MICROPYPATH="%s:%s" % (lib, HERE))


def _time(mp, lib):
    run = subprocess.run([mp, "-X", "heapsize=640k", os.path.join(HERE, "core_loop.py")], capture_output=True,
                         text=True, env=_env(lib))
    if run.returncode:  # the VM's own message (a MemoryError building the flight, say), not only the exit status
        sys.exit("bench/bundle_loop.py: core_loop.py on the bundle failed:\n" + run.stderr + run.stdout)
    return json.loads(run.stdout.strip().splitlines()[-1])


def _child(mp):
    return [mp, "-X", "heapsize=8m", os.path.join(HERE, "core_instructions.py")]


def _callgrind(cmd, env, out):
    subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=" + out] + cmd, capture_output=True,
                   env=env, check=True)


def _by_function(cmd, env):
    """{function: instructions} of one callgrind run of cmd, each function's own (callgrind_annotate)."""
    with tempfile.NamedTemporaryFile(suffix=".cg") as out:
        _callgrind(cmd, env, out.name)
        text = subprocess.run(["callgrind_annotate", "--inclusive=no", "--threshold=100", "--auto=no", out.name],
                              capture_output=True, text=True, check=True).stdout
    counts = {}
    for line in text.splitlines():
        m = re.match(r"\s*([\d,]+) \([\s\d.]+%\)\s+(\S+)", line)
        if m and "PROGRAM" not in line:
            name = m.group(2).split(":")[-1]
            counts[name] = counts.get(name, 0) + int(m.group(1).replace(",", ""))
    return counts


def _profile(mp, lib, top):
    """The pass's instructions by VM function (machine code that callgrind cannot name shows as its address)."""
    runs = [_by_function(_child(mp) + ["--child", str(n)], _env(lib)) for n in (3 * PASSES, PASSES)]
    # gc_info is the looks at the free heap (HeapWatch's mem_free walks, between passes): out, as
    # bench/core_instructions.py takes them out.
    per = {k: (runs[0].get(k, 0) - runs[1].get(k, 0)) / (2 * PASSES) for k in set(runs[0]) | set(runs[1])
           if k != "gc_info"}
    total = sum(per.values())
    rows = sorted(per.items(), key=lambda kv: -kv[1])[:top]
    return {"ir_per_pass": round(total), "functions": [[k, round(v), round(100.0 * v / total, 1)] for k, v in rows]}


def _calls(cmd, env, fn):
    """How often `fn` was called in one callgrind run of cmd."""
    with tempfile.NamedTemporaryFile(suffix=".cg") as out:
        _callgrind(cmd, env, out.name)
        names = {}
        total = 0
        target = False
        with open(out.name) as f:
            for line in f:
                # a name is given once, where its id first appears, on an fn= or a cfn= line
                m = re.match(r"(c?fn)=\((\d+)\)(?: (.*))?", line)
                if m:
                    if m.group(3):
                        names[m.group(2)] = m.group(3).strip()
                    target = m.group(1) == "cfn" and names.get(m.group(2)) == fn
                elif target and line.startswith("calls="):
                    total += int(line[6:].split()[0])
                    target = False
    return total


def _frames(mp, lib):
    counts = [_calls(_child(mp) + ["--child", str(n)], _env(lib), "m_malloc_maybe") for n in (3 * PASSES, PASSES)]
    return round((counts[0] - counts[1]) / (2 * PASSES), 1)


def compare(mp, root):
    libs = {"bytecode": _bundle(root, "bytecode", ())[0], "native": _bundle(root, "native", NATIVE_MODULES)[0]}
    result = {"runtime": "micropython", "native_modules": len(NATIVE_MODULES)}
    for name in libs:
        result[name] = {"us_per_pass": None}
    for _ in range(RUNS):
        for name, lib in libs.items():
            r = _time(mp, lib)
            best = result[name]["us_per_pass"]
            if best is None or r["us_per_pass"] < best:
                result[name]["us_per_pass"] = r["us_per_pass"]
            result[name]["bytes_per_pass"] = r["bytes_per_pass"]
    for name, lib in libs.items():
        result[name]["ir_per_pass"] = ir_per_pass(_child(mp), _env(lib))
        result[name]["heap_frames_per_pass"] = _frames(mp, lib)
    sizes = {}
    for chip in CHIPS:
        sizes[chip] = {"bytecode": _bundle(root, chip + "-b", (), chip)[1],
                       "native": _bundle(root, chip + "-n", NATIVE_MODULES, chip)[1]}
    result["bundle_bytes"] = sizes
    return result


def each(mp, root, modules):
    base = ir_per_pass(_child(mp), _env(_bundle(root, "bytecode", ())[0]))
    base_rp2040 = _bundle(root, "rp2040-b", (), "rp2040")[1]
    result = {"ir_per_pass_bytecode": base}
    for m in modules:
        ir = ir_per_pass(_child(mp), _env(_bundle(root, "one", (m,))[0]))
        grown = _bundle(root, "rp2040-one", (m,), "rp2040")[1] - base_rp2040
        result[m] = {"ir_saved": base - ir, "rp2040_bytes_added": grown}
        print(json.dumps({m: result[m]}), file=sys.stderr, flush=True)
    return result


def main(argv):
    mp = find_micropython()
    with tempfile.TemporaryDirectory() as root:
        if argv and argv[0] == "--profile":
            print(json.dumps({name: _profile(mp, _bundle(root, name, native)[0], 15)
                              for name, native in (("bytecode", ()), ("native", NATIVE_MODULES))}))
        elif argv and argv[0] == "--each":
            modules = argv[1:] or [rel for rel, _ in bundle_sources()
                                   if rel.split("/")[0] in ("core", "protocols", "drivers") or rel == "compat.py"]
            print(json.dumps(each(mp, root, modules)))
        else:
            print(json.dumps(compare(mp, root)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
