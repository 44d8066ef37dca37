"""`hoverfly fly` from the command line: JSON shape, and bad input as one-line errors."""

import json

from hoverfly.cli import main

KEYS = ("scenario", "airframe", "seed", "sim_time_s", "wall_time_s", "realtime_factor", "loop_hz", "crashed",
        "armed", "events", "tilt_rms_deg", "max_tilt_deg", "altitude_m", "horizontal_drift_m", "steps", "loop")


def test_fly_json_has_the_documented_keys(capsys):
    assert main(["fly", "--scenario", "angle-steps", "--duration", "6", "--json", "--set", "p_roll=50"]) == 0
    r = json.loads(capsys.readouterr().out)
    for k in KEYS:
        assert k in r
    assert set(r["altitude_m"]) == {"min", "max", "final"}
    assert set(r["loop"]) >= {"mean_us", "max_us", "overruns"}
    step = r["steps"][0]
    for k in ("axis", "mode", "from", "to", "unit", "rise_ms", "overshoot_pct", "settle_ms", "steady_error"):
        assert k in step
    assert all(set(e) == {"t_s", "event", "detail"} for e in r["events"])


def _error(capsys, argv):
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code != 0
    assert err.startswith("hoverfly: error:") and "\n" not in err and "Traceback" not in err
    return err


def test_unknown_airframe_is_one_line(capsys):
    assert "unknown airframe 'x9'" in _error(capsys, ["fly", "--airframe", "x9"])


def test_unknown_scenario_is_one_line(capsys):
    assert "unknown scenario" in _error(capsys, ["fly", "--scenario", "nope"])


def test_out_of_range_parameter_names_the_range(capsys):
    assert "0 .. 250" in _error(capsys, ["fly", "--set", "p_roll=900"])
    assert "unknown parameter" in _error(capsys, ["fly", "--set", "p_rol=9"])
    assert "name=value" in _error(capsys, ["fly", "--set", "p_roll"])


def test_malformed_scenario_files_are_one_line(capsys, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("duration_s = [\n")
    assert "not valid TOML" in _error(capsys, ["fly", "--scenario", str(bad)])
    bad.write_text('duration_s = 5\n[[at]]\nt = 1\nthrotle = 0.5\n')
    assert "unknown key 'throtle'" in _error(capsys, ["fly", "--scenario", str(bad)])
    bad.write_text('duration_s = 5\n[[at]]\nt = 9\narm = true\n')
    assert "out of range" in _error(capsys, ["fly", "--scenario", str(bad)])
    assert "does not exist" in _error(capsys, ["fly", "--scenario", str(tmp_path / "none.toml")])


def test_bad_numbers_on_the_command_line(capsys):
    assert "invalid" in _error(capsys, ["fly", "--duration", "abc"])
    assert "duration" in _error(capsys, ["fly", "--duration", "-1"])
