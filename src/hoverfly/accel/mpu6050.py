"""Viper twin of MPU6050.read (MicroPython only; chosen at import by drivers/mpu6050.py).

`read(self, gyro_rad_s, accel_m_s2)` is MPU6050.read itself on MicroPython: the driver puts it on
the class, and `read_python` (the bytecode method, with drivers/mpu6050.py `read_burst`, its
pure-Python twin, inline here) stays the reference and the fallback wherever viper is missing
(CPython, the wasm port). Bit for bit the same: the 14-byte burst from ACCEL_XOUT_H (big-endian
int16: accel X/Y/Z, TEMP, gyro X/Y/Z; RM-MPU-6000A-00 §4.17-4.19), an OSError counted in
bus_errors, the frozen/saturated watch in the driver's state array (`_st`, the layout
drivers/mpu6050.py declares as ST_*), the rare flags through MPU6050._finish, temp_raw, samples,
and for an axis-map plan the body-frame (FRD) gyro in rad/s and accel in m/s² written into the
caller's array('f')s as float32 bit patterns, so a read makes no float objects.

A viper method makes no bytecode frame (read_python's 12 words would be taken from the heap at
every call: py/objfun.c VM_MAX_STATE_ON_STACK is 11) and reaches the driver's burst buffer and
state through a table of their addresses (`bind`, written once by the driver's constructor:
MicroPython's collector never moves an object, and the two are never replaced or resized), so
the only runtime calls are the transfer, the attribute traffic and the two output arrays' casts.

The scaling: each value is an integer n (sign * count, or sign * (gyro * 16 - bias)) times the
scale k held as float32 (mantissa m with its hidden bit, biased exponent e). The float32 nearest
to n * k (ties to even) is what the Python twin's `n * k` stores into an array('f') on every port:
a float32 port rounds the product once, and on a float64 port |n| < 2**21 and a 24-bit mantissa
make the product exact before the array's one rounding. Here the product n * m (< 2**45) is
built from 12-bit pieces as hi * 2**24 + lo, then rounded to 24 bits by hand. The float32 bit
pattern goes straight into the array: sign << 31, exponent e + the bits dropped, mantissa.

It sits at the start of the pass (board.read_imu -> MPU6050.read). Viper reads and writes raw
memory: the driver's own 14-byte buffer and array('i') of ST_SIZE, and the caller's gyro and accel
array('f')s of at least 3 (little-endian IEEE float32, as on every target). Viper ints are 32-bit
on the RP2040/RP2350: the plan keeps |bias| < 2**20 and the scales within 2**-100..2**100
(MPU6050._plan leaves anything else to Python), so |n| < 2**21, the exponent field stays within
1..254, and every intermediate is below 2**28 (the accel's two products n * (m's 12-bit halves),
n <= 2**15) but the sign bit, which is meant to fill the machine word. The plan and state words
viper reads are never negative: a ptr32 load comes back zero-extended on a 64-bit port.
tests/portable/test_mpu6050_twins.py checks the twins agree.
"""

# ptr8/ptr32 are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython
from micropython import const

from hoverfly.accel.addr import bind  # noqa: F401  (the stage's configure binds through it)

# The state layout (the same numbers as drivers/mpu6050.py's ST_*; the twin test checks them).
ST_OFF = const(0)  # 0..2: body axis k's chip axis as a byte offset in the burst (0/2/4)
ST_FLIP = const(3)  # 3..5: 1 if body axis k is that chip axis negated
ST_BIAS = const(6)  # 6..8: that chip axis's gyro bias in 1/16 LSB, plus BIAS_OFFSET
ST_GYRO_M = const(9)  # gyro scale (rad/s per 1/16 LSB) as float32: mantissa with its hidden bit
ST_GYRO_E = const(10)  # ... and biased exponent
ST_ACCEL_M = const(11)  # accel scale (m/s² per LSB) as float32: mantissa
ST_ACCEL_E = const(12)  # ... and biased exponent
ST_SCALED = const(13)  # 1: write the floats; 0: leave chip-frame counts in ST_RAW for Python
ST_LAST = const(14)  # 14..19: the last sample's six raw words, chip order (accel x y z, gyro x y z)
ST_SAME = const(20)  # consecutive samples equal to the one before, at most SAME_CAP
ST_PREV = const(21)  # the last call's flags: non-zero if it left frozen/saturated flags to clear
ST_TEMP = const(22)  # TEMP_OUT, signed (written here, read by Python only)
ST_RAW = const(23)  # 23..28: signed chip-frame counts, accel x y z, gyro x y z (ST_SCALED 0 only)
BIAS_OFFSET = const(1048576)  # 2**20
SAME_CAP = const(16777216)  # 2**24: the same-sample count stops here (the flags stay within 2**27)


@micropython.viper
def read(self, gyro_rad_s, accel_m_s2) -> bool:
    try:
        self._bus.readfrom_mem_into(self.address, 0x3B, self._buf)  # ACCEL_XOUT_H, RM §4.17
    except OSError:
        self.bus_errors = int(self.bus_errors) + 1
        return False
    tab = ptr32(self._tab)  # _buf's and _st's addresses (bind), two words each: low, high
    b = ptr8(tab[0] | ((tab[1] << 16) << 16))
    s = ptr32(tab[2] | ((tab[3] << 16) << 16))
    # Frozen and saturated watch on the six raw words, chip order (TEMP at bytes 6..7 is not
    # watched); written out, six times, as a loop here costs a tenth of the call more.
    same = 1
    sat = 0  # a word at +32767, -32768 or -32767 (0x7FFF..0x8001): pinned at a rail
    v = (b[0] << 8) | b[1]
    if v != s[ST_LAST + 0]:
        same = 0
        s[ST_LAST + 0] = v
    if v >= 0x7FFF and v <= 0x8001:
        sat = 1
    v = (b[2] << 8) | b[3]
    if v != s[ST_LAST + 1]:
        same = 0
        s[ST_LAST + 1] = v
    if v >= 0x7FFF and v <= 0x8001:
        sat = 1
    v = (b[4] << 8) | b[5]
    if v != s[ST_LAST + 2]:
        same = 0
        s[ST_LAST + 2] = v
    if v >= 0x7FFF and v <= 0x8001:
        sat = 1
    v = (b[8] << 8) | b[9]
    if v != s[ST_LAST + 3]:
        same = 0
        s[ST_LAST + 3] = v
    if v >= 0x7FFF and v <= 0x8001:
        sat = 1
    v = (b[10] << 8) | b[11]
    if v != s[ST_LAST + 4]:
        same = 0
        s[ST_LAST + 4] = v
    if v >= 0x7FFF and v <= 0x8001:
        sat = 1
    v = (b[12] << 8) | b[13]
    if v != s[ST_LAST + 5]:
        same = 0
        s[ST_LAST + 5] = v
    if v >= 0x7FFF and v <= 0x8001:
        sat = 1
    count = 0
    if same:
        count = s[ST_SAME] + 1
        if count > SAME_CAP:
            count = SAME_CAP
    s[ST_SAME] = count
    flags = (count << 3) | (sat << 2)
    v = (b[6] << 8) | b[7]
    temp = (v ^ 0x8000) - 0x8000
    s[ST_TEMP] = temp
    if s[ST_SCALED] == 0:
        i = 0
        j = ST_RAW
        while i < 14:
            v = (b[i] << 8) | b[i + 1]
            s[j] = (v ^ 0x8000) - 0x8000
            j += 1
            i += 2
            if i == 6:
                i = 8
        flags |= 2
    else:
        # The scales' mantissas in 12-bit halves, for the products below.
        am = s[ST_ACCEL_M]
        amh = am >> 12
        aml = am & 0xFFF
        ae = s[ST_ACCEL_E]
        gm = s[ST_GYRO_M]
        gmh = gm >> 12
        gml = gm & 0xFFF
        ge = s[ST_GYRO_E]
        ga = ptr32(gyro_rad_s)
        aa = ptr32(accel_m_s2)
        axis = 0
        while axis < 3:
            off = s[ST_OFF + axis]
            flip = s[ST_FLIP + axis]
            v = (b[off] << 8) | b[off + 1]
            n = (v ^ 0x8000) - 0x8000  # int16 sign extension: 0..0xFFFF -> -32768..32767
            bits = 0
            if n != 0:
                sign = flip
                if n < 0:
                    sign ^= 1
                    n = -n
                # n * m = hi * 2**24 + lo; n <= 2**15, so two products below 2**28
                p = n * amh
                lo = n * aml + ((p & 0xFFF) << 12)
                hi = (p >> 12) + (lo >> 24)
                lo = lo & 0xFFFFFF
                sh = 0
                mant = lo  # hi == 0: n * m is within 2**23..2**24, exact
                if hi != 0:
                    # sh = the bit length of hi (1..22): the product's bits below the 24 kept
                    t = hi
                    if t >= 0x1000:
                        t = t >> 12
                        sh = 12
                    if t >= 0x40:
                        t = t >> 6
                        sh += 6
                    if t >= 0x8:
                        t = t >> 3
                        sh += 3
                    if t >= 0x2:
                        t = t >> 1
                        sh += 1
                    if t >= 0x2:
                        sh += 1
                    sh += 1
                    # to nearest, ties to even: add half less one, plus the kept part's lowest bit
                    lo += (1 << (sh - 1)) - 1 + ((lo >> sh) & 1)
                    mant = ((hi + (lo >> 24)) << (24 - sh)) | ((lo & 0xFFFFFF) >> sh)
                    if mant == 0x1000000:  # rounded up to the next power of two
                        mant = 0x800000
                        sh += 1
                bits = (sign << 31) | ((ae + sh) << 23) | (mant & 0x7FFFFF)
            aa[axis] = bits
            # The same for the gyro, 8 bytes on (RM §4.17/4.19), in 1/16 LSB less the bias.
            v = (b[off + 8] << 8) | b[off + 9]
            n = ((v ^ 0x8000) - 0x8000) * 16 - (s[ST_BIAS + axis] - BIAS_OFFSET)
            bits = 0
            if n != 0:
                sign = flip
                if n < 0:
                    sign ^= 1
                    n = -n
                # n * m = hi * 2**24 + lo from 12-bit pieces (n < 2**21): four products below 2**25
                nh = n >> 12
                nl = n & 0xFFF
                mid = nh * gml + nl * gmh
                lo = nl * gml + ((mid & 0xFFF) << 12)
                hi = nh * gmh + (mid >> 12) + (lo >> 24)
                lo = lo & 0xFFFFFF
                sh = 0
                mant = lo  # hi == 0: n * m is within 2**23..2**24, exact
                if hi != 0:
                    # sh = the bit length of hi (1..22): the product's bits below the 24 kept
                    t = hi
                    if t >= 0x1000:
                        t = t >> 12
                        sh = 12
                    if t >= 0x40:
                        t = t >> 6
                        sh += 6
                    if t >= 0x8:
                        t = t >> 3
                        sh += 3
                    if t >= 0x2:
                        t = t >> 1
                        sh += 1
                    if t >= 0x2:
                        sh += 1
                    sh += 1
                    # to nearest, ties to even: add half less one, plus the kept part's lowest bit
                    lo += (1 << (sh - 1)) - 1 + ((lo >> sh) & 1)
                    mant = ((hi + (lo >> 24)) << (24 - sh)) | ((lo & 0xFFFFFF) >> sh)
                    if mant == 0x1000000:  # rounded up to the next power of two
                        mant = 0x800000
                        sh += 1
                bits = (sign << 31) | ((ge + sh) << 23) | (mant & 0x7FFFFF)
            ga[axis] = bits
            axis += 1
    if flags == 0 and s[ST_PREV] != 0:
        s[ST_PREV] = 0
        flags = 1
    else:
        s[ST_PREV] = flags
    if flags:
        self._finish(gyro_rad_s, accel_m_s2)
    self.temp_raw = temp
    self.samples = int(self.samples) + 1
    return True
