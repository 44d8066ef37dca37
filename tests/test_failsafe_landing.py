"""The failsafe's landing detection, judged on rx-loss flights: it disarms on the ground, never in the air."""

import pytest

from hoverfly.sim.runner import fly


# Seeds on which rotor vibration once passed the touchdown spike metres up: the craft disarmed and fell.
@pytest.mark.parametrize("airframe,seed", [("5inch", 40), ("5inch", 70), ("5inch", 192), ("f450", 70), ("f450", 5)])
def test_a_failsafe_landing_disarms_on_the_ground_not_in_the_air(airframe, seed):
    r = fly("rx-loss", airframe, seed=seed)
    names = [e["event"] for e in r["events"]]
    assert not r["crashed"], r["events"]
    assert "landed" in names and names.index("landed") > names.index("failsafe_stage2"), names
    assert not r["armed"] and r["altitude_m"]["final"] < 0.05, r["altitude_m"]
