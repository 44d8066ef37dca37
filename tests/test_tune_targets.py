"""The default tunes against issue 28's "Must show" (sim/airframes/5inch.toml and f450.toml [params]), on
several seeds, measured as `hoverfly fly --json` measures them (logs/steps.py on the true state):

5-inch: rate step 0 -> 400 deg/s rise (10-90 %) <= 21 ms, overshoot <= 5 %, settle (+-5 %) <= 50 ms (and the
flip's end, -400 -> 0, within 5 % too);
angle step 0 -> 30 deg: 90 % within 120 ms, overshoot <= 5 %, steady error <= 0.5 deg; a 1 N m x 100 ms
torque kick back within 2 deg in <= 150 ms; hover tilt RMS (10 s, angle mode) <= 0.4 deg. Betaflight's
default tune on the same physics: 21 ms / 11 % / 70 ms, 175 ms / 10 % / -1.9 deg, 457 ms, 0.41 deg.
The F450 is held to its own figures (its airframe file says them, before and after the tune).
"""

import pytest

from hoverfly.sim.runner import fly
from hoverfly.sim.scenario import HERE, parse_scenario

SEEDS = (1, 2, 3)

TARGETS = {
    # The issue's figures, but the two the attitude estimate sets, not the controller: a held 30 deg bank's
    # steady error (the accelerometer pulls the estimate towards level in a bank) and the hover's tilt (the
    # accelerometer's bias, 0.03 m/s² sigma, is read as tilt: seed 1's alone leans it 0.45 deg). The tune leaves
    # both where they were (before -> after, seeds 1-3: steady error 0.54/1.10/0.53 -> 0.49/1.08/0.59 deg,
    # hover 0.67/0.84/0.22 -> 0.67/0.79/0.21 deg): held here no worse than before, and the issue's own
    # figures, after the pilot's accelerometer calibration, in
    # test_a_calibrated_5inch_meets_the_hover_tilt_and_steady_error_targets below.
    "5inch": {"rate_rise_ms": 21.0, "rate_overshoot_pct": 5.0, "rate_settle_ms": 50.0, "stop_overshoot_pct": 5.0,
              "angle_t90_ms": 120.0, "angle_overshoot_pct": 5.0, "angle_steady_deg": 1.15,
              "torque_back_ms": 150.0, "hover_tilt_rms_deg": 0.85},
    # The F450 before this tune (seeds 1-3): rise 40-41 ms, settle 58-61 ms, angle step 90 % at 139-150 ms,
    # torque kick 112-113 ms; steady error and hover tilt as the 5-inch's, the estimate's
    "f450": {"rate_rise_ms": 38.0, "rate_overshoot_pct": 5.0, "rate_settle_ms": 57.0, "stop_overshoot_pct": 6.0,
             "angle_t90_ms": 126.0, "angle_overshoot_pct": 5.0, "angle_steady_deg": 1.0,
             "torque_back_ms": 92.0, "hover_tilt_rms_deg": 0.9},
}


def _figures(airframe, seed):
    out = {}
    r = fly("rate-steps", airframe, seed)
    assert not r["crashed"]
    ups = [s for s in r["steps"] if s["from"] == 0 and s["to"] == 400]
    assert len(ups) == 2  # roll and pitch
    out["rate_rise_ms"] = max(s["rise_ms"] for s in ups)
    out["rate_overshoot_pct"] = max(s["overshoot_pct"] for s in ups)
    out["rate_settle_ms"] = max(s["settle_ms"] if s["settle_ms"] is not None else 1e9 for s in ups)
    # the end of each flip: -400 deg/s back to 0
    out["stop_overshoot_pct"] = max(s["overshoot_pct"] for s in r["steps"] if s["to"] == 0)
    r = fly("angle-steps", airframe, seed)
    assert not r["crashed"]
    tilts = [s for s in r["steps"] if s["to"] == 30]
    assert len(tilts) == 2
    out["angle_t90_ms"] = max(s["t90_ms"] if s["t90_ms"] is not None else 1e9 for s in tilts)
    out["angle_overshoot_pct"] = max(s["overshoot_pct"] for s in tilts)
    out["angle_steady_deg"] = max(abs(s["steady_error"]) for s in tilts)
    r = fly("torque-kick", airframe, seed)
    assert not r["crashed"]
    kicks = [d for d in r["disturbances"] if d["kind"] == "torque"]
    assert len(kicks) == 3
    out["torque_back_ms"] = max(d["back_within_2deg_ms"] if d["back_within_2deg_ms"] is not None else 1e9
                                for d in kicks[:2])  # the 1 N m ones, roll and pitch
    r = fly("hover", airframe, seed)
    assert not r["crashed"] and r["armed"]
    out["hover_tilt_rms_deg"] = r["tilt_rms_deg"]
    return out


@pytest.mark.parametrize("airframe", sorted(TARGETS))
@pytest.mark.parametrize("seed", SEEDS)
def test_the_default_tune_meets_the_issue_targets(airframe, seed):
    got = _figures(airframe, seed)
    late = {k: (got[k], limit) for k, limit in TARGETS[airframe].items() if got[k] > limit}
    assert not late, (airframe, seed, late, got)


def _calibrated(name):
    """A built-in scenario with the pilot's accelerometer calibration on the ground before arming (a Betaflight
    pilot's routine: the configurator's MSP_ACC_CALIBRATION, sim/scenario.py's acc_calibration)."""
    text = (HERE / (name + ".toml")).read_text()
    return parse_scenario(text + "\n[[at]]\nt = 1.5\nacc_calibration = true\n", name)


# The calibration stores the estimate's lean on level ground as acc_trim_roll/pitch (seed 2: -0.92 / 0.38 deg),
# and angle mode levels to the trimmed attitude (Betaflight's angle trim): uncalibrated, seeds 1-3 hover at
# 0.67/0.79/0.21 deg and hold a 30 deg bank 0.49/1.08/0.59 deg off, as the accelerometer's bias leans them.
@pytest.mark.parametrize("pid_math", ["float", "fixed"])
def test_a_calibrated_5inch_meets_the_hover_tilt_and_steady_error_targets(pid_math):
    seeds = SEEDS if pid_math == "float" else SEEDS[1:2]  # the Pico's path on the seed leaning most
    for seed in seeds:
        h = fly(_calibrated("hover"), "5inch", seed, overrides=(("pid_math", pid_math),))
        assert not h["crashed"] and h["armed"]
        assert [e for e in h["events"] if e["event"] == "acc_calibration"], h["events"]
        a = fly(_calibrated("angle-steps"), "5inch", seed, overrides=(("pid_math", pid_math),))
        assert not a["crashed"]
        steady = max(abs(s["steady_error"]) for s in a["steps"] if s["to"] == 30)
        assert h["tilt_rms_deg"] <= 0.4 and steady <= 0.5, (seed, h["tilt_rms_deg"], steady)
