"""FlySky iBUS (servo/RX stream) codec: 32-byte frames in, 14 channels out.

Takes the receiver's byte stream (115200 baud 8N1, not inverted; reference/protocols.md §3)
in any chunking through `IbusDecoder.feed`. Gives `channels_us` (the low 12 bits of each
of the 14 slots, which iBUS sends directly in µs; channels 15 and 16 read 1500 µs),
`channels_raw` (the 14 slots as sent, all 16 bits; 15-16 read 0) and counters. It sits at
the start of the receiver task. `encode_rc_frame` builds frames for the simulator and tests.

Frame: `0x20` (frame length 32), `0x40` (command: channel data), 14 × u16 LE, u16 LE
checksum = 0xFFFF - (sum of bytes 0..29) & 0xFFFF. Betaflight only checks the first byte;
here a frame starts at 0x20 0x40 (a 0x20 followed by anything else is not a channel frame
and counts in `length_errors`), and a bad checksum counts in `crc_errors`.
The top nibbles some receivers use for channels 15-18 are not decoded (old receivers
leave them 0, which would read as 0 µs).
"""

from hoverfly.compat import const
from hoverfly.protocols.rxcodec import CENTRE_US, SerialRxDecoder

HEADER = const(0x20)
COMMAND_CHANNELS = const(0x40)
FRAME_LEN = const(32)
IBUS_CHANNELS = const(14)


def _sync_table():
    t = bytearray(256)
    t[HEADER] = 1
    return bytes(t)


class IbusDecoder(SerialRxDecoder):
    """Streaming iBUS decoder; see the module docstring and rxcodec.SerialRxDecoder."""

    _SYNC = _sync_table()
    _HEADER = 2
    _MAX_FRAME = FRAME_LEN

    def __init__(self):
        super().__init__()
        us = self.channels_us
        for c in range(IBUS_CHANNELS, 16):
            us[c] = CENTRE_US

    def _frame_len(self, src, i):
        if src[i + 1] != COMMAND_CHANNELS:
            return 0
        return FRAME_LEN

    def _take(self, src, i, total):
        s = 0
        for k in range(i, i + 30):
            s += src[k]
        if (0xFFFF - s) & 0xFFFF != src[i + 30] | src[i + 31] << 8:
            self.crc_errors += 1
            return -1
        raw = self.channels_raw
        us = self.channels_us
        p = i + 2
        for c in range(IBUS_CHANNELS):
            v = src[p] | src[p + 1] << 8
            raw[c] = v
            us[c] = v & 0x0FFF
            p += 2
        self.frames += 1
        return 1


def encode_rc_frame_raw(slots, out=None):
    """A 32-byte iBUS frame from up to 14 slot values (u16, masked; missing slots 1500)."""
    if out is None:
        out = bytearray(FRAME_LEN)
    out[0] = HEADER
    out[1] = COMMAND_CHANNELS
    n = len(slots)
    p = 2
    for c in range(IBUS_CHANNELS):
        v = (slots[c] & 0xFFFF) if c < n else CENTRE_US
        out[p] = v & 0xFF
        out[p + 1] = v >> 8
        p += 2
    s = 0
    for k in range(30):
        s += out[k]
    s = (0xFFFF - s) & 0xFFFF
    out[30] = s & 0xFF
    out[31] = s >> 8
    return out


_SLOTS = [0] * IBUS_CHANNELS  # encoder scratch: not re-entrant


def encode_rc_frame(channels_us, out=None):
    """A 32-byte iBUS frame from up to 14 µs values (rounded, clamped to 0..4095; missing ones 1500).

    Channels beyond the 14th are ignored: iBUS does not carry them.
    """
    n = len(channels_us)
    slots = _SLOTS
    for c in range(IBUS_CHANNELS):
        if c < n:
            v = int(round(channels_us[c]))
            slots[c] = 0 if v < 0 else (0x0FFF if v > 0x0FFF else v)
        else:
            slots[c] = CENTRE_US
    return encode_rc_frame_raw(slots, out)
