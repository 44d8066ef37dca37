"""ULog writer: spec byte layouts (protocols.md 7.3, sim-physics-and-logs.md 6.1), refusals, ring sink."""

import struct

from hoverfly.compat import IS_MICROPYTHON, collect_garbage, disable_gc, enable_gc, mem_alloc
from hoverfly.protocols.ulog import RingSink, UlogWriter


def _hex(text):
    parts = text.split()
    out = bytearray(len(parts))
    for i in range(len(parts)):
        out[i] = int(parts[i], 16)
    return bytes(out)


class ListSink:
    """Keeps every message the writer hands over, one write per message."""

    def __init__(self):
        self.chunks = []

    def write(self, data):
        self.chunks.append(bytes(data))
        return len(data)

    def all(self):
        return b"".join(self.chunks)


class NullSink:
    def write(self, data):
        return None


RATE_FIELDS = (
    ("uint64_t", "timestamp"),
    ("float[3]", "xyz"),
    ("uint8_t", "armed"),
    ("uint8_t[7]", "_padding0"),
)
HEADER_1000 = "55 4C 6F 67 01 12 35 01 E8 03 00 00 00 00 00 00"


def _writer(start_us=1000):
    sink = ListSink()
    return UlogWriter(sink, start_us), sink


def test_header_and_flag_bits_open_the_file():
    w, sink = _writer(1000)
    assert sink.chunks[0] == _hex(HEADER_1000)
    # B: u16 size 40, 'B', 40 zero bytes (no default params, no appended data)
    assert sink.chunks[1] == _hex("28 00 42") + bytes(40)
    assert len(sink.all()) == 16 + 43
    assert w.bytes_written == 59 and w.messages == 2


def test_format_message_is_name_colon_fields_with_trailing_semicolons():
    w, sink = _writer()
    assert w.add_format("rate", RATE_FIELDS)
    text = b"rate:uint64_t timestamp;float[3] xyz;uint8_t armed;uint8_t[7] _padding0;"
    assert sink.chunks[-1] == _hex("48 00 46") + text


def test_info_string_vector():
    w, sink = _writer()
    assert w.add_info("char[8] sys_name", "hoverfly")
    key = _hex("63 68 61 72 5B 38 5D 20 73 79 73 5F 6E 61 6D 65")  # "char[8] sys_name"
    assert sink.chunks[-1] == _hex("19 00 49 10") + key + b"hoverfly"


def test_info_int32_and_uint32_values_are_little_endian():
    w, sink = _writer()
    assert w.add_info("int32_t time_ref_utc", -2)
    assert sink.chunks[-1] == _hex("19 00 49 14") + b"int32_t time_ref_utc" + _hex("FE FF FF FF")
    assert w.add_info("uint32_t ver_sw_release", 0x010203FF)
    assert sink.chunks[-1][-4:] == _hex("FF 03 02 01")


def test_param_vector_from_the_reference():
    w, sink = _writer()
    assert w.add_param("MC_ROLL_P", 6.5)
    assert sink.chunks[-1] == _hex("14 00 50 0F 66 6C 6F 61 74 20 4D 43 5F 52 4F 4C 4C 5F 50 00 00 D0 40")


def test_int_param_is_int32():
    w, sink = _writer()
    assert w.add_param("p_roll", 45)
    assert sink.chunks[-1] == _hex("13 00 50 0E") + b"int32_t p_roll" + _hex("2D 00 00 00")


def test_subscription_and_data_vectors_from_the_reference():
    w, sink = _writer()
    w.add_format("rate", RATE_FIELDS)
    msg_id = w.subscribe("rate")
    assert msg_id == 0
    assert sink.chunks[-1] == _hex("07 00 41 00 00 00 72 61 74 65")
    assert w.write_data(msg_id, 2000, (0.5, -0.25, 1.0, 1))
    # trailing _padding0 is not written
    assert sink.chunks[-1] == _hex(
        "17 00 44 00 00 D0 07 00 00 00 00 00 00 00 00 00 3F 00 00 80 BE 00 00 80 3F 01"
    )


def test_a_sample_the_caller_clamped_is_written_the_same_without_the_range_checks():
    w, sink = _writer()
    w.add_format("rate", RATE_FIELDS)
    msg_id = w.subscribe("rate")
    assert w.write_data(msg_id, 2000, (0.5, -0.25, 1.0, 1))
    checked = sink.chunks[-1]
    assert w.write_data(msg_id, 2000, (0.5, -0.25, 1.0, 1), True)
    assert sink.chunks[-1] == checked
    assert not w.write_data(msg_id, 2000, (0.5, -0.25, 1.0, 300))  # uint8 out of range: refused
    assert w.refused == 1


def test_a_ring_with_a_spill_drains_itself_once_it_holds_spill_at_bytes():
    out = []

    def take(mv):
        out.append(bytes(mv))

    ring = RingSink(32, take, 8)
    assert ring.write(b"abcde") == 5
    assert out == [] and ring.used == 5  # below spill_at: it waits
    assert ring.write(b"fghi") == 4
    assert out == [b"abcdefghi"] and ring.used == 0
    assert RingSink(32).write(b"x" * 20) == 20  # no spill: a board drains it in its slack


def test_second_instance_gets_multi_id_1_and_the_next_msg_id():
    w, sink = _writer()
    w.add_format("rate", RATE_FIELDS)
    assert w.subscribe("rate", 0) == 0
    assert w.subscribe("rate", 1) == 1
    assert sink.chunks[-1] == _hex("07 00 41 01 01 00 72 61 74 65")
    assert w.subscribe("rate", 1) == -1  # the same instance twice would mislabel data
    assert w.refused == 1


def test_log_string_sync_dropout_and_param_change_layouts():
    w, sink = _writer()
    w.add_param("p_roll", 45)
    w.begin_data()
    assert w.log_message(6, 5000, "hi")
    assert sink.chunks[-1] == _hex("0B 00 4C 36 88 13 00 00 00 00 00 00 68 69")
    assert w.sync()
    assert sink.chunks[-1] == _hex("08 00 53 2F 73 13 20 25 0C BB 12")
    assert w.dropout(1000)
    assert sink.chunks[-1] == _hex("02 00 4F E8 03")
    assert w.param_change("p_roll", 50, 6000)
    assert sink.chunks[-1] == _hex("13 00 50 0E") + b"int32_t p_roll" + _hex("32 00 00 00")


def test_log_level_is_clamped_to_ascii_0_to_7():
    w, sink = _writer()
    w.log_message(12, 0, b"x")
    assert sink.chunks[-1][3] == 0x37
    w.log_message(-1, 0, b"x")
    assert sink.chunks[-1][3] == 0x30


def test_format_without_timestamp_is_refused_and_not_written():
    w, sink = _writer()
    n = len(sink.chunks)
    assert not w.add_format("bad", (("float[3]", "xyz"),))
    assert not w.add_format("bad2", (("uint32_t", "timestamp"), ("float", "x")))  # wrong type
    assert len(sink.chunks) == n
    assert w.refused == 2
    assert w.subscribe("bad") == -1


def test_definitions_after_the_first_subscription_are_refused():
    w, sink = _writer()
    w.add_format("rate", RATE_FIELDS)
    w.subscribe("rate")
    n = len(sink.chunks)
    assert not w.add_format("late", (("uint64_t", "timestamp"), ("float", "x")))
    assert not w.add_info("char[2] ver_sw", "v1")
    assert not w.add_param("p_pitch", 1)
    assert len(sink.chunks) == n
    assert w.refused == 3


def test_log_string_also_ends_definitions():
    w, _ = _writer()
    w.log_message(6, 0, "boot")
    assert not w.add_format("late", (("uint64_t", "timestamp"),))


def test_bad_definitions_are_refused():
    w, _ = _writer()
    assert not w.add_info("sys_name", "x")  # no type: pyulog flags corruption
    assert not w.add_info("char[4] sys_name", "hoverfly")  # length differs from the type
    assert not w.add_info("int8_t small", 300)
    assert not w.add_param("bad name", 1)
    assert not w.add_param("big", 1 << 31)
    assert not w.add_param("text", "x")
    assert not w.add_format("x", (("float[0]", "a"), ("uint64_t", "timestamp")))
    assert not w.add_format("x", (("vec9", "a"), ("uint64_t", "timestamp")))  # unknown type
    assert not w.add_format("x y", (("uint64_t", "timestamp"),))
    assert not w.add_format("x", (("uint64_t", "timestamp"), ("float", "timestamp")))
    assert w.add_param("ok", 1)
    assert not w.add_param("ok", 2)  # keys are unique
    assert w.refused == 11


def test_timestamp_going_backwards_is_clamped_per_topic():
    w, sink = _writer()
    w.add_format("rate", RATE_FIELDS)
    a = w.subscribe("rate", 0)
    b = w.subscribe("rate", 1)
    assert w.write_data(a, 5000, (0.0, 0.0, 0.0, 0))
    assert w.write_data(b, 1000, (0.0, 0.0, 0.0, 0))  # another topic: its own clock
    assert w.write_data(a, 4000, (0.0, 0.0, 0.0, 0))
    assert sink.chunks[-1][5:13] == _hex("88 13 00 00 00 00 00 00")  # 5000
    assert w.clamped_timestamps == 1


def test_bad_samples_are_refused_and_counted_never_raised():
    w, sink = _writer()
    w.add_format("rate", RATE_FIELDS)
    m = w.subscribe("rate")
    n = len(sink.chunks)
    assert not w.write_data(m, 1, (0.0, 0.0, 0.0))  # too few values
    assert not w.write_data(m, 1, (0.0, 0.0, 0.0, 256))  # uint8 out of range
    assert not w.write_data(m, 1, (0.0, 0.0, 0.0, -1))
    assert not w.write_data(m, 1, ("a", 0.0, 0.0, 1))
    assert not w.write_data(7, 1, (0.0, 0.0, 0.0, 1))  # unknown msg_id
    assert not w.write_data(m, 1 << 64, (0.0, 0.0, 0.0, 1))
    assert not w.write_data(m, 1, None)
    assert len(sink.chunks) == n
    assert w.refused == 7


def test_u64_timestamp_above_2_to_the_32_packs_exactly():
    w, sink = _writer()
    w.add_format("t", (("uint64_t", "timestamp"),))
    m = w.subscribe("t")
    w.write_data(m, 0x0123456789ABCDEF, ())
    assert sink.chunks[-1] == _hex("0A 00 44 00 00 EF CD AB 89 67 45 23 01")


def test_padding_in_the_middle_is_zeros_and_timestamp_may_come_later():
    w, sink = _writer()
    w.add_format(
        "odd", (("uint8_t", "a"), ("uint8_t[2]", "_padding0"), ("uint64_t", "timestamp"), ("int16_t", "b"))
    )
    m = w.subscribe("odd")
    assert w.write_data(m, 0x0102, (0xAA, -2))
    assert sink.chunks[-1] == _hex("0F 00 44 00 00 AA 00 00 02 01 00 00 00 00 00 00 FE FF")


def test_bool_and_char_array_fields():
    w, sink = _writer()
    w.add_format("s", (("uint64_t", "timestamp"), ("bool", "armed"), ("char[4]", "mode")))
    m = w.subscribe("s")
    assert w.write_data(m, 1, (True, b"ACRO"))
    assert sink.chunks[-1][-5:] == b"\x01ACRO"


def test_nested_format_is_flattened_into_the_parent():
    w, sink = _writer()
    assert w.add_format("vec3", (("uint64_t", "timestamp"), ("float[3]", "v")))
    assert w.add_format("pair", (("uint64_t", "timestamp"), ("vec3[2]", "acc")))
    m = w.subscribe("pair")
    assert w.write_data(m, 3, (1, 1.0, 0.0, 0.0, 2, 0.0, 0.0, 1.0))
    d = sink.chunks[-1]
    assert len(d) == 5 + 8 + 2 * 20
    assert d[13:21] == _hex("01 00 00 00 00 00 00 00") and d[21:25] == _hex("00 00 80 3F")


def test_maybe_sync_writes_about_once_a_second():
    w, sink = _writer()
    w.begin_data()
    written = 0
    for t_us in range(0, 3000000, 1000):
        if w.maybe_sync(t_us):
            written += 1
    assert written == 3


def test_ring_sink_round_trips_across_the_wrap():
    ring = RingSink(64)
    out = bytearray()
    sent = bytearray()
    split = 0
    for i in range(40):
        msg = bytes([i]) * (1 + i % 23)
        split += ring._head + len(msg) > ring.size
        assert ring.write(msg) == len(msg)
        sent.extend(msg)
        ring.drain(out.extend, ring.used - 1)  # one byte stays: the ring never empties, so it wraps
    ring.drain(out.extend)
    assert split > 5  # messages did straddle the end
    assert ring.dropped_bytes == 0 and ring.used == 0
    assert bytes(out) == bytes(sent)
    assert ring.bytes_in == ring.bytes_out == len(out)


def test_an_emptied_ring_starts_again_at_the_front():
    ring = RingSink(16)
    chunks = []
    ring.write(b"0123456789")
    ring.drain(chunks.append)
    ring.write(b"abcdefghij")  # would straddle the end at 10; the ring is empty, so it goes at 0
    ring.drain(lambda mv: chunks.append(bytes(mv)))
    assert chunks[1:] == [b"abcdefghij"]  # one piece, not two


def test_ring_sink_drain_honours_max_bytes_and_partial_writes():
    ring = RingSink(16)
    ring.write(b"0123456789")
    out = bytearray()
    assert ring.drain(out.extend, 4) == 4
    assert ring.drain(lambda mv: out.extend(mv[:3]) or 3) == 3  # the port took only 3
    assert ring.drain(out.extend) == 3
    assert bytes(out) == b"0123456789"


def test_ring_full_drops_whole_messages_and_writer_marks_the_dropout():
    ring = RingSink(200)
    w = UlogWriter(ring, 0)
    w.add_format("rate", RATE_FIELDS)
    m = w.subscribe("rate")
    out = bytearray()
    ring.drain(out.extend)
    for i in range(10):  # 26 bytes each: 7 fit, 3 dropped
        w.write_data(m, i * 1000, (0.0, 0.0, 0.0, 0))
    # the ring refused the first; the writer held back the rest while the ring stayed full
    assert w.dropped_messages == 3 and ring.dropped_messages == 1 and ring.dropouts == 1
    ring.drain(out.extend)
    assert w.write_data(m, 20000, (0.0, 0.0, 0.0, 0))
    ring.drain(out.extend)
    # O (dropout since the first lost sample at 7000 us: 13 ms) then the sample
    assert out[-31:-26] == _hex("02 00 4F 0D 00")
    assert out[-26:-23] == _hex("17 00 44")
    assert w.dropouts == 1


def test_a_memoryview_written_into_the_ring_round_trips_across_the_wrap():
    # The logger hands its batches over as memoryviews of its stage.
    ring = RingSink(16)
    out = bytearray()
    stage = bytearray(b"0123456789abcdef")
    assert ring.write(memoryview(stage)[0:10]) == 10
    ring.drain(out.extend, 9)  # one byte stays: the next write straddles the end
    assert ring.write(memoryview(stage)[4:14]) == 10
    ring.drain(out.extend)
    assert bytes(out) == b"0123456789" + b"456789abcd"


LINK_FIELDS = (
    ("uint64_t", "timestamp"),
    ("uint32_t", "frames"),
    ("float", "rssi_dbm"),
    ("bool", "ok"),
)


def test_messages_packed_by_data_layout_equal_write_data():
    direct, sink_d = _writer(0)
    packed, sink_p = _writer(0)
    for w in (direct, packed):
        w.add_format("rate", RATE_FIELDS)
        w.add_format("link", LINK_FIELDS)
    ids = [(w.subscribe("rate"), w.subscribe("link")) for w in (direct, packed)]
    direct.write_data(ids[0][0], 7000, (0.5, -1.0, 2.0, 1))
    direct.write_data(ids[0][1], 7000, (123456, -71.5, True))
    head_r, fmt_r = packed.data_layout(ids[1][0])
    head_l, fmt_l = packed.data_layout(ids[1][1])
    assert head_r == bytes(sink_d.chunks[-2][0:5]) and head_l == bytes(sink_d.chunks[-1][0:5])
    fmt = "<5s" + fmt_r + "5s" + fmt_l
    buf = bytearray(struct.calcsize(fmt))
    assert packed.write_packed(buf, fmt, (head_r, 7000, 0.5, -1.0, 2.0, 1, head_l, 7000, 123456, -71.5, True), 2, 7000)
    assert sink_p.chunks[-1] == sink_d.chunks[-2] + sink_d.chunks[-1]  # two messages, one write
    assert packed.messages == direct.messages and packed.bytes_written == direct.bytes_written
    assert packed.data_layout(99) is None


def test_write_packed_refuses_all_of_a_pack_it_cannot_pack():
    w, sink = _writer(0)
    w.add_format("link", LINK_FIELDS)
    m = w.subscribe("link")
    head, fmt = w.data_layout(m)
    n = len(sink.chunks)
    buf = bytearray(5 + 8 + 4 + 4 + 1)
    assert not w.write_packed(buf, "<5s" + fmt, (head, 1000, "not a number", 0.0, True), 1, 1000)
    assert w.refused == 1 and len(sink.chunks) == n


def test_writer_through_a_ring_equals_direct_bytes():
    direct = ListSink()
    ring = RingSink(97)  # odd size so messages straddle the end
    out = bytearray()
    for sink in (direct, ring):
        w = UlogWriter(sink, 5)
        ring.drain(out.extend)
        w.add_format("rate", RATE_FIELDS)
        ring.drain(out.extend)
        m = w.subscribe("rate")
        for i in range(50):
            w.write_data(m, i, (i * 0.5, -1.0, 2.0, i & 1))
            ring.drain(out.extend, ring.used - 3)  # never empty: messages straddle the end
    ring.drain(out.extend)
    assert bytes(out) == direct.all()


def test_write_data_allocates_nothing_on_micropython():
    w = UlogWriter(NullSink(), 0)
    w.add_format(
        "vehicle_attitude",
        (("uint64_t", "timestamp"), ("float[4]", "q"), ("float[3]", "rate"), ("uint8_t", "reset_counter")),
    )
    m = w.subscribe("vehicle_attitude")
    values = [1.0, 0.0, 0.0, 0.0, 0.1, 0.2, 0.3, 1]
    w.write_data(m, 1, values)
    collect_garbage()
    disable_gc()
    try:
        before = mem_alloc()
        for t in range(2, 102):
            w.write_data(m, t, values)
        grown = mem_alloc() - before
    finally:
        enable_gc()
    assert grown == 0 or not IS_MICROPYTHON
    assert w.messages == 2 + 1 + 1 + 101
