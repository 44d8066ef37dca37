"""Viper twin of core/fixedimu.py's `filter_pass` (MicroPython only; chosen at import by core/fixedimu.py).

The same integer arithmetic, step for step, as the Python `filter_pass`, which stays the reference
and the fallback; tests/portable/test_fixedimu.py runs both on the same inputs and wants every
output bit equal. As in accel/rate.py:

- Floats are read and written as their float32 bits (`ptr32` on the "f" arrays): the decode
  truncates toward zero and clamps as `fixedimu._dec`; the encode needs no rounding, since every
  state word is within 2**24 (a PT1 step never passes its input, and the inputs are clamped
  there), which float32 holds exactly, as an array store of `y / 2**16` does. No float object is
  made.
- The product `k * (x - y)` is done on the difference's 16-bit halves: with k <= 2**15 and
  |x - y| < 2**25 no partial product passes 2**31 (viper ints are 32-bit machine words on the
  RP2040/RP2350; 64-bit on the unix VM).
- `ptr32` loads are zero-extended on a 64-bit port: values that may be negative are sign-extended
  by `(v << sx) >> sx`, sx 32 there and 0 on a 32-bit port.

Layouts (co, st, io) are core/fixedimu.py's; the indices are repeated here as literals with the
names in comments. st[9..17] holds the decoded inputs: gyro raw, gyro bias, accel raw.
"""

# ptr32/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython


@micropython.viper
def filter_pass(co_a, st_a, io):
    co = ptr32(co_a)
    st = ptr32(st_a)
    graw = ptr32(io[0])
    bias = ptr32(io[1])
    gout = ptr32(io[2])
    araw = ptr32(io[3])
    aout = ptr32(io[4])
    one = 1
    sx = 0
    if (one << 31) > 0:
        sx = 32
    # ---- decode: gyro raw[3], bias[3] (Q16, +-2**23), accel raw[3] (Q16, +-2**24) -> st[9..17]
    j = 0
    while j < 9:
        lim = 0x800000
        if j < 3:
            b = graw[j]
        elif j < 6:
            b = bias[j - 3]
        else:
            b = araw[j - 6]
            lim = 0x1000000
        e = (b >> 23) & 0xFF
        v = 0
        if e == 0xFF:
            if (b & 0x7FFFFF) == 0:
                v = lim
        elif e != 0:
            m = (b & 0x7FFFFF) | 0x800000
            sh = e - 150 + 16
            if sh >= 0:
                if sh > 7:
                    v = lim
                else:
                    v = m << sh
            elif sh > -24:
                v = m >> (0 - sh)
            if v > lim:
                v = lim
        if (b >> 31) & 1:
            v = 0 - v
        st[9 + j] = v
        j += 1
    # ---- the filters (CO_GYRO_K 0, CO_ACC_K 3; S_GYRO 0, S_ACC1 3, S_ACC2 6): y += (k * (x - y) + 2**14) >> 15
    i = 0
    while i < 3:
        k = co[i]
        x = ((st[9 + i] << sx) >> sx) - ((st[12 + i] << sx) >> sx)
        y = (st[i] << sx) >> sx
        d = x - y
        y += (k * (d >> 16) << 1) + ((k * (d & 0xFFFF) + 16384) >> 15)
        st[i] = y
        k = co[3 + i]
        s1 = (st[3 + i] << sx) >> sx
        d = ((st[15 + i] << sx) >> sx) - s1
        s1 += (k * (d >> 16) << 1) + ((k * (d & 0xFFFF) + 16384) >> 15)
        st[3 + i] = s1
        y = (st[6 + i] << sx) >> sx
        d = s1 - y
        y += (k * (d >> 16) << 1) + ((k * (d & 0xFFFF) + 16384) >> 15)
        st[6 + i] = y
        i += 1
    # ---- encode: gyro out[3] = st[0..2], accel out[3] = st[6..8] -> float32 bits of v / 2**16
    j = 0
    while j < 6:
        if j < 3:
            v = (st[j] << sx) >> sx
        else:
            v = (st[3 + j] << sx) >> sx
        bits = 0
        if v != 0:
            sgn = 0
            a = v
            if v < 0:
                a = 0 - v
                sgn = one << 31
            pw = 0
            tt = a
            while tt >= 256:
                tt = tt >> 8
                pw += 8
            while tt > 1:
                tt = tt >> 1
                pw += 1
            if pw > 23:  # |v| <= 2**24 (the state's bound): only 2**24 itself, exact
                mm = a >> (pw - 23)
            else:
                mm = a << (23 - pw)
            bits = sgn | ((pw - 16 + 127) << 23) | (mm & 0x7FFFFF)
        if j < 3:
            gout[j] = bits
        else:
            aout[j - 3] = bits
        j += 1
