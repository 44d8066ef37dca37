"""compat: tick arithmetic across the 2**30 wrap, the same on both Pythons."""

from hoverfly.compat import TICKS_MAX, TICKS_PERIOD, ticks_add, ticks_diff


def test_ticks_diff_is_signed_across_the_wrap():
    before = TICKS_MAX - 10
    after = ticks_add(before, 25)
    assert after == 14 or TICKS_PERIOD != 1 << 30
    assert ticks_diff(after, before) == 25
    assert ticks_diff(before, after) == -25


def test_ticks_add_wraps_to_the_period():
    assert ticks_add(TICKS_MAX, 1) == 0
    assert ticks_add(0, -1) == TICKS_MAX
    assert ticks_add(TICKS_MAX - 4, 10) == 5
    assert ticks_diff(ticks_add(7, TICKS_PERIOD >> 2), 7) == TICKS_PERIOD >> 2


def test_crc8_check_values_from_the_catalogue():
    from hoverfly.protocols.crc import crc8_ba, crc8_dvb_s2, xor8

    data = b"123456789"
    assert crc8_dvb_s2(data) == 0xBC
    assert crc8_ba(data) == 0x20
    assert xor8(data) == 0x31
