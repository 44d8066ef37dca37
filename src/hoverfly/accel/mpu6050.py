"""Viper twin of the MPU-6050 burst decode (MicroPython only; chosen at import by drivers/mpu6050.py).

Takes the 14-byte burst from ACCEL_XOUT_H (big-endian int16: accel X/Y/Z, TEMP, gyro X/Y/Z;
RM-MPU-6000A-00 §4.17-4.19) and the driver's axis plan; gives the integers MPU6050.read's
pure-Python axis-map path computes, bit for bit, into a preallocated array('i'). That Python
path stays the reference and the fallback wherever viper is missing (CPython, the wasm port).

- `decode(buf, plan, out)`: plan is array('H') of 12, per body axis: the offset of its chip axis
  in the burst (0/2/4), 1 if the axis is flipped (else 0), and that chip axis's gyro bias in
  1/16 LSB as two 16-bit halves, low then high (`plan(...)` builds it; unsigned halves because a
  ptr32 load of a negative int32 comes back zero-extended on a 64-bit port). out is array('i') of 13:
  out[0..2] accel and out[3..5] gyro counts of each body axis's chip axis (signed, unflipped:
  what Imu._watch takes), out[6] TEMP_OUT, out[7..9] sign * (gyro * 16 - bias) and
  out[10..12] sign * accel. The float scaling stays in Python (one product per axis).

It sits at the start of the pass (board.read_imu -> MPU6050.read). Viper reads and writes raw
memory: buf must hold 14 bytes, plan and out must be array('H') of 12 and array('i') of 13 (the
driver's own). Viper ints are 32-bit on the RP2040/RP2350: a count is 16 bits, sign-extended by
hand below; gyro * 16 is within +-2**19 and `plan` refuses (returns None for) a bias outside
+-2**20 (calibration gives an average of counts * 16, within +-2**19), so every intermediate stays
within +-2**21, far inside 31 bits.
tests/portable/test_viper_twins.py checks the twins agree.
"""

# ptr8/ptr16/ptr32 are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

from array import array

import micropython

BIAS_LIMIT = 1 << 20  # |bias16| below this keeps every viper intermediate within +-2**21


def plan(offsets, signs, biases):
    """decode()'s plan from three per-axis sequences (offset 0/2/4, sign +-1, int bias in 1/16 LSB);
    None if a bias is not an int within +-BIAS_LIMIT (the caller keeps its Python path then)."""
    p = array("H", [0] * 12)
    for k in range(3):
        b = biases[k]
        if not isinstance(b, int) or b <= -BIAS_LIMIT or b >= BIAS_LIMIT:
            return None
        p[4 * k] = offsets[k]
        p[4 * k + 1] = 1 if signs[k] < 0 else 0
        p[4 * k + 2] = b & 0xFFFF
        p[4 * k + 3] = (b >> 16) & 0xFFFF
    return p


@micropython.viper
def decode(buf, plan, out):
    b = ptr8(buf)
    p = ptr16(plan)
    o = ptr32(out)
    k = 0
    while k < 3:
        off = p[4 * k]
        flip = p[4 * k + 1]
        hi = p[4 * k + 3]
        bias = (((hi ^ 0x8000) - 0x8000) << 16) | p[4 * k + 2]  # |bias| < 2**20: hi is -16..15
        v = (b[off] << 8) | b[off + 1]
        v = (v ^ 0x8000) - 0x8000  # int16 sign extension: 0..0xFFFF -> -32768..32767
        o[k] = v
        o[10 + k] = -v if flip else v
        v = (b[off + 8] << 8) | b[off + 9]
        v = (v ^ 0x8000) - 0x8000
        o[3 + k] = v
        v = v * 16 - bias
        o[7 + k] = -v if flip else v
        k += 1
    v = (b[6] << 8) | b[7]
    o[6] = (v ^ 0x8000) - 0x8000
