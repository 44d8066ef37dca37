"""Seed-001 maintenance protocol: every command and header field from the seed's tables, framing."""

from hoverfly.protocols import maintenance as mt
from hoverfly.protocols.maintenance import MaintenanceParser


def _hex(text):
    parts = text.split()
    out = bytearray(len(parts))
    for i in range(len(parts)):
        out[i] = int(parts[i], 16)
    return bytes(out)


# The seed's header table, bytes 0..7 left to right (bit 7 first), without the cmd id bits.
SEED_HEADER_NAMES = (
    "raw_accel_x raw_accel_y raw_accel_z raw_gyro_x raw_gyro_y raw_gyro_z raw_magn_x raw_magn_y "
    "raw_magn_z filtered_accel_x filtered_accel_y filtered_accel_z filtered_gyro_x filtered_gyro_y "
    "filtered_gyro_z filtered_magn_x filtered_magn_y filtered_magn_z throttle_signal roll_signal "
    "pitch_signal throttle_set_point roll_set_point pitch_set_point body_roll body_pitch body_yaw "
    "roll_PID_error roll_PID_p roll_PID_i roll_PID_d roll_PID_u pitch_PID_error pitch_PID_p pitch_PID_i "
    "pitch_PID_d pitch_PID_u yaw_PID_error yaw_PID_p yaw_PID_i yaw_PID_d yaw_PID_u "
    "motor1_signal motor2_signal motor3_signal motor4_signal motors_armed builtin_test_status "
    "motor_params js_params PID_params ptf1_params imu_type i2c_read sw_ver imu_offset throttle_params"
).split()

# The seed's reply table "Size (bytes)" column, same order (imu_offset: 12, see the docs).
SEED_FIELD_SIZES = [4] * 18 + [2, 2, 2, 2] + [4] * 20 + [2, 2, 2, 2, 1, 4, 48, 24, 72, 36, 1, 1, 4, 12, 6]

# The seed's command table "Payload size (bytes)" column, command ids 0..25.
SEED_PAYLOAD_SIZES = (10, 12, 12, 12, 12, 12, 11, 10, 15, 15, 15, 15, 18, 18, 18, 34, 34, 34, 22, 22, 22,
                      11, 13, 14, 10, 16)

# Valid arguments for every command (what a client would send).
GOOD_ARGS = (
    (), (1500,), (1100,), (1200,), (2000,), (1000,), (1,), (), (1, 1000, 2000), (0, 1050, 1950),
    (1, 1100, 1900), (1, 1000, 1999), (0.25, 0.5), (0.0, 1.0), (0.75, 0.125),
    (1.5, 0.25, 0.0, 50.0, 0.5, 2.0), (2.0, 0.0, 0.5, 40.0, 0.0, 1.0), (1.0, 0.125, 0.0, 30.0, 0.25, 0.5),
    (0.125, 0.125, 0.125), (0.5, 0.25, 0.125),
    (0.0, 0.0, 1.0), (2,), (1, 0x68, 0x75), (0, 0x68, 0x6B, 0x80), (), (1300, 1450, 1600),
)
RC = (1, 1000, 1500, 1500, 1100)


def test_header_table_has_the_seeds_57_fields_in_order():
    assert mt.FIELD_COUNT == 57 == len(mt.FIELDS) == len(SEED_HEADER_NAMES)
    for k in range(57):
        assert mt.FIELDS[k][0] == SEED_HEADER_NAMES[k], k
        assert mt.FIELD_SIZE[k] == SEED_FIELD_SIZES[k], mt.FIELDS[k][0]
    assert mt.MAX_REPLY_PAYLOAD == sum(SEED_FIELD_SIZES) == 377


def test_every_field_sits_at_the_seeds_bit():
    for k in range(57):
        h = mt.encode_header([SEED_HEADER_NAMES[k]], 0)
        expect = bytearray(8)
        expect[k // 8] = 0x80 >> (k % 8)  # the seed draws bit 7 first in each header byte
        assert h == expect, k
        assert mt.header_fields(h) == [k]
        assert mt.header_wants(h, k) and mt.header_cmd(h) == 0
    h = mt.encode_header([], 0x55)
    assert h == bytearray(7) + bytes([0x55])  # cmd id bits 6..0 of header byte 7
    assert mt.header_cmd(mt.encode_header("all", 25)) == 25
    assert mt.encode_header("all", 25) == _hex("FF FF FF FF FF FF FF 99")


def test_firmware_layout_is_the_c_bitfield_order():
    h = mt.encode_header(["raw_accel_x", "throttle_params"], 25, mt.LAYOUT_FIRMWARE)
    assert h == _hex("01 00 00 00 00 00 00 33")  # field 56 = bit 0 of byte 7, cmd 25 << 1
    assert mt.header_cmd(h, mt.LAYOUT_FIRMWARE) == 25
    assert mt.header_fields(h, mt.LAYOUT_FIRMWARE) == [0, 56]


def test_request_sizes_equal_the_seeds_payload_column():
    for c in range(26):
        assert mt.request_size(c) == SEED_PAYLOAD_SIZES[c], c
        frame = mt.encode_request([], c, GOOD_ARGS[c], RC)
        assert len(frame) == 1 + 8 + SEED_PAYLOAD_SIZES[c], c
    assert mt.request_size(26) == -1


def test_request_vector_set_motor1_byte_exact():
    frame = mt.encode_request(["body_roll"], mt.CMD_SET_MOTOR1, (1500,), RC)
    #            sync header                   pulse  override armed roll  pitch throttle cks
    assert frame == _hex("FF 00 00 00 80 00 00 00 01 DC 05 01 E8 03 DC 05 DC 05 4C 04 FA")


def test_reply_vector_byte_exact_and_decoded_back():
    header = mt.encode_header(["body_roll", "motors_armed", "sw_ver"], 0)
    assert header == _hex("00 00 00 80 00 02 02 00")
    frame = mt.encode_reply(header, {"body_roll": 1.5, "motors_armed": 1, "sw_ver": (1, 2, 3, 1)})
    assert frame == _hex("FF 00 00 00 80 00 02 02 00 00 00 C0 3F 01 01 02 03 01 7F")
    values = mt.decode_reply(header, frame[9:-1])
    assert values == [("body_roll", 1.5), ("motors_armed", 1), ("sw_ver", (1, 2, 3, 1))]


def test_every_command_is_parsed_back_by_the_server():
    p = MaintenanceParser(queue_depth=1)
    for c in range(26):
        frame = mt.encode_request(["motor1_signal", "PID_params"], c, GOOD_ARGS[c], RC)
        assert p.feed(frame) == 1, c
        assert p.pop()
        assert p.cmd_id == c
        assert p.arg_count == len(GOOD_ARGS[c])
        for k in range(p.arg_count):
            assert p.args[k] == GOOD_ARGS[c][k], (c, k)  # all test floats are exact in float32
        assert (p.rc_override, p.rc_armed_us, p.rc_roll_us, p.rc_pitch_us, p.rc_throttle_us) == RC
        assert p.wants(42) and p.wants(50) and not p.wants(0)
        assert mt.validate_command(c, p.args) is None, c
    assert p.frames == 26 and p.crc_errors == 0 and p.resyncs == 0


def test_every_header_field_round_trips_in_a_reply():
    values = {}
    for k in range(57):
        name, code, count = mt.FIELDS[k]
        if count == 1:
            values[name] = 0.5 + k if code == "f" else k + 1
        else:
            values[name] = [(j + 1.25) if code == "f" else j + 1 for j in range(count)]
    for k in range(57):
        header = mt.encode_header([k], 0)
        frame = mt.encode_reply(header, values)
        assert len(frame) == 1 + 8 + SEED_FIELD_SIZES[k] + 1
        got = mt.decode_reply(header, frame[9:-1])
        name = mt.FIELDS[k][0]
        v = values[name]
        assert got == [(name, tuple(v) if isinstance(v, list) else v)], name


def test_full_reply_parsed_by_the_client_in_header_order():
    header = mt.encode_header("all", 0)
    frame = mt.encode_reply(header, {"throttle_params": (1300, 1450, 1600), "imu_type": 1,
                                     "PID_params": [float(j) for j in range(18)]})
    assert len(frame) == 1 + 8 + 377 + 1
    c = MaintenanceParser(replies=True, expected_header=header)
    for k in range(len(frame)):  # one byte at a time
        c.feed(frame[k:k + 1])
    assert c.pop()
    names = [v[0] for v in c.values]
    assert names == SEED_HEADER_NAMES
    d = dict(c.values)
    assert d["throttle_params"] == (1300, 1450, 1600) and d["imu_type"] == 1 and d["raw_accel_x"] == 0.0
    assert d["PID_params"][6 + mt.PID_KP] == 6.0  # pitch row
    assert d["imu_offset"] == (0.0, 0.0, 0.0)


def test_reply_with_another_header_is_skipped_and_counted():
    want = mt.encode_header(["body_roll"], 0)
    other = mt.encode_header(["body_pitch"], 0)
    c = MaintenanceParser(replies=True, expected_header=want)
    n = c.feed(mt.encode_reply(other, {}) + mt.encode_reply(want, {"body_roll": -2.0}))
    assert n == 1 and c.header_mismatches >= 1
    assert c.pop() and c.values == [("body_roll", -2.0)]


def test_bad_checksum_is_dropped_and_the_next_request_decoded():
    good = mt.encode_request([], mt.CMD_SET_ALL_MOTORS, (1200,), RC)
    bad = bytearray(good)
    bad[10] ^= 0x10
    p = MaintenanceParser()
    assert p.feed(bytes(bad) + good) == 1
    assert p.crc_errors == 1
    assert p.pop() and p.args[0] == 1200


def test_unknown_command_id_is_counted_and_resynchronised():
    frame = bytearray(mt.encode_request([], 0, (), RC))
    frame[8] = 26  # cmd id 26: not in the table, length unknown
    p = MaintenanceParser()
    assert p.feed(bytes(frame) + mt.encode_request([], 7, (), RC)) == 1
    assert p.unknown_commands == 1
    assert p.pop() and p.cmd_id == mt.CMD_FLASH_WRITE


def test_request_split_at_every_byte_and_garbage_between():
    frame = mt.encode_request("all", mt.CMD_SET_ROLL_PID, GOOD_ARGS[15], RC)
    for cut in range(len(frame) + 1):
        p = MaintenanceParser()
        n = p.feed(b"\x00\x13" + frame[:cut]) + p.feed(frame[cut:] + b"\xff\x07")
        assert n == 1, cut
        assert p.pop() and p.cmd_id == 15 and p.args[3] == 50.0


def test_header_mask_stays_in_small_ints():
    lo, hi = mt.header_mask(mt.encode_header("all", 0))
    assert lo == (1 << 29) - 1 and hi == (1 << 28) - 1
    assert lo < (1 << 30) and hi < (1 << 30)
    lo, hi = mt.header_mask(mt.encode_header(["raw_accel_x", "roll_PID_i", "throttle_params"], 0))
    assert lo == 1  # field 0
    assert hi == 1 | (1 << 27)  # fields 29 and 56


def test_validation_refuses_with_a_reason():
    bad = (
        (1, (999,)), (5, (2001,)), (6, (2,)), (8, (1, 1500, 1400)), (9, (3, 1000, 2000)),
        (10, (1, 900, 2000)), (12, (float("nan"), 1.0)), (15, (-1.0, 0.0, 0.0, 1.0, 0.0, 0.0)),
        (16, (1.0, 0.0, 0.0, float("inf"), 0.0, 0.0)),
        (17, (1.0, 0.0, 0.0, 1.0, 0.0)), (18, (-0.1, 0.1, 0.1)), (21, (3,)), (22, (2, 0x68, 0)),
        (23, (0, 0x80, 0, 0)), (25, (1500, 1400, 1600)), (25, (900, 1400, 1600)), (26, ()), (3, ()),
    )
    for cmd, args in bad:
        reason = mt.validate_command(cmd, args)
        assert isinstance(reason, str) and len(reason) > 5, (cmd, args)
    assert mt.validate_remote_control(1, 1000, 1500, 1500, 999) is not None
    assert mt.validate_remote_control(2, 1000, 1500, 1500, 1000) is not None
    assert mt.validate_remote_control(0, 0, 0, 0, 0) is None
    assert mt.validate_remote_control(*RC) is None


def test_encoder_refuses_values_that_do_not_fit():
    for call in ((lambda: mt.encode_request([], 1, (70000,))), (lambda: mt.encode_request([], 1, ())),
                 (lambda: mt.encode_request([], 26, ())), (lambda: mt.encode_header(["nope"], 0))):
        try:
            call()
            raised = False
        except ValueError:
            raised = True
        assert raised
