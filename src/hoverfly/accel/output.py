"""Viper twin of core/output.py's `OutputStage.update_fixed` (MicroPython only; chosen at import by core/output.py).

`update_fixed` is the method itself (core/output.py puts it on the class, as core/fixedimu.py does),
so the pass makes no bytecode call for it. The same integer arithmetic as the Python `motors_fixed`
(`OutputStage.update_fixed_python`), which stays the reference and the fallback;
tests/portable/test_output_fixed.py runs both on the same inputs and wants every output bit and the
clamp count equal. As in accel/rate.py, floats are read and written as their float32
bits (`ptr32` on the "f" arrays), so no float object is made:

- The clamps are decided on the bits: NaN, and anything negative but -0.0, is the floor (counted);
  anything above 1.0 (0x3F800000), +inf included, is 1.0 (counted), as `OutputStage.update`'s
  float comparisons decide them.
- A demand in 0..1 is truncated to Q16; the command is idle + (span * demand + 2**13) >> 14 in
  Q16 (span Q14, so the product stays under 2**31 on a 32-bit port), with each motor's own floor
  and span from the plan (motor_enable, motorN_min_us/_max_us; a disabled motor has both 0, so its
  command is 0.0, stop), written as the float32 bits of command / 2**16: at most 2**17, so exact,
  as an array store of that value is; the exponent in five halving steps.
- Disarmed: every motor's command is 0.0 (bits 0). The clamp count saturates just past 2**30, as
  the Python twin's does, so reading it back never needs more than a 32-bit word.
"""

# ptr32/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython


@micropython.viper
def update_fixed(self, motor_norm, armed: int, motor_out):
    """OutputStage.update_fixed itself (core/output.py puts it on the class): no bytecode frame."""
    out = ptr32(motor_out)
    plan = ptr32(self._fixed_plan)  # array('i'): motors, then per motor floor Q16, span Q14 (none negative)
    n = int(plan[0])
    i = 0
    if not armed:
        while i < n:  # the float32 bits of 0.0
            out[i] = 0
            i += 1
        return
    norm = ptr32(motor_norm)
    one = 1
    low31 = (one << 31) - 1  # 0x7FFFFFFF and 0x7F800000 (+inf): no constant of 2**30 or more, which is
    inf = ((one << 8) - 1) << 23  # not a small int on a 32-bit port
    clamped = 0
    while i < n:
        idle = int(plan[1 + 2 * i])
        span = int(plan[2 + 2 * i])
        b = norm[i]
        mag = b & low31
        v = 0
        if mag > inf:  # NaN
            clamped += 1
        elif (b >> 31) & 1:
            if mag != 0:  # below 0 (-0.0 is 0)
                clamped += 1
        elif mag > 0x3F800000:  # above 1.0
            v = 65536
            clamped += 1
        else:
            e = (mag >> 23) & 0xFF
            if e != 0:
                m = (mag & 0x7FFFFF) | 0x800000
                sh = e - 150 + 16
                if sh >= 0:
                    v = m << sh
                elif sh > -24:
                    v = m >> (0 - sh)
        c = idle + ((span * v + 8192) >> 14)  # at most 2**17: exact in float32
        bits = 0
        if c > 0:
            pw = 0  # floor(log2(c)), c < 2**18
            tt = c
            if tt >= 0x10000:
                tt = tt >> 16
                pw = 16
            if tt >= 0x100:
                tt = tt >> 8
                pw += 8
            if tt >= 0x10:
                tt = tt >> 4
                pw += 4
            if tt >= 4:
                tt = tt >> 2
                pw += 2
            if tt >= 2:
                pw += 1
            bits = ((pw - 16 + 127) << 23) | ((c << (23 - pw)) & 0x7FFFFF)
        out[i] = bits
        i += 1
    if clamped:
        v = int(self.clamped)
        if v < 0x3FFFFFFF:  # a count that saturates near 2**30 stays a machine word on a 32-bit port
            self.clamped = v + clamped
