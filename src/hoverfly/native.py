"""Native twins of the simulated flight's modules, for CPython: the same sources, compiled by Cython.

A simulated flight runs the portable flight core and the simulator's models on CPython, one lockstep step
at a time; most of a step is the interpreter's own work (bench/sim_rtf.py). Compiled as plain Python (no
types declared, type inference off: every operation keeps Python's meaning, every float is a Python float,
no fused multiply-adds), the modules below run the same flight bit for bit and about 1.4 times as fast
(tests/test_native.py flies seeds both ways and compares the result dicts; docs/sweep-and-tune.md has the
figures). Nothing changes for MicroPython or the Pico: the portable .py files stay the only source.

    python -m hoverfly.native build     # Cython and a C compiler (pip install cython); about 2 CPU minutes
    python -m hoverfly.native status    # which modules have a current native twin
    hoverfly fly ...                    # flights (and sweeps, tunes, the benches) use them once built
    HOVERFLY_NATIVE=0 hoverfly fly ...  # the same flight on the .py files alone

`./dev` builds them (only what changed since the last build) before it flies, tests or benches, wherever a C
compiler and Cython are: the default path of a simulated flight is the compiled one. The test suite runs the .py
files (tests/conftest.py sets HOVERFLY_NATIVE=0) and tests/test_native.py holds the two equal.

A twin is kept under the SHA-256 of the source it was compiled from (in HOVERFLY_NATIVE_DIR, by default
~/.cache/hoverfly/native/<python>), and used only while that source is unchanged: a module edited since
the build, or never built, is imported from its .py as usual. So a stale build can slow a flight down,
never change it.
"""

import os
import sys

# The twins' finder and where they live are hoverfly/nativeenv.py's (loaded at start-up); this module builds them.
from hoverfly.nativeenv import (  # noqa: F401 - the names the build, the tests and the benches take from here
    MODULES,
    NativeFinder,
    _suffix,
    cache_dir,
    digest,
    install,
    report,
    source_path,
    twin_path,
)

# Cython as a compiler of plain Python: no C types guessed for locals (a C double's `**` or `%` is not
# Python's), and no contraction of a * b + c into one rounding (an FMA, where the CPU has one).
_DIRECTIVES = {"language_level": 3, "infer_types": False}
_CFLAGS = ["-ffp-contract=off"]

def _build_one(name, directory, work):
    """Compile one module to its twin; returns (name, None) or (name, why it failed)."""
    import contextlib
    import io
    import pathlib
    import shutil

    from Cython.Build import cythonize
    from setuptools import Distribution, Extension

    src = source_path(name)
    d = digest(src)
    out = twin_path(name, d, directory)
    if out.is_file():
        return name, None
    tmp = pathlib.Path(work) / name
    err = io.StringIO()
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            ext = Extension(name, [str(src)], extra_compile_args=_CFLAGS)
            exts = cythonize([ext], compiler_directives=_DIRECTIVES, build_dir=str(tmp / "c"), quiet=True)
            dist = Distribution({"ext_modules": exts})
            cmd = dist.get_command_obj("build_ext")
            cmd.build_lib = str(tmp / "lib")
            cmd.build_temp = str(tmp / "obj")
            cmd.ensure_finalized()
            cmd.run()
            built = cmd.get_ext_fullpath(name)
    except BaseException as exc:  # noqa: BLE001 - one module's failure is reported, the others still build
        text = (str(exc) or type(exc).__name__).strip().splitlines()
        return name, (text[-1] if text else type(exc).__name__) + " " + err.getvalue()[-300:].strip()
    directory.mkdir(parents=True, exist_ok=True)
    part = out.with_name(out.name + ".part")
    shutil.copyfile(built, part)
    os.replace(part, out)  # whole or absent: a process importing meanwhile never sees half a file
    for old in directory.glob("%s.*%s" % (name, _suffix())):  # twins of earlier sources
        if old != out:
            old.unlink()
    return name, None


def build(modules=MODULES, directory=None, jobs=2, progress=None):
    """Compile every listed module whose current source has no twin yet; returns {name: why} of failures."""
    import pathlib
    import tempfile
    from concurrent.futures import ProcessPoolExecutor

    try:
        import Cython  # noqa: F401
    except ImportError:
        from hoverfly.errors import UserError

        raise UserError("native build needs Cython: pip install cython") from None
    directory = pathlib.Path(directory or cache_dir())
    failed = {}
    with tempfile.TemporaryDirectory() as work, ProcessPoolExecutor(max_workers=max(1, jobs)) as pool:
        for name, why in pool.map(_build_one, modules, [directory] * len(modules), [work] * len(modules)):
            if why:
                failed[name] = why
            if progress is not None:
                progress(name, why)
    return failed


def status(modules=MODULES, directory=None):
    """{name: "current" | "stale" | "none"} for each listed module."""
    import pathlib

    directory = pathlib.Path(directory or cache_dir())
    out = {}
    for name in modules:
        src = source_path(name)
        if twin_path(name, digest(src), directory).is_file():
            out[name] = "current"
        elif list(directory.glob("%s.*%s" % (name, _suffix()))):
            out[name] = "stale"
        else:
            out[name] = "none"
    return out


def main(argv=None):
    import argparse

    ap = argparse.ArgumentParser(prog="python -m hoverfly.native", description=__doc__.split("\n\n")[0])
    ap.add_argument("action", choices=("build", "status"))
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--quiet", action="store_true", help="build: print nothing when every twin is current")
    args = ap.parse_args(argv)
    if args.action == "build":
        todo = [m for m, state in status().items() if state != "current"]
        if args.quiet and not todo:
            return 0
        if args.quiet:
            print("compiling %d of the simulator's modules with Cython (only what changed since the last build)"
                  % len(todo), flush=True)
        def say(name, why):
            print(("FAILED %s: %s" % (name, why)) if why else name)

        failed = build(todo, jobs=args.jobs, progress=None if args.quiet else say)
        if args.quiet:
            for name, why in sorted(failed.items()):
                print("FAILED %s: %s" % (name, why))
        print("%d of %d modules native in %s" % (len(MODULES) - len(failed), len(MODULES), cache_dir()))
        return 1 if failed else 0
    for name, state in status().items():
        print("%-36s %s" % (name, state))
    return 0


if __name__ == "__main__":
    sys.exit(main())
