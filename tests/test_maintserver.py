"""Seed-001 maintenance server, built from the seed's tables: every header field, every command,
the radio override, and bad input (checksums, lengths, unknown commands, ranges, armed writes)."""

import math
import struct
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).parent / "portable"))
from configfakes import make_flight  # noqa: E402

from hoverfly.core.config.params import Params  # noqa: E402
from hoverfly.core.config.storage import Storage  # noqa: E402
from hoverfly.core.links.maintserver import ERROR_CMD, MaintServer  # noqa: E402
from hoverfly.protocols import maintenance as mp  # noqa: E402


@pytest.fixture
def srv():
    flight, board = make_flight()
    storage = Storage(board)
    storage.load(flight.params)
    return MaintServer(flight, storage), flight, board


def _exchange(server, frame):
    out = []
    server.feed(frame, len(frame), out.append)
    return b"".join(out)


def _reply(server, fields, cmd=0, args=(), rc=None):
    frame = mp.encode_request(fields, cmd, args, rc)
    raw = _exchange(server, frame)
    assert raw, "no reply"
    assert raw[0] == 0xFF
    header = raw[1:9]
    assert header[:7] == frame[1:8] and (header[7] & 0x80) == (frame[8] & 0x80)
    assert mp.xor8(raw, 1, len(raw) - 1) == raw[-1]
    values = mp.decode_reply(header, raw[9:-1])
    assert values is not None, "reply length does not match its header"
    return mp.header_cmd(header), dict(values)


@pytest.mark.parametrize("k", range(mp.FIELD_COUNT))
def test_every_header_field_alone_is_answered_with_its_size(srv, k):
    server, _, _ = srv
    cmd, values = _reply(server, [k])
    assert cmd == 0 and list(values) == [mp.FIELDS[k][0]]


def test_all_fields_at_once_in_header_order(srv):
    server, f, _ = srv
    f.signals.accel_raw_m_s2[2] = -9.80665
    f.signals.gyro_raw_rad_s[0] = 0.5
    f.signals.attitude.roll_rad = math.radians(10)
    f.signals.rc_channels_us[2] = 1234
    f.signals.motor_out[2] = 0.25
    f.arming.armed = True
    cmd, v = _reply(server, "all")
    assert list(v) == [fl[0] for fl in mp.FIELDS]
    assert v["raw_accel_z"] == pytest.approx(-9.80665, abs=1e-5)
    assert v["raw_gyro_x"] == pytest.approx(math.degrees(0.5), abs=1e-3)
    assert v["body_roll"] == pytest.approx(10.0, abs=1e-3)
    assert v["throttle_signal"] == 1234
    assert v["motor3_signal"] == 1250 and v["motor1_signal"] == 1000
    assert v["motors_armed"] == 1
    assert v["PID_params"][0] == 45 and v["PID_params"][5] == 40 and v["PID_params"][3] == 400
    assert v["ptf1_params"][3] == pytest.approx(1 / (2 * math.pi * 250), rel=1e-5)
    assert v["sw_ver"] == (0, 1, 0, mp.RELEASE_BETA)
    assert v["motor_params"][:3] == (1, 1000, 2000)
    assert v["imu_type"] == mp.IMU_MPU6050  # the sim-like fake board says nothing: the imu_type parameter
    assert v["js_params"] == pytest.approx((0.1, 0.005) * 3)
    assert v["throttle_params"] == (1350, 1500, 1650)


# Commands the server carries out (reply echoes the id) and those it refuses by design (ERROR_CMD).
GOOD_ARGS = {
    0: (), 6: (1,), 7: (),
    8: (0, 1100, 1900), 9: (1, 1200, 1800), 10: (1, 1000, 2000), 11: (1, 1050, 1950),
    12: (0.5, 0.25), 13: (0.75, 0.125), 14: (1.0, 0.0),
    15: (50.0, 60.0, 0.25, 300.0, 0.5, 30.0), 16: (51.0, 61.0, 0.0, 300.0, -2.5, 31.0),
    17: (52.0, 62.0, 1.5, 300.0, 0.0, 0.0),
    18: (0.01, 0.01, 0.01), 19: (0.001, 0.001, 0.001), 20: (0.0, 0.0, 0.0), 21: (mp.IMU_BNO055,), 24: (),
    25: (1300, 1500, 1700),
}
# the fake board has no I2C: the commands are refused with that reason
UNSUPPORTED = {22: (0, 0x28, 0x00), 23: (0, 0x28, 0x3D, 0x0C)}


@pytest.mark.parametrize("cmd", sorted(GOOD_ARGS))
def test_supported_commands_are_carried_out(srv, cmd):
    server, f, board = srv
    got, _ = _reply(server, [], cmd, GOOD_ARGS[cmd])
    assert got == cmd, server.last_error
    p = f.params
    if cmd == 7:
        q = Params()
        Storage(board).load(q)
        assert q.values == p.values
    elif cmd == 15:
        assert (p.get("p_roll"), p.get("i_roll"), p.get("d_roll"), p.get("iterm_limit")) == (50, 60, 30, 300)
        assert (p.get("pid_kt_roll"), p.get("pid_ad_roll")) == (0.25, 0.5)
    elif cmd == 8:
        assert p.get("motor_enable") == 0xFE and (p.get("motor1_min_us"), p.get("motor1_max_us")) == (1100, 1900)
    elif cmd == 12:
        assert (p.get("ab_thr_alpha"), p.get("ab_thr_beta")) == (0.5, 0.25)
    elif cmd == 21:  # a reboot parameter: stored (and saved), the running flight keeps its boot value
        assert p.stored("imu_type") == "bno055" and p.get("imu_type") == "mpu6050"
    elif cmd == 25:
        assert (p.get("thr_descend_us"), p.get("thr_hover_us"), p.get("thr_climb_us")) == (1300, 1500, 1700)
    elif cmd == 17:
        assert (p.get("p_yaw"), p.get("i_yaw"), p.get("d_yaw")) == (52, 62, 0)
    elif cmd == 18:
        assert p.get("acc_lpf_hz") == 16
    elif cmd == 19:
        assert p.get("gyro_lpf1_hz") == 159
    elif cmd == 6:
        assert server.motor_control and f.config_session & 4


@pytest.mark.parametrize("cmd", sorted(GOOD_ARGS))
def test_every_set_command_reads_back_what_it_sent(srv, cmd):
    # the seed's read-back: the field each command writes holds exactly the numbers sent
    server, _, _ = srv
    field = {8: "motor_params", 9: "motor_params", 10: "motor_params", 11: "motor_params", 12: "js_params",
             13: "js_params", 14: "js_params", 15: "PID_params", 16: "PID_params", 17: "PID_params",
             18: "ptf1_params", 19: "ptf1_params", 20: "ptf1_params", 21: "imu_type",
             25: "throttle_params"}.get(cmd)
    if field is None:
        return
    _reply(server, [], cmd, GOOD_ARGS[cmd])
    _, v = _reply(server, [field])
    args = GOOD_ARGS[cmd]
    got = v[field]
    if 8 <= cmd <= 11:
        k = cmd - 8
        assert got[3 * k:3 * k + 3] == args
    elif 12 <= cmd <= 14:
        k = cmd - 12
        assert got[2 * k:2 * k + 2] == args
    elif 15 <= cmd <= 17:
        k = cmd - 15
        assert got[6 * k:6 * k + 6] == args
    elif 18 <= cmd <= 20:
        k = cmd - 18
        want = args[0]
        if want:  # the cutoff is a whole number of Hz: the time constant of the nearest one reads back
            want = 1 / (2 * math.pi * round(1 / (2 * math.pi * want)))
        assert got[3 * k:3 * k + 3] == pytest.approx((want,) * 3, rel=1e-6)
    else:
        assert got == (args[0] if cmd == 21 else args)


@pytest.mark.parametrize("cmd", sorted(UNSUPPORTED))
def test_i2c_commands_on_a_board_without_i2c_get_an_error_reply_and_change_nothing(srv, cmd):
    server, f, _ = srv
    before = dict(f.params.values)
    got, _ = _reply(server, ["motor_params"], cmd, UNSUPPORTED[cmd])
    assert got == ERROR_CMD and "no I2C" in server.last_error
    assert f.params.values == before


def test_motor_commands_need_control_motors_first(srv):
    server, f, _ = srv
    assert _reply(server, [], 1, (1100,))[0] == ERROR_CMD
    assert f.motor_test.requests == []
    assert _reply(server, [], 6, (1,))[0] == 6
    for cmd in range(1, 6):
        assert _reply(server, [], cmd, (1000 + 100 * cmd,))[0] == cmd
    # motor_test_pct 30: 1400 and 1500 us run at 1300; "all motors" is each enabled motor
    assert [(i, round(v, 3)) for i, v in f.motor_test.requests] == [(0, 0.1), (1, 0.2), (2, 0.3), (3, 0.3),
                                                                    (0, 0.3), (1, 0.3), (2, 0.3), (3, 0.3)]
    assert server.capped == 2 and "motor_test_pct" in server.last_capped
    assert _reply(server, [], 6, (0,))[0] == 6
    assert f.config_session & 4 == 0 and f.motor_test.stops == 1


def test_session_end_releases_motor_control(srv):
    server, f, _ = srv
    _reply(server, [], 6, (1,))
    server.close()
    assert not server.motor_control and f.config_session & 4 == 0


def test_reset_imu_offset_takes_the_current_attitude(srv):
    server, f, _ = srv
    f.signals.attitude.roll_rad = math.radians(2.0)
    f.signals.attitude.pitch_rad = math.radians(-1.0)
    _, v = _reply(server, ["imu_offset"], 24)
    assert v["imu_offset"] == pytest.approx((2.0, -1.0, 0.0), abs=1e-4)


def test_remote_control_tag_overrides_the_radio(srv):
    server, f, _ = srv
    got, _ = _reply(server, [], 0, (), (1, 1900, 1600, 1400, 1300))
    assert got == 0
    ch = f.rc_calls[-1]
    assert ch[0] == 1600 and ch[1] == 1400 and ch[2] == 1300 and ch[4] == 1900  # AETR + AUX1 arm
    assert _reply(server, [], 0, (), (0, 0, 0, 0, 0))[0] == 0
    assert len(f.rc_calls) == 1


@pytest.mark.parametrize("cmd,args", [
    (1, (999,)), (5, (2001,)), (6, (2,)), (15, (float("nan"), 1.0, 0.0, 1.0, 0.0, 1.0)),
    (15, (45.5, 80.0, 0.0, 400.0, 0.0, 40.0)), (15, (300.0, 80.0, 0.0, 400.0, 0.0, 40.0)),
    (18, (-1.0, -1.0, -1.0)), (18, (0.01, 0.02, 0.01)), (20, (0.1, 0.1, 0.1)), (21, (3,)),
    (22, (2, 0x28, 0)), (23, (0, 0x80, 0, 0)), (25, (1700, 1500, 1300)), (25, (1300, 1500, 2100)),
    (8, (1, 1500, 1400)), (8, (2, 1000, 2000)), (9, (1, 900, 2000)), (12, (1.5, 0.1)), (13, (0.5, -0.1)),
    (14, (float("inf"), 0.1)), (16, (50.0, 60.0, -1.0, 300.0, 0.0, 30.0)), (17, (50.0, 60.0, 0.0, 600.0, 0.0, 30.0)),
])
def test_out_of_range_values_get_an_error_reply_and_change_nothing(srv, cmd, args):
    server, f, _ = srv
    _reply(server, [], 6, (1,))
    before = dict(f.params.values)
    n = len(f.motor_test.requests)
    assert _reply(server, [], cmd, args)[0] == ERROR_CMD
    assert f.params.values == before and len(f.motor_test.requests) == n


def test_bad_override_pulses_refuse_the_whole_request(srv):
    server, f, _ = srv
    assert _reply(server, [], 15, GOOD_ARGS[15], (1, 900, 1500, 1500, 1000))[0] == ERROR_CMD
    assert f.params.get("p_roll") == 45 and f.rc_calls == []


def test_writes_while_armed_are_refused(srv):
    server, f, board = srv
    f.arming.armed = True
    before = dict(f.params.values)
    for cmd in (1, 5, 7, 8, 12, 15, 18, 19, 21, 22, 23, 24, 25):
        args = GOOD_ARGS.get(cmd, UNSUPPORTED.get(cmd, (1200,)))
        assert _reply(server, [], cmd, args)[0] == ERROR_CMD
    assert f.params.values == before and board.store.writes == 0 and f.motor_test.requests == []
    assert _reply(server, ["body_roll"], 0)[0] == 0  # reading is fine
    assert _reply(server, [], 6, (0,))[0] == 6  # stopping motors is always allowed


def test_bad_checksum_wrong_length_and_unknown_command_are_counted_drops(srv):
    server, f, _ = srv
    good = mp.encode_request(["body_roll"], 15, GOOD_ARGS[15])
    bad = bytearray(good)
    bad[-1] ^= 0x55
    assert _exchange(server, bytes(bad)) == b""
    assert server.parser.crc_errors >= 1
    unknown = bytearray(mp.encode_request([], 0))
    unknown[8] = 30  # command id 30: no length known
    unknown[-1] = mp.xor8(unknown, 1, len(unknown) - 1)
    assert _exchange(server, bytes(unknown)) == b""
    assert server.parser.unknown_commands == 1
    short = good[:-3]  # truncated, then the line goes quiet
    assert _exchange(server, short) == b""
    server.parser.idle()
    assert server.parser.length_errors >= 1
    assert f.params.get("p_roll") == 45
    assert _reply(server, ["body_roll"], 0)[0] == 0  # and the next good frame is answered


def test_firmware_layout_server_answers_firmware_layout(srv):
    _, f, _ = srv
    server = MaintServer(f, None, mp.LAYOUT_FIRMWARE)
    frame = mp.encode_request(["body_pitch"], 21, (3,), None, mp.LAYOUT_FIRMWARE)  # no IMU id 3: refused
    raw = _exchange(server, frame)
    assert mp.header_cmd(raw[1:9], mp.LAYOUT_FIRMWARE) == ERROR_CMD
    assert len(raw) == 1 + 8 + 4 + 1


@settings(max_examples=300, derandomize=True, deadline=None)
@given(st.binary(max_size=400))
def test_random_bytes_never_raise_and_never_write_while_armed(data):
    flight, _ = make_flight()
    flight.arming.armed = True
    server = MaintServer(flight, None)
    before = dict(flight.params.values)
    out = []
    server.feed(data, len(data), out.append)
    assert flight.params.values == before and flight.motor_test.requests == []
    for frame in out:
        assert frame[0] == 0xFF


def test_pid_float_layout_is_six_floats():
    frame = mp.encode_request([], 15, GOOD_ARGS[15])
    assert len(frame) == 9 + 34
    assert struct.unpack_from("<6f", frame, 9) == pytest.approx(GOOD_ARGS[15])


def test_capped_motor_command_runs_at_the_cap_and_reads_back_capped():
    # given a real motor test (motor_test_pct 30) and motor 2 limited to 1250 us, when the client asks
    # 1800 us, then the reply carries the command out and its motor signals read the pulses the motors run
    f, _ = make_flight(seams=False)
    server = MaintServer(f, None)
    assert f.params.set("motor2_max_us", 1250) is None
    _reply(server, [], 6, (1,))
    got, v = _reply(server, ["motor1_signal", "motor2_signal", "motor3_signal"], 5, (1800,))
    assert got == 5, server.last_error
    assert (v["motor1_signal"], v["motor2_signal"], v["motor3_signal"]) == (1300, 1250, 1300)
    assert "motor_test_pct 30" in server.last_capped and "motor2_max_us" in server.last_capped
    assert _reply(server, [], 6, (0,))[0] == 6 and not f.motor_test.active


def test_a_disabled_motor_is_refused_by_the_motor_test_and_stays_stopped_armed():
    f, _ = make_flight(seams=False)
    server = MaintServer(f, None)
    assert _reply(server, [], 9, (0, 1000, 2000))[0] == 9  # motor 2 disabled
    _reply(server, [], 6, (1,))
    assert _reply(server, [], 2, (1200,))[0] == ERROR_CMD and "disabled" in server.last_error
    assert _reply(server, [], 5, (1200,))[0] == 5
    assert list(f.motor_test.values[:4]) == pytest.approx([0.2, 0.0, 0.2, 0.2])
    _reply(server, [], 6, (0,))
    f.configure()
    from array import array
    out = array("f", [0.0] * 4)
    f.output.update(array("f", [0.7] * 4), True, out)  # SAFETY: armed, the mixer asks 0.7 of every motor
    assert out[1] == 0.0 and out[0] > 0.5


class _Raises:
    def __get__(self, obj, cls):
        raise RuntimeError("sensor gone")


@pytest.mark.parametrize("value,want", [("mpu6050", 1), ("MPU-6050", 1), ("BNO055", 2), ("lsm9ds1", 0), (2, 2),
                                        ("icm42688", 255), ("auto", 255), (7, 255), (-1, 255), (3.5, 255),
                                        (b"bno055", 2), (b"\xff", 255), (object(), 255), (True, 255)])
def test_imu_type_encodes_whatever_the_board_says_and_never_raises(srv, value, want):
    server, _, board = srv
    board.imu_type = value
    got, v = _reply(server, "all")
    assert got == 0 and v["imu_type"] == want


def test_a_field_that_raises_is_sent_as_zero_and_counted(srv):
    server, f, board = srv
    type(board).imu_type = _Raises()
    try:
        f.signals.attitude = None  # body_* cannot be read
        got, v = _reply(server, "all")
    finally:
        del type(board).imu_type
    assert got == 0 and v["body_roll"] == 0.0 and v["imu_type"] == 255
    assert server.field_errors >= 3 and "body_" in server.last_field_error


# ----------------------------------------------------------------- the boards' I2C (commands 22-23)
def test_rp2_board_i2c_reads_and_writes_the_imu_bus_through_machine_i2c():
    # the rp2 fakes' machine.I2C serves the MPU-6050 register model, as the IMU's bus on the board
    sys.path.insert(0, str(Path(__file__).parent / "rp2fakes"))
    import machine

    from hoverfly.sim.regmodels import MPU6050Model
    from test_rp2_board import _board

    machine.reset()
    try:
        chip = MPU6050Model()
        machine.attach_i2c(0, chip)
        b = _board()
        b.setup()
        assert b.i2c_read(0, 0x68, 0x75) == 0x68  # WHO_AM_I
        assert b.i2c_write(0, 0x68, 0x19, 0x07) is None and b.i2c_read(0, 0x68, 0x19) == 0x07
        assert (0x19, 0x07) in chip.writes
        assert "no answer" in b.i2c_read(0, 0x29, 0x00)  # nobody at 0x29: ENODEV, a reason
        assert "no pins" in b.i2c_read(1, 0x68, 0x75)
        machine.i2c_fail(0, 1)
        assert "not acknowledged" in b.i2c_write(0, 0x68, 0x19, 0x01)
        assert b.i2c_errors == 2 and chip.regs[0x19] == 0x07
        # through the server: the byte read is the i2c_read field
        flight, _ = make_flight()
        flight.board = b
        server = MaintServer(flight, None)
        got, v = _reply(server, ["i2c_read"], 22, (0, 0x68, 0x75))
        assert got == 22 and v["i2c_read"] == 0x68
        got, _ = _reply(server, ["i2c_read"], 22, (0, 0x29, 0x75))
        assert got == ERROR_CMD and "no answer" in server.last_error
    finally:
        machine.reset()


def test_sim_board_i2c_serves_the_imu_register_model_with_the_live_sample():
    from hoverfly.sim.board import SimBoard

    b = SimBoard(4)
    assert b.i2c_read(0, 0x68, 0x75) == 0x68
    b.accel[0], b.accel[1], b.accel[2] = 0.0, 0.0, -9.80665  # level, at rest: FRD z up is -1 g
    hi, lo = b.i2c_read(0, 0x68, 0x3F), b.i2c_read(0, 0x68, 0x40)  # ACCEL_ZOUT at +-2 g: 16384 LSB/g
    assert abs(((hi << 8) | lo) - 16384) <= 1
    assert b.i2c_write(0, 0x68, 0x1C, 0x18) is None  # +-16 g
    hi, lo = b.i2c_read(0, 0x68, 0x3F), b.i2c_read(0, 0x68, 0x40)
    assert abs(((hi << 8) | lo) - 2048) <= 1
    assert "no device" in b.i2c_read(0, 0x28, 0x00) and "no device" in b.i2c_write(1, 0x68, 0x19, 1)
