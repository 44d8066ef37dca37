"""Native twins of the simulated flight's modules, for CPython: the same sources, compiled by Cython.

A simulated flight runs the portable flight core and the simulator's models on CPython, one lockstep step
at a time; most of a step is the interpreter's own work (bench/sim_rtf.py). Compiled as plain Python (no
types declared, type inference off: every operation keeps Python's meaning, every float is a Python float,
no fused multiply-adds), the modules below run the same flight bit for bit and about 1.4 times as fast
(tests/test_native.py flies seeds both ways and compares the result dicts; docs/sweep-and-tune.md has the
figures). Nothing changes for MicroPython or the Pico: the portable .py files stay the only source.

    python -m hoverfly.native build     # Cython and a C compiler (pip install cython); about 2 CPU minutes
    python -m hoverfly.native status    # which modules have a current native twin
    HOVERFLY_NATIVE=1 hoverfly fly ...  # flights (and sweeps, tunes, the benches) use them

A twin is kept under the SHA-256 of the source it was compiled from (in HOVERFLY_NATIVE_DIR, by default
~/.cache/hoverfly/native/<python>), and used only while that source is unchanged: a module edited since
the build, or never built, is imported from its .py as usual. So a stale build can slow a flight down,
never change it.
"""

import os
import sys

# What only a build or an installed finder needs (hashlib, pathlib, importlib's loaders, Cython) is imported where
# it is used: hoverfly/nativeenv.py imports this module at start-up when HOVERFLY_NATIVE is set.

# What a lockstep step runs: the simulator's models and the flight core's pass, tasks and codecs. Modules
# that find their files by __file__ (scenarios, airframes, the bridge) stay Python: a twin lives elsewhere.
MODULES = (
    "hoverfly.compat",
    "hoverfly.sim.physics",
    "hoverfly.sim.sensors",
    "hoverfly.sim.pilot",
    "hoverfly.sim.esc",
    "hoverfly.sim.rxlink",
    "hoverfly.sim.board",
    "hoverfly.sim.runner",
    "hoverfly.core.flight",
    "hoverfly.core.scheduler",
    "hoverfly.core.board",
    "hoverfly.core.events",
    "hoverfly.core.signals",
    "hoverfly.core.stages.filters",
    "hoverfly.core.stages.pid",
    "hoverfly.core.stages.control",
    "hoverfly.core.stages.rates",
    "hoverfly.core.stages.rc",
    "hoverfly.core.stages.mixer",
    "hoverfly.core.stages.output",
    "hoverfly.core.stages.estimator",
    "hoverfly.core.stages.receiver",
    "hoverfly.core.command.commander",
    "hoverfly.core.command.autopilot",
    "hoverfly.core.command.motortest",
    "hoverfly.core.safety.arming",
    "hoverfly.core.safety.failsafe",
    "hoverfly.core.safety.supervisor",
    "hoverfly.protocols.dshot",
    "hoverfly.protocols.crsf",
    "hoverfly.protocols.rxcodec",
    "hoverfly.protocols.crc",
    "hoverfly.protocols.bridge",  # the firmware bridge's host end (sim/bridge.py finds files by __file__)
)

# Cython as a compiler of plain Python: no C types guessed for locals (a C double's `**` or `%` is not
# Python's), and no contraction of a * b + c into one rounding (an FMA, where the CPU has one).
_DIRECTIVES = {"language_level": 3, "infer_types": False}
_CFLAGS = ["-ffp-contract=off"]
_SRC = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # the folder holding hoverfly/


def _suffix():
    import importlib.machinery

    return importlib.machinery.EXTENSION_SUFFIXES[0]


def cache_dir():
    import pathlib

    d = os.environ.get("HOVERFLY_NATIVE_DIR")
    if d:
        return pathlib.Path(d)
    return pathlib.Path.home() / ".cache" / "hoverfly" / "native" / sys.implementation.cache_tag


def source_path(name):
    import pathlib

    return pathlib.Path(_SRC).joinpath(*name.split(".")).with_suffix(".py")


def digest(path):
    import hashlib
    import pathlib

    return hashlib.sha256(pathlib.Path(path).read_bytes()).hexdigest()[:20]


def twin_path(name, source_digest, directory=None):
    return (directory or cache_dir()) / ("%s.%s%s" % (name, source_digest, _suffix()))


def _twin_loader(name, path, source):
    """A loader of the twin at path that gives the module its source's __file__: code that reads a module's
    source or finds files beside it (fastgen, the bridge) finds them where they are."""
    import importlib.machinery

    class TwinLoader(importlib.machinery.ExtensionFileLoader):
        def exec_module(self, module):
            module.__file__ = source
            importlib.machinery.ExtensionFileLoader.exec_module(self, module)
            module.__file__ = source

    return TwinLoader(name, path)


class NativeFinder:
    """On sys.meta_path: a listed module whose current source has a twin is loaded from the twin."""

    def __init__(self, modules, directory):
        self.modules = frozenset(modules)
        self.directory = directory
        self.loaded = []
        self.python = []  # listed, but imported from the .py: no twin of this source

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in self.modules:
            return None
        import importlib.machinery
        import importlib.util

        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None or not (spec.origin or "").endswith(".py"):
            return None
        so = twin_path(fullname, digest(spec.origin), self.directory)
        if not so.is_file():
            self.python.append(fullname)
            return None
        self.loaded.append(fullname)
        loader = _twin_loader(fullname, str(so), spec.origin)
        return importlib.util.spec_from_file_location(fullname, str(so), loader=loader)


_finder = None


def install(modules=MODULES, directory=None):
    """Import the listed modules from their current twins from now on; returns the finder (one per process).
    Modules imported before the call stay as they are: install before importing the simulator."""
    global _finder
    if _finder is None:
        _finder = NativeFinder(modules, directory or cache_dir())
        sys.meta_path.insert(0, _finder)
    return _finder


def report():
    """Which listed modules this process runs native and which from Python ({} when not installed)."""
    if _finder is None:
        return {}
    return {"native": sorted(set(_finder.loaded)), "python": sorted(set(_finder.python))}


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
    args = ap.parse_args(argv)
    if args.action == "build":
        failed = build(jobs=args.jobs, progress=lambda n, why: print(("FAILED %s: %s" % (n, why)) if why else n))
        print("%d of %d modules native in %s" % (len(MODULES) - len(failed), len(MODULES), cache_dir()))
        return 1 if failed else 0
    for name, state in status().items():
        print("%-36s %s" % (name, state))
    return 0


if __name__ == "__main__":
    sys.exit(main())
