"""The firmware's serve loop checks a frame it has framed by its lengths with frame_crc_ok: it must
accept exactly what the bridge decoder accepts, and answer a damaged frame with an ERROR, never act on it."""

import io

from hypothesis import given, settings
from hypothesis import strategies as st

from hoverfly.boards.bridge_fw import Firmware, serve
from hoverfly.protocols import bridge as B


@settings(max_examples=300, deadline=None)
@given(kind=st.sampled_from(B.KINDS), payload=st.binary(max_size=80), flip_at=st.integers(0, 200),
       flip=st.integers(1, 255))
def test_frame_crc_ok_agrees_with_the_decoder_on_intact_and_damaged_frames(kind, payload, flip_at, flip):
    f = bytearray(B.frame(kind, payload))
    if flip_at < len(f) - 1 and flip_at >= 4:  # damage the payload or the CRC, keep the framing
        f[flip_at] ^= flip
    n = len(payload)
    head = f[1:4]
    body = f[4:]
    dec = B.BridgeDecoder()
    assert B.frame_crc_ok(head, body, n) == (dec.feed(bytes(f)) == 1)


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
