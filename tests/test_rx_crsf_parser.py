"""Our CRSF codec against an independent one: PyPI crsf-parser 0.3.2, both directions.

crsf-parser's `channels` list comes out reversed (its index 0 is channel 16: it reads the
22 bytes as one big-endian bit string). The reference vector settles which order is right:
channel 1 of `C8 18 16 AC 98 ...` is 172 (reference/protocols.md §1.3), and ours says so.
"""

import random

import pytest

crsf_parser = pytest.importorskip("crsf_parser")
from crsf_parser import CRSFParser, PacketsTypes, PacketValidationStatus  # noqa: E402
from crsf_parser.handling import crsf_build_frame  # noqa: E402

from hoverfly.protocols import crsf  # noqa: E402

RC_MIXED = bytes.fromhex("C8 18 16 AC 98 38 F8 7E 01 70 FA A0 8F BB 00 F8 3F 2B C0 37 71 F0 B1 02 7C A4")
RC_MIXED_RAW = [172, 1811, 992, 191, 1792, 500, 1000, 1500, 0, 2047, 172, 992, 1811, 992, 172, 992]


def _their_parse(stream):
    got = []
    CRSFParser(lambda content, status: got.append((content, status))).parse_stream(bytearray(stream))
    return got


def test_crsf_parser_reads_the_reference_vector_in_reverse_channel_order():
    (content, status), = _their_parse(RC_MIXED)
    assert status == PacketValidationStatus.VALID
    assert list(content.payload.channels) == RC_MIXED_RAW[::-1]
    d = crsf.CrsfDecoder()
    assert d.feed(RC_MIXED) == 1 and list(d.channels_raw) == RC_MIXED_RAW


def test_random_rc_frames_we_encode_crsf_parser_decodes():
    rng = random.Random(1234)
    for _ in range(300):
        raw = [rng.randrange(2048) for _ in range(16)]
        (content, status), = _their_parse(bytes(crsf.encode_rc_frame_raw(raw)))
        assert status == PacketValidationStatus.VALID
        assert list(content.payload.channels)[::-1] == raw


def test_random_rc_frames_crsf_parser_builds_we_decode():
    rng = random.Random(4321)
    d = crsf.CrsfDecoder()
    for _ in range(300):
        raw = [rng.randrange(2048) for _ in range(16)]
        frame = bytes(crsf_build_frame(PacketsTypes.RC_CHANNELS_PACKED, {"channels": raw[::-1]}))
        assert d.feed(frame) == 1
        assert list(d.channels_raw) == raw
        assert list(d.channels_us) == [crsf.us_of_ticks(v) for v in raw]
    assert d.crc_errors == 0 and d.frames == 300


def test_random_us_frames_agree_in_ticks():
    rng = random.Random(99)
    for _ in range(200):
        us = [rng.randrange(988, 2013) for _ in range(16)]
        (content, _), = _their_parse(bytes(crsf.encode_rc_frame(us)))
        assert list(content.payload.channels)[::-1] == [crsf.ticks_of_us(u) for u in us]


def test_link_statistics_agree_both_ways():
    rng = random.Random(7)
    d = crsf.CrsfDecoder()
    for _ in range(100):
        f = dict(
            uplink_rssi_ant_1=rng.randrange(256), uplink_rssi_ant_2=rng.randrange(256),
            uplink_link_quality=rng.randrange(101), uplink_snr=rng.randrange(-128, 128),
            diversity_active_antenna=rng.randrange(2), rf_mode=rng.randrange(3),
            uplink_tx_power=rng.randrange(7), downlink_rssi=rng.randrange(256),
            downlink_link_quality=rng.randrange(101), downlink_snr=rng.randrange(-128, 128),
        )
        theirs = bytes(crsf_build_frame(PacketsTypes.LINK_STATISTICS, f))
        ours = bytes(crsf.encode_link_statistics(
            -f["uplink_rssi_ant_1"], -f["uplink_rssi_ant_2"], f["uplink_link_quality"], f["uplink_snr"],
            f["diversity_active_antenna"], f["rf_mode"], f["uplink_tx_power"], -f["downlink_rssi"],
            f["downlink_link_quality"], f["downlink_snr"]))
        assert ours == theirs
        d.feed(theirs)
        assert (d.rssi1_dbm, d.rssi2_dbm, d.snr_db, d.downlink_snr_db) == (
            -f["uplink_rssi_ant_1"], -f["uplink_rssi_ant_2"], f["uplink_snr"], f["downlink_snr"])
    assert d.link_stats_frames == 100


def test_battery_telemetry_agrees():
    out = bytearray(64)
    n = crsf.encode_battery(out, 16.8, 12.3, 1234, 75)
    (content, status), = _their_parse(bytes(out[:n]))
    assert status == PacketValidationStatus.VALID
    p = content.payload
    assert (p.voltage, p.current, p.capacity, p.remaining) == (168, 123, 1234, 75)
