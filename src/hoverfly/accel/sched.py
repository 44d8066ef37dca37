"""Viper twin of core/scheduler.py's `pass_stats` (MicroPython only; chosen at import by core/scheduler.py).

The pass statistics Flight.step records at every pass, in Scheduler.stats (array "i", PS_* of
core/scheduler.py, repeated here as literals): one native call with no bytecode frame and no attribute
look-up. The same integer steps as the Python twin; tests/portable/test_scheduler.py runs both.
Counts wrap at 2**30 - 1 (COUNT_MASK), built by a shift (a constant of 2**30 or more is no small int
on a 32-bit port); every stored value is non-negative but the cycle time, which is only stored.
"""

# ptr32/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython


@micropython.viper
def pass_stats(ps_a, cycle_us: int):
    ps = ptr32(ps_a)
    one = 1
    mask = (one << 30) - 1  # COUNT_MASK
    if cycle_us > mask:
        cycle_us = mask
    ps[0] = (ps[0] + 1) & mask  # PS_PASSES
    ps[1] = cycle_us  # PS_CYCLE
    if cycle_us > int(ps[2]):  # PS_CYCLE_MAX
        ps[2] = cycle_us
    j = cycle_us - int(ps[5])  # PS_PERIOD
    if j < 0:
        j = -j
    ps[4] = (ps[4] + j) & mask  # PS_JITTER_SUM
    if j > int(ps[3]):  # PS_JITTER_MAX
        ps[3] = j
