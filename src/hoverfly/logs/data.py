"""A ULog file as numpy arrays: what plots, reports, CSV export and replay read.

`load(path)` gives a `FlightLog`: topics as {name: {field: ndarray}} (pyulog's flattened field
names, `timestamp` in µs, plus `t_s` from the log's start), the parameters in hoverfly's own
terms (choice parameters back to their words), their changes, the log strings and the
warnings of a partial read. Works on any ULog (PX4's too); hoverfly-specific helpers return
None when a topic is missing. Raises only LogReadError (a UserError) for unreadable files.
"""

import numpy as np

from hoverfly.core.config.params import PARAMS, row
from hoverfly.logs.ulogread import LogReadError, open_ulog, summarise

AXES = ("roll", "pitch", "yaw")


def param_from_ulog(name, value):
    """A logged parameter value back in hoverfly's terms: a choice index to its word, a float32
    to the shortest decimal that gives the same float32 (so 0.1 comes back as 0.1)."""
    r = row(name)
    if hasattr(value, "item"):
        value = value.item()
    if r is None:
        return value
    default = r[1]
    if isinstance(default, str):
        choices = r[4]
        if isinstance(value, int) and 0 <= value < len(choices):
            return choices[value]
        return default
    if isinstance(default, float):
        return float("%.7g" % float(value))
    return int(value)


class FlightLog:
    def __init__(self, path, ulog, warnings):
        self.path = str(path)
        self.ulog = ulog
        self.summary = summarise(ulog, warnings)
        self.warnings = self.summary["warnings"]
        self.start_us = int(ulog.start_timestamp)
        self.topics = {}
        for d in ulog.data_list:
            if d.multi_id != 0 or "timestamp" not in d.data:
                continue
            fields = dict(d.data)
            fields["t_s"] = (fields["timestamp"].astype(np.int64) - self.start_us) * 1e-6
            self.topics[d.name] = fields
        self.params_raw = dict(ulog.initial_parameters)
        self.params = {k: param_from_ulog(k, v) for k, v in self.params_raw.items()}
        self.changed_params = [(int(t), k, param_from_ulog(k, v)) for t, k, v in ulog.changed_parameters]
        self.messages = self.summary["messages"]
        self.info = self.summary["info"]

    @property
    def is_hoverfly(self):
        return str(self.info.get("sys_name", "")) == "hoverfly"

    def topic(self, name):
        return self.topics.get(name)

    def field(self, topic, name):
        t = self.topics.get(topic)
        if t is None:
            return None
        return t.get(name)

    def vector(self, topic, base, n):
        """Array fields base[0..n-1] as an (samples, n) array, or None."""
        t = self.topics.get(topic)
        if t is None:
            return None
        cols = []
        for i in range(n):
            c = t.get("%s[%d]" % (base, i))
            if c is None:
                return None
            cols.append(c)
        return np.stack(cols, axis=1)

    def rate_hz(self, topic):
        for t in self.summary["topics"]:
            if t["name"] == topic and t["multi_id"] == 0:
                return t["rate_hz"]
        return 0.0

    def motor_count(self):
        n = self.info.get("hoverfly_motor_count")
        if isinstance(n, int) and 0 < n <= 16:
            return n
        no = self.field("actuator_outputs", "noutputs")
        if no is not None and len(no):
            return int(max(1, min(16, no[-1])))
        return 4

    def param(self, name, default=None):
        return self.params.get(name, default)


def load(path, topics=None):
    """Read `path` into a FlightLog. Raises LogReadError only."""
    ulog, warnings = open_ulog(path, topics)
    try:
        return FlightLog(path, ulog, warnings)
    except LogReadError:
        raise
    except Exception as exc:  # noqa: BLE001 - damaged content pyulog let through
        raise LogReadError("%s: ULog file too damaged to use (%s)" % (path, type(exc).__name__)) from None


def params_table(log):
    """(name, value, default, unit, note) rows: hoverfly's table order first, then unknown names."""
    rows = []
    seen = set()
    for r in PARAMS:
        name = r[0]
        if name in log.params:
            unit = r[4] if isinstance(r[4], str) else "|".join(r[4])
            rows.append((name, log.params[name], r[1], unit, "" if log.params[name] == r[1] else "changed"))
            seen.add(name)
    for name in sorted(log.params):
        if name not in seen:
            rows.append((name, log.params[name], None, "", "not a hoverfly parameter"))
    return rows
