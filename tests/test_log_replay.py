"""Replay: a logged flight's sensor and receiver streams through a fresh Flight, with new parameters.

Given a rate-steps flight logged at the loop rate, when it is replayed with the logged
parameters the controller's outputs (PID terms, sums, motors) come out as logged; with a
changed gain they change the way that gain says; bad input is one error line.
"""

import json

import numpy as np
import pytest

from hoverfly.cli import main
from hoverfly.errors import UserError
from hoverfly.logs.data import load
from hoverfly.logs.replay import replay
from hoverfly.sim.runner import fly


@pytest.fixture(scope="module")
def logged(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("replay") / "rate-steps.ulg")
    fly("rate-steps", "5inch", seed=7, log_path=path)
    return path, load(path)


def test_replay_with_the_logged_parameters_reproduces_the_controller_outputs(logged):
    _, log = logged
    r = replay(log)
    assert r.warnings == []
    assert len(r.t_s) == 9000
    diffs = r.max_abs_diff()
    for key in ("sum_roll", "sum_pitch", "sum_yaw", "p_roll", "d_pitch", "i_roll", "f_pitch", "motor0",
                "motor3"):
        assert key in diffs
        # float32 in the log, float32 in the replay: equal to the last bit here, 1e-6 allowed
        assert diffs[key] <= 1e-6, (key, diffs[key])
    assert np.max(np.abs(r.old["sum_roll"])) > 0.05  # the flight really moved the sticks


def test_doubling_roll_p_doubles_the_roll_p_term_and_leaves_pitch_alone(logged):
    _, log = logged
    p = log.params["p_roll"]
    r = replay(log, [("p_roll", 2 * p)])
    ratio = r.rms("new")["p_roll"] / r.rms("old")["p_roll"]
    assert ratio == pytest.approx(2.0, rel=1e-3)
    assert r.max_abs_diff()["p_pitch"] == 0.0
    assert r.max_abs_diff()["sum_roll"] > 0.01


def test_more_roll_d_means_a_larger_d_term_and_more_motor_activity(logged):
    _, log = logged
    # D-min on: D rests at d_min_roll and rises towards d_roll on fast moves, so both are doubled
    r = replay(log, [("d_roll", 2 * log.params["d_roll"]), ("d_min_roll", 2 * log.params["d_min_roll"])])
    assert r.rms("new")["d_roll"] > 1.9 * r.rms("old")["d_roll"]

    def activity(d):
        return sum(float(np.sum(np.abs(np.diff(d["motor%d" % m])))) for m in range(4))

    assert activity(r.new) > activity(r.old)


def test_a_lower_gyro_lowpass_smooths_the_filtered_gyro(logged):
    _, log = logged
    r = replay(log, [("gyro_lpf1_hz", 60)])

    def roughness(x):
        return float(np.sqrt(np.mean(np.square(np.diff(x)))))

    assert roughness(r.new["gyro_roll"]) < roughness(r.old["gyro_roll"])


def test_replay_applies_parameter_changes_logged_in_flight(tmp_path):
    path = str(tmp_path / "changes.ulg")
    from hoverfly.sim.runner import SimRun

    run = SimRun("5inch", "hover", 7, duration_s=3.0, log_path=str(path))
    run.scenario["events"].append({"t": 0.5, "set": {"gyro_lpf1_hz": 120}})
    run.scenario["events"].sort(key=lambda e: e["t"])
    run.run()
    log = load(path)
    assert [(k, v) for _, k, v in log.changed_params] == [("gyro_lpf1_hz", 120)]
    r = replay(log)
    assert r.max_abs_diff()["sum_roll"] <= 1e-6


def test_replay_cli_prints_numbers_and_writes_old_against_new_plots(logged, tmp_path, capsys):
    path, _ = logged
    out = tmp_path / "rp"
    assert main(["log", "replay", path, "--set", "p_pitch=60", "--out", str(out), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["passes"] == 9000 and d["overrides"] == [["p_pitch", "60"]]
    assert d["max_abs_diff"]["p_pitch"] > 0 and d["max_abs_diff"]["p_roll"] == 0
    for p in d["plots"]:
        raw = open(p, "rb").read()
        assert raw[:4] == b"\x89PNG" and len(raw) > 10000


def test_replay_refuses_bad_parameters_and_logs_without_sensor_samples(logged, tmp_path, capsys):
    path, log = logged
    assert main(["log", "replay", path, "--set", "p_roll=9999"]) == 2
    assert "out of range" in capsys.readouterr().err
    assert main(["log", "replay", path, "--set", "nonsense"]) == 2
    from hoverfly.protocols.ulog import UlogWriter

    other = tmp_path / "other.ulg"
    with open(other, "wb") as f:
        w = UlogWriter(f, 0)
        w.add_format("vehicle_attitude", (("uint64_t", "timestamp"), ("float[4]", "q")))
        m = w.subscribe("vehicle_attitude")
        for k in range(10):
            w.write_data(m, k * 1000, (1.0, 0.0, 0.0, 0.0))
    with pytest.raises(UserError):
        replay(load(str(other)))
    assert main(["log", "replay", str(other)]) == 2
    assert "nothing to replay" in capsys.readouterr().err


def test_a_log_at_a_lower_rate_than_the_loop_warns_that_replay_needs_the_loop_rate(tmp_path):
    path = str(tmp_path / "slow.ulg")
    fly("hover", "5inch", seed=2, duration_s=1.0, overrides=[("blackbox_rate_hz", 250)], log_path=path)
    r = replay(load(path))
    assert any("blackbox_rate_hz = loop_hz" in w for w in r.warnings)
