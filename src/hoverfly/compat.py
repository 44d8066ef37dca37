"""The one module that knows MicroPython from CPython.

Gives the portable code (core, protocols, drivers) a microsecond/millisecond tick
clock with MicroPython's wrap arithmetic, `const`, garbage-collection hooks and
exception printing. On CPython the tick clock is masked to 2**30 exactly as on
the rp2 port, and tests can start it just below the wrap (`set_ticks_origin_us`)
so any raw tick subtraction fails loudly on the host too.

It also installs a `micropython` stub module on CPython so that
`import micropython` / `@micropython.native` run unchanged on both.
"""

import sys

IS_MICROPYTHON = sys.implementation.name == "micropython"

if IS_MICROPYTHON:
    import gc
    import time

    from micropython import const  # noqa: F401  (re-exported)

    # The port's own period: 2**30 on rp2 (31-bit small ints), 2**62 on the 64-bit unix port.
    TICKS_MAX = time.ticks_add(0, -1)
    TICKS_PERIOD = TICKS_MAX + 1
    TICKS_HALF = TICKS_PERIOD >> 1

    ticks_us = time.ticks_us
    ticks_ms = time.ticks_ms
    ticks_diff = time.ticks_diff
    ticks_add = time.ticks_add
    sleep_us = time.sleep_us

    def set_ticks_origin_us(origin_us):
        """No-op on the device: its clock is the hardware's."""

    def print_exception(exc):
        sys.print_exception(exc)

    def collect_garbage():
        gc.collect()

    def disable_gc():
        gc.disable()

    def enable_gc():
        gc.enable()

    def mem_free():
        return gc.mem_free()

    def mem_alloc():
        return gc.mem_alloc()

else:
    import time
    import traceback
    import types

    # As the rp2 port: the ticks period is the small-int range of a 32-bit port, 2**30.
    TICKS_PERIOD = 1 << 30
    TICKS_MAX = TICKS_PERIOD - 1
    TICKS_HALF = TICKS_PERIOD >> 1

    def const(value):
        return value

    def _identity(fn):
        return fn

    if "micropython" not in sys.modules:
        _stub = types.ModuleType("micropython")
        _stub.const = const
        _stub.native = _identity
        _stub.viper = _identity
        sys.modules["micropython"] = _stub

    _perf_ns = time.perf_counter_ns
    # Start near the wrap by default so host runs exercise it within seconds.
    _origin_us = [TICKS_PERIOD - 5_000_000 - _perf_ns() // 1000]

    def set_ticks_origin_us(origin_us):
        """Make ticks_us() read `origin_us` now (tests put it just below the wrap)."""
        _origin_us[0] = origin_us - _perf_ns() // 1000

    def ticks_us():
        return (_perf_ns() // 1000 + _origin_us[0]) & TICKS_MAX

    def ticks_ms():
        return ((_perf_ns() // 1000 + _origin_us[0]) // 1000) & TICKS_MAX

    def ticks_diff(end, start):
        """Signed end - start in ticks, correct across one wrap (as MicroPython)."""
        return ((end - start + TICKS_HALF) & TICKS_MAX) - TICKS_HALF

    def ticks_add(ticks, delta):
        return (ticks + delta) & TICKS_MAX

    def sleep_us(us):
        if us > 0:
            time.sleep(us * 1e-6)

    def print_exception(exc):
        traceback.print_exception(type(exc), exc, exc.__traceback__)

    def collect_garbage():
        pass

    def disable_gc():
        pass

    def enable_gc():
        pass

    def mem_free():
        return 0

    def mem_alloc():
        return 0


def ticks_elapsed_us(now_us, since_us):
    """Microseconds from `since_us` to `now_us` (ticks), never negative."""
    d = ticks_diff(now_us, since_us)
    return d if d > 0 else 0


# MicroPython's hash-table sizes (py/map.c hash_allocation_sizes): an instance's attribute table takes the
# next one up only when it is full, so a table is often nearly full, and in a full table a look-up that
# misses (every method call: the instance is searched before its class) probes on to an empty slot.
_MAP_SIZES = (0, 2, 4, 6, 8, 10, 12, 17, 23, 29, 37, 47, 59, 73, 97, 127, 167, 223, 293, 389, 521, 691, 919,
              1223, 1627, 2161)
ROOM_LOAD_PCT = 80  # attr_room leaves a table at most this full


def map_size(n):
    """The slots of a MicroPython attribute table holding n attributes (none ever deleted)."""
    for size in _MAP_SIZES:
        if size >= n:
            return size
    return n + (n >> 1) | 1  # past the table, as py/map.c: odd, half again


def attr_room(obj):
    """On MicroPython, while obj's attribute table is more than ROOM_LOAD_PCT full, add spare attributes
    (`_room<n>`, None; n counts the attributes, so a later call adds new names) until it has grown to a
    size with that much room; returns how many
    (0 on CPython, whose dicts keep their own room). For an object the pass reads many times (the Flight,
    its commander and supervisor): in a nearly full table every method call's missed instance look-up
    probes a long run of slots before it reaches an empty one."""
    if not IS_MICROPYTHON:
        return 0
    n = len(obj.__dict__)
    k = 0
    while n + k > 0 and (n + k) * 100 > map_size(n + k) * ROOM_LOAD_PCT:
        setattr(obj, "_room%d" % (n + k), None)
        k += 1
    return k
