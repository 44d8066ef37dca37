"""What the viper stages share: their address tables and the encode's log2 table. MicroPython only.

A viper stage (accel/rate.py, imufilter.py, att.py, mpu6050.py) reaches its arrays through a table of their
data addresses that its configure writes once with `bind`, instead of a runtime call per array per pass.
Safe because MicroPython's collector never moves an object and these arrays never grow; the stage keeps a
reference to each. An address takes two 32-bit words (the unix VM is 64-bit).
"""

# ptr32/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython

# floor(log2(i)) for i in 1..255 (0 for 0): a float32 encode's exponent, a byte at a time
LOG2 = bytearray(256)
for _i in range(2, 256):
    LOG2[_i] = LOG2[_i >> 1] + 1


@micropython.viper
def bind(tab, k: int, buf):
    """Write the address of buf's data (an array or bytearray) into tab's entry k (two words)."""
    t = ptr32(tab)
    v = int(ptr32(buf))
    t[2 * k] = v
    t[2 * k + 1] = (v >> 16) >> 16
