"""MSP framing and payloads cross-checked with an independent client: PyPI yamspy 0.3.3.

yamspy talks to a pyserial port; here its `conn` is a fake serial object, so frames it writes
are compared with hoverfly's encoder and frames hoverfly encodes are read back by yamspy's own
receive state machine (`receive_msg`) and payload decoders (`process_recv_data`).
"""

import logging

import pytest

from hoverfly.protocols import msp
from hoverfly.protocols.msp import MspParser

yamspy = pytest.importorskip("yamspy")


class FakeSerial:
    """What yamspy uses of a pyserial port: read(n), write(b), closed."""

    def __init__(self, rx=b""):
        self.rx = bytearray(rx)
        self.tx = bytearray()
        self.closed = False

    def read(self, size=1):
        out = bytes(self.rx[:size])
        del self.rx[:size]
        return out

    def write(self, data):
        self.tx += bytes(data)
        return len(data)

    def close(self):
        self.closed = True


@pytest.fixture
def board():
    level = logging.getLogger().level
    b = yamspy.MSPy("/dev/null", logfilename=None, loglevel="WARNING")
    logging.getLogger().setLevel(level)
    b.conn = FakeSerial()
    b.INAV = False  # yamspy sets this in connect(); a Betaflight-style FC
    return b


def _yamspy_reads(board, frame):
    board.conn = FakeSerial(frame)
    handler = board.receive_msg()
    return handler


@pytest.mark.parametrize("code,data", [
    (msp.MSP_API_VERSION, []),
    (msp.MSP_STATUS_EX, []),
    (msp.MSP_SET_RAW_RC, list(msp.pack_set_raw_rc([1500, 1500, 1000, 1500, 1000, 2000, 1500, 1500]))),
    (msp.MSP_SET_MOTOR, list(msp.pack_set_motor([1000, 1100] + [1000] * 6))),
    (msp.MSP_SET_ARMING_DISABLED, list(msp.pack_set_arming_disabled(True, False))),
    (0x1001, []),
    (0x3003, [7, 1, 2, 3]),
    (0x2000, list(range(200))),
])
def test_yamspy_requests_equal_hoverfly_requests(board, code, data):
    board.send_RAW_msg(code, data)
    version = 1 if code < 255 else 2
    assert bytes(board.conn.tx) == msp.encode_request(code, bytes(data), version=version)
    p = MspParser()
    assert p.feed(board.conn.tx) == 1
    assert p.pop() and p.cmd == code and p.message() == bytes(data) and p.version == version


@pytest.mark.parametrize("version,cmd,payload", [
    (1, msp.MSP_API_VERSION, bytes([0, 1, 46])),
    (1, msp.MSP_SET_RAW_RC, b""),
    (1, msp.MSP_RC, bytes(range(32))),
    (1, 71, bytes(300)),  # jumbo
    (1, 70, bytes(range(255))),  # exactly at the jumbo threshold
    (2, msp.MSP_API_VERSION, bytes([0, 1, 46])),
    (2, 0x1F03, bytes(range(100))),
    (2, 0x3003, b""),
])
def test_yamspy_receive_state_machine_reads_hoverfly_replies(board, version, cmd, payload):
    frame = msp.encode_reply(version, cmd, payload)
    h = _yamspy_reads(board, frame)
    assert not h["crcError"] and not h["packet_error"]
    assert h["msp_version"] == version
    assert h["code"] == cmd
    assert h["message_direction"] == 1
    assert bytes(h["dataView"] or b"") == payload


def test_yamspy_sees_hoverfly_error_reply_as_unsupported(board):
    h = _yamspy_reads(board, msp.encode_reply(1, 77, error=True))
    assert h["unsupported"] == 1


def test_yamspy_flags_a_corrupted_hoverfly_frame(board):
    frame = bytearray(msp.encode_reply(1, msp.MSP_ATTITUDE, msp.pack_attitude(1, 2, 3)))
    frame[-1] ^= 0xFF
    assert _yamspy_reads(board, bytes(frame))["crcError"]


def test_yamspy_decodes_hoverfly_payloads(board):
    replies = [
        (msp.MSP_API_VERSION, msp.pack_api_version(0, 1, 46)),
        (msp.MSP_FC_VARIANT, msp.pack_fc_variant("HVFL")),
        (msp.MSP_ATTITUDE, msp.pack_attitude(123, -45, 270)),
        (msp.MSP_ALTITUDE, msp.pack_altitude(1234, -5)),
        (msp.MSP_ANALOG, msp.pack_analog(1186, 321, 900, 1550)),
        (msp.MSP_MOTOR, msp.pack_motor([1000, 1200, 1400, 1600])),
        (msp.MSP_RC, msp.pack_rc([1500, 1501, 1000, 2000, 1200])),
        (msp.MSP_RAW_IMU, msp.pack_raw_imu((10, -20, 2048), (1, 2, -3), (0, 0, 0))),
        (msp.MSP_UID, msp.pack_uid(0x11223344, 5, 0xFFFFFFFF)),
        (msp.MSP_BOXIDS, msp.pack_boxids([0, 1, 2, 50])),
    ]
    for cmd, payload in replies:
        h = _yamspy_reads(board, msp.encode_reply(1, cmd, payload))
        h["dataView"] = bytearray(h["dataView"])
        assert board.process_recv_data(h) >= 0, cmd  # it returns len(data) after consuming it
    assert board.CONFIG["apiVersion"] == "1.46.0"
    assert board.CONFIG["flightControllerIdentifier"] == "HVFL"
    assert board.SENSOR_DATA["kinematics"] == [12.3, -4.5, 270]
    assert board.SENSOR_DATA["altitude"] == 12.34
    assert board.ANALOG["mAhdrawn"] == 321 and board.ANALOG["rssi"] == 900
    assert board.ANALOG["amperage"] == 15.5 and board.ANALOG["voltage"] == 11.86
    assert board.MOTOR_DATA == [1000, 1200, 1400, 1600, 0, 0, 0, 0]
    assert board.RC["channels"] == [1500, 1501, 1000, 2000, 1200]
    assert board.CONFIG["uid"] == [0x11223344, 5, 0xFFFFFFFF]
    assert board.SENSOR_DATA["accelerometer"] == [10, -20, 2048]
    assert board.SENSOR_DATA["gyroscope"] == [1, 2, -3]
    assert board.AUX_CONFIG_IDS == [0, 1, 2, 50]


def test_command_ids_agree_with_yamspy_table():
    names = {
        "MSP_API_VERSION": msp.MSP_API_VERSION, "MSP_FC_VARIANT": msp.MSP_FC_VARIANT,
        "MSP_FC_VERSION": msp.MSP_FC_VERSION, "MSP_BOARD_INFO": msp.MSP_BOARD_INFO,
        "MSP_BUILD_INFO": msp.MSP_BUILD_INFO, "MSP_NAME": msp.MSP_NAME, "MSP_SET_NAME": msp.MSP_SET_NAME,
        "MSP_MODE_RANGES": msp.MSP_MODE_RANGES, "MSP_FEATURE_CONFIG": msp.MSP_FEATURE_CONFIG,
        "MSP_RX_CONFIG": msp.MSP_RX_CONFIG, "MSP_ARMING_CONFIG": msp.MSP_ARMING_CONFIG,
        "MSP_SET_REBOOT": msp.MSP_REBOOT, "MSP_ARMING_DISABLE": msp.MSP_SET_ARMING_DISABLED,
        "MSP_STATUS": msp.MSP_STATUS, "MSP_RAW_IMU": msp.MSP_RAW_IMU, "MSP_MOTOR": msp.MSP_MOTOR,
        "MSP_RC": msp.MSP_RC, "MSP_ATTITUDE": msp.MSP_ATTITUDE, "MSP_ALTITUDE": msp.MSP_ALTITUDE,
        "MSP_ANALOG": msp.MSP_ANALOG, "MSP_RC_TUNING": msp.MSP_RC_TUNING, "MSP_PID": msp.MSP_PID,
        "MSP_BOXNAMES": msp.MSP_BOXNAMES, "MSP_BOXIDS": msp.MSP_BOXIDS,
        "MSP_MOTOR_CONFIG": msp.MSP_MOTOR_CONFIG, "MSP_STATUS_EX": msp.MSP_STATUS_EX,
        "MSP_UID": msp.MSP_UID, "MSP_SET_RAW_RC": msp.MSP_SET_RAW_RC, "MSP_SET_PID": msp.MSP_SET_PID,
        "MSP_ACC_CALIBRATION": msp.MSP_ACC_CALIBRATION, "MSP_MAG_CALIBRATION": msp.MSP_MAG_CALIBRATION,
        "MSP_SET_MOTOR": msp.MSP_SET_MOTOR, "MSP_EEPROM_WRITE": msp.MSP_EEPROM_WRITE,
    }
    for name, code in names.items():
        assert yamspy.MSPy.MSPCodes[name] == code, name


def test_arming_flag_names_agree_with_yamspy_where_it_is_current(board):
    # yamspy's table predates bits 20+ being renamed; bits 0..19 must agree (CLI spelling).
    theirs = board.armingDisableFlagNames_BF
    for bit in range(20):
        if bit == 3:
            continue  # yamspy still calls bit 3 BADRX; Betaflight 4.5 names it NOT_DISARMED
        assert theirs[bit].replace(" ", "_") == msp.ARMING_DISABLE_CLI_NAMES[bit], bit
