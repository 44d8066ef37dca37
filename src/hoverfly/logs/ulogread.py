"""Read a ULog file with pyulog and summarise it; bad user files become one-line LogReadError.

Takes a path (a hoverfly log, a PX4 log, or whatever the user pointed at). Gives either the
pyulog `ULog` object (`open_ulog`, for plots, reports and replay) or a plain summary dict
(`read_summary`): topics with sample counts and rates, info, parameters and their changes,
log strings, dropouts, duration, pyulog's file_corruption flag and the warnings pyulog
printed. Host-side only (CPython, numpy through pyulog).

pyulog raises on a bad header or an unknown incompatible flag, prints (to stdout) when it
skips corrupt data, and can trip over its own numpy conversion on corrupted formats. All of
that is caught here: a file that cannot be read at all is a `LogReadError` (a UserError, so
the CLI prints one line); a file read in part comes back with `file_corruption` and
`warnings` set. Nothing else escapes for any bytes on disk.
"""

import contextlib
import io
import os

from hoverfly.errors import UserError

_LEVELS = {
    0x30: "emergency",
    0x31: "alert",
    0x32: "critical",
    0x33: "error",
    0x34: "warning",
    0x35: "notice",
    0x36: "info",
    0x37: "debug",
}


class LogReadError(UserError):
    """A log file that cannot be read: missing, not ULog, or damaged beyond reading."""


def open_ulog(path, topics=None):
    """Parse `path` with pyulog; returns (ULog, warnings list). Raises LogReadError only.

    `topics`: optional list of topic names to load (pyulog's message_name_filter_list).
    """
    try:
        from pyulog import ULog
        from pyulog.exceptions import ULogException
    except ImportError as exc:  # pragma: no cover - pyulog is a declared dependency
        raise LogReadError("reading ULog needs pyulog (%s)" % exc) from None
    name = os.fspath(path)
    try:
        handle = open(name, "rb")  # noqa: SIM115 - pyulog closes it
    except OSError as exc:
        raise LogReadError("%s: cannot open (%s)" % (name, exc.strerror or exc)) from None
    printed = io.StringIO()
    try:
        with contextlib.redirect_stdout(printed):
            ulog = ULog(handle, topics, disable_str_exceptions=True)
    except ULogException as exc:
        raise LogReadError("%s: not a readable ULog file (%s)" % (name, exc)) from None
    except (MemoryError, RecursionError) as exc:
        raise LogReadError("%s: ULog file too damaged to read (%s)" % (name, type(exc).__name__)) from None
    except Exception as exc:  # noqa: BLE001 - any pyulog failure on user bytes is a read error
        raise LogReadError(
            "%s: ULog file too damaged to read (%s: %s)" % (name, type(exc).__name__, _one_line(exc))
        ) from None
    finally:
        handle.close()
    warnings = [line.strip() for line in printed.getvalue().splitlines() if line.strip()]
    cut = framing_end(name)
    if cut is not None:
        warnings.append("file ends inside a message at byte %d of %d (cut off?): read up to the last whole "
                        "message" % cut)
    return ulog, warnings


def framing_end(path):
    """(offset of the unfinished message, file size) when the file ends inside a message, else None.

    Walks the message headers only (u16 size, u8 type); pyulog reads such a file silently.
    """
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError:
        return None
    n = len(data)
    off = 16
    if n < off:
        return None
    while off + 3 <= n:
        size = data[off] | (data[off + 1] << 8)
        if off + 3 + size > n:
            return off, n
        off += 3 + size
    if off != n:
        return off, n
    return None


def _one_line(exc):
    text = str(exc).splitlines()
    return text[0][:200] if text else ""


def _plain(value):
    """numpy scalars and bytes to JSON-friendly Python values."""
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, bytes):
        return value.hex()
    return value


def summarise(ulog, warnings=()):
    """Summary dict of a parsed ULog (see read_summary)."""
    topics = []
    for d in ulog.data_list:
        t = d.data.get("timestamp")
        n = 0 if t is None else len(t)
        first_us = int(t[0]) if n else 0
        last_us = int(t[-1]) if n else 0
        span_s = (last_us - first_us) * 1e-6
        topics.append(
            {
                "name": d.name,
                "multi_id": d.multi_id,
                "msg_id": d.msg_id,
                "samples": n,
                "rate_hz": (n - 1) / span_s if n > 1 and span_s > 0 else 0.0,
                "first_us": first_us,
                "last_us": last_us,
                "fields": [f.field_name for f in d.field_data],
            }
        )
    topics.sort(key=lambda x: (x["name"], x["multi_id"]))
    start_us = int(ulog.start_timestamp)
    last_us = int(ulog.last_timestamp)
    out_warnings = list(warnings)
    if ulog.file_corruption:
        out_warnings.append("file corruption detected: some data may be missing")
    return {
        "start_us": start_us,
        "last_us": last_us,
        "duration_s": max(0, last_us - start_us) * 1e-6,
        "file_corruption": bool(ulog.file_corruption),
        "topics": topics,
        "info": {k: _plain(v) for k, v in ulog.msg_info_dict.items()},
        "params": {k: _plain(v) for k, v in ulog.initial_parameters.items()},
        "changed_params": [(int(t), k, _plain(v)) for t, k, v in ulog.changed_parameters],
        "messages": [
            {
                "timestamp_us": int(m.timestamp),
                "level": _LEVELS.get(m.log_level, "unknown"),
                "text": m.message,
            }
            for m in ulog.logged_messages
        ],
        "dropouts": [
            {"timestamp_us": int(o.timestamp), "duration_ms": int(o.duration)} for o in ulog.dropouts
        ],
        "warnings": out_warnings,
    }


def read_summary(path, topics=None):
    """Open `path` and summarise it. Raises LogReadError only.

    Keys: start_us, last_us, duration_s, file_corruption, topics (name, multi_id, msg_id,
    samples, rate_hz, first_us, last_us, fields), info, params, changed_params
    ((timestamp_us, name, value) as pyulog stamps them: the last sample's time), messages
    (timestamp_us, level, text), dropouts, warnings.
    """
    ulog, warnings = open_ulog(path, topics)
    try:
        return summarise(ulog, warnings)
    except Exception as exc:  # noqa: BLE001 - damaged content pyulog let through
        raise LogReadError(
            "%s: ULog file too damaged to summarise (%s: %s)"
            % (os.fspath(path), type(exc).__name__, _one_line(exc))
        ) from None
