"""What one attitude update costs: the float Mahony (core/stages/estimator.py) against the fixed-point one
(core/fastpass/fixedatt.py: the viper twin on MicroPython, the Python twin elsewhere).

Both run the same 250 Hz update on the same turning, vibrating samples (a quarter of the calls
trusted less, or not at all, as in a manoeuvre), armed, with the bias integral on. `float` is one
`Mahony.update` call (its Euler angles included); `fixed` is one `FixedAttitude.step` that updates
(every = 1), with and without the float attributes it can set (`angle_floats`), and `fixed_sum` a
step that only adds the gyro into the average (the three passes in four between updates at 1 kHz).
Rounds alternate between the variants; each figure is the best of ROUNDS. Bytes are a call's heap
allocation (gc.mem_alloc, the collector off; 0 on CPython, which has no such count).

Prints one JSON object {runtime, calls, us_per_call: {...}, bytes_per_call: {...}}. With --count
(CPython running MicroPython under valgrind's callgrind, bench/core_instructions.py's counter) it
prints the instructions a call executes on the MicroPython VM instead, {runtime, calls,
ir_per_call: {...}}: the figure to compare by on this shared host. Those runs collect every 16th call, as
the rp2 main loop does, and the collections are left out of the count.

    MICROPYPATH=src .venv/bin/micropython -X heapsize=1m bench/estimator.py
    .venv/bin/python bench/estimator.py
    .venv/bin/python bench/estimator.py --count
"""

import sys
from array import array

from hoverfly.compat import collect_garbage, disable_gc, enable_gc, mem_alloc, ticks_diff, ticks_us
from hoverfly.core.config.params import Params
from hoverfly.core.fastpass import fixedatt
from hoverfly.core.stages.estimator import Attitude, Mahony

CALLS = 100  # with the collector off: 100 float calls make about 390 kB
ROUNDS = 15
N = 64  # distinct samples, cycled


class _Signals:
    def __init__(self):
        self.gyro_rad_s = array("f", [0.0, 0.0, 0.0])
        self.accel_m_s2 = array("f", [0.0, 0.0, -9.80665])


def _samples():
    g = []
    a = []
    s = 12345
    for n in range(N):
        row = []
        for _ in range(6):
            s = (s * 1103515245 + 12345) & 0x7FFFFFFF
            row.append(((s >> 7) / 16777216.0) * 2.0 - 1.0)
        g.append(array("f", [2.0 * row[0], 1.5 * row[1], 0.5 * row[2]]))
        lift = 1.0 if n % 4 else 1.5 + (n % 8) * 0.02  # every fourth: 0.5 g off (untrusted) or near 0.1
        a.append(array("f", [row[3], row[4], -9.80665 * lift + row[5]]))
    return g, a


def _stages():
    p = Params()
    p.set("imu_dcm_ki", 100)
    m = Mahony()
    m.configure(p)
    att = Attitude()
    s = _Signals()
    return m, att, s


def _variants():
    """(name, fn(n), angle_floats or None) for each variant; fn runs one call on sample n."""
    gs, acs = _samples()
    # one stage per sample, its arrays holding the sample (a float copied in would be a float made)
    floats = []
    fixed = []
    sums = []
    for k in range(N):
        floats.append((_stages()[0], Attitude()))
        m, att, s = _stages()
        s.gyro_rad_s = gs[k]
        s.accel_m_s2 = acs[k]
        fx = fixedatt.FixedAttitude()
        fx.configure(m, att, s, 250, 1, True)
        fixed.append(fx)
        fs = fixedatt.FixedAttitude()
        fs.configure(m, Attitude(), s, 1000, 1 << 7, True)  # the sum only (it never gets to the update)
        sums.append(fs)

    def run_float(n):
        m, att = floats[n % N]
        m.update(gs[n % N], acs[n % N], 0.004, True, att)

    def run_fixed(n):
        fixed[n % N].step(4000, True)

    def run_sum(n):
        fs = sums[n % N]
        fs.st[fixedatt.S_N] = 0
        fs.step(1000, True)

    def run_none(n):  # the loop and the look-ups alone
        m, att = floats[n % N]
        return gs[n % N]

    return (("float", run_float, None), ("fixed", run_fixed, False), ("fixed_floats", run_fixed, True),
            ("fixed_sum", run_sum, None), ("loop", run_none, None)), fixed


def main():
    variants, fixed = _variants()
    best = {}
    nbytes = {}
    for _ in range(ROUNDS):
        for name, fn, floats in variants:
            if floats is not None:
                for fx in fixed:
                    fx.angle_floats = floats
            collect_garbage()
            disable_gc()
            a0 = mem_alloc()
            t0 = ticks_us()
            for n in range(CALLS):
                fn(n)
            t = ticks_diff(ticks_us(), t0)
            b = mem_alloc() - a0
            enable_gc()
            if name not in best or t < best[name]:
                best[name] = t
                nbytes[name] = b
    loop = best["loop"]
    names = ("float", "fixed", "fixed_floats", "fixed_sum")
    print('{"runtime": "%s", "calls": %d, "fixed_is_viper": %s, "us_per_call": {%s}, "bytes_per_call": {%s}}' % (
        sys.implementation.name, CALLS, "true" if fixedatt.HAS_ACCEL else "false",
        ", ".join('"%s": %.2f' % (k, (best[k] - loop) / CALLS) for k in names),
        ", ".join('"%s": %.1f' % (k, (nbytes[k] - nbytes["loop"]) / CALLS) for k in names)))


def _child(name, calls):
    variants, fixed = _variants()
    for vname, fn, floats in variants:
        if vname == name:
            if floats is not None:
                for fx in fixed:
                    fx.angle_floats = floats
            for n in range(calls):
                fn(n)
                if n & 15 == 15:  # as the rp2 main loop collects (bench/rc_instructions.py): with no collection
                    collect_garbage()  # the allocator's search through the float garbage is most of the count


def count():
    """Instructions a call of each variant executes under callgrind (less the loop's), MicroPython."""
    import json
    import os

    from core_instructions import _count, micropython_vm

    here = os.path.dirname(os.path.abspath(__file__))
    mp = micropython_vm()
    env = dict(os.environ, MICROPYPATH="%s:%s" % (os.path.join(os.path.dirname(here), "src"), here))
    cmd = [mp, "-X", "heapsize=8m", os.path.abspath(__file__), "--child"]
    calls = 400
    # the variants' set-up is the same in every run: the difference is the calls alone
    base = _count(cmd + ["loop", str(calls)], env)
    ir = {}
    for name in ("float", "fixed", "fixed_floats", "fixed_sum"):
        ir[name] = round((_count(cmd + [name, str(calls)], env) - base) / calls)
    print(json.dumps({"runtime": "micropython", "calls": calls, "ir_per_call": ir}))


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--child":
        _child(sys.argv[2], int(sys.argv[3]))
    elif len(sys.argv) == 2 and sys.argv[1] == "--count":
        count()
    else:
        main()
