"""PX4 ULog writer: topics, info, parameters and log strings in, ULog bytes out to any sink.

Takes a sink (anything with `write(bytes_like)`: a file on CPython/Linux, a flash file or
a serial port on the Pico, or the `RingSink` below that a board drains in its slack) and a
caller-supplied 64-bit microsecond time base (the flight core extends its 2**30 tick clock
itself). Gives a file that pyulog, PlotJuggler and Flight Review read. It sits in the
logging task: the core's signals go in through `write_data`, nothing comes back.

Format: reference/sim-physics-and-logs.md section 6 and protocols.md section 7.3 (PX4
`ulog_file_format.md`). All little-endian, fields packed without alignment, strings
without NUL. Order that readers need, and that this writer enforces:
header, `B` flag bits, then Definitions (`F` formats, `I`/`M` info, `P` parameters), then
Data (`A` subscriptions, `D` samples, `L` strings, `P` changes, `S` syncs, `O` dropouts).
Definitions after the first subscription (or log string) are refused and counted, because
pyulog ignores an `F` there and then silently stops parsing at the first `D` that uses it.
Every format must carry `uint64_t timestamp` for the same reason.

Steady state: `write_data` packs a caller's tuple/list (field order, arrays flattened, the
top-level timestamp passed separately) into a per-topic preallocated buffer with a
precomputed struct format and hands it to the sink in one `write`. Nothing is allocated
when the values are a tuple or list (an `array` would box each element on MicroPython).
Bad input never raises: it is refused and counted, and a timestamp that goes backwards
is clamped to the topic's last one and counted.
"""

import struct

from hoverfly.compat import const

_MAGIC = b"ULog\x01\x12\x35"
_VERSION = const(1)
_SYNC_MAGIC = b"\x2f\x73\x13\x20\x25\x0c\xbb\x12"
_FLAG_BITS_LEN = const(40)  # u8 compat[8], u8 incompat[8], u64 appended_offsets[3]
_MAX_PAYLOAD = const(65535)
_SYNC_INTERVAL_US = const(1000000)  # the spec asks for a sync about every second
_U64_MAX = 0xFFFFFFFFFFFFFFFF
_I64_MIN = -0x8000000000000000
_I64_MAX = 0x7FFFFFFFFFFFFFFF

_MSG_D = const(0x44)

# type -> (struct code, bytes, lowest int, highest int); floats carry None bounds.
# bool and char have no struct code on MicroPython: bool packs as 'B', char[N] as 'Ns'.
_TYPES = {
    "int8_t": ("b", 1, -0x80, 0x7F),
    "uint8_t": ("B", 1, 0, 0xFF),
    "int16_t": ("h", 2, -0x8000, 0x7FFF),
    "uint16_t": ("H", 2, 0, 0xFFFF),
    "int32_t": ("i", 4, -0x80000000, 0x7FFFFFFF),
    "uint32_t": ("I", 4, 0, 0xFFFFFFFF),
    "int64_t": ("q", 8, _I64_MIN, _I64_MAX),
    "uint64_t": ("Q", 8, 0, _U64_MAX),
    "float": ("f", 4, None, None),
    "double": ("d", 8, None, None),
    "bool": ("B", 1, 0, 1),
    "char": ("s", 1, None, None),
}

# What struct raises on a value it cannot pack: CPython's struct.error, MicroPython's
# ValueError/TypeError/OverflowError.
if hasattr(struct, "error"):
    _PACK_ERRORS = (ValueError, TypeError, OverflowError, IndexError, struct.error)
else:
    _PACK_ERRORS = (ValueError, TypeError, OverflowError, IndexError)

_FIELD_CHARS = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_"
_FORMAT_CHARS = _FIELD_CHARS + "/-"


def _valid_name(name, allowed):
    if not isinstance(name, str) or not name:
        return False
    for c in name:
        if c not in allowed:
            return False
    return True


def _split_type(type_str):
    """'float[4]' -> ('float', 4, True); 'float' -> ('float', 1, False); bad -> (None, 0, False)."""
    if not isinstance(type_str, str):
        return None, 0, False
    i = type_str.find("[")
    if i < 0:
        return type_str, 1, False
    if not type_str.endswith("]"):
        return None, 0, False
    digits = type_str[i + 1 : -1]
    if not digits or not digits.isdigit():
        return None, 0, False
    n = int(digits)
    if n < 1 or n > _MAX_PAYLOAD:
        return None, 0, False
    return type_str[:i], n, True


def _to_bytes(value):
    if isinstance(value, str):
        return value.encode()
    if isinstance(value, (bytes, bytearray, memoryview)):
        return bytes(value)
    return None


def _encode_value(type_str, value):
    """Bytes of one info/parameter value of a ULog type, or None if it does not fit."""
    base, n, is_array = _split_type(type_str)
    if base not in _TYPES:
        return None
    code, size, lo, hi = _TYPES[base]
    if code == "s":
        raw = _to_bytes(value)
        if raw is None or len(raw) != n:
            return None
        return raw
    if is_array:
        raw = _to_bytes(value)
        if raw is not None:
            return raw if len(raw) == n * size else None
        try:
            if len(value) != n:
                return None
        except TypeError:
            return None
        items = value
    else:
        items = (value,)
    out = bytearray(n * size)
    off = 0
    for v in items:
        if lo is not None:
            if not isinstance(v, int) or v < lo or v > hi:
                return None
        elif not isinstance(v, (int, float)):
            return None
        try:
            struct.pack_into("<" + code, out, off, v)
        except _PACK_ERRORS:
            return None
        off += size
    return bytes(out)


def _message(msg_type, payload):
    buf = bytearray(3 + len(payload))
    struct.pack_into("<HB", buf, 0, len(payload), msg_type)
    buf[3:] = payload
    return buf


class UlogWriter:
    """Write one ULog stream to `sink`, starting at `start_us` (u64 µs of the caller's time base).

    Counters: bytes_written, messages, refused (bad calls), clamped_timestamps,
    dropped_messages (the sink took less than a whole message), dropouts ('O' written),
    sink_errors (the sink raised OSError).
    """

    def __init__(self, sink, start_us=0):
        self._sink = sink
        self._sink_free = getattr(sink, "free", None)  # RingSink tells its room; others don't
        self.bytes_written = 0
        self.messages = 0
        self.refused = 0
        self.clamped_timestamps = 0
        self.dropped_messages = 0
        self.dropouts = 0
        self.sink_errors = 0
        self.in_data = False
        # name -> (items, payload bytes); an item is (code, count, bytes, values, lo, hi, is_ts)
        self._formats = {}
        self._info_keys = {}
        self._param_types = {}
        self._topics = {}  # (format name, multi_id) -> msg_id
        # Per-topic state, indexed by msg_id; all built in subscribe().
        self._bufs = []
        self._fmts = []
        self._nvalues = []
        self._ts_offset = []  # 0: timestamp packed first with the values; else its offset
        self._checks = []  # None or tuple of (value index, lo, hi) for integer fields
        self._last_ts = []
        self._last_log_us = 0
        self._next_sync_us = 0
        self._dropping = False
        self._drop_start_us = 0
        self._sync_buf = _message(0x53, _SYNC_MAGIC)
        self._dropout_buf = bytearray(5)
        struct.pack_into("<HB", self._dropout_buf, 0, 2, 0x4F)
        if not isinstance(start_us, int) or start_us < 0 or start_us > _U64_MAX:
            self.refused += 1
            start_us = 0
        header = bytearray(16)
        header[0:7] = _MAGIC
        header[7] = _VERSION
        struct.pack_into("<Q", header, 8, start_us)
        self._emit(header)
        # All flags zero: no default parameters, no appended data (B must sit at offset 16).
        self._emit(_message(0x42, bytes(_FLAG_BITS_LEN)))

    # ---- sink ---------------------------------------------------------------------------

    def _emit(self, buf):
        """Hand one whole message to the sink; False (and counted) if it did not take it all."""
        n = len(buf)
        try:
            r = self._sink.write(buf)
        except OSError:
            self.sink_errors += 1
            return False
        if r is not None and r < n:
            self.dropped_messages += 1
            return False
        self.bytes_written += n
        self.messages += 1
        return True

    def _emit_timed(self, buf, timestamp_us):
        """Emit a data-section message; open or close a dropout around it."""
        if self._dropping:
            # Close the gap only when the 'O' and this message both fit, so a nearly full
            # ring does not fill up with one-millisecond dropouts.
            if self._sink_free is None or self._sink_free() >= 5 + len(buf):
                self._close_dropout(timestamp_us)
            else:
                self.dropped_messages += 1
                return False
        if self._emit(buf):
            return True
        if not self._dropping:
            self._dropping = True
            self._drop_start_us = timestamp_us
        return False

    def _close_dropout(self, timestamp_us):
        ms = (timestamp_us - self._drop_start_us) // 1000
        if ms < 0:
            ms = 0
        elif ms > 0xFFFF:
            ms = 0xFFFF
        struct.pack_into("<H", self._dropout_buf, 3, ms)
        if self._emit(self._dropout_buf):
            self._dropping = False
            self.dropouts += 1

    # ---- definitions --------------------------------------------------------------------

    def _refuse(self):
        self.refused += 1
        return False

    def add_format(self, name, fields):
        """Define format `name` from (type, field name) pairs; True if written, else refused."""
        if self.in_data or not _valid_name(name, _FORMAT_CHARS) or name in self._formats:
            return self._refuse()
        items = []
        names = {}
        text = name + ":"
        has_ts = False
        size = 0
        try:
            pairs = tuple(fields)
        except TypeError:
            return self._refuse()
        if not pairs:
            return self._refuse()
        for pair in pairs:
            try:
                type_str, field = pair
            except (TypeError, ValueError):
                return self._refuse()
            if not _valid_name(field, _FIELD_CHARS) or field in names:
                return self._refuse()
            names[field] = True
            base, n, is_array = _split_type(type_str)
            if base is None:
                return self._refuse()
            padding = field.startswith("_padding")
            if base in _TYPES:
                code, nbytes, lo, hi = _TYPES[base]
                is_ts = field == "timestamp" and type_str == "uint64_t"
                has_ts = has_ts or is_ts
                if padding:
                    items.append(("x", n * nbytes, n * nbytes, 0, None, None, False))
                elif code == "s":
                    items.append(("s", n, n, 1, None, None, False))
                else:
                    items.append((code, n, n * nbytes, n, lo, hi, is_ts))
                size += n * nbytes
            elif base in self._formats:
                sub_items, sub_size = self._formats[base]
                for _ in range(n):
                    for it in sub_items:
                        # A nested format's own timestamp is an ordinary value of the parent.
                        items.append(it[:6] + (False,))
                size += n * sub_size
            else:
                return self._refuse()
            text += type_str + " " + field + ";"
        # pyulog silently stops parsing at the first sample of a format without it.
        if not has_ts or size > _MAX_PAYLOAD - 2 or len(text) > _MAX_PAYLOAD:
            return self._refuse()
        if not self._emit(_message(0x46, text.encode())):
            return False
        self._formats[name] = (tuple(items), size)
        return True

    def _key_value(self, key_type_name, value):
        if not isinstance(key_type_name, str) or key_type_name.count(" ") != 1:
            return None, None  # pyulog flags an info key without a type as corruption
        type_str, key = key_type_name.split(" ")
        if not _valid_name(key, _FIELD_CHARS):
            return None, None
        if type_str.startswith("char[") and isinstance(value, str):
            value = value.encode()
        raw = _encode_value(type_str, value)
        if raw is None:
            return None, None
        k = key_type_name.encode()
        if len(k) > 255 or len(k) + len(raw) > _MAX_PAYLOAD - 2:
            return None, None
        return k, raw

    def add_info(self, key_type_name, value):
        """Info `I`: key 'type name' (e.g. 'char[8] sys_name', 'uint32_t ver_sw_release')."""
        if self.in_data:
            return self._refuse()
        k, raw = self._key_value(key_type_name, value)
        if k is None or key_type_name in self._info_keys:
            return self._refuse()
        payload = bytearray(1 + len(k) + len(raw))
        payload[0] = len(k)
        payload[1 : 1 + len(k)] = k
        payload[1 + len(k) :] = raw
        if not self._emit(_message(0x49, payload)):
            return False
        self._info_keys[key_type_name] = True
        return True

    def add_multi_info(self, key_type_name, value, is_continued=False):
        """Multi info `M`: the key may repeat; is_continued appends to the previous value."""
        if self.in_data:
            return self._refuse()
        k, raw = self._key_value(key_type_name, value)
        if k is None:
            return self._refuse()
        payload = bytearray(2 + len(k) + len(raw))
        payload[0] = 1 if is_continued else 0
        payload[1] = len(k)
        payload[2 : 2 + len(k)] = k
        payload[2 + len(k) :] = raw
        return self._emit(_message(0x4D, payload))

    def _param_payload(self, name, value, type_str):
        if not _valid_name(name, _FIELD_CHARS) or len(name) > 255 - 8:
            return None
        if type_str is None:
            if isinstance(value, bool) or isinstance(value, int):
                type_str = "int32_t"
            elif isinstance(value, float):
                type_str = "float"
            else:
                return None
        if type_str == "int32_t" and isinstance(value, float):
            if value != int(value):
                return None
            value = int(value)
        k, raw = self._key_value(type_str + " " + name, value)
        if k is None:
            return None
        payload = bytearray(1 + len(k) + len(raw))
        payload[0] = len(k)
        payload[1 : 1 + len(k)] = k
        payload[1 + len(k) :] = raw
        return type_str, payload

    def add_param(self, name, value):
        """Initial parameter `P`: int -> int32_t, float -> float."""
        if self.in_data or name in self._param_types:
            return self._refuse()
        got = self._param_payload(name, value, None)
        if got is None:
            return self._refuse()
        if not self._emit(_message(0x50, got[1])):
            return False
        self._param_types[name] = got[0]
        return True

    def begin_data(self):
        """End the Definitions section; later add_format/add_info/add_param are refused."""
        self.in_data = True

    # ---- data ---------------------------------------------------------------------------

    def subscribe(self, format_name, multi_id=0):
        """Add subscription `A` for a defined format; returns its msg_id, or -1 (refused)."""
        if format_name not in self._formats or not isinstance(multi_id, int):
            self.refused += 1
            return -1
        msg_id = len(self._bufs)
        key = (format_name, multi_id)
        if multi_id < 0 or multi_id > 255 or msg_id > 0xFFFF or key in self._topics:
            self.refused += 1
            return -1
        self.begin_data()
        items, size = self._formats[format_name]
        items = list(items)
        while items and items[-1][0] == "x":  # trailing padding is not written (spec)
            size -= items[-1][2]
            items.pop()
        ts_first = items[0][6]
        fmt = "<"
        checks = []
        nvalues = 0
        ts_offset = 0
        offset = 0
        for code, count, nbytes, nvals, lo, hi, is_ts in items:
            if is_ts:
                ts_offset = offset
                if not ts_first:
                    fmt += "8x"  # packed with the values as zeros, then overwritten
            else:
                fmt += "%d%s" % (count, code)
                if lo is not None:
                    for i in range(nvals):
                        checks.append((nvalues + i, lo, hi))
                nvalues += nvals
            offset += nbytes
        if ts_first:
            fmt = "<Q" + fmt[1:]
        buf = bytearray(5 + size)
        struct.pack_into("<HBH", buf, 0, 2 + size, _MSG_D, msg_id)
        name = format_name.encode()
        payload = bytearray(3 + len(name))
        struct.pack_into("<BH", payload, 0, multi_id, msg_id)
        payload[3:] = name
        self._topics[key] = msg_id
        self._bufs.append(buf)
        self._fmts.append(fmt)
        self._nvalues.append(nvalues)
        self._ts_offset.append(0 if ts_first else 5 + ts_offset)
        self._checks.append(tuple(checks) if checks else None)
        self._last_ts.append(0)
        self._emit(_message(0x41, payload))
        return msg_id

    def write_data(self, msg_id, timestamp_us, values, in_range=False):
        """One sample `D`: values in field order (arrays flattened, top-level timestamp apart).

        Returns True if the sink took it. Refuses (and counts) an unknown msg_id, a wrong
        number of values, an integer out of its type's range; clamps a timestamp that
        goes backwards to the topic's last one. `in_range`: the caller has clamped every integer
        to its type (the flight logger's slow topics), so the per-field checks are skipped.
        """
        try:
            if msg_id < 0 or msg_id >= len(self._bufs) or len(values) != self._nvalues[msg_id]:
                self.refused += 1
                return False
            checks = self._checks[msg_id]
            if checks is not None and not in_range:
                # MicroPython's struct wraps out-of-range integers silently; CPython raises.
                for i, lo, hi in checks:
                    v = values[i]
                    if v < lo or v > hi:
                        self.refused += 1
                        return False
            last = self._last_ts[msg_id]
            if timestamp_us < last:
                timestamp_us = last
                self.clamped_timestamps += 1
            elif timestamp_us > _U64_MAX:
                self.refused += 1
                return False
            buf = self._bufs[msg_id]
            ts_offset = self._ts_offset[msg_id]
            if ts_offset == 0:
                struct.pack_into(self._fmts[msg_id], buf, 5, timestamp_us, *values)
            else:
                struct.pack_into(self._fmts[msg_id], buf, 5, *values)
                struct.pack_into("<Q", buf, ts_offset, timestamp_us)
        except _PACK_ERRORS:
            self.refused += 1
            return False
        self._last_ts[msg_id] = timestamp_us
        return self._emit_timed(buf, timestamp_us)

    def data_layout(self, msg_id):
        """(header, payload format) of topic msg_id's `D` message, for a caller that packs several
        samples in one go and hands them over with write_packed: the 5 header bytes and the struct
        format (no byte-order prefix) of its payload, timestamp first. None for an unknown topic or
        one whose timestamp is not its first field."""
        if not isinstance(msg_id, int) or msg_id < 0 or msg_id >= len(self._bufs) or self._ts_offset[msg_id] != 0:
            return None
        return bytes(self._bufs[msg_id][0:5]), self._fmts[msg_id][1:]

    def write_packed(self, buf, fmt, values, count, timestamp_us):
        """`count` whole `D` messages in one write: `values` (each message's header and fields, by
        data_layout) packed by `fmt` into `buf`, all stamped `timestamp_us`. True if the sink took
        them. The caller keeps its integers in range and its timestamps in order (no per-field
        checks, no clamp: write_data's in_range for several topics at once); a value struct cannot
        pack refuses all of them (counted); dropouts as for write_data."""
        try:
            struct.pack_into(fmt, buf, 0, *values)
        except _PACK_ERRORS:
            self.refused += count
            return False
        if self._emit_timed(buf, timestamp_us):
            self.messages += count - 1
            return True
        return False

    def log_message(self, level, timestamp_us, text):
        """Log string `L`: level 0 (emergency) .. 7 (debug), text str or bytes."""
        raw = _to_bytes(text)
        if raw is None or not isinstance(level, int) or not isinstance(timestamp_us, int):
            return self._refuse()
        if timestamp_us > _U64_MAX:
            return self._refuse()
        if timestamp_us < self._last_log_us:
            timestamp_us = self._last_log_us
            self.clamped_timestamps += 1
        self._last_log_us = timestamp_us
        self.begin_data()  # pyulog ends Definitions at the first L as well
        if level < 0:
            level = 0
        elif level > 7:
            level = 7
        raw = raw[: _MAX_PAYLOAD - 9]
        payload = bytearray(9 + len(raw))
        struct.pack_into("<BQ", payload, 0, 0x30 + level, timestamp_us)
        payload[9:] = raw
        return self._emit_timed(_message(0x4C, payload), timestamp_us)

    def param_change(self, name, value, timestamp_us):
        """Parameter change `P` in the Data section (readers stamp it with the last sample's time).

        Before begin_data() it is the parameter's initial value (add_param).
        """
        if not self.in_data:
            return self.add_param(name, value)
        got = self._param_payload(name, value, self._param_types.get(name))
        if got is None or not isinstance(timestamp_us, int):
            return self._refuse()
        self._param_types[name] = got[0]
        return self._emit_timed(_message(0x50, got[1]), timestamp_us)

    def sync(self):
        """Sync `S`: lets a reader find its place again after corruption."""
        return self._emit(self._sync_buf)

    def maybe_sync(self, timestamp_us):
        """Write a sync if about a second has passed since the last one; True if written."""
        if timestamp_us < self._next_sync_us:
            return False
        self._next_sync_us = timestamp_us + _SYNC_INTERVAL_US
        return self.sync()

    def dropout(self, duration_ms):
        """Dropout `O`: `duration_ms` of data lost (clamped to 0..65535)."""
        if not isinstance(duration_ms, int):
            return self._refuse()
        if duration_ms < 0:
            duration_ms = 0
        elif duration_ms > 0xFFFF:
            duration_ms = 0xFFFF
        struct.pack_into("<H", self._dropout_buf, 3, duration_ms)
        return self._emit(self._dropout_buf)


class RingSink:
    """A preallocated byte ring the writer fills and a board drains in its slack.

    `write` takes a whole message or nothing (a partial message would corrupt the stream):
    when there is no room it returns 0 and counts dropped_bytes/dropped_messages, and each
    run of drops counts one dropout; the writer then emits an 'O' when room returns.
    With `spill` (a drain write_fn) the write that leaves `spill_at` bytes or more in the ring
    drains it there and then (a host writing to a file: nobody has to drain between passes).
    """

    def __init__(self, size, spill=None, spill_at=0):
        self._buf = bytearray(size)
        self._mv = memoryview(self._buf)
        self.size = size
        self._head = 0  # next byte written
        self._tail = 0  # next byte drained
        self.used = 0
        self.bytes_in = 0
        self.bytes_out = 0
        self.dropped_bytes = 0
        self.dropped_messages = 0
        self.dropouts = 0
        self.dropping = False
        self.high_water = 0
        self.write_errors = 0
        self._spill = spill
        self._spill_at = spill_at

    def free(self):
        return self.size - self.used

    def write(self, data):
        n = len(data)
        if n > self.size - self.used:
            self.dropped_bytes += n
            self.dropped_messages += 1
            if not self.dropping:
                self.dropping = True
                self.dropouts += 1
            return 0
        self.dropping = False
        # Stored through the ring's memoryview: a bytearray's slice assignment copies a memoryview
        # (the logger's batches) into a temporary first, CPython's memoryview copies it straight in.
        mv = self._mv
        head = self._head
        first = self.size - head
        if n <= first:
            mv[head : head + n] = data
        else:
            # Split across the end, once per trip round the ring: one memoryview (a small
            # allocation) instead of a byte-by-byte Python loop that would cost milliseconds
            # for a batch on an RP2040.
            src = memoryview(data)
            mv[head:] = src[:first]
            mv[: n - first] = src[first:n]
        head += n
        if head >= self.size:
            head -= self.size
        self._head = head
        self.used += n
        self.bytes_in += n
        if self.used > self.high_water:
            self.high_water = self.used
        if self._spill is not None and self.used >= self._spill_at:
            self.drain(self._spill)
        return n

    def drain(self, write_fn, max_bytes=-1):
        """Pass up to `max_bytes` (-1: all) to `write_fn(memoryview)`; returns bytes drained.

        write_fn returns how many bytes it took (None = all of them) and must copy what it
        keeps: the view is reused. An OSError from it is counted and ends the drain.
        """
        done = 0
        while self.used > 0 and (max_bytes < 0 or done < max_bytes):
            chunk = self.size - self._tail
            if chunk > self.used:
                chunk = self.used
            if max_bytes >= 0 and chunk > max_bytes - done:
                chunk = max_bytes - done
            try:
                r = write_fn(self._mv[self._tail : self._tail + chunk])
            except OSError:
                self.write_errors += 1
                break
            took = chunk if r is None else r
            if took < 0:
                took = 0
            elif took > chunk:
                took = chunk
            self._tail += took
            if self._tail >= self.size:
                self._tail -= self.size
            self.used -= took
            self.bytes_out += took
            done += took
            if took < chunk:
                break
        if self.used == 0:
            # Empty: start again at the front, so the writes keep landing in the same few
            # kilobytes (cache-warm) instead of walking the whole ring.
            self._head = 0
            self._tail = 0
        return done
