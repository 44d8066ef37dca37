"""The firmware's serve loop checks a frame it has framed by its lengths with frame_crc_ok: it must
accept exactly what the bridge decoder accepts, and answer a damaged frame with an ERROR, never act on it."""

import io

from hypothesis import given, settings
from hypothesis import strategies as st

from hoverfly.boards.bridge_fw import BAD, END, RX_SIZE, Firmware, FrameReader, serve
from hoverfly.protocols import bridge as B


@settings(max_examples=300, deadline=None)
@given(kind=st.sampled_from(B.KINDS), payload=st.binary(max_size=80), flip_at=st.integers(0, 200),
       flip=st.integers(1, 255))
def test_frame_crc_ok_agrees_with_the_decoder_on_intact_and_damaged_frames(kind, payload, flip_at, flip):
    f = bytearray(B.frame(kind, payload))
    if flip_at < len(f) - 1 and flip_at >= 4:  # damage the payload or the CRC, keep the framing
        f[flip_at] ^= flip
    n = len(payload)
    dec = B.BridgeDecoder()
    assert B.frame_crc_ok(f, n) == (dec.feed(bytes(f)) == 1)


def test_a_damaged_step_is_answered_with_an_error_and_not_flown():
    good = B.frame(B.HELLO, B.VERSION.encode())
    bad = bytearray(B.frame(B.BOOT, b"\x00\x00\x00\x00"))
    bad[5] ^= 0x40  # a payload bit flipped on the way
    out = io.BytesIO()
    fw = Firmware()
    assert serve(io.BytesIO(good + bytes(bad) + B.frame(B.QUIT)), out, fw) == 0
    d = B.BridgeDecoder()
    d.feed(out.getvalue())
    assert d.pop() == B.HELLO
    assert d.pop() == B.ERROR and "CRC" in d.text()
    assert fw.flight is None  # the damaged BOOT built nothing
    assert d.pop() == B.ACK


class _Trickle(io.BytesIO):
    """A stream whose readinto hands over at most `most` bytes a call, as a USB port or a pipe may."""

    def __init__(self, data, most):
        io.BytesIO.__init__(self, data)
        self.most = most
        self.reads = 0

    def readinto(self, buf):
        self.reads += 1
        view = memoryview(buf)
        return io.BytesIO.readinto(self, view[:self.most] if len(view) > self.most else view)


def _served(stream):
    """What FrameReader hands out of stream: (kind, payload) for each good frame, "BAD" for a CRC failure."""
    buf = bytearray(RX_SIZE)
    reader = FrameReader(stream.readinto, buf)
    got = []
    while True:
        kind = reader.next()
        if kind == END:
            return got, reader
        got.append("BAD" if kind == BAD else (kind, bytes(buf[B.HEADER:B.HEADER + reader.length])))


@settings(max_examples=200, deadline=None)
@given(frames=st.lists(st.tuples(st.sampled_from(B.KINDS), st.binary(max_size=60)), min_size=1, max_size=8),
       garbage=st.lists(st.binary(max_size=12), min_size=9, max_size=9), most=st.integers(1, 70),
       flip=st.integers(-1, 7))
def test_the_serve_loop_frames_a_stream_as_the_decoder_does_whatever_the_reads_bring(frames, garbage, most, flip):
    # given frames with garbage between them (no sync byte in it: then the decoder and the reader can only
    # pick up at a real frame start), one of them damaged in its payload or CRC, arriving a few bytes a read
    stream = bytearray()
    for i, (kind, payload) in enumerate(frames):
        stream += bytes(b for b in garbage[i] if b != B.SYNC)
        f = bytearray(B.frame(kind, payload))
        if i == flip:
            f[-1] ^= 0x5A
        stream += f
    dec = B.BridgeDecoder(depth=16)
    dec.feed(bytes(stream))
    expected = []
    while dec.pending():
        kind = dec.pop()
        expected.append((kind, bytes(dec.payload[:dec.length])))
    # when the firmware's reader takes them
    got, reader = _served(_Trickle(bytes(stream), most))
    # then it hands out the decoder's frames in order, and reports the damaged one instead of using it
    assert [g for g in got if g != "BAD"] == expected
    assert got.count("BAD") == reader.crc_errors == dec.crc_errors
    assert reader.frames == dec.frames


def test_the_reader_asks_only_for_what_the_frame_lacks():
    # a read that asks past the frame would wait on a Pico's USB (and on MicroPython's pipes) for bytes the
    # host sends only after this frame's answer: two reads a frame, header then the rest
    stream = _Trickle(B.frame(B.STEP, bytes(60)) + B.frame(B.QUIT), 4096)
    asked = []
    read = stream.readinto

    def readinto(buf):
        asked.append(len(buf))
        return read(buf)

    stream.readinto = readinto
    got, _ = _served(stream)
    assert [g[0] for g in got] == [B.STEP, B.QUIT]
    assert asked[:4] == [B.HEADER, 60 + 1, B.HEADER, 1]


def test_garbage_an_unknown_kind_and_a_length_past_the_maximum_are_skipped_and_counted():
    bad_kind = bytes([B.SYNC, 0x7E, 1, 0, 9, 9])
    too_long = bytes([B.SYNC, B.STEP, 0xFF, 0xFF])
    got, reader = _served(io.BytesIO(b"\x00\x01\x02" + bad_kind + too_long + B.frame(B.ACK, b"ok")))
    assert got == [(B.ACK, b"ok")]
    assert reader.kind_errors == 1 and reader.length_errors == 1 and reader.resyncs >= 3
