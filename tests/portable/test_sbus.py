"""SBUS codec: the reference vectors (reference/protocols.md §2) both ways, flags, footer framing.

Plain asserts: runs under pytest and under MicroPython (tests/portable/mprun.py).
"""

from hoverfly.protocols import sbus

CENTRE = bytes.fromhex("0F E0 03 1F F8 C0 07 3E F0 81 0F 7C E0 03 1F F8 C0 07 3E F0 81 0F 7C 00 00")
MIXED = bytes.fromhex("0F AD A0 38 F8 D0 07 80 FF D3 87 BB AD 00 1F C5 C1 07 C0 FF 05 C0 FF 09 00")
MIXED_RAW = [173, 1812, 992, 1000, 0, 2047, 500, 1500, 173, 992, 1812, 992, 1024, 1023, 1, 2046]


def test_centre_vector_decodes():
    d = sbus.SbusDecoder()
    assert d.feed(CENTRE) == 1
    assert list(d.channels_raw) == [992] * 16 and list(d.channels_us) == [1500] * 16
    assert not d.failsafe and not d.frame_lost and not d.ch17 and not d.ch18


def test_mixed_vector_decodes_channels_and_flags():
    d = sbus.SbusDecoder()
    assert d.feed(MIXED) == 1
    assert list(d.channels_raw) == MIXED_RAW
    assert d.ch17 and not d.ch18 and d.failsafe and not d.frame_lost
    assert d.failsafe_frames == 1 and d.lost_frames == 0


def test_vectors_encode_byte_exact():
    assert bytes(sbus.encode_rc_frame([1500] * 16)) == CENTRE
    assert bytes(sbus.encode_rc_frame_raw(MIXED_RAW, ch17=True, failsafe=True)) == MIXED


def test_us_mapping_is_betaflights_rounded():
    # 5*raw/8 + 880: 173 -> 988.125, 992 -> 1500, 1811 -> 2011.875, 1812 -> 2012.5
    assert [sbus.us_of_raw(v) for v in (173, 992, 1811, 1812, 0, 2047)] == [988, 1500, 2012, 2013, 880, 2159]


def test_decode_of_encode_is_exact_over_the_tick_range():
    for us in range(880, 2160):
        assert sbus.us_of_raw(sbus.raw_of_us(us)) == us, us


def test_flags_round_trip():
    d = sbus.SbusDecoder()
    for bits in range(16):
        f = sbus.encode_rc_frame([1200] * 16, None, bits & 1, bits & 2, bits & 4, bits & 8)
        assert f[23] == bits
        d.feed(f)
        assert (d.ch17, d.ch18, d.frame_lost, d.failsafe) == (bool(bits & 1), bool(bits & 2),
                                                             bool(bits & 4), bool(bits & 8))
    assert d.frames == 16 and d.lost_frames == 8 and d.failsafe_frames == 8


def test_split_at_every_byte_boundary_decodes():
    for cut in range(1, 25):
        d = sbus.SbusDecoder()
        assert d.feed(MIXED[:cut]) + d.feed(MIXED[cut:]) == 1, cut
        assert list(d.channels_raw) == MIXED_RAW


def test_sbus2_footers_accepted_and_others_refused():
    d = sbus.SbusDecoder()
    for footer in (0x04, 0x14, 0x24, 0x34):
        assert d.feed(sbus.encode_rc_frame_raw(MIXED_RAW, footer=footer)) == 1
    assert d.feed(sbus.encode_rc_frame_raw(MIXED_RAW, footer=0x55)) == 0
    assert d.length_errors == 1
    loose = sbus.SbusDecoder(check_footer=False)
    assert loose.feed(sbus.encode_rc_frame_raw(MIXED_RAW, footer=0x55)) == 1


def test_garbage_and_a_dropped_byte_resynchronise():
    d = sbus.SbusDecoder()
    damaged = CENTRE[:7] + CENTRE[8:]  # one byte lost on the wire
    done = d.feed(b"\x01\x02\x03" + damaged + MIXED + CENTRE)
    assert done == 2
    assert list(d.channels_raw) == [992] * 16
    assert d.length_errors >= 1 and d.resyncs >= 3


def test_idle_drops_a_partial_frame():
    d = sbus.SbusDecoder()
    d.feed(MIXED[:9])
    d.idle()
    assert d.length_errors == 1 and d.resyncs == 9
    assert d.feed(CENTRE) == 1
