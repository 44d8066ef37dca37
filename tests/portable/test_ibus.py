"""iBUS codec: the reference vectors (reference/protocols.md §3) both ways, checksum, framing.

Plain asserts: runs under pytest and under MicroPython (tests/portable/mprun.py).
"""

from hoverfly.protocols import ibus

CENTRE = bytes.fromhex(
    "20 40 DC 05 DC 05 DC 05 DC 05 DC 05 DC 05 DC 05 DC 05 DC 05 DC 05 DC 05 DC 05 DC 05 DC 05 51 F3"
)
MIXED = bytes.fromhex(
    "20 40 E8 03 D0 07 DC 05 D2 04 4C 04 6C 07 DC 05 DC 05 E8 03 D0 07 DC 05 DC 05 DC 05 DC 05 5B F4"
)
MIXED_US = [1000, 2000, 1500, 1234, 1100, 1900, 1500, 1500, 1000, 2000, 1500, 1500, 1500, 1500]


def test_vectors_decode_14_channels_and_pad_to_16():
    d = ibus.IbusDecoder()
    assert d.feed(CENTRE) == 1
    assert list(d.channels_us) == [1500] * 16
    assert d.feed(MIXED) == 1
    assert list(d.channels_us) == MIXED_US + [1500, 1500]
    assert list(d.channels_raw[:14]) == MIXED_US
    assert d.frames == 2 and d.crc_errors == 0 and d.bytes == 64


def test_vectors_encode_byte_exact():
    assert bytes(ibus.encode_rc_frame([1500] * 14)) == CENTRE
    assert bytes(ibus.encode_rc_frame([])) == CENTRE
    assert bytes(ibus.encode_rc_frame(MIXED_US + [1000, 1000])) == MIXED  # 15-16 not carried


def test_top_nibbles_are_not_channel_data():
    f = bytearray(ibus.encode_rc_frame_raw([0xF000 | 1234] * 14))
    d = ibus.IbusDecoder()
    assert d.feed(f) == 1
    assert d.channels_us[0] == 1234 and d.channels_raw[0] == 0xF000 | 1234


def test_bad_checksum_is_counted_and_the_next_frame_decodes():
    bad = bytearray(MIXED)
    bad[5] ^= 0x01
    d = ibus.IbusDecoder()
    assert d.feed(bytes(bad) + CENTRE) == 1
    assert d.crc_errors == 1 and list(d.channels_us[:14]) == [1500] * 14


def test_0x20_without_the_channel_command_is_not_a_frame():
    d = ibus.IbusDecoder()
    assert d.feed(b"\x20\x41\x20" + MIXED) == 1  # 20 41: not channels; 20 20: neither
    assert d.length_errors == 2 and d.resyncs == 3


def test_split_at_every_byte_boundary_decodes():
    for cut in range(1, 32):
        d = ibus.IbusDecoder()
        assert d.feed(MIXED[:cut]) + d.feed(MIXED[cut:]) == 1, cut
        assert list(d.channels_us[:14]) == MIXED_US


def test_round_trip_over_the_servo_range():
    d = ibus.IbusDecoder()
    for base in range(800, 2201, 100):
        chans = [base + k for k in range(14)]
        assert d.feed(ibus.encode_rc_frame(chans)) == 1
        assert list(d.channels_us[:14]) == chans
