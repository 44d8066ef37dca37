"""BridgeDecoder.feed_frame (the host's one-copy path for an answer read whole) delivers and counts exactly
what feed() does, for whole frames, damaged ones, split ones and several in one chunk."""

import random

from hoverfly.protocols import bridge as B


def _state(dec):
    frames = []
    while dec.pending():
        kind = dec.pop()
        frames.append((kind, bytes(dec.payload[:dec.length])))
    return (frames, dec.frames, dec.crc_errors, dec.length_errors, dec.kind_errors, dec.resyncs, dec.overruns,
            dec.bytes)


def _both(chunks):
    slow = B.BridgeDecoder(depth=4)
    fast = B.BridgeDecoder(depth=4)
    for c in chunks:
        slow.feed(c)
        fast.feed_frame(c)
    return _state(slow), _state(fast)


def test_a_whole_good_frame_is_delivered_as_feed_delivers_it():
    out = B.frame(B.OUT, bytes(range(40)))
    slow, fast = _both([out])
    assert fast == slow
    assert fast[0] == [(B.OUT, bytes(range(40)))]


def test_a_frame_with_a_bad_crc_or_length_is_counted_as_feed_counts_it():
    good = bytearray(B.frame(B.OUT, bytes(range(40))))
    bad_crc = bytearray(good)
    bad_crc[-1] ^= 0x55
    bad_body = bytearray(good)
    bad_body[10] ^= 0x01
    too_long = bytearray(good) + b"\x00"
    for chunk in (bad_crc, bad_body, too_long, good[:-3], b"\x00" + good, bytes(good) * 2):
        slow, fast = _both([bytes(chunk), bytes(good)])
        assert fast == slow, chunk


def test_random_chunks_of_a_damaged_stream_decode_alike():
    rng = random.Random(29)
    stream = bytearray()
    for _ in range(200):
        f = bytearray(B.frame(rng.choice(B.KINDS), bytes(rng.randrange(256) for _ in range(rng.randrange(60)))))
        if rng.random() < 0.2:
            f[rng.randrange(len(f))] = rng.randrange(256)
        stream += f
    chunks = []
    i = 0
    while i < len(stream):
        n = rng.randrange(1, 90)
        chunks.append(bytes(stream[i:i + n]))
        i += n
    slow, fast = _both(chunks)
    assert fast == slow


def test_take_frame_counts_a_whole_good_frame_as_feed_does_and_leaves_its_payload_where_it_is():
    out = B.frame(B.OUT, bytes(range(40)))
    slow = B.BridgeDecoder(depth=4)
    slow.feed(out)
    taker = B.BridgeDecoder(depth=4)
    assert taker.take_frame(out) == B.OUT
    assert (taker.frames, taker.bytes, taker.pending()) == (slow.frames, slow.bytes, 0)
    assert out[B.HEADER:len(out) - 1] == bytes(range(40))


def test_take_frame_takes_nothing_that_is_not_exactly_one_good_frame():
    good = bytearray(B.frame(B.OUT, bytes(range(40))))
    bad_crc = bytearray(good)
    bad_crc[-1] ^= 0x55
    for chunk in (bad_crc, good + b"\x00", good[:-3], b"\x00" + good, good * 2):
        dec = B.BridgeDecoder(depth=4)
        assert dec.take_frame(bytes(chunk)) == -1
        assert (dec.frames, dec.bytes, dec.crc_errors) == (0, 0, 0)
    # nor while a frame is half received: the chunk belongs after it
    dec = B.BridgeDecoder(depth=4)
    dec.feed(bytes(good[:10]))
    assert dec.take_frame(bytes(good)) == -1
