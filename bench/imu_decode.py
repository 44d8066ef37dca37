"""MPU-6050 read() cost: µs per read and bytes allocated per read, with the bus and without it.

Run: `.venv/bin/python bench/imu_decode.py` and
`MICROPYPATH=src:.frozen .venv/bin/micropython -X heapsize=192k bench/imu_decode.py`.
(`--reads N`: a quick run of N reads instead of 20000 on CPython, 2000 on MicroPython.)
Prints one JSON object with two mountings: `axis_map` (CW0, what the rp2 board and
bench/core_loop.py fly) and `aligned` (a board tilted by 0.05 rad: a general rotation).
- `read_us`, `bus_us`: read() over the fake I2C bus and register model (frozen registers: the
  same sample every read, so the driver's frozen watch fires), and that bus's readfrom_mem_into
  of 14 bytes alone (the model's cost dwarfs the driver's).
- `driver_us`: the driver alone, read() less its bus call, both over a bus whose
  readfrom_mem_into copies one of three held bursts in (a few bytecodes, no model).
  The pair is timed alternately, best of RUNS each; the host's noise is about ±0.3 µs.
- `alloc_bytes_per_read` (held bursts): gc.mem_alloc deltas with GC off on MicroPython, tracemalloc on CPython.

`--instructions` counts instead (valgrind's callgrind on the MicroPython VM, `MICROPYPATH` as above):
instructions per driver read (held bus, a run of reads less a run of bus calls, over N_COUNT; both runs
collect every 16 reads, as the rp2 main loop does, and the collections are left out of the count),
and `board_ir_per_read`: bench/core_loop.py's BenchBoard.read_imu whole (its burst bus included)
less an empty loop; the figures to compare two versions of the driver by. Prints {"bench", "n",
"axis_map_ir_per_read", "aligned_ir_per_read", "board_ir_per_read"}.
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

RUNS = 7
N = 2000 if IS_MICROPYTHON else 20000
if "--reads" in sys.argv:  # a short run checks that the bench still runs; figures need the default
    N = int(sys.argv[sys.argv.index("--reads") + 1])
N_COUNT = 2000


def _no_wait(us):
    pass


class HeldBus:
    """The model's bus until `held`; then readfrom_mem_into hands out three bursts taken from the
    model beforehand, in turn (never the same twice running: the frozen watch stays quiet, as on a
    live sensor)."""

    def __init__(self, bus):
        self.bus = bus
        self.bursts = []
        self.held = False
        self.k = 0

    def readfrom_mem_into(self, address, register, buf):
        if not self.held:
            self.bus.readfrom_mem_into(address, register, buf)
        else:
            k = self.k + 1
            if k == 3:
                k = 0
            self.k = k
            buf[:] = self.bursts[k]

    def writeto_mem(self, address, register, data):
        self.bus.writeto_mem(address, register, data)


def _setup(orientation):
    model = MPU6050Model(orientation, noise_lsb=0)
    bus = HeldBus(FakeI2C(model))
    drv = MPU6050(bus, orientation, delay_us=_no_wait)
    drv.configure()
    for k in range(3):
        model.set_motion((0.1 + 0.01 * k, -0.2, 0.3), (0.5, -0.4 - 0.01 * k, -9.8))
        b = bytearray(14)
        bus.readfrom_mem_into(drv.address, 0x3B, b)
        bus.bursts.append(bytes(b))
    model.freeze()  # registers hold still: the bench times the driver, not the model's maths
    return bus, drv


def _loops(bus, drv):
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

    reads(1)
    return reads, bus_only


def _time_us(fn, n):
    t0 = ticks_us()
    fn(n)
    return ticks_diff(ticks_us(), t0) / n


def _best_pair_us(f1, f2, n):
    """Best of RUNS for each of two loops, timed alternately (the host's load hits both alike)."""
    b1 = b2 = None
    for _ in range(RUNS):
        t1 = _time_us(f1, n)
        t2 = _time_us(f2, n)
        if b1 is None or t1 < b1:
            b1 = t1
        if b2 is None or t2 < b2:
            b2 = t2
    return b1, b2


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
    reads, bus_only = _loops(bus, drv)
    read_us, bus_us = _best_pair_us(reads, bus_only, N)
    bus.held = True
    m = 100 if IS_MICROPYTHON else 500  # GC is off while counting: stay inside a 192 KB heap
    alloc_read = _alloc_per_call(reads, m)
    held_read_us, held_bus_us = _best_pair_us(reads, bus_only, N)
    return ('{"read_us": %.3f, "bus_us": %.3f, "driver_us": %.3f, "alloc_bytes_per_read": %.1f}'
            % (read_us, bus_us, held_read_us - held_bus_us, alloc_read))


def _mountings():
    return (("axis_map", Orientation()), ("aligned", Orientation(CW270_FLIP, 0.0, 0.05, 0.0)))


def _child(mount_name, mode, n):
    if mount_name == "board":  # bench/core_loop.py's board: read_imu as the flight pass calls it
        from core_loop import BenchBoard

        board = BenchBoard()
        g = array("f", [0.0, 0.0, 0.0])
        a = array("f", [0.0, 0.0, 0.0])
        r = board.read_imu
        r(g, a)
        collect_garbage()
        disable_gc()
        if mode == "read":
            for _ in range(n):
                r(g, a)
        else:
            for _ in range(n):
                pass
        return
    for name, o in _mountings():
        if name == mount_name:
            bus, drv = _setup(o)
            reads, bus_only = _loops(bus, drv)
            bus.held = True
            collect_garbage()
            disable_gc()
            # 16 reads between collections, as bench/rc_instructions.py: the aligned read's floats
            # would otherwise leave the allocator searching a heap of garbage, and that search would be the count
            loop = reads if mode == "read" else bus_only
            for k in range(0, n, 16):
                loop(min(16, n - k))
                collect_garbage()


def _instructions():
    import json
    import os

    from core_instructions import _count

    me = os.path.abspath(__file__)
    mp = os.path.join(os.path.dirname(sys.executable), "micropython")
    env = dict(os.environ)
    if "MICROPYPATH" not in env:
        env["MICROPYPATH"] = "%s/src:.frozen" % os.path.dirname(os.path.dirname(me))
    out = {"bench": "imu_decode", "n": N_COUNT}
    for name in ("axis_map", "aligned", "board"):
        counts = {}
        for mode in ("read", "bus"):
            # less the collections (bench/core_instructions.py's counter): the runs collect every 16 reads
            counts[mode] = _count([mp, "-X", "heapsize=8m", me, "--child", name, mode, str(N_COUNT)], env)
        out[name + "_ir_per_read"] = round((counts["read"] - counts["bus"]) / N_COUNT)
    print(json.dumps(out))


def main():
    parts = ['"%s": %s' % (name, measure(o)) for name, o in _mountings()]
    print('{"bench": "imu_decode", "impl": "%s", "n": %d, %s}' % (sys.implementation.name, N, ", ".join(parts)))


if len(sys.argv) > 1 and sys.argv[1] == "--child":
    _child(sys.argv[2], sys.argv[3], int(sys.argv[4]))
elif len(sys.argv) > 1 and sys.argv[1] == "--instructions":
    _instructions()
else:
    main()
