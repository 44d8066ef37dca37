"""Parameter storage: two slots, sequence numbers, CRC; cut or corrupt writes keep the last good set."""

from struct import pack

from hoverfly.core.config import storage as st
from hoverfly.core.config.params import Params
from hoverfly.core.config.storage import (
    EMPTY,
    LOADED,
    LOADED_OLDER,
    LOST,
    SLOT_BYTES,
    MemoryStorageBoard,
    Storage,
    crc32,
    encode_record,
    parse_record,
)


def _saved(values_list):
    """A board whose image went through one save per dict of changes; returns (board, storage)."""
    board = MemoryStorageBoard()
    s = Storage(board)
    s.load(Params())
    for changes in values_list:
        p = Params()
        for k in changes:
            assert p.set(k, changes[k]) is None
        assert s.save(p) is None
    return board, s


def test_crc32_check_value():
    assert crc32(b"123456789") == 0xCBF43926


def test_fresh_board_boots_defaults_without_a_fault():
    p = Params()
    s = Storage(MemoryStorageBoard())
    assert s.load(p) == EMPTY
    assert not s.failed
    assert p.diff() == []


def test_saved_set_loads_after_restart():
    board, _ = _saved([{"p_roll": 60, "gyro_lpf1_type": "biquad", "motor_idle_pct": 7.25}])
    p = Params()
    s = Storage(board)
    assert s.load(p) == LOADED
    assert p.get("p_roll") == 60 and p.get("gyro_lpf1_type") == "biquad" and p.get("motor_idle_pct") == 7.25
    assert s.seq == 1 and s.slot == 0


def test_saves_alternate_slots_with_rising_sequence():
    board, s = _saved([{"p_roll": 50}, {"p_roll": 51}, {"p_roll": 52}])
    assert s.seq == 3 and s.slot == 0
    assert parse_record(board.image, 0)[1] == 3
    assert parse_record(board.image, SLOT_BYTES)[1] == 2
    p = Params()
    Storage(board).load(p)
    assert p.get("p_roll") == 52


def test_save_cut_at_any_byte_keeps_the_previous_set():
    board, s = _saved([{"p_roll": 50}, {"p_roll": 51}])
    old = board.image
    p = Params()
    p.set("p_roll", 99)
    s.save(p)
    new = board.image
    # The new record went to slot 0; cut the in-place write at a sample of bytes through it.
    end = 0
    for cut in range(0, SLOT_BYTES, 97):
        image = new[:cut] + old[cut:]
        q = Params()
        status = Storage(MemoryStorageBoard(image)).load(q)
        assert status in (LOADED, LOADED_OLDER)
        assert q.get("p_roll") in (51, 99)
        if q.get("p_roll") == 99:
            end = cut
    assert end > 0  # once the record is whole the new set loads


def test_both_slots_bad_boots_defaults_and_flags_it():
    board, _ = _saved([{"p_roll": 50}, {"p_roll": 51}])
    image = bytearray(board.image)
    image[20] ^= 0xFF
    image[SLOT_BYTES + 20] ^= 0xFF
    p = Params()
    s = Storage(MemoryStorageBoard(bytes(image)))
    assert s.load(p) == LOST
    assert s.failed
    assert p.diff() == []


def test_corrupt_newest_slot_loads_the_older_one():
    board, _ = _saved([{"p_roll": 50}, {"p_roll": 51}])
    image = bytearray(board.image)
    image[SLOT_BYTES + 30] ^= 0x01
    p = Params()
    assert Storage(MemoryStorageBoard(bytes(image))).load(p) == LOADED_OLDER
    assert p.get("p_roll") == 50


def test_save_after_a_lost_image_starts_over():
    p = Params()
    s = Storage(MemoryStorageBoard(b"garbage" * 10))
    assert s.load(p) == LOST
    p.set("p_roll", 70)
    assert s.save(p) is None
    q = Params()
    assert Storage(s.board).load(q) == LOADED and q.get("p_roll") == 70


def _record(entries, seq=1, fmt=1):
    payload = b""
    for name, code, value in entries:
        nb = name.encode()
        payload += pack("<B", len(nb)) + nb + code
        if code == b"i":
            payload += pack("<i", value)
        elif code == b"f":
            payload += pack("<d", value)
        else:
            vb = value.encode()
            payload += pack("<B", len(vb)) + vb
    head = b"HVFP" + pack("<BBHII", fmt, 0, len(entries), seq, len(payload))
    body = head + payload
    return body + pack("<I", crc32(body))


def test_unknown_names_and_out_of_range_values_are_skipped_and_counted():
    image = _record([("p_roll", b"i", 61), ("retired_thing", b"i", 3), ("i_roll", b"i", 9999),
                     ("gyro_lpf1_type", b"s", "pt2")])
    p = Params()
    s = Storage(MemoryStorageBoard(image))
    assert s.load(p) == LOADED
    assert s.skipped == 2
    assert p.get("p_roll") == 61 and p.get("i_roll") == 80 and p.get("gyro_lpf1_type") == "pt2"


def test_renamed_parameters_load_under_their_new_name():
    st.RENAMED["old_p_roll"] = "p_roll"
    try:
        p = Params()
        Storage(MemoryStorageBoard(_record([("old_p_roll", b"i", 33)]))).load(p)
        assert p.get("p_roll") == 33
    finally:
        del st.RENAMED["old_p_roll"]


def test_older_formats_migrate_and_newer_ones_are_refused():
    saved = st.MIGRATIONS
    st.FORMAT = 2
    st.MIGRATIONS = ((2, lambda entries: [(n, v * 2 if n == "p_roll" else v) for n, v in entries]),)
    try:
        p = Params()
        Storage(MemoryStorageBoard(_record([("p_roll", b"i", 30)], fmt=1))).load(p)
        assert p.get("p_roll") == 60
    finally:
        st.FORMAT = 1
        st.MIGRATIONS = saved
    p = Params()
    assert Storage(MemoryStorageBoard(_record([("p_roll", b"i", 30)], fmt=2))).load(p) == LOST


def test_failed_write_changes_nothing():
    board, s = _saved([{"p_roll": 50}])
    before = board.image
    board.fail = True
    p = Params()
    p.set("p_roll", 77)
    assert s.save(p) == "storage write failed"
    assert board.image == before and s.seq == 1


def test_record_holds_every_table_row():
    r = parse_record(encode_record(Params().values, 5))
    assert r[1] == 5
    names = [e[0] for e in r[2]]
    from hoverfly.core.config.params import PARAMS
    assert names == [row[0] for row in PARAMS]
