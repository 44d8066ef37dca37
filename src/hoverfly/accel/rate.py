"""Viper twin of core/fixedrate.py's `rate_pass` (MicroPython only; chosen at import by core/fixedrate.py).

The same integer arithmetic, step for step, as the Python `rate_pass`, which stays the reference and
the fallback; tests/portable/test_fixedrate.py runs both on the same inputs and wants every output
bit equal. What differs is only how the machine does it:

- A product `c * x / 2**s` (rounded half up) is done on x's 16-bit halves, `c * (x >> 16)` and
  `c * (x & 0xFFFF)`, so with |c| < 2**15 and |x| < 2**31 no partial product passes 2**31: viper ints
  are 32-bit machine words on the RP2040/RP2350 (64-bit on the unix VM, where overflow would not
  show; the Python twin's checked run covers the bounds).
- Floats are read and written as their float32 bits (`ptr32` on the "f" arrays): the decode truncates
  toward zero and clamps exactly as `fixedrate._dec`; the encode rounds to nearest, ties to even, as
  an array store of `v / 2**q` does. So no float object is made at all.
- `ptr32` loads are zero-extended on a 64-bit port: values that may be negative are sign-extended by
  `(v << sx) >> sx`, sx 32 there and 0 on a 32-bit port.
- The product is written out at each use rather than called: a call from viper code to a viper
  function costs ~85 ns on the unix VM, the inline product a few.
- No constant of 2**30 or more appears (not a small int on a 32-bit port): those are shifted up
  at run time from `one`.

Layouts (co, st, io, flags) are core/fixedrate.py's; the indices are repeated here as literals
with the names in comments (a const from another module is not inlined into viper code). st[40..52]
holds the decoded inputs, st[53..] the outputs before they are encoded.
"""

# ptr32/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython


@micropython.viper
def rate_pass(co_a, st_a, io, flags: int, dt_us: int) -> int:
    co = ptr32(co_a)
    st = ptr32(st_a)
    fin = ptr32(io[0])
    gy = ptr32(io[1])
    rt = ptr32(io[2])
    sk = ptr32(io[3])
    one = 1
    sx = 0
    if (one << 31) > 0:
        sx = 32
    big = one << 30
    # ---- decode: gyro[3], rate[3] (Q16), throttle (Q16), angles[4] (Q24), sticks[2] (Q15) -> st[40..52]
    j = 0
    while j < 13:
        q = 16
        lim = 0x800000
        if j < 3:
            b = gy[j]
        elif j < 6:
            b = rt[j - 3]
        elif j < 11:
            b = fin[j - 6]
            if j > 6:
                q = 24
                lim = 0x4000000
        else:
            b = sk[j - 11]
            q = 15
            lim = 0x8000
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
        st[40 + j] = v
        j += 1
    # ---- dt, clamped; 1/dt when it changes (S_DT 26, S_INV_DT 27; DT_NOMINAL 12)
    if dt_us <= 0:
        dt_us = co[12]
    if dt_us < 64:
        dt_us = 64
    elif dt_us > 20000:
        dt_us = 20000
    if dt_us != st[26]:
        st[26] = dt_us
        st[27] = 1000000 // dt_us
    inv_dt = st[27]
    mode = flags & 3
    thr = (st[46] << sx) >> sx
    if thr < 0:
        thr = 0
    elif thr > 65536:
        thr = 65536
    sp0 = (st[43] << sx) >> sx
    sp1 = (st[44] << sx) >> sx
    sp2 = (st[45] << sx) >> sx
    roll_sp = (st[47] << sx) >> sx
    pitch_sp = (st[48] << sx) >> sx
    # ---- the angle loop (ANG_GAIN 0/1, ANG_FF 2/3, ANG_LIM 4, HORIZON 5; S_LAST_ROLL 24, S_LAST_PITCH 25)
    if mode != 0:
        lim = co[4]
        gm = (co[0] << sx) >> sx
        gs = co[1] + 8
        fm = (co[2] << sx) >> sx
        fs = co[3]
        a = 0
        while a < 2:
            if a == 0:
                asp = roll_sp
                x = roll_sp - ((st[24] << sx) >> sx)
                att = (st[49] << sx) >> sx
            else:
                asp = pitch_sp
                x = pitch_sp - ((st[25] << sx) >> sx)
                att = (st[50] << sx) >> sx
            if x > 0x2000000:  # _DSP_LIM
                x = 0x2000000
            elif x < -0x2000000:
                x = -0x2000000
            # v = mul(inv_dt, x, 8): the angle setpoint's speed, Q16
            v = ((inv_dt * (x >> 16)) << 8) + ((inv_dt * (x & 0xFFFF) + 128) >> 8)
            if v > 0x800000:
                v = 0x800000
            elif v < -0x800000:
                v = -0x800000
            # level = mul(gain, asp - att, gs) + mul(ff, v, fs)
            x = asp - att
            c = gm
            s = gs
            if s <= 16:
                if s:
                    r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
                else:
                    r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
            else:
                r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
            lv = r
            x = v
            c = fm
            s = fs
            if s <= 16:
                if s:
                    r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
                else:
                    r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
            else:
                r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
            lv += r
            if lv > lim:
                lv = lim
            elif lv < 0 - lim:
                lv = 0 - lim
            if a == 0:
                lr = lv
            else:
                lp = lv
            a += 1
        if mode == 1:
            sp0 = lr
            sp1 = lp
        else:  # horizon
            d0 = (st[51] << sx) >> sx
            if d0 < 0:
                d0 = 0 - d0
            d1 = (st[52] << sx) >> sx
            if d1 < 0:
                d1 = 0 - d1
            if d1 > d0:
                d0 = d1
            w = (co[5] * (32768 - d0)) >> 15
            if w >= 32768:
                sp0 = lr
                sp1 = lp
            elif w > 0:
                x = lr - sp0
                sp0 += ((w * (x >> 16)) << 1) + ((w * (x & 0xFFFF) + 16384) >> 15)
                x = lp - sp1
                sp1 += ((w * (x >> 16)) << 1) + ((w * (x & 0xFFFF) + 16384) >> 15)
    st[24] = roll_sp
    st[25] = pitch_sp
    # ---- TPA (TPA_ON 6, TPA_BP 7, TPA_M 8, TPA_S 9; S_TPA 28)
    tpa = 32768
    bp = (co[7] << sx) >> sx
    if co[6] and thr > bp:
        x = thr - bp
        c = co[8]
        s = co[9]
        if s <= 16:
            if s:
                r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
            else:
                r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
        else:
            r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
        tpa = 32768 - r
    changed = 0
    if tpa != st[28]:
        changed = 2
    st[28] = tpa
    i_active = flags & 4
    sat = st[29]
    tpa_p = co[10]
    # ---- the three rate PIDs (axis coefficients at 16 + 20k, state at 8k)
    k = 0
    while k < 3:
        b = 16 + k * 20
        sb = k * 8
        if k == 0:
            sp = sp0
        elif k == 1:
            sp = sp1
        else:
            sp = sp2
        g = (st[40 + k] << sx) >> sx
        t = tpa
        if k == 2:
            t = 32768
        err = sp - g
        # p = mul(KP, err)
        x = err
        c = (co[b] << sx) >> sx
        s = co[b + 1]
        if s <= 16:
            if s:
                r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
            else:
                r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
        else:
            r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
        p = r
        if tpa_p and t != 32768:
            p = ((t * (p >> 16)) << 1) + ((t * (p & 0xFFFF) + 16384) >> 15)
        if i_active:
            i = (st[sb] << sx) >> sx
            # step = mul(KI, mul(dt_us, err, 8))
            x = ((dt_us * (err >> 16)) << 8) + ((dt_us * (err & 0xFFFF) + 128) >> 8)
            c = (co[b + 2] << sx) >> sx
            s = co[b + 3]
            if s <= 16:
                if s:
                    r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
                else:
                    r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
            else:
                r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
            step = r
            if co[b + 12]:  # I-term relax
                y = (st[sb + 4] << sx) >> sx
                x = sp - y
                c = co[b + 13]
                s = co[b + 14]
                if s <= 16:
                    if s:
                        r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
                    else:
                        r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
                else:
                    r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
                y += r
                st[sb + 4] = y
                x = sp - y
                if x < 0:
                    x = 0 - x
                c = co[b + 15]
                s = co[b + 16]
                if s <= 16:
                    if s:
                        r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
                    else:
                        r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
                else:
                    r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
                factor = 32768 - r
                if factor <= 0:
                    step = 0
                elif factor != 32768:
                    step = ((factor * (step >> 16)) << 1) + ((factor * (step & 0xFFFF) + 16384) >> 15)
            # anti-windup: not toward the side the mixer could not deliver
            up = 0
            if step > 0:
                up = 1
            was_up = 0
            if ((st[sb + 1] << sx) >> sx) > 0:
                was_up = 1
            if sat == 0 or up != was_up:
                i += step
            lim = co[b + 10]
            if i > lim:
                i = lim
            elif i < 0 - lim:
                i = 0 - lim
        else:
            i = 0
        st[sb] = i
        # D on measurement: x = mul(inv_dt, g - last, 9), Q7, clamped to 2**26
        x = g - ((st[sb + 2] << sx) >> sx)
        x = ((inv_dt * (x >> 16)) << 7) + ((inv_dt * (x & 0xFFFF) + 256) >> 9)
        if x > 0x4000000:
            x = 0x4000000
        elif x < -0x4000000:
            x = -0x4000000
        st[sb + 2] = g
        dm = co[b + 17]
        ds = co[b + 18]
        y = (st[sb + 5] << sx) >> sx
        x = x - y
        c = dm
        s = ds
        if s <= 16:
            if s:
                r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
            else:
                r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
        else:
            r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
        y += r
        st[sb + 5] = y
        if co[b + 19]:  # PT2: the second stage
            y2 = (st[sb + 6] << sx) >> sx
            x = y - y2
            if s <= 16:
                if s:
                    r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
                else:
                    r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
            else:
                r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
            y2 += r
            st[sb + 6] = y2
            y = y2
        x = y
        c = (co[b + 4] << sx) >> sx
        s = co[b + 5]
        if s <= 16:
            if s:
                r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
            else:
                r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
        else:
            r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
        d = r
        if t != 32768:
            d = ((t * (d >> 16)) << 1) + ((t * (d & 0xFFFF) + 16384) >> 15)
        # feed-forward: mul(KF, mul(inv_dt, sp - last, 9)) + mul(KST, sp)
        x = sp - ((st[sb + 3] << sx) >> sx)
        x = ((inv_dt * (x >> 16)) << 7) + ((inv_dt * (x & 0xFFFF) + 256) >> 9)
        if x > 0x4000000:
            x = 0x4000000
        elif x < -0x4000000:
            x = -0x4000000
        c = (co[b + 6] << sx) >> sx
        s = co[b + 7]
        if s <= 16:
            if s:
                r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
            else:
                r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
        else:
            r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
        f = r
        x = sp
        c = (co[b + 8] << sx) >> sx
        s = co[b + 9]
        if s <= 16:
            if s:
                r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + (one << (s - 1))) >> s)
            else:
                r = ((c * (x >> 16)) << 16) + c * (x & 0xFFFF)
        else:
            r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
        f += r
        st[sb + 3] = sp
        out = p + (i >> 10) + d + f
        lim = co[b + 11]
        if out > lim:
            out = lim
        elif out < 0 - lim:
            out = 0 - lim
        st[sb + 1] = out
        # staged outputs: terms p, i, d, f at 53 + k, +3, +6, +9; torque at 65 + k
        st[53 + k] = p
        st[56 + k] = i
        st[59 + k] = d
        st[62 + k] = f
        st[65 + k] = out
        k += 1
    # ---- the mixer (MOTORS 11, weights Q14 at 76 + 3m; S_MIX 30, S_SAT 29)
    r0 = (st[1] << sx) >> sx
    r1 = (st[9] << sx) >> sx
    r2 = (st[17] << sx) >> sx
    n = co[11]
    lo = big
    hi = 0 - big
    m = 0
    while m < n:
        w = 76 + 3 * m
        c = (co[w] << sx) >> sx
        v = ((c * (r0 >> 16)) << 2) + ((c * (r0 & 0xFFFF) + 8192) >> 14)
        c = (co[w + 1] << sx) >> sx
        v += ((c * (r1 >> 16)) << 2) + ((c * (r1 & 0xFFFF) + 8192) >> 14)
        c = (co[w + 2] << sx) >> sx
        v += ((c * (r2 >> 16)) << 2) + ((c * (r2 & 0xFFFF) + 8192) >> 14)
        st[30 + m] = v
        if v < lo:
            lo = v
        if v > hi:
            hi = v
        m += 1
    span = hi - lo
    sat = 0
    airmode = flags & 8
    throttle = thr
    if span > 65536:
        scale = big // span
        m = 0
        while m < n:
            x = (st[30 + m] << sx) >> sx
            st[30 + m] = ((scale * (x >> 16)) << 2) + ((scale * (x & 0xFFFF) + 8192) >> 14)
            m += 1
        x = lo
        lo = ((scale * (x >> 16)) << 2) + ((scale * (x & 0xFFFF) + 8192) >> 14)
        x = hi
        hi = ((scale * (x >> 16)) << 2) + ((scale * (x & 0xFFFF) + 8192) >> 14)
        if airmode:
            throttle = 32768
        sat = 1
    if airmode or span > 65536:
        if throttle + hi > 65536:
            throttle = 65536 - hi
        if throttle + lo < 0:
            throttle = 0 - lo
    m = 0
    while m < n:
        v = throttle + ((st[30 + m] << sx) >> sx)
        if v < 0:
            v = 0
            sat = 1
        elif v > 65536:
            v = 65536
            sat = 1
        st[68 + m] = v
        m += 1
    st[29] = sat
    # ---- encode: terms[12], torque[3], motor[n], then the angle loop's rate[2] -> float32 bits
    terms = ptr32(io[4])
    tq = ptr32(io[5])
    mo = ptr32(io[6])
    nout = 15 + n
    total = nout
    if mode != 0:
        st[68 + n] = sp0
        st[69 + n] = sp1
        total = nout + 2
    j = 0
    while j < total:
        v = (st[53 + j] << sx) >> sx
        q = 16
        if j >= 3 and j < 6:
            q = 26
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
            bits = sgn | ((pw - q + 127) << 23) | (mm & 0x7FFFFF)
        if j < 12:
            terms[j] = bits
        elif j < 15:
            tq[j - 12] = bits
        elif j < nout:
            mo[j - 15] = bits
        else:
            rt[j - nout] = bits
        j += 1
    return sat | changed
