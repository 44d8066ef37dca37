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

Reading always ends, in time bounded by the file's size (issue 30: pyulog 1.3 hung on 46 of
37 505 mutated logs). pyulog reads through `_BoundedFile`, not the file itself:
- pyulog steps over a corrupt header by reading its claimed payload and seeking back
  `2 + size` bytes, one byte past the header. Near the end of the file that read comes back
  short, the seek lands before the header and the same bytes are read again forever. Here a
  read advances the position by what was asked, as pyulog assumes, so the step is one byte.
- Whatever else pyulog's recovery does, `_BoundedFile` counts its reads and seeks (a 64 KB
  read as two calls: the copy costs about as much as a call) and past CALLS_PER_BYTE per byte
  of the file (plus CALLS_FLOOR) answers end-of-file, so pyulog ends with what it has and the
  reader says where it stopped. A byte-by-byte walk through garbage with no sync to jump to
  takes 3 calls a byte (a run of zeros), a clean log under 1; 37 505 mutated simulator logs
  took at most 0.25 and none was stopped (tests/test_log_reader_fuzz.py, bench/fuzz.py).
- A subscription flattens its format (nested formats, arrays) into one field per value.
  A format of more than MAX_FIELDS values can never fit a data message (65 535 bytes, at
  least one each) and nesting can make it exponential; such a subscription is refused as
  corrupt (pyulog skips it and reads on), and all subscriptions together get at most
  MAX_TOTAL_FIELDS.
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


CALLS_PER_BYTE = 16  # reads and seeks pyulog may make per byte of the file
CALLS_FLOOR = 1 << 20  # and this many more, whatever the size
MAX_FIELDS = 65533  # values in one format: a data message holds 65 535 bytes, 2 of them the msg_id
MAX_TOTAL_FIELDS = 1 << 19  # all subscriptions together: pyulog builds objects at ~3 µs a value
# (a PX4 log holds some 30 000 values in all its subscriptions, hoverfly's fewer than 2 000)
MAX_WARNINGS = 20
MAX_NESTING = 32  # formats inside formats (PX4 nests two or three deep)


class _BoundedFile:
    """A log's bytes as the file object pyulog reads, with its calls counted and bounded.

    `read(n)` moves the position on by n even where the file ends first (pyulog seeks back
    from where a whole read would have left it); a negative seek target is a ValueError
    (pyulog counts that as corruption and reads on). Once `calls` passes `budget` every read
    is end-of-file and `stopped_at` says where.
    """

    def __init__(self, data, budget):
        self._data = data
        self._pos = 0
        self.calls = 0
        self.budget = budget
        self.stopped_at = -1
        # A relative seek or tell made past the end, where a plain file would have stopped at the end: from
        # then on pyulog reads this file differently from the plain one (on purpose: that is the hang's fix).
        self.past_end_used = False

    def read(self, n=-1):
        pos = self._pos
        if n is None or n < 0:
            n = max(0, len(self._data) - pos)
        self.calls += 1 + (n >> 16)
        if self.calls > self.budget:
            if self.stopped_at < 0:
                self.stopped_at = min(pos, len(self._data))
            return b""
        self._pos = pos + n
        return self._data[pos : pos + n]

    def seek(self, offset, whence=0):
        self.calls += 1
        if whence == 1:
            if self._pos > len(self._data):
                self.past_end_used = True
            offset += self._pos
        elif whence == 2:
            offset += len(self._data)
        if offset < 0:
            raise ValueError("negative seek position %d" % offset)
        self._pos = offset
        return offset

    def tell(self):
        if self._pos > len(self._data):
            self.past_end_used = True
        return self._pos

    def close(self):
        pass


def _format_values(formats, name, memo, depth=0):
    """How many values format `name` flattens into (arrays and nested formats counted out);
    MAX_FIELDS + 1 for one that is too big, nests too deep or contains itself."""
    if name in memo:
        return memo[name]
    if depth > MAX_NESTING:
        return MAX_FIELDS + 1
    memo[name] = MAX_FIELDS + 1  # while counting: a format met again inside itself is a loop
    from pyulog import ULog

    total = 0
    fmt = formats.get(name)
    for type_name, array_size, _field in fmt.fields if fmt is not None else ():
        if type_name in ULog._UNPACK_TYPES:
            each = 1
        elif type_name in formats:
            each = _format_values(formats, type_name, memo, depth + 1)
        else:
            each = 0  # pyulog itself refuses the unknown type (KeyError)
        total += each * max(1, array_size)
        if total > MAX_FIELDS:
            total = MAX_FIELDS + 1
            break
    memo[name] = total
    return total


def _bounded_ulog_class():
    """pyulog's ULog with subscriptions whose flattened size is checked before pyulog builds them."""
    from pyulog import ULog

    counted = [0]

    class _AddLogged(ULog._MessageAddLogged):
        def _parse_format(self, message_formats):
            n = _format_values(message_formats, self.message_name, {})
            if n > MAX_FIELDS:
                # a ValueError: pyulog counts the subscription as corrupt and reads on
                raise ValueError("format %r has more values than a message can hold" % self.message_name[:40])
            counted[0] += n
            if counted[0] > MAX_TOTAL_FIELDS:
                raise ValueError("subscriptions hold more than %d values in all" % MAX_TOTAL_FIELDS)
            ULog._MessageAddLogged._parse_format(self, message_formats)

    class _BoundedULog(ULog):
        _MessageAddLogged = _AddLogged

    return _BoundedULog


def open_ulog(path, topics=None):
    """Parse `path` with pyulog; returns (ULog, warnings list). Raises LogReadError only.

    `topics`: optional list of topic names to load (pyulog's message_name_filter_list).
    """
    try:
        from pyulog.exceptions import ULogException
    except ImportError as exc:  # pragma: no cover - pyulog is a declared dependency
        raise LogReadError("reading ULog needs pyulog (%s)" % exc) from None
    name = os.fspath(path)
    try:
        with open(name, "rb") as f:
            data = f.read()
    except OSError as exc:
        raise LogReadError("%s: cannot open (%s)" % (name, exc.strerror or exc)) from None
    except MemoryError:
        raise LogReadError("%s: too big to read into memory" % name) from None
    handle = _BoundedFile(data, CALLS_FLOOR + CALLS_PER_BYTE * len(data))
    printed = io.StringIO()
    try:
        with contextlib.redirect_stdout(printed):
            ulog = _bounded_ulog_class()(handle, topics, disable_str_exceptions=True)
    except ULogException as exc:
        raise LogReadError("%s: not a readable ULog file (%s)" % (name, exc)) from None
    except (MemoryError, RecursionError) as exc:
        raise LogReadError("%s: ULog file too damaged to read (%s)" % (name, type(exc).__name__)) from None
    except Exception as exc:  # noqa: BLE001 - any pyulog failure on user bytes is a read error
        raise LogReadError(
            "%s: ULog file too damaged to read (%s: %s)" % (name, type(exc).__name__, _one_line(exc))
        ) from None
    warnings = [line.strip() for line in printed.getvalue().splitlines() if line.strip()]
    if len(warnings) > MAX_WARNINGS:  # pyulog says it once per unknown msg_id: up to 65 536 lines
        warnings[MAX_WARNINGS:] = ["... and %d more such warnings" % (len(warnings) - MAX_WARNINGS)]
    if handle.stopped_at >= 0:
        ulog._file_corrupt = True
        warnings.append("too damaged to read on past byte %d of %d: read up to there" % (handle.stopped_at,
                                                                                        len(data)))
    cut = framing_end(data)
    if cut is not None:
        warnings.append("file ends inside a message at byte %d of %d (cut off?): read up to the last whole "
                        "message" % cut)
    return ulog, warnings


def framing_end(data):
    """(offset of the unfinished message, file size) when a log's bytes end inside a message, else None.

    Walks the message headers only (u16 size, u8 type); pyulog reads such a file silently.
    """
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
