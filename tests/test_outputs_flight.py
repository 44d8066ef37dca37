"""Flight tests through the motor wires: every ESC protocol, the output failsafe, eRPM, motor test.

The simulated ESCs decode the frames or pulse widths the flight core's output codec puts on
the wire (sim/esc.py), so these flights exercise the wire both ways.
"""

import json
import math

import pytest

from hoverfly.cli import main
from hoverfly.core.stages.output import PROTOCOLS
from hoverfly.sim.runner import SimRun, fly
from hoverfly.sim.scenario import parse_scenario

HOVER_AND_STEP = """
name = "hover-step"
duration_s = 6.2
mode = "angle"
[[at]]
t = 2.0
arm = true
[[at]]
t = 2.5
hold_altitude_m = 2.0
[[at]]
t = 4.8
step = { axis = "roll", to = 20, unit = "deg" }
[[at]]
t = 5.5
step = { axis = "roll", to = 0, unit = "deg" }
"""


def _stall(at_s, ms, duration_s=5.5):
    return parse_scenario("""
duration_s = %g
mode = "angle"
[[at]]
t = 2.0
arm = true
[[at]]
t = 2.5
hold_altitude_m = 2.0
[[at]]
t = %g
stall_ms = %g
""" % (duration_s, at_s, ms))


@pytest.mark.parametrize("esc", PROTOCOLS)
def test_hover_and_roll_step_fly_with_every_esc_protocol(esc, tmp_path, capsys):
    path = tmp_path / "hover-step.toml"
    path.write_text(HOVER_AND_STEP)
    assert main(["fly", "--esc", esc, "--scenario", str(path), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert not r["crashed"]
    assert abs(r["altitude_m"]["final"] - 2.0) < 0.5
    steps = [s for s in r["steps"] if s["axis"] == "roll"]
    assert len(steps) == 2
    for s in steps:
        assert s["t90_ms"] is not None and s["t90_ms"] <= 200.0, s
        assert s["overshoot_pct"] <= 10.0, s
    out = r["outputs"]
    assert out["esc"] == esc
    assert out["frames"] >= 4 * 6200 and out["errors"] == 0  # every frame read by the ESCs
    assert out["failsafe_trips"] == 0


def test_unknown_esc_is_refused_in_one_line(capsys):
    assert main(["fly", "--esc", "dshot9000"]) == 2
    assert "dshot9000" in capsys.readouterr().err


def test_output_failsafe_cuts_the_motors_100_ms_into_a_controller_stall():
    run = SimRun("5inch", _stall(4.5, 400.0), seed=7)
    trace = []
    run.on_step = lambda r: trace.append((r.board.sim_us * 1e-6, max(r.board.motor_cmd), r.vehicle.vd))
    result = run.run()
    fs = [e for e in result["events"] if e["event"] == "output_failsafe"]
    assert len(fs) == 2, fs
    # The last pass ran at 4.499 s; 100 ms later (to the output timer's 1 ms tick) every output is stop.
    assert fs[0]["t_s"] == pytest.approx(4.6, abs=0.002)
    assert fs[1]["detail"] == "commands resumed" and fs[1]["t_s"] == pytest.approx(4.9, abs=0.002)
    before = [m for t, m, _ in trace if 4.4 <= t < 4.59]
    during = [m for t, m, _ in trace if 4.602 <= t < 4.899]
    assert min(before) > 0.2  # hovering on the last command right up to the cut
    assert max(during) == 0.0  # every motor stopped
    down_m_s = {round(t, 3): vd for t, _, vd in trace}
    assert down_m_s[4.899] - down_m_s[4.6] > 2.0  # and the craft falls: 0.3 s at nearly 1 g
    assert result["outputs"]["failsafe_trips"] == 1
    assert not result["crashed"]  # the pass came back in time to catch it


def test_output_failsafe_follows_its_parameter_on_analog_escs():
    sc = _stall(4.5, 300.0)
    sc["params"] = {"output_fs_ms": 50}
    r = fly(sc, "5inch", seed=7, esc="pwm")
    fs = [e for e in r["events"] if e["event"] == "output_failsafe"]
    assert fs and fs[0]["t_s"] == pytest.approx(4.55, abs=0.002)


def test_a_stall_shorter_than_the_failsafe_time_keeps_the_motors_running():
    r = fly(_stall(4.5, 80.0), "5inch", seed=7)
    assert not [e for e in r["events"] if e["event"] == "output_failsafe"]
    assert r["outputs"]["failsafe_trips"] == 0


def test_bidirectional_dshot_reports_the_rotor_speed():
    run = SimRun("5inch", "hover", seed=7, overrides=[("dshot_bidir", "1")], duration_s=4.0)
    r = run.run()
    assert not r["crashed"] and r["outputs"]["bidir"]
    rpm_true = [w * 60.0 / (2.0 * math.pi) for w in run.vehicle.omega]
    rpm = list(run.flight.signals.motor_rpm[:4])
    for got, want in zip(rpm, rpm_true, strict=True):
        assert got == pytest.approx(want, rel=0.01)  # one loop old, 9-bit period mantissa
    assert run.flight.output.reply_errors == 0 and run.flight.output.replies > 4 * 3500
    # eRPM = RPM x pole pairs (14 poles)
    assert run.flight.signals.motor_erpm[0] == pytest.approx(rpm[0] * 7, abs=7)


def test_frames_cross_the_pulse_train_model_both_ways():
    run = SimRun("5inch", "hover", seed=7, overrides=[("dshot_bidir", "1")], duration_s=3.4)
    run.board.set_escs("dshot600", 14, line=True)
    r = run.run()
    assert not r["crashed"] and r["altitude_m"]["max"] > 0.2  # took off
    assert r["outputs"]["errors"] == 0
    assert run.flight.output.reply_errors == 0 and max(run.flight.signals.motor_rpm[:4]) > 5000


def test_oneshot_frames_cross_the_pulse_train_model():
    run = SimRun("5inch", "hover", seed=7, duration_s=3.4, esc="oneshot125")
    run.board.set_escs("oneshot125", line=True)
    r = run.run()
    assert not r["crashed"] and r["altitude_m"]["max"] > 0.2 and r["outputs"]["errors"] == 0


def test_boot_turns_3d_mode_off_so_escs_left_in_3d_fly_normally():
    run = SimRun("5inch", "hover", seed=7, duration_s=4.5)
    run.board.set_escs("dshot600", mode_3d=True)
    r = run.run()
    assert all(not e.mode_3d for e in run.board.escs)
    assert not r["crashed"] and abs(r["altitude_m"]["final"] - 2.0) < 0.6


def test_reversed_motors_get_the_spin_direction_command_on_their_own_line():
    run = SimRun("5inch", "hover", seed=7, duration_s=1.0, overrides=[("motor_reversed", "5"),
                                                                       ("motor_order", "2143")])
    run.run()
    # motors 1 and 3 reversed; motor 1 is on output 2, motor 3 on output 4 (ESCs listed by output)
    assert [e.spin_reversed for e in run.board.escs] == [False, True, False, True]


def test_motor_order_remap_still_flies():
    r = fly("hover", "5inch", seed=7, overrides=[("motor_order", "3412")], duration_s=4.5)
    assert not r["crashed"] and r["tilt_rms_deg"] < 1.5


def test_motor_test_on_the_bench_spins_one_motor_and_expires():
    sc = parse_scenario('duration_s = 3\nmode = "angle"\n')
    run = SimRun("5inch", sc, seed=1)
    answers = []
    motors = {}

    def bench(r):
        t = round(r.board.sim_us * 1e-6, 3)
        if t == 1.5:
            answers.append(r.flight.motor_test.request(r.board.now_us(), 2, 0.15, True))
        motors[t] = list(r.board.motor_cmd)

    run.on_step = bench
    run.run()
    assert answers == [None]
    assert motors[2.0][2] == pytest.approx(0.15, abs=0.001)  # decoded by its ESC
    assert motors[2.0][0] == motors[2.0][1] == motors[2.0][3] == 0.0
    assert motors[2.5][2] > 0.0  # 1 s after the request: still on
    assert motors[2.502][2] == 0.0  # not refreshed: expired
    assert not run.flight.motor_test.active
