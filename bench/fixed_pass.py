"""Cost of the fixed-point stages alone: the controller + mixer (`FixedRate.update`) and the IMU
filters (`FixedImuFilter.update`), on bench/core_loop.py's armed flight (angle mode, its gains).

Each stage is called in a loop of `calls` with the flight's own signals, three gyro samples in turn
(copied in between batches, untimed), the GC off; the figure is the best of `runs` batches, less an
empty loop's cost. Prints one JSON object: {runtime, calls, rate_us, rate_bytes, imu_us, imu_bytes}.

    MICROPYPATH=src .venv/bin/micropython -X heapsize=1m bench/fixed_pass.py
    MICROPYPATH=src .venv/bin/micropython -X heapsize=1m bench/fixed_pass.py --count 10000

`--count N` makes N calls of each stage and prints nothing else: for instruction counts, run it under
callgrind at two N and divide the difference (`valgrind --tool=callgrind --callgrind-out-file=/dev/null`
prints the total; the pass's figure is (Ir(N2) - Ir(N1)) / (N2 - N1) for both stages together, or use
`--only rate` / `--only imu`).
"""

import sys

from core_loop import armed_flight
from hoverfly.compat import (
    IS_MICROPYTHON,
    collect_garbage,
    disable_gc,
    enable_gc,
    mem_alloc,
    ticks_diff,
    ticks_us,
)


def _gyros(f):
    g = f.signals.gyro_rad_s
    return ((g[0], g[1], g[2]), (g[0] + 0.01, g[1] - 0.02, g[2]), (g[0] - 0.005, g[1], g[2] + 0.015))


def _rate_loop(n, fixed, sp, att, i_active, airmode):
    for _ in range(n):
        fixed.update(sp, 1000, i_active, airmode)


def _imu_loop(n, imu, sp, att, i_active, airmode):
    for _ in range(n):
        imu.update()


def _empty_loop(n, stage, sp, att, i_active, airmode):
    for _ in range(n):
        pass


def _time(loop, args, calls, runs):
    """Best µs of `runs` batches of `calls` calls, and the bytes of the last batch. The calls run in a plain
    loop: a closure around the call would take its frame from the heap on every call (its cells and the call's
    stack pass 11 words), which on the bench flight's heap costs more than the stage."""
    best = None
    nbytes = 0
    for _ in range(runs):
        collect_garbage()
        disable_gc()
        a0 = mem_alloc()
        t0 = ticks_us()
        loop(calls, *args)
        t1 = ticks_us()
        nbytes = mem_alloc() - a0
        enable_gc()
        d = ticks_diff(t1, t0)
        if best is None or d < best:
            best = d
    return best, nbytes


def main():
    args = sys.argv[1:]
    count = 0
    only = ""
    if "--count" in args:
        count = int(args[args.index("--count") + 1])
    if "--only" in args:
        only = args[args.index("--only") + 1]
    board, f, t = armed_flight()
    assert f._fixed_on and f._fixed_imu_on, "the fixed stages are not on (pid_math, viper twins)"
    s = f.signals
    sp = s.setpoint
    att = s.attitude
    fixed = f.fixed
    imu = f.fixed_imu
    i_active = f.commander.i_active
    airmode = f.commander.airmode_active

    if count:
        collect_garbage()
        if only != "imu":
            for _ in range(count):
                fixed.update(sp, 1000, i_active, airmode)
        if only != "rate":
            for _ in range(count):
                imu.update()
        return
    calls = 2000 if IS_MICROPYTHON else 20000
    runs = 15
    res = {}
    for name, loop, stage in (("rate", _rate_loop, fixed), ("imu", _imu_loop, imu), ("empty", _empty_loop, None)):
        args = (stage, sp, att, i_active, airmode)
        us = None
        nbytes = 0
        for g in _gyros(f):
            s.gyro_rad_s[0], s.gyro_rad_s[1], s.gyro_rad_s[2] = g
            s.gyro_raw_rad_s[0], s.gyro_raw_rad_s[1], s.gyro_raw_rad_s[2] = g
            d, b = _time(loop, args, calls, runs // 3)
            us = d if us is None or d < us else us
            nbytes += b
        res[name] = (us, nbytes)
    e = res["empty"][0]
    runtime = "micropython" if IS_MICROPYTHON else "cpython"
    print('{"runtime": "%s", "calls": %d, "rate_us": %.3f, "rate_bytes": %.1f, "imu_us": %.3f, "imu_bytes": %.1f}'
          % (runtime, calls, (res["rate"][0] - e) / calls, res["rate"][1] / (3 * calls),
             (res["imu"][0] - e) / calls, res["imu"][1] / (3 * calls)))


if __name__ == "__main__":
    main()
    sys.stdout.flush()
