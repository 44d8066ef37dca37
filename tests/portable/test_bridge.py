"""Bridge framing (protocols/bridge.py): round trips, any chunking, CRC and resync counting."""

from struct import pack_into, unpack_from

from hoverfly.protocols import bridge as B


def test_frame_round_trips_through_the_decoder():
    f = B.frame(B.ACK, b"hello")
    assert f[0] == 0xB5 and f[1] == B.ACK and f[2] == 5 and f[3] == 0
    d = B.BridgeDecoder()
    assert d.feed(f) == 1
    assert d.pop() == B.ACK
    assert d.text() == "hello"
    assert d.pop() == -1


def test_empty_payload_frame():
    d = B.BridgeDecoder()
    assert d.feed(B.frame(B.QUIT)) == 1
    assert d.pop() == B.QUIT and d.length == 0


def test_byte_by_byte_feed_gives_the_same_frames():
    data = B.frame(B.PARAMS, b"p_roll=50") + B.frame(B.BOOT, b"\x00\x00\x00\x00")
    d = B.BridgeDecoder()
    done = 0
    for i in range(len(data)):
        done += d.feed(data[i:i + 1])
    assert done == 2
    assert d.pop() == B.PARAMS and d.text() == "p_roll=50"
    assert d.pop() == B.BOOT and d.length == 4


def test_bad_crc_is_counted_and_the_next_frame_still_decodes():
    bad = bytearray(B.frame(B.ACK, b"x"))
    bad[-1] ^= 0xFF
    d = B.BridgeDecoder()
    assert d.feed(bytes(bad) + B.frame(B.ACK, b"y")) == 1
    assert d.crc_errors == 1
    assert d.pop() == B.ACK and d.text() == "y"


def test_garbage_before_a_frame_counts_resyncs():
    d = B.BridgeDecoder()
    assert d.feed(b"\x00\x01abc" + B.frame(B.OUT, b"\x01")) == 1
    assert d.resyncs == 5


def test_impossible_length_is_counted():
    d = B.BridgeDecoder()
    d.feed(bytes([0xB5, B.STEP, 0xFF, 0xFF]))
    assert d.length_errors == 1 and d.frames == 0


def test_step_payload_layout():
    buf = bytearray(B.MAX_PAYLOAD + B.OVERHEAD)
    pack_into(B.STEP_FMT, buf, B.HEADER, 123456, B.STEP_IMU_FRESH, 0.5, -0.25, 0.0, 0.0, 0.0, -9.75,
              1.0, 0.0, 0.0, 0.0, 16.5, 3.25)
    buf[B.HEADER + B.STEP_SIZE] = 0xC8
    n = B.finish(buf, B.STEP, B.STEP_SIZE + 1)
    d = B.BridgeDecoder()
    assert d.feed(buf, n) == 1
    assert d.pop() == B.STEP and d.length == B.STEP_SIZE + 1
    v = unpack_from(B.STEP_FMT, d.payload, 0)
    assert v[0] == 123456 and v[1] == 1 and v[2] == 0.5 and v[7] == -9.75 and v[13] == 3.25
    assert d.payload[B.STEP_SIZE] == 0xC8


def test_event_records_clamp_to_32_bits():
    buf = bytearray(B.EVENT_SIZE)
    B.put_event(buf, 0, 5000, 3, 1 << 40)
    t, e, detail = unpack_from(B.EVENT_FMT, buf, 0)
    assert (t, e, detail) == (5000, 3, 0x7FFFFFFF)


def test_oversized_payload_is_refused():
    try:
        B.frame(B.PARAMS, bytes(B.MAX_PAYLOAD + 1))
    except ValueError:
        return
    raise AssertionError("expected ValueError")
