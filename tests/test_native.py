"""Native twins (hoverfly/native.py): a flight flown on compiled modules is the flight flown on the .py files,
bit for bit, and a twin of another source is never loaded. The twins are the default path of a simulated flight
(`./dev` builds every module of native.MODULES into native.cache_dir()): the test flies on those, building what
is not current."""

import json
import os
import shutil
import subprocess
import sys

import pytest

from hoverfly import native

# Every module a default flight runs compiled (about 2 CPU minutes to build where `./dev` has not already).
_TWINS = native.MODULES

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


def test_flights_on_native_twins_are_bit_identical_to_flights_on_the_sources():
    pytest.importorskip("Cython")
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler to build the twins with (./dev test installs gcc)")
    directory = native.cache_dir()
    failed = native.build(_TWINS, directory, jobs=2)
    assert failed == {}
    assert all(native.status(_TWINS, directory)[m] == "current" for m in _TWINS)

    on = _fly(directory, True)
    off = _fly(directory, False)

    # the flight ran every listed module it imported compiled (the bridge's codec is not imported in-process)
    assert on["native"]["python"] == []
    assert {"hoverfly.core.flight", "hoverfly.sim.physics", "hoverfly.sim.runner"} <= set(on["native"]["native"])
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


_PROBE = """
import sys
import hoverfly
from hoverfly import nativeenv
print("installed" if nativeenv._finder is not None else "off")
"""


def _probe(env_native, directory):
    env = {k: v for k, v in os.environ.items() if k not in ("HOVERFLY_NATIVE", "HOVERFLY_NATIVE_DIR")}
    if env_native is not None:
        env["HOVERFLY_NATIVE"] = env_native
    env["HOVERFLY_NATIVE_DIR"] = str(directory)
    p = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    return p.stdout.strip()


def test_twins_are_the_default_wherever_they_were_built_and_off_with_hoverfly_native_0(tmp_path):
    built = tmp_path / "twins"
    built.mkdir()

    assert _probe(None, built) == "installed"  # the default: the twins ./dev built
    assert _probe("1", built) == "installed"
    assert _probe("0", built) == "off"  # the .py files alone
    assert _probe(None, tmp_path / "never-built") == "off"  # nothing built: nothing to look for
