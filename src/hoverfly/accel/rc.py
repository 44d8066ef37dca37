"""Viper twins of core/stages/rc.py's `rc_pass` and `rc_frame` (MicroPython only; chosen at import by
core/stages/rc.py).

The same integer arithmetic, step for step, as the Python `rc_pass`, which stays the reference and
the fallback; tests/portable/test_rc_fixed.py runs both on the same inputs and wants every output
bit, state word and change mask equal. As in accel/imufilter.py:

- Outputs are written as their float32 bits (`ptr32` on the "f" arrays), so no float object is
  made: the smoothed stick (Q20, |y| <= 2**20) and the rate (Q16, |r| < 2**23) are exact in float32,
  as an array store of `y / 2**20` and `r / 2**16` is.
- Products stay below 2**31 (viper ints are 32-bit machine words on the RP2040/RP2350; 64-bit on
  the unix VM): the PT2 step's `k * (x - y)` on the difference's 16-bit halves (k <= 2**15,
  |x - y| <= 2**21); the Q16 products of two values in 0..2**16 on the second one's bytes; the
  stick times a rate (< 2**22) on the rate's 11-bit halves. core/stages/rc.py's docstring of `rc_pass`
  gives the bounds.
- `ptr32` loads are zero-extended on a 64-bit port: values that may be negative are sign-extended
  by `(v << sx) >> sx`, sx 32 there and 0 on a 32-bit port.

Layouts (co, st) are core/stages/rc.py's; the indices are repeated here as literals with the names in
comments.
"""

# ptr32/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython


@micropython.viper
def rc_pass(co_a, st_a, stick_a, rate_a) -> int:
    co = ptr32(co_a)
    st = ptr32(st_a)
    stick = ptr32(stick_a)
    rate = ptr32(rate_a)
    one = 1
    sx = 0
    if (one << 31) > 0:
        sx = 32
    k = co[0]  # CO_K
    changed = 0
    i = 0
    while i < 4:
        x = (st[i] << sx) >> sx  # S_X
        s1 = (st[4 + i] << sx) >> sx  # S_S1
        y = (st[8 + i] << sx) >> sx  # S_Y
        if s1 != x or y != x:
            # the PT2's two stages, each y += (k * d + 2**14) >> 15, at least one LSB towards its input
            d = x - s1
            if d != 0:
                p = (k * (d >> 16) << 1) + ((k * (d & 0xFFFF) + 16384) >> 15)
                if p == 0:
                    p = 1
                    if d < 0:
                        p = -1
                s1 += p
            st[4 + i] = s1
            d = s1 - y
            if d != 0:
                p = (k * (d >> 16) << 1) + ((k * (d & 0xFFFF) + 16384) >> 15)
                if p == 0:
                    p = 1
                    if d < 0:
                        p = -1
                y += p
                st[8 + i] = y
                changed |= one << i
        if i < 3:
            a = y
            if y < 0:
                a = 0 - y
            a = (a + 8) >> 4  # the curve's stick in Q16
            # a2 = a * a >> 16, on a's bytes
            t = a * (a >> 8)
            a2 = (t >> 8) + ((((t & 255) << 8) + a * (a & 255)) >> 16)
            e = co[7 + i]  # CO_E
            curve = a2
            if e != 0:
                t = a2 * (a2 >> 8)
                a4 = (t >> 8) + ((((t & 255) << 8) + a2 * (a2 & 255)) >> 16)
                t = a4 * (a2 >> 8)
                a6 = (t >> 8) + ((((t & 255) << 8) + a4 * (a2 & 255)) >> 16)
                t = a6 * (e >> 8)
                curve = (t >> 8) + ((((t & 255) << 8) + a6 * (e & 255)) >> 16)
                f = 65536 - e
                t = a2 * (f >> 8)
                curve += (t >> 8) + ((((t & 255) << 8) + a2 * (f & 255)) >> 16)
            c = co[1 + i]  # CO_C
            t = a * (c >> 11)
            r = (t >> 5) + ((((t & 31) << 11) + a * (c & 0x7FF)) >> 16)
            c = co[4 + i]  # CO_T
            t = curve * (c >> 11)
            r += (t >> 5) + ((((t & 31) << 11) + curve * (c & 0x7FF)) >> 16)
            # the stick and the rate (sign of the stick) as float32 bits of y / 2**20 and r / 2**16
            j = 0
            while j < 2:
                v = y
                q = 20
                if y < 0:
                    v = 0 - y
                if j == 1:
                    v = r
                    q = 16
                bits = 0
                if v != 0:
                    pw = 0
                    tt = v
                    while tt >= 256:
                        tt = tt >> 8
                        pw += 8
                    while tt > 1:
                        tt = tt >> 1
                        pw += 1
                    bits = ((pw - q + 127) << 23) | ((v << (23 - pw)) & 0x7FFFFF)
                    if y < 0:
                        bits = bits | (one << 31)
                if j == 0:
                    stick[i] = bits
                else:
                    rate[i] = bits
                j += 1
        i += 1
    return changed


@micropython.viper
def rc_frame(fco_a, last_a, channels_a, st_a, src_a) -> int:
    """core/stages/rc.py `rc_frame`: the receiver's 16 channels copied in, the sticks that moved (their µs into last),
    in fixed point their Q20 into st (_stick_q's arithmetic, the division included), and the mode switches in
    range. Layout FC_* of core/stages/rc.py, repeated here as literals. µs values are below 2**16 and Q20 values
    within +-2**20; the one product, a * 2**21 with a < 500, stays below 2**30."""
    fco = ptr32(fco_a)
    last = ptr32(last_a)
    ch16 = ptr16(channels_a)
    st = ptr32(st_a)
    src = ptr16(src_a)
    i = 0
    while i < 16:  # CHANNELS: the receiver's frame into the pilot's (a copy onto itself when the same array)
        ch16[i] = src[i]
        i += 1
    r = 0
    i = 0
    while i < 4:
        us = int(ch16[fco[i]])  # FC_CH + i
        if us != last[i]:  # -1 (none yet) loads as 2**32 - 1 on a 64-bit port: never a µs value either
            last[i] = us
            r |= 1 << i
            if fco[6] and i < 3:  # FC_FIXED
                db = fco[4]  # FC_DB
                if i == 2:
                    db = fco[5]  # FC_YAW_DB
                d = us - 1500
                q = 0
                if d > db or d < -db:
                    if d > 0:
                        d -= db
                    else:
                        d += db
                    den = 500 - db
                    a = d
                    if d < 0:
                        a = -d
                    if a >= den:
                        q = 0x100000  # 1.0 in Q20
                    else:
                        q = (a * 0x200000 + den) // (2 * den)
                    if d < 0:
                        q = -q
                if i == 1:
                    q = -q  # pitch: stick forward is nose down (FRD)
                st[i] = q  # S_X + i
        i += 1
    n = int(len(channels_a))
    bit = 16  # RF_ARM, then HORIZON, ANGLE, AIRMODE, AP
    k = 7  # FC_SW
    while k < 22:  # FC_SIZE
        ch = fco[k]
        if ch > 0 and ch <= n:
            v = int(ch16[ch - 1])
            if v >= fco[k + 1] and v < fco[k + 2]:
                r |= bit
        bit <<= 1
        k += 3
    return r
