"""Viper twin of core/fixedrate.py's `FixedRate.update` (MicroPython only; chosen at import by core/fixedrate.py).

The same integer arithmetic, step for step, as the Python `rate_pass`, which stays the reference and
the fallback; tests/portable/test_fixedrate.py runs both on the same inputs and wants every output
and state bit equal. What differs is only how the machine does it:

- `update` is the method itself (core/fixedrate.py puts it on the class): a bytecode method of six
  arguments gets its frame from the heap on every call (more than 11 words, py/objfun.c), and a
  viper function keeps it on the C stack. Its runtime calls are the attribute loads of the pass's
  five scalar inputs and their float32 stores into `fin`, `self._tab` and `self.fin`, and the
  truth of the two flags; the mixer's `saturated` is stored only when it changes.
- The arrays are reached through `self._tab`, a table of their buffers' addresses (`bind` writes it
  when the stage is configured): MicroPython's collector never moves an object, and these arrays
  never grow, so an address stays good while the arrays live (the stage keeps them in `_io`). A
  `ptr32(array)` each pass would cost a runtime call per array. An address is two 32-bit words,
  low then high (the high word is 0 on a 32-bit port), so one layout serves both.
- A product `c * x / 2**s` (rounded half up) is done on x's 16-bit halves, `c * (x >> 16)` and
  `c * (x & 0xFFFF)`, so with |c| < 2**15 and |x| < 2**31 no partial product passes 2**31: viper ints
  are 32-bit machine words on the RP2040/RP2350 (64-bit on the unix VM, where overflow would not
  show; the Python twin's checked run covers the bounds). A zero coefficient gives 0 exactly, so
  its product is skipped.
- Floats are read and written as their float32 bits (`ptr32` on the "f" arrays): the decode truncates
  toward zero and clamps exactly as `fixedrate._dec`; the encode rounds to nearest, ties to even, as
  an array store of `v / 2**q` does, with its exponent from a table of floor(log2) for 0..255
  (`LOG2`). So no float object is made. Only the inputs the mode reads are decoded (the rate
  setpoint's roll and pitch not in angle mode, the attitude not in acro, the sticks only in horizon).
- `ptr32` loads are zero-extended on a 64-bit port: values that may be negative are sign-extended by
  `(v << sx) >> sx`, sx 32 there and 0 on a 32-bit port.
- The product is written out at each use rather than called: a call from viper code to a viper
  function costs ~85 ns on the unix VM, the inline product a few.
- No constant of 2**30 or more appears (not a small int on a 32-bit port): those are shifted up
  at run time from `one`.

Layouts (co, st, fin, flags) are core/fixedrate.py's; the indices are repeated here as literals
with the names in comments (a const from another module is not inlined into viper code). st[40..52]
holds the decoded inputs, st[53..] the outputs before they are encoded. The address table (`_tab`):
co 0, st 1, fin 2, gyro 3, rate 4, stick 5, terms 6, torque 7, motor 8, LOG2 9.
"""

# ptr8/ptr32/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython

from hoverfly.accel.addr import LOG2, bind  # noqa: F401  (the stage's configure binds through them)

TAB_SIZE = 20  # ten addresses of two words


@micropython.viper
def update(self, sp, attitude, dt_us: int, i_active, airmode_active):
    t = ptr32(self._tab)
    if t[0] == 0 and t[1] == 0:  # not configured: no addresses to write through
        return
    # the scalar inputs as float32 (IN_THR 0, IN_ROLL_SP 1, IN_PITCH_SP 2, IN_ROLL 3, IN_PITCH 4)
    fo = self.fin
    fo[0] = sp.throttle_norm
    fo[1] = sp.roll_angle_rad
    fo[2] = sp.pitch_angle_rad
    mode = int(sp.mode) & 3
    if mode != 0:
        fo[3] = attitude.roll_rad
        fo[4] = attitude.pitch_rad
    flags = mode
    if i_active:
        flags |= 4
    if airmode_active:
        flags |= 8
    coa = t[0] | ((t[1] << 16) << 16)
    sta = t[2] | ((t[3] << 16) << 16)
    co = ptr32(coa)
    st = ptr32(sta)
    one = 1
    sx = 0
    if (one << 31) > 0:
        sx = 32
    big = one << 30
    # ---- decode: gyro[3], rate[3] (Q16), throttle (Q16), angles[4] (Q24), sticks[2] (Q15) -> st[40..52],
    # in runs of one array and format; what the mode does not read is skipped (its slot is not read either).
    # A run: its source address, its first slot in st, its length, and the thresholds on the exponent e:
    # value << (e - c) with c = 150 - q; 0 from e <= c - 24; the clamp lim past c + 7
    run = 0
    while run < 6:
        c = 134
        lim = 0x800000
        n = 3
        if run == 0:
            src = t[6] | ((t[7] << 16) << 16)  # gyro
            dst = 40
        elif run == 1:
            src = t[8] | ((t[9] << 16) << 16)  # rate
            dst = 43
            if mode == 1:  # angle mode: the rate setpoint's roll and pitch come from the angle loop
                src += 8
                dst = 45
                n = 1
        else:
            src = t[4] | ((t[5] << 16) << 16)  # fin
            if run == 2:  # throttle
                dst = 46
                n = 1
            else:
                c = 126
                lim = 0x4000000
                n = 2
                if run == 3:  # the angle setpoints
                    src += 4
                    dst = 47
                elif run == 4:  # the attitude: not in acro
                    src += 12
                    dst = 49
                    if mode == 0:
                        n = 0
                else:  # the sticks: horizon only
                    src = t[10] | ((t[11] << 16) << 16)
                    dst = 51
                    c = 135
                    lim = 0x8000
                    if mode < 2:
                        n = 0
        sr = ptr32(src)
        j = 0
        while j < n:
            b = sr[j]
            e = (b >> 23) & 0xFF
            if e < c:
                v = 0
                if e > c - 24:
                    v = ((b & 0x7FFFFF) | 0x800000) >> (c - e)
            elif e <= c + 7:
                v = ((b & 0x7FFFFF) | 0x800000) << (e - c)
            elif e == 0xFF and (b & 0x7FFFFF) != 0:  # NaN
                v = 0
            else:  # past the clamp, or infinite
                v = lim
            if v > lim:  # a stick of 1 or more is within the shifts
                v = lim
            if (b >> 31) & 1:
                v = 0 - v
            st[dst + j] = v
            j += 1
        run += 1
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
    thr = (st[46] << sx) >> sx
    if thr < 0:
        thr = 0
    elif thr > 65536:
        thr = 65536
    sp0 = 0
    sp1 = 0
    if mode != 1:
        sp0 = (st[43] << sx) >> sx
        sp1 = (st[44] << sx) >> sx
    sp2 = (st[45] << sx) >> sx
    roll_sp = (st[47] << sx) >> sx
    pitch_sp = (st[48] << sx) >> sx
    # ---- the angle loop (ANG_GAIN 0/1, ANG_FF 2/3, ANG_LIM 4, HORIZON 5; S_LAST_ROLL 24, S_LAST_PITCH 25)
    lr = 0
    lp = 0
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
            lv = 0
            if c != 0:
                if s <= 16:
                    lv = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((one << s) >> 1)) >> s)
                else:
                    lv = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
            x = v
            c = fm
            s = fs
            if c != 0:
                if s <= 16:
                    lv += ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((one << s) >> 1)) >> s)
                else:
                    lv += (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
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
        r = 0
        if c != 0:
            if s <= 16:
                r = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((one << s) >> 1)) >> s)
            else:
                r = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
        tpa = 32768 - r
    tpa_changed = 0
    if tpa != st[28]:
        tpa_changed = 1
    st[28] = tpa
    i_on = flags & 4
    sat = st[29]
    tpa_p = co[10]
    # ---- the three rate PIDs: ca the axis's coefficients (AXIS 16 + 20k), sa its state (8k)
    k = 0
    while k < 3:
        ca = ptr32(coa + 4 * (16 + 20 * k))
        sa = ptr32(sta + 32 * k)
        if k == 0:
            spk = sp0
        elif k == 1:
            spk = sp1
        else:
            spk = sp2
        g = (st[40 + k] << sx) >> sx
        tk = tpa
        if k == 2:
            tk = 32768
        err = spk - g
        # p = mul(KP, err)
        x = err
        c = (ca[0] << sx) >> sx
        s = ca[1]
        p = 0
        if c != 0:
            if s <= 16:
                p = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((one << s) >> 1)) >> s)
            else:
                p = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
        if tpa_p and tk != 32768:
            p = ((tk * (p >> 16)) << 1) + ((tk * (p & 0xFFFF) + 16384) >> 15)
        i = 0
        if i_on:
            i = (sa[0] << sx) >> sx
            # step = mul(KI, mul(dt_us, err, 8))
            x = ((dt_us * (err >> 16)) << 8) + ((dt_us * (err & 0xFFFF) + 128) >> 8)
            c = (ca[2] << sx) >> sx
            s = ca[3]
            step = 0
            if c != 0:
                if s <= 16:
                    step = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((one << s) >> 1)) >> s)
                else:
                    step = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
            if ca[12]:  # I-term relax
                y = (sa[4] << sx) >> sx
                x = spk - y
                c = ca[13]
                s = ca[14]
                if c != 0:
                    if s <= 16:
                        y += ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((one << s) >> 1)) >> s)
                    else:
                        y += (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
                sa[4] = y
                x = spk - y
                if x < 0:
                    x = 0 - x
                c = ca[15]
                s = ca[16]
                factor = 32768
                if c != 0:
                    if s <= 16:
                        factor -= ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((one << s) >> 1)) >> s)
                    else:
                        factor -= (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
                if factor <= 0:
                    step = 0
                elif factor != 32768:
                    step = ((factor * (step >> 16)) << 1) + ((factor * (step & 0xFFFF) + 16384) >> 15)
            # anti-windup: not toward the side the mixer could not deliver
            up = 0
            if step > 0:
                up = 1
            was_up = 0
            if ((sa[1] << sx) >> sx) > 0:
                was_up = 1
            if sat == 0 or up != was_up:
                i += step
            lim = ca[10]
            if i > lim:
                i = lim
            elif i < 0 - lim:
                i = 0 - lim
        sa[0] = i
        # D on measurement: x = mul(inv_dt, g - last, 9), Q7, clamped to 2**26
        x = g - ((sa[2] << sx) >> sx)
        x = ((inv_dt * (x >> 16)) << 7) + ((inv_dt * (x & 0xFFFF) + 256) >> 9)
        if x > 0x4000000:
            x = 0x4000000
        elif x < -0x4000000:
            x = -0x4000000
        sa[2] = g
        c = ca[17]
        s = ca[18]
        y = (sa[5] << sx) >> sx
        x = x - y
        if c != 0:
            if s <= 16:
                y += ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((one << s) >> 1)) >> s)
            else:
                y += (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
        sa[5] = y
        if ca[19]:  # PT2: the second stage
            y2 = (sa[6] << sx) >> sx
            x = y - y2
            if c != 0:
                if s <= 16:
                    y2 += ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((one << s) >> 1)) >> s)
                else:
                    y2 += (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
            sa[6] = y2
            y = y2
        x = y
        c = (ca[4] << sx) >> sx
        s = ca[5]
        d = 0
        if c != 0:
            if s <= 16:
                d = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((one << s) >> 1)) >> s)
            else:
                d = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
            if tk != 32768:
                d = ((tk * (d >> 16)) << 1) + ((tk * (d & 0xFFFF) + 16384) >> 15)
        # feed-forward: mul(KF, mul(inv_dt, spk - last, 9)) + mul(KST, spk)
        f = 0
        c = (ca[6] << sx) >> sx
        if c != 0:
            x = spk - ((sa[3] << sx) >> sx)
            x = ((inv_dt * (x >> 16)) << 7) + ((inv_dt * (x & 0xFFFF) + 256) >> 9)
            if x > 0x4000000:
                x = 0x4000000
            elif x < -0x4000000:
                x = -0x4000000
            s = ca[7]
            if s <= 16:
                f = ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((one << s) >> 1)) >> s)
            else:
                f = (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
        c = (ca[8] << sx) >> sx
        if c != 0:
            x = spk
            s = ca[9]
            if s <= 16:
                f += ((c * (x >> 16)) << (16 - s)) + ((c * (x & 0xFFFF) + ((one << s) >> 1)) >> s)
            else:
                f += (c * (x >> 16) + ((c * (x & 0xFFFF)) >> 16) + (one << (s - 17))) >> (s - 16)
        sa[3] = spk
        out = p + (i >> 10) + d + f
        lim = ca[11]
        if out > lim:
            out = lim
        elif out < 0 - lim:
            out = 0 - lim
        sa[1] = out
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
    r0h = r0 >> 16
    r0l = r0 & 0xFFFF
    r1h = r1 >> 16
    r1l = r1 & 0xFFFF
    r2h = r2 >> 16
    r2l = r2 & 0xFFFF
    n = co[11]
    lo = big
    hi = 0 - big
    m = 0
    while m < n:
        cw = ptr32(coa + 4 * (76 + 3 * m))
        c = (cw[0] << sx) >> sx
        v = ((c * r0h) << 2) + ((c * r0l + 8192) >> 14)
        c = (cw[1] << sx) >> sx
        v += ((c * r1h) << 2) + ((c * r1l + 8192) >> 14)
        c = (cw[2] << sx) >> sx
        v += ((c * r2h) << 2) + ((c * r2l + 8192) >> 14)
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
    sat_was = st[29]
    st[29] = sat
    # ---- encode: terms[12], torque[3], motor[n], then the angle loop's rate[2] -> float32 bits, in runs of
    # one array and format: the staged words st[src..], the exponent's bias 127 - q (q 26 for the I-terms)
    if mode != 0:
        st[68 + n] = sp0
        st[69 + n] = sp1
    lg = ptr8(t[18] | ((t[19] << 16) << 16))
    run = 0
    every = int(co[13])  # TERMS_EVERY: the terms and torques (runs 0..3) only every this many passes
    if every > 1:
        c = int(st[38]) - 1  # S_TERMS_N
        if c <= 0:
            c = every
        else:
            run = 4
        st[38] = c
    while run < 6:
        eb = 111
        cnt = 3
        if run < 3:
            dst = t[12] | ((t[13] << 16) << 16)  # terms
            src = 53
            if run == 1:
                dst += 12
                src = 56
                eb = 101
            elif run == 2:
                dst += 24
                src = 59
                cnt = 6
        elif run == 3:
            dst = t[14] | ((t[15] << 16) << 16)  # torque
            src = 65
        elif run == 4:
            dst = t[16] | ((t[17] << 16) << 16)  # motor
            src = 68
            cnt = n
        else:
            dst = t[8] | ((t[9] << 16) << 16)  # rate: the angle loop's roll and pitch
            src = 68 + n
            cnt = 2
            if mode == 0:
                cnt = 0
        o = ptr32(dst)
        eb -= 1  # the mantissa's leading one carries into the exponent field: added, not masked
        j = 0
        while j < cnt:
            v = (st[src + j] << sx) >> sx
            bits = 0
            if v != 0:
                a = v
                sg = 0
                if v < 0:
                    a = 0 - v
                    sg = one << 31
                if a >= 0x10000:
                    if a >= 0x1000000:
                        pw = 24 + lg[a >> 24]
                    else:
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
                bits = (((pw + eb) << 23) + mm) | sg
            o[j] = bits
            j += 1
        run += 1
    if sat != sat_was:
        if sat:
            self._mixer.saturated = True
        else:
            self._mixer.saturated = False
    if tpa_changed:
        self._tpa_changed()
