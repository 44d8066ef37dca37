"""Parameter storage: the live Params as a versioned, CRC-checked blob in two slots.

Takes the Params and the Board's storage seam (`load_storage() -> bytes | None`,
`save_storage(image) -> bool`); gives `Storage.load(params)` at boot and `Storage.save(params)`
from the CLI, MSP EEPROM_WRITE and the maintenance protocol's flash write. Runs at boot and
on a save only, never in the flight pass.

Image: slot 0 at offset 0, slot 1 at offset SLOT_BYTES (8 KiB; slot 0 is padded with 0xFF, the
erased-flash value, when slot 1 is in use). A save writes the slot that does not hold the newest
good record, with the next sequence number, and leaves the other slot's bytes as they were; so a
save cut off at any byte (power lost, file write interrupted) leaves the previous record intact and
it loads at the next boot. Both slots bad: the table's defaults, and `failed` is set for the
built-in test.

Record (little-endian):
    magic "HVFP" | u8 format | u8 0 | u16 entry count | u32 sequence | u32 payload bytes
    | payload | u32 CRC-32 (IEEE) over everything before it
Payload entries, keyed by name so rows can be added, reordered or retired:
    u8 name length | name | u8 type | value     type 'i': i32, 'f': f64, 's': u8 length + text
Loading takes each entry through params.check (the one check every surface uses): an unknown
name (a retired row), a value outside today's range, a non-finite number, or a value this board
cannot run (a mixer_type for another motor count) is skipped, named in `skipped_names` with its
reason in `skip_reasons`, and that parameter keeps the value it had (its default, or the craft's);
the rest of the record loads, so the boot always comes up. Names
in RENAMED load under their new name, rows in RETIRED into the rows that replaced them; a record of an
older format goes through MIGRATIONS.
"""

from struct import pack, pack_into, unpack_from

from hoverfly.compat import const
from hoverfly.core.config.params import PARAMS, check
from hoverfly.core.stages.mixer import MIXER_TABLES

MAGIC = b"HVFP"
FORMAT = const(1)  # newest record layout this firmware writes
SLOT_BYTES = const(8192)
HEADER_BYTES = const(16)
CRC_BYTES = const(4)

# Status after load()
EMPTY = const(0)  # nothing stored yet (first boot): defaults, not a fault
LOADED = const(1)  # the newest record loaded
LOADED_OLDER = const(2)  # the newest slot was bad; the other one loaded
LOST = const(3)  # something was stored but no slot is readable: defaults, built-in test flag
STATUS_NAMES = ("empty", "loaded", "loaded older slot", "lost: defaults")

# Parameter renames, old name -> new name, applied to every record on load (rows that moved).
RENAMED = {}
# Retired rows whose setting lives on in other rows: old name -> {old value: ((name, value), ...)}, or
# old name -> (names,) to copy the value into each. A record saved before the change loads as it flew.
RETIRED = {
    # map_aetr -> rc_map (the receiver channel per roll, pitch, yaw, throttle, AUX1..4). Its RETA read
    # roll on channel 4, pitch 3, yaw 2, throttle 1 (Betaflight's map TREA1234), and keeps doing so.
    "map_aetr": {"AETR": (("rc_map", 12435678),), "TAER": (("rc_map", 23415678),),
                 "RETA": (("rc_map", 43215678),)},
    # one alpha-beta pair for every stick -> a pair per stick
    "rc_ab_alpha": ("ab_roll_alpha", "ab_pitch_alpha", "ab_yaw_alpha", "ab_thr_alpha"),
    "rc_ab_beta": ("ab_roll_beta", "ab_pitch_beta", "ab_yaw_beta", "ab_thr_beta"),
}
# Older record formats: (format, fn(entries) -> entries) applied in order to a record whose
# format is below it, so an old blob keeps loading after the layout changes. Format 1 is the first.
MIGRATIONS = ()

_crc_table = None


def _table():
    global _crc_table
    if _crc_table is None:
        t = []
        for i in range(256):
            c = i
            for _ in range(8):
                c = (c >> 1) ^ 0xEDB88320 if c & 1 else c >> 1
            t.append(c)
        _crc_table = t
    return _crc_table


def crc32(data, start=0, end=-1):
    """CRC-32/ISO-HDLC (zlib's) of data[start:end]. Storage only: its ints pass 2**30 on rp2."""
    if end < 0:
        end = len(data)
    t = _table()
    c = 0xFFFFFFFF
    for i in range(start, end):
        c = t[(c ^ data[i]) & 0xFF] ^ (c >> 8)
    return c ^ 0xFFFFFFFF


def encode_record(values, seq):
    """One record holding every table parameter's value from `values` (dict name -> value)."""
    parts = []
    count = 0
    for r in PARAMS:
        name = r[0]
        v = values.get(name, r[1])
        nb = name.encode()
        if isinstance(r[1], str):
            tb = str(v).encode()
            parts.append(pack("<B", len(nb)) + nb + b"s" + pack("<B", len(tb)) + tb)
        elif isinstance(r[1], float):
            parts.append(pack("<B", len(nb)) + nb + b"f" + pack("<d", float(v)))
        else:
            parts.append(pack("<B", len(nb)) + nb + b"i" + pack("<i", int(v)))
        count += 1
    payload = b"".join(parts)
    head = bytearray(HEADER_BYTES)
    head[0:4] = MAGIC
    pack_into("<BBHII", head, 4, FORMAT, 0, count, seq & 0xFFFFFFFF, len(payload))
    body = bytes(head) + payload
    return body + pack("<I", crc32(body))


def parse_record(image, offset=0):
    """(format, seq, [(name, value), ...]) of the record at `offset`, or None if it is not whole,
    not ours, too new, or fails its CRC. Never raises on any bytes."""
    n = len(image)
    if offset < 0 or n - offset < HEADER_BYTES + CRC_BYTES:
        return None
    if bytes(image[offset:offset + 4]) != MAGIC:
        return None
    fmt, _, count, seq, length = unpack_from("<BBHII", image, offset + 4)
    if fmt < 1 or fmt > FORMAT or length > SLOT_BYTES:
        return None
    end = offset + HEADER_BYTES + length
    if end + CRC_BYTES > n:
        return None
    if unpack_from("<I", image, end)[0] != crc32(image, offset, end):
        return None
    entries = []
    p = offset + HEADER_BYTES
    try:
        for _ in range(count):
            k = image[p]
            name = bytes(image[p + 1:p + 1 + k]).decode()
            p += 1 + k
            t = image[p]
            p += 1
            if t == 0x69:  # 'i'
                v = unpack_from("<i", image, p)[0]
                p += 4
            elif t == 0x66:  # 'f'
                v = unpack_from("<d", image, p)[0]
                p += 8
            elif t == 0x73:  # 's'
                k = image[p]
                v = bytes(image[p + 1:p + 1 + k]).decode()
                p += 1 + k
            else:
                return None
            if p > end:
                return None
            entries.append((name, v))
    except (IndexError, ValueError, UnicodeError):
        return None  # a record whose CRC matched but whose entries do not parse: treat as bad
    return fmt, seq, entries


def _newer(a, b):
    # Sequence numbers compared as serial numbers (wrap after 2**32 saves).
    return ((a - b) & 0xFFFFFFFF) < 0x80000000 and a != b


def _unretire(entries):
    """entries with each RETIRED row given as the rows that carry its setting now (an unknown old value
    stays as it is, to be skipped and counted)."""
    out = []
    for name, value in entries:
        r = RETIRED.get(name)
        if r is None:
            out.append((name, value))
        elif isinstance(r, dict):
            out.extend(r.get(value, ((name, value),)))
        else:
            for new in r:
                out.append((new, value))
    return out


class Storage:
    """The two-slot parameter store on one board."""

    def __init__(self, board):
        self.board = board
        self.image = b""
        self.slot = -1  # slot of the newest good record, -1 none
        self.seq = 0
        self.status = EMPTY
        self.failed = False  # built-in test: stored parameters were lost
        self.skipped = 0  # names or values of the loaded record that were not applied
        self.skipped_names = []  # ... their names, and why (one line each), for status and the log
        self.skip_reasons = []
        self.saves = 0
        self.last_error = None

    def load(self, params):
        """Read the newest good record into params; returns the status (EMPTY, LOADED ...)."""
        image = None
        try:
            image = self.board.load_storage()
        except OSError:
            image = b"\x00"  # unreadable counts as lost
        self.skipped = 0
        self.skipped_names = []
        self.skip_reasons = []
        params.load_skipped = self.skipped_names
        if not image:
            self.image = b""
            self.slot = -1
            self.status = EMPTY
            self.failed = False
            return self.status
        self.image = bytes(image)
        best = None
        best_slot = -1
        bad = 0
        for slot in (0, 1):
            r = parse_record(self.image, slot * SLOT_BYTES)
            if r is None:
                if slot == 0 or len(self.image) > SLOT_BYTES:
                    bad += 1
                continue
            if best is None or _newer(r[1], best[1]):
                best = r
                best_slot = slot
        if best is None:
            self.slot = -1
            self.status = LOST
            self.failed = True
            return self.status
        self.slot = best_slot
        self.seq = best[1]
        self.status = LOADED_OLDER if bad else LOADED
        self.failed = False
        self._apply(params, best[0], best[2])
        return self.status

    def _apply(self, params, fmt, entries):
        for f, fn in MIGRATIONS:
            if fmt < f:
                entries = fn(entries)
        pairs = []
        for name, value in _unretire(entries):
            name = RENAMED.get(name, name)
            key, v, err = check(name, value)
            if err is None:
                err = self._unfit(key, v)
            if err is not None:
                self.skipped += 1
                self.skipped_names.append(name)
                self.skip_reasons.append(err)
                continue
            pairs.append((key, v))
        params.update(pairs)

    def _unfit(self, name, value):
        # A value the table allows but this board cannot boot with: a frame for another motor count
        # (the outputs, ESCs and, in the simulator, the airframe are built for the board's count).
        if name == "mixer_type":
            table = MIXER_TABLES.get(value)
            if table is None:
                return "mixer_type = %s has no mixer table" % value
            n = getattr(self.board, "motor_count", 0)
            if n and len(table) != n:
                return "mixer_type = %s drives %d motors, this board has %d" % (value, len(table), n)
        return None

    def summary(self):
        """The load in one line: status, and the stored values skipped with why."""
        text = STATUS_NAMES[self.status]
        if self.skipped:
            text += ", %d stored value%s skipped: %s" % (self.skipped, "" if self.skipped == 1 else "s",
                                                          "; ".join(self.skip_reasons[:4]))
            if self.skipped > 4:
                text += "; ..."
        return text

    def save(self, params):
        """Write params into the other slot. None on success, else the reason (nothing changed)."""
        seq = (self.seq + 1) & 0xFFFFFFFF
        record = encode_record(params.saved_values(), seq)
        if len(record) > SLOT_BYTES:
            self.last_error = "parameters do not fit the %d-byte storage slot" % SLOT_BYTES
            return self.last_error
        slot = 1 - self.slot if self.slot >= 0 else 0
        old = self.image
        if slot == 0:
            if len(old) > SLOT_BYTES:
                image = record + b"\xff" * (SLOT_BYTES - len(record)) + old[SLOT_BYTES:]
            else:
                image = record
        else:
            head = old[:SLOT_BYTES]
            image = head + b"\xff" * (SLOT_BYTES - len(head)) + record
        ok = False
        try:
            ok = self.board.save_storage(image)
        except OSError:
            ok = False
        if not ok:
            self.last_error = "storage write failed"
            return self.last_error
        self.image = image
        self.slot = slot
        self.seq = seq
        self.saves += 1
        self.status = LOADED
        self.failed = False
        self.last_error = None
        return None


class MemoryStorageBoard:
    """A board's storage seam in RAM (tests and boards without a file system)."""

    def __init__(self, image=None):
        self.image = image
        self.writes = 0
        self.fail = False

    def load_storage(self):
        return self.image

    def save_storage(self, image):
        if self.fail:
            return False
        self.image = bytes(image)
        self.writes += 1
        return True
