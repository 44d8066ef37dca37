"""MSP server: Betaflight layouts from the live flight, error replies, writes, CLI on the same port."""

from configfakes import make_flight

from hoverfly.core.config.params import Params
from hoverfly.core.config.storage import Storage
from hoverfly.core.links.mspserver import CONFIG_MSP, MspServer
from hoverfly.core.links.task import ConfigPort
from hoverfly.core.stages.control import MODE_MANUAL
from hoverfly.protocols import msp


def _server(seams=True):
    flight, board = make_flight(seams)
    storage = Storage(board)
    storage.load(flight.params)
    return MspServer(flight, storage), flight, board


def _ask(server, cmd, payload=b"", version=1, encapsulated=False):
    out = []
    frame = msp.encode_request(cmd, payload, version, encapsulated)
    server.feed(frame, len(frame), out.append)
    p = msp.MspParser()
    for chunk in out:
        p.feed(chunk)
    assert p.pop(), "no reply"
    assert p.cmd == cmd and p.version == version and p.encapsulated == encapsulated
    return p.direction, p.message()


def test_identity_replies():
    s, _, _ = _server()
    assert _ask(s, msp.MSP_API_VERSION) == (msp.DIR_REPLY, bytes([0, 1, 46]))
    assert _ask(s, msp.MSP_FC_VARIANT)[1] == b"HVFL"
    assert msp.unpack_fc_version(_ask(s, msp.MSP_FC_VERSION)[1])[:3] == (0, 1, 0)
    info = msp.unpack_board_info(_ask(s, msp.MSP_BOARD_INFO)[1])
    assert info["board_id"] == "HVFL" and info["target_name"] == "HOVERFLY" and info["gyro_rate_hz"] == 1000
    assert len(_ask(s, msp.MSP_BUILD_INFO)[1]) == 26
    assert _ask(s, msp.MSP_NAME)[1] == b"hoverfly"
    assert len(msp.unpack_uid(_ask(s, msp.MSP_UID)[1])) == 3


def test_v2_and_v2_over_v1_requests_get_answers_in_kind():
    s, _, _ = _server()
    assert _ask(s, msp.MSP_API_VERSION, version=2) == (msp.DIR_REPLY, bytes([0, 1, 46]))
    assert _ask(s, msp.MSP_API_VERSION, version=2, encapsulated=True)[1] == bytes([0, 1, 46])


def test_status_carries_the_arming_reasons():
    s, f, _ = _server()
    f.arming.flags = (1 << 2) | (1 << 12)
    for cmd, ex in ((msp.MSP_STATUS, False), (msp.MSP_STATUS_EX, True)):
        d = msp.unpack_status(_ask(s, cmd)[1], ex)
        assert d["arming_disable_flags"] == f.arming.flags
        assert d["sensors"] & 32 and d["sensors"] & 1
        assert d["mode_flags"] & 1 == 0


def test_raw_imu_reads_one_g_up_at_rest():
    s, f, _ = _server()
    f.signals.accel_raw_m_s2[2] = -9.80665
    acc, gyro, mag = msp.unpack_raw_imu(_ask(s, msp.MSP_RAW_IMU)[1])
    assert acc[2] == 2048 and acc[0] == 0 and gyro == (0, 0, 0)


def test_attitude_rc_motor_pid_and_tuning():
    s, f, _ = _server()
    f.signals.attitude.roll_rad = 0.1
    f.signals.attitude.pitch_rad = -0.05
    f.signals.attitude.yaw_rad = -1.0
    roll, pitch, yaw = msp.unpack_attitude(_ask(s, msp.MSP_ATTITUDE)[1])
    assert roll == 57 and pitch == -28 and yaw == 302
    ch = f.signals.rc_channels_us
    ch[0], ch[1], ch[2], ch[3], ch[4] = 1400, 1450, 1100, 1600, 1900  # AETR
    rc = msp.unpack_rc(_ask(s, msp.MSP_RC)[1])
    assert rc[:5] == [1400, 1450, 1600, 1100, 1900]  # roll, pitch, yaw, throttle, aux1
    f.signals.motor_out[1] = 0.5
    assert msp.unpack_motor(_ask(s, msp.MSP_MOTOR)[1]) == [1000, 1500, 1000, 1000, 0, 0, 0, 0]
    pid = msp.unpack_pid(_ask(s, msp.MSP_PID)[1])
    assert pid[0] == (45, 80, 40) and pid[2] == (45, 80, 0)
    tuning = msp.unpack_rc_tuning(_ask(s, msp.MSP_RC_TUNING)[1])
    assert tuning["roll_rc_rate"] == 7 and tuning["rates_type"] == 4
    assert len(_ask(s, msp.MSP_ALTITUDE)[1]) == 6 and len(_ask(s, msp.MSP_ANALOG)[1]) == 9


def test_modes_boxes_and_ranges():
    s, _, _ = _server()
    assert msp.unpack_boxnames(_ask(s, msp.MSP_BOXNAMES)[1])[:3] == ["ARM", "ANGLE", "HORIZON"]
    assert msp.unpack_boxids(_ask(s, msp.MSP_BOXIDS)[1])[:3] == [0, 1, 2]
    ranges = msp.unpack_mode_ranges(_ask(s, msp.MSP_MODE_RANGES)[1])
    assert ranges[0] == (0, 0, msp.step_of_us(1700), msp.step_of_us(2100))


def test_a_plane_has_inavs_manual_box_and_a_quad_does_not():
    s, f, _ = _server()
    assert "MANUAL" not in msp.unpack_boxnames(_ask(s, msp.MSP_BOXNAMES)[1])
    direction, _ = _ask(s, msp.MSP_SET_MODE_RANGE, msp.pack_set_mode_range(5, 12, 2, 32, 48))
    assert direction == msp.DIR_ERROR and f.params.get("manual_ch") == 0  # refused on a quad, nothing changed
    f.params.values["mixer_type"] = "airplane"
    assert msp.unpack_boxnames(_ask(s, msp.MSP_BOXNAMES)[1])[-1] == "MANUAL"
    assert msp.unpack_boxids(_ask(s, msp.MSP_BOXIDS)[1])[-1] == 12  # INAV's permanent id
    assert _ask(s, msp.MSP_SET_MODE_RANGE, msp.pack_set_mode_range(5, 12, 2, 32, 48))[0] == msp.DIR_REPLY
    assert f.params.get("manual_ch") == 7  # AUX3
    assert msp.unpack_mode_ranges(_ask(s, msp.MSP_MODE_RANGES)[1])[5] == (12, 2, 32, 48)
    f.signals.setpoint.mode = MODE_MANUAL
    assert msp.unpack_status(_ask(s, msp.MSP_STATUS)[1])["mode_flags"] & 32  # MANUAL's bit, its place in BOXIDS


def test_unknown_command_gets_an_error_reply():
    s, _, _ = _server()
    assert _ask(s, 77) == (msp.DIR_ERROR, b"")
    assert _ask(s, 0x1234, version=2) == (msp.DIR_ERROR, b"")
    assert _ask(s, 78, bytes(300)) == (msp.DIR_ERROR, b"")  # a jumbo request
    assert s.unknown == 3


def test_set_pid_changes_params_and_is_refused_while_armed():
    s, f, _ = _server()
    pl = msp.pack_pid([(50, 60, 30), (51, 61, 31), (52, 62, 0)])
    assert _ask(s, msp.MSP_SET_PID, pl) == (msp.DIR_REPLY, b"")
    assert f.params.get("p_roll") == 50 and f.params.get("d_pitch") == 31 and f.params.get("i_yaw") == 62
    f.arming.armed = True
    pl = msp.pack_pid([(90, 60, 30), (51, 61, 31), (52, 62, 0)])
    assert _ask(s, msp.MSP_SET_PID, pl)[0] == msp.DIR_ERROR
    assert f.params.get("p_roll") == 50
    assert _ask(s, msp.MSP_EEPROM_WRITE)[0] == msp.DIR_ERROR
    assert _ask(s, msp.MSP_SET_PID, b"\x01\x02")[0] == msp.DIR_ERROR


def test_set_raw_rc_reaches_the_flight():
    s, f, _ = _server()
    assert _ask(s, msp.MSP_SET_RAW_RC, msp.pack_set_raw_rc([1500, 1600, 1000, 1500, 1000, 2000, 1500, 1500]))[0] \
        == msp.DIR_REPLY
    assert f.rc_calls == [[1500, 1600, 1000, 1500, 1000, 2000, 1500, 1500]]
    assert _ask(s, msp.MSP_SET_RAW_RC, b"\x00")[0] == msp.DIR_ERROR
    assert _ask(s, msp.MSP_SET_RAW_RC, msp.pack_set_raw_rc([3000] * 8))[0] == msp.DIR_ERROR
    assert len(f.rc_calls) == 1


def test_set_raw_rc_without_the_autopilot_seam_is_an_error():
    s, f, _ = _server(seams=False)
    if getattr(f, "on_msp_rc", None) is None:
        assert _ask(s, msp.MSP_SET_RAW_RC, msp.pack_set_raw_rc([1500] * 8))[0] == msp.DIR_ERROR


def test_motor_test_needs_the_arming_lock_and_the_lock_ends_with_the_session():
    s, f, _ = _server()
    pl = msp.pack_set_motor([1100] * 4)
    assert _ask(s, msp.MSP_SET_MOTOR, pl)[0] == msp.DIR_ERROR  # props-off not acknowledged
    assert _ask(s, msp.MSP_SET_ARMING_DISABLED, msp.pack_set_arming_disabled(True))[0] == msp.DIR_REPLY
    assert f.config_session & CONFIG_MSP
    assert _ask(s, msp.MSP_SET_MOTOR, pl)[0] == msp.DIR_REPLY
    assert f.motor_test.requests[-1][0] == -1 and abs(f.motor_test.requests[-1][1] - 0.1) < 1e-9
    assert _ask(s, msp.MSP_SET_MOTOR, msp.pack_set_motor([1000, 1200, 1000, 1000]))[0] == msp.DIR_REPLY
    assert (1, 0.2) in [(i, round(v, 3)) for i, v in f.motor_test.requests]
    assert _ask(s, msp.MSP_SET_MOTOR, msp.pack_set_motor([2500] * 4))[0] == msp.DIR_ERROR
    s.close()
    assert f.config_session & CONFIG_MSP == 0 and not s.arming_disabled


def test_eeprom_write_acc_calibration_and_reboot():
    s, f, board = _server()
    f.params.set("p_roll", 66)
    assert _ask(s, msp.MSP_EEPROM_WRITE)[0] == msp.DIR_REPLY
    p = Params()
    Storage(board).load(p)
    assert p.get("p_roll") == 66
    f.signals.attitude.roll_rad = 0.01
    assert _ask(s, msp.MSP_ACC_CALIBRATION)[0] == msp.DIR_REPLY
    assert abs(f.params.get("acc_trim_roll") - 0.573) < 0.01
    # A board that cannot reboot says so; one that can reboots once the reply is written.
    assert _ask(s, msp.MSP_REBOOT)[0] == msp.DIR_ERROR and "cannot reboot" in s.last_error
    events = []
    s.on_reboot = lambda: events.append("reboot")
    out = []
    s.feed(msp.encode_request(msp.MSP_REBOOT), 6, lambda b: (out.append(b), events.append("reply")))
    assert events == ["reply", "reboot"] and msp.DIR_REPLY == out[0][2]
    assert _ask(s, msp.MSP_REBOOT, b"\x01")[0] == msp.DIR_ERROR


def test_hash_between_frames_enters_the_cli_and_inside_a_frame_does_not():
    flight, _ = make_flight()
    port = ConfigPort(flight)
    out = []
    frame = msp.encode_request(msp.MSP_SET_RAW_RC, bytes([0x23, 5] * 8))  # '#' bytes in the payload
    port.feed(frame, len(frame), out.append)
    assert not port.cli.active and len(flight.rc_calls) == 1
    data = msp.encode_request(msp.MSP_API_VERSION) + b"#"
    for k in range(len(data)):  # one byte at a time
        port.feed(data[k:k + 1], 1, out.append)
    assert port.cli.active and flight.config_session & 1
    port.feed(b"exit\r", 5, out.append)
    assert not port.cli.active and flight.config_session & 1 == 0
    out = []
    port.feed(frame, len(frame), out.append)  # MSP again after exit
    assert b"".join(out)[:3] == b"$M>"


def test_garbage_never_raises():
    s, _, _ = _server()
    out = []
    junk = bytes((i * 73 + 11) & 0xFF for i in range(3000)) + b"$M<\x05\x01" + b"$X<\x00\xff\xff\xff\xff"
    s.feed(junk, len(junk), out.append)
    assert s.parser.bytes == len(junk)
