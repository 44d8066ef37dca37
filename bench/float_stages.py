"""The flight core's float stages on CPython, one at a time: what each costs a call in a hovering 5-inch.

Flies the 5-inch hover (the default path: the native twins where built, or the .py files with --python),
then calls each stage of the pass on the flight's own state and signals, best of 7 rounds, the empty call's
cost taken off. Prints one JSON object: us_per_call per stage, native (how many modules ran compiled).

    .venv/bin/python bench/float_stages.py [--calls 50000] [--python]

The stages keep their state between calls (the PID integrates, the filters move), as they do in flight: the
figures are for comparing versions of a stage or the twins with the .py files (alternate the runs), not a
flight's share; bench/sim_rtf.py gives where a step's time goes.
"""

import json
import os
import sys
import time

if "--python" in sys.argv:  # before hoverfly is imported: it installs the twins' finder at import
    os.environ["HOVERFLY_NATIVE"] = "0"

from hoverfly import nativeenv  # noqa: E402
from hoverfly.sim.runner import SimRun  # noqa: E402


def _best_ns(fn, calls, rounds=7):
    clock = time.perf_counter_ns
    best = None
    for _ in range(rounds):
        t0 = clock()
        for _ in range(calls):
            fn()
        ns = (clock() - t0) / calls
        best = ns if best is None or ns < best else best
    return best


def main():
    calls = int(sys.argv[sys.argv.index("--calls") + 1]) if "--calls" in sys.argv else 50000
    run = SimRun("5inch", "hover", 1, duration_s=3.0)
    run.run()
    fl = run.flight
    s = fl.signals
    sp = fl._sp
    c = fl.controller
    stages = {
        "controller": lambda: c.update(sp, s.attitude, s.gyro_rad_s, 0.001, True, False, s.torque_norm),
        "pid_roll": lambda: c.roll.update(0.1, 0.05, 0.001, 1.0, True, False),
        "pid_yaw": lambda: c.yaw.update(0.1, 0.05, 0.001, 1.0, True, False),
        "mixer": lambda: fl.mixer.update(sp.throttle_norm, s.torque_norm, True, s.motor_norm),
        "control_float": lambda: fl._control_float(1000, sp),
        "rc": lambda: fl.rc.update(sp),
        "commander": lambda: fl.commander.update(sp, fl._last_us),
        "estimate": lambda: fl._estimate(1000),
        "gyro_filter": lambda: fl.gyro_filter.update(s.gyro_raw_rad_s, fl.calibration.bias_rad_s, s.gyro_rad_s),
        "accel_filter": lambda: fl.accel_filter.update(s.accel_raw_m_s2, s.accel_m_s2),
    }
    empty = _best_ns(lambda: None, calls)
    out = {name: round((_best_ns(fn, calls) - empty) / 1000.0, 3) for name, fn in stages.items()}
    native = len(nativeenv.report().get("native", ()))
    print(json.dumps({"mode": sp.mode, "calls": calls, "native_modules": native, "us_per_call": out}))


if __name__ == "__main__":
    main()
