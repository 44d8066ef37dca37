"""`hoverfly tune`: a small search that flies, a diff that `hoverfly params restore` applies to a running
controller, a nonsense airframe or a search that finds nothing flyable ends in one clear line, never gains
that crash, and Ctrl-C stops with the best so far."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

from hoverfly.cli import main
from hoverfly.cli_params import read_set_file
from hoverfly.errors import UserError
from hoverfly.sim import tune
from hoverfly.sim.airframes import load_airframe

pytest.importorskip("optuna")

HOVERFLY = str(Path(sys.executable).parent / "hoverfly")
_PORTS = re.compile(r"CLI\+MSP on 127\.0\.0\.1:(\d+), maintenance on 127\.0\.0\.1:(\d+)")


def _one_line_error(capsys, argv):
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("hoverfly: error:") and "\n" not in err and "Traceback" not in err
    return err


def test_the_hand_tune_flies_the_tuning_flight_and_is_scored():
    a = load_airframe("5inch")
    m = tune.fly_tune(a, tune._proposal(tune.hand_tune(a), a), 1)
    assert m["unflyable"] is None
    assert 10 < m["rate_t90_ms"] < 120 and 50 < m["angle_t90_ms"] < 400
    assert m["kick_peak_deg"] > 2.0  # the knocks did tilt it, and it came back (else unflyable)
    assert 0 < tune.score([m]) < tune.UNFLYABLE


def test_gains_of_zero_cannot_fly_and_the_search_says_so(monkeypatch, capsys):
    monkeypatch.setattr(tune, "SPACE", (("p_roll", 0, 0), ("i_roll", 0, 0), ("d_roll", 0, 0), ("f_roll", 0, 0),
                                        ("angle_p_gain", 0, 0), ("gyro_lpf1_hz", 250, 250),
                                        ("dterm_lpf1_hz", 75, 75)))
    err = _one_line_error(capsys, ["tune", "--airframe", "5inch", "--trials", "1", "--seeds", "1",
                                   "--check-seeds", "1", "--workers", "1", "--out", "/tmp/never-written.txt",
                                   "--quiet"])
    assert "nothing the search tried could fly" in err


def test_a_craft_too_weak_to_hover_is_refused_before_any_flight(tmp_path, capsys):
    text = (Path(__file__).parent.parent / "src/hoverfly/sim/airframes/f450.toml").read_text()
    weak = tmp_path / "weak.toml"
    weak.write_text(text.replace("kt = 1.3e-5", "kt = 2.0e-6"))
    assert "cannot hover" in _one_line_error(capsys, ["tune", "--airframe", str(weak), "--quiet"])
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("mass_kg = 1.3", "mass_kg = -1"))
    assert "mass_kg" in _one_line_error(capsys, ["tune", "--airframe", str(bad), "--quiet"])
    assert "--trials" in _one_line_error(capsys, ["tune", "--airframe", "f450", "--trials", "0"])


def _fake_flight(unflyable_seeds=(), unflyable_if=None):
    """A stand-in flight for the choosing logic: the score falls as p_roll nears 90."""
    def fly(airframe, values, seed):
        bad = seed in unflyable_seeds or (unflyable_if is not None and unflyable_if(values))
        m = {k: 1.0 for k, _s, _w in tune._SCORE}
        m["rate_t90_ms"] = 20.0 + abs(values["p_roll"] - 90)
        m["unflyable"] = "crashed" if bad else None
        return m
    return fly


def test_gains_that_crash_on_a_check_seed_are_never_given(monkeypatch):
    a = load_airframe("5inch")
    # every proposal flies its training seed; the best ones crash on check seed 1001
    monkeypatch.setattr(tune, "fly_tune", _fake_flight(unflyable_seeds=(1001,)))
    with pytest.raises(UserError, match="did not fly every check seed"):
        tune.tune(a, trials=4, train_seeds=(1,), check_seeds=(1001,), workers=1)


def test_the_best_proposal_that_flies_every_check_seed_is_chosen(monkeypatch):
    a = load_airframe("5inch")
    # proposals with p_roll above 100 crash on the check seeds only: the search may rank them first
    def fly(airframe, values, seed):
        return _fake_flight(unflyable_if=lambda v: seed >= 1000 and v["p_roll"] > 100)(airframe, values, seed)

    monkeypatch.setattr(tune, "fly_tune", fly)
    r = tune.tune(a, trials=12, train_seeds=(1,), check_seeds=(1001,), workers=1, candidates=12)
    assert not r["interrupted"] and r["values"]["p_roll"] <= 100
    assert all(trial for trial, why in r["rejected"])


def test_ctrl_c_stops_with_the_best_so_far_and_no_values(monkeypatch):
    a = load_airframe("5inch")
    monkeypatch.setattr(tune, "fly_tune", _fake_flight())
    seen = []

    def stop_after_two(done, total, best):
        seen.append(done)
        if done == 2:
            raise KeyboardInterrupt

    r = tune.tune(a, trials=10, train_seeds=(1,), check_seeds=(1001,), workers=1, progress=stop_after_two)
    assert r["interrupted"] and r["values"] is None and r["trials"] == 2
    assert r["best"]["score"] < tune.UNFLYABLE and seen == [1, 2]


class _Sim:
    def __init__(self, storage):
        self.proc = subprocess.Popen([HOVERFLY, "sim", "--msp-port", "0", "--maint-port", "0", "--storage",
                                      storage, "--duration", "120"], stdout=subprocess.PIPE, text=True)
        m = _PORTS.search(self.proc.stdout.readline())
        if m is None:
            self.stop()
            raise AssertionError("no ports from hoverfly sim")
        self.cli_url = "socket://127.0.0.1:%s" % m.group(1)

    def stop(self):
        self.proc.terminate()
        self.proc.wait(10)
        self.proc.stdout.close()


def test_a_tiny_tune_saves_a_diff_that_params_restore_applies(tmp_path, capsys):
    pytest.importorskip("serial")
    out = tmp_path / "f450-tune.txt"
    code = main(["tune", "--airframe", "f450", "--trials", "2", "--seeds", "1", "--check-seeds", "1",
                 "--workers", "2", "--out", str(out), "--quiet"])
    printed = capsys.readouterr().out
    assert code == 0
    assert "hand tune" in printed and "tuned" in printed and "check seeds 1001" in printed
    wanted, is_diff = read_set_file(str(out))
    assert is_diff and {"p_roll", "d_roll", "angle_p_gain"} <= set(wanted)
    sim = _Sim(str(tmp_path / "params.bin"))
    try:
        assert main(["params", "restore", str(out), "--yes", "--port", sim.cli_url]) == 0
        capsys.readouterr()
        for name in ("p_roll", "d_pitch", "angle_p_gain", "gyro_lpf1_hz", "dterm_lpf1_hz"):
            assert main(["params", "get", name, "--port", sim.cli_url]) == 0
            got = capsys.readouterr().out.strip().splitlines()[0]
            if name in wanted:
                assert got == "%s = %s" % (name, wanted[name])
    finally:
        sim.stop()
