"""AUX mode switches in flight (issue 3): the failsafe test switch and the AIRMODE switch.

Flown in lockstep on the simulator (CRSF wire, 250 Hz frames) with a fixed seed; a scenario
`channel = {ch, us}` event moves the switch, and the flight is judged by its events and state.
"""

import pytest

from hoverfly.errors import UserError
from hoverfly.sim.runner import SimRun, fly
from hoverfly.sim.scenario import parse_scenario

_SWITCH_T_S = 7.0
_CRSF_FRAME_S = 0.004  # 250 Hz


def _events(r, name):
    return [e for e in r["events"] if e["event"] == name]


def _t(r, name):
    ev = _events(r, name)
    return ev[0]["t_s"] if ev else None


def _hover(params, events, duration_s=12):
    """Arm at 2 s, hold 3 m from 2.5 s, then the extra [[at]] entries."""
    text = "duration_s = %s\n[params]\n%s\n" % (duration_s, params)
    text += "[[at]]\nt = 2.0\narm = true\n[[at]]\nt = 2.5\nhold_altitude_m = 3.0\n"
    for t, body in events:
        text += "[[at]]\nt = %s\n%s\n" % (t, body)
    return parse_scenario(text)


def _fs_switch_flight(mode, off_at_s=None):
    events = [(_SWITCH_T_S, "channel = {ch = 9, us = 2000}")]
    if off_at_s is not None:
        events.append((off_at_s, "channel = {ch = 9, us = 1000}"))
    return fly(_hover('fs_switch_ch = 9\nfs_switch_mode = "%s"' % mode, events), "5inch", seed=7)


def test_failsafe_switch_stage1_runs_the_lost_receiver_timing_lands_and_disarms():
    r = _fs_switch_flight("stage1")
    lost = _events(r, "rx_lost")
    assert len(lost) == 1 and lost[0]["detail"] == "fs_switch"
    assert _SWITCH_T_S - _CRSF_FRAME_S <= lost[0]["t_s"] <= _SWITCH_T_S  # the last frame taken
    stage1 = _events(r, "failsafe_stage1")
    assert stage1[0]["detail"] == "fs_switch"
    assert 0.0 < stage1[0]["t_s"] - _SWITCH_T_S <= 0.150
    assert _t(r, "failsafe_stage2") - stage1[0]["t_s"] == pytest.approx(0.4, abs=0.05)
    assert _t(r, "landed") is not None
    assert [e["detail"] for e in _events(r, "disarmed")] == ["landed"]
    assert not r["armed"] and not r["crashed"]


def test_failsafe_switch_stage1_released_within_stage1_hands_the_sticks_back():
    r = _fs_switch_flight("stage1", off_at_s=_SWITCH_T_S + 0.25)
    assert _t(r, "failsafe_stage1") is not None
    assert _t(r, "failsafe_stage2") is None
    end = _events(r, "failsafe_end")
    assert end and end[0]["detail"] == "0" and end[0]["t_s"] <= _SWITCH_T_S + 0.27
    assert _events(r, "rx_restored")[-1]["t_s"] >= _SWITCH_T_S + 0.25
    assert r["armed"] and not r["crashed"]


def test_failsafe_switch_stage2_goes_straight_to_the_procedure():
    r = _fs_switch_flight("stage2")
    stage2 = _t(r, "failsafe_stage2")
    assert stage2 is not None and 0.0 < stage2 - _SWITCH_T_S <= 0.015  # one slow pass (100 Hz)
    assert _t(r, "failsafe_stage1") == stage2
    assert _events(r, "failsafe_stage2")[0]["detail"] == "land"
    assert [e["detail"] for e in _events(r, "disarmed")] == ["landed"]
    assert not r["armed"] and not r["crashed"]


def test_failsafe_switch_kill_disarms_within_one_rx_frame():
    r = _fs_switch_flight("kill")
    disarm = _events(r, "disarmed")
    assert disarm and disarm[0]["detail"] == "fs_switch"
    # the frame carrying the switch, plus one receiver-task period (500 Hz) to read it
    assert 0.0 < disarm[0]["t_s"] - _SWITCH_T_S <= _CRSF_FRAME_S + 0.002
    assert _t(r, "failsafe_stage1") is None and _t(r, "rx_lost") is None  # the link itself is fine
    assert not r["armed"]


def test_failsafe_switch_kill_blocks_arming_while_on_then_arms_after_a_toggle():
    sc = parse_scenario("""
duration_s = 6
[params]
fs_switch_ch = 9
fs_switch_mode = "kill"
[[at]]
t = 2.0
arm = true
[[at]]
t = 2.5
channel = {ch = 9, us = 2000}
[[at]]
t = 3.0
arm = false
[[at]]
t = 3.5
arm = true
[[at]]
t = 4.0
channel = {ch = 9, us = 1000}
[[at]]
t = 4.5
arm = false
[[at]]
t = 5.0
arm = true
""")
    r = fly(sc, "5inch", seed=7)
    armed = _events(r, "armed")
    assert [round(e["t_s"], 1) for e in armed] == [2.0, 5.0]
    assert _events(r, "disarmed")[0]["detail"] == "fs_switch"
    blocked = _events(r, "arming_blocked")
    assert len(blocked) == 1 and blocked[0]["detail"].startswith("BOXFAILSAFE:")
    assert 3.5 <= blocked[0]["t_s"] < 3.52
    assert r["armed"]


def test_failsafe_switch_with_no_channel_does_nothing():
    r = fly(_hover("", [(_SWITCH_T_S, "channel = {ch = 9, us = 2000}")], duration_s=9), "5inch", seed=7)
    assert _t(r, "failsafe_stage1") is None and _t(r, "rx_lost") is None
    assert r["armed"] and not r["crashed"]


class AirmodeTrace:
    """flight.commander.airmode_active and i_active each pass after a time, as (t_s, airmode, i_term)."""

    def __init__(self, run, after_s):
        self.after_s = after_s
        self.rows = []
        run.on_step = self

    def __call__(self, run):
        t = run.board.sim_us * 1e-6
        if t >= self.after_s:
            f = run.flight
            self.rows.append((t, f.commander.airmode_active, f.commander.i_active))


def _airmode_run(params, events):
    run = SimRun("5inch", _hover(params, events, duration_s=9), seed=7)
    trace = AirmodeTrace(run, 4.0)
    return run.run(), trace.rows


def test_airmode_switch_off_keeps_air_mode_off_but_the_i_term_on():
    r, rows = _airmode_run("airmode_ch = 10", [])  # the switch stays low (1000 µs) the whole flight
    assert _events(r, "airmode") == []
    assert not any(a for _, a, _ in rows)
    assert all(i for _, _, i in rows)  # flying: the I-term works, air mode or not
    assert r["armed"] and not r["crashed"]


def test_airmode_switch_turns_air_mode_on_and_off_in_flight():
    r, rows = _airmode_run("airmode_ch = 10", [(5.0, "channel = {ch = 10, us = 2000}"),
                                                (7.0, "channel = {ch = 10, us = 1000}")])
    ev = [(e["t_s"], e["detail"]) for e in _events(r, "airmode")]
    assert len(ev) == 2 and ev[0][1] == "1" and ev[1][1] == "0"
    assert 5.0 <= ev[0][0] <= 5.01 and 7.0 <= ev[1][0] <= 7.01
    assert not any(a for t, a, _ in rows if t < 5.0 or t > 7.01)
    assert all(a for t, a, _ in rows if 5.01 < t < 7.0)
    assert r["armed"] and not r["crashed"]


def test_airmode_with_no_channel_follows_the_airmode_parameter():
    r_on, rows_on = _airmode_run("", [(5.0, "channel = {ch = 10, us = 1000}")])
    assert [e["detail"] for e in _events(r_on, "airmode")] == ["1"]
    assert all(a for _, a, _ in rows_on)
    r_off, rows_off = _airmode_run("airmode = 0", [(5.0, "channel = {ch = 10, us = 2000}")])
    assert _events(r_off, "airmode") == []
    assert not any(a for _, a, _ in rows_off)


@pytest.mark.parametrize("body, words", [
    ("channel = {ch = 4, us = 2000}", "5..16"),
    ("channel = {ch = 9, us = 2500}", "out of range"),
    ("channel = {ch = 9}", "channel must be a table"),
    ("channel = 9", "channel must be a table"),
])
def test_scenario_channel_event_is_checked(body, words):
    with pytest.raises(UserError, match=words):
        parse_scenario("duration_s = 5\n[[at]]\nt = 1.0\n%s\n" % body)
