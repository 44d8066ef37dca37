"""Bridge framing (protocols/bridge.py): round trips, any chunking, CRC and resync counting."""

from struct import pack_into, unpack_from

from hoverfly.protocols import bridge as B


def test_frame_round_trips_through_the_decoder():
    f = B.frame(B.ACK, b"hello")
    assert f[0] == 0xB5 and f[1] == B.ACK and f[2] == 5 and f[3] == 0
    d = B.BridgeDecoder()
    assert d.feed(f) == 1
    assert d.pop() == B.ACK
    assert d.text() == "hello"
    assert d.pop() == -1


def test_empty_payload_frame():
    d = B.BridgeDecoder()
    assert d.feed(B.frame(B.QUIT)) == 1
    assert d.pop() == B.QUIT and d.length == 0


def test_byte_by_byte_feed_gives_the_same_frames():
    data = B.frame(B.PARAMS, b"p_roll=50") + B.frame(B.BOOT, b"\x00\x00\x00\x00")
    d = B.BridgeDecoder()
    done = 0
    for i in range(len(data)):
        done += d.feed(data[i:i + 1])
    assert done == 2
    assert d.pop() == B.PARAMS and d.text() == "p_roll=50"
    assert d.pop() == B.BOOT and d.length == 4


def test_bad_crc_is_counted_and_the_next_frame_still_decodes():
    bad = bytearray(B.frame(B.ACK, b"x"))
    bad[-1] ^= 0xFF
    d = B.BridgeDecoder()
    assert d.feed(bytes(bad) + B.frame(B.ACK, b"y")) == 1
    assert d.crc_errors == 1
    assert d.pop() == B.ACK and d.text() == "y"


def test_garbage_before_a_frame_counts_resyncs():
    d = B.BridgeDecoder()
    assert d.feed(b"\x00\x01abc" + B.frame(B.OUT, b"\x01")) == 1
    assert d.resyncs == 5


def test_impossible_length_is_counted():
    d = B.BridgeDecoder()
    d.feed(bytes([0xB5, B.STEP, 0xFF, 0xFF]))
    assert d.length_errors == 1 and d.frames == 0


def test_step_payload_layout():
    buf = bytearray(B.MAX_PAYLOAD + B.OVERHEAD)
    pack_into(B.STEP_FMT, buf, B.HEADER, 123456, B.STEP_IMU_FRESH, 0.5, -0.25, 0.0, 0.0, 0.0, -9.75,
              1.0, 0.0, 0.0, 0.0, 16.5, 3.25)
    buf[B.HEADER + B.STEP_SIZE] = 0xC8
    n = B.finish(buf, B.STEP, B.STEP_SIZE + 1)
    d = B.BridgeDecoder()
    assert d.feed(buf, n) == 1
    assert d.pop() == B.STEP and d.length == B.STEP_SIZE + 1
    v = unpack_from(B.STEP_FMT, d.payload, 0)
    assert v[0] == 123456 and v[1] == 1 and v[2] == 0.5 and v[7] == -9.75 and v[13] == 3.25
    assert d.payload[B.STEP_SIZE] == 0xC8


def test_event_records_clamp_to_32_bits():
    buf = bytearray(B.EVENT_SIZE)
    B.put_event(buf, 0, 5000, 3, 1 << 40)
    t, e, detail = unpack_from(B.EVENT_FMT, buf, 0)
    assert (t, e, detail) == (5000, 3, 0x7FFFFFFF)


def test_oversized_payload_is_refused():
    try:
        B.frame(B.PARAMS, bytes(B.MAX_PAYLOAD + 1))
    except ValueError:
        return
    raise AssertionError("expected ValueError")


def test_frame_layout_sizes_match_their_formats():
    from struct import calcsize

    assert calcsize(B.STEP_FMT) == B.STEP_SIZE
    assert calcsize(B.OUT_HEAD_FMT) == B.OUT_HEAD_SIZE
    assert calcsize(B.EVENT_FMT) == B.EVENT_SIZE
    assert calcsize(B.MSP_RC_HEAD_FMT) == B.MSP_RC_HEAD_SIZE
    assert calcsize(B.RC_ANSWER_FMT) == B.RC_ANSWER_SIZE


def test_every_kind_is_distinct():
    kinds = list(B.KINDS)
    for k in kinds:
        assert kinds.count(k) == 1 and k != B.SYNC


def test_hello_carries_the_protocol_version():
    d = B.BridgeDecoder()
    assert d.feed(B.frame(B.HELLO, B.VERSION.encode())) == 1
    assert d.pop() == B.HELLO and d.text() == B.VERSION


def test_zero_padding_finishes_a_half_sent_frame_and_the_next_frame_decodes():
    # given a decoder left inside the longest frame (its sender died after the header)
    d = B.BridgeDecoder()
    d.feed(bytes([0xB5, B.STEP, B.MAX_PAYLOAD & 0xFF, B.MAX_PAYLOAD >> 8]))
    # when the host pads with zeros, then says HELLO
    d.feed(bytes(B.MAX_PAYLOAD + B.OVERHEAD + 1) + B.frame(B.HELLO, b"v"))
    # then the half frame fails its CRC, the zeros left over are skipped, and HELLO arrives
    assert d.crc_errors == 1 and d.resyncs == 5 and d.frames == 1
    assert d.pop() == B.HELLO and d.text() == "v"


def test_msp_rc_round_trips_through_the_decoder():
    buf = bytearray(B.MAX_PAYLOAD + B.OVERHEAD)
    ch = [1500, 1500, 1000, 1500, 2000, 1000, 1800, 1500]
    n = B.put_msp_rc(buf, 2500000, ch, len(ch))
    assert n == B.OVERHEAD + B.MSP_RC_HEAD_SIZE + 2 * len(ch)
    d = B.BridgeDecoder()
    assert d.feed(buf, n) == 1
    assert d.pop() == B.MSP_RC
    assert unpack_from(B.MSP_RC_HEAD_FMT, d.payload, 0) == (2500000, 8)
    out = [0] * B.MAX_RC_CHANNELS
    assert B.read_msp_rc(d.payload, d.length, out) == 8
    assert out[:8] == ch
    # little-endian u16 on the wire: 1500 = 0x05DC
    assert d.payload[5] == 0xDC and d.payload[6] == 0x05


def test_msp_rc_clamps_what_does_not_fit_the_wire():
    buf = bytearray(B.MAX_PAYLOAD + B.OVERHEAD)
    ch = [70000, -5] + [1500] * 20
    n = B.put_msp_rc(buf, -1, ch, len(ch))
    d = B.BridgeDecoder()
    d.feed(buf, n)
    d.pop()
    out = [0] * B.MAX_RC_CHANNELS
    assert B.read_msp_rc(d.payload, d.length, out) == B.MAX_RC_CHANNELS
    assert out[0] == 0xFFFF and out[1] == 0
    assert unpack_from("<I", d.payload, 0)[0] == 0


def test_malformed_msp_rc_payloads_are_refused_not_raised():
    out = [0] * B.MAX_RC_CHANNELS
    assert B.read_msp_rc(b"\x00\x00", 2, out) == -1  # shorter than its head
    assert B.read_msp_rc(b"\x00\x00\x00\x00\x04\xdc\x05", 7, out) == -1  # claims 4 channels, holds 1
    assert B.read_msp_rc(b"\x00\x00\x00\x00\x13" + bytes(38), 43, out) == -1  # 19 > MSP's 18
    assert B.read_msp_rc(b"\x00\x00\x00\x00\x02\xdc\x05\xe8\x03", 9, [0]) == -1  # more than out holds
    assert B.read_msp_rc(b"\x00\x00\x00\x00\x00", 5, out) == 0


def test_step_flags_carry_the_open_configuration_sessions():
    flags = B.STEP_IMU_FRESH | ((2 | 4) & B.STEP_SESSION_MASK) << B.STEP_SESSION_SHIFT
    assert flags & B.STEP_IMU_FRESH
    assert (flags >> B.STEP_SESSION_SHIFT) & B.STEP_SESSION_MASK == 6


# ------------------------------------------- the firmware end moves the frame's floats exactly
# On a little-endian MicroPython the firmware copies float32 bytes (boards/bridge_fw.py RAW_FLOATS); on CPython
# it unpacks and packs them. Either way the board, the flight and the answer see the float32 the host sent.
_INPUTS = (0.1, -0.2, 0.3, 0.4, -0.5, -9.81, 0.9, 0.1, -0.2, 0.3, 16.1, 2.7)  # gyro, accel, q, V, A


def _f32(values):
    from array import array

    return list(array("f", values))


def _booted():
    from hoverfly.boards.bridge_fw import Firmware

    fw = Firmware()
    fw.handle(B.HELLO, B.VERSION.encode(), len(B.VERSION))
    fw.handle(B.BOOT, bytes(4), 4)
    return fw


def _step(fw, sim_us, flags, values, rx=b""):
    buf = bytearray(B.MAX_PAYLOAD + B.OVERHEAD)
    pack_into(B.STEP_FMT, buf, B.HEADER, sim_us, flags, *values)
    p = B.HEADER + B.STEP_SIZE
    for i in range(len(rx)):
        buf[p + i] = rx[i]
    n = B.STEP_SIZE + len(rx)
    B.finish(buf, B.STEP, n)
    total = fw.handle(B.STEP, buf[B.HEADER:B.HEADER + n], n)
    d = B.BridgeDecoder()
    assert d.feed(fw.out, total) == 1 and d.pop() == B.OUT
    return d


def test_a_step_gives_the_board_the_float32_values_the_host_sent():
    fw = _booted()
    _step(fw, 1000, B.STEP_IMU_FRESH, _INPUTS)
    assert list(fw.board.inputs) == _f32(_INPUTS)
    assert fw.board.sim_us == 1000
    # a step without a new IMU sample leaves the last one and takes the rest
    later = (9.0, 9.0, 9.0, 9.0, 9.0, 9.0, 0.5, 0.5, 0.5, 0.5, 15.9, 3.1)
    _step(fw, 2000, 0, later)
    assert list(fw.board.inputs) == _f32(_INPUTS[:6] + later[6:])


def test_the_answer_carries_the_motors_and_attitude_the_flight_holds_as_float32_bytes():
    fw = _booted()
    for i in range(5):
        d = _step(fw, 1000 * (i + 1), B.STEP_IMU_FRESH, _INPUTS)
    p = d.payload
    n = p[1]
    m = p[2]
    at = B.OUT_HEAD_SIZE
    board = fw.board
    expect = bytearray(4 * (n + m + 4))
    for i in range(n):
        pack_into("<f", expect, 4 * i, board.motor_out[i])
    q = fw.flight.signals.attitude.q
    for i in range(4):
        pack_into("<f", expect, 4 * (n + m + i), q[i])
    assert bytes(p[at:at + len(expect)]) == bytes(expect)
    assert unpack_from("<f", p, at + 4 * (n + m))[0] == q[0]


def test_the_bridge_board_hands_its_sample_and_motors_over_unchanged():
    from array import array

    from hoverfly.boards.bridge_fw import BridgeBoard

    board = BridgeBoard()
    for i in range(12):
        board.inputs[i] = _INPUTS[i]
    gyro = array("f", [0.0] * 3)
    accel = array("f", [0.0] * 3)
    assert not board.read_imu(gyro, accel)  # nothing new yet
    board.imu_fresh = True
    assert board.read_imu(gyro, accel) and not board.imu_fresh
    assert list(gyro) + list(accel) == _f32(_INPUTS[:6])
    q = array("f", [0.0] * 4)
    assert board.read_attitude(q) and list(q) == _f32(_INPUTS[6:10])
    motors = array("f", [0.25, 0.5, 0.75, 1.0, 0.0, 0.0, 0.0, 0.0])
    board.write_motors(motors, 4)
    assert board.motor_count == 4 and list(board.motor_out[:4]) == [0.25, 0.5, 0.75, 1.0]

    class Power:
        battery_v = 0.0
        current_a = 0.0

    power = Power()
    board.read_battery(power)
    assert [power.battery_v, power.current_a] == _f32(_INPUTS[10:])
