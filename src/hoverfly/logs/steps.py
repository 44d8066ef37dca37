"""The one step-response measurement: `hoverfly fly`, `hoverfly log report` and `log replay` all use it.

A step is a stick moved at once and then held: a rate step in acro (the set point is deg/s, the
response the gyro), an angle step in angle or horizon mode (deg, the estimated attitude). Measured
in the time domain on the step itself, from the level before (`start`) to the level asked for
(`target`), over the window until the next step, mode change or stick move:

- rise: 10 % to 90 % of the span; t90: from the step to 90 %
- overshoot: the peak past the target, % of the span
- settle: from the step until the response stays within ±5 % of the span around the target
- steady error: target minus the mean response over the last fifth of the window

Plain Python on purpose (no numpy): the simulator's runner measures every pass with it while it
flies, the log tools on the logged samples. The simulator measures against the scenario's command
on the physics; a log holds the set point the controller got and the filtered gyro (or estimated
attitude) at blackbox_rate_hz, so the two differ by the stick's quantisation on the receiver link
(an 11-bit CRSF channel: 400 deg/s asked, 399.4 flown), by the frame's latency (up to one frame
period later in the log) and by the gyro filter's noise and delay; tests/test_logs.py holds them
to the tolerances in docs/logs.md.
"""

SETTLE_BAND = 0.05  # ±5 % of the span: the usual settling band


def measure_step(samples, start, target):
    """samples: [(t_s from the step, value)] in the set point's unit. Returns the figures (None where
    the response never got there within the window)."""
    a = target - start
    span = abs(a) if a != 0 else 1.0
    sign = 1.0 if a >= 0 else -1.0
    t10 = t90 = None
    peak = -1e9
    for t, v in samples:
        frac = (v - start) * sign / span
        if t10 is None and frac >= 0.1:
            t10 = t
        if t90 is None and frac >= 0.9:
            t90 = t
        if frac > peak:
            peak = frac
    settle = None
    band = SETTLE_BAND * span
    for t, v in reversed(samples):
        if abs(v - target) > band:
            settle = t
            break
    if settle is None:
        settle = 0.0
    elif samples and settle >= samples[-1][0]:
        settle = None  # never settled within the window
    n_tail = max(1, len(samples) // 5)
    tail = samples[-n_tail:]
    steady = sum(target - v for _, v in tail) / len(tail) if tail else None
    return {
        "rise_ms": None if (t10 is None or t90 is None) else round((t90 - t10) * 1000.0, 1),
        "t90_ms": None if t90 is None else round(t90 * 1000.0, 1),
        "overshoot_pct": round(max(0.0, (peak - 1.0) * 100.0), 2) if samples else None,
        "settle_ms": None if settle is None else round(settle * 1000.0, 1),
        "steady_error": None if steady is None else round(steady, 3),
    }


def _ms(v):
    return "-" if v is None else "%g ms" % v


def step_line(s):
    """One step as `hoverfly fly`, `log report` and `log replay` print it."""
    unit = "deg/s" if s["unit"] == "dps" else s["unit"]
    return ("step %s %s %g -> %g %s%s: rise %s, 90%% at %s, overshoot %s, settle %s, steady error %s"
            % (s["axis"], s["mode"], s["from"], s["to"], unit, " at %.2f s" % s["t_s"] if "t_s" in s else "",
               _ms(s["rise_ms"]), _ms(s["t90_ms"]),
               "-" if s["overshoot_pct"] is None else "%.1f %%" % s["overshoot_pct"], _ms(s["settle_ms"]),
               "-" if s["steady_error"] is None else "%.2f %s" % (s["steady_error"], unit)))


def describe():
    """One sentence for reports: how the figures were measured."""
    return ("Measured on each commanded step (a stick moved at once and held): rise 10-90 %% of the step, "
            "90 %% at = from the stick's move to 90 %%, overshoot past the set point in %% of the step, "
            "settle = until the response stays within ±%d %% of the step, steady error = set point minus "
            "the mean of the window's last fifth. Acro steps: set point against gyro (deg/s); angle steps: "
            "angle set point against the attitude estimate (deg)." % round(SETTLE_BAND * 100))
