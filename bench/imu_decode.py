"""MPU-6050 read() + decode cost over the fake I2C bus: µs per read and bytes allocated per read.

Run: `.venv/bin/python bench/imu_decode.py` and
`MICROPYPATH=src:.frozen .venv/bin/micropython -X heapsize=192k bench/imu_decode.py`.
Prints one JSON object. `bus_us` is the fake bus + register model alone (one
readfrom_mem_into of 14 bytes), so `decode_us` = read_us - bus_us is the driver's own
share (decode, frozen/saturation watch, scale, rotate). Times are the best of several runs.
Allocation: gc.mem_alloc deltas with GC off on MicroPython, tracemalloc on CPython.
"""

import sys

_here = __file__.rsplit("/", 1)[0] if "/" in __file__ else "."
if "/" in _here:
    _root = _here.rsplit("/", 1)[0]
else:
    _root = ".." if _here == "." else "."
for _p in (_root + "/tests", _root + "/src"):
    if _p not in sys.path:
        sys.path.append(_p)

from array import array  # noqa: E402

from hoverfly.compat import (  # noqa: E402
    IS_MICROPYTHON,
    collect_garbage,
    disable_gc,
    enable_gc,
    mem_alloc,
    ticks_diff,
    ticks_us,
)
from hoverfly.drivers.mpu6050 import MPU6050  # noqa: E402
from hoverfly.drivers.orientation import CW270_FLIP, Orientation  # noqa: E402
from rp2fakes.regmodels import FakeI2C, MPU6050Model  # noqa: E402

RUNS = 5
N = 2000 if IS_MICROPYTHON else 20000


def _no_wait(us):
    pass


def _setup(orientation):
    model = MPU6050Model(orientation, noise_lsb=0)
    bus = FakeI2C(model)
    drv = MPU6050(bus, orientation, delay_us=_no_wait)
    drv.configure()
    model.set_motion((0.1, -0.2, 0.3), (0.5, -0.4, -9.8))
    model.freeze()  # registers hold still: the bench times the driver, not the model's maths
    return bus, drv


def _best_us(fn, n):
    best = None
    for _ in range(RUNS):
        t0 = ticks_us()
        fn(n)
        dt = ticks_diff(ticks_us(), t0)
        if best is None or dt < best:
            best = dt
    return best / n


def _alloc_per_call(fn, n):
    if IS_MICROPYTHON:
        collect_garbage()
        disable_gc()
        before = mem_alloc()
        fn(n)
        after = mem_alloc()
        enable_gc()
        return (after - before) / n
    import tracemalloc

    fn(10)
    tracemalloc.start()
    snap0 = tracemalloc.take_snapshot()
    fn(n)
    snap1 = tracemalloc.take_snapshot()
    tracemalloc.stop()
    grown = 0
    for stat in snap1.compare_to(snap0, "filename"):
        if stat.size_diff > 0:
            grown += stat.size_diff
    return grown / n


def measure(orientation):
    bus, drv = _setup(orientation)
    g = array("f", [0.0, 0.0, 0.0])
    a = array("f", [0.0, 0.0, 0.0])
    buf = bytearray(14)
    addr = drv.address

    def reads(n):
        r = drv.read
        for _ in range(n):
            r(g, a)

    def bus_only(n):
        f = bus.readfrom_mem_into
        for _ in range(n):
            f(addr, 0x3B, buf)

    read_us = _best_us(reads, N)
    bus_us = _best_us(bus_only, N)
    m = 100 if IS_MICROPYTHON else 500  # GC is off while counting: stay inside a 192 KB heap
    alloc_read = _alloc_per_call(reads, m)
    alloc_bus = _alloc_per_call(bus_only, m)
    return read_us, bus_us, alloc_read, alloc_bus


def main():
    r0, b0, ar0, ab0 = measure(Orientation())
    r1, b1, ar1, ab1 = measure(Orientation(CW270_FLIP, 0.0, 0.05, 0.0))
    impl = sys.implementation.name
    out = (
        '{"bench": "imu_decode", "impl": "%s", "n": %d, '
        '"axis_map": {"read_us": %.3f, "bus_us": %.3f, "decode_us": %.3f, '
        '"alloc_bytes_per_read": %.1f, "alloc_bytes_bus_only": %.1f}, '
        '"aligned": {"read_us": %.3f, "bus_us": %.3f, "decode_us": %.3f, '
        '"alloc_bytes_per_read": %.1f, "alloc_bytes_bus_only": %.1f}}'
    ) % (impl, N, r0, b0, r0 - b0, ar0, ab0, r1, b1, r1 - b1, ar1, ab1)
    print(out)


main()
