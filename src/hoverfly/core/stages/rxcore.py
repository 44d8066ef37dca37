"""The serial receiver parsed on the second core, handed to the flight loop without a lock.

The RP2040 and RP2350 have two cores; MicroPython's `_thread` starts a function on core 1, and
the rp2 port has no global interpreter lock, so both cores run Python at once (seed 000 splits its
work the same way). With `rx_core1` on, core 1 owns the receiver UART and the protocol codec: it reads
the bytes, frames and checks them, and publishes each result; the flight loop on core 0 only picks up
what was published, in the receiver task, and sends its telemetry frames back through the same
handover (core 1 writes them to the UART, so one core alone touches it).

The handover (`RxLink`) is a sequence lock with one writer and one reader, on preallocated arrays only:
- the writer makes the sequence word odd, writes the frame count, the flags, the error and link
  statistics words and the 16 channels, then makes the sequence word even again;
- the reader takes the sequence word; when it is even and new, it copies everything and reads the
  word again: if it moved, the copy may be torn and is dropped (the next poll takes the newer one).
Each word is a 32-bit array element, stored and loaded whole by one instruction on the Cortex-M0+
and M33, which keep their stores in order; nothing here allocates, so core 1 never waits on the
heap's lock while core 0 collects. Counters wrap at 2**30 (small ints on both ports).

A core-1 loop that raises stops publishing: the link watch on core 0 then sees no frames and the
failsafe runs as for a receiver gone quiet; `fault` says why (the board's status line shows it).
The same code runs as a thread on CPython and on the MicroPython unix port (the tests), and its
`poll` can be stepped by hand for a deterministic run.
"""

from array import array

from hoverfly.compat import const, sleep_us
from hoverfly.protocols.rxcodec import CHANNELS

MASK = const(0x3FFFFFFF)  # counters and the sequence wrap here: small ints on a 32-bit port
TX_BYTES = const(64)  # one telemetry frame (CRSF frames are at most 64 bytes)

# words of RxLink.words
W_SEQ = const(0)  # odd while core 1 writes
W_FRAMES = const(1)  # valid RC frames decoded, all told (wraps at MASK)
W_FAILSAFE = const(2)  # the last frame carried the receiver's failsafe flag (SBUS)
W_LOST = const(3)  # the last frame was a repeat (SBUS frame lost)
W_CRC = const(4)  # codec errors, all told: CRC / checksum
W_LENGTH = const(5)  # and impossible lengths / footers
W_STATS = const(6)  # CRSF link-statistics frames, all told
W_LQ = const(7)  # their link quality (%), RSSI (dBm) and SNR (dB)
W_RSSI = const(8)
W_SNR = const(9)
W_TX_LEN = const(10)  # telemetry bytes waiting in RxLink.tx for core 1 (0 = the buffer is free)
W_STOP = const(11)  # core 0 sets it: core 1's loop returns
W_POLLS = const(12)  # core 1's reads, all told (it is alive while this moves)
W_RUNNING = const(13)  # 1 while core 1's loop runs
_WORDS = const(14)

IDLE_US = const(200)  # core 1 rests this long after a read that found nothing (a CRSF frame is 0.6 ms)


class RxLink:
    """What the two cores share: words, the last frame's channels, one telemetry frame."""

    def __init__(self):
        self.words = array("i", [0] * _WORDS)
        self.channels_us = array("H", [1500] * CHANNELS)
        self.tx = bytearray(TX_BYTES)
        self.fault = None  # the exception that stopped core 1's loop, if one did


class RxCore:
    """Core 1's side: the UART read through the codec, each result published to the link."""

    def __init__(self, link, decoder):
        self.link = link
        self.decoder = decoder
        self._buf = bytearray(64)
        self._chan = memoryview(link.channels_us)
        self._seen = -1  # the codec's counts at the last publish, summed (publish only when one moved)
        self._crsf = hasattr(decoder, "link_stats_frames")

    def poll(self, board):
        """One read: feed the codec, publish what changed, send a waiting telemetry frame. The byte count."""
        w = self.link.words
        n = board.read_rx(self._buf)
        if n > 0:
            dec = self.decoder
            new = dec.feed(self._buf, n)
            seen = dec.crc_errors + dec.length_errors
            if self._crsf:
                seen += dec.link_stats_frames
            if new or seen != self._seen:
                self._seen = seen
                self._publish(new)
        tx = w[W_TX_LEN]
        if tx:
            board.write_rx(self.link.tx, tx)
            w[W_TX_LEN] = 0
        w[W_POLLS] = (w[W_POLLS] + 1) & MASK
        return n

    def _publish(self, new):
        dec = self.decoder
        w = self.link.words
        seq = w[W_SEQ]
        w[W_SEQ] = (seq + 1) & MASK  # odd: a reader that sees this drops its copy
        if new:
            self._chan[0:CHANNELS] = dec.channels_us
            w[W_FRAMES] = (w[W_FRAMES] + new) & MASK
            w[W_FAILSAFE] = 1 if dec.failsafe else 0
            w[W_LOST] = 1 if dec.frame_lost else 0
        w[W_CRC] = dec.crc_errors & MASK
        w[W_LENGTH] = dec.length_errors & MASK
        if self._crsf:
            w[W_LQ] = dec.link_quality_pct
            w[W_RSSI] = dec.rssi_dbm
            w[W_SNR] = dec.snr_db
            w[W_STATS] = dec.link_stats_frames & MASK
        w[W_SEQ] = (seq + 2) & MASK  # even again: the copy is whole

    def run(self, board):
        """Core 1's loop, until core 0 sets W_STOP; an exception stops it and is kept in link.fault."""
        link = self.link
        w = link.words
        w[W_RUNNING] = 1
        try:
            while not w[W_STOP]:
                if self.poll(board) <= 0:
                    sleep_us(IDLE_US)
        except Exception as exc:  # the link watch fails safe on the silence; the status says why
            link.fault = exc
        w[W_RUNNING] = 0


class LinkView:
    """Core 0's side: the last whole copy of what core 1 published, with the attributes the receiver
    reads from a codec (channels_us, failsafe, frame_lost, the error and link-statistics counts)."""

    def __init__(self, link):
        self.link = link
        self.channels_us = array("H", [1500] * CHANNELS)
        self._view = memoryview(self.channels_us)
        self._scratch = array("H", [1500] * CHANNELS)  # a copy lands here until it is known whole
        self._scratch_view = memoryview(self._scratch)
        self.words = array("i", [0] * _WORDS)  # the last whole copy of RxLink.words
        self._words_view = memoryview(self.words)
        self.failsafe = False
        self.frame_lost = False
        self.crc_errors = 0
        self.length_errors = 0
        self.link_stats_frames = 0
        self.link_quality_pct = 0
        self.rssi_dbm = 0
        self.snr_db = 0
        self.frames = 0  # as W_FRAMES at the last whole copy
        self.torn = 0  # copies dropped because core 1 wrote meanwhile
        self._seq = 0

    def take(self):
        """New valid frames since the last take; -1 when core 1 published nothing new since (or the copy was
        torn: the next take has the newer one). 0: a publish without frames (error or link-statistics counts
        moved). Everything is copied at once into `words` (this side's copy of RxLink.words) and a scratch
        buffer, and kept only if the sequence word did not move meanwhile; the attributes follow the copy."""
        link = self.link
        w = link.words
        seq = w[W_SEQ]
        if seq == self._seq or seq & 1:
            return -1
        self._words_view[0:_WORDS] = w  # one copy each, no allocation: then the sequence word again
        self._scratch_view[0:CHANNELS] = link.channels_us
        if w[W_SEQ] != seq:
            self.torn += 1  # the copy may be half old, half new
            return -1
        self._seq = seq
        c = self.words
        new = (c[W_FRAMES] - self.frames) & MASK
        if new:
            self.frames = c[W_FRAMES]
            self._view[0:CHANNELS] = self._scratch
            self.failsafe = c[W_FAILSAFE] != 0
            self.frame_lost = c[W_LOST] != 0
        self.crc_errors = c[W_CRC]
        self.length_errors = c[W_LENGTH]
        if c[W_STATS] != self.link_stats_frames:
            self.link_stats_frames = c[W_STATS]
            self.link_quality_pct = c[W_LQ]
            self.rssi_dbm = c[W_RSSI]
            self.snr_db = c[W_SNR]
        return new

    def tx_buffer(self):
        """The buffer to build the next telemetry frame in (then `send`), or None while core 1 has not
        written the last one yet (the frame waits for the next slot: nothing is built, nothing lost)."""
        if self.link.words[W_TX_LEN]:
            return None
        return self.link.tx

    def send(self, n):
        """The frame built in tx_buffer(), n bytes, for core 1 to write."""
        self.link.words[W_TX_LEN] = n

    def stop(self):
        self.link.words[W_STOP] = 1
