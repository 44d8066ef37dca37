"""MSP servo messages in INAV's byte layouts: MSP_SERVO (103), MSP_SERVO_CONFIGURATIONS (120) and
MSP_SET_SERVO_CONFIGURATION (212), MSP2_INAV_SERVO_MIXER (0x2020) and MSP2_INAV_SET_SERVO_MIXER (0x2021);
writes refused while armed, bad ones an error frame that changes nothing."""

from struct import pack

from configfakes import FakeBoard

from hoverfly.core.config.params import Params
from hoverfly.core.flight import Flight
from hoverfly.core.links.mspserver import MspServer
from hoverfly.protocols import msp


def _server(mixer_type="airplane"):
    board = FakeBoard()
    params = Params()
    assert params.set("mixer_type", mixer_type) is None
    flight = Flight(board, params)
    flight.start(board.now_us())
    return MspServer(flight, None), flight


def _ask(server, cmd, payload=b"", version=1):
    out = []
    frame = msp.encode_request(cmd, payload, version, False)
    server.feed(frame, len(frame), out.append)
    p = msp.MspParser()
    for chunk in out:
        p.feed(chunk)
    assert p.pop(), "no reply"
    assert p.cmd == cmd
    return p.direction, p.message()


def test_msp_servo_is_eight_u16_widths():
    s, f = _server()
    f.signals.servo_us[0] = 1720
    f.signals.servo_us[2] = 1234
    d, payload = _ask(s, msp.MSP_SERVO)
    assert d == msp.DIR_REPLY and len(payload) == 16
    assert payload[:6] == bytes([0xB8, 0x06, 0xDC, 0x05, 0xD2, 0x04])  # 1720, 1500, 1234 little-endian


def test_servo_configurations_are_14_bytes_a_servo_as_inav_sends_them_for_the_boards_4_servos():
    s, f = _server()
    assert f.params.update([("servo1_min_us", 1100), ("servo1_mid_us", 1520), ("servo1_rate", -100)]) is None
    d, payload = _ask(s, msp.MSP_SERVO_CONFIGURATIONS)
    assert d == msp.DIR_REPLY and len(payload) == 4 * 14
    # servo 0: min 1000, max 2000, middle 1500, rate 100, then 0, 0, 255 and a u32 0
    assert payload[:14] == bytes([0xE8, 0x03, 0xD0, 0x07, 0xDC, 0x05, 100, 0, 0, 255, 0, 0, 0, 0])
    # servo 1: rate -100 as INAV's int8 byte
    assert payload[14:21] == bytes([0x4C, 0x04, 0xD0, 0x07, 0xF0, 0x05, 0x9C])
    assert msp.unpack_servo_configurations(payload)[1] == (1100, 2000, 1520, -100)


def test_set_servo_configuration_writes_one_servo():
    s, f = _server()
    req = bytes([2]) + pack("<HHHb", 1100, 1900, 1480, -90) + bytes([0, 0, 255, 0, 0, 0, 0])
    assert req == msp.pack_set_servo_configuration(2, 1100, 1900, 1480, -90)
    assert _ask(s, msp.MSP_SET_SERVO_CONFIGURATION, req) == (msp.DIR_REPLY, b"")
    assert [f.params.get("servo2_" + n) for n in ("min_us", "max_us", "mid_us", "rate")] == [1100, 1900, 1480, -90]


def test_set_servo_configuration_min_above_max_or_bad_length_is_an_error_and_changes_nothing():
    s, f = _server()
    for req in (msp.pack_set_servo_configuration(1, 2000, 1000, 1500, 100),
                msp.pack_set_servo_configuration(4, 1000, 2000, 1500, 100),  # servos 0..3
                msp.pack_set_servo_configuration(1, 1000, 2000, 1500, 127),
                msp.pack_set_servo_configuration(1, 1000, 2000, 1500, 100)[:10]):
        assert _ask(s, msp.MSP_SET_SERVO_CONFIGURATION, req)[0] == msp.DIR_ERROR
    assert f.params.get("servo1_min_us") == 1000 and f.params.get("servo1_rate") == 100


def test_servo_mixer_lists_the_preset_as_8_rules_of_6_bytes():
    s, _ = _server("flying_wing")
    d, payload = _ask(s, msp.MSP2_INAV_SERVO_MIXER, version=2)
    assert d == msp.DIR_REPLY and len(payload) == 8 * 6
    # rule 1: servo 0 <- stabilised roll at -50 %, no speed limit, condition 255 (always)
    assert payload[6:12] == bytes([0, 0, 0xCE, 0xFF, 0, 255])
    rules = msp.unpack_servo_mixer(payload)
    assert rules[:4] == [(0, 1, 50, 0, 255), (0, 0, -50, 0, 255), (1, 1, 50, 0, 255), (1, 0, 50, 0, 255)]
    assert rules[4] == (0, 0, 0, 0, 255)


def test_set_servo_mixer_sets_one_rule_and_the_mixer_runs_it():
    s, f = _server()
    req = bytes([2, 2, 2]) + pack("<h", -100) + bytes([20, 255])
    assert req == msp.pack_set_servo_mixer(2, 2, 2, -100, 20)
    assert _ask(s, msp.MSP2_INAV_SET_SERVO_MIXER, req, version=2) == (msp.DIR_REPLY, b"")
    f.configure_if_changed()
    assert f.servos.rules == 3 and f.params.get("smix2_rate") == -100 and f.params.get("smix0_rate") == 100
    rules = msp.unpack_servo_mixer(_ask(s, msp.MSP2_INAV_SERVO_MIXER, version=2)[1])
    assert rules[2] == (2, 2, -100, 20, 255)


def test_set_servo_mixer_bad_rules_are_errors_and_change_nothing():
    s, f = _server()
    for req in (msp.pack_set_servo_mixer(0, 4, 0, 100, 0),  # servo 4: this board drives 0..3
                msp.pack_set_servo_mixer(0, 0, 14, 100, 0),  # flaps
                msp.pack_set_servo_mixer(0, 0, 0, 300, 0),  # rate beyond 125
                msp.pack_set_servo_mixer(8, 0, 0, 100, 0),  # rule 8: rules are 0..7
                msp.pack_set_servo_mixer(0, 0, 0, 100, 0, condition=3),  # a logic condition
                msp.pack_set_servo_mixer(0, 0, 0, 100, 0)[:6]):
        assert _ask(s, msp.MSP2_INAV_SET_SERVO_MIXER, req, version=2)[0] == msp.DIR_ERROR
    assert s.last_error
    assert all(f.params.get("smix%d_rate" % i) == 0 for i in range(8))


def test_servo_writes_are_refused_while_armed():
    s, f = _server()
    f.arming.armed = True
    assert _ask(s, msp.MSP2_INAV_SET_SERVO_MIXER, msp.pack_set_servo_mixer(0, 0, 0, -100, 0), 2)[0] == msp.DIR_ERROR
    assert s.last_error == "refused while armed"
    assert _ask(s, msp.MSP_SET_SERVO_CONFIGURATION,
                msp.pack_set_servo_configuration(0, 1000, 2000, 1400, 100))[0] == msp.DIR_ERROR
    assert f.params.get("smix0_rate") == 0 and f.params.get("servo0_mid_us") == 1500
    assert _ask(s, msp.MSP_SERVO)[0] == msp.DIR_REPLY  # reading goes on
