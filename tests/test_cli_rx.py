"""`hoverfly rx decode` / `hoverfly rx encode` through hoverfly.cli.main."""

import json

import pytest

import hoverfly.cli
from hoverfly.cli import main
from hoverfly.protocols import crsf, sbus

RC_MIXED = bytes.fromhex("C8 18 16 AC 98 38 F8 7E 01 70 FA A0 8F BB 00 F8 3F 2B C0 37 71 F0 B1 02 7C A4")
LINK_1 = bytes.fromhex("C8 0C 14 3C 41 64 09 00 04 03 46 62 FE CD")
PING = bytes.fromhex("C8 04 28 00 EA 54")
SBUS_MIXED = bytes.fromhex("0F AD A0 38 F8 D0 07 80 FF D3 87 BB AD 00 1F C5 C1 07 C0 FF 05 C0 FF 09 00")


@pytest.fixture(autouse=True)
def _rx_cli(monkeypatch):
    monkeypatch.setattr(hoverfly.cli, "COMMAND_MODULES", ("hoverfly.cli_rx",))


def _lines(capsys):
    return [json.loads(line) for line in capsys.readouterr().out.splitlines()]


def test_decode_crsf_json_gives_one_object_per_frame_then_a_summary(tmp_path, capsys):
    bad = bytearray(RC_MIXED)
    bad[9] ^= 1
    cap = tmp_path / "crsf.bin"
    cap.write_bytes(b"\x55\x55" + RC_MIXED + LINK_1 + bytes(bad) + PING + RC_MIXED)
    assert main(["rx", "decode", "--protocol", "crsf", str(cap), "--json"]) == 0
    recs = _lines(capsys)
    assert [r["type"] for r in recs] == ["rc", "link_statistics", "device_ping", "rc", "summary"]
    assert recs[0]["channels_us"][:5] == [988, 2011, 1500, 1000, 2000] and len(recs[0]["channels_us"]) == 16
    assert recs[1]["rssi_dbm"] == -60 and recs[1]["link_quality_pct"] == 100
    assert recs[2]["dest"] == 0x00 and recs[2]["origin"] == 0xEA
    s = recs[-1]
    assert (s["frames"], s["crc_errors"], s["bytes"]) == (2, 1, 2 + 26 + 14 + 26 + 6 + 26)
    assert s["resyncs"] >= 2


def test_decode_sbus_json_carries_the_flags(tmp_path, capsys):
    cap = tmp_path / "sbus.bin"
    cap.write_bytes(SBUS_MIXED + bytes(sbus.encode_rc_frame([1500] * 16, frame_lost=True)))
    assert main(["rx", "decode", "--protocol", "sbus", str(cap), "--json"]) == 0
    recs = _lines(capsys)
    assert recs[0]["failsafe"] is True and recs[0]["frame_lost"] is False and recs[0]["ch17"] is True
    assert recs[1]["frame_lost"] is True and recs[1]["channels_us"] == [1500] * 16
    assert recs[2]["type"] == "summary" and recs[2]["frames"] == 2


def test_decode_human_lines(tmp_path, capsys):
    cap = tmp_path / "crsf.bin"
    cap.write_bytes(RC_MIXED + LINK_1)
    assert main(["rx", "decode", "--protocol", "crsf", str(cap)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("rc   988 2011 1500 1000 2000")
    assert "rssi -60 dBm" in out[1] and "lq 100%" in out[1]
    assert "frames 1" in out[2] and "crc_errors 0" in out[2]


def test_decode_reads_stdin(monkeypatch, capsys):
    import io
    import sys

    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(RC_MIXED)))
    assert main(["rx", "decode", "--protocol", "crsf", "-", "--json"]) == 0
    assert _lines(capsys)[0]["type"] == "rc"


def test_decode_missing_file_is_a_user_error(tmp_path, capsys):
    assert main(["rx", "decode", "--protocol", "crsf", str(tmp_path / "nope.bin")]) == 2
    err = capsys.readouterr().err
    assert "no such file" in err and "Traceback" not in err


def test_unknown_protocol_is_a_user_error(capsys):
    assert main(["rx", "decode", "--protocol", "dsm", "x.bin"]) == 2
    assert "invalid choice" in capsys.readouterr().err


def test_encode_hex_pads_to_16_channels(capsys):
    assert main(["rx", "encode", "--protocol", "crsf", "--channels", "1500,1500", "--hex"]) == 0
    out = capsys.readouterr().out.strip()
    assert out == "C8 18 16 E0 03 1F F8 C0 07 3E F0 81 0F 7C E0 03 1F F8 C0 07 3E F0 81 0F 7C AD"


def test_encode_binary_to_stdout_and_file(tmp_path, capsysbinary):
    assert main(["rx", "encode", "--protocol", "sbus", "--channels", "1500", "--failsafe"]) == 0
    frame = capsysbinary.readouterr().out
    assert len(frame) == 25 and frame[0] == 0x0F and frame[23] == 0x08
    out = tmp_path / "f.bin"
    assert main(["rx", "encode", "--protocol", "ibus", "--channels", "1000,2000", "--out", str(out)]) == 0
    data = out.read_bytes()
    assert len(data) == 32 and data[:6] == bytes.fromhex("20 40 E8 03 D0 07")


def test_encode_then_decode_round_trips(tmp_path, capsys):
    chans = [1000 + 60 * k for k in range(16)]
    out = tmp_path / "f.bin"
    assert main(["rx", "encode", "--protocol", "crsf", "--channels", ",".join(map(str, chans)), "--out", str(out)]) == 0
    d = crsf.CrsfDecoder()
    assert d.feed(out.read_bytes()) == 1 and list(d.channels_us) == chans


@pytest.mark.parametrize("channels, words", [
    ("1500,abc", "not a number"),
    ("1500,799", "outside 800..2200"),
    ("2201", "outside 800..2200"),
    (",".join(["1500"] * 17), "carries 16 channels"),
])
def test_encode_bad_channels_are_user_errors(channels, words, capsys):
    assert main(["rx", "encode", "--protocol", "crsf", "--channels", channels]) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


def test_encode_sbus_flags_refused_for_crsf(capsys):
    assert main(["rx", "encode", "--protocol", "crsf", "--failsafe"]) == 2
    assert "SBUS flags" in capsys.readouterr().err
