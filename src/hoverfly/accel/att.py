"""Viper twin of core/fixedatt.py's `FixedAttitude.step` (MicroPython only; chosen at import by core/fixedatt.py).

The same integer arithmetic, step for step, as the Python `att_pass`, which stays the reference and
the fallback; tests/portable/test_fixedatt.py runs both on the same inputs and wants every output
bit equal. As in accel/rate.py and accel/imufilter.py:

- `step` is the method itself (core/fixedatt.py puts it on the class), so a pass makes no bytecode
  call and no Python frame. The arrays are reached through a table of their buffers' addresses
  (`bind` writes it when the stage is configured; MicroPython's collector never moves an object and
  these arrays never grow): `ptr32(array)` each pass would be a runtime call per array. An address
  is two 32-bit words, low then high (the high word is 0 on a 32-bit port).
- Floats are read and written as their float32 bits: the decode truncates toward zero and clamps as
  `fixedatt._dec`; the encode rounds to nearest, ties to even, as an array store of `v / 2**q` does,
  its exponent from a table of floor(log2) for 0..255 (`LOG2`). No float object is made.
- A gain or a dt times a word, `c * x / 2**s` rounded half up, is done on x's 16-bit halves
  (|c| < 2**15). A product of two wide words, `(a * b + 2**27) >> 28`, is done on 15-bit halves of
  both: a*b = ah*bh*2**30 + (ah*bl + al*bh)*2**15 + al*bl, so with |a| < 2**30, |b| < 2**29 - 2**15
  and a result within 2**30 no partial result passes 2**31 (viper ints are 32-bit machine words on
  the RP2040/RP2350; 64-bit on the unix VM, where an overflow would not show:
  tests/test_fixedatt_bounds.py checks the bounds).
  The wide products are listed in co (CO_PAIRS: st indices a * 64 + b) and done in five loops.
- `ptr32` loads are zero-extended on a 64-bit port: values that may be negative are sign-extended
  by `(v << sx) >> sx`, sx 32 there and 0 on a 32-bit port.
- Divisions are of non-negative words only (the sign is put back after).

Layouts (co, st) are core/fixedatt.py's; the indices are repeated here as literals with the names
in comments. st: 0..2 the gyro sum, 3 the passes summed, 4 their µs; 8..11 the quaternion w x y z,
12..14 the half-angle step, 15 1/|q|, 16..18 the gyro average, 20..22 the bias, 24..26 the
accelerometer, 32..44 the products, then the angles staged for the encode. The address table
(`_tab`): co 0, st 1, gyro 2, accel 3, quaternion 4, angles 5, bias 6, LOG2 7.
"""

# ptr8/ptr32/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython

from hoverfly.accel.addr import LOG2, bind  # noqa: F401  (the stage's configure binds through them)

TAB_SIZE = 16  # eight addresses of two words


@micropython.viper
def step(self, dt_us: int, armed: int) -> int:
    tb = ptr32(self._tab)
    if tb[0] == 0 and tb[1] == 0:  # not configured: no addresses to write through
        return 0
    co = ptr32(tb[0] | ((tb[1] << 16) << 16))
    st = ptr32(tb[2] | ((tb[3] << 16) << 16))
    one = 1
    sx = 0
    if (one << 31) > 0:
        sx = 32
    if dt_us > 25000:  # _DT_MAX
        dt_us = 25000
    elif dt_us < -25000:
        dt_us = -25000
    # ---- the gyro (Q16, +-2**22) into the sum (S_GSUM 0..2)
    src = ptr32(tb[4] | ((tb[5] << 16) << 16))
    j = 0
    while j < 3:
        b = src[j]
        lim = 0x400000
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
        st[j] = ((st[j] << sx) >> sx) + v
        j += 1
    us = ((st[4] << sx) >> sx) + dt_us
    n = st[3] + 1
    if n < co[7]:  # CO_EVERY: not yet
        st[3] = n
        st[4] = us
        return 0
    st[3] = 0
    st[4] = 0
    dt = us
    if dt <= 0:
        dt = n * co[8]  # CO_DT_NOM
    if dt > 25000:
        dt = 25000
    # ---- the average, Q16 sum to Q22, truncated toward 0 (st[16..18])
    j = 0
    while j < 3:
        s = (st[j] << sx) >> sx
        st[j] = 0
        a = s
        if s < 0:
            a = 0 - s
        d = a // n
        v = (d << 6) + (((a - d * n) << 6) // n)
        if s < 0:
            v = 0 - v
        st[16 + j] = v
        j += 1
    # ---- decode: quaternion (Q28, 2**28) -> st[8..11], bias (Q30, 2**29) -> st[20..22],
    # accelerometer (Q16, 2**24) -> st[24..26]
    ac = ptr32(tb[6] | ((tb[7] << 16) << 16))
    qa = ptr32(tb[8] | ((tb[9] << 16) << 16))
    bi = ptr32(tb[12] | ((tb[13] << 16) << 16))
    j = 0
    while j < 10:
        if j < 4:
            b = qa[j]
            q = 28
            lim = 0x10000000
        elif j < 7:
            b = bi[j - 4]
            q = 30
            lim = 0x20000000
        else:
            b = ac[j - 7]
            q = 16
            lim = 0x1000000
        e = (b >> 23) & 0xFF
        v = 0
        if e == 0xFF:
            if (b & 0x7FFFFF) == 0:
                v = lim
        elif e != 0:
            m = (b & 0x7FFFFF) | 0x800000
            sh = e - 150 + q
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
        if j < 4:
            st[8 + j] = v
        elif j < 7:
            st[16 + j] = v
        else:
            st[17 + j] = v
        j += 1
    # |q|^2 (CO_PAIRS 56..59): a quaternion off 1 by more than a quarter starts level (_Q2_LO, _Q2_HI)
    k = 0
    while k < 4:
        p = co[56 + k]
        a = (st[p >> 6] << sx) >> sx
        b = (st[p & 63] << sx) >> sx
        ah = a >> 15
        al = a & 0x7FFF
        bh = b >> 15
        bl = b & 0x7FFF
        st[32 + k] = ((ah * bh) << 2) + ((ah * bl + al * bh + ((al * bl + 0x8000000) >> 15)) >> 13)
        k += 1
    n2 = ((st[32] << sx) >> sx) + ((st[33] << sx) >> sx) + ((st[34] << sx) >> sx) + ((st[35] << sx) >> sx)
    if n2 < 0xC000000 or n2 > 0x14000000:
        st[8] = 0x10000000
        st[9] = 0
        st[10] = 0
        st[11] = 0
    result = 1  # R_UPDATED
    # ---- the accelerometer: its length (the trust) and its direction, scaled to 13-14 bits
    a0 = (st[24] << sx) >> sx
    a1 = (st[25] << sx) >> sx
    a2 = (st[26] << sx) >> sx
    m = a0
    if a0 < 0:
        m = 0 - a0
    t = a1
    if a1 < 0:
        t = 0 - a1
    if t > m:
        m = t
    t = a2
    if a2 < 0:
        t = 0 - a2
    if t > m:
        m = t
    trust = 0
    e0 = 0
    e1 = 0
    e2 = 0
    if m > 0:
        sh = 0
        while (m >> sh) >= 0x4000:
            sh += 1
        ls = 0
        while (m << ls) < 0x2000:
            ls += 1
        if a0 < 0:
            a0 = 0 - (((0 - a0) >> sh) << ls)
        else:
            a0 = (a0 >> sh) << ls
        if a1 < 0:
            a1 = 0 - (((0 - a1) >> sh) << ls)
        else:
            a1 = (a1 >> sh) << ls
        if a2 < 0:
            a2 = 0 - (((0 - a2) >> sh) << ls)
        else:
            a2 = (a2 >> sh) << ls
        # nrm = isqrt(|a|^2), bit by bit
        x = a0 * a0 + a1 * a1 + a2 * a2
        nrm = 0
        bt = one << 30
        while bt > x:
            bt = bt >> 2
        while bt != 0:
            if x >= nrm + bt:
                x -= nrm + bt
                nrm = (nrm >> 1) + bt
            else:
                nrm = nrm >> 1
            bt = bt >> 2
        d = ((nrm << sh) >> ls) - 642690  # |a| - 1 g, Q16 (_G16)
        if d < 0:
            d = 0 - d
        if d < 32134:  # _DEV5
            trust = 32768
        elif d < 64269:  # _DEV10
            trust = ((64269 - d) * 33414) >> 15  # _TRUST_K
            if trust > 32768:
                trust = 32768
        if trust != 0:
            # the measured down, Q15
            if a0 < 0:
                u0 = ((0 - a0) << 15) // nrm
            else:
                u0 = 0 - ((a0 << 15) // nrm)
            if a1 < 0:
                u1 = ((0 - a1) << 15) // nrm
            else:
                u1 = 0 - ((a1 << 15) // nrm)
            if a2 < 0:
                u2 = ((0 - a2) << 15) // nrm
            else:
                u2 = 0 - ((a2 << 15) // nrm)
            # products xz wy wx yz ww xx yy zz (CO_PAIRS 36..43) -> st[32..39]
            k = 0
            while k < 8:
                p = co[36 + k]
                a = (st[p >> 6] << sx) >> sx
                b = (st[p & 63] << sx) >> sx
                ah = a >> 15
                al = a & 0x7FFF
                bh = b >> 15
                bl = b & 0x7FFF
                st[32 + k] = ((ah * bh) << 2) + ((ah * bl + al * bh + ((al * bl + 0x8000000) >> 15)) >> 13)
                k += 1
            # the estimated down, Q14
            vx = (2 * (((st[32] << sx) >> sx) - ((st[33] << sx) >> sx)) + 8192) >> 14
            vy = (2 * (((st[34] << sx) >> sx) + ((st[35] << sx) >> sx)) + 8192) >> 14
            vz = (((st[36] << sx) >> sx) - ((st[37] << sx) >> sx) - ((st[38] << sx) >> sx)
                  + ((st[39] << sx) >> sx) + 8192) >> 14
            # the error, Q29
            e0 = u1 * vz - u2 * vy
            e1 = u2 * vx - u0 * vz
            e2 = u0 * vy - u1 * vx
            if trust != 32768:
                e0 = ((trust * (e0 >> 16)) << 1) + ((trust * (e0 & 0xFFFF) + 16384) >> 15)
                e1 = ((trust * (e1 >> 16)) << 1) + ((trust * (e1 & 0xFFFF) + 16384) >> 15)
                e2 = ((trust * (e2 >> 16)) << 1) + ((trust * (e2 & 0xFFFF) + 16384) >> 15)
            st[28] = e0
            st[29] = e1
            st[30] = e2
            if co[6]:  # CO_KI_ON: the bias integral, Q30 (CO_KI_M 4, CO_KI_S 5)
                c = co[4]
                s = co[5]
                j = 0
                while j < 3:
                    ee = (st[28 + j] << sx) >> sx
                    # x = mul(dt, e, 14)
                    x = ((dt * (ee >> 16)) << 2) + ((dt * (ee & 0xFFFF) + 8192) >> 14)
                    if s <= 16:
                        if s:
                            r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
                        else:
                            r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
                    else:
                        r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
                    v = ((st[20 + j] << sx) >> sx) - r
                    if v > 0x20000000:  # _B_LIM
                        v = 0x20000000
                    elif v < -0x20000000:
                        v = -0x20000000
                    st[20 + j] = v
                    j += 1
                result = 3  # R_UPDATED | R_BIAS
    # ---- the corrected rate (Q22) and the half-angle step (Q28) -> st[12..14]
    if armed:
        c = co[0]
        s = co[1] + 7
    else:
        c = co[2]
        s = co[3] + 7
    j = 0
    while j < 3:
        r = ((st[16 + j] << sx) >> sx) - ((((st[20 + j] << sx) >> sx) + 128) >> 8)
        if trust != 0:
            x = (st[28 + j] << sx) >> sx
            if s <= 16:
                if s:
                    r += ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
                else:
                    r += ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
            else:
                r += (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
        if r > 0x10000000:  # _R_LIM
            r = 0x10000000
        elif r < -0x10000000:
            r = -0x10000000
        v = ((dt * (r >> 16)) << 1) + ((dt * (r & 0xFFFF) + 16384) >> 15)
        st[12 + j] = v + ((25468 * (v >> 16) + ((25468 * (v & 0xFFFF)) >> 16) + 4) >> 3)  # _DT_K
        j += 1
    # ---- the rotation: products (CO_PAIRS 44..55) -> st[32..43]
    k = 0
    while k < 12:
        p = co[44 + k]
        a = (st[p >> 6] << sx) >> sx
        b = (st[p & 63] << sx) >> sx
        ah = a >> 15
        al = a & 0x7FFF
        bh = b >> 15
        bl = b & 0x7FFF
        st[32 + k] = ((ah * bh) << 2) + ((ah * bl + al * bh + ((al * bl + 0x8000000) >> 15)) >> 13)
        k += 1
    w = (st[8] << sx) >> sx
    x = (st[9] << sx) >> sx
    y = (st[10] << sx) >> sx
    z = (st[11] << sx) >> sx
    st[8] = w - ((st[32] << sx) >> sx) - ((st[33] << sx) >> sx) - ((st[34] << sx) >> sx)
    st[9] = x + ((st[35] << sx) >> sx) + ((st[36] << sx) >> sx) - ((st[37] << sx) >> sx)
    st[10] = y + ((st[38] << sx) >> sx) - ((st[39] << sx) >> sx) + ((st[40] << sx) >> sx)
    st[11] = z + ((st[41] << sx) >> sx) + ((st[42] << sx) >> sx) - ((st[43] << sx) >> sx)
    # |n|^2 (CO_PAIRS 56..59): at least 0.75 after the check above (a rotation does not shorten q)
    k = 0
    while k < 4:
        p = co[56 + k]
        a = (st[p >> 6] << sx) >> sx
        b = (st[p & 63] << sx) >> sx
        ah = a >> 15
        al = a & 0x7FFF
        bh = b >> 15
        bl = b & 0x7FFF
        st[32 + k] = ((ah * bh) << 2) + ((ah * bl + al * bh + ((al * bl + 0x8000000) >> 15)) >> 13)
        k += 1
    n2 = ((st[32] << sx) >> sx) + ((st[33] << sx) >> sx) + ((st[34] << sx) >> sx) + ((st[35] << sx) >> sx)
    # 1/|n|: an integer square root's reciprocal, then two Newton steps
    x = n2
    r = 0
    bt = one << 30
    while bt > x:
        bt = bt >> 2
    while bt != 0:
        if x >= r + bt:
            x -= r + bt
            r = (r >> 1) + bt
        else:
            r = r >> 1
        bt = bt >> 2
    inv = ((one << 30) // r) << 12
    k = 0
    while k < 2:
        # r = mulw(mulw(n2, inv), inv)
        a = n2
        b = inv
        ah = a >> 15
        al = a & 0x7FFF
        bh = b >> 15
        bl = b & 0x7FFF
        a = ((ah * bh) << 2) + ((ah * bl + al * bh + ((al * bl + 0x8000000) >> 15)) >> 13)
        ah = a >> 15
        al = a & 0x7FFF
        r = ((ah * bh) << 2) + ((ah * bl + al * bh + ((al * bl + 0x8000000) >> 15)) >> 13)
        # inv += mulw(inv, 1 - r) >> 1
        a = 0x10000000 - r
        ah = a >> 15
        al = a & 0x7FFF
        inv += (((ah * bh) << 2) + ((ah * bl + al * bh + ((al * bl + 0x8000000) >> 15)) >> 13)) >> 1
        k += 1
    st[15] = inv
    # the normalisation (CO_PAIRS 60..63)
    k = 0
    while k < 4:
        p = co[60 + k]
        a = (st[p >> 6] << sx) >> sx
        b = (st[p & 63] << sx) >> sx
        ah = a >> 15
        al = a & 0x7FFF
        bh = b >> 15
        bl = b & 0x7FFF
        st[32 + k] = ((ah * bh) << 2) + ((ah * bl + al * bh + ((al * bl + 0x8000000) >> 15)) >> 13)
        k += 1
    st[8] = st[32]
    st[9] = st[33]
    st[10] = st[34]
    st[11] = st[35]
    # ---- the angles: products xx yy zz wx yz wy zx wz xy (CO_PAIRS 64..72) -> st[32..40]
    k = 0
    while k < 9:
        p = co[64 + k]
        a = (st[p >> 6] << sx) >> sx
        b = (st[p & 63] << sx) >> sx
        ah = a >> 15
        al = a & 0x7FFF
        bh = b >> 15
        bl = b & 0x7FFF
        st[32 + k] = ((ah * bh) << 2) + ((ah * bl + al * bh + ((al * bl + 0x8000000) >> 15)) >> 13)
        k += 1
    xx = (st[32] << sx) >> sx
    yy = (st[33] << sx) >> sx
    zz = (st[34] << sx) >> sx
    ct = 0x10000000 - 2 * (xx + yy)  # cos_tilt
    sp = 2 * (((st[37] << sx) >> sx) - ((st[38] << sx) >> sx))
    if sp > 0x10000000:
        sp = 0x10000000
    elif sp < -0x10000000:
        sp = -0x10000000
    # three CORDIC atan2: roll (its length is cos pitch times the gain), pitch, yaw -> st[44..46]
    cp = 0
    k = 0
    while k < 3:
        if k == 0:
            y = 2 * (((st[35] << sx) >> sx) + ((st[36] << sx) >> sx))
            x = ct
        elif k == 1:
            a = sp  # mulw(sp, _CORDIC_K), the gain in co[9]
            b = co[9]
            ah = a >> 15
            al = a & 0x7FFF
            bh = b >> 15
            bl = b & 0x7FFF
            y = ((ah * bh) << 2) + ((ah * bl + al * bh + ((al * bl + 0x8000000) >> 15)) >> 13)
            x = cp
        else:
            y = 2 * (((st[39] << sx) >> sx) + ((st[40] << sx) >> sx))
            x = 0x10000000 - 2 * (yy + zz)
        z = 0
        if x < 0:
            if y >= 0:
                t = x
                x = y
                y = 0 - t
                z = 421657428  # _HALF_PI
            else:
                t = x
                x = 0 - y
                y = t
                z = -421657428
        i = 0
        while i < 26:  # N_CORDIC, atan(2**-i) at CO_ATAN 10
            if y > 0:
                t = x + (y >> i)
                y = y - (x >> i)
                x = t
                z += co[10 + i]
            else:
                t = x - (y >> i)
                y = y + (x >> i)
                x = t
                z -= co[10 + i]
            i += 1
        if k == 0:
            cp = x
        st[44 + k] = z
        k += 1
    st[47] = ct
    # ---- encode: q[4] = st[8..11], angles[4] = st[44..47] (Q28), bias[3] = st[20..22] (Q30)
    ang = ptr32(tb[10] | ((tb[11] << 16) << 16))
    lg = ptr8(tb[14] | ((tb[15] << 16) << 16))
    total = 8
    if result == 3:
        total = 11
    j = 0
    while j < total:
        q = 28
        if j < 4:
            v = (st[8 + j] << sx) >> sx
        elif j < 8:
            v = (st[40 + j] << sx) >> sx
        else:
            v = (st[12 + j] << sx) >> sx
            q = 30
        bits = 0
        if v != 0:
            a = v
            if v < 0:
                a = 0 - v
            if a >= 0x1000000:
                pw = 24 + lg[a >> 24]
            elif a >= 0x10000:
                pw = 16 + lg[a >> 16]
            elif a >= 0x100:
                pw = 8 + lg[a >> 8]
            else:
                pw = lg[a]
            if pw > 23:
                kk = pw - 23
                mm = a >> kk
                rem = a - (mm << kk)
                half = one << (kk - 1)
                if rem > half:
                    mm += 1
                elif rem == half and (mm & 1):
                    mm += 1
                if mm >= 0x1000000:
                    mm = mm >> 1
                    pw += 1
            else:
                mm = a << (23 - pw)
            bits = ((pw - q + 127) << 23) | (mm & 0x7FFFFF)
            if v < 0:
                bits = bits | (one << 31)
        if j < 4:
            qa[j] = bits
        elif j < 8:
            ang[j - 4] = bits
        else:
            bi[j - 8] = bits
        j += 1
    # the float stage's own bookkeeping, as FixedAttitude.step does it in Python
    if result == 3:
        self._mahony._bias_zero = False
    if self.angle_floats:
        self._attitude.set_from_angles()
    return result
