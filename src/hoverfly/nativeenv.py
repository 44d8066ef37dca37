"""CPython start-up hook of the native twins (hoverfly/native.py builds them): their finder is installed before any
simulator module loads, unless HOVERFLY_NATIVE=0. By default (unset, or 1) a simulated flight runs on whatever twins
are built and current (`./dev` builds them where a C compiler is) and on the .py files for the rest, bit for bit the
same flight either way. hoverfly/__init__.py imports this on CPython only. What only a build needs (Cython,
setuptools, the command line: python -m hoverfly.native) is in native.py, which loads only when asked for."""

import os
import sys

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


_mode = os.environ.get("HOVERFLY_NATIVE", "")
if _mode != "0" and (_mode == "1" or os.path.isdir(str(cache_dir()))):  # never built: nothing to look for
    install()
