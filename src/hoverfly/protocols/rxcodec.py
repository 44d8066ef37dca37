"""What every receiver codec shares: the streaming framer and the 11-bit channel packing.

Takes receiver bytes in any chunking (`feed(data, n=-1)`) and hands each complete,
length-plausible candidate frame to the protocol's `_take`, which checks it and decodes
values into preallocated arrays (`channels_us`, `channels_raw`, 16 channels each).
Gives the receiver task one interface for CRSF, SBUS and iBUS (rxfactory.py's `make_decoder`
builds them, and the PPM/PWM edge decoders of `pulses.py`, by name). It sits at the start of the receiver task:
board.rx bytes -> decoder -> rc input stage.

Framing rule, the same for all serial protocols: hunt for a sync byte (each skipped byte
counts in `resyncs`), read the header far enough to know the frame length (an impossible
length counts in `length_errors`), wait for the whole frame, let the protocol check it.
If the check fails (CRC, footer) only the sync byte is skipped and the bytes after it are
searched again, so a real frame hiding behind a false sync is still found. The decoder
behaves identically however the bytes are chunked: a frame split across `feed` calls is
assembled in `_buf`, and a failed assembled frame is re-scanned from `_scratch`, exactly
as the one-chunk path would have done (counters included).

Nothing here raises on bad bytes, and a frame that arrives in one chunk is checked and
decoded straight from the caller's buffer without copying or allocating.
"""

from array import array
from struct import pack_into, unpack_from

from hoverfly.compat import IS_MICROPYTHON

CHANNELS = 16  # every decoder reports 16 channels (iBUS pads 15-16 with 1500 µs)
CENTRE_US = 1500
MIN_PULSE_US = 800  # anything outside 800..2200 µs is not a servo pulse (Betaflight's PWM limits)
MAX_PULSE_US = 2200

PROTOCOLS = ("crsf", "sbus", "ibus", "ppm", "pwm")


def new_channels(fill=0):
    """A fresh array('H') of 16 channels."""
    return array("H", [fill] * CHANNELS)


class SerialRxDecoder:
    """Streaming framer shared by CRSF, SBUS and iBUS.

    Subclasses set `_SYNC` (bytes of 256 flags: which bytes may start a frame), `_HEADER`
    (bytes needed before `_frame_len` can answer) and `_MAX_FRAME`, and implement
    `_frame_len(src, i)` (total frame bytes, 0 = impossible header) and
    `_take(src, i, total)` (1 = good RC frame, 0 = other valid frame, -1 = bad, counted).
    """

    _SYNC = bytes(256)
    _HEADER = 1
    _MAX_FRAME = 64

    def __init__(self):
        self.channels_us = new_channels()
        self.channels_raw = new_channels()
        self.frames = 0  # good RC frames
        self.crc_errors = 0
        self.resyncs = 0  # bytes skipped while hunting for a frame start
        self.bytes = 0
        self.length_errors = 0
        self.failsafe = False  # receiver-reported failsafe (SBUS flag; CRSF/iBUS have none)
        self.frame_lost = False  # receiver says this frame is a repeat (SBUS flag)
        self._buf = bytearray(self._MAX_FRAME)
        self._scratch = bytearray(self._MAX_FRAME)
        self._pos = 0  # bytes of a partial frame held in _buf
        self._want = 0  # its total length once the header is known, else 0
        self._new = 0

    def feed(self, data, n=-1):
        """Take the first n bytes of data (all if n < 0); return how many new RC frames completed."""
        size = len(data)
        if n < 0 or n > size:
            n = size
        self.bytes += n
        self._new = 0
        self._scan(data, 0, n)
        return self._new

    def idle(self):
        """The line went quiet (UART idle/receive timeout): a partial frame will never complete.

        Optional; a board that sees inter-frame gaps can call it to resynchronise at once,
        as Betaflight does with its inter-byte timeout. The dropped partial counts in
        `length_errors` (a truncated frame).
        """
        if self._pos:
            self.length_errors += 1
            self.resyncs += self._pos
            self._pos = 0
            self._want = 0

    def reset_counters(self):
        self.frames = self.crc_errors = self.resyncs = self.bytes = self.length_errors = 0

    # -- framing ---------------------------------------------------------------------

    def _scan(self, src, i, n):
        sync = self._SYNC
        header = self._HEADER
        while i < n:
            if self._pos:
                i = self._assemble(src, i, n)
                continue
            if not sync[src[i]]:
                self.resyncs += 1
                i += 1
                continue
            if n - i < header:
                self._stash(src, i, n, 0)
                return
            total = self._frame_len(src, i)
            if total == 0:
                self.length_errors += 1
                self.resyncs += 1
                i += 1
                continue
            if n - i < total:
                self._stash(src, i, n, total)
                return
            r = self._take(src, i, total)
            if r < 0:
                self.resyncs += 1  # skip only the false sync byte and search the rest again
                i += 1
            else:
                i += total
                if r:
                    self._new += 1

    def _stash(self, src, i, n, total):
        buf = self._buf
        pos = 0
        while i < n:
            buf[pos] = src[i]
            pos += 1
            i += 1
        self._pos = pos
        self._want = total

    def _assemble(self, src, i, n):
        buf = self._buf
        pos = self._pos
        want = self._want
        if want == 0:
            header = self._HEADER
            while pos < header and i < n:
                buf[pos] = src[i]
                pos += 1
                i += 1
            self._pos = pos
            if pos < header:
                return i
            want = self._frame_len(buf, 0)
            if want == 0:
                self.length_errors += 1
                self._rescan(pos)
                return i
            self._want = want
        while pos < want and i < n:
            buf[pos] = src[i]
            pos += 1
            i += 1
        if pos < want:
            self._pos = pos
            return i
        self._pos = 0
        self._want = 0
        r = self._take(buf, 0, want)
        if r < 0:
            self._rescan(want)
        elif r:
            self._new += 1
        return i

    def _rescan(self, m):
        # Same as the one-chunk path: drop the sync byte, search buf[1:m] again. The rescan
        # starts with no partial frame, so it can only stash (never complete) one: no recursion.
        self.resyncs += 1
        buf = self._buf
        scratch = self._scratch
        for k in range(1, m):
            scratch[k - 1] = buf[k]
        self._pos = 0
        self._want = 0
        self._scan(scratch, 0, m - 1)

    def _frame_len(self, src, i):
        return 0

    def _take(self, src, i, total):
        return -1


# -- 16 × 11-bit channels, LSB first (CRSF 0x16 payload, SBUS bytes 1..22) ----------------
#
# unpack11(src, p, raw, us, us_of_raw): wire values from src[p:p+22] into raw[0..15] and
#   us_of_raw[value] into us[0..15].
# check_unpack11(src, p, raw, us, us_of_raw, crc_table): src[p] is a type byte, then the 22
#   channel bytes, then a CRC-8 (table-driven, over type + channels); returns 0 on a CRC
#   mismatch (nothing written) or 1 after unpacking. This is CRSF's whole RC frame check.
#
# Two twins each, tested equal (tests/test_rx_fuzz.py). The indexed twins read each byte
# once into locals and allocate nothing: MicroPython's, and the source hoverfly.fastgen generates
# their viper from (accel/rxcodec.py, docs/fastpass.md; tests/portable/test_viper_twins.py holds
# them equal), which MicroPython runs where it loads. The struct twins fetch the bytes with one
# unpack_from and store with pack_into: on CPython that is ~1 µs of a ~5 µs frame, but the tuple
# would allocate on MicroPython.
#
# Viper reads raw memory without bounds checks: src must hold the whole frame (the framers call
# only with complete frames), raw/us/us_of_raw are array('H') (us_of_raw 2048 long) and crc_table
# 256 bytes. Every intermediate is a byte, an 11-bit value or an index: far from 2**31.


# fastpass: unpack11 src:B raw:H us:H us_of_raw:H
def _unpack11_indexed(src, p, raw, us, us_of_raw):
    c = 0
    while c < 16:
        b0 = src[p]
        b1 = src[p + 1]
        b2 = src[p + 2]
        b3 = src[p + 3]
        b4 = src[p + 4]
        b5 = src[p + 5]
        b6 = src[p + 6]
        b7 = src[p + 7]
        b8 = src[p + 8]
        b9 = src[p + 9]
        b10 = src[p + 10]
        v = (b0 | b1 << 8) & 0x7FF
        raw[c] = v
        us[c] = us_of_raw[v]
        v = (b1 >> 3 | b2 << 5) & 0x7FF
        raw[c + 1] = v
        us[c + 1] = us_of_raw[v]
        v = (b2 >> 6 | b3 << 2 | b4 << 10) & 0x7FF
        raw[c + 2] = v
        us[c + 2] = us_of_raw[v]
        v = (b4 >> 1 | b5 << 7) & 0x7FF
        raw[c + 3] = v
        us[c + 3] = us_of_raw[v]
        v = (b5 >> 4 | b6 << 4) & 0x7FF
        raw[c + 4] = v
        us[c + 4] = us_of_raw[v]
        v = (b6 >> 7 | b7 << 1 | b8 << 9) & 0x7FF
        raw[c + 5] = v
        us[c + 5] = us_of_raw[v]
        v = (b8 >> 2 | b9 << 6) & 0x7FF
        raw[c + 6] = v
        us[c + 6] = us_of_raw[v]
        v = (b9 >> 5 | b10 << 3) & 0x7FF
        raw[c + 7] = v
        us[c + 7] = us_of_raw[v]
        c += 8
        p += 11


# fastpass: check_unpack11 src:B raw:H us:H us_of_raw:H crc_table:B
def _check_unpack11_indexed(src, p, raw, us, us_of_raw, crc_table):
    t = crc_table
    c = t[src[p]]
    b0 = src[p + 1]
    c = t[c ^ b0]
    b1 = src[p + 2]
    c = t[c ^ b1]
    b2 = src[p + 3]
    c = t[c ^ b2]
    b3 = src[p + 4]
    c = t[c ^ b3]
    b4 = src[p + 5]
    c = t[c ^ b4]
    b5 = src[p + 6]
    c = t[c ^ b5]
    b6 = src[p + 7]
    c = t[c ^ b6]
    b7 = src[p + 8]
    c = t[c ^ b7]
    b8 = src[p + 9]
    c = t[c ^ b8]
    b9 = src[p + 10]
    c = t[c ^ b9]
    b10 = src[p + 11]
    c = t[c ^ b10]
    b11 = src[p + 12]
    c = t[c ^ b11]
    b12 = src[p + 13]
    c = t[c ^ b12]
    b13 = src[p + 14]
    c = t[c ^ b13]
    b14 = src[p + 15]
    c = t[c ^ b14]
    b15 = src[p + 16]
    c = t[c ^ b15]
    b16 = src[p + 17]
    c = t[c ^ b16]
    b17 = src[p + 18]
    c = t[c ^ b17]
    b18 = src[p + 19]
    c = t[c ^ b18]
    b19 = src[p + 20]
    c = t[c ^ b19]
    b20 = src[p + 21]
    c = t[c ^ b20]
    b21 = src[p + 22]
    c = t[c ^ b21]
    if c != src[p + 23]:
        return 0
    v = (b0 | b1 << 8) & 0x7FF
    raw[0] = v
    us[0] = us_of_raw[v]
    v = (b1 >> 3 | b2 << 5) & 0x7FF
    raw[1] = v
    us[1] = us_of_raw[v]
    v = (b2 >> 6 | b3 << 2 | b4 << 10) & 0x7FF
    raw[2] = v
    us[2] = us_of_raw[v]
    v = (b4 >> 1 | b5 << 7) & 0x7FF
    raw[3] = v
    us[3] = us_of_raw[v]
    v = (b5 >> 4 | b6 << 4) & 0x7FF
    raw[4] = v
    us[4] = us_of_raw[v]
    v = (b6 >> 7 | b7 << 1 | b8 << 9) & 0x7FF
    raw[5] = v
    us[5] = us_of_raw[v]
    v = (b8 >> 2 | b9 << 6) & 0x7FF
    raw[6] = v
    us[6] = us_of_raw[v]
    v = (b9 >> 5 | b10 << 3) & 0x7FF
    raw[7] = v
    us[7] = us_of_raw[v]
    v = (b11 | b12 << 8) & 0x7FF
    raw[8] = v
    us[8] = us_of_raw[v]
    v = (b12 >> 3 | b13 << 5) & 0x7FF
    raw[9] = v
    us[9] = us_of_raw[v]
    v = (b13 >> 6 | b14 << 2 | b15 << 10) & 0x7FF
    raw[10] = v
    us[10] = us_of_raw[v]
    v = (b15 >> 1 | b16 << 7) & 0x7FF
    raw[11] = v
    us[11] = us_of_raw[v]
    v = (b16 >> 4 | b17 << 4) & 0x7FF
    raw[12] = v
    us[12] = us_of_raw[v]
    v = (b17 >> 7 | b18 << 1 | b19 << 9) & 0x7FF
    raw[13] = v
    us[13] = us_of_raw[v]
    v = (b19 >> 2 | b20 << 6) & 0x7FF
    raw[14] = v
    us[14] = us_of_raw[v]
    v = (b20 >> 5 | b21 << 3) & 0x7FF
    raw[15] = v
    us[15] = us_of_raw[v]
    return 1


def _check_unpack11_struct(src, p, raw, us, us_of_raw, crc_table):
    t = crc_table
    (
        c, b0, b1, b2, b3, b4, b5, b6, b7, b8, b9, b10,
        b11, b12, b13, b14, b15, b16, b17, b18, b19, b20, b21, crc,
    ) = unpack_from("24B", src, p)
    c = t[c]
    c = t[c ^ b0]
    c = t[c ^ b1]
    c = t[c ^ b2]
    c = t[c ^ b3]
    c = t[c ^ b4]
    c = t[c ^ b5]
    c = t[c ^ b6]
    c = t[c ^ b7]
    c = t[c ^ b8]
    c = t[c ^ b9]
    c = t[c ^ b10]
    c = t[c ^ b11]
    c = t[c ^ b12]
    c = t[c ^ b13]
    c = t[c ^ b14]
    c = t[c ^ b15]
    c = t[c ^ b16]
    c = t[c ^ b17]
    c = t[c ^ b18]
    c = t[c ^ b19]
    c = t[c ^ b20]
    c = t[c ^ b21]
    if c != crc:
        return 0
    v0 = (b0 | b1 << 8) & 0x7FF
    v1 = (b1 >> 3 | b2 << 5) & 0x7FF
    v2 = (b2 >> 6 | b3 << 2 | b4 << 10) & 0x7FF
    v3 = (b4 >> 1 | b5 << 7) & 0x7FF
    v4 = (b5 >> 4 | b6 << 4) & 0x7FF
    v5 = (b6 >> 7 | b7 << 1 | b8 << 9) & 0x7FF
    v6 = (b8 >> 2 | b9 << 6) & 0x7FF
    v7 = (b9 >> 5 | b10 << 3) & 0x7FF
    v8 = (b11 | b12 << 8) & 0x7FF
    v9 = (b12 >> 3 | b13 << 5) & 0x7FF
    v10 = (b13 >> 6 | b14 << 2 | b15 << 10) & 0x7FF
    v11 = (b15 >> 1 | b16 << 7) & 0x7FF
    v12 = (b16 >> 4 | b17 << 4) & 0x7FF
    v13 = (b17 >> 7 | b18 << 1 | b19 << 9) & 0x7FF
    v14 = (b19 >> 2 | b20 << 6) & 0x7FF
    v15 = (b20 >> 5 | b21 << 3) & 0x7FF
    pack_into("16H", raw, 0, v0, v1, v2, v3, v4, v5, v6, v7,
              v8, v9, v10, v11, v12, v13, v14, v15)
    pack_into(
        "16H", us, 0,
        us_of_raw[v0], us_of_raw[v1], us_of_raw[v2], us_of_raw[v3],
        us_of_raw[v4], us_of_raw[v5], us_of_raw[v6], us_of_raw[v7],
        us_of_raw[v8], us_of_raw[v9], us_of_raw[v10], us_of_raw[v11],
        us_of_raw[v12], us_of_raw[v13], us_of_raw[v14], us_of_raw[v15],
    )
    return 1


def _unpack11_struct(src, p, raw, us, us_of_raw):
    (
        b0, b1, b2, b3, b4, b5, b6, b7, b8, b9, b10,
        b11, b12, b13, b14, b15, b16, b17, b18, b19, b20, b21,
    ) = unpack_from("22B", src, p)
    v0 = (b0 | b1 << 8) & 0x7FF
    v1 = (b1 >> 3 | b2 << 5) & 0x7FF
    v2 = (b2 >> 6 | b3 << 2 | b4 << 10) & 0x7FF
    v3 = (b4 >> 1 | b5 << 7) & 0x7FF
    v4 = (b5 >> 4 | b6 << 4) & 0x7FF
    v5 = (b6 >> 7 | b7 << 1 | b8 << 9) & 0x7FF
    v6 = (b8 >> 2 | b9 << 6) & 0x7FF
    v7 = (b9 >> 5 | b10 << 3) & 0x7FF
    v8 = (b11 | b12 << 8) & 0x7FF
    v9 = (b12 >> 3 | b13 << 5) & 0x7FF
    v10 = (b13 >> 6 | b14 << 2 | b15 << 10) & 0x7FF
    v11 = (b15 >> 1 | b16 << 7) & 0x7FF
    v12 = (b16 >> 4 | b17 << 4) & 0x7FF
    v13 = (b17 >> 7 | b18 << 1 | b19 << 9) & 0x7FF
    v14 = (b19 >> 2 | b20 << 6) & 0x7FF
    v15 = (b20 >> 5 | b21 << 3) & 0x7FF
    pack_into("16H", raw, 0, v0, v1, v2, v3, v4, v5, v6, v7,
              v8, v9, v10, v11, v12, v13, v14, v15)
    pack_into(
        "16H", us, 0,
        us_of_raw[v0], us_of_raw[v1], us_of_raw[v2], us_of_raw[v3],
        us_of_raw[v4], us_of_raw[v5], us_of_raw[v6], us_of_raw[v7],
        us_of_raw[v8], us_of_raw[v9], us_of_raw[v10], us_of_raw[v11],
        us_of_raw[v12], us_of_raw[v13], us_of_raw[v14], us_of_raw[v15],
    )


if IS_MICROPYTHON:
    unpack11 = _unpack11_indexed
    check_unpack11 = _check_unpack11_indexed
    try:  # generated from the indexed twins; absent, or a port without viper: they run as Python
        from hoverfly.accel import rxcodec as _viper

        unpack11 = _viper.unpack11
        check_unpack11 = _viper.check_unpack11
    except (ImportError, SyntaxError, NameError, ValueError, TypeError):  # TypeError: ViperTypeError
        pass
else:
    unpack11 = _unpack11_struct
    check_unpack11 = _check_unpack11_struct


def pack11(raw, out, p):
    """Pack 16 wire values (each masked to 11 bits) LSB first into out[p:p+22]."""
    c = 0
    while c < 16:
        v0 = raw[c] & 0x7FF
        v1 = raw[c + 1] & 0x7FF
        v2 = raw[c + 2] & 0x7FF
        v3 = raw[c + 3] & 0x7FF
        v4 = raw[c + 4] & 0x7FF
        v5 = raw[c + 5] & 0x7FF
        v6 = raw[c + 6] & 0x7FF
        v7 = raw[c + 7] & 0x7FF
        out[p] = v0 & 0xFF
        out[p + 1] = (v0 >> 8 | v1 << 3) & 0xFF
        out[p + 2] = (v1 >> 5 | v2 << 6) & 0xFF
        out[p + 3] = (v2 >> 2) & 0xFF
        out[p + 4] = (v2 >> 10 | v3 << 1) & 0xFF
        out[p + 5] = (v3 >> 7 | v4 << 4) & 0xFF
        out[p + 6] = (v4 >> 4 | v5 << 7) & 0xFF
        out[p + 7] = (v5 >> 1) & 0xFF
        out[p + 8] = (v5 >> 9 | v6 << 2) & 0xFF
        out[p + 9] = (v6 >> 6 | v7 << 5) & 0xFF
        out[p + 10] = (v7 >> 3) & 0xFF
        c += 8
        p += 11


def fill_raw(channels, raw, raw_of_us, pad_raw):
    """raw[c] = raw_of_us(channels[c]) for the given channels, pad_raw for the rest (encoders)."""
    n = len(channels)
    for c in range(CHANNELS):
        raw[c] = raw_of_us(channels[c]) if c < n else pad_raw

