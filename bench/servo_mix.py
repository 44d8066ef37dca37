"""The servo mixer's pass (ServoMixer.update, armed) per call: µs and heap bytes, for the airplane preset (3 rules),
the flying wing's (4 rules) and a full 8-rule table with speed limits, the roll command changing every pass. On
MicroPython the kernel is its generated viper twin (accel/servos.py: run `python -m hoverfly.fastgen` first),
without it the Python kernel.
Prints one JSON object; every figure is the best of RUNS batches (the host is shared and noisy).

    .venv/bin/python bench/servo_mix.py
    MICROPYPATH=src:.frozen .venv/bin/micropython -X heapsize=384k bench/servo_mix.py
    .venv/bin/python bench/servo_mix.py --passes 200   # a quick run (PASSES: 2000 on MicroPython, else 20000)
"""

import json
import sys
from array import array

from hoverfly.compat import IS_MICROPYTHON, collect_garbage, disable_gc, enable_gc, mem_alloc, ticks_diff, ticks_us
from hoverfly.core.config.params import Params
from hoverfly.core.stages.servos import ServoMixer

RUNS = 7
PASSES = 2000 if IS_MICROPYTHON else 20000
if "--passes" in sys.argv:  # a short run checks that the bench still runs; figures need the default
    PASSES = int(sys.argv[sys.argv.index("--passes") + 1])


def _mixer(frame, rules=0):
    p = Params()
    p.set("mixer_type", frame)
    for i in range(rules):
        p.update([("smix%d_servo" % i, i % 4), ("smix%d_input" % i, i % 12), ("smix%d_rate" % i, 50),
                  ("smix%d_speed" % i, 100)])
    m = ServoMixer()
    m.configure(p)
    return m


def _batch(m, passes):
    """µs and bytes of `passes` update calls, the roll and pitch commands changing every pass."""
    tq = array("f", [0.1, -0.2, 0.05])
    m.bind(tq, array("H", [1500] * 18), array("H", [1500] * 8))
    update = m.update
    collect_garbage()
    disable_gc()
    a0 = mem_alloc()
    t0 = ticks_us()
    for k in range(passes):
        tq[0] = 0.1 if k & 1 else 0.12  # a constant float: no float made by the bench itself
        update(1000, True, 0.5)
    t1 = ticks_us()
    a1 = mem_alloc()
    enable_gc()
    return ticks_diff(t1, t0), a1 - a0


def main():
    result = {"runtime": "micropython" if IS_MICROPYTHON else "cpython", "passes": PASSES}
    for name, m in (("airplane", _mixer("airplane")), ("flying_wing", _mixer("flying_wing")),
                    ("rules8_speed", _mixer("airplane", 8))):
        best_us = None
        best_b = None
        for _ in range(RUNS):
            us, nbytes = _batch(m, PASSES)
            best_us = us if best_us is None or us < best_us else best_us
            best_b = nbytes if best_b is None or nbytes < best_b else best_b
        result[name] = {"rules": m.rules, "us_per_pass": round(best_us / PASSES, 3),
                        "bytes_per_pass": round(best_b / PASSES, 1)}
    print(json.dumps(result))


if __name__ == "__main__" or sys.implementation.name == "micropython":
    main()
