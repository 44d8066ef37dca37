"""The cost of core/config/params.check on the configuration links' path (never the flight pass).

A CLI `set`, an MSP or maintenance write and each entry of the storage load go through check(): a
valid value, a hostile one (inf, NaN, a huge int, text), and an unknown name with its "did you mean"
(the edit-distance search over the table, the costliest case). On a Pico the links task runs between
passes, so these figures say how long one mistyped line can hold the loop.

Run: `.venv/bin/python bench/param_check.py` or
`MICROPYPATH=src .venv/bin/micropython -X heapsize=512k bench/param_check.py`. Prints one JSON object
with microseconds per call for each case (the host is shared: compare runs taken side by side).
"""

import sys

try:
    from time import ticks_diff, ticks_us
except ImportError:  # CPython
    import time

    def ticks_us():
        return int(time.perf_counter() * 1e6)

    def ticks_diff(a, b):
        return a - b

from hoverfly.core.config.params import check

ROUNDS = 20
CASES = (
    ("valid", (("p_roll", "55"), ("motor_idle_pct", 6.5), ("mixer_type", "hexx"), ("failsafe_delay", "4"))),
    ("hostile", (("p_roll", float("inf")), ("d_roll", float("nan")), ("failsafe_delay", 1e308),
                 ("loop_hz", 10 ** 400), ("p_roll", "1e400"), ("p_roll", None))),
    ("unknown_name", (("p_rol", 1), ("gyro_lpf_hz", 1), ("failsafe_procedur", "drop"), ("abcdefghijklmnop", 1))),
)


def main():
    out = {"runtime": sys.implementation.name, "rounds": ROUNDS}
    for label, items in CASES:
        t0 = ticks_us()
        for _ in range(ROUNDS):
            for name, value in items:
                check(name, value)
        out[label + "_us_per_call"] = round(ticks_diff(ticks_us(), t0) / (ROUNDS * len(items)), 1)
    text = "{" + ", ".join('"%s": %s' % (k, ('"%s"' % v) if isinstance(v, str) else v) for k, v in
                           sorted(out.items())) + "}"
    print(text)


main()
