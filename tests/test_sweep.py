"""`hoverfly sweep`: grids and seeds become jobs, flights come back the same however many workers fly
them, files and plots are written, Ctrl-C keeps what is done, Ray flies the same rows."""

import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from hoverfly.cli import main
from hoverfly.errors import UserError
from hoverfly.sim import sweep

HOVERFLY = str(Path(sys.executable).parent / "hoverfly")


def _without_wall(rows):
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in sorted(rows, key=lambda r: r["job"])]


def test_grid_specs_read_as_betaflight_users_write_them():
    assert sweep.parse_values("40:60:5", "--set p_roll") == [40, 45, 50, 55, 60]
    assert sweep.parse_values("0.5,1,2", "--noise") == [0.5, 1, 2]
    assert sweep.parse_values("3", "--wind") == [3]
    for bad in ("60:40:5", "1:2", "a,b", "1:5:0", "nan", ""):
        with pytest.raises(UserError):
            sweep.parse_values(bad, "--set p_roll")
    with pytest.raises(UserError, match="p_roll"):
        sweep.parse_set_grid(["p_roll=200:300:50"])  # 300 is past the table's 250
    with pytest.raises(UserError, match="unknown parameter"):
        sweep.parse_set_grid(["p_rol=40:60:5"])


def test_jobs_are_every_grid_point_times_every_seed_in_a_fixed_order():
    jobs = sweep.make_jobs("hover", "5inch", 3, [("p_roll", [40, 50])], wind=[0, 4])
    assert len(jobs) == 2 * 2 * 3
    assert [j["job"] for j in jobs] == list(range(12))
    assert jobs[0]["grid"] == {"p_roll": 40, "wind_m_s": 0} and jobs[0]["seed"] == 1
    assert jobs[-1]["grid"] == {"p_roll": 50, "wind_m_s": 4} and jobs[-1]["seed"] == 3
    with pytest.raises(UserError):
        sweep.make_jobs("hover", "5inch", 0)
    with pytest.raises(UserError):
        sweep.make_jobs("hover", "5inch", 1, battery=[0])


def test_rx_loss_flights_are_the_same_on_one_and_on_two_workers_and_all_land():
    jobs = sweep.make_jobs("rx-loss", "5inch", 2)
    one, stopped1 = sweep.run_local(jobs, 1)
    two, stopped2 = sweep.run_local(jobs, 2)
    assert not stopped1 and not stopped2
    assert _without_wall(one) == _without_wall(two)
    assert sweep.summarise(one) == sweep.summarise(two)
    for r in one:
        # the receiver stops at 7 s: stage 2 lands it and it disarms on the ground, near where it took off
        assert not r["crashed"] and not r["ended_armed"]
        assert r["rx_lost_s"] == pytest.approx(7.1, abs=0.15)
        assert r["alt_final_m"] < 0.05
        assert r["landed_from_takeoff_m"] < 5.0
    s = sweep.summarise(one)[0]
    assert s["flights"] == 2 and s["crashed"] == 0
    lands = sorted(r["landed_from_takeoff_m"] for r in one)
    assert s["landed_from_takeoff_m"]["max"] == lands[-1] and s["landed_from_takeoff_m"]["p50"] == lands[0]


def test_wind_moves_the_craft_and_comes_from_the_seed():
    jobs = sweep.make_jobs("hover", "5inch", 2, wind=[0, 6], duration_s=6)
    rows = sorted(sweep.run_local(jobs, 1)[0], key=lambda r: r["job"])
    calm, windy = rows[:2], rows[2:]
    assert all(not r["crashed"] for r in rows)
    # the position hold is the pilot's; a steady 6 m/s wind pushes the craft further than still air
    assert max(r["drift_m"] for r in windy) > max(r["drift_m"] for r in calm)


def test_ctrl_c_keeps_the_flights_done(monkeypatch):
    jobs = sweep.make_jobs("hover", "5inch", 4, duration_s=0.3)

    def stop_after_first(done, total):
        raise KeyboardInterrupt

    rows, stopped = sweep.run_local(jobs, 1, stop_after_first)
    assert stopped and len(rows) == 1
    rows, stopped = sweep.run_local(jobs, 2, stop_after_first)
    assert stopped and 1 <= len(rows) < 4


def test_sweep_command_writes_table_csv_json_and_plots(tmp_path, capsys):
    out_csv = tmp_path / "s.csv"
    out_json = tmp_path / "s.json"
    plots = tmp_path / "plots"
    code = main(["sweep", "hover", "--seeds", "2", "--set", "p_roll=40:50:10", "--duration", "4", "--workers", "2",
                 "--csv", str(out_csv), "--json", str(out_json), "--plot", str(plots), "--quiet"])
    out = capsys.readouterr().out
    assert code == 0
    assert "hover: 4 flights" in out and "tilt_rms_deg" in out
    with open(out_csv) as fh:
        rows = list(csv.DictReader(fh))
    assert [r["p_roll"] for r in rows] == ["40", "40", "50", "50"] and [r["seed"] for r in rows] == ["1", "2"] * 2
    data = json.loads(out_json.read_text())
    assert data["flights"] == 4 and not data["interrupted"]
    assert [s["p_roll"] for s in data["summary"]] == [40, 50]
    assert (plots / "tilt_rms_deg_vs_p_roll.png").stat().st_size > 1000
    assert (plots / "drift_m_hist.png").stat().st_size > 1000


@pytest.mark.parametrize("argv, words", [
    (["sweep", "hover", "--set", "p_roll=60:40:5"], "lo <= hi"),
    (["sweep", "hover", "--set", "p_roll"], "name=lo:hi:step"),
    (["sweep", "hover", "--seeds", "0"], "--seeds"),
    (["sweep", "nope"], "unknown scenario"),
    (["sweep", "hover", "--wind", "50"], "--wind"),
    (["sweep", "hover", "--csv", "/no/such/dir/x.csv"], "no directory"),
])
def test_sweep_mistakes_are_one_line(capsys, argv, words):
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("hoverfly: error:") and "\n" not in err and words in err


def _loopback_only():
    """A network namespace with only loopback: Ray's servers listen on every interface they see."""
    if shutil.which("unshare") is None:
        return None
    probe = subprocess.run(["unshare", "-rn", "sh", "-c", "ip link set lo up"], capture_output=True)
    return ["unshare", "-rn", "sh", "-c", 'ip link set lo up && exec "$@"', "sh"] if probe.returncode == 0 else None


def test_ray_flies_the_same_rows_as_the_local_pool(tmp_path):
    pytest.importorskip("ray")
    wrap = _loopback_only()
    if wrap is None:
        pytest.skip("no loopback-only network namespace here (unshare -rn) to start Ray in")
    out = tmp_path / "ray.json"
    p = subprocess.run(wrap + [HOVERFLY, "sweep", "hover", "--seeds", "2", "--duration", "2", "--ray", "local",
                               "--workers", "2", "--json", str(out), "--quiet"],
                       capture_output=True, text=True, timeout=240)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "Ray at local" in p.stdout
    ray_rows = json.loads(out.read_text())["rows"]
    local_rows, _ = sweep.run_local(sweep.make_jobs("hover", "5inch", 2, duration_s=2), 1)
    assert _without_wall(ray_rows) == _without_wall(local_rows)
