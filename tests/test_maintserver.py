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

from hoverfly.core.maintserver import ERROR_CMD, MaintServer  # noqa: E402
from hoverfly.core.params import Params  # noqa: E402
from hoverfly.core.storage import Storage  # noqa: E402
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
    assert v["imu_type"] == mp.IMU_MPU6050


# Commands the server carries out (reply echoes the id) and those it refuses by design (ERROR_CMD).
GOOD_ARGS = {
    0: (), 6: (1,), 7: (),
    15: (50.0, 60.0, 0.0, 300.0, 0.0, 30.0), 16: (51.0, 61.0, 0.0, 300.0, 0.0, 31.0),
    17: (52.0, 62.0, 0.0, 300.0, 0.0, 0.0),
    18: (0.01, 0.01, 0.01), 19: (0.001, 0.001, 0.001), 20: (0.0, 0.0, 0.0), 21: (mp.IMU_MPU6050,), 24: (),
}
UNSUPPORTED = {
    8: (1, 1000, 2000), 9: (1, 1000, 2000), 10: (1, 1000, 2000), 11: (1, 1000, 2000),
    12: (0.5, 0.1), 13: (0.5, 0.1), 14: (0.5, 0.1), 22: (0, 0x28, 0x00), 23: (0, 0x28, 0x3D, 0x0C),
    25: (1300, 1500, 1700),
}


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
    elif cmd == 17:
        assert (p.get("p_yaw"), p.get("i_yaw"), p.get("d_yaw")) == (52, 62, 0)
    elif cmd == 18:
        assert p.get("acc_lpf_hz") == 16
    elif cmd == 19:
        assert p.get("gyro_lpf1_hz") == 159
    elif cmd == 6:
        assert server.motor_control and f.config_session & 4


@pytest.mark.parametrize("cmd", sorted(UNSUPPORTED))
def test_commands_without_a_hoverfly_meaning_get_an_error_reply_and_change_nothing(srv, cmd):
    server, f, _ = srv
    before = dict(f.params.values)
    got, _ = _reply(server, ["motor_params"], cmd, UNSUPPORTED[cmd])
    assert got == ERROR_CMD and server.last_error
    assert f.params.values == before


def test_motor_commands_need_control_motors_first(srv):
    server, f, _ = srv
    assert _reply(server, [], 1, (1100,))[0] == ERROR_CMD
    assert f.motor_test.requests == []
    assert _reply(server, [], 6, (1,))[0] == 6
    for cmd in range(1, 6):
        assert _reply(server, [], cmd, (1000 + 100 * cmd,))[0] == cmd
    assert [(i, round(v, 3)) for i, v in f.motor_test.requests] == [(0, 0.1), (1, 0.2), (2, 0.3), (3, 0.4),
                                                                    (-1, 0.5)]
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
    (18, (-1.0, -1.0, -1.0)), (18, (0.01, 0.02, 0.01)), (20, (0.1, 0.1, 0.1)), (21, (3,)), (21, (2,)),
    (22, (2, 0x28, 0)), (23, (0, 0x80, 0, 0)), (25, (1700, 1500, 1300)),
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
    for cmd in (1, 5, 7, 15, 18, 19, 24):
        args = GOOD_ARGS.get(cmd, (1200,))
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
    frame = mp.encode_request(["body_pitch"], 21, (2,), None, mp.LAYOUT_FIRMWARE)
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
