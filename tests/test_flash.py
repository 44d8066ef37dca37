"""`hoverfly flash`: the --out bundle has every module precompiled and it imports under MicroPython."""

import os
import pathlib
import subprocess

import pytest

from hoverfly.cli import main
from hoverfly.cli_flash import ARCH, CHIPS, NATIVE_MODULES, bundle_sources, mpy_arch
from hoverfly.cli_flash import MPY_ARCH_CODE as MPY_ARCH
from test_micropython import MICROPYTHON, MPY_CROSS

ROOT = pathlib.Path(__file__).resolve().parent.parent


def _modules(lib):
    """{module name: the architecture code in its .mpy header} of a built bundle."""
    mods = {}
    for rel, _src in bundle_sources():
        mpy = (lib / "hoverfly" / rel).with_suffix(".mpy")
        assert mpy.exists(), rel
        parts = ("hoverfly/" + rel)[:-3].split("/")
        if parts[-1] == "__init__":
            parts = parts[:-1]
        arch = mpy_arch(mpy)
        assert arch is not None, rel
        mods[".".join(parts)] = arch
    return mods


def _import_all(lib, mods):
    code = "for m in %r:\n    __import__(m)\nprint('imported', %d)\n" % (mods, len(mods))
    env = dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (lib, ROOT / "tests" / "rp2fakes"))
    return subprocess.run([MICROPYTHON, "-X", "heapsize=1m", "-c", code], capture_output=True, text=True,
                          env=env, cwd=str(lib), timeout=60)


def _module(rel):
    return "hoverfly." + rel[:-3].replace("/", ".")


@pytest.mark.skipif(MPY_CROSS is None, reason="mpy-cross not installed")
@pytest.mark.parametrize("chip", CHIPS)
def test_out_bundle_has_every_module_and_native_modules_as_the_chips_machine_code(chip, tmp_path, capsys):
    assert main(["flash", "--out", str(tmp_path), "--chip", chip, "--mpy-cross", MPY_CROSS]) == 0
    assert "built" in capsys.readouterr().out
    lib = tmp_path / "lib"
    mods = _modules(lib)
    assert "hoverfly.boards.rp2.board" in mods and "hoverfly.core.flight" in mods
    assert not list(lib.rglob("*.py"))  # nothing left as source
    assert (tmp_path / "main.py").read_text().startswith("from hoverfly.boards.rp2.main import main")
    arch = MPY_ARCH[ARCH[chip]]
    native = {_module(rel) for rel in NATIVE_MODULES}
    assert "hoverfly.core.flight" in native
    for name, code in mods.items():
        # the viper accel modules and NATIVE_MODULES are machine code for this chip; the rest is bytecode
        want = arch if name in native or name.startswith("hoverfly.accel.") else 0
        assert code == want, (name, code, want)
    if MICROPYTHON is None:
        return
    # Machine code for a chip: the host VM refuses it ("incompatible .mpy arch", a ValueError).
    res = _import_all(lib, ["hoverfly.core.flight"])
    assert res.returncode != 0 and "incompatible" in res.stderr + res.stdout


@pytest.mark.skipif(MPY_CROSS is None, reason="mpy-cross not installed")
def test_bytecode_bundle_holds_no_machine_code_but_the_viper_modules(tmp_path, capsys):
    assert main(["flash", "--out", str(tmp_path), "--bytecode", "--mpy-cross", MPY_CROSS]) == 0
    assert "(0 as armv6m machine code)" in capsys.readouterr().out
    for name, code in _modules(tmp_path / "lib").items():
        assert code == (MPY_ARCH["armv6m"] if name.startswith("hoverfly.accel.") else 0), name


@pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")
def test_unix_bundle_imports_every_module_under_micropython(unix_bundle):
    lib = unix_bundle / "lib"
    mods = _modules(lib)
    assert mods["hoverfly.core.flight"] == MPY_ARCH["x64"] and mods["hoverfly.accel.rate"] == MPY_ARCH["x64"]
    res = _import_all(lib, sorted(mods))
    assert res.returncode == 0, res.stdout + res.stderr
    assert "imported %d" % len(mods) in res.stdout


def test_unix_bundle_is_not_for_a_board_port(capsys):
    assert main(["flash", "--port", "/dev/ttyACM0", "--chip", "unix-x64"]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "Traceback" not in err and err.count("\n") == 1


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
