"""Safety flight tests (issue 5): failsafe timing and landing, arming reasons, seed 004's autopilot.

Flown in lockstep on the simulator with a fixed seed and judged as a pilot would.
"""

import pytest

from hoverfly.core.safety.arming import REASONS, reason_bit
from hoverfly.sim.runner import SimRun, fly
from hoverfly.sim.scenario import parse_scenario

AIRFRAMES = ("5inch", "f450")


def _events(r, name):
    return [e for e in r["events"] if e["event"] == name]


def _t(r, name):
    ev = _events(r, name)
    return ev[0]["t_s"] if ev else None


class Trace:
    """Altitude and position after a time, sampled every pass."""

    def __init__(self, run, after_s):
        self.after_s = after_s
        self.rows = []
        run.on_step = self

    def __call__(self, run):
        t = run.board.sim_us * 1e-6
        if t >= self.after_s:
            v = run.vehicle
            self.rows.append((t, v.altitude_m(), v.pn, v.pe, v.tilt_rad(), run.flight.arming.armed))


@pytest.mark.parametrize("airframe", AIRFRAMES)
def test_rx_loss_mid_hover_lands_level_on_time_without_climb_or_drift(airframe):
    run = SimRun(airframe, "rx-loss", seed=7)
    trace = Trace(run, 7.0)  # the receiver stops at 7.0 s
    r = run.run()
    last_frame = _t(r, "rx_lost")  # recorded at the time of the last valid frame
    assert last_frame is not None and 6.9 <= last_frame <= 7.0
    assert _t(r, "failsafe_stage1") - last_frame <= 0.150
    assert abs(_t(r, "failsafe_stage2") - last_frame - 0.500) <= 0.050
    assert _t(r, "landed") is not None
    assert [e["detail"] for e in _events(r, "disarmed")] == ["landed"]
    assert not r["crashed"] and not r["armed"]
    t0, alt0, n0, e0, _, _ = trace.rows[0]
    assert max(row[1] for row in trace.rows) <= alt0 + 1.0
    assert max(((row[2] - n0) ** 2 + (row[3] - e0) ** 2) ** 0.5 for row in trace.rows) <= 5.0
    touchdown = [row for row in trace.rows if row[1] <= 0.01][0]
    assert touchdown[4] * 57.3 <= 10.0  # level when it touches down
    assert run.vehicle.impact_m_s <= 2.0


def test_drop_disarms_at_stage_two():
    r = fly("failsafe-drop", "5inch", seed=7)
    stage2 = _t(r, "failsafe_stage2")
    assert abs(stage2 - _t(r, "rx_lost") - 0.5) <= 0.05
    disarm = _events(r, "disarmed")
    assert disarm[0]["detail"] == "failsafe" and disarm[0]["t_s"] == stage2


def test_short_dropout_ends_in_stage_one_and_restored_link_does_not_take_over_a_landing():
    r = fly("rx-restore", "5inch", seed=7)
    ends = _events(r, "failsafe_end")
    assert ends[0]["t_s"] < 6.3 and ends[0]["detail"] == "0"  # 250 ms dropout: stage 1 only
    assert _t(r, "failsafe_stage2") == pytest.approx(8.5, abs=0.05)
    # the link is back at 9.5 s, but the landing goes on until the pilot moves a stick at 10 s
    assert ends[1]["detail"] == "1" and 10.0 <= ends[1]["t_s"] <= 10.1
    assert r["armed"] and not r["crashed"]


@pytest.mark.parametrize("airframe", AIRFRAMES)
def test_frozen_imu_in_flight_disarms_not_a_flyaway(airframe):
    r = fly("imu-freeze", airframe, seed=7)
    assert _t(r, "imu_fault") <= 6.0 + 0.035
    assert _events(r, "disarmed")[0]["detail"] == "imu_fault"
    assert r["altitude_m"]["max"] < 2.0 and r["altitude_m"]["final"] < 0.05


def test_imu_stuck_on_one_sample_is_an_imu_fault():
    sc = parse_scenario("""
duration_s = 6
[[at]]
t = 2.0
arm = true
[[at]]
t = 2.5
hold_altitude_m = 1.0
[[at]]
t = 5.0
imu_stuck = true
""")
    r = fly(sc, "5inch", seed=7)
    fault = _events(r, "imu_fault")
    assert fault and fault[0]["detail"] == "imu_frozen" and fault[0]["t_s"] <= 5.15
    assert not r["armed"]


def test_arming_refusals_scenario_names_each_reason_then_arms():
    r = fly("arming-refusals", "5inch", seed=7)
    blocked = [e["detail"].split(":")[0] for e in _events(r, "arming_blocked")]
    assert blocked == ["BOOTGRACE", "THROTTLE", "CLI", "MSP", "MAINTENANCE", "BATTERY", "ANGLE", "NOGYRO"]
    assert _t(r, "autopilot_enabled") is not None  # in autopilot mode the switch enables, never arms
    armed = _events(r, "armed")
    assert len(armed) == 1 and armed[0]["t_s"] >= 8.0


# Each reason the flight sets from its own state, with what makes it true (after boot, disarmed).
_CONDITIONS = {
    "CLI": lambda r: setattr(r.flight, "config_session", 1),
    "MSP": lambda r: setattr(r.flight, "config_session", 2),
    "MAINTENANCE": lambda r: setattr(r.flight, "config_session", 4),
    "MOTOR_TEST": lambda r: setattr(r.flight.motor_test, "active", True),
    "BIT": lambda r: setattr(r.flight.bit, "storage_ok", False),
    "LOAD": lambda r: setattr(r.flight.faults, "_period_us", 10),  # the loop "should" run at 100 kHz
    "RXLOSS": lambda r: setattr(r.flight, "rx_ok", False),
    "THROTTLE": lambda r: setattr(r.pilot, "throttle", 0.5),
    "BATTERY": lambda r: setattr(r.flight.supervisor, "_vbat_min_cell_v", 4.3),
    "ANGLE": lambda r: setattr(r.flight.arming, "small_angle_cos", 1.01),
    "CALIB": lambda r: r.flight.calibration.reset(),
    "AUTOPILOT": lambda r: r.pilot.overrides_us.__setitem__(6, 2000),
    "FAILSAFE": lambda r: setattr(r.flight.failsafe, "state", 1) or setattr(r.flight.failsafe, "update", _noop),
    "CRASH": lambda r: setattr(r.flight.supervisor, "_crash_latched", True) or setattr(r.flight.rc, "arm_switch", True),
}


def _noop(*args):
    return None


@pytest.mark.parametrize("name", sorted(_CONDITIONS))
def test_every_arming_reason_blocks_and_is_named(name):
    run = SimRun("5inch", "hover", seed=1, duration_s=2.5)  # the pilot arms at 2.0 s
    state = {"flags": 0}
    bit = reason_bit(name)

    def hook(r):
        f = r.flight
        if r.board.sim_us >= 1_900_000:
            _CONDITIONS[name](r)
            state["flags"] |= f.arming.flags
    run.on_step = hook
    r = run.run()
    assert bit >= 0 and state["flags"] & (1 << bit), name
    assert not r["armed"], name
    # In autopilot mode the switch enables instead of arming; during a failsafe it is not read at all.
    if name not in ("AUTOPILOT", "FAILSAFE"):
        blocked = _events(r, "arming_blocked")
        assert blocked and blocked[0]["detail"].startswith(name + ":"), (name, r["events"])
        assert REASONS[bit][1] in blocked[0]["detail"]


# ------------------------------------------------------------------ seed 004: the autopilot
@pytest.fixture(scope="module")
def autopilot_run():
    run = SimRun("5inch", "autopilot", seed=7)
    samples = []

    def hook(r):
        f = r.flight
        samples.append((r.board.sim_us * 1e-6, f.autopilot.state, f.autopilot.privilege(),
                        f.signals.setpoint.throttle_norm, f.rc.throttle_raw, f.autopilot.throttle_norm,
                        f.autopilot.latch_norm, f.arming.armed, r.vehicle.altitude_m()))
    run.on_step = hook
    return run.run(), samples


def _at(samples, t):
    return min(samples, key=lambda s: abs(s[0] - t))


def test_autopilot_msp_flood_and_arming_refused_before_the_procedure(autopilot_run):
    r, samples = autopilot_run
    # 0.5 .. 1.8 s: 100 Hz of valid-looking MSP RC, an arm request among them: nothing armed, no privilege
    assert all(not s[7] and s[2] == 0 for s in samples if s[0] < 2.2)
    refused = r["autopilot"]["refused"]
    assert refused["autopilot switch is off"] >= 100
    assert any("arm switch on after the autopilot switch" in k for k in refused)
    assert _t(r, "autopilot_enabled") == pytest.approx(2.2, abs=0.02)
    armed = _events(r, "armed")
    assert armed[0]["detail"] == "autopilot" and armed[0]["t_s"] >= 2.45


def test_autopilot_soft_override_roll_and_throttle_cap(autopilot_run):
    r, samples = autopilot_run
    details = [(e["t_s"], e["detail"]) for e in _events(r, "autopilot_override")]
    assert any(d == "roll" and 7.0 <= t < 7.1 for t, d in details)
    assert any(d == "throttle_cap" and 8.5 <= t < 8.6 for t, d in details)
    s = _at(samples, 8.8)  # the pilot's stick at 0.15 caps the autopilot's throttle
    assert s[3] <= 0.16 and s[5] > 0.2


def test_autopilot_hard_override_latches_throttle_until_the_stick_comes_down(autopilot_run):
    r, samples = autopilot_run
    hard = [e["t_s"] for e in _events(r, "autopilot_override") if e["detail"] == "hard"]
    assert hard and hard[0] == pytest.approx(12.0, abs=0.02)
    during = [s for s in samples if 12.1 <= s[0] < 13.5]
    assert all(s[7] for s in during)  # still armed after the autopilot switch went off
    latch = during[0][6]
    assert latch > 0.2
    assert all(s[4] >= 0.89 and abs(s[3] - latch) < 1e-6 for s in during)  # stick at 0.9, throttle held
    released = [e["t_s"] for e in _events(r, "autopilot_override") if e["detail"] == "latch_released"]
    assert released[0] == pytest.approx(13.5, abs=0.02)
    assert _at(samples, 13.55)[6] < 0.0


def test_silent_autopilot_hands_back_to_the_pilot_and_arm_switch_off_disarms(autopilot_run):
    r, samples = autopilot_run
    timeouts = [e["t_s"] for e in _events(r, "autopilot_disabled") if e["detail"] == "timeout"]
    assert timeouts and 24.15 <= timeouts[0] <= 24.25  # ap_timeout_ms = 200 after its last frame
    s = _at(samples, 24.5)
    assert s[7] and s[6] >= 0.0 and s[2] & 16  # pilot flies with the throttle latched
    last = _events(r, "disarmed")[-1]
    assert last["detail"] == "switch" and last["t_s"] == pytest.approx(28.5, abs=0.05)
    assert not r["crashed"] and not r["armed"]


@pytest.mark.parametrize("scenario", ["autopilot", "rx-loss", "rx-restore"])
def test_who_flies_word_always_agrees_with_the_failsafe_and_autopilot_states(scenario):
    # The commander flies the pilot's sticks without looking further while its source word is 0; the failsafe
    # writes its bit at each change of stage, the commander the autopilot's after each call that can change it.
    # At the end of every pass the word must say what the failsafe and autopilot states say, through a whole
    # scenario of autopilot enabling, overrides, latches, silence, link loss and restore.
    from hoverfly.core.command.autopilot import AP_ENABLED
    from hoverfly.core.command.commander import SOURCE_AUTOPILOT, SOURCE_FAILSAFE
    from hoverfly.core.safety.failsafe import IDLE

    run = SimRun("5inch", scenario, seed=3)
    seen = set()

    def hook(r):
        f = r.flight
        ap = f.autopilot
        truth = 0
        if f.failsafe.state != IDLE:
            truth |= SOURCE_FAILSAFE
        if ap.state == AP_ENABLED or ap.latch_norm >= 0.0:
            truth |= SOURCE_AUTOPILOT
        assert f.commander.source == truth, (r.board.sim_us, f.failsafe.state, ap.state, ap.latch_norm)
        seen.add(truth)

    run.on_step = hook
    run.run()
    assert 0 in seen and len(seen) > 1  # the pilot alone, and some other source, both flew
