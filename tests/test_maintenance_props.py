"""Maintenance-protocol properties (hypothesis): requests and replies with random fields, commands and
values survive any chunking and garbage; random, truncated and corrupted input never raises and
is counted; an independent struct-based decoder agrees with the parser."""

import struct

from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from hoverfly.protocols import maintenance as mt
from hoverfly.protocols.maintenance import MaintenanceParser

SETTINGS = settings(max_examples=300, derandomize=True, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])
NO_SYNC = st.binary(max_size=30).map(lambda b: b.replace(b"\xff", b"\x7f"))
F32 = st.floats(width=32, allow_nan=False, allow_infinity=False)
LAYOUTS = st.sampled_from((mt.LAYOUT_SEED, mt.LAYOUT_FIRMWARE))


def _value(code):
    if code == "f":
        return F32
    return st.integers(0, {"B": 0xFF, "H": 0xFFFF, "I": 0xFFFFFFFF}[code])


@st.composite
def requests(draw, layout=mt.LAYOUT_SEED):
    fields = draw(st.lists(st.integers(0, 56), unique=True))
    cmd = draw(st.integers(0, 25))
    fmt = mt.COMMANDS[cmd][1]
    args = tuple(draw(_value(c)) for c in fmt)
    rc = (draw(st.integers(0, 1)),) + tuple(draw(st.integers(0, 0xFFFF)) for _ in range(4))
    frame = mt.encode_request(fields, cmd, args, rc, layout)
    return frame, (sorted(fields), cmd, args, rc)


def _independent_decode_request(frame):
    # Straight from the seed's table, not from the module: sync, 8 header bytes (bit 7 first),
    # cmd = low 7 bits of byte 7, arguments, <BHHHH REMOTE_CONTROL_TAG, XOR of all but the sync.
    h = frame[1:9]
    fields = [k for k in range(57) if h[k // 8] & (0x80 >> (k % 8))]
    cmd = h[7] & 0x7F
    fmt = "<" + mt.COMMANDS[cmd][1]
    n = struct.calcsize(fmt)
    args = struct.unpack_from(fmt, frame, 9)
    rc = struct.unpack_from("<BHHHH", frame, 9 + n)
    x = 0
    for b in frame[1:-1]:
        x ^= b
    assert x == frame[-1]
    assert len(frame) == 9 + n + 9 + 1
    return fields, cmd, args, rc


def _drain(p):
    out = []
    while p.pop():
        if p.replies:
            out.append((bytes(p.header), p.values))
        else:
            out.append((mt.header_fields(p.header, p.layout), p.cmd_id, tuple(p.args[: p.arg_count]),
                        (p.rc_override, p.rc_armed_us, p.rc_roll_us, p.rc_pitch_us, p.rc_throttle_us)))
    return out


def _feed(p, stream, cuts):
    got = []
    prev = 0
    for c in sorted(set(c % (len(stream) + 1) for c in cuts)) + [len(stream)]:
        p.feed(stream[prev:c])
        prev = c
        got += _drain(p)
    return got


@SETTINGS
@given(requests())
def test_independent_decoder_agrees_with_the_encoder(r):
    frame, expect = r
    assert _independent_decode_request(frame) == expect


@SETTINGS
@given(st.lists(st.tuples(NO_SYNC, requests()), min_size=1, max_size=5), NO_SYNC,
       st.lists(st.integers(0, 2000), max_size=10))
def test_requests_between_garbage_in_any_chunking_are_decoded_in_order(items, tail, cuts):
    # Requests whose header or arguments hold 0xFF are fine, but a false sync inside garbage is not
    # possible here: garbage has no 0xFF, so every frame is found at its true start.
    stream = b"".join(g + f for g, (f, _) in items) + tail
    p = MaintenanceParser(queue_depth=8)
    assert _feed(p, stream, cuts) == [e for _, (_, e) in items]
    assert p.crc_errors == 0 and p.resyncs == sum(len(g) for g, _ in items) + len(tail)


@SETTINGS
@given(LAYOUTS, st.data())
def test_layouts_round_trip_through_the_parser(layout, data):
    frame, expect = data.draw(requests(layout))
    p = MaintenanceParser(layout=layout)
    assert _feed(p, frame, []) == [expect]


@st.composite
def replies(draw, layout=mt.LAYOUT_SEED):
    fields = draw(st.lists(st.integers(0, 56), unique=True))
    header = mt.encode_header(fields, draw(st.integers(0, 25)), layout)
    values = {}
    expect = []
    for k in sorted(fields):
        name, code, count = mt.FIELDS[k]
        if count == 1:
            v = draw(_value(code))
        else:
            v = tuple(draw(_value(code)) for _ in range(count))
        values[name] = v
        expect.append((name, v))
    return header, mt.encode_reply(header, values, layout), expect


@SETTINGS
@given(replies(), NO_SYNC, st.lists(st.integers(0, 2000), max_size=8))
def test_replies_decode_values_in_header_order(r, garbage, cuts):
    header, frame, expect = r
    c = MaintenanceParser(replies=True, expected_header=header)
    got = _feed(c, garbage + frame + garbage, cuts)
    assert got == [(bytes(header), expect)]
    assert mt.decode_reply(header, frame[9:-1]) == expect


@SETTINGS
@given(st.binary(max_size=1500), st.lists(st.integers(0, 2000), max_size=8), st.booleans(), LAYOUTS)
def test_random_bytes_never_raise(data, cuts, replies_side, layout):
    p = MaintenanceParser(replies=replies_side, queue_depth=16, layout=layout)
    got = _feed(p, data, cuts)
    assert p.bytes == len(data)
    assert len(got) + p.dropped == p.frames


@SETTINGS
@given(requests(), st.data(), requests())
def test_corrupted_request_is_dropped_counted_and_the_next_decoded(bad, data, good):
    frame = bytearray(bad[0])
    assume(0xFF not in frame[1:])  # no false sync inside the broken frame
    k = data.draw(st.integers(9, len(frame) - 1))  # an argument, tag or checksum byte: length unchanged
    frame[k] = data.draw(st.sampled_from([v for v in range(255) if v != frame[k]]))
    p = MaintenanceParser()
    assert _feed(p, bytes(frame) + good[0], data.draw(st.lists(st.integers(0, 200), max_size=4))) == [good[1]]
    assert p.crc_errors == 1


@SETTINGS
@given(requests(), st.data(), requests())
def test_truncated_request_then_idle_then_next_decoded(cut_req, data, good):
    frame = cut_req[0]
    cut = data.draw(st.integers(1, len(frame) - 1))
    p = MaintenanceParser()
    assert _feed(p, frame[:cut], []) == []
    p.idle()
    assert _feed(p, good[0], []) == [good[1]]
