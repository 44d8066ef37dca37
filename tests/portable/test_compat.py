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



def _existing_names(count):
    """Attribute names the VM has interned already (the core's own): the test adds no names of its own to
    MicroPython's qstr pools, which never give memory back (a few hundred split the heap enough that the
    logger test's 270 KB buffer no longer fits a 4 MB heap)."""
    import hoverfly.core.flight as flight
    import hoverfly.core.log.logger as logger

    names = []
    for source in (flight, flight.Flight, logger, logger.Logger):
        for name in dir(source):
            if not name.startswith("__") and name not in names:
                names.append(name)
    assert len(names) >= count
    return names[:count]


def test_attr_room_leaves_an_attribute_table_room():
    from hoverfly.compat import IS_MICROPYTHON, ROOM_LOAD_PCT, attr_room, map_size

    class Bag:
        pass

    names = _existing_names(98)
    for n in (0, 1, 2, 7, 8, 9, 12, 13, 17, 37, 38, 47, 60, 69, 73, 74, 97, 98):
        b = Bag()
        for i in range(n):
            setattr(b, names[i], i)
        k = attr_room(b)
        if not IS_MICROPYTHON:
            assert k == 0 and len(b.__dict__) == n
            continue
        m = n + k
        assert len(b.__dict__) == m
        assert m == 0 or m * 100 <= map_size(m) * ROOM_LOAD_PCT  # room now
        assert k == 0 or (m - 1) * 100 > map_size(m - 1) * ROOM_LOAD_PCT  # and no spare one more than needed
        assert attr_room(b) == 0  # a second call has nothing to add
        for i in range(n):
            assert getattr(b, names[i]) == i  # the object's own attributes untouched
        if n == 69:  # the Flight's count: 69 of 73 slots, then 74 of 97
            assert k == 5
    assert [map_size(n) for n in (0, 1, 8, 9, 69, 73, 74)] == [0, 2, 8, 10, 73, 73, 97]
