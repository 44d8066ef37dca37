"""The portable tests on a 32-bit MicroPython, where viper integers wrap at 32 bits as on the Pico.

The PyPI MicroPython VM (tests/test_micropython.py) is a 64-bit build: a viper product past 2**31
there is still exact, so a viper stage that lets one through passes every twin test on it and
gives wrong motor commands on an RP2040/RP2350. The 32-bit unix port (`micropython-i686`, viper and
the x86 native emitter; /work/shared/tools/README.md) has the Pico's integer width, and here runs the
same portable suite with the same setup: tests/portable/mprun.py from `src/` and `tests/portable/`,
with the viper stages tests/conftest.py generated (docs/fastpass.md), twin and bound tests included.

CI finds the binary at ../shared/tools/micropython-i686 from the repository's root (or at the path in
HOVERFLY_MP32). Missing, these tests fail and say where to get it; HOVERFLY_NO_MP32=1 turns them off
on a machine that cannot run it (README, Development).
"""

import os
import subprocess

import pytest

from test_micropython import MICROPYTHON, MPY_CROSS, ROOT, SRC, SUITE_HEAP

MP32 = os.environ.get("HOVERFLY_MP32") or str(ROOT.parent / "shared" / "tools" / "micropython-i686")
WHERE = (
    "a 32-bit MicroPython unix port (static i686 build with viper) is expected at %s: the team copy is "
    "../shared/tools/micropython-i686 (see ../shared/tools/README.md; built from micropython/micropython "
    "with the recipe in ../shared/reference/micropython.md section 4.x, or point HOVERFLY_MP32 at one). "
    "Without it the Pico's 32-bit integer arithmetic is not checked; HOVERFLY_NO_MP32=1 skips these tests"
)


def _env():
    # The same MICROPYPATH as the 64-bit runs in tests/test_micropython.py: the sources and the generated
    # viper stages from src/, the portable tests beside them.
    return dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (SRC, ROOT / "tests" / "portable"))


def _run(exe, args, timeout=600):
    return subprocess.run([exe] + args, capture_output=True, text=True, timeout=timeout, cwd=str(ROOT), env=_env())


@pytest.fixture(scope="module")
def mp32():
    if os.environ.get("HOVERFLY_NO_MP32") == "1":
        pytest.skip("HOVERFLY_NO_MP32=1: the 32-bit MicroPython checks are off")
    if not (os.path.isfile(MP32) and os.access(MP32, os.X_OK)):
        pytest.fail("no 32-bit MicroPython: " + WHERE % MP32, pytrace=False)
    res = _run(MP32, ["-c", "import sys; print(sys.maxsize)"], timeout=60)
    if res.returncode != 0 or res.stdout.strip() != str(2**31 - 1):
        pytest.fail("%s is not a 32-bit MicroPython (sys.maxsize %r): %s" % (MP32, res.stdout.strip() + res.stderr,
                                                                             WHERE % MP32), pytrace=False)
    return MP32


def test_portable_tests_pass_on_32_bit_micropython(mp32):
    res = _run(mp32, ["-X", SUITE_HEAP, str(ROOT / "tests" / "portable" / "mprun.py")])
    print(res.stdout[-3000:])
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-2000:]
    assert " 0 failed" in res.stdout


# The fixed-point pass's product c * x / 2**s (core/fastpass/fixedrate.py `_mul`, the reference) with |c| < 2**15 and
# |x| < 2**30, in viper: whole, as the Python reads, and split on x's 16-bit halves, as the generated viper
# stages write it. Each line: c x s reference whole split.
_PRODUCTS = """
import micropython
from hoverfly.core.fastpass.fixedrate import _mul


@micropython.viper
def whole(c: int, x: int, s: int) -> int:
    return (c * x + ((1 << s) >> 1)) >> s


@micropython.viper
def split(c: int, x: int, s: int) -> int:
    return ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((1 << s) >> 1)) >> s)


for c, x, s in %r:
    print(c, x, s, _mul(c, x, s), whole(c, x, s), split(c, x, s))
"""
_CASES = [(c, x, s) for c in (3, 181, -181, 20000, -32767, 32767) for x in (1000, 65535, 1 << 20, -(1 << 20),
                                                                              123456789, -987654321, (1 << 30) - 1)
          for s in (0, 8, 16) if abs(c * x) >> s < (1 << 30)]  # results the fixed pass's words can hold


def _wrap32(v):
    return ((v + (1 << 31)) & 0xFFFFFFFF) - (1 << 31)


def _products(exe):
    res = _run(exe, ["-c", _PRODUCTS % (_CASES,)], timeout=60)
    assert res.returncode == 0, res.stdout + res.stderr
    rows = [tuple(int(v) for v in line.split()) for line in res.stdout.split("\n") if line.strip()]
    assert len(rows) == len(_CASES)
    return rows


@pytest.mark.skipif(MICROPYTHON is None, reason="the 64-bit micropython not installed")
def test_a_viper_product_past_2_to_the_31_is_caught_on_32_bits_and_not_on_64(mp32):
    # A viper stage that multiplies whole where the product can pass 2**31: on the 64-bit VM it gives the
    # Python twin's result, so the twin tests there pass; on 32 bits (the Pico) it wraps. Only this VM sees it.
    past = 0
    for c, x, s, want, whole, split in _products(MICROPYTHON):
        assert whole == want and split == want, (c, x, s, want, whole, split)
    for c, x, s, want, whole, split in _products(mp32):
        assert split == want, ("the split product must be exact on 32 bits", c, x, s, want, split)
        r = (1 << s) >> 1
        if -(1 << 31) <= c * x + r < (1 << 31):
            assert whole == want, (c, x, s, want, whole)
        else:
            past += 1
            assert whole != want and whole == _wrap32(c * x + r) >> s, (c, x, s, want, whole)
    assert past >= 30  # a third of the cases pass 2**31: the check is not vacuous


@pytest.mark.skipif(MPY_CROSS is None, reason="mpy-cross not installed")
def test_portable_tests_pass_on_32_bits_from_an_x86_flash_bundle(mp32, tmp_path, monkeypatch):
    # As a board loads it: the bundle `hoverfly flash` builds, precompiled, its NATIVE_MODULES and the viper
    # stages as 32-bit machine code (mpy-cross -march=x86 here, armv6m/armv7m/rv32imc on the chips).
    from hoverfly import cli_flash

    monkeypatch.setitem(cli_flash.ARCH, "unix-x86", "x86")
    cli_flash.build(tmp_path, "unix-x86", MPY_CROSS)
    lib = tmp_path / "lib"
    env = dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (lib, ROOT / "tests" / "portable"))
    where = subprocess.run([mp32, "-c", "import hoverfly.core.flight as f; print(f.__file__)"],
                           capture_output=True, text=True, env=env, timeout=60)
    assert where.stdout.strip() == str(lib / "hoverfly" / "core" / "flight.mpy"), where.stdout + where.stderr
    res = subprocess.run([mp32, "-X", SUITE_HEAP, str(ROOT / "tests" / "portable" / "mprun.py")],
                         capture_output=True, text=True, timeout=600, cwd=str(ROOT), env=env)
    print(res.stdout[-3000:])
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-2000:]
    assert " 0 failed" in res.stdout
