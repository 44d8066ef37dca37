"""Viper twin of the board codec's DShot encode (MicroPython only; chosen at import by protocols/dshot.py).

- `encode_planned(motor_out_a, count, plan_a, out_words)`: protocols/dshot.py `encode_planned` on the
  float32 bits of an array('f') (the motor commands 0..1), following DshotEncoder.plan's array: one
  16-bit word per motor on its output line in out_words (array('H'), written through ptr16). Returns
  `moving | clamped << 8`. The same words, bit for bit, as the Python twin, which stays the reference
  and the fallback wherever viper is missing (CPython, the wasm port, a list of commands);
  tests/portable/test_dshot_planned.py checks them.

It sits at the end of the pass (output codec, board.write_motors) and makes no float object.
"""

# ptr16/ptr32/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython


@micropython.viper
def encode_planned(motor_out_a, count: int, plan_a, out_words) -> int:
    """protocols/dshot.py `encode_planned` on the float32 bits of an array('f'): no float object at all.

    plan (array('i'), DshotEncoder.plan): [0] motors, [1] low_fp, [2] span_fp (< 2**27), [3] flags
    (1 stop at zero, 2 bidirectional, 4 the port's floats are float32), [4] telemetry motor + 1,
    [5 + motor] its output line. The product span_fp * t is worked out exactly on integers,
    span_fp * mantissa as hi * 2**24 + lo from 12-bit limbs (every partial below 2**28), then
    rounded to 24 significant bits (nearest, ties to even) where the port's float is float32, as
    its float product is; on a double port the product is exact anyway (at most 51 bits), so
    `int(span_fp * t)` is the floor of the exact product. Returns moving | clamped << 8.
    """
    t = ptr32(motor_out_a)
    p = ptr32(plan_a)
    o = ptr16(out_words)
    n = int(p[0])
    if count < n:
        n = count
    low = int(p[1])
    span = int(p[2])
    flags = int(p[3])
    tm = int(p[4]) - 1
    stop_at_zero = flags & 1
    bidir = flags & 2
    round24 = flags & 4
    s1 = span >> 12  # below 2**15
    s0 = span & 0xFFF
    one = 1
    low31 = (one << 31) - 1  # 0x7FFFFFFF and 0x7F800000 (+inf): no constant of 2**30 or more, which is
    inf = ((one << 8) - 1) << 23  # not a small int on a 32-bit port
    moving = 0
    clamped = 0
    i = 0
    while i < n:
        b = t[i]
        mag = b & low31
        v = -1
        fp = 0  # floor(span_fp * t) on the port's float
        if mag > inf or ((b >> 31) & 1 and mag != 0):  # NaN, or below 0 (-0.0 is 0)
            clamped += 1
            if stop_at_zero:
                v = 0
        elif mag > 0x3F800000:  # above 1.0, +inf included
            clamped += 1
            fp = span
        elif mag == 0:
            if stop_at_zero:
                v = 0
        elif mag == 0x3F800000:  # 1.0: span_fp itself (a float on either port)
            fp = span
        else:
            e = mag >> 23
            m = mag & 0x7FFFFF
            if e == 0:  # subnormal: m * 2**-149
                e = 1
            else:
                m = m | 0x800000
            q = 150 - e  # t = m / 2**q, q >= 24 below 1.0
            m1 = m >> 12
            m0 = m & 0xFFF
            mid = s1 * m0 + s0 * m1  # below 2**28
            lo = s0 * m0 + ((mid & 0xFFF) << 12)  # below 2**25
            hi = s1 * m1 + (mid >> 12) + (lo >> 24)  # below 2**28: span_fp * m = hi * 2**24 + lo
            lo = lo & 0xFFFFFF
            if round24 and hi != 0:
                d = 0  # bits past the 24 a float32 keeps: the bit length of hi
                x = hi
                while x != 0:
                    x = x >> 1
                    d += 1
                if d <= 24:
                    mm = (hi << (24 - d)) | (lo >> d)
                    r = lo & ((one << d) - 1)
                    half = one << (d - 1)
                    if r > half or (r == half and (mm & 1)):
                        mm += 1
                else:
                    k = d - 24
                    mm = hi >> k
                    r = hi & ((one << k) - 1)
                    half = one << (k - 1)
                    if r > half or (r == half and (lo != 0 or (mm & 1))):
                        mm += 1
                sh = q - d  # the rounded product is mm * 2**d / 2**q
                if sh < 0:
                    fp = mm << (0 - sh)
                elif sh < 31:
                    fp = mm >> sh
            else:
                sh = q - 24
                if sh < 31:
                    fp = hi >> sh
        if v < 0:
            v = (low + fp) >> 16
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
        o[int(p[5 + i])] = (w << 4) | (c & 0xF)
        i += 1
    return moving | (clamped << 8)
