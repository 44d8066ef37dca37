"""Receiver decoders under bad input: property tests (hypothesis) and a bounded seeded fuzz run.

What must hold for CRSF, SBUS and iBUS: no exception escapes `feed`; every byte is counted;
the result (frames, error counters, channels) does not depend on how the bytes are chunked;
frames after garbage, truncated frames or corrupted frames are still decoded. Also: the
CPython and MicroPython twins of the 11-bit unpack are equal, and the PWM/PPM edge
decoders read back what the edge generators produce at any time, wrap included.
"""

import random
import time

from hypothesis import given, settings
from hypothesis import strategies as st

from hoverfly.compat import TICKS_MAX, ticks_add
from hoverfly.protocols import crsf, ibus, rxcodec, sbus
from hoverfly.protocols.crc import CRC8_DVB_S2_TABLE
from hoverfly.protocols.pulses import PpmCapture, PwmCapture, ppm_edges, pwm_edges

DECODERS = {
    "crsf": (crsf.CrsfDecoder, lambda raw: bytes(crsf.encode_rc_frame_raw(raw)), {0xC8, 0xEA, 0xEC, 0xEE, 0x00}),
    "sbus": (sbus.SbusDecoder, lambda raw: bytes(sbus.encode_rc_frame_raw(raw)), {0x0F}),
    "ibus": (ibus.IbusDecoder, lambda raw: bytes(ibus.encode_rc_frame_raw([v + 800 for v in raw[:14]])), {0x20}),
}
PROTOCOLS = sorted(DECODERS)
FUZZ = settings(max_examples=300, derandomize=True, deadline=None)

raw_channels = st.lists(st.integers(0, 1400), min_size=16, max_size=16)


def _state(d):
    return (d.frames, d.crc_errors, d.resyncs, d.length_errors, d.bytes, list(d.channels_raw),
            list(d.channels_us))


def _feed_chunks(d, stream, cuts):
    done = 0
    prev = 0
    for c in sorted(set(cuts)) + [len(stream)]:
        if c <= prev or c > len(stream):
            continue
        done += d.feed(memoryview(stream)[prev:c])
        prev = c
    return done


@FUZZ
@given(proto=st.sampled_from(PROTOCOLS), data=st.binary(max_size=400))
def test_random_bytes_never_raise_and_every_byte_counts(proto, data):
    d = DECODERS[proto][0]()
    d.feed(data)
    assert d.bytes == len(data)
    assert d.frames >= 0 and d.resyncs <= len(data) + 64


@FUZZ
@given(proto=st.sampled_from(PROTOCOLS), frames=st.lists(raw_channels, min_size=1, max_size=4),
       junk=st.lists(st.binary(max_size=40), min_size=5, max_size=5),
       cuts=st.lists(st.integers(0, 400), max_size=30))
def test_chunking_never_changes_the_result(proto, frames, junk, cuts):
    cls, enc, _ = DECODERS[proto]
    stream = b"".join(junk[k % 5] + enc(raw) for k, raw in enumerate(frames))
    whole = cls()
    n_whole = whole.feed(stream)
    split = cls()
    n_split = _feed_chunks(split, stream, cuts)
    assert n_whole == n_split
    assert _state(whole) == _state(split)
    one = cls()
    assert sum(one.feed(bytes((b,))) for b in stream) == n_whole
    assert _state(one) == _state(whole)


@FUZZ
@given(proto=st.sampled_from(PROTOCOLS), frames=st.lists(raw_channels, min_size=1, max_size=5),
       junk=st.lists(st.binary(max_size=30), min_size=5, max_size=5))
def test_every_frame_between_sync_free_garbage_is_decoded(proto, frames, junk):
    cls, enc, syncs = DECODERS[proto]
    junk = [bytes(b for b in j if b not in syncs) for j in junk]
    stream = b"".join(junk[k % 5] + enc(raw) for k, raw in enumerate(frames))
    d = cls()
    assert d.feed(stream) == len(frames)
    assert d.resyncs == sum(len(junk[k % 5]) for k in range(len(frames)))
    assert d.crc_errors == 0 and d.length_errors == 0
    last = cls()
    last.feed(enc(frames[-1]))
    assert list(d.channels_us) == list(last.channels_us)


@FUZZ
@given(proto=st.sampled_from(PROTOCOLS), raw=raw_channels, cut=st.integers(1, 31), flip=st.integers(0, 255))
def test_truncated_or_corrupted_frame_then_good_frames_recovers(proto, raw, cut, flip):
    cls, enc, _ = DECODERS[proto]
    good = enc(raw)
    bad = bytearray(good)
    bad[1 + flip % (len(bad) - 1)] ^= 1 << (flip % 8)
    stream = good[: cut % len(good)] + bytes(bad) + good + good + good
    d = cls()
    assert d.feed(stream) >= 1
    assert list(d.channels_us) == list(_decoded(cls, good).channels_us)


def _decoded(cls, frame):
    d = cls()
    d.feed(frame)
    return d


def test_crsf_bad_crcs_are_counted():
    good = bytes(crsf.encode_rc_frame([1500] * 16))
    d = crsf.CrsfDecoder()
    for k in range(3, 25):
        bad = bytearray(good)
        bad[k] ^= 0x10
        d.feed(bytes(bad))
    assert d.crc_errors == 22 and d.frames == 0
    assert d.feed(good) == 1


def test_bounded_fuzz_run_with_fixed_seed():
    """A few seconds of mutated receiver streams (flips, drops, inserts) in random chunks."""
    rng = random.Random(20240611)
    deadline = time.monotonic() + 3.0
    runs = 0
    while time.monotonic() < deadline:
        proto = PROTOCOLS[runs % 3]
        cls, enc, _ = DECODERS[proto]
        stream = bytearray()
        for _ in range(rng.randrange(1, 8)):
            stream += enc([rng.randrange(1400) for _ in range(16)])
            if proto == "crsf" and rng.random() < 0.3:
                stream += crsf.encode_link_statistics(-rng.randrange(130), -rng.randrange(130))
        for _ in range(rng.randrange(0, 6)):
            op = rng.randrange(3)
            k = rng.randrange(len(stream))
            if op == 0:
                stream[k] ^= 1 << rng.randrange(8)
            elif op == 1:
                del stream[k]
            else:
                stream.insert(k, rng.randrange(256))
        stream = bytes(stream)
        whole = cls()
        whole.feed(stream)
        split = cls()
        _feed_chunks(split, stream, [rng.randrange(len(stream) + 1) for _ in range(rng.randrange(10))])
        assert _state(whole) == _state(split)
        assert whole.bytes == len(stream)
        runs += 1
    assert runs > 100


@FUZZ
@given(data=st.binary(min_size=24, max_size=24))
def test_check_unpack11_twins_agree(data):
    for src in (data, bytes((0x16,)) + _with_crc(data[1:23])):
        a = (rxcodec.new_channels(), rxcodec.new_channels())
        b = (rxcodec.new_channels(), rxcodec.new_channels())
        ra = rxcodec._check_unpack11_indexed(src, 0, a[0], a[1], crsf.US_OF_TICKS, CRC8_DVB_S2_TABLE)
        rb = rxcodec._check_unpack11_struct(src, 0, b[0], b[1], crsf.US_OF_TICKS, CRC8_DVB_S2_TABLE)
        assert ra == rb and list(a[0]) == list(b[0]) and list(a[1]) == list(b[1])


def _with_crc(payload):
    c = CRC8_DVB_S2_TABLE[0x16]
    for b in payload:
        c = CRC8_DVB_S2_TABLE[c ^ b]
    return bytes(payload) + bytes((c,))


@FUZZ
@given(data=st.binary(min_size=22, max_size=22))
def test_unpack11_twins_agree_and_invert_pack11(data):
    a = (rxcodec.new_channels(), rxcodec.new_channels())
    b = (rxcodec.new_channels(), rxcodec.new_channels())
    rxcodec._unpack11_indexed(data, 0, a[0], a[1], sbus.US_OF_RAW)
    rxcodec._unpack11_struct(data, 0, b[0], b[1], sbus.US_OF_RAW)
    assert list(a[0]) == list(b[0]) and list(a[1]) == list(b[1])
    out = bytearray(22)
    rxcodec.pack11(a[0], out, 0)
    assert bytes(out) == data


@FUZZ
@given(chans=st.lists(st.integers(800, 2200), min_size=1, max_size=16), t0=st.integers(0, TICKS_MAX))
def test_pwm_reads_back_generated_edges_at_any_time(chans, t0):
    cap = PwmCapture(len(chans))
    done = sum(cap.edge(c, lv, t) for c, lv, t in pwm_edges(chans, t0))
    assert done == 1 and list(cap.channels_us[: len(chans)]) == chans and cap.errors == 0


@FUZZ
@given(chans=st.lists(st.integers(800, 2200), min_size=4, max_size=8), t0=st.integers(0, TICKS_MAX))
def test_ppm_reads_back_generated_edges_at_any_time(chans, t0):
    cap = PpmCapture()
    done = sum(cap.edge(lv, t) for lv, t in ppm_edges(chans, t0, frame_us=22500, frames=3))
    assert done == 1 and list(cap.channels_us[: len(chans)]) == chans and cap.errors == 0


@FUZZ
@given(events=st.lists(st.tuples(st.integers(-2, 20), st.integers(0, 1), st.integers(0, TICKS_MAX)), max_size=200))
def test_edge_decoders_never_raise_on_random_edges(events):
    pwm = PwmCapture(8)
    ppm = PpmCapture()
    t = ticks_add(TICKS_MAX, -100)
    for ch, lv, dt in events:
        t = ticks_add(t, dt % 30000)
        pwm.edge(ch, lv, t)
        ppm.edge(lv, t)
    for v in list(pwm.channels_us) + list(ppm.channels_us):
        assert v == 0 or 800 <= v <= 2200 or v == 1500
