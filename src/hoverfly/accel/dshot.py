"""Viper twin of DShot's per-pass motor encode (MicroPython only; chosen at import by protocols/dshot.py).

Takes what DshotEncoder.encode_motors' armed loop takes (motor commands 0..1, the fixed-point
throttle range, the flags) and gives the same DShot words, bit for bit, as that pure-Python loop,
which stays the reference and the fallback wherever viper is missing (CPython, the wasm port):

- `encode_armed(motor_norm, n, low_fp, span_fp, stop_at_zero, tm, bidir, out_words)`: one
  16-bit word per motor into out_words[0..n-1] (array('H'), written through ptr16, so it must
  be one and hold n words). Returns `moving | clamped << 8`: how many words differ from the stop
  word, and how many commands were outside 0..1 or NaN (n <= 8 motors, so moving fits 8 bits).

It sits at the end of the pass (output codec, board.write_motors). The float part stays
Python objects (a motor command is a float; `span_fp * t` is the same float product the Python
twin makes, truncated by the same `int`), so the words cannot differ on a float32 or float64
port; the clamps, the fixed-point shift and the CRC nibble are machine words.
Viper ints are 32-bit on the RP2040/RP2350: low_fp + span_fp * t <= low_fp + span_fp =
(2047 + 0.5) * 65536 < 2**28 for any idle (dshot._fixed_point_range), and the word is 16 bits,
so every intermediate stays below 2**31. tests/portable/test_viper_twins.py checks the twins agree.
"""

# ptr16/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython

_trunc = int  # the float -> int truncation as a call: viper's int() cast would not take a float
_ONE = 1.0
_ZERO = 0.0


@micropython.viper
def encode_armed(motor_norm, n: int, low_fp: int, span_fp, stop_at_zero: int, tm: int, bidir: int,
                 out_words) -> int:
    o = ptr16(out_words)
    one = _ONE
    zero = _ZERO
    trunc = _trunc
    moving = 0
    clamped = 0
    i = 0
    while i < n:
        t = motor_norm[i]
        v = -1
        if t > one:
            t = one
            clamped += 1
        elif not (t >= zero):  # below 0, or NaN
            clamped += 1
            if stop_at_zero:
                v = 0
            else:
                t = zero
        elif stop_at_zero and t == zero:
            v = 0
        if v < 0:
            v = (low_fp + int(trunc(span_fp * t))) >> 16
            if v > 2047:
                v = 2047
        w = v << 1
        if i == tm:
            w |= 1
        if w:
            moving += 1
        c = w ^ (w >> 4) ^ (w >> 8)
        if bidir:
            c = ~c
        o[i] = (w << 4) | (c & 0xF)
        i += 1
    return moving | (clamped << 8)
