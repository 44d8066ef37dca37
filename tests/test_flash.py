"""`hoverfly flash`: the --out bundle has every module precompiled and it imports under MicroPython."""

import os
import pathlib
import subprocess

import pytest

from hoverfly.cli import main
from hoverfly.cli_flash import bundle_sources
from test_micropython import MICROPYTHON, MPY_CROSS

ROOT = pathlib.Path(__file__).resolve().parent.parent


@pytest.mark.skipif(MPY_CROSS is None, reason="mpy-cross not installed")
def test_out_bundle_has_every_module_and_imports_under_micropython(tmp_path, capsys):
    assert main(["flash", "--out", str(tmp_path), "--mpy-cross", MPY_CROSS]) == 0
    assert "built" in capsys.readouterr().out
    lib = tmp_path / "lib"
    mods = []
    for rel, _src in bundle_sources():
        mpy = (lib / "hoverfly" / rel).with_suffix(".mpy")
        assert mpy.exists(), rel
        parts = ("hoverfly/" + rel)[:-3].split("/")
        if parts[-1] == "__init__":
            parts = parts[:-1]
        mods.append(".".join(parts))
    assert "hoverfly.boards.rp2.board" in mods and "hoverfly.core.flight" in mods
    assert not list(lib.rglob("*.py"))  # nothing left as source
    assert (tmp_path / "main.py").read_text().startswith("from hoverfly.boards.rp2.main import main")
    if MICROPYTHON is None:
        return
    # The viper accel modules hold RP2040 machine code: the host VM refuses them ("incompatible .mpy
    # arch", a ValueError) and the modules that use them fall back to their Python twins, as imported here.
    native = [m for m in mods if m.startswith("hoverfly.accel.")]
    assert "hoverfly.accel.crsf" in native
    mods = [m for m in mods if m not in native]
    code = "for m in %r:\n    __import__(m)\nprint('imported', %d)\n" % (mods, len(mods))
    env = dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (lib, ROOT / "tests" / "rp2fakes"))
    res = subprocess.run([MICROPYTHON, "-X", "heapsize=1m", "-c", code], capture_output=True, text=True,
                         env=env, cwd=str(tmp_path), timeout=60)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "imported %d" % len(mods) in res.stdout


def test_flash_needs_a_port_or_an_out_dir(capsys):
    assert main(["flash"]) == 2
    assert "--port" in capsys.readouterr().err


def test_missing_mpy_cross_is_one_line(tmp_path, capsys):
    assert main(["flash", "--out", str(tmp_path), "--mpy-cross", "/nonexistent/mpy-cross"]) == 2
    err = capsys.readouterr().err
    assert "mpy-cross" in err and "Traceback" not in err and err.count("\n") == 1


@pytest.mark.skipif(MPY_CROSS is None, reason="mpy-cross not installed")
def test_missing_port_is_one_line(capsys):
    assert main(["flash", "--port", "/dev/ttyNOPE9", "--mpy-cross", MPY_CROSS]) == 2
    err = capsys.readouterr().err
    assert "/dev/ttyNOPE9" in err and "Traceback" not in err
