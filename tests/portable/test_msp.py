"""MSP v1/v2 codec: the reference vectors (protocols.md §6.2) both ways, framing, payload layouts."""

from hoverfly.protocols import msp
from hoverfly.protocols.msp import MspParser


def _hex(text):
    parts = text.split()
    out = bytearray(len(parts))
    for i in range(len(parts)):
        out[i] = int(parts[i], 16)
    return bytes(out)


API_REQ_V1 = _hex("24 4D 3C 00 01 01")
API_REPLY_V1 = _hex("24 4D 3E 03 01 00 01 2E 2D")
VARIANT_REPLY = _hex("24 4D 3E 04 02 42 54 46 4C 1A")
ATTITUDE_REQ = _hex("24 4D 3C 00 6C 6C")
ATTITUDE_REPLY = _hex("24 4D 3E 06 6C 7B 00 D3 FF 0E 01 32")
RAW_RC_REQ = _hex("24 4D 3C 10 C8 DC 05 DC 05 E8 03 DC 05 E8 03 D0 07 DC 05 DC 05 D6")
RAW_RC_ACK = _hex("24 4D 3E 00 C8 C8")
SET_MOTOR_REQ = _hex("24 4D 3C 10 D6 E8 03 4C 04 E8 03 E8 03 E8 03 E8 03 E8 03 E8 03 65")
EEPROM_REQ = _hex("24 4D 3C 00 FA FA")
STATUS_EX_REQ = _hex("24 4D 3C 00 96 96")
ERROR_77 = _hex("24 4D 21 00 4D 4D")
API_REQ_V2 = _hex("24 58 3C 00 01 00 00 00 45")
API_REPLY_V2 = _hex("24 58 3E 00 01 00 03 00 00 01 2E 9C")
REQ_0x1001_V2 = _hex("24 58 3C 00 01 10 00 00 5C")
API_REQ_V2_OVER_V1 = _hex("24 4D 3C 06 FF 00 01 00 00 00 45 BD")
JUMBO_71 = _hex("24 4D 3E FF 47 2C 01") + bytes(300) + _hex("95")
RC_8 = [1500, 1500, 1000, 1500, 1000, 2000, 1500, 1500]


def _messages(parser):
    out = []
    while parser.pop():
        out.append((parser.version, parser.direction, parser.cmd, parser.message(), parser.encapsulated))
    return out


def test_encoders_reproduce_the_reference_vectors():
    assert msp.encode_request(msp.MSP_API_VERSION) == API_REQ_V1
    assert msp.encode_reply(1, msp.MSP_API_VERSION, msp.pack_api_version(0, 1, 46)) == API_REPLY_V1
    assert msp.encode_reply(1, msp.MSP_FC_VARIANT, msp.pack_fc_variant("BTFL")) == VARIANT_REPLY
    assert msp.encode_request(msp.MSP_ATTITUDE) == ATTITUDE_REQ
    assert msp.encode_reply(1, msp.MSP_ATTITUDE, msp.pack_attitude(123, -45, 270)) == ATTITUDE_REPLY
    assert msp.encode_request(msp.MSP_SET_RAW_RC, msp.pack_set_raw_rc(RC_8)) == RAW_RC_REQ
    assert msp.encode_reply(1, msp.MSP_SET_RAW_RC) == RAW_RC_ACK
    motors = msp.pack_set_motor([1000, 1100] + [1000] * 6)
    assert msp.encode_request(msp.MSP_SET_MOTOR, motors) == SET_MOTOR_REQ
    assert msp.encode_request(msp.MSP_EEPROM_WRITE) == EEPROM_REQ
    assert msp.encode_request(msp.MSP_STATUS_EX) == STATUS_EX_REQ
    assert msp.encode_v1(77, b"", error=True) == ERROR_77
    assert msp.encode_reply(1, 77, error=True) == ERROR_77
    assert msp.encode_request(msp.MSP_API_VERSION, version=2) == API_REQ_V2
    assert msp.encode_reply(2, msp.MSP_API_VERSION, msp.pack_api_version()) == API_REPLY_V2
    assert msp.encode_request(0x1001, version=2) == REQ_0x1001_V2
    assert msp.encode_request(msp.MSP_API_VERSION, version=2, encapsulated=True) == API_REQ_V2_OVER_V1
    assert msp.encode_reply(1, 71, bytes(300)) == JUMBO_71
    assert len(JUMBO_71) == 308


def test_parser_decodes_every_reference_vector_in_one_stream():
    stream = (API_REQ_V1 + API_REPLY_V1 + VARIANT_REPLY + ATTITUDE_REPLY + RAW_RC_REQ + ERROR_77
              + API_REQ_V2 + API_REPLY_V2 + REQ_0x1001_V2 + API_REQ_V2_OVER_V1 + JUMBO_71)
    p = MspParser(queue_depth=11)
    assert p.feed(stream) == 11
    got = _messages(p)
    assert got[0] == (1, msp.DIR_REQUEST, 1, b"", False)
    assert got[1] == (1, msp.DIR_REPLY, 1, bytes([0, 1, 46]), False)
    assert got[2][3] == b"BTFL"
    assert msp.unpack_attitude(got[3][3]) == (123, -45, 270)
    assert msp.unpack_set_raw_rc(got[4][3]) == RC_8
    assert got[5] == (1, msp.DIR_ERROR, 77, b"", False)
    assert got[6] == (2, msp.DIR_REQUEST, 1, b"", False)
    assert got[7] == (2, msp.DIR_REPLY, 1, bytes([0, 1, 46]), False)
    assert got[8][2] == 0x1001
    assert got[9] == (2, msp.DIR_REQUEST, 1, b"", True)
    assert got[10][2] == 71 and got[10][3] == bytes(300)
    assert p.frames == 11 and p.crc_errors == 0 and p.resyncs == 0


def test_message_split_at_every_byte_is_decoded_once():
    for frame in (RAW_RC_REQ, API_REPLY_V2, API_REQ_V2_OVER_V1, JUMBO_71):
        for cut in range(len(frame) + 1):
            p = MspParser(queue_depth=2)
            n = p.feed(frame[:cut]) + p.feed(frame[cut:])
            assert n == 1, cut
            assert p.pop()
            assert not p.pop()
            assert p.crc_errors == 0


def test_one_byte_at_a_time_matches_one_chunk():
    stream = b"xx$M" + RAW_RC_REQ + b"\x00$" + API_REPLY_V2 + b"$X<" + JUMBO_71
    a = MspParser()
    a.feed(stream)
    b = MspParser()
    for k in range(len(stream)):
        b.feed(stream[k:k + 1])
    assert _messages(a) == _messages(b)
    assert (a.frames, a.crc_errors, a.resyncs, a.length_errors) == (b.frames, b.crc_errors, b.resyncs,
                                                                     b.length_errors)


def test_feed_takes_only_the_first_n_bytes():
    p = MspParser()
    buf = bytearray(64)
    for k in range(len(ATTITUDE_REQ)):
        buf[k] = ATTITUDE_REQ[k]
    assert p.feed(buf, len(ATTITUDE_REQ)) == 1
    assert p.bytes == len(ATTITUDE_REQ)
    assert p.feed(memoryview(API_REQ_V1)) == 1


def test_bad_checksum_is_dropped_counted_and_the_next_frame_decoded():
    bad = bytearray(ATTITUDE_REPLY)
    bad[-1] ^= 0x01
    bad_v2 = bytearray(API_REPLY_V2)
    bad_v2[-1] ^= 0x80
    p = MspParser()
    assert p.feed(bytes(bad) + bytes(bad_v2) + API_REQ_V1) == 1
    assert p.crc_errors == 2
    assert p.pop() and p.cmd == msp.MSP_API_VERSION
    assert not p.pop()


def test_frame_hidden_behind_a_false_start_is_found():
    # "$M<" with a size that swallows the real frame: the checksum fails and the rescan finds it.
    stream = _hex("24 4D 3C 08") + API_REQ_V1 + bytes(4)
    p = MspParser()
    assert p.feed(stream) == 1
    assert p.pop() and p.cmd == msp.MSP_API_VERSION
    assert p.crc_errors == 1


def test_oversize_frame_is_refused_and_counted():
    p = MspParser(max_payload=64)
    big = msp.encode_v2(0x1F03, bytes(100), msp.DIR_REQUEST)
    assert p.feed(big + API_REQ_V1) == 1
    assert p.oversize == 1
    assert p.pop() and p.cmd == 1


def test_v2_over_v1_with_bad_inner_crc_is_dropped():
    bad = bytearray(API_REQ_V2_OVER_V1)
    bad[-2] ^= 0x01  # inner CRC
    bad[-1] ^= 0x01  # keep the outer XOR right
    p = MspParser()
    assert p.feed(bytes(bad) + API_REQ_V1) == 1
    assert p.crc_errors == 1
    assert p.pop() and p.version == 1


def test_full_queue_keeps_the_newest_and_counts_the_dropped():
    p = MspParser(queue_depth=2)
    frames = [msp.encode_request(c) for c in (1, 2, 3)]
    assert p.feed(b"".join(frames)) == 3
    assert p.dropped == 1
    assert p.pending() == 2
    assert p.pop() and p.cmd == 2
    assert p.pop() and p.cmd == 3


def test_idle_drops_a_truncated_frame_so_the_next_is_decoded_at_once():
    p = MspParser()
    p.feed(RAW_RC_REQ[:7])
    p.idle()
    assert p.length_errors == 1
    assert p.feed(API_REQ_V1) == 1


def test_garbage_never_raises():
    p = MspParser(max_payload=32)
    junk = bytearray(256)
    for k in range(256):
        junk[k] = (k * 73 + 41) & 0xFF
    p.feed(junk)
    p.feed(b"$$$$MMMXXX<<<>>>!!!" * 3 + b"$M>\xff")
    p.feed(b"$X>\x00\x01\x00\xff\xff")
    assert p.feed(b"\x00" * 40 + API_REQ_V1) >= 1


def test_status_layouts_have_betaflight_sizes():
    s = msp.pack_status(125, 0, 0x21, 1, 0, 12, 1 << msp.ARMING_DISABLED_MSP, cpu_temp_c=40)
    assert len(s) == 24
    d = msp.unpack_status(s)
    assert d["cycle_time_us"] == 125 and d["sensors"] == 0x21 and d["mode_flags"] == 1
    assert d["arming_flag_count"] == 26 and d["arming_disable_flags"] == 1 << 16 and d["cpu_temp_c"] == 40
    ex = msp.pack_status_ex(125, pid_profile_count=3, rate_profile=2, extra_mode_bytes=b"\x01")
    assert len(ex) == 25
    d = msp.unpack_status(ex, ex=True)
    assert d["pid_profile_count"] == 3 and d["rate_profile"] == 2 and d["extra_mode_bytes"] == b"\x01"


def test_payload_round_trips():
    assert msp.unpack_api_version(msp.pack_api_version()) == (0, 1, 46)
    assert msp.unpack_fc_version(msp.pack_fc_version(4, 5, 1)) == (4, 5, 1, None)
    assert msp.unpack_fc_version(msp.pack_fc_version(25, 12, 0, "2025.12.0")) == (25, 12, 0, "2025.12.0")
    assert msp.unpack_name(msp.pack_name("hoverfly-quad-number-one")) == "hoverfly-quad-nu"
    acc, gyro, mag = msp.unpack_raw_imu(msp.pack_raw_imu((0, 0, 2048), (-16, 40000, 3), (1, 2, 3)))
    assert tuple(acc) == (0, 0, 2048) and tuple(gyro) == (-16, 32767, 3) and tuple(mag) == (1, 2, 3)
    assert msp.unpack_motor(msp.pack_motor([1000, 1500, 2000, 1000])) == [1000, 1500, 2000, 1000, 0, 0, 0, 0]
    assert msp.unpack_rc(msp.pack_rc(RC_8)) == RC_8
    assert msp.unpack_attitude(msp.pack_attitude(-1800, 900, -90)) == (-1800, 900, 270)
    assert msp.unpack_altitude(msp.pack_altitude(-250, 37)) == (-250, 37)
    assert msp.unpack_analog(msp.pack_analog(1234, 560, 1023, -150)) == (123, 560, 1023, -150, 1234)
    assert msp.unpack_analog(msp.pack_analog(4000, 0))[0] == 255  # clamped
    gains = [(45, 80, 30), (47, 84, 34), (45, 80, 0), (50, 50, 75), (40, 0, 0)]
    assert msp.unpack_pid(msp.pack_pid(gains)) == gains
    assert msp.unpack_boxnames(msp.pack_boxnames(["ARM", "ANGLE"])) == ["ARM", "ANGLE"]
    assert msp.pack_boxnames(["ARM", "ANGLE"]) == b"ARM;ANGLE;"
    assert msp.unpack_boxids(msp.pack_boxids([0, 1, 50])) == [0, 1, 50]
    assert msp.unpack_uid(msp.pack_uid(1, 2, 0xFFFFFFFF)) == (1, 2, 0xFFFFFFFF)
    assert msp.unpack_set_arming_disabled(msp.pack_set_arming_disabled(True, False)) == (1, 0)
    assert msp.unpack_set_arming_disabled(b"") == (0, 0)
    assert msp.unpack_reboot(msp.pack_reboot(1)) == 1 and msp.unpack_reboot(msp.pack_reboot()) == 0
    r = msp.pack_mode_ranges([(0, 0, msp.step_of_us(1700), msp.step_of_us(2100))])
    assert len(r) == 80
    assert msp.unpack_mode_ranges(r)[0] == (0, 0, 32, 48)
    assert msp.us_of_step(32) == 1700


def test_rc_tuning_is_23_bytes_in_wire_order():
    t = {"roll_rc_rate": 100, "roll_rc_expo": 0, "roll_rate": 70, "pitch_rate": 70, "yaw_rate": 70,
         "throttle_mid": 50, "yaw_rc_rate": 100, "pitch_rc_rate": 100, "roll_rate_limit_dps": 1998,
         "rates_type": 3}
    b = msp.pack_rc_tuning(t)
    assert len(b) == 23
    assert b[0] == 100 and b[2] == 70 and b[6] == 50 and b[-1] == 3
    d = msp.unpack_rc_tuning(b)
    assert d["roll_rate_limit_dps"] == 1998 and d["pitch_rc_rate"] == 100 and "_zero1" not in d


def test_board_and_build_info_round_trip():
    b = msp.pack_board_info("HVFL", 0, 0, 0x01, "PICO", "pico", "RPI", b"", 0, 2, 1000, 0x1, 0, 1)
    d = msp.unpack_board_info(b)
    assert d["board_id"] == "HVFL" and d["target_name"] == "PICO" and d["manufacturer_id"] == "RPI"
    assert d["gyro_rate_hz"] == 1000 and d["problems"] == 1 and d["i2c_devices"] == 1
    date, time, githash, opts = msp.unpack_build_info(msp.pack_build_info("Jan 01 2026", "12:00:00",
                                                                          "abcdef1", (1, 2)))
    assert (date, time, githash, opts) == ("Jan 01 2026", "12:00:00", "abcdef1", [1, 2])


def test_set_raw_rc_into_fills_a_preallocated_array_without_overrun():
    from array import array

    out = array("H", [0] * 4)
    payload = msp.pack_set_raw_rc(RC_8)
    assert msp.unpack_set_raw_rc_into(payload, len(payload), out) == 4
    assert list(out) == RC_8[:4]
    assert msp.unpack_set_raw_rc(payload, 5) == RC_8[:2]  # an odd trailing byte is ignored


def test_arming_flags_table_follows_the_reference_bits():
    f = msp.ARMING_DISABLE_FLAGS
    assert len(f) == msp.ARMING_FLAG_COUNT == 26
    assert f[0] == "NO_GYRO" and f[2] == "RX_FAILSAFE" and f[7] == "THROTTLE" and f[8] == "ANGLE"
    assert f[16] == "MSP" and f[23] == "ACC_CALIBRATION" and f[25] == "ARM_SWITCH"
    assert len(msp.ARMING_DISABLE_CLI_NAMES) == 26 and msp.ARMING_DISABLE_CLI_NAMES[2] == "RXLOSS"
    assert msp.arming_flag_names((1 << 7) | (1 << 16) | (1 << 30)) == ["THROTTLE", "MSP", "BIT30"]


def test_command_ids_match_the_reference():
    assert (msp.MSP_API_VERSION, msp.MSP_FC_VARIANT, msp.MSP_FC_VERSION, msp.MSP_BOARD_INFO) == (1, 2, 3, 4)
    assert (msp.MSP_BUILD_INFO, msp.MSP_NAME, msp.MSP_REBOOT, msp.MSP_SET_ARMING_DISABLED) == (5, 10, 68, 99)
    assert (msp.MSP_STATUS, msp.MSP_RAW_IMU, msp.MSP_MOTOR, msp.MSP_RC) == (101, 102, 104, 105)
    assert (msp.MSP_ATTITUDE, msp.MSP_ALTITUDE, msp.MSP_ANALOG, msp.MSP_RC_TUNING) == (108, 109, 110, 111)
    assert (msp.MSP_PID, msp.MSP_BOXNAMES, msp.MSP_BOXIDS, msp.MSP_STATUS_EX) == (112, 116, 119, 150)
    assert (msp.MSP_UID, msp.MSP_SET_RAW_RC, msp.MSP_SET_PID, msp.MSP_ACC_CALIBRATION) == (160, 200, 202, 205)
    assert (msp.MSP_SET_MOTOR, msp.MSP_EEPROM_WRITE, msp.MSP_MODE_RANGES) == (214, 250, 34)


def test_encoder_refuses_impossible_frames():
    for bad in ((lambda: msp.encode_v1(256)), (lambda: msp.encode_v2(70000)),
                (lambda: msp.encode_v1(1, b"", "?"))):
        try:
            bad()
            raised = False
        except ValueError:
            raised = True
        assert raised
