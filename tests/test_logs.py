"""Flight logs from the simulator: pyulog reads them whole and cut, `hoverfly log` tools, step response.

Given a lockstep flight logged with `hoverfly fly --log` (seed fixed), when pyulog, the CLI and
the analysis read it, then the topics are there at the logging rate, cut files keep everything
before the cut, plots are real PNGs and the step-response estimate agrees with the steps the
simulator measured.
"""

import json
import math
import os
import random

import numpy as np
import pytest
from pyulog import ULog

from hoverfly.cli import main
from hoverfly.core.log.logger import FAST_TOPICS, SLOW_TOPICS
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


# Stated tolerances between the simulator's figures (physics truth, the scenario's command, every pass)
# and a log's (filtered gyro, the set point after the 11-bit receiver link, frames up to 4 ms later).
RISE_TOL_MS = 3.0
T90_TOL_MS = 5.0
SETTLE_TOL_MS = 6.0
OVERSHOOT_TOL_PCT = 1.5


def _agree(a, b, what):
    assert (a["axis"], a["mode"]) == (b["axis"], b["mode"]), what
    assert abs(a["rise_ms"] - b["rise_ms"]) <= RISE_TOL_MS, (what, a, b)
    assert abs(a["t90_ms"] - b["t90_ms"]) <= T90_TOL_MS, (what, a, b)
    assert abs(a["settle_ms"] - b["settle_ms"]) <= SETTLE_TOL_MS, (what, a, b)
    assert abs(a["overshoot_pct"] - b["overshoot_pct"]) <= OVERSHOOT_TOL_PCT, (what, a, b)


def test_fly_log_report_and_replay_give_the_same_step_figures_for_the_same_flight(rate_steps, tmp_path, capsys):
    result, path = rate_steps
    flown = result["steps"]
    assert main(["log", "report", path, "--out", str(tmp_path / "r")]) == 0
    report = json.loads((tmp_path / "r" / "steps.json").read_text())
    assert "rise 10-90" in report["method"]
    logged = report["steps"]
    capsys.readouterr()
    assert main(["log", "replay", path, "--out", str(tmp_path / "p"), "--json"]) == 0
    replayed = json.loads(capsys.readouterr().out)["steps"]
    assert len(flown) == len(logged) == len(replayed) == 6
    for f, lg, rp in zip(flown, logged, replayed, strict=True):
        assert lg["t_s"] == pytest.approx(f["t_s"], abs=0.005)  # the same step, one frame later at most
        _agree(f, lg, "fly against log report")
        _agree(lg, rp, "log report against replay")
        assert lg["to"] == pytest.approx(f["to"], rel=0.01)  # 400 deg/s asked, 399.4 through CRSF's 11 bits


def _second_order(t_s, wn_rad_s, zeta):
    wd = wn_rad_s * math.sqrt(1 - zeta * zeta)
    phi = math.acos(zeta)
    return 1 - np.exp(-zeta * wn_rad_s * t_s) / math.sqrt(1 - zeta * zeta) * np.sin(wd * t_s + phi)


def _synthetic_log(path, wn_rad_s, zeta, steps_dps):
    """A ULog as hoverfly writes one, holding roll rate steps whose gyro is an exact second-order response."""
    from hoverfly.protocols.ulog import UlogWriter

    with open(path, "wb") as f:
        w = UlogWriter(f, 0)
        w.add_format("input_rc", [("uint64_t", "timestamp"), ("uint16_t[18]", "values")])
        w.add_format("vehicle_rates_setpoint", [("uint64_t", "timestamp"), ("float", "roll"), ("float", "pitch"),
                                                ("float", "yaw")])
        w.add_format("vehicle_angular_velocity", [("uint64_t", "timestamp"), ("float[3]", "xyz")])
        w.add_format("hoverfly_pid", [("uint64_t", "timestamp"), ("uint8_t", "mode")])
        w.add_param("deadband", 0)
        w.begin_data()
        rc = w.subscribe("input_rc")
        sp = w.subscribe("vehicle_rates_setpoint")
        gy = w.subscribe("vehicle_angular_velocity")
        pid = w.subscribe("hoverfly_pid")
        # a 400 deg/s stick step every 0.5 s: 1 kHz samples, a receiver frame every 4 ms
        levels = [0.0] + list(steps_dps)
        for k in range(int(0.5 * len(levels) * 1000)):
            t_us = 1000 + k * 1000
            i = k // 500
            level = levels[i]
            if k % 4 == 0:
                w.write_data(rc, t_us, [1500 + round(level * 500 / 400)] + [1500] * 17)
            prev = levels[i - 1] if i > 0 else 0.0
            y = prev + (level - prev) * (_second_order(np.array([(k % 500) * 1e-3]), wn_rad_s, zeta)[0]
                                         if i > 0 else 1.0)
            w.write_data(sp, t_us, [level / 57.29577951308232, 0.0, 0.0])
            w.write_data(gy, t_us, [y / 57.29577951308232, 0.0, 0.0])
            w.write_data(pid, t_us, [0])


def test_a_known_second_order_response_built_into_a_log_gives_its_figures_back(tmp_path):
    from hoverfly.logs.analysis import log_steps

    wn, zeta = 2 * math.pi * 12.0, 0.5
    path = str(tmp_path / "second_order.ulg")
    _synthetic_log(path, wn, zeta, (400.0, -400.0, 0.0))
    # the figures of the continuous response, at 1 µs
    t = np.arange(0, 0.5, 1e-6)
    y = _second_order(t, wn, zeta)
    rise_ms = (t[np.argmax(y >= 0.9)] - t[np.argmax(y >= 0.1)]) * 1000
    t90_ms = t[np.argmax(y >= 0.9)] * 1000
    settle_ms = t[np.nonzero(np.abs(y - 1) > 0.05)[0][-1]] * 1000
    overshoot_pct = 100 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta * zeta))  # 16.3 %
    steps = log_steps(load(path))
    assert [(s["from"], s["to"]) for s in steps] == [(0.0, 400.0), (400.0, -400.0), (-400.0, 0.0)]
    for s in steps:
        # the log's samples are 1 ms apart: each time within a sample of the truth
        assert s["rise_ms"] == pytest.approx(rise_ms, abs=1.0)
        assert s["t90_ms"] == pytest.approx(t90_ms, abs=1.0)
        assert s["settle_ms"] == pytest.approx(settle_ms, abs=1.0)
        assert s["overshoot_pct"] == pytest.approx(overshoot_pct, abs=0.1)
        assert s["steady_error"] == pytest.approx(0.0, abs=0.5)


def test_a_softer_roll_tune_shows_a_slower_rise_in_the_log_as_in_the_flight(tmp_path):
    from hoverfly.logs.analysis import log_steps

    path = str(tmp_path / "soft.ulg")
    soft = fly("rate-steps", "5inch", seed=7, log_path=path, overrides=[("p_roll", 20), ("f_roll", 0)])
    flown = [s for s in soft["steps"] if s["axis"] == "roll"]
    logged = [s for s in log_steps(load(path)) if s["axis"] == "roll"]
    assert len(flown) == len(logged) == 3
    for f, lg in zip(flown, logged, strict=True):
        assert lg["rise_ms"] > 40.0
        assert abs(f["rise_ms"] - lg["rise_ms"]) <= RISE_TOL_MS


def test_report_and_steps_json_say_how_the_steps_are_measured(rate_steps, tmp_path, capsys):
    _, path = rate_steps
    assert main(["log", "report", path, "--out", str(tmp_path / "r")]) == 0
    out = capsys.readouterr().out
    assert "step roll rate 0 -> 399.363 deg/s at 5.50 s: rise" in out
    index = (tmp_path / "r" / "index.html").read_text()
    assert "Measured on each commanded step" in index and "settle" in index


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
    assert params["p_roll"] == 97 and params["mixer_type"] == "quadx" and params["motor_idle_pct"] == 5.5
    assert main(["log", "csv", path, "--out", str(tmp_path / "csv"), "--topic", "input_rc"]) == 0
    lines = (tmp_path / "csv" / "rate-steps_input_rc.csv").read_text().splitlines()
    assert lines[0].startswith("timestamp,t_s,timestamp_last_signal") and len(lines) > 2000
    assert main(["log", "plot", path, "--out", str(tmp_path / "p"), "--only", "motors"]) == 0
    assert os.listdir(tmp_path / "p") == ["motors.png"]
    assert main(["log", "plot", path, "--only", "nonsense"]) == 2


def test_the_attitude_plot_has_the_angle_set_point_in_angle_mode_only(tmp_path):
    from hoverfly.logs.plot import angle_setpoint_deg

    path = str(tmp_path / "angle.ulg")
    fly("angle-steps", "5inch", seed=7, duration_s=6.5, log_path=path)
    t, sp = angle_setpoint_deg(load(path))
    at = lambda s: sp[np.searchsorted(t, s), 0]  # noqa: E731
    assert at(4.9) == pytest.approx(0.0, abs=0.5) and at(5.5) == pytest.approx(30.0, abs=0.5)  # the roll step
    assert at(6.2) == pytest.approx(0.0, abs=0.5)


def test_no_angle_set_point_is_drawn_while_in_acro(rate_steps):
    from hoverfly.logs.plot import angle_setpoint_deg

    t, sp = angle_setpoint_deg(load(rate_steps[1]))
    acro = (t > 5.1) & (t < 8.1)
    assert np.isnan(sp[acro]).all() and not np.isnan(sp[(t > 1.0) & (t < 4.9)]).any()


def test_the_spectrum_marks_the_filter_cut_offs_the_flight_ran_with(tmp_path):
    from hoverfly.logs.plot import filter_cutoffs

    path = str(tmp_path / "f.ulg")
    fly("hover", "5inch", seed=1, duration_s=1.0, log_path=path,
        overrides=[("gyro_lpf1_hz", 180), ("gyro_lpf2_hz", 300), ("gyro_notch1_hz", 220), ("gyro_notch1_cut", 160)])
    hz = [c[0] for c in filter_cutoffs(load(path))]
    assert hz == [180, 300, 220, 70]  # lpf1, lpf2 (below Nyquist), the notch, the 5-inch's D-term low-pass


def test_pid_panels_scale_to_p_i_d_not_to_feed_forward_spikes(rate_steps):
    from hoverfly.logs.plot import _robust_lim

    pid = load(rate_steps[1]).topic("hoverfly_pid")
    lo, hi = _robust_lim([pid["p[0]"], pid["i[0]"], pid["d[0]"]])
    assert hi < 0.5 * float(np.max(np.abs(pid["f[0]"])))  # F's spikes would have flattened the terms
    assert hi >= float(np.percentile(np.abs(pid["p[0]"]), 99))


def test_replay_plots_say_open_loop_and_name_the_changed_parameters(rate_steps, tmp_path):
    from hoverfly.logs.replay import _title, _zoom_window, replay

    r = replay(load(rate_steps[1]), [("p_roll", 70)])
    assert "open loop" in _title(r, "PID terms") and "p_roll=70" in _title(r, "PID terms")
    t0, t1 = _zoom_window(r, ["p_roll"])
    i = int(np.argmax(np.abs(r.new["p_roll"] - r.old["p_roll"])))
    assert t0 <= r.t_s[i] <= t1 and t1 - t0 == pytest.approx(0.6)


def test_a_log_at_half_the_loop_rate_gives_the_flight_s_step_figures(tmp_path):
    from hoverfly.logs.analysis import log_steps

    path = str(tmp_path / "rs500.ulg")
    flown = fly("rate-steps", "5inch", seed=7, log_path=path, overrides=[("blackbox_rate_hz", 500)])["steps"]
    logged = log_steps(load(path))
    assert len(logged) == len(flown) == 6
    for f, lg in zip(flown, logged, strict=True):
        _agree(f, lg, "fly against a 500 Hz log")
