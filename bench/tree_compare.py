"""bench/core_loop.py on the MicroPython VM for two trees, run in turn on the same host: this checkout and REV.

Run: `.venv/bin/python bench/tree_compare.py REV [--runs 6] [--heap 2m] [--instructions]`
(REV: any commit, e.g. 5166070, the tree issue 26 was filed against; needs git and the MicroPython VM,
on PATH or next to this Python).

A µs figure is a property of the host as much as of the code: on this shared 2-core host the same tree reads
tens of per cent apart from one day to another. Two trees compared in alternate runs within the same minutes
see the same host. REV is exported with `git archive` into a temporary folder; each tree's generated viper
stages are written by its own `hoverfly.fastgen` (a tree from before the generator has none to write); then
bench/core_loop.py of each tree runs on its own sources, REV first, `--runs` times each.

--heap sets the VM's heap for both (default 2m). bench/core_loop.py's documented 640k makes a tree with more code
collect more often, and the passes right after a collection run with the host's caches emptied (its
`us_per_pass_after_gc`, two to three times a normal pass), so at 640k the figure moves with the size of the
tree's code; at 2m neither tree collects within its 2000 passes and the passes alone are compared.
--instructions adds each tree's bench/core_instructions.py count on the VM (callgrind, host-independent; needs
valgrind, about half a minute a tree).

Prints one JSON object: {rev, runs, heap, trees: {REV: {...}, "this": {...}}}; each tree gives the lists and
the median and minimum of us_per_pass, tasks_us_per_pass, loop_us_per_pass, with bytes_per_pass and
passes_per_gc of its last run, and ir_per_pass with --instructions.
"""

import json
import os
import pathlib
import subprocess
import sys
import tempfile

from core_instructions import micropython_vm

ROOT = pathlib.Path(__file__).resolve().parent.parent
KEYS = ("us_per_pass", "tasks_us_per_pass", "loop_us_per_pass")


def _export(rev, dest):
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev], capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(dest)], input=archive, check=True)


def _fastgen(tree):
    """The tree's own generated viper stages (none before the generator came in)."""
    if (tree / "src" / "hoverfly" / "fastgen.py").exists():
        env = dict(os.environ, PYTHONPATH=str(tree / "src"))
        subprocess.run([sys.executable, "-m", "hoverfly.fastgen"], cwd=tree, env=env, check=True,
                       stdout=subprocess.DEVNULL)


def _core_loop(tree, vm, heap):
    env = dict(os.environ, MICROPYPATH="src:.frozen")
    out = subprocess.run([vm, "-X", "heapsize=" + heap, "bench/core_loop.py"], cwd=tree, env=env,
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def _instructions(tree):
    env = dict(os.environ, PYTHONPATH="%s:%s" % (tree / "src", tree / "bench"))
    out = subprocess.run([sys.executable, "bench/core_instructions.py", "--micropython"], cwd=tree, env=env,
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])["micropython"]["ir_per_pass"]


def _median(values):
    v = sorted(values)
    n = len(v)
    return v[n // 2] if n % 2 else (v[n // 2 - 1] + v[n // 2]) / 2


def _summary(runs):
    result = {}
    for key in KEYS:
        values = [r[key] for r in runs]
        result[key] = values
        result[key + "_median"] = round(_median(values), 2)
        result[key + "_min"] = min(values)
    result["bytes_per_pass"] = runs[-1]["bytes_per_pass"]
    result["passes_per_gc"] = runs[-1]["passes_per_gc"]
    return result


def main(argv):
    if not argv or argv[0].startswith("-"):
        print("usage: bench/tree_compare.py REV [--runs N] [--heap SIZE] [--instructions]", file=sys.stderr)
        return 2
    rev = argv[0]
    runs = int(argv[argv.index("--runs") + 1]) if "--runs" in argv else 6
    heap = argv[argv.index("--heap") + 1] if "--heap" in argv else "2m"
    vm = micropython_vm()
    if vm is None:
        print("bench/tree_compare.py: no MicroPython VM (micropython on PATH or next to this Python)",
              file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        base = pathlib.Path(tmp)
        try:
            _export(rev, base)
        except subprocess.CalledProcessError:
            print("bench/tree_compare.py: git cannot export %r" % rev, file=sys.stderr)
            return 1
        _fastgen(base)
        _fastgen(ROOT)
        results = {rev: [], "this": []}
        for _ in range(runs):
            results[rev].append(_core_loop(base, vm, heap))
            results["this"].append(_core_loop(ROOT, vm, heap))
        trees = {name: _summary(r) for name, r in results.items()}
        if "--instructions" in argv:
            trees[rev]["ir_per_pass"] = _instructions(base)
            trees["this"]["ir_per_pass"] = _instructions(ROOT)
    print(json.dumps({"rev": rev, "runs": runs, "heap": heap, "trees": trees}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
