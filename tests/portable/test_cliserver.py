"""The Betaflight-style CLI: get/set/dump/diff/save/defaults/status/exit over a byte stream."""

from configfakes import make_flight

from hoverfly.core.config.params import Params
from hoverfly.core.config.storage import Storage
from hoverfly.core.links.cliserver import CliServer


def _cli():
    flight, board = make_flight()
    storage = Storage(board)
    storage.load(flight.params)
    cli = CliServer(flight, storage)
    out = []
    cli.enter(out.append)
    return cli, flight, board


def _type(cli, text):
    out = []
    data = text.encode()
    cli.feed(data, len(data), out.append)
    return b"".join(out).decode()


def test_enter_echo_and_prompt():
    cli, f, _ = _cli()
    assert cli.active and f.config_session & 1
    text = _type(cli, "help\r\n")
    assert text.startswith("help\r\n") and "diff [all]" in text and text.endswith("\r\n# ")


def test_get_by_part_and_exact_with_range():
    cli, _, _ = _cli()
    text = _type(cli, "get p_r\r")
    assert "p_roll = 45" in text and "p_pitch" not in text
    text = _type(cli, "get tpa_rate\r")
    assert "Allowed range: 0 - 100 %" in text and "Default value: 65" in text
    assert "ERROR" in _type(cli, "get nothing_like_this\r")


def test_set_with_range_check_and_aliases():
    cli, f, _ = _cli()
    assert "p_roll set to 55" in _type(cli, "set p_roll = 55\r")
    assert f.params.get("p_roll") == 55
    text = _type(cli, "set p_roll = 400\r")
    assert "out of range 0 .. 250" in text and f.params.get("p_roll") == 55
    _type(cli, "set gyro_lpf1_static_hz = 180\r")
    assert f.params.get("gyro_lpf1_hz") == 180
    _type(cli, "set dshot_idle_value = 650\r")
    assert f.params.get("motor_idle_pct") == 6.5
    _type(cli, "set gyro_lpf1_type = BIQUAD\r")
    assert f.params.get("gyro_lpf1_type") == "biquad"
    assert "unknown parameter" in _type(cli, "set nope = 1\r")
    assert "use set name = value" in _type(cli, "set p_roll 3\r")


def test_backspace_edits_the_line():
    cli, f, _ = _cli()
    _type(cli, "set p_roll = 599\x08\x08\x7f60\r")
    assert f.params.get("p_roll") == 60


def test_dump_and_diff():
    cli, _, _ = _cli()
    _type(cli, "set p_yaw = 50\r")
    dump = _type(cli, "dump\r")
    assert "set p_roll = 45" in dump and "set p_yaw = 50" in dump and "batch start" in dump
    diff = _type(cli, "diff all\r")
    assert "set p_yaw = 50" in diff and "set p_roll" not in diff


def test_diff_pasted_back_restores_the_set():
    cli, f, _ = _cli()
    _type(cli, "set p_yaw = 50\rset motor_idle_pct = 4.5\r")
    diff = _type(cli, "diff\r")
    body = diff[diff.index("# diff"):]
    _type(cli, "defaults nosave\r")
    assert f.params.diff() == []
    lines = [ln for ln in body.split("\r\n") if ln and not ln.startswith("#")]
    _type(cli, "\r".join(lines) + "\r")
    assert f.params.get("p_yaw") == 50 and f.params.get("motor_idle_pct") == 4.5


def test_save_writes_storage_and_leaves():
    cli, f, board = _cli()
    _type(cli, "set i_roll = 90\r")
    text = _type(cli, "save\r")
    assert "Saving" in text and not cli.active and f.config_session & 1 == 0
    p = Params()
    Storage(board).load(p)
    assert p.get("i_roll") == 90


def test_defaults_saves_unless_nosave():
    cli, f, board = _cli()
    _type(cli, "set i_roll = 90\rsave\r")
    cli.enter(lambda b: None)
    _type(cli, "defaults\r")
    p = Params()
    Storage(board).load(p)
    assert p.get("i_roll") == 80 and f.params.get("i_roll") == 80


def test_unsafe_commands_refused_while_armed():
    cli, f, _ = _cli()
    f.arming.armed = True
    for line in ("set p_roll = 10", "save", "defaults nosave"):
        assert "refused while armed" in _type(cli, line + "\r")
    assert f.params.get("p_roll") == 45 and cli.active
    assert "p_roll = 45" in _type(cli, "get p_roll\r")


def test_status_names_the_arming_reasons_in_words():
    cli, f, _ = _cli()
    f.arming.flags = (1 << 2) | (1 << 13)
    text = _type(cli, "status\r")
    assert "0x2004" in text and "RXLOSS" in text and "receiver lost" in text
    assert "Loop: 1000 Hz" in text and "Sensors:" in text and "Link:" in text and "Storage:" in text


def test_exit_and_unknown_and_long_lines():
    cli, f, _ = _cli()
    assert "unknown command" in _type(cli, "fly\r")
    assert "too long" in _type(cli, "x" * 300 + "\r")
    _type(cli, "exit\r")
    assert not cli.active and f.config_session & 1 == 0
