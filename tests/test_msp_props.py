"""MSP parser properties (hypothesis): any bytes, any chunking, corruption and garbage never raise;
valid frames around them are decoded exactly once, in order, and the drops are counted."""

from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from hoverfly.protocols import msp
from hoverfly.protocols.msp import MspParser

SETTINGS = settings(max_examples=300, derandomize=True, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])
MAX_PAYLOAD = 400

NO_DOLLAR = st.binary(max_size=40).map(lambda b: b.replace(b"$", b"#"))
ANY_PAYLOAD = st.binary(max_size=300)


@st.composite
def messages(draw, payload=ANY_PAYLOAD):
    kind = draw(st.sampled_from(("v1", "v2", "v2v1")))
    direction = draw(st.sampled_from((msp.DIR_REQUEST, msp.DIR_REPLY, msp.DIR_ERROR)))
    data = draw(payload)
    if kind == "v1":
        cmd = draw(st.integers(0, 254))
        frame = msp.encode_v1(cmd, data, direction)
        return frame, (1, direction, cmd, data, False)
    cmd = draw(st.integers(0, 0xFFFF))
    flags = draw(st.integers(0, 255))
    if kind == "v2":
        frame = msp.encode_v2(cmd, data, direction, flags=flags)
        return frame, (2, direction, cmd, data, False)
    data = data[:MAX_PAYLOAD - 6]
    frame = msp.encode_v2_over_v1(cmd, data, direction, flags=flags)
    return frame, (2, direction, cmd, data, True)


def _cuts(draw_list, total):
    return sorted(set(c % (total + 1) for c in draw_list))


def _feed_in_pieces(parser, stream, cuts):
    got = []
    prev = 0
    for c in list(cuts) + [len(stream)]:
        parser.feed(stream[prev:c])
        prev = c
        while parser.pop():
            got.append((parser.version, parser.direction, parser.cmd, parser.message(), parser.encapsulated))
    return got


@SETTINGS
@given(st.binary(max_size=2000), st.lists(st.integers(0, 4000), max_size=8))
def test_random_bytes_never_raise_and_counters_add_up(data, cuts):
    p = MspParser(max_payload=MAX_PAYLOAD, queue_depth=64)
    got = _feed_in_pieces(p, data, _cuts(cuts, len(data)))
    assert p.bytes == len(data)
    assert len(got) + p.dropped == p.frames
    for m in got:
        assert len(m[3]) <= MAX_PAYLOAD


@SETTINGS
@given(st.lists(st.tuples(NO_DOLLAR, messages()), min_size=1, max_size=6), NO_DOLLAR,
       st.lists(st.integers(0, 4000), max_size=10))
def test_frames_between_garbage_in_any_chunking_are_all_decoded_in_order(items, tail, cuts):
    stream = b"".join(g + f for g, (f, _) in items) + tail
    p = MspParser(max_payload=MAX_PAYLOAD, queue_depth=8)
    got = _feed_in_pieces(p, stream, _cuts(cuts, len(stream)))
    assert got == [m for _, (_, m) in items]
    assert p.crc_errors == 0 and p.oversize == 0
    assert p.resyncs == sum(len(g) for g, _ in items) + len(tail)


@SETTINGS
@given(messages(payload=NO_DOLLAR.filter(len)), st.data(), messages(),
       st.lists(st.integers(0, 4000), max_size=6))
def test_bad_checksum_frame_is_dropped_counted_and_the_next_decoded(bad, data, good, cuts):
    frame, _ = bad
    assume(b"$" not in frame[1:])  # no false start inside the broken frame to swallow the good one
    frame = bytearray(frame)
    header = 8 if frame[1] == ord("X") else (7 if frame[3] == 255 else 5)
    k = data.draw(st.integers(header, len(frame) - 1))  # a payload or checksum byte: length unchanged
    frame[k] = data.draw(st.sampled_from([v for v in range(256) if v != frame[k] and v != 0x24]))
    stream = bytes(frame) + good[0]
    p = MspParser(max_payload=MAX_PAYLOAD, queue_depth=8)
    got = _feed_in_pieces(p, stream, _cuts(cuts, len(stream)))
    assert got == [good[1]]
    assert p.crc_errors == 1


@SETTINGS
@given(messages(), st.data(), messages(), st.lists(st.integers(0, 4000), max_size=6))
def test_truncated_frame_then_idle_line_then_next_frame_decoded(cut_msg, data, good, cuts):
    frame = cut_msg[0]
    cut = data.draw(st.integers(1, len(frame) - 1))
    p = MspParser(max_payload=MAX_PAYLOAD, queue_depth=8)
    assert _feed_in_pieces(p, frame[:cut], _cuts(cuts, cut)) == []
    p.idle()
    assert p.length_errors + p.resyncs >= 1
    assert _feed_in_pieces(p, good[0], []) == [good[1]]


@SETTINGS
@given(messages())
def test_split_anywhere_decodes_once(m):
    frame, expect = m
    for cut in range(0, len(frame) + 1, max(1, len(frame) // 40)):
        p = MspParser(max_payload=MAX_PAYLOAD)
        assert _feed_in_pieces(p, frame, [cut]) == [expect]


@SETTINGS
@given(st.integers(MAX_PAYLOAD + 1, 3000), messages())
def test_oversize_declared_frames_are_counted_and_skipped(size, good):
    big = msp.encode_v2(0x1000, bytes(size), msp.DIR_REPLY)
    p = MspParser(max_payload=MAX_PAYLOAD)
    got = _feed_in_pieces(p, big + good[0], [])
    assert got[-1] == good[1]
    assert p.oversize >= 1
