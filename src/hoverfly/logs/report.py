"""`hoverfly log report`: every plot of a flight log plus an index.html that ties them together.

The page holds the log's summary (system, duration, topics and their rates, dropouts,
warnings of a partial read), the log messages (arming, failsafe, modes), the parameters
that differ from hoverfly's defaults and their changes in flight, the step-response numbers
per step (logs/steps.py: the same measurement as `hoverfly fly`), and the PNGs of `hoverfly.logs.plot`.
"""

import html
import json
import os

from hoverfly.logs import analysis, plot
from hoverfly.logs.data import params_table
from hoverfly.logs.steps import describe


def _table(headers, rows):
    out = ["<table><tr>" + "".join("<th>%s</th>" % html.escape(str(h)) for h in headers) + "</tr>"]
    for r in rows:
        cells = "".join("<td>%s</td>" % html.escape("" if c is None else str(c)) for c in r)
        out.append("<tr>" + cells + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def _gyro_filters(log):
    """The gyro filters' section: their delay at 100 Hz per axis, and what they did to the motors' peaks."""
    out = ["<h2>Gyro filters</h2>"]
    delays = [analysis.filter_delay_ms(log, 100.0, axis) for axis in range(3)]
    out.append("<p>Group delay of the gyro filter chain at 100 Hz (from the log's filter parameters, with the RPM "
               "filter's and the dynamic notch's notches where they sat): roll %.2f ms, pitch %.2f ms, yaw %.2f ms."
               "</p>" % tuple(delays))
    found = analysis.notch_frequencies(log)
    if found is None:
        out.append("<p>No motor frequencies in this log (hoverfly_notch: bidirectional DShot off and no dynamic "
                   "notch): the RPM filter's effect cannot be measured.</p>")
        return out
    if found["motor_hz"]:
        out.append("<p>Motors' median rotation frequency (eRPM): %s Hz. RPM filter notches: %s.</p>" % (
            ", ".join("%.1f" % hz for hz in found["motor_hz"]),
            ", ".join("%.1f" % hz for hz, _ in found["rpm_notches_hz"]) or "none (rpm_harmonics 0, or below "
            "rpm_min_hz)"))
    dyn = ["%s %s" % (analysis.AXES[a], ", ".join("%.1f Hz" % hz for hz in found["dyn_notch_hz"][a]))
           for a in range(3) if found["dyn_notch_hz"][a]]
    if dyn:
        out.append("<p>Dynamic notches (median centre while on): %s.</p>" % html.escape("; ".join(dyn)))
    rows = analysis.motor_peak_attenuation(log)
    if rows:
        out.append("<p>The motors' peaks in the gyro while they turned: raw against filtered at the motors' median "
                   "frequency and its harmonics (nearest spectrum bin).</p>")
        out.append(_table(("axis", "frequency (Hz)", "raw (deg/s)", "filtered (deg/s)", "filtered / raw (dB)"),
                          [(a, hz, "%.4f" % r, "%.4f" % f, db) for a, hz, r, f, db in rows]))
    return out


def write_report(log, out_dir):
    """Write plots and index.html into out_dir; returns {"index": path, "plots": [...], "steps": [...],
    "axes": [...]} (each step as `hoverfly fly --json` gives it, plus its time in the log)."""
    os.makedirs(out_dir, exist_ok=True)
    found = analysis.log_steps(log)
    written = []
    for name, fn, title in plot.PLOTS:
        path = os.path.join(out_dir, name + ".png")
        p = fn(log, path, found) if name == "step_response" else fn(log, path)
        if p is not None:
            written.append((name, title, p))
    s = log.summary
    steps = [analysis.public(st) for st in found]
    axes = analysis.axis_summary(found)
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>hoverfly log report: %s</title>"
        % html.escape(os.path.basename(log.path)),
        "<style>body{font-family:sans-serif;margin:1.5em;max-width:1100px}table{border-collapse:collapse;"
        "margin:0.5em 0}td,th{border:1px solid #ccc;padding:2px 8px;font-size:90%}th{background:#eee}"
        "img{max-width:100%;border:1px solid #ddd;margin:0.5em 0}.warn{color:#a40}</style></head><body>",
        "<h1>Flight log %s</h1>" % html.escape(os.path.basename(log.path)),
        "<p>%s, %s, software %s; %.2f s logged.</p>" % (
            html.escape(str(log.info.get("sys_name", "?"))), html.escape(str(log.info.get("ver_hw", "?"))),
            html.escape(str(log.info.get("ver_sw", "?"))), s["duration_s"]),
    ]
    for w in s["warnings"]:
        parts.append("<p class='warn'>warning: %s</p>" % html.escape(w))
    parts.append("<h2>Topics</h2>")
    parts.append(_table(("topic", "samples", "rate (Hz)"),
                        [(t["name"], t["samples"], "%.1f" % t["rate_hz"]) for t in s["topics"]]))
    if s["dropouts"]:
        parts.append("<p class='warn'>%d dropouts, %d ms of data lost.</p>"
                     % (len(s["dropouts"]), sum(d["duration_ms"] for d in s["dropouts"])))
    parts.append("<h2>Messages</h2>")
    parts.append(_table(("time (s)", "level", "text"),
                        [("%.3f" % ((m["timestamp_us"] - log.start_us) * 1e-6), m["level"], m["text"])
                         for m in s["messages"]]))
    parts.append("<h2>Step response</h2>")
    parts.append("<p>%s</p>" % html.escape(describe()))
    if steps:
        parts.append(_table(("time (s)", "axis", "mode", "from", "to", "unit", "rise 10-90 % (ms)", "90 % at (ms)",
                             "overshoot (%)", "settle ±5 % (ms)", "steady error"),
                            [(st["t_s"], st["axis"], st["mode"], st["from"], st["to"], st["unit"], st["rise_ms"],
                              st["t90_ms"], st["overshoot_pct"], st["settle_ms"], st["steady_error"])
                             for st in steps]))
        parts.append(_table(("axis", "mode", "steps", "mean rise (ms)", "mean 90 % at (ms)", "mean settle (ms)",
                             "largest overshoot (%)"),
                            [(a["axis"], a["mode"], a["steps"], a["rise_ms"], a["t90_ms"], a["settle_ms"],
                              a["overshoot_pct"]) for a in axes]))
    else:
        parts.append("<p>No held stick step in this log (a stick moved at once by %d us or more and held for "
                     "%.1f s): nothing to measure.</p>" % (analysis.MIN_STEP_US, analysis.MIN_HOLD_S))
    parts.extend(_gyro_filters(log))
    changed = [r for r in params_table(log) if r[4]]
    parts.append("<h2>Parameters that differ from the defaults</h2>")
    parts.append(_table(("name", "value", "default", "unit", ""), changed) if changed else "<p>none</p>")
    if log.changed_params:
        parts.append("<h2>Parameter changes in flight</h2>")
        parts.append(_table(("time (s)", "name", "value"),
                            [("%.3f" % ((t - log.start_us) * 1e-6), k, v) for t, k, v in log.changed_params]))
    parts.append("<h2>Plots</h2>")
    for name, title, p in written:
        parts.append("<h3>%s</h3><img src='%s' alt='%s'>"
                     % (html.escape(title), html.escape(os.path.basename(p)), html.escape(name)))
    parts.append("</body></html>")
    index = os.path.join(out_dir, "index.html")
    with open(index, "w") as f:
        f.write("\n".join(parts))
    with open(os.path.join(out_dir, "steps.json"), "w") as f:
        json.dump({"method": describe(), "steps": steps, "axes": axes}, f, indent=1)
    return {"index": index, "plots": [p for _, _, p in written], "steps": steps, "axes": axes}
