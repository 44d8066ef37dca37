"""A plane's pitot: the board's read_airspeed taken by the 50 Hz task into signals.airspeed_m_s, shown by the
CLI's status line and by INAV's MSP2_INAV_AIR_SPEED (0x2009: u32 cm/s, 0 without a pitot)."""

from struct import pack

from configfakes import FakeBoard

from hoverfly.core.config.params import Params
from hoverfly.core.flight import Flight
from hoverfly.core.links.cliserver import CliServer
from hoverfly.core.links.mspserver import MspServer
from hoverfly.protocols import msp


class PitotBoard(FakeBoard):
    """A board with a pitot that reads `airspeed_m_s` (None: no sensor fitted)."""

    def __init__(self, airspeed_m_s=None):
        FakeBoard.__init__(self)
        self.airspeed_m_s = airspeed_m_s
        self.reads = 0

    def read_airspeed(self):
        self.reads += 1
        return self.airspeed_m_s


def _fly(board, mixer_type="airplane", passes=60):
    """A flight on `board` run for `passes` 1 kHz passes (the 50 Hz task runs about three times)."""
    params = Params()
    assert params.set("mixer_type", mixer_type) is None
    flight = Flight(board, params)
    flight.start(board.now_us())
    _run(flight, board, passes)
    return flight


def _run(flight, board, passes):
    for _ in range(passes):
        board.t_us += 1000
        flight.step(board.t_us)


def _ask(server, cmd):
    out = []
    frame = msp.encode_request(cmd, b"", 2, False)
    server.feed(frame, len(frame), out.append)
    p = msp.MspParser()
    for chunk in out:
        p.feed(chunk)
    assert p.pop(), "no reply"
    assert p.cmd == cmd
    return p.direction, p.message()


def _status(flight):
    return "\n".join(CliServer(flight, None).cmd_status())


def test_the_pitot_is_read_by_the_50_hz_task_not_every_pass():
    board = PitotBoard(13.24)
    f = _fly(board, passes=100)
    assert f.signals.airspeed_valid and abs(f.signals.airspeed_m_s - 13.24) < 1e-6
    # 100 passes at 1 kHz: five or six runs of the 50 Hz task, not a hundred reads
    assert 4 <= board.reads <= 7


def test_msp2_inav_air_speed_is_a_u32_of_cm_s_as_inav_sends_it():
    f = _fly(PitotBoard(13.24))
    d, payload = _ask(MspServer(f, None), msp.MSP2_INAV_AIR_SPEED)
    assert d == msp.DIR_REPLY
    assert payload == bytes([0x2C, 0x05, 0x00, 0x00])  # 1324 cm/s little-endian
    assert msp.unpack_air_speed(payload) == 1324


def test_msp2_inav_air_speed_without_a_pitot_is_zero_not_an_error():
    f = _fly(PitotBoard(None), mixer_type="quadx")
    d, payload = _ask(MspServer(f, None), msp.MSP2_INAV_AIR_SPEED)
    assert d == msp.DIR_REPLY and payload == pack("<I", 0)
    assert not f.signals.airspeed_valid


def test_cli_status_prints_a_planes_airspeed_on_the_sensors_line():
    f = _fly(PitotBoard(13.24))
    sensors = [line for line in _status(f).split("\n") if line.startswith("Sensors:")]
    assert len(sensors) == 1 and sensors[0].endswith("; airspeed 13.2 m/s")


def test_cli_status_says_nothing_of_airspeed_on_a_board_without_a_pitot():
    f = _fly(PitotBoard(None), mixer_type="quadx")
    assert "airspeed" not in _status(f)


def test_a_pitot_that_stops_answering_is_no_longer_shown():
    board = PitotBoard(15.0)
    f = _fly(board)
    assert "airspeed 15.0 m/s" in _status(f)
    board.airspeed_m_s = None
    _run(f, board, 40)
    assert not f.signals.airspeed_valid and "airspeed" not in _status(f)
    _, payload = _ask(MspServer(f, None), msp.MSP2_INAV_AIR_SPEED)
    assert payload == pack("<I", 0)


def test_air_speed_codec_clamps_and_never_raises():
    assert msp.pack_air_speed(-5) == pack("<I", 0)
    assert msp.pack_air_speed(1e12) == pack("<I", 0xFFFFFFFF)
    assert msp.unpack_air_speed(b"\x01\x02\x03") is None
    assert msp.unpack_air_speed(b"") is None
    assert msp.unpack_air_speed(pack("<I", 2500) + b"\xff") == 2500


def _crc8_dvb_s2(data):
    """CRC-8/DVB-S2 (poly 0xD5) bit by bit: an implementation apart from the codec's table."""
    crc = 0
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = ((crc << 1) ^ 0xD5) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def test_crsf_airspeed_frame_is_a_big_endian_u16_of_tenths_of_km_h():
    from hoverfly.protocols import crsf

    out = bytearray(64)
    n = crsf.encode_airspeed(out, 13.9)  # 50.04 km/h -> 500
    assert n == 6
    assert bytes(out[:5]) == bytes([0xC8, 0x04, 0x0A, 0x01, 0xF4])
    assert out[5] == _crc8_dvb_s2(out[2:5])
    crsf.encode_airspeed(out, -3.0)
    assert out[3] == 0 and out[4] == 0
    crsf.encode_airspeed(out, 1e9)
    assert out[3] == 0xFF and out[4] == 0xFF


def test_crsf_telemetry_carries_the_airspeed_in_its_rotation_only_while_the_pitot_reads():
    from hoverfly.protocols import crsf

    t = crsf.CrsfTelemetryScheduler(1000)
    out = bytearray(64)
    t.set_battery(12.0, 1.0, 10, 90)
    t.set_attitude(0.0, 0.0, 0.0)
    t.set_airspeed(15.0)
    kinds = []
    for k in range(6):
        n = t.poll(10000 * (k + 1), 1, out)
        assert n > 0
        kinds.append(out[2])
    assert kinds == [0x08, 0x1E, 0x0A, 0x08, 0x1E, 0x0A]
    t.clear(crsf.KIND_AIRSPEED)
    for k in range(4):
        t.poll(100000 + 10000 * k, 1, out)
        assert out[2] != 0x0A
