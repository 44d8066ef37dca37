"""Arming after configuration (issue 30) and the arming race (issue 25, seed 000).

An arm request meets the reasons as they stand at its frame: throttle raised in the same receiver frame as
the arm switch is refused with THROTTLE. After any change of parameters, mode ranges or sessions a switch
that reads "on" must be seen off before it arms (Betaflight's ARM switch rule), whichever surface made the
change: a CLI paste that moves the ARM range under the switch's low position and closes the session in the
same send (`exit`, `save`), MSP_SET_MODE_RANGE, the maintenance protocol. Flown on the simulator in
lockstep, the bytes going through the configuration links' servers as a client's would.
"""


from hoverfly.core.board import SERIAL_CONFIG, SERIAL_MAINT
from hoverfly.core.links.task import attach
from hoverfly.core.safety.arming import ARM_SWITCH, THROTTLE
from hoverfly.protocols import maintenance as mp
from hoverfly.protocols import msp
from hoverfly.sim.runner import SimRun
from hoverfly.sim.scenario import parse_scenario


def _events(r, name):
    return [e for e in r["events"] if e["event"] == name]


class ScriptedClient:
    """The sim board's serial seam: each (t_us, port, bytes) is read once the board's clock reaches t_us,
    all of it in one read (one send from the client); the replies are kept."""

    def __init__(self, board, script):
        self.board = board
        self.script = list(script)
        self.replies = {SERIAL_CONFIG: b"", SERIAL_MAINT: b""}

    def read(self, port, buf):
        for i, (t_us, p, data) in enumerate(self.script):
            if p == port and self.board.sim_us >= t_us:
                del self.script[i]
                buf[: len(data)] = data
                return len(data)
        return 0

    def write(self, port, data, n=-1):
        n = len(data) if n < 0 else n
        self.replies[port] += bytes(data[:n])
        return n


def _ground_run(script, duration_s=4.0, arm_at_s=None, storage_path=None):
    """The 5-inch on the ground, the pilot's arm switch low (1000 us) throughout (or moved high at
    arm_at_s), the configuration links attached (with a parameter store at storage_path) and a scripted
    client on them."""
    sc = parse_scenario("duration_s = %r\nmode = \"angle\"\n" % duration_s)
    run = SimRun("5inch", sc, seed=3)
    run.board.serial = ScriptedClient(run.board, script)
    storage = None
    if storage_path is not None:
        from hoverfly.core.config.storage import Storage

        run.board.storage_path = storage_path
        storage = Storage(run.board)
    links = attach(run.flight, storage)
    seen = {"flags": 0, "armed": False}

    def hook(r):
        if arm_at_s is not None and r.board.sim_us >= arm_at_s * 1e6:
            r.pilot.arm = True
        seen["flags"] |= r.flight.arming.flags
        seen["armed"] = seen["armed"] or r.flight.arming.armed
    run.on_step = hook
    return run, links, seen


# ------------------------------------------------------------------ the arming race (seed 000)
def test_throttle_and_switch_in_the_same_frame_is_refused_with_throttle():
    # given a craft ready to arm, when one receiver frame carries the throttle at 60 % and the arm
    # switch on together, then the request meets THROTTLE (not the 100 Hz task's flags of before the
    # frame, which had the throttle low) and the motors never spin
    run, _, seen = _ground_run([], duration_s=3.5)
    state = {"frame": None}

    def hook(r):
        if r.board.sim_us >= 3_000_000 and state["frame"] is None:
            r.pilot.throttle = 0.6
            r.pilot.arm = True
            state["frame"] = r.flight.rc.frames
            state["flags_before"] = r.flight.arming.flags
    run.on_step = hook
    r = run.run()
    assert state["flags_before"] & (1 << THROTTLE) == 0  # the slow task's reasons: throttle low, ready
    blocked = _events(r, "arming_blocked")
    assert blocked and blocked[0]["detail"].startswith("THROTTLE:"), r["events"]
    assert 3.0 <= blocked[0]["t_s"] <= 3.01
    assert not _events(r, "armed") and not r["armed"]
    assert r["outputs"]["frames"] > 0 and r["altitude_m"]["max"] < 0.01


def test_arming_race_scenario_throttle_up_with_the_switch_does_not_arm():
    # the same as a scenario: `arm` and `throttle` in one event (the pilot moves both at once)
    sc = parse_scenario("""
duration_s = 4
mode = "angle"
[[at]]
t = 3.0
arm = true
throttle = 0.6
""")
    r = SimRun("5inch", sc, seed=5).run()
    blocked = _events(r, "arming_blocked")
    assert blocked and blocked[0]["detail"].startswith("THROTTLE:"), r["events"]
    assert not _events(r, "armed") and r["altitude_m"]["max"] < 0.01


def test_switch_on_with_throttle_low_still_arms_on_its_frame():
    # the fresh look only adds reasons: a ready craft arms on the switch's frame as before
    sc = parse_scenario("duration_s = 3.5\nmode = \"angle\"\n[[at]]\nt = 3.0\narm = true\n")
    r = SimRun("5inch", sc, seed=5).run()
    armed = _events(r, "armed")
    assert armed and 3.0 <= armed[0]["t_s"] <= 3.01 and r["armed"]


# ------------------------------------------------------------------ arming after configuration
PASTE_EXIT = b"#\r\nset arm_min_us = 900\r\nexit\r\n"
PASTE_SAVE = b"#\r\nset arm_min_us = 900\r\nsave\r\n"


def _assert_never_armed_and_told_why(r, seen, client):
    assert not seen["armed"] and not _events(r, "armed"), r["events"]
    assert seen["flags"] & (1 << ARM_SWITCH)  # "arm switch was on: switch it off, then on"
    assert r["altitude_m"]["max"] < 0.01


def test_cli_paste_moving_the_arm_range_under_the_switch_then_exit_does_not_arm():
    # given the switch in its low position (1000 us, outside ARM 1700..2100), when a CLI client pastes
    # `set arm_min_us = 900` and `exit` in one send at 2.5 s, then the switch now reads "on" but has not
    # been seen off since the change: the craft does not arm, and ARMSWITCH says why
    run, links, seen = _ground_run([(2_500_000, SERIAL_CONFIG, PASTE_EXIT)])
    r = run.run()
    client = run.board.serial
    assert b"arm_min_us set to 900" in client.replies[SERIAL_CONFIG] or b"900" in client.replies[SERIAL_CONFIG]
    assert run.flight.params.get("arm_min_us") == 900 and run.flight.config_session == 0
    assert run.flight.rc.arm_switch  # the low position is inside the new range
    _assert_never_armed_and_told_why(r, seen, client)


def test_cli_paste_moving_the_arm_range_under_the_switch_then_save_does_not_arm(tmp_path):
    run, links, seen = _ground_run([(2_500_000, SERIAL_CONFIG, PASTE_SAVE)], storage_path=str(tmp_path / "p.bin"))
    r = run.run()
    assert b"Saving" in run.board.serial.replies[SERIAL_CONFIG]
    assert (tmp_path / "p.bin").exists()
    assert run.flight.params.get("arm_min_us") == 900 and run.flight.config_session == 0
    assert run.flight.rc.arm_switch
    _assert_never_armed_and_told_why(r, seen, run.board.serial)


def test_after_a_cli_change_the_switch_toggled_off_and_on_arms():
    # the rule asks for a toggle, nothing more: with ARM moved to 1300..2100 (the low position stays off),
    # a switch moved high after the paste arms; one held high through the paste needs off, then on
    paste = b"#\r\nset arm_min_us = 1300\r\nexit\r\n"
    run, _, seen = _ground_run([(2_500_000, SERIAL_CONFIG, paste)], duration_s=3.5, arm_at_s=3.0)
    r = run.run()
    armed = _events(r, "armed")
    assert armed and 3.0 <= armed[0]["t_s"] <= 3.01


def test_a_switch_held_on_through_a_configuration_change_must_be_toggled():
    # given the switch on (blocked by the open session), when the session closes, then switching it on
    # is not enough: it is seen off first, and then it arms
    sc = parse_scenario("""
duration_s = 5
mode = "angle"
[[at]]
t = 2.0
config_session = 1
[[at]]
t = 2.2
arm = true
[[at]]
t = 2.5
config_session = 0
[[at]]
t = 3.5
arm = false
[[at]]
t = 4.0
arm = true
""")
    r = SimRun("5inch", sc, seed=5).run()
    armed = _events(r, "armed")
    assert armed and 4.0 <= armed[0]["t_s"] <= 4.01, r["events"]


def test_msp_set_mode_range_moving_arm_under_the_switch_does_not_arm():
    # given the switch low, when a configurator sends MSP_SET_MODE_RANGE putting ARM (box 0) on AUX1 over
    # 900..2100 (steps 0..48), then the switch reads on but the craft does not arm
    payload = bytes([0, 0, 0, 0, 48])
    req = msp.encode_request(msp.MSP_SET_MODE_RANGE, payload)
    run, _, seen = _ground_run([(2_500_000, SERIAL_CONFIG, req)])
    r = run.run()
    assert run.flight.params.get("arm_min_us") == 900, run.board.serial.replies
    assert run.flight.rc.arm_switch
    _assert_never_armed_and_told_why(r, seen, run.board.serial)


def test_a_maintenance_write_in_the_frame_of_the_switch_must_be_followed_by_a_toggle():
    # given a ready craft, when a maintenance client's PID write is served and the very next receiver
    # frame carries the switch on (no 100 Hz look between them), then the request sees a parameter change
    # not yet applied: refused until the switch is seen off; off and on again, it arms
    sc = parse_scenario("duration_s = 4.5\nmode = \"angle\"\n")
    run = SimRun("5inch", sc, seed=3)
    p = run.flight.params
    frame = mp.encode_request((), mp.CMD_SET_ROLL_PID, (p.get("p_roll") + 1, p.get("i_roll"), p.get("pid_kt_roll"),
                                                         p.get("iterm_limit"), p.get("pid_ad_roll"), p.get("d_roll")))
    run.board.serial = ScriptedClient(run.board, [])
    links = attach(run.flight)
    f = run.flight
    arming_task = [t for t in f.scheduler.tasks if t.name == "arming"][0]
    state = {"sent": None}

    def hook(r):
        t = r.board.sim_us
        if state["sent"] is None and t >= 3_000_000 and arming_task.next_us - f._last_us >= 4000:
            # served now, as the links task would, and the switch on in the next frame
            changed = f.params.changed
            links.config.feed(frame, len(frame), lambda data, n=-1: None)
            assert f.params.changed != changed, "the maintenance write was not taken"
            r.pilot.arm = True
            state["sent"] = t
        if t >= 3_500_000 and t < 3_600_000:
            r.pilot.arm = False
        if t >= 4_000_000:
            r.pilot.arm = True
    run.on_step = hook
    r = run.run()
    armed = _events(r, "armed")
    assert state["sent"] is not None
    assert armed and armed[0]["t_s"] >= 4.0, r["events"]
