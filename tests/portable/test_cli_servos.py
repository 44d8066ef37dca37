"""The CLI's INAV servo commands: smix (list, set a rule, reset) and servo (list, set), refused while armed or
with a bad value (one error line, nothing changes), and status showing a plane's servo outputs."""

from configfakes import FakeBoard

from hoverfly.core.config.params import Params
from hoverfly.core.flight import Flight
from hoverfly.core.links.cliserver import CliServer


def _cli(mixer_type="airplane"):
    board = FakeBoard()
    params = Params()
    assert params.set("mixer_type", mixer_type) is None
    flight = Flight(board, params)
    flight.start(board.now_us())
    cli = CliServer(flight, None)
    cli.enter([].append)
    return cli, flight


def _type(cli, text):
    out = []
    data = (text + "\r").encode()
    cli.feed(data, len(data), out.append)
    return b"".join(out).decode()


def _errors(text):
    return [line for line in text.split("\r\n") if "ERROR" in line]


def test_smix_lists_the_airplane_preset_as_inav_prints_rules():
    cli, _ = _cli()
    text = _type(cli, "smix")
    assert "# airplane preset (no rules stored)" in text
    assert "smix 0 0 0 100 0  # Stabilised Roll" in text
    assert "smix 1 1 1 100 0  # Stabilised Pitch" in text
    assert "smix 2 2 2 100 0  # Stabilised Yaw" in text


def test_smix_sets_a_rule_keeping_the_others_and_the_mixer_runs_it():
    cli, f = _cli()
    text = _type(cli, "smix 2 2 2 -100 50")
    assert not _errors(text) and "smix 2 2 2 -100 50" in text and "smix 0 0 0 100 0" in text
    assert "preset" not in text
    f.configure_if_changed()
    assert f.servos.rules == 3 and f.params.get("smix2_rate") == -100 and f.params.get("smix2_speed") == 50


def test_smix_reset_brings_the_preset_back():
    cli, f = _cli()
    _type(cli, "smix 0 3 0 100 0")
    text = _type(cli, "smix reset")
    assert "# airplane preset (no rules stored)" in text and f.params.get("smix0_servo") == 0


def test_smix_naming_a_servo_that_does_not_exist_is_one_error_line_and_changes_nothing():
    cli, f = _cli()
    text = _type(cli, "smix 0 4 0 100 0")
    assert _errors(text) == ["###ERROR: smix: servo 4 does not exist: servos are 0..3###"]
    for line in ("smix 0 0 0 200 0", "smix 0 0 13 100 0", "smix 0 0 0 100 300", "smix 8 0 0 100 0",
                 "smix 0 zero 0 100 0", "smix 0 0 0"):
        assert len(_errors(_type(cli, line))) == 1, line
    assert all(f.params.get("smix%d_rate" % i) == 0 for i in range(8))


def test_servo_lists_and_sets_end_points_centre_and_rate():
    cli, f = _cli()
    assert "servo 2 1000 2000 1500 100" in _type(cli, "servo")
    text = _type(cli, "servo 2 1100 1900 1520 -100")
    assert not _errors(text) and "servo 2 1100 1900 1520 -100" in text
    assert f.params.get("servo2_mid_us") == 1520 and f.params.get("servo2_rate") == -100


def test_servo_with_min_above_max_is_one_error_line_and_changes_nothing():
    cli, f = _cli()
    text = _type(cli, "servo 1 2000 1000 1500 100")
    assert len(_errors(text)) == 1 and "servo 1:" in text and "min" in text
    assert len(_errors(_type(cli, "servo 1 1000 2000 1500 150"))) == 1
    assert len(_errors(_type(cli, "servo 7 1000 2000 1500 100"))) == 1  # this board drives servos 0..3
    assert f.params.get("servo1_min_us") == 1000 and f.params.get("servo1_rate") == 100


def test_smix_and_servo_writes_are_refused_while_armed():
    cli, f = _cli()
    f.arming.armed = True
    for line in ("smix 0 0 0 50 0", "smix reset", "servo 0 1000 2000 1400 100"):
        assert "refused while armed" in _type(cli, line), line
    assert f.params.get("smix0_rate") == 0 and f.params.get("servo0_mid_us") == 1500
    assert "smix 0 0 0 100 0" in _type(cli, "smix")  # listing still works


def test_status_shows_a_planes_servo_outputs():
    cli, f = _cli()
    text = _type(cli, "status")
    assert "Servos: 1500 1500 1500 us (airplane, 3 rules)" in text
    cli_quad, _ = _cli("quadx")
    assert "Servos:" not in _type(cli_quad, "status")
