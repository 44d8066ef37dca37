"""Cost of one pass of the gyro notch filters alone: the RPM filter and the dynamic notch, float and fixed point.

Runs under CPython and MicroPython (64- and 32-bit VMs); prints one JSON object: per stage, µs and bytes
allocated a call (bytes from gc.mem_alloc() with the collector off; 0 on CPython, which does not count
them). A quad's four motors near a 5-inch's hover, a gyro with their vibration on top of noise.

    .venv/bin/python bench/notch_filters.py
    .venv/bin/python -m hoverfly.fastgen   # first: the fixed RPM filter's viper twin (docs/fastpass.md)
    MICROPYPATH=src .venv/bin/micropython -X heapsize=4m bench/notch_filters.py
    MICROPYPATH=src ../shared/tools/micropython-i686 -X heapsize=4m bench/notch_filters.py
    .venv/bin/python bench/notch_filters.py --calls 200   # a quick run (CALLS: 20000 on CPython, 2000 on MicroPython)

The µs are wall-clock on a shared host (they move by 10-30 % from run to run); bench/core_instructions.py
--rpm N counts the whole pass with the RPM filter by instructions instead.
"""

import math
import sys

from hoverfly.compat import IS_MICROPYTHON, collect_garbage, disable_gc, enable_gc, mem_alloc, ticks_diff, ticks_us
from hoverfly.core.config.params import Params
from hoverfly.core.fastpass import fixeddyn, fixedrpm
from hoverfly.core.signals import Signals
from hoverfly.core.stages.dynnotch import DynNotch
from hoverfly.core.stages.rpmfilter import RpmFilter

CALLS = 2000 if IS_MICROPYTHON else 20000
if "--calls" in sys.argv:  # a short run checks that every stage still runs; figures need the default
    CALLS = int(sys.argv[sys.argv.index("--calls") + 1])


def _measure(fn, gyro):
    """(µs, bytes) a call of fn(n), the gyro refreshed before each call as a new sample would be."""
    collect_garbage()
    disable_gc()
    us = 0
    nbytes = 0
    try:
        for n in range(CALLS):
            x = 0.2 * math.sin(n * 1.05) + 0.01 * ((n * 7919) % 13 - 6)
            gyro[0] = x
            gyro[1] = -x
            gyro[2] = 0.5 * x
            a0 = mem_alloc()
            t0 = ticks_us()
            fn(n)
            t1 = ticks_us()
            nbytes += mem_alloc() - a0
            us += ticks_diff(t1, t0)
            if n % 64 == 63:
                enable_gc()
                collect_garbage()
                disable_gc()
    finally:
        enable_gc()
    return us / CALLS, nbytes / CALLS


def main():
    result = {"runtime": sys.implementation.name, "calls": CALLS, "word_bits": 64 if sys.maxsize > 2 ** 32 else 32,
              "fixed_rpm_viper": fixedrpm.HAS_ACCEL, "fixed_dyn_viper": fixeddyn.HAS_ACCEL}
    for harmonics in (1, 3):
        p = Params()
        p.set("rpm_harmonics", harmonics)
        s = Signals()
        for m in range(4):
            s.motor_rpm[m] = 10000 + 30 * m
        f = RpmFilter()
        f.configure(p, 1000, 4, True)
        g = s.gyro_rad_s

        def float_pass(n, f=f, g=g, rpm=s.motor_rpm):
            f.reply_ok(f.due())
            f.update(g, rpm, n)

        us, b = _measure(float_pass, g)
        result["rpm_float_h%d" % harmonics] = {"us": round(us, 2), "bytes": round(b, 1)}
        fx = fixedrpm.FixedRpmFilter()
        fx.configure(f, s, True)

        def fixed_pass(n, fx=fx):
            fx.reply_ok(fx.due())
            fx.update(n)

        us, b = _measure(fixed_pass, g)
        result["rpm_fixed_h%d" % harmonics] = {"us": round(us, 2), "bytes": round(b, 1)}
    for count in (1, 3):
        p = Params()
        p.set("dyn_notch_count", count)
        d = DynNotch()
        d.configure(p, 1000)
        g = Signals().gyro_rad_s

        def dyn_pass(n, d=d, g=g):
            d.update(g)

        us, b = _measure(dyn_pass, g)
        result["dyn_float_%d" % count] = {"us": round(us, 2), "bytes": round(b, 1)}
        s = Signals()
        fx = fixeddyn.FixedDynNotch()
        fx.configure(d, s, True)

        def dyn_fixed_pass(n, fx=fx):
            fx.update()

        us, b = _measure(dyn_fixed_pass, s.gyro_rad_s)
        result["dyn_fixed_%d" % count] = {"us": round(us, 2), "bytes": round(b, 1)}
    items = ['"%s": %s' % (k, _json(v)) for k, v in result.items()]
    print("{" + ", ".join(items) + "}")


def _json(v):
    if isinstance(v, dict):
        return "{" + ", ".join('"%s": %s' % (k, _json(x)) for k, x in v.items()) + "}"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"%s"' % v
    return str(v)


if __name__ == "__main__":
    main()
