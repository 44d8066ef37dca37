"""Viper twin of core/safety/failsafe.py's `FaultWatch.check_imu` (MicroPython only; chosen at import by
core/safety/failsafe.py).

`check_imu` is the method itself (core/safety/failsafe.py puts it on the class), so the 100 Hz task makes no
bytecode call for it and no float object: the six raw values are read as their float32 bits (`ptr32` on
the "f" arrays, or the pass record's float views), and so are the limits:

- Frozen: the six words equal to the last check's, bit for bit (the method's promise: "bit-identical").
  The Python twin compares the values, which differs only where no IMU driver goes: -0.0 against 0.0
  (equal values, other bits) and NaN (never equal to itself).
- Saturated: |value| above the limit, decided on the magnitude bits (the sign cleared): for finite
  floats and infinity that orders as the values do; a NaN (magnitude above +inf's bits) is not
  saturated, as `nan > limit` is False in the Python twin. 34.0 is 0x42080000 and 150.0 is 0x43160000.
- Not finite: magnitude bits at or above +inf's (an infinity or a NaN): fault 5 (FAULT_IMU_NONFINITE) from
  this check on, before frozen and saturated (the counts still run, as the Python twin's).
- The counts (same, saturated) and the last words live in the FaultWatch's `_imu_st` (array "i", 8):
  words 0..5 the last bits, 6 the frozen count, 7 the saturated count; they stop at 2**20 (the Python
  twin's grow on, and are only ever compared with _IMU_BAD_CHECKS, 10). No constant here reaches 2**30,
  which is not a small int on a 32-bit port: the larger ones are built by shifts.

tests/portable/test_faults_twin.py runs both twins on the same samples and wants the same faults.
"""

# ptr32/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython


@micropython.viper
def check_imu(self, gyro_raw_rad_s, accel_raw_m_s2) -> int:
    """FaultWatch.check_imu itself: 0 none, 1 frozen, 2 saturated (FAULT_NONE / _IMU_FROZEN / _SATURATED)."""
    st = ptr32(self._imu_st)
    g = ptr32(gyro_raw_rad_s)
    a = ptr32(accel_raw_m_s2)
    one = 1
    low31 = (one << 31) - 1
    inf = ((one << 8) - 1) << 23  # +inf's bits: a magnitude above them is a NaN
    g_sat = 0x4208  # 34.0 is 0x42080000, 150.0 0x43160000: shifted at run time (folded, the constant
    a_sat = 0x4316  # would be 2**30 or more: an object on a 32-bit port, which viper cannot compare)
    g_sat <<= 16
    a_sat <<= 16
    same = 1
    sat = 0
    bad = 0
    i = 0
    while i < 3:
        gb = g[i]
        ab = a[i]
        if gb != st[i] or ab != st[3 + i]:
            same = 0
        st[i] = gb
        st[3 + i] = ab
        m = gb & low31
        if m > g_sat and m <= inf:
            sat = 1
        if m >= inf:
            bad = 1
        m = ab & low31
        if m > a_sat and m <= inf:
            sat = 1
        if m >= inf:
            bad = 1
        i += 1
    n = int(st[6])
    if same:
        if n < (one << 20):
            n += 1
    else:
        n = 0
    st[6] = n
    frozen = n
    n = int(st[7])
    if sat:
        if n < (one << 20):
            n += 1
    else:
        n = 0
    st[7] = n
    fault = 0
    if bad:
        fault = 5  # FAULT_IMU_NONFINITE
    elif frozen >= 10:  # _IMU_BAD_CHECKS
        fault = 1  # FAULT_IMU_FROZEN
    elif n >= 10:
        fault = 2  # FAULT_IMU_SATURATED
    self.imu_fault = fault
    return fault
