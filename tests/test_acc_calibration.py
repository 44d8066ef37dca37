"""The pilot's accelerometer calibration in a scenario (`acc_calibration = true` in an [[at]] entry): sent as the
configurator sends it, an MSP_ACC_CALIBRATION to the flight's MSP server, which stores the attitude the estimate
reads on level ground as acc_trim_roll / acc_trim_pitch, and refuses it while armed."""

import math

import pytest

from hoverfly.errors import UserError
from hoverfly.sim.runner import SimRun
from hoverfly.sim.scenario import HERE, parse_scenario


def calibrated(name, at_s=1.5):
    """A built-in scenario with the pilot's calibration at `at_s` (the built-ins arm at 2 s)."""
    text = (HERE / (name + ".toml")).read_text()
    return parse_scenario(text + "\n[[at]]\nt = %g\nacc_calibration = true\n" % at_s, name)


def _cal_events(run):
    return [e for e in run.events_out if e["event"] == "acc_calibration"]


def test_the_calibration_on_the_ground_stores_the_estimates_lean_as_the_trims():
    run = SimRun("5inch", calibrated("hover"), seed=1, duration_s=1.51)
    run.run()
    (ev,) = _cal_events(run)
    assert ev["t_s"] == 1.5 and not ev["detail"].startswith("refused"), ev
    roll_trim = run.params.get("acc_trim_roll")
    pitch_trim = run.params.get("acc_trim_pitch")
    att = run.flight.signals.attitude
    # the estimate's own reading, a pass or so after it was taken
    assert abs(roll_trim - math.degrees(att.roll_rad)) < 0.02
    assert abs(pitch_trim - math.degrees(att.pitch_rad)) < 0.02
    # the craft sits level: what the trims hold is the estimate's error (seed 1's accelerometer bias)
    roll, pitch, _ = run.vehicle.euler_rad()
    assert abs(math.degrees(roll)) < 0.02 and abs(math.degrees(pitch)) < 0.02, (roll, pitch)
    assert math.hypot(roll_trim, pitch_trim) > 0.3, (roll_trim, pitch_trim)
    assert ev["detail"] == "roll %.2f deg, pitch %.2f deg" % (roll_trim, pitch_trim)


def test_a_calibration_asked_for_in_flight_is_refused_and_changes_nothing():
    run = SimRun("5inch", calibrated("hover", at_s=3.0), seed=2, duration_s=3.2)
    result = run.run()
    assert result["armed"] and not result["crashed"]
    (ev,) = _cal_events(run)
    assert ev["detail"] == "refused: refused while armed", ev
    assert run.params.get("acc_trim_roll") == 0.0 and run.params.get("acc_trim_pitch") == 0.0


def test_acc_calibration_is_true_or_false():
    with pytest.raises(UserError, match="acc_calibration must be true or false"):
        parse_scenario('duration_s = 3\n[[at]]\nt = 1\nacc_calibration = 1\n', "bad")
    with pytest.raises(UserError, match="did you mean acc_calibration"):
        parse_scenario('duration_s = 3\n[[at]]\nt = 1\nacc_calibraton = true\n', "bad")
