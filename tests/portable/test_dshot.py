"""DShot codec: frame and reply vectors (protocols.md §4), clamping, motor encoder, command queue, EDT."""

from array import array

from hoverfly.compat import IS_MICROPYTHON, collect_garbage, disable_gc, enable_gc, mem_alloc, ticks_add
from hoverfly.protocols import dshot
from hoverfly.protocols.dshot import (
    DshotCommandQueue,
    DshotEncoder,
    ErpmDecoder,
    dshot_frame,
    dshot_timing,
    frame_crc_ok,
    frame_value,
)

# value, t, normal word, bidirectional word (protocols.md §4.2 vectors)
FRAME_VECTORS = (
    (1046, 0, 0x82C6, 0x82C9),
    (48, 0, 0x0606, 0x0609),
    (2047, 0, 0xFFEE, 0xFFE1),
    (0, 0, 0x0000, 0x000F),
    (21, 1, 0x02B9, 0x02B6),
    (13, 1, 0x01BA, 0x01B5),
    (1, 1, 0x0033, 0x003C),
)

# 12-bit, 16-bit word, GCR 20 bit, 21 transition bits, 21 line levels, BF eRPM/100 (§4.3 vectors)
REPLY_VECTORS = (
    (0x5F4, 0x5F41, 0xABFBB, "110101011111110111011", "011001101010100101101", 300),
    (0x32C, 0x32C2, 0x9CBD2, "110011100101111010010", "011101000110101100011", 1000),
    (0xFFF, 0xFFF0, 0x7BDF9, "101111011110111111001", "001010010100101010001", 0),
    (0x22D, 0x22D2, 0x949B2, "110010100100110110010", "011100111000100100011", None),
)

T0 = (1 << 30) - 3000  # start just below the rp2 tick wrap


def test_frame_vectors_normal_and_bidirectional():
    for value, t, normal, bidir in FRAME_VECTORS:
        assert dshot_frame(value, t) == normal, value
        assert dshot_frame(value, t, True) == bidir, value


def test_frame_bits_go_out_msb_first():
    w = dshot_frame(1046, 0)
    bits = "".join("1" if (w >> (15 - i)) & 1 else "0" for i in range(16))
    assert bits == "1000001011000110"


def test_frame_fields_read_back_and_crc_checks():
    for value, t, normal, bidir in FRAME_VECTORS:
        assert frame_value(normal) == value and dshot.frame_telemetry(normal) == t
        assert frame_crc_ok(normal) and not frame_crc_ok(normal, True)
        assert frame_crc_ok(bidir, True) and not frame_crc_ok(bidir)
        assert not frame_crc_ok(normal ^ 0x0100)


def test_out_of_range_value_is_clamped_and_counted_never_wrapped():
    dshot.reset_frame_clamped()
    assert frame_value(dshot_frame(2048)) == 2047  # a wrap would give 0 = stop
    assert frame_value(dshot_frame(4096 + 100)) == 2047
    assert frame_value(dshot_frame(-1)) == 0  # a wrap would give 2047 = full throttle
    assert dshot.frame_clamped() == 3
    dshot_frame(2047)
    dshot_frame(0)
    assert dshot.frame_clamped() == 3


def test_betaflight_external_scale():
    assert dshot.value_from_external(1000) == 0
    assert dshot.value_from_external(1001) == 48
    assert dshot.value_from_external(1500) == 1046  # 1046.5 truncated as BF's uint16 cast
    assert dshot.value_from_external(2000) == 2047
    assert dshot.value_from_external(900) == 0 and dshot.value_from_external(2500) == 2047


def test_throttle_to_value_maps_armed_range_from_idle_to_full():
    enc = DshotEncoder(4, stop_at_zero=False)
    assert enc.throttle_to_value(0.5, 0.0, armed=False) == 0
    assert enc.throttle_to_value(0.0, 0.0) == 48
    assert enc.throttle_to_value(1.0, 0.0) == 2047
    assert enc.throttle_to_value(0.5, 0.0) == 1048  # 48 + 999.5, rounded half up
    # Betaflight dshot_idle_value 5.5 %: 48 + 1999 * 0.055 = 157.9
    assert enc.throttle_to_value(0.0, 5.5) == 158
    assert enc.throttle_to_value(1.0, 5.5) == 2047


def test_stop_at_zero_follows_the_board_contract():
    enc = DshotEncoder(4, idle_pct=5.5)  # stop_at_zero=True by default: 0 = stop
    assert enc.throttle_to_value(0.0) == 0
    assert enc.throttle_to_value(0.0001) == 158
    assert enc.clamped == 0


def test_encode_motors_writes_words_and_disarmed_writes_stop():
    enc = DshotEncoder(4, stop_at_zero=False)
    out = array("H", [0xAAAA] * 4)
    motors = array("f", [0.0, 0.5, 1.0, 0.25])
    enc.encode_motors(motors, True, out)
    assert [frame_value(w) for w in out] == [48, 1048, 2047, 548]
    assert all(frame_crc_ok(w) for w in out)
    enc.encode_motors(motors, False, out)
    assert list(out) == [0, 0, 0, 0]


def test_encode_motors_bidirectional_and_telemetry_request():
    enc = DshotEncoder(4, bidir=True, stop_at_zero=False)
    enc.telemetry_motor = 2
    out = array("H", [0] * 4)
    enc.encode_motors(array("f", [0.0, 0.0, 0.0, 1.0]), True, out)
    assert out[0] == 0x0609 and out[3] == 0xFFE1
    assert dshot.frame_telemetry(out[2]) == 1 and frame_crc_ok(out[2], True)
    enc.encode_motors(array("f", [0.0] * 4), False, out)
    assert list(out) == [0x000F] * 4


def test_encode_motors_clamps_and_counts_bad_commands():
    enc = DshotEncoder(4, stop_at_zero=False)
    out = array("H", [0] * 4)
    nan = float("nan")
    enc.encode_motors([1.7, -0.3, nan, float("inf")], True, out)
    assert [frame_value(w) for w in out] == [2047, 48, 48, 2047]
    assert enc.clamped == 4
    stop = DshotEncoder(2)
    stop.encode_motors([nan, -1.0], True, out)
    assert out[0] == 0 and out[1] == 0 and stop.clamped == 2


def test_encode_values_integer_path_clamps_and_allocates_nothing():
    enc = DshotEncoder(4)
    out = array("H", [0] * 4)
    vals = array("h", [48, 1046, 3000, -5])
    enc.encode_values(vals, out)
    assert [frame_value(w) for w in out] == [48, 1046, 2047, 0] and enc.clamped == 2
    if IS_MICROPYTHON:
        vals = array("h", [48, 1046, 1500, 2047])
        enc.encode_values(vals, out)
        collect_garbage()
        disable_gc()
        try:
            before = mem_alloc()
            for _ in range(50):
                enc.encode_values(vals, out)
            grown = mem_alloc() - before
        finally:
            enable_gc()
        assert grown == 0, grown


def test_bit_timing_table_matches_the_reference():
    # speed: bit ns, T0H, T1H, frame ns, PIO SM Hz (8 x bit rate), reply bit ns (5/4 rate)
    expect = {
        150: (6667, 2500, 5000, 106667, 1200000, 5333),
        300: (3333, 1250, 2500, 53333, 2400000, 2667),
        600: (1667, 625, 1250, 26667, 4800000, 1333),
        1200: (833, 313, 625, 13333, 9600000, 667),
    }
    for speed in dshot.SPEEDS_KBIT:
        assert dshot_timing(speed) == expect[speed], speed
        bit_ns = dshot_timing(speed)[0]
        # PIO: 6 of 8 cycles high for a 1, 3 for a 0
        assert abs(bit_ns * dshot.PIO_CYCLES_HIGH_1 / dshot.PIO_CYCLES_PER_BIT - dshot_timing(speed)[2]) < 1
        assert abs(bit_ns * dshot.PIO_CYCLES_HIGH_0 / dshot.PIO_CYCLES_PER_BIT - dshot_timing(speed)[1]) < 1
    assert dshot_timing(450) is None


def test_pio_word_puts_the_frame_in_the_top_half():
    assert dshot.pio_word(0x82C6) == 0x82C60000
    assert dshot.pio_word(0x82C6) == 0x82C6 << dshot.PIO_SHIFT


def test_command_table_names_repeats_and_waits():
    names = dshot.COMMAND_NAMES
    assert names[1] == "BEEP1" and names[5] == "BEEP5" and names[6] == "ESC_INFO"
    assert names[9] == "3D_MODE_OFF" and names[12] == "SAVE_SETTINGS"
    assert names[13] == "EXTENDED_TELEMETRY_ENABLE" and names[21] == "SPIN_DIRECTION_REVERSED"
    assert names[22] == "LED0_ON" and names[29] == "LED3_OFF" and names[31] == "SILENT_MODE"
    assert dshot.command_repeats(1) == 1 and dshot.command_delay_us(1) == 260000
    assert dshot.command_repeats(6) == 1 and dshot.command_delay_us(6) == 12000
    for v in (7, 8, 9, 10, 12, 13, 14, 20, 21):
        assert dshot.command_repeats(v) == 10, v
    assert dshot.command_delay_us(12) == 35000
    assert dshot.command_repeats(0) == 0 and dshot.command_repeats(48) == 0
    assert dshot.command_value("beacon3") == 3 and dshot.command_value("DSHOT_CMD_SAVE_SETTINGS") == 12
    assert dshot.command_value("NO_SUCH") == -1


def test_queue_refuses_values_outside_1_to_47_and_while_armed():
    q = DshotCommandQueue()
    for bad in (0, 48, -1, 2047):
        r = q.push(bad, False)
        assert r is not True and "1..47" in r
    r = q.push(12, True)
    assert r is not True and "armed" in r
    assert q.refused == 5 and not q.busy()


def _run(q, start_us, step_us, frames, armed=False, throttle=0x0000):
    """Word per frame at a fixed frame interval: list of (t_us offset, word)."""
    out = []
    now = start_us
    for i in range(frames):
        out.append((i * step_us, q.word(now, armed, throttle)))
        now = ticks_add(now, step_us)
    return out


def test_queue_repeats_a_settings_command_ten_times_1ms_apart_then_throttle():
    q = DshotCommandQueue()
    assert q.push(dshot.CMD_SPIN_DIRECTION_REVERSED, False) is True
    frames = _run(q, T0, 125, 200)  # 8 kHz loop across the tick wrap
    cmd = dshot_frame(21, 1)
    sent = [t for t, w in frames if w == cmd]
    assert len(sent) == 10 and sent[0] == 0
    assert all(sent[i + 1] - sent[i] == 1000 for i in range(9))
    assert all(w == 0 for t, w in frames if t > sent[-1])
    assert not q.busy() and q.sent == 10


def test_queue_waits_after_a_beep_before_the_next_command():
    q = DshotCommandQueue(bidir=True)
    q.push(dshot.CMD_BEEP1, False)
    q.push(dshot.CMD_ESC_INFO, False)
    frames = _run(q, T0, 1000, 400)
    beep = [t for t, w in frames if w == dshot_frame(1, 1, True)]
    info = [t for t, w in frames if w == dshot_frame(6, 1, True)]
    assert beep == [0] and info == [260000]


def test_arming_drops_queued_commands():
    q = DshotCommandQueue()
    q.push(dshot.CMD_SAVE_SETTINGS, False)
    q.push(dshot.CMD_BEEP2, False)
    assert q.word(T0, False, 0) == dshot_frame(12, 1)
    assert q.word(ticks_add(T0, 2000), True, 0x1234) == 0x1234
    assert q.aborted == 1 and not q.busy()
    assert q.word(ticks_add(T0, 4000), False, 0) == 0


def test_apply_overwrites_only_the_target_motor():
    q = DshotCommandQueue()
    q.push(dshot.CMD_LED0_ON, False, motor=2)
    out = array("H", [0] * 4)
    assert q.apply(T0, False, out) is True
    assert list(out) == [0, 0, dshot_frame(22, 1), 0]
    out = array("H", [0] * 4)
    assert q.apply(ticks_add(T0, 1000), False, out) is False and list(out) == [0, 0, 0, 0]


def test_queue_full_is_refused():
    q = DshotCommandQueue(capacity=2)
    assert q.push(1, False) is True and q.push(2, False) is True
    assert "full" in q.push(3, False) and q.refused == 1


def test_reply_vectors_gcr_line_code_and_levels():
    for v12, word, gcr, trans, levels, _ in REPLY_VECTORS:
        assert dshot.reply_word(v12) == word
        code = dshot.gcr_encode(word)
        assert code == int(trans, 2) and code & 0xFFFFF == gcr
        assert dshot.code_to_levels(code) == int(levels, 2)
        assert dshot.levels_to_code(int(levels, 2)) == code
        assert dshot.gcr_decode(code) == word


def test_reply_vectors_decode_to_period_erpm_and_betaflight_value():
    for _, word, _, _, _, bf in REPLY_VECTORS:
        assert dshot.reply_crc_ok(word)
        if bf is None:
            continue
        p = dshot.reply_period_us(word)
        assert ((600000 + p // 2) // p if p else 0) == bf
        assert dshot.period_to_erpm(p) // 100 == bf
    assert dshot.reply_period_us(0x5F41) == 2000 and dshot.period_to_erpm(2000) == 30000
    assert dshot.reply_period_us(0x32C2) == 600 and dshot.period_to_erpm(600) == 100000
    assert dshot.reply_period_us(0xFFF0) == 0


def test_erpm_to_rpm_uses_pole_pairs():
    assert dshot.erpm_to_rpm(30000, 14) == 4286  # 30000 / 7
    assert dshot.erpm_to_rpm(100000, 12) == 16667
    assert dshot.rpm_to_erpm(4000, 14) == 28000


def test_simulated_esc_encoders_give_the_vector_words():
    assert dshot.erpm_reply_word(30000) == 0x5F41
    assert dshot.erpm_reply_word(100000) == 0x32C2
    assert dshot.erpm_reply_word(0) == 0xFFF0
    assert dshot.period_reply_word(70000) == 0xFFF0
    assert dshot.edt_reply_word(dshot.KIND_TEMPERATURE, 45) == 0x22D2


def test_erpm_round_trips_within_mantissa_precision():
    for erpm in (918, 1000, 5000, 30000, 100000, 234000, 400000):
        p = dshot.reply_period_us(dshot.erpm_reply_word(erpm))
        back = dshot.period_to_erpm(p)
        assert abs(back - erpm) <= erpm // 128 + 1, (erpm, back)


def test_motor_slower_than_the_longest_period_reads_stopped():
    assert dshot.erpm_reply_word(917) == 0xFFF0
    assert dshot.erpm_reply_word(500) == 0xFFF0


def test_decoder_reads_levels_and_counts_bad_frames():
    dec = ErpmDecoder(pole_count=14)
    assert dec.decode_levels(int("011001101010100101101", 2)) == dshot.KIND_ERPM
    assert dec.period_us == 2000 and dec.erpm == 30000 and dec.rpm == 4286
    assert dec.decode_word(0x5F40) == dshot.KIND_INVALID and dec.crc_errors == 1
    assert dec.decode_code(0x0ABFBB) == dshot.KIND_INVALID  # no start bit
    assert dec.decode_code(0x100000) == dshot.KIND_INVALID  # quintet 00000 is not GCR
    assert dec.gcr_errors == 2 and dec.frames == 1
    assert dec.decode_word(0xFFF0) == dshot.KIND_ERPM and dec.erpm == 0 and dec.rpm == 0


def test_edt_turns_on_with_the_enable_reply_and_decodes_kinds():
    dec = ErpmDecoder()
    assert dec.decode_word(0x22D2) == dshot.KIND_ERPM  # EDT off: read as an eRPM frame
    assert dec.decode_word(dshot.reply_word(0xE01)) == dshot.KIND_STATUS and dec.edt
    assert dec.decode_word(0x22D2) == dshot.KIND_TEMPERATURE and dec.temperature_c == 45
    assert dec.decode_word(dshot.edt_reply_word(dshot.KIND_VOLTAGE, 66)) == dshot.KIND_VOLTAGE
    assert dec.voltage_v == 16.5
    assert dec.decode_word(dshot.edt_reply_word(dshot.KIND_CURRENT, 12)) == dshot.KIND_CURRENT
    assert dec.current_a == 12
    assert dec.decode_word(dshot.edt_reply_word(dshot.KIND_STRESS, 7)) == dshot.KIND_STRESS
    assert dec.stress == 7
    assert dec.decode_word(dshot.edt_reply_word(dshot.KIND_DEBUG1, 3)) == dshot.KIND_DEBUG1
    assert dec.debug1 == 3
    assert dec.decode_word(0x5F41) == dshot.KIND_ERPM and dec.erpm == 30000  # prefix 0101 is eRPM
    assert dec.decode_word(dshot.reply_word(0xEFF)) == dshot.KIND_STATUS and not dec.edt
    assert dec.edt_frames == 7


def test_decode_reply_for_tools():
    assert dshot.decode_reply(0x5F41) == (dshot.KIND_ERPM, (2000, 30000, 4286))
    assert dshot.decode_reply(0x22D2) == (dshot.KIND_TEMPERATURE, 45)
    assert dshot.decode_reply(0x22D2, edt=False)[0] == dshot.KIND_ERPM
    assert dshot.decode_reply(0x5F40) == (dshot.KIND_INVALID, None)


def test_every_single_bit_flip_of_a_reply_word_is_rejected():
    for v12 in range(0, 4096, 13):
        word = dshot.reply_word(v12)
        for b in range(16):
            assert not dshot.reply_crc_ok(word ^ (1 << b)), (hex(word), b)
