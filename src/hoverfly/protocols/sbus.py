"""SBUS (Futaba, FrSky, ELRS "SBUS" output) codec: 25-byte frames in, 16 channels and flags out.

Takes the receiver's byte stream (100000 baud, 8 data bits, even parity, 2 stop bits,
inverted line; reference/protocols.md §2) in any chunking through `SbusDecoder.feed`.
The inversion and the 8E2 framing are the board's business (on the rp2 the UART inverts
with `invert=UART.INV_RX`); this codec only ever sees bytes. Gives 16 channels
(`channels_raw` 11-bit wire values, `channels_us`), the digital channels `ch17`/`ch18`,
`frame_lost` (flag bit 2: the receiver repeated an old frame) and `failsafe` (flag bit 3),
plus counters. It sits at the start of the receiver task. `encode_rc_frame` builds frames
for the simulator and tests.

Frame: `0x0F`, 22 bytes of 16 × 11-bit channels packed LSB first (as CRSF), flags, footer.
SBUS has no checksum; Betaflight frames by timing instead. A byte stream has no timing,
so the footer is checked: 0x00, or an SBUS2 slot footer 0x04/0x14/0x24/0x34 (what
SBUS2 receivers send). A frame with another footer is refused and counted in
`length_errors` (the frame did not end where a frame ends) and the search restarts one
byte after its 0x0F. Receivers that put other values there need `check_footer=False`;
a board that sees UART idle gaps can also call `idle()` to resynchronise.
Frames with frame_lost or failsafe set are still decoded and counted in `frames`
(the flags say what they are; `lost_frames` / `failsafe_frames` count them).

µs mapping (Betaflight): `us = 5 * raw / 8 + 880`, rounded half up to whole µs
(173 -> 988, 992 -> 1500, 1812 -> 2013 from 2012.5); the encoder picks the raw value that
decodes back to the same µs (988 -> 172, 1500 -> 992, 2012 -> 1811), so
decode(encode(us)) == us over 880..2159 µs.
"""

from array import array

from hoverfly.compat import const
from hoverfly.protocols.rxcodec import SerialRxDecoder, fill_raw, new_channels, pack11, unpack11

HEADER = const(0x0F)
FRAME_LEN = const(25)
FLAG_CH17 = const(0x01)
FLAG_CH18 = const(0x02)
FLAG_FRAME_LOST = const(0x04)
FLAG_FAILSAFE = const(0x08)
RAW_CENTRE = const(992)


def _sync_table():
    t = bytearray(256)
    t[HEADER] = 1
    return bytes(t)


def _footer_table():
    t = bytearray(256)
    for b in (0x00, 0x04, 0x14, 0x24, 0x34):
        t[b] = 1
    return bytes(t)


_FOOTER_OK = _footer_table()


def us_of_raw(raw):
    return ((raw * 5 + 4) >> 3) + 880


def raw_of_us(us):
    t = (8 * (int(round(us)) - 880)) // 5
    if t < 0:
        return 0
    if t > 2047:
        return 2047
    return t


def _us_table():
    t = array("H")
    for v in range(2048):
        t.append(us_of_raw(v))
    return t


US_OF_RAW = _us_table()


class SbusDecoder(SerialRxDecoder):
    """Streaming SBUS decoder; see the module docstring and rxcodec.SerialRxDecoder."""

    _SYNC = _sync_table()
    _HEADER = 1
    _MAX_FRAME = FRAME_LEN

    def __init__(self, check_footer=True):
        super().__init__()
        self.check_footer = check_footer
        self.ch17 = False
        self.ch18 = False
        self.flags = 0
        self.lost_frames = 0
        self.failsafe_frames = 0

    def _frame_len(self, src, i):
        return FRAME_LEN

    def _take(self, src, i, total):
        if self.check_footer and not _FOOTER_OK[src[i + 24]]:
            self.length_errors += 1
            return -1
        unpack11(src, i + 1, self.channels_raw, self.channels_us, US_OF_RAW)
        flags = src[i + 23]
        self.flags = flags
        self.ch17 = bool(flags & FLAG_CH17)
        self.ch18 = bool(flags & FLAG_CH18)
        lost = bool(flags & FLAG_FRAME_LOST)
        failsafe = bool(flags & FLAG_FAILSAFE)
        self.frame_lost = lost
        self.failsafe = failsafe
        if lost:
            self.lost_frames += 1
        if failsafe:
            self.failsafe_frames += 1
        self.frames += 1
        return 1


_RAW = new_channels()  # encoder scratch: not re-entrant


def encode_rc_frame_raw(channels_raw, out=None, ch17=False, ch18=False, frame_lost=False, failsafe=False,
                        footer=0):
    """A 25-byte SBUS frame from 16 raw 11-bit values and the four flags."""
    if out is None:
        out = bytearray(FRAME_LEN)
    out[0] = HEADER
    pack11(channels_raw, out, 1)
    flags = 0
    if ch17:
        flags |= FLAG_CH17
    if ch18:
        flags |= FLAG_CH18
    if frame_lost:
        flags |= FLAG_FRAME_LOST
    if failsafe:
        flags |= FLAG_FAILSAFE
    out[23] = flags
    out[24] = footer & 0xFF
    return out


def encode_rc_frame(channels_us, out=None, ch17=False, ch18=False, frame_lost=False, failsafe=False):
    """A 25-byte SBUS frame from up to 16 µs values (missing ones 1500 µs) and the four flags."""
    fill_raw(channels_us, _RAW, raw_of_us, RAW_CENTRE)
    return encode_rc_frame_raw(_RAW, out, ch17, ch18, frame_lost, failsafe)
