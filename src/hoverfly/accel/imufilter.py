"""Viper twin of core/fixedimu.py's `FixedImuFilter.update` (MicroPython only; chosen at import by core/fixedimu.py).

The same integer arithmetic, step for step, as the Python `filter_pass`, which stays the reference
and the fallback; tests/portable/test_fixedimu.py runs both on the same inputs and wants every
output bit equal. What differs is only how the machine does it:

- `update` is the method itself (core/fixedimu.py puts it on the class), so the pass makes no
  bytecode call and no Python frame: the only runtime call is the one attribute load of `self._tab`.
- The arrays are reached through that table of their buffers' addresses (`bind` writes it when the
  filter is configured): MicroPython's collector never moves an object, and these arrays never grow,
  so an address stays good while the arrays live (the filter keeps them in `_io`). A `ptr32(array)`
  each pass would cost a runtime call per array, more than the filters' arithmetic. An address is
  two 32-bit words, low then high (the high word is 0 on a 32-bit port), so one layout serves both.
- Floats are read and written as their float32 bits (`ptr32` on the "f" arrays): the decode
  truncates toward zero and clamps as `fixedimu._dec`; the encode needs no rounding, since every
  state word is within 2**24 (a PT1 step never passes its input, and the inputs are clamped
  there), which float32 holds exactly, as an array store of `y / 2**16` does. No float object is
  made. The exponent of the encode comes from a table of floor(log2) for 0..255 (`LOG2`).
- The product `k * (x - y)` is done on the difference's 16-bit halves: with k <= 2**15 and
  |x - y| < 2**25 no partial product passes 2**31 (viper ints are 32-bit machine words on the
  RP2040/RP2350; 64-bit on the unix VM).
- `ptr32` loads are zero-extended on a 64-bit port: values that may be negative are sign-extended
  by `(v << sx) >> sx`, sx 32 there and 0 on a 32-bit port.

Layouts (co, st, io) are core/fixedimu.py's; the indices are repeated here as literals with the
names in comments. The address table (`_tab`): co 0, st 1, gyro raw 2, gyro bias 3, gyro out 4,
accel raw 5, accel out 6, LOG2 7.
"""

# ptr8/ptr32/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython

from hoverfly.accel.addr import LOG2, bind  # noqa: F401  (the stage's configure binds through them)

TAB_SIZE = 16  # eight addresses of two words


@micropython.viper
def update(self):
    t = ptr32(self._tab)
    if t[0] == 0 and t[1] == 0:  # not configured: no addresses to write through
        return
    co = ptr32(t[0] | ((t[1] << 16) << 16))
    st = ptr32(t[2] | ((t[3] << 16) << 16))
    graw = ptr32(t[4] | ((t[5] << 16) << 16))
    bias = ptr32(t[6] | ((t[7] << 16) << 16))
    gout = ptr32(t[8] | ((t[9] << 16) << 16))
    araw = ptr32(t[10] | ((t[11] << 16) << 16))
    aout = ptr32(t[12] | ((t[13] << 16) << 16))
    lg = ptr8(t[14] | ((t[15] << 16) << 16))
    one = 1
    sx = 0
    if (one << 31) > 0:
        sx = 32
    # per axis: decode the gyro, its bias and the accelerometer (Q16; +-2**23, +-2**23, +-2**24);
    # the filters (CO_GYRO_K 0, CO_ACC_K 3; S_GYRO 0, S_ACC1 3, S_ACC2 6): y += (k * (x - y) + 2**14) >> 15;
    # encode the gyro out (st[i]) and the accelerometer out (st[6 + i]) as float32 bits of v / 2**16
    i = 0
    while i < 3:
        x = 0
        j = 0
        while j < 3:
            lim = 0x800000
            if j == 0:
                b = graw[i]
            elif j == 1:
                b = bias[i]
            else:
                b = araw[i]
                lim = 0x1000000
            e = (b >> 23) & 0xFF
            if e < 134:  # |value| < 128, inside the clamps: shifted right, or 0 below 2**-16
                v = 0
                if e > 110:
                    v = ((b & 0x7FFFFF) | 0x800000) >> (134 - e)
            elif e < 142:
                v = ((b & 0x7FFFFF) | 0x800000) << (e - 134)
                if v > lim:
                    v = lim
            elif e == 0xFF and (b & 0x7FFFFF) != 0:  # NaN
                v = 0
            else:  # past the clamp, or infinite
                v = lim
            if (b >> 31) & 1:
                v = 0 - v
            if j == 0:
                x = v
            elif j == 1:
                x = x - v
            j += 1
        # x: the gyro less its bias; v: the accelerometer
        k = co[i]
        y = (st[i] << sx) >> sx
        d = x - y
        y += (k * (d >> 16) << 1) + ((k * (d & 0xFFFF) + 16384) >> 15)
        st[i] = y
        k = co[3 + i]
        s1 = (st[3 + i] << sx) >> sx
        d = v - s1
        s1 += (k * (d >> 16) << 1) + ((k * (d & 0xFFFF) + 16384) >> 15)
        st[3 + i] = s1
        y2 = (st[6 + i] << sx) >> sx
        d = s1 - y2
        y2 += (k * (d >> 16) << 1) + ((k * (d & 0xFFFF) + 16384) >> 15)
        st[6 + i] = y2
        j = 0
        while j < 2:
            if j == 0:
                v = y
            else:
                v = y2
            bits = 0
            if v != 0:
                a = v
                sg = 0
                if v < 0:
                    a = 0 - v
                    sg = one << 31
                if a >= 0x10000:
                    if a >= 0x1000000:  # 2**24 itself (the state's bound): exact
                        pw = 24
                    else:
                        pw = 16 + lg[a >> 16]
                elif a >= 0x100:
                    pw = 8 + lg[a >> 8]
                else:
                    pw = lg[a]
                if pw > 23:
                    mm = a >> (pw - 23)
                else:
                    mm = a << (23 - pw)
                # the mantissa's leading one carries into the exponent field: added, not masked
                bits = (((pw + 110) << 23) + mm) | sg
            if j == 0:
                gout[i] = bits
            else:
                aout[i] = bits
            j += 1
        i += 1
