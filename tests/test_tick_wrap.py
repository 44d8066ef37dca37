"""The tick clock wraps every 2**30 us (about 18 minutes; MicroPython's period on a Pico too), and a tick difference
reads negative once it passes half that. Flights longer than 9 minutes must not notice."""

from hoverfly.sim.runner import fly

_LATE_ARM = """
name = "late-arm"
description = "Sit disarmed for 10 minutes, then arm and hover."
duration_s = 612
mode = "angle"
judge_from_s = 605.0

[[at]]
t = 600.0
arm = true

[[at]]
t = 600.5
hold_altitude_m = 2.0
"""


def test_a_craft_left_on_for_ten_minutes_arms_and_hovers_and_its_events_keep_their_times(tmp_path):
    # given a quad left disarmed for 10 minutes (past the half period, 537 s), when the pilot arms and takes off,
    # then it arms at once (not "still booting"), hovers at 2 m, and every event is dated in flight time
    path = tmp_path / "late-arm.toml"
    path.write_text(_LATE_ARM)
    r = fly(str(path), "5inch", seed=3, overrides=(("loop_hz", 100),))  # 100 Hz: ten minutes in seconds of CPU
    events = r["events"]
    blocked = [e for e in events if e["event"] == "arming_blocked"]
    assert not blocked, blocked
    armed = [e["t_s"] for e in events if e["event"] == "armed"]
    assert armed and abs(armed[0] - 600.0) < 0.05, events
    times = [e["t_s"] for e in events]
    assert times == sorted(times) and min(times) >= 0.0, times
    assert not r["crashed"] and abs(r["altitude_m"]["final"] - 2.0) < 0.3, r["altitude_m"]
