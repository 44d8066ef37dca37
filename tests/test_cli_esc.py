"""`hoverfly esc encode` / `hoverfly esc decode-erpm`: reference vectors through the CLI, errors exit 2."""

import json

import pytest

import hoverfly.cli


@pytest.fixture
def esc(monkeypatch, capsys):
    monkeypatch.setattr(hoverfly.cli, "COMMAND_MODULES", ("hoverfly.cli_esc",))

    def run(*argv):
        code = hoverfly.cli.main(["esc", *argv])
        out, err = capsys.readouterr()
        return code, out, err

    return run


def _json(esc, *argv):
    code, out, err = esc(*argv, "--json")
    assert code == 0, err
    return json.loads(out)


def test_encode_dshot_vector_json(esc):
    d = _json(esc, "encode", "--protocol", "dshot600", "--value", "1046")
    assert d["frame"] == 0x82C6 and d["hex"] == "0x82C6" and d["bits"] == "1000001011000110"
    assert d["protocol"] == "dshot600" and d["telemetry"] is False and d["bidir"] is False
    assert (d["bit_ns"], d["t0h_ns"], d["t1h_ns"], d["frame_ns"]) == (1667, 625, 1250, 26667)
    assert d["sm_freq_hz"] == 4800000 and d["pio_word"] == "0x82C60000"


def test_encode_dshot_command_bidirectional(esc):
    d = _json(esc, "encode", "--protocol", "dshot300", "--value", "13", "--telemetry", "--bidir")
    assert d["hex"] == "0x01B5" and d["command_repeats"] == 10 and "EXTENDED_TELEMETRY_ENABLE" in d["meaning"]
    assert d["reply_bit_ns"] == 2667


def test_encode_dshot_text(esc):
    code, out, _ = esc("encode", "--protocol", "dshot150", "--value", "48")
    assert code == 0 and "0x0606" in out and "T1H 5000 ns" in out


def test_encode_analog_worked_example(esc):
    expect = {"pwm": 1234.0, "oneshot125": 154.25, "oneshot42": 51.828, "multishot": 9.68}
    for proto, us in expect.items():
        d = _json(esc, "encode", "--protocol", proto, "--value", "234")
        assert d["pulse_us"] == pytest.approx(us, abs=1e-6), proto
        assert "frame" not in d
    d = _json(esc, "encode", "--protocol", "pwm", "--value", "500",
              "--rate-hz", "400", "--timer-hz", "1000000")
    assert d["pulse_us"] == 1500 and d["period_counts"] == 2500 and d["compare_counts"] == 1500


def test_encode_servo(esc):
    d = _json(esc, "encode", "--protocol", "servo", "--value", "-1000")
    assert d["pulse_us"] == 1000 and d["rate_hz"] == 50


@pytest.mark.parametrize("argv", [
    ("encode", "--protocol", "dshot600", "--value", "2048"),
    ("encode", "--protocol", "dshot600", "--value", "-1"),
    ("encode", "--protocol", "dshot600", "--value", "abc"),
    ("encode", "--protocol", "oneshot125", "--value", "1001"),
    ("encode", "--protocol", "pwm", "--value", "10", "--rate-hz", "600"),
    ("encode", "--protocol", "pwm", "--value", "10", "--bidir"),
    ("encode", "--protocol", "dshot999", "--value", "10"),
    ("decode-erpm", "12345"),
    ("decode-erpm", "XYZ"),
    ("decode-erpm", "5F41", "--poles", "7"),
    ("decode-erpm", "3FFFFF", "--gcr"),
])
def test_bad_values_are_one_line_user_errors(esc, argv):
    code, out, err = esc(*argv)
    assert code == 2
    assert err.startswith("hoverfly: error:") and err.count("\n") == 1


def test_decode_erpm_vector_json(esc):
    d = _json(esc, "decode-erpm", "5F41")
    assert d == {"word": "0x5F41", "crc_ok": True, "kind": "erpm", "stopped": False, "period_us": 2000,
                 "erpm": 30000, "rpm": 4286, "poles": 14}
    d = _json(esc, "decode-erpm", "0x32C2", "--poles", "12")
    assert d["erpm"] == 100000 and d["rpm"] == 16667
    d = _json(esc, "decode-erpm", "FFF0")
    assert d["stopped"] and d["erpm"] == 0


def test_decode_erpm_from_line_code(esc):
    d = _json(esc, "decode-erpm", "%X" % int("110101011111110111011", 2), "--gcr")
    assert d["word"] == "0x5F41" and d["gcr_ok"] and d["period_us"] == 2000


def test_decode_edt_temperature(esc):
    d = _json(esc, "decode-erpm", "22D2")
    assert d["kind"] == "temperature" and d["value"] == 45 and d["unit"] == "degC"
    d = _json(esc, "decode-erpm", "22D2", "--no-edt")
    assert d["kind"] == "erpm"


def test_corrupted_reply_reports_bad_crc_and_exits_1(esc):
    code, out, _ = esc("decode-erpm", "5F40", "--json")
    assert code == 1 and json.loads(out) == {"word": "0x5F40", "crc_ok": False, "kind": "invalid"}
    code, out, _ = esc("decode-erpm", "100000", "--gcr")
    assert code == 1 and "bad GCR" in out


def test_decode_text(esc):
    code, out, _ = esc("decode-erpm", "5F41")
    assert code == 0 and "30000 eRPM" in out and "4286 RPM" in out
