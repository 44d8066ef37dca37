"""The fast pass generator (hoverfly.fastgen): what it writes runs on MicroPython, 64 and 32 bits, and gives
the Python kernel's bits; what it cannot map is refused with the line.

The stages' own twin tests (tests/portable/test_fixed*.py) hold the generated stages to their Python; here a
small stage written for the purpose drives every construct of the dialect to its edges: the split product at
constant and run-time shifts, the float32 decode at its clamps, the encode's rounding, a helper with early
returns, loops and elifs whose tests need a product first.
"""

import os
import pathlib
import subprocess

import pytest

from hoverfly import fastgen
from test_micropython import MICROPYTHON, MPY_CROSS
from test_micropython32 import MP32, WHERE

ROOT = pathlib.Path(__file__).resolve().parent.parent
SRC = ROOT / "src"

DEMO = '''
from array import array

from hoverfly.compat import const

_LIM = const(0x800000)
_BIG = const(0x40000000)
_Q16 = 65536.0
_Q8 = 256.0
_INV16 = 1.0 / 65536.0


def _mul(c, x, s):
    if s:
        return (c * x + (1 << (s - 1))) >> s
    return c * x


def _dec(x, scale, lim):
    if x != x:
        return 0
    v = x * scale
    if v >= lim:
        return lim
    if v <= -lim:
        return -lim
    return int(v)


def _mulw(a, b):
    return (a * b + 0x8000000) >> 28


def _turn(a, b):
    if a < 0:
        return -b, a
    return b, a >> 1


def _clamp(v, lim):
    if v > lim:
        return lim
    if v < -lim:
        return -lim
    return v


# fastpass: Demo.update co:i st:i fin:f fout:f
def demo_pass(co, st, io, n):
    fin, fout = io
    mul = _mul
    lo = _BIG
    for k in range(n):
        x = _dec(fin[k], _Q16, _LIM)
        st[k] = x
        st[8 + k] = _dec(fin[k], _Q8, 1000)
        st[16 + k] = mul(co[0], st[8 + k], 0) + mul(co[1], x, 8)
        st[24 + k] = mul(co[1], x, 16) + mul(co[0], x, 20)
        st[32 + k] = _clamp(mul(co[1], x, co[2 + k]), co[10])
        if x < lo:
            lo = x
        if mul(co[1], x, 15) > 100:
            st[40 + k] = 1
        elif mul(co[1], x, 14) < -100:
            st[40 + k] = -1
        else:
            st[40 + k] = 0
        st[48 + k] += 1
        if co[11] > 0 and not co[0] or st[k]:  # truth tests on loads, as loaded
            st[48 + k] += 2
        fout[k] = st[16 + k] * _INV16  # past 2**24: the encode rounds
        fout[8 + k] = st[32 + k] * _INV16
        m = fin[k]  # a float local: compared on its bits
        if m > 1.5:
            st[60] += 1
        elif not (m >= -0.25):
            st[61] += 1
        elif m == 0.0:
            st[62] += 1
        else:
            st[63] = int(m * 4096.0)
        if 2.0 <= m:
            st[59] += 1
    g = [0, 0, 0]
    for i, v in enumerate((st[0], st[1], st[2])):
        g[i] = v * 2
    for i in range(3):
        g[i] += st[8 + i]
    p, q = _turn(g[0], g[1])
    g[2] += p - q
    a = b = 0
    for v in g:
        if v > a:
            a, b = v, a
    st[56] = _mulw(st[0] << 6, st[1] << 6)
    st[57] = _turn(g[2], a)[0] + b
    x, y, z = g
    st[58] = x - y + z
    return lo


class Demo:
    def __init__(self):
        self.co = array("i", [0] * 12)
        self.st = array("i", [0] * 64)
        self.fin = array("f", [0.0] * 8)
        self.fout = array("f", [0.0] * 16)
        self._tab = array("i", [0] * 10)

    def update(self, n):
        r = demo_pass(self.co, self.st, (self.fin, self.fout), n)
        self.lo = r + 1
'''

# The function form (no address table: the encode's exponent by halving steps), on the encode's whole range.
DEMO_FN = '''
_INV16 = 1.0 / 65536.0


# fastpass: encode_all a:i f:f
def encode_all(a, f, n):
    s = 0
    for k in range(n):
        f[k] = a[k] * _INV16
        s += a[k] & 1
    return s
'''

DRIVER = '''
import sys
from array import array
import demo
import demo_fast
from hoverfly.accel.addr import bind

def lcg():
    s = [12345]
    def nxt():
        s[0] = (s[0] * 1103515245 + 12345) & 0x7FFFFFFF
        return s[0]
    return nxt

rnd = lcg()
a = demo.Demo()
b = demo.Demo()
bind(b._tab, 0, b.co)
bind(b._tab, 1, b.st)
bind(b._tab, 2, b.fin)
bind(b._tab, 3, b.fout)
bind(b._tab, 4, demo_fast.LOG2)
odd = (0.0, -0.0, 1e-9, 127.99999, 128.0, -128.0, 1e30, -1e30, float("inf"), float("-inf"), float("nan"),
       3.9, -3.9, 0.5, 2.0 ** -16, 2.0 ** -17, 255.5, 1000.0 / 256.0, 4.0, 1.5, -0.25, 2.0, 1.0)
bad = 0
for n in range(4000):
    for k in range(12):
        v = (rnd() & 0x7FFF) - 0x4000
        if rnd() & 7 == 0:
            v = 0
        if k >= 2 and k < 10:
            v = 8 + rnd() % 23  # the run-time shifts
        if k == 10:
            v = rnd() & 0x7FFFFF
        a.co[k] = b.co[k] = v
    for k in range(8):
        r = rnd()
        if r & 3 == 0:
            x = odd[r % len(odd)]
        else:
            x = ((r & 0xFFFFFF) - 0x800000) / float(1 << (r % 20))
        a.fin[k] = b.fin[k] = x
    demo.Demo.update(a, 8)
    demo_fast.update(b, 8)
    if a.lo != b.lo:
        bad += 1
    for k in range(64):
        if a.st[k] != b.st[k]:
            bad += 1
            if bad < 5:
                print("st", n, k, a.st[k], b.st[k], [a.fin[j] for j in range(8)], list(a.co))
    for k in range(16):
        if a.fout[k] != b.fout[k]:
            bad += 1
            if bad < 5:
                print("fout", n, k, a.fout[k], b.fout[k])
import demo_fn
import demo_fn_fast
ia = array("i", [0] * 64)
fa = array("f", [0.0] * 64)
fb = array("f", [0.0] * 64)
for n in range(300):
    for k in range(64):
        r = rnd()
        v = (r & 0x7FFFFFFF) >> (r % 31)
        ia[k] = -v if k & 1 else v
    if demo_fn.encode_all(ia, fa, 64) != demo_fn_fast.encode_all(ia, fb, 64):
        bad += 1
    for k in range(64):
        if fa[k] != fb[k]:
            bad += 1
print("mismatches", bad)
'''


# Several kernels in one module (rc.py's rc_pass and rc_frame): a method on the call's arrays with unsigned
# 16-bit ones (receiver channels), their len(), an augmented store and chained comparisons; and a function
# comparing float locals with each other and storing them (FaultWatch's frozen-sample check), every IEEE 754
# corner in its inputs.
DEMO_MULTI = '''
from array import array

from hoverfly.compat import const

_INF = float("inf")
_NEG_INF = float("-inf")
_GROUPS = const(4)


def _in(v, lo, hi):
    return 1 if lo <= v < hi else 0


# fastpass: Frames.take ch:H@ src:H@ lims:i@ out:i@
def frame_bits(ch, src, lims, out):
    n = len(ch)
    for i in range(len(src)):
        ch[i] = src[i]
    ch[n - 1] += 7
    r = 0
    bit = 1
    k = 0
    while k < 3 * _GROUPS:
        c = lims[k]
        if 0 < c <= n and lims[k + 1] <= ch[c - 1] < lims[k + 2]:
            r |= bit
        if lims[k + 1] < c < lims[k + 2] <= n:
            r |= bit << 8
        if 0 < c <= n:
            r += _in(ch[c - 1], lims[k + 1], lims[k + 2]) << 16
        bit <<= 1
        k += 3
    out[0] = r
    return n


class Frames:
    def __init__(self):
        self.ch = array("H", [0] * 18)
        self.lims = array("i", [0] * 12)
        self.out = array("i", [0])
        self.n = 0

    def take(self, src):
        n = frame_bits(self.ch, src, self.lims, self.out)
        self.n = n + 1


# fastpass: float_order a:f b:f out:i
def float_order(a, b, out, n):
    total = 0
    for i in range(n):
        x = a[i]
        y = b[i]
        r = 0
        if x == y:
            r |= 1
        if x != y:
            r |= 2
        if x < y:
            r |= 4
        if x <= y:
            r |= 8
        if y > x:
            r |= 16
        if y >= x:
            r |= 32
        if _NEG_INF < x < _INF:
            r |= 64
        if not (-1.0 <= y <= 1.0):
            r |= 128
        out[i] = r
        b[i] = x
        total += r
    return total
'''

DRIVER_MULTI = '''
import struct
from array import array
import demo_multi
import demo_multi_fast

s = [777]
def rnd():
    s[0] = (s[0] * 1103515245 + 12345) & 0x7FFFFFFF
    return s[0]

def bits(x):
    return struct.unpack("<I", struct.pack("<f", x))[0]

bad = 0
a = demo_multi.Frames()
b = demo_multi.Frames()
src = array("H", [0] * 16)
for n in range(3000):
    for k in range(12):
        v = rnd() % 20 if k % 3 == 0 else 800 + rnd() % 1500  # channels 0 (none) .. 19 (beyond the 18)
        a.lims[k] = b.lims[k] = v
    for k in range(16):
        src[k] = (0, 1000, 1500, 2000, 60000, rnd() % 2600)[rnd() % 6]
    demo_multi.Frames.take(a, src)
    demo_multi_fast.take(b, src)
    if a.n != b.n or a.out[0] != b.out[0] or list(a.ch) != list(b.ch):
        bad += 1
        if bad < 5:
            print("frame", n, a.n, b.n, a.out[0], b.out[0], list(a.ch), list(b.ch))
odd = (0.0, -0.0, 1.0, -1.0, 1.0000001, -0.99999994, 1e-45, -1e-45, 3.4028234e38, -3.4028234e38, float("inf"),
       float("-inf"), float("nan"), -float("nan"), 2.5, -2.5, 0.1)
fa = array("f", [0.0] * 16)
fb = array("f", [0.0] * 16)
ga = array("f", [0.0] * 16)
gb = array("f", [0.0] * 16)
oa = array("i", [0] * 16)
ob = array("i", [0] * 16)
for n in range(3000):
    for k in range(16):
        x = odd[rnd() % len(odd)]
        y = x if rnd() & 3 == 0 else odd[rnd() % len(odd)]
        fa[k] = fb[k] = x
        ga[k] = gb[k] = y
    if demo_multi.float_order(fa, ga, oa, 16) != demo_multi_fast.float_order(fb, gb, ob, 16):
        bad += 1
    for k in range(16):
        same = bits(ga[k]) == bits(gb[k]) or (ga[k] != ga[k] and gb[k] != gb[k])  # a NaN's payload may differ
        if oa[k] != ob[k] or not same:
            bad += 1
            if bad < 5:
                print("float", n, k, fa[k], ga[k], gb[k], oa[k], ob[k])
print("mismatches", bad)
'''


# The shared arithmetic imported, not written in the module (core/fastpass/fixedmath.py, under names of the
# kernel's choosing), and a helper of another module (fixedatt's CORDIC _atan2, which reads its own module's
# constants N_CORDIC, CO_ATAN and _HALF_PI) inlined with them.
DEMO_IMPORTED = '''
from hoverfly.core.fastpass.fixedatt import _atan2 as atan2_q28
from hoverfly.core.fastpass.fixedmath import dec as to_q16
from hoverfly.core.fastpass.fixedmath import mul as scaled
from hoverfly.core.fastpass.fixedmath import mulw as mul_q28


# fastpass: headings co:i gain:i fin:f out:i
def headings(co, gain, fin, out, n):
    for k in range(n):
        x = to_q16(fin[k], 65536.0, 0x800000)
        y = to_q16(fin[n + k], 65536.0, 0x800000)
        z, r = atan2_q28(co, y, x)
        out[k] = z
        out[n + k] = r
        out[2 * n + k] = scaled(gain[k], x, 12) + mul_q28(x << 5, y << 5) + scaled(gain[k], y, gain[n + k])
    return n
'''

DRIVER_IMPORTED = '''
from array import array
import demo_imported
import demo_imported_fast
from hoverfly.core.fastpass import fixedatt

s = [4242]
def rnd():
    s[0] = (s[0] * 1103515245 + 12345) & 0x7FFFFFFF
    return s[0]

co = array("i", [0] * fixedatt.CO_SIZE)
fixedatt._fill_tables(co)
gain = array("i", [0] * 16)
fin = array("f", [0.0] * 16)
oa = array("i", [0] * 24)
ob = array("i", [0] * 24)
odd = (0.0, -0.0, 127.99, -128.0, 1e30, float("inf"), float("-inf"), float("nan"), 2.0 ** -16, -3.5)
bad = 0
for n in range(3000):
    for k in range(8):
        gain[k] = (rnd() & 0x7FFF) - 0x4000
        gain[8 + k] = rnd() % 31
    for k in range(16):
        r = rnd()
        fin[k] = odd[r % len(odd)] if r & 3 == 0 else ((r & 0xFFFFFF) - 0x800000) / float(1 << (r % 20))
    if demo_imported.headings(co, gain, fin, oa, 8) != demo_imported_fast.headings(co, gain, fin, ob, 8):
        bad += 1
    for k in range(24):
        if oa[k] != ob[k]:
            bad += 1
            if bad < 5:
                print("out", n, k, oa[k], ob[k])
print("mismatches", bad)
'''


# The byte-level dialect the codecs are written in (protocols/rxcodec.py, crc.py): bytes and bytearrays as ptr8
# (unsigned), 16-bit words as ptr16, module tables (bytes, array('H')) read through pointers, under another name
# too, len() of a byte argument, byte stores, and an early return.
DEMO_BYTES = '''
from array import array

_TABLE = bytes([(i * 37 + 11) & 0xFF for i in range(256)])
_WORDS = array("H", [(i * 40503 + 7) & 0xFFFF for i in range(64)])


# fastpass: mix src:B out:B words:H acc:i
def mix(src, p, n, out, words, acc):
    t = _TABLE
    c = 0
    for i in range(p, p + n):
        c = t[c ^ src[i]]
        out[i - p] = c
        out[n + i - p] = (src[i] << 3) & 0xFF
    words[0] = c | (src[p] << 8)
    words[1] = _WORDS[c & 63]
    acc[0] += _WORDS[c & 63] - 30000
    if c > 200:
        return len(src) - c
    total = 0
    k = 0
    while k < n:
        total += src[p + k] * (k + 1)
        k += 1
    return total
'''

DRIVER_BYTES = '''
from array import array
import demo_bytes
import demo_bytes_fast

s = [99]
def rnd():
    s[0] = (s[0] * 1103515245 + 12345) & 0x7FFFFFFF
    return s[0] >> 8

bad = 0
for n in range(3000):
    size = 1 + rnd() % 40
    src = bytearray([rnd() & 0xFF for _ in range(size)])
    if n & 1:
        src = bytes(src)
    p = rnd() % size
    k = rnd() % (size - p + 1)
    oa = bytearray(2 * k + 1)
    ob = bytearray(2 * k + 1)
    wa = array("H", [0, 0])
    wb = array("H", [0, 0])
    aa = array("i", [n * 7919 - 10000000])
    ab = array("i", [n * 7919 - 10000000])
    if k == 0:
        continue
    ra = demo_bytes.mix(src, p, k, oa, wa, aa)
    rb = demo_bytes_fast.mix(src, p, k, ob, wb, ab)
    if ra != rb or oa != ob or list(wa) != list(wb) or aa[0] != ab[0]:
        bad += 1
        if bad < 5:
            print("mix", n, ra, rb, bytes(oa), bytes(ob), list(wa), list(wb), aa[0], ab[0])
print("mismatches", bad)
'''


# Floats crossed with integers as the codecs do (drivers/mpu6050.py, protocols/dshot.py): a count times a float32
# scale given as its parts into an 'f' array, and an integer times a float local floored as the port's float
# product is (here a float64 port's: exact), the float local clamped to constants first.
DEMO_FLOATS = '''
from hoverfly.core.fastpass.fixedmath import float32_of


# fastpass: scale_all counts:i parts:i out:f
def scale_all(counts, parts, out, n):
    k = float32_of(parts[0], parts[1])
    for i in range(n):
        out[i] = counts[i] * k
    return n


# fastpass: products t:f xs:i res:i
def products(t, xs, res, n):
    for i in range(n):
        m = t[i]
        if m > 1.0:
            m = 1.0
        elif not (m >= -1.0):
            m = 0.0
        res[i] = int(xs[i] * m)
    return n
'''

DRIVER_FLOATS = '''
import struct
from array import array
import demo_floats
import demo_floats_fast

s = [2024]
def rnd():
    s[0] = (s[0] * 1103515245 + 12345) & 0x7FFFFFFF
    return s[0] >> 4

def bits(x):
    return struct.unpack("<I", struct.pack("<f", x))[0]

bad = 0
counts = array("i", [0] * 16)
parts = array("i", [0, 0])
oa = array("f", [0.0] * 16)
ob = array("f", [0.0] * 16)
for n in range(2000):
    parts[0] = 0x800000 | (rnd() & 0x7FFFFF) if n % 5 else 0x800000 | ((rnd() & 0x7FF) << 12)  # ties often
    parts[1] = 60 + rnd() % 120
    for i in range(16):
        v = rnd() % (1 << (1 + rnd() % 21))
        counts[i] = -v if rnd() & 1 else v
    demo_floats.scale_all(counts, parts, oa, 16)
    demo_floats_fast.scale_all(counts, parts, ob, 16)
    for i in range(16):
        if bits(oa[i]) != bits(ob[i]):
            bad += 1
            if bad < 5:
                print("scale", parts[0], parts[1], counts[i], oa[i], ob[i])
odd = (0.0, -0.0, 1.0, -1.0, 0.99999994, -0.99999994, 1e-45, -1e-45, 1e-40, 2.0, -2.0, float("inf"), float("-inf"),
       float("nan"), 0.5, 1.0 / 3, 2.0 ** -24, 1e30)
t = array("f", [0.0] * 16)
xs = array("i", [0] * 16)
ra = array("i", [0] * 16)
rb = array("i", [0] * 16)
for n in range(3000):
    for i in range(16):
        r = rnd()
        t[i] = odd[r % len(odd)] if r & 3 == 0 else ((rnd() & 0xFFFFFF) / 16777216.0) * (2.0 ** -(rnd() % 30))
        if rnd() & 1:
            t[i] = -t[i]
        xs[i] = rnd() % (1 << (1 + rnd() % 27))
    demo_floats.products(t, xs, ra, 16)
    demo_floats_fast.products(t, xs, rb, 16)
    for i in range(16):
        if ra[i] != rb[i]:
            bad += 1
            if bad < 5:
                print("product", t[i], xs[i], ra[i], rb[i])
print("mismatches", bad)
'''


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("fastgen-demo")
    (d / "demo.py").write_text(DEMO)
    (d / "demo_fast.py").write_text(fastgen.generate_source(DEMO, "demo.py"))
    (d / "demo_fn.py").write_text(DEMO_FN)
    (d / "demo_fn_fast.py").write_text(fastgen.generate_source(DEMO_FN, "demo_fn.py"))
    (d / "driver.py").write_text(DRIVER)
    (d / "demo_multi.py").write_text(DEMO_MULTI)
    (d / "demo_multi_fast.py").write_text(fastgen.generate_source(DEMO_MULTI, "demo_multi.py"))
    (d / "driver_multi.py").write_text(DRIVER_MULTI)
    (d / "demo_imported.py").write_text(DEMO_IMPORTED)
    (d / "demo_imported_fast.py").write_text(fastgen.generate_source(DEMO_IMPORTED, "demo_imported.py"))
    (d / "driver_imported.py").write_text(DRIVER_IMPORTED)
    (d / "demo_bytes.py").write_text(DEMO_BYTES)
    (d / "demo_bytes_fast.py").write_text(fastgen.generate_source(DEMO_BYTES, "demo_bytes.py"))
    (d / "driver_bytes.py").write_text(DRIVER_BYTES)
    (d / "demo_floats.py").write_text(DEMO_FLOATS)
    (d / "demo_floats_fast.py").write_text(fastgen.generate_source(DEMO_FLOATS, "demo_floats.py"))
    (d / "driver_floats.py").write_text(DRIVER_FLOATS)
    return d


def _run(demo_dir, vm, driver):
    exe = MICROPYTHON
    if vm != "64-bit":  # as tests/test_micropython32.py: missing, the 32-bit check fails and says where to get it
        if os.environ.get("HOVERFLY_NO_MP32") == "1":
            pytest.skip("HOVERFLY_NO_MP32=1: the 32-bit MicroPython checks are off")
        if not os.path.isfile(MP32):
            pytest.fail("no 32-bit MicroPython: " + WHERE % MP32, pytrace=False)
        exe = MP32
    res = subprocess.run([exe, "-X", "heapsize=4m", str(demo_dir / driver)], capture_output=True, text=True,
                         timeout=300, env={"MICROPYPATH": "%s:%s:.frozen" % (demo_dir, SRC)})
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.strip().endswith("mismatches 0"), res.stdout[-2000:]


@pytest.mark.parametrize("vm", ["64-bit", "32-bit"])
def test_the_generated_code_gives_the_python_kernels_bits_on_64_and_32_bits(demo_dir, vm):
    _run(demo_dir, vm, "driver.py")


@pytest.mark.parametrize("vm", ["64-bit", "32-bit"])
def test_two_kernels_of_a_module_16_bit_arrays_chains_and_float_pairs_give_the_pythons_bits(demo_dir, vm):
    _run(demo_dir, vm, "driver_multi.py")


@pytest.mark.parametrize("vm", ["64-bit", "32-bit"])
def test_imported_intrinsics_and_another_modules_helper_give_the_pythons_bits(demo_dir, vm):
    _run(demo_dir, vm, "driver_imported.py")


@pytest.mark.parametrize("vm", ["64-bit", "32-bit"])
def test_byte_level_kernels_bytes_words_and_module_tables_give_the_pythons_results(demo_dir, vm):
    _run(demo_dir, vm, "driver_bytes.py")


@pytest.mark.parametrize("vm", ["64-bit", "32-bit"])
def test_counts_times_float32_scales_and_integers_times_float_locals_give_the_pythons_bits(demo_dir, vm):
    _run(demo_dir, vm, "driver_floats.py")


def test_a_module_table_is_imported_from_the_kernels_module_and_read_through_a_pointer(demo_dir):
    text = (demo_dir / "demo_bytes_fast.py").read_text()
    assert "from demo_bytes import _TABLE, _WORDS" in text
    assert "ptr8(_TABLE)" in text and "ptr16(_WORDS)" in text and "ptr8(_src_obj)" in text


def test_a_drivers_read_stays_a_bool_method_with_its_counters_done_on_ints():
    # drivers/mpu6050.py: `if read_burst(...):`, `self.samples += 1`, `return True` (the twin test,
    # tests/portable/test_mpu6050_twins.py, holds its bits to the Python on both VMs)
    text = fastgen.generate("mpu6050")
    assert "def read(self, gyro_rad_s, accel_m_s2) -> bool:" in text
    assert "self.samples = int(self.samples) + 1" in text and "self.bus_errors = int(self.bus_errors) + 1" in text
    assert "if _result:\n        self._finish(gyro_rad_s, accel_m_s2)" in text
    assert "float32_of" not in text  # the scale's product written out on integers


def _bodies(text):
    return text[text.index("\n@micropython.viper\n"):]


def test_the_intrinsics_imported_from_fixedmath_are_written_out_as_a_modules_own_are():
    own = DEMO.split("\n\n\ndef _mul(")[0] + "\n\n\ndef _turn(" + DEMO.split("\n\n\ndef _turn(")[1]
    imported = own.replace("from hoverfly.compat import const\n", "from hoverfly.compat import const\n"
                           "from hoverfly.core.fastpass.fixedmath import dec as _dec\n"
                           "from hoverfly.core.fastpass.fixedmath import mul as _mul\n"
                           "from hoverfly.core.fastpass.fixedmath import mulw as _mulw\n")
    assert "def _mul(" not in imported and "import mul as _mul" in imported
    assert _bodies(fastgen.generate_source(imported)) == _bodies(fastgen.generate_source(DEMO))
    # written out in place, never called: the generated module imports nothing of fixedmath
    assert "fixedmath" not in fastgen.generate_source(imported)


def test_a_stage_is_generated_again_when_a_module_it_imports_helpers_from_changes(monkeypatch):
    before = fastgen.source_hash("hoverfly.core.fastpass.fixedimu")
    assert "hoverfly.core.fastpass.fixedmath" in fastgen._imported_modules(
        (SRC / "hoverfly/core/fastpass/fixedimu.py").read_text())
    real = pathlib.Path.read_bytes

    def edited(path):
        data = real(path)
        return data + b"\n# edited\n" if path.name == "fixedmath.py" else data

    monkeypatch.setattr(pathlib.Path, "read_bytes", edited)
    assert fastgen.source_hash("hoverfly.core.fastpass.fixedimu") != before


def test_a_module_of_two_kernels_is_one_module_of_two_viper_functions(demo_dir):
    text = (demo_dir / "demo_multi_fast.py").read_text()
    assert text.count("\n@micropython.viper\ndef ") == 2
    assert "def take(self, src)" in text and "def float_order(" in text
    assert "ptr16(self.ch)" in text and "int(len(self.ch))" in text


def test_a_constant_of_2_30_is_built_at_run_time_not_written_as_a_literal(demo_dir):
    text = (demo_dir / "demo_fast.py").read_text()
    assert "(_one << 30)" in text
    assert "1073741824" not in text


def _refused(body, why):
    src = DEMO.replace("    return lo\n", body + "    return lo\n", 1).replace(
        "from hoverfly.compat import const\n",
        "from hoverfly.compat import const\nfrom hoverfly.core.fastpass.fixedmath import float32_of\n")
    with pytest.raises(fastgen.FastGenError, match=why):
        fastgen.generate_source(src)


def test_what_the_generator_cannot_map_is_refused_with_the_reason():
    _refused("    lo = fin[0] + 1\n", "read only through _dec")
    _refused("    m = fin[0]\n    if m > 0.1:\n        lo = 1\n", "not a float32")
    _refused("    m = fin[0]\n    lo = m + 1\n", "float local")
    _refused("    fout[0] = lo * 0.3\n", "power of two")
    _refused("    lo = lo * 0.5\n", "float constant")
    _refused("    for k in range(3):\n        continue\n", "continue")
    _refused("    lo = undefined_name\n", "unknown name")
    _refused("    lo = len(co)\n", "not in the dialect")
    _refused("    lo = _dec(fin[0], 3.0, 5)\n", "power of two")
    _refused("    if 0 < mul(co[1], lo, 3) < 5:\n        lo = 1\n", "plain value")
    _refused("    m = fin[0]\n    lo = len(fin)\n", "only of an array from the call")
    _refused("    k = float32_of(co[0], co[1])\n    lo = k + 1\n", "float32 scale")
    with pytest.raises(fastgen.FastGenError, match="one kernel a module"):
        fastgen.generate_source(DEMO + DEMO.split("class Demo")[0].split("# fastpass: ")[0]
                                + "# fastpass: Demo.again co:i st:i fin:f fout:f\ndef again(co, st, io, n):\n"
                                + "    return 0\n")


def test_every_stage_is_generated_current_and_compiles_for_64_and_32_bit_machine_code(tmp_path):
    fastgen.generate_all()
    for name in fastgen.STAGES:
        assert fastgen.is_current(name), name
        if MPY_CROSS is None:
            continue
        for arch in ("x64", "x86", "armv6m"):
            out = tmp_path / ("%s-%s.mpy" % (name, arch))
            res = subprocess.run([MPY_CROSS, "-march=" + arch, "-o", str(out), str(fastgen.generated_path(name))],
                                 capture_output=True, text=True)
            assert res.returncode == 0, (name, arch, res.stderr)


def test_a_changed_source_is_generated_again():
    name = next(iter(fastgen.STAGES))
    path = fastgen.generated_path(name)
    path.write_text(path.read_text().replace(fastgen.HASH_LINE, fastgen.HASH_LINE + "0"))
    assert not fastgen.is_current(name)
    assert fastgen.generate_all() == [path]
    assert fastgen.is_current(name)


def test_the_generated_files_are_not_committed():
    res = subprocess.run(["git", "check-ignore", "-q", str(fastgen.generated_path(next(iter(fastgen.STAGES))))],
                         cwd=ROOT)
    assert res.returncode == 0
