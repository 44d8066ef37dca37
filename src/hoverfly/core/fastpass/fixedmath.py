"""The fixed-point kernels' shared arithmetic: the split product, the Q28 product, the float32 decode and scale.

Every fixed-point kernel (fixedimu.py, fixedrate.py, fixedatt.py, ...) imports these, under the names it
likes (`from hoverfly.core.fastpass.fixedmath import dec as _dec, mul as _mul`), so there is one Python
reference of each. hoverfly.fastgen knows them by where they come from: in a generated viper function each
call is written out in place (docs/fastpass.md, the dialect), never called, so these bodies are what the
CPython and MicroPython twins run and what the generated code is held to, bit for bit.

The limits below are the generated code's, not Python's: the viper product is split so that no partial
result passes 2**31 on a 32-bit port (RP2040/RP2350), which holds only within them.
"""

from struct import pack, unpack


def mul(c, x, s):
    """c * x / 2**s rounded half up; the generated code splits x in 16-bit halves, so |c| < 2**15 and
    |x| < 2**31 keep every partial product below 2**31. s >= 0, a constant or a run-time value."""
    if s:
        return (c * x + (1 << (s - 1))) >> s
    return c * x


def mulw(a, b):
    """a * b / 2**28 rounded half up: two Q28 words; the generated code splits both in 15-bit halves, so
    |a| < 2**30, |b| < 2**29 and a result within 2**30 keep every partial sum below 2**31."""
    return (a * b + 0x8000000) >> 28


def dec(x, scale, lim):
    """A float in fixed point: x * scale (a power of two, Q16: 65536.0) truncated toward 0, clamped to
    +-lim, NaN as 0. The generated code reads it from an 'f' array's float32 bits: no float object."""
    if x != x:
        return 0
    v = x * scale
    if v >= lim:
        return lim
    if v <= -lim:
        return -lim
    return int(v)


def float32_of(mantissa, exponent):
    """The float32 of its parts: the mantissa with its hidden bit (2**23..2**24-1) and the biased exponent
    (1..254); exact as this port's float. A kernel multiplies an integer n (|n| < 2**21) by it into an 'f' array:
    n * k rounded once to float32 (a float64 product is exact), which the generated code builds on integers."""
    return unpack("<f", pack("<I", (exponent << 23) | (mantissa & 0x7FFFFF)))[0]
