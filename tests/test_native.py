"""Native twins (hoverfly/native.py): a flight flown on compiled modules is the flight flown on the .py files,
bit for bit, and a twin of another source is never loaded."""

import json
import os
import shutil
import subprocess
import sys

import pytest

from hoverfly import native

# Compiled here: the simulator's physics and IMU model, the ESCs and the flight core's filters and PIDs (floats
# through every kind of operation the models use), few enough to build in a test.
_TWINS = ("hoverfly.sim.physics", "hoverfly.sim.sensors", "hoverfly.sim.esc", "hoverfly.core.stages.filters",
          "hoverfly.core.stages.pid")

_FLY = """
import json, sys
from hoverfly import native
from hoverfly.sim.runner import fly
out = []
for scenario, seed, extra in json.loads(sys.argv[1]):
    r = fly(scenario, "5inch", seed=seed, duration_s=4.0, **extra)
    for k in ("wall_time_s", "realtime_factor", "loop"):
        r.pop(k)
    out.append(r)
import hoverfly.sim.physics as physics
print(json.dumps({"flights": out, "native": native.report(), "physics_file": physics.__file__}, sort_keys=True))
"""

_CASES = [["hover", 1, {}], ["hover", 7, {"esc": "dshot300", "rx": "sbus"}], ["flip", 2, {}], ["rx-loss", 3, {}],
          ["gusty-hover", 4, {}]]


def _fly(directory, native_on):
    env = dict(os.environ)
    env["HOVERFLY_NATIVE"] = "1" if native_on else "0"
    env["HOVERFLY_NATIVE_DIR"] = str(directory)
    p = subprocess.run([sys.executable, "-c", _FLY, json.dumps(_CASES)], env=env, capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    return json.loads(p.stdout)


def test_flights_on_native_twins_are_bit_identical_to_flights_on_the_sources(tmp_path):
    pytest.importorskip("Cython")
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler to build the twins with (./dev test installs gcc)")
    failed = native.build(_TWINS, tmp_path, jobs=2)
    assert failed == {}
    assert all(native.status(_TWINS, tmp_path)[m] == "current" for m in _TWINS)

    on = _fly(tmp_path, True)
    off = _fly(tmp_path, False)

    assert set(_TWINS) <= set(on["native"]["native"])  # the flight did run on them
    assert off["native"] == {}
    assert on["physics_file"] == off["physics_file"] == str(native.source_path("hoverfly.sim.physics"))
    assert on["flights"] == off["flights"]  # every figure, event and step, to the last bit


def test_a_twin_of_another_source_is_not_loaded(tmp_path):
    name = "hoverfly.sim.physics"
    stale = native.twin_path(name, "0" * 20, tmp_path)
    stale.write_bytes(b"not a module")  # a twin left from an earlier version of physics.py
    finder = native.NativeFinder((name,), tmp_path)

    assert finder.find_spec(name, [str(native.source_path(name).parent)]) is None  # the .py is imported
    assert finder.python == [name]
    assert native.status((name,), tmp_path) == {name: "stale"}


def test_unlisted_modules_are_left_to_the_normal_import(tmp_path):
    finder = native.NativeFinder(("hoverfly.sim.physics",), tmp_path)

    assert finder.find_spec("hoverfly.sim.scenario", None) is None
    assert finder.python == []
