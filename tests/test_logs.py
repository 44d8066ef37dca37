"""Flight logs from the simulator: pyulog reads them whole and cut, `hoverfly log` tools, step response.

Given a lockstep flight logged with `hoverfly fly --log` (seed fixed), when pyulog, the CLI and
the analysis read it, then the topics are there at the logging rate, cut files keep everything
before the cut, plots are real PNGs and the step-response estimate agrees with the steps the
simulator measured.
"""

import json
import os
import random

import pytest
from pyulog import ULog

from hoverfly.cli import main
from hoverfly.core.logger import FAST_TOPICS, SLOW_TOPICS
from hoverfly.logs.data import load
from hoverfly.logs.ulogread import LogReadError, read_summary
from hoverfly.sim.runner import fly

PX4_TOPICS = ("vehicle_attitude", "vehicle_angular_velocity", "vehicle_rates_setpoint", "actuator_outputs",
              "input_rc", "battery_status", "sensor_combined", "vehicle_status")


@pytest.fixture(scope="module")
def rate_steps(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("log") / "rate-steps.ulg")
    result = fly("rate-steps", "5inch", seed=7, log_path=path)
    return result, path


@pytest.fixture(scope="module")
def short_log(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("short") / "short.ulg")
    fly("hover", "5inch", seed=3, duration_s=0.4, log_path=path)
    return path


def _rates(path):
    s = read_summary(path)
    return s, {t["name"]: t for t in s["topics"]}


@pytest.mark.parametrize("scenario,airframe,rate_hz", [("hover", "f450", 1000), ("demo", "5inch", 500),
                                                       ("flip", "5inch", 250)])
def test_sim_logs_open_in_pyulog_clean_with_every_topic_at_the_logging_rate(tmp_path, scenario, airframe,
                                                                            rate_hz):
    path = str(tmp_path / "f.ulg")
    r = fly(scenario, airframe, seed=1, duration_s=2.5, overrides=[("blackbox_rate_hz", rate_hz)],
            log_path=path)
    ulog = ULog(path)
    assert not ulog.file_corruption
    s, topics = _rates(path)
    assert s["warnings"] == []
    for name in PX4_TOPICS + FAST_TOPICS + SLOW_TOPICS:
        assert name in topics, name
    for name in FAST_TOPICS:
        assert topics[name]["rate_hz"] == pytest.approx(rate_hz, rel=0.01), name
    for name in SLOW_TOPICS:
        assert topics[name]["rate_hz"] == pytest.approx(10.0, rel=0.05), name
    assert topics["input_rc"]["rate_hz"] == pytest.approx(min(rate_hz, 250.0), rel=0.05)
    assert r["log"]["dropped"] == 0
    assert s["info"]["sys_name"] == "hoverfly" and s["params"]["blackbox_rate_hz"] == rate_hz


def test_log_holds_arming_events_as_messages_and_the_flight_duration(rate_steps):
    result, path = rate_steps
    s = read_summary(path)
    texts = [m["text"] for m in s["messages"]]
    assert "armed 0" in texts and "mode acro" in texts
    assert s["duration_s"] == pytest.approx(result["sim_time_s"], abs=0.002)


def _d_counts(data, cut):
    """Samples per msg_id in whole D messages before `cut`."""
    counts = {}
    off = 16
    while off + 3 <= cut:
        size = data[off] | (data[off + 1] << 8)
        if off + 3 + size > cut:
            break
        if data[off + 2] == 0x44:
            mid = data[off + 3] | (data[off + 4] << 8)
            counts[mid] = counts.get(mid, 0) + 1
        off += 3 + size
    return counts


def _check_cut(data, cut, tmp_path):
    p = tmp_path / "cut.ulg"
    p.write_bytes(data[:cut])
    try:
        s = read_summary(str(p))
    except LogReadError:
        assert cut < 16 + 43  # only a cut inside the header or flag bits is unreadable
        return
    want = _d_counts(data, cut)
    got = {t["msg_id"]: t["samples"] for t in s["topics"]}
    for mid, n in want.items():
        assert got.get(mid, 0) == n, (cut, mid, got.get(mid), n)


def test_a_log_cut_at_any_byte_keeps_everything_before_the_cut(short_log, tmp_path):
    data = open(short_log, "rb").read()
    rng = random.Random(5)
    # every byte of the header, flag bits and first formats, a fine comb through the rest of the
    # definitions and the first data frames, then a spread over the rest
    offsets = list(range(0, 400)) + list(range(400, 9000, 17)) + sorted(rng.randrange(9000, len(data))
                                                                          for _ in range(80))
    for cut in offsets:
        _check_cut(data, cut, tmp_path)


def test_cut_or_corrupted_logs_give_a_warning_or_one_error_line_never_a_traceback(short_log, tmp_path,
                                                                                  capsys):
    data = bytearray(open(short_log, "rb").read())
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(bytes(data[: len(data) // 2 + 7]))
    assert main(["log", "info", str(cut)]) == 0
    assert "cut off" in capsys.readouterr().err
    rng = random.Random(11)
    bad = tmp_path / "bad.ulg"
    for _ in range(25):
        d = bytearray(data)
        for _ in range(20):
            d[rng.randrange(16, len(d))] = rng.randrange(256)
        bad.write_bytes(bytes(d))
        for cmd in ("info", "params"):
            code = main(["log", cmd, str(bad)])
            err = capsys.readouterr().err
            assert code in (0, 2)
            assert "Traceback" not in err
    junk = tmp_path / "junk.ulg"
    junk.write_bytes(b"hello, not a log")
    assert main(["log", "report", str(junk), "--out", str(tmp_path / "r")]) == 2
    assert "not a readable ULog" in capsys.readouterr().err
    assert main(["log", "info", str(tmp_path / "missing.ulg")]) == 2


def test_report_writes_an_index_and_non_empty_pngs(rate_steps, tmp_path, capsys):
    _, path = rate_steps
    out = tmp_path / "report"
    assert main(["log", "report", path, "--out", str(out)]) == 0
    index = (out / "index.html").read_text()
    pngs = sorted(p for p in os.listdir(out) if p.endswith(".png"))
    names = ("attitude", "rates", "motors", "pid", "gyro_spectrum", "spectrogram", "step_response")
    assert pngs == sorted(n + ".png" for n in names)
    for p in pngs:
        raw = (out / p).read_bytes()
        assert raw[:8] == b"\x89PNG\r\n\x1a\n" and len(raw) > 10000, p
        assert p in index


def test_step_response_from_the_log_agrees_with_the_steps_the_simulator_measured(rate_steps):
    result, path = rate_steps
    from hoverfly.logs.analysis import step_responses

    est = step_responses(load(path))
    for axis in ("roll", "pitch"):
        measured = [s for s in result["steps"] if s["axis"] == axis and s["mode"] == "rate"]
        assert measured
        rise = sum(s["rise_ms"] for s in measured) / len(measured)
        over = max(s["overshoot_pct"] for s in measured)
        e = est[axis]
        assert e is not None and e["windows"] >= 3
        assert abs(e["rise_ms"] - rise) <= 8.0, (axis, e["rise_ms"], rise)
        assert e["overshoot_pct"] <= over + 10.0, (axis, e["overshoot_pct"], over)
        assert 0.8 <= e["settled"] <= 1.1


def test_step_response_estimate_sees_a_slower_tune(tmp_path):
    path = str(tmp_path / "soft.ulg")
    soft = fly("rate-steps", "5inch", seed=7, log_path=path, overrides=[("p_roll", 20), ("f_roll", 0)])
    from hoverfly.logs.analysis import step_responses

    est = step_responses(load(path))["roll"]
    measured = [s["rise_ms"] for s in soft["steps"] if s["axis"] == "roll"]
    assert est["rise_ms"] > 35.0
    assert abs(est["rise_ms"] - sum(measured) / len(measured)) <= 0.35 * est["rise_ms"]


def test_info_params_csv_and_plot_commands(rate_steps, tmp_path, capsys):
    _, path = rate_steps
    assert main(["log", "info", path]) == 0
    out = capsys.readouterr().out
    assert "vehicle_attitude" in out and "1000.0" in out
    assert main(["log", "info", path, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["file_corruption"] is False
    assert main(["log", "params", path, "--changed"]) == 0
    assert "angle_p_gain" in capsys.readouterr().out  # the scenario's tune
    assert main(["log", "params", path, "--json"]) == 0
    params = json.loads(capsys.readouterr().out)["params"]
    assert params["p_roll"] == 45 and params["mixer_type"] == "quadx" and params["motor_idle_pct"] == 5.5
    assert main(["log", "csv", path, "--out", str(tmp_path / "csv"), "--topic", "input_rc"]) == 0
    lines = (tmp_path / "csv" / "rate-steps_input_rc.csv").read_text().splitlines()
    assert lines[0].startswith("timestamp,t_s,timestamp_last_signal") and len(lines) > 2000
    assert main(["log", "plot", path, "--out", str(tmp_path / "p"), "--only", "motors"]) == 0
    assert os.listdir(tmp_path / "p") == ["motors.png"]
    assert main(["log", "plot", path, "--only", "nonsense"]) == 2
