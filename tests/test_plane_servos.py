"""A plane's servos through the whole chain: the pilot's sticks -> receiver -> controller -> servo mixer ->
the board's output codec -> the simulated servos -> JSBSim's surfaces, flown in lockstep and judged as a
pilot checks a plane: each stick moves the right surface the right way and the plane answers; disarmed
and in the output failsafe the surfaces sit at their servos' centres; the flight log and its report show
the servos."""

import math

import pytest

from hoverfly.sim.runner import SimRun
from test_micropython import MICROPYTHON

pytest.importorskip("jsbsim")


def _scenario(tmp_path, airframe, events, params=None, start=True, duration_s=4.0):
    lines = ['name = "servo-check"', 'description = "sticks one at a time"', 'airframe = "%s"' % airframe,
             "duration_s = %s" % duration_s, 'mode = "acro"', "", "[params]", "small_angle = 180"]
    for k, v in (params or {}).items():
        lines.append("%s = %s" % (k, v))
    if start:
        lines += ["", "[start]", "altitude_m = 100", "airspeed_m_s = 14"]
    for t, ev in events:
        lines += ["", "[[at]]", "t = %s" % t]
        for k, v in ev.items():
            lines.append("%s = %s" % (k, str(v).lower() if isinstance(v, bool) else v))
    path = tmp_path / ("%s-servos.toml" % airframe)
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def _fly(path, airframe, log_path=None, firmware="cpython"):
    """Fly it; returns (run, result, samples): per pass (t_s, armed, servo widths on the wire, roll deg, the
    motor's command as its ESC read it)."""
    run = SimRun(airframe, path, log_path=log_path, firmware=firmware, micropython=MICROPYTHON)
    samples = []

    def on_step(r):
        b = r.board
        samples.append((b.sim_us * 1e-6, r.flight.arming.armed, list(b.output.servo_us[:4]),
                        math.degrees(r.vehicle.roll_rad), b.motor_cmd[0]))

    run.on_step = on_step
    result = run.run()
    return run, result, samples


def _at(samples, t_s):
    for s in samples:
        if s[0] >= t_s:
            return s
    return samples[-1]


ARM = (1.5, {"arm": True})


def test_trainer_each_stick_moves_its_own_surface_the_right_way_and_the_plane_answers(tmp_path):
    # roll right, then the stick back (pitch is forward-positive on the transmitter: back = nose up), then
    # yaw right; each held 0.3 s
    path = _scenario(tmp_path, "trainer", [ARM, (2.0, {"roll": 0.4}), (2.3, {"roll": 0.0, "pitch": -0.4}),
                                           (2.6, {"pitch": 0.0, "yaw": 0.4}), (2.9, {"yaw": 0.0})])
    run, result, samples = _fly(path, "trainer", log_path=str(tmp_path / "servos.ulg"))
    assert run.flight.servos.count == 3 and not result["crashed"]
    level = _at(samples, 1.9)
    assert level[1] and all(abs(w - 1500) < 15 for w in level[2][:3])
    aileron = _at(samples, 2.25)[2]
    assert aileron[0] > 1530 and abs(aileron[1] - 1500) < 20 and abs(aileron[2] - 1500) < 20
    assert _at(samples, 2.3)[3] > level[3] + 5.0  # and the plane rolls right
    elevator = _at(samples, 2.55)[2]
    assert elevator[1] > 1530 and abs(elevator[0] - 1500) < 20
    rudder = _at(samples, 2.85)[2]
    assert rudder[2] > 1530 and abs(rudder[1] - 1500) < 20
    # the log carries actuator_servos and the report plots them
    from hoverfly.logs.data import load
    from hoverfly.logs.report import write_report

    run.close()
    log = load(str(tmp_path / "servos.ulg"))
    sv = log.topic("actuator_servos")
    assert sv is not None and len(sv["t_s"]) > 50
    assert 1500 + 500 * sv["control[0]"].max() > 1530 and not sv["control[3]"].any()
    out = write_report(log, str(tmp_path / "report"))
    assert any(p.endswith("servos.png") for p in out["plots"])


def test_wing_elevons_mix_roll_and_pitch_the_way_its_wiring_takes_them(tmp_path):
    path = _scenario(tmp_path, "wing", [ARM, (2.0, {"roll": 0.4}), (2.3, {"roll": 0.0, "pitch": -0.4}),
                                        (2.6, {"pitch": 0.0})], duration_s=3.0)
    run, result, samples = _fly(path, "wing")
    assert run.flight.servos.count == 2 and not result["crashed"]
    roll = _at(samples, 2.25)[2]
    assert roll[0] < 1480 and roll[1] > 1520  # roll right: left elevon down, right elevon up
    assert _at(samples, 2.3)[3] > _at(samples, 1.9)[3] + 5.0
    pitch = _at(samples, 2.55)[2]
    assert pitch[0] > 1510 and pitch[1] > 1510  # nose up: both trailing edges up


def test_disarmed_surfaces_sit_at_their_centres_whatever_the_sticks(tmp_path):
    path = _scenario(tmp_path, "trainer", [(1.5, {"roll": 0.8, "pitch": 0.8, "yaw": 0.8})],
                     params={"servo1_mid_us": 1540}, start=False, duration_s=2.5)
    run, result, samples = _fly(path, "trainer")
    assert not any(s[1] for s in samples)
    assert all(s[2][:3] == [1500, 1540, 1500] for s in samples if s[0] > 0.01)


def test_disarmed_in_manual_the_surfaces_follow_the_sticks_for_a_preflight_check_and_the_motor_stays_stopped(
        tmp_path):
    # INAV's preflight check: MANUAL on AUX4 (channel 8), disarmed on the ground, each stick in turn
    events = [(1.2, {"channel": "{ ch = 8, us = 1900 }"}), (1.5, {"roll": 0.6}), (1.8, {"roll": 0.0, "yaw": -0.6}),
              (2.1, {"yaw": 0.0})]
    path = _scenario(tmp_path, "trainer", events, params={"manual_ch": 8}, start=False, duration_s=2.5)
    run, result, samples = _fly(path, "trainer")
    assert not any(s[1] for s in samples)
    assert _at(samples, 1.1)[2][:3] == [1500, 1500, 1500]  # before MANUAL: centred
    assert _at(samples, 1.75)[2][0] > 1600 and _at(samples, 2.05)[2][2] < 1400
    assert all(s[4] == 0.0 for s in samples)


def test_output_failsafe_puts_each_servo_at_its_own_centre_and_the_stick_comes_back_after(tmp_path):
    path = _scenario(tmp_path, "trainer", [ARM, (2.0, {"roll": 0.5}), (2.2, {"stall_ms": 300})],
                     params={"servo0_mid_us": 1520}, duration_s=3.0)
    run, result, samples = _fly(path, "trainer")
    assert _at(samples, 2.15)[2][0] > 1560
    trips = [e for e in result["events"] if e["event"] == "output_failsafe"]
    assert trips and trips[0]["t_s"] == pytest.approx(2.3, abs=0.01)  # 100 ms after the last command
    held = [s for s in samples if 2.31 <= s[0] <= 2.49]
    assert held and all(s[2][:3] == [1520, 1500, 1500] for s in held)
    assert _at(samples, 2.7)[2][0] > 1560  # commands resumed: the aileron is the stick's again


@pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")
def test_the_firmware_in_the_micropython_vm_drives_the_same_surfaces(tmp_path):
    # the core in the VM (its generated viper servo kernel), its widths over the firmware bridge to the same servos
    events = [ARM, (2.0, {"roll": 0.4}), (2.3, {"roll": 0.0, "pitch": -0.4}), (2.6, {"pitch": 0.0})]
    path = _scenario(tmp_path, "trainer", events, duration_s=3.0)
    _, result, vm = _fly(path, "trainer", firmware="micropython")
    _, _, host = _fly(path, "trainer")
    assert result["firmware_runtime"] == "micropython" and not result["crashed"]
    for t in (1.9, 2.25, 2.55, 2.9):
        a = _at(vm, t)[2][:3]
        b = _at(host, t)[2][:3]
        assert all(abs(x - y) <= 10 for x, y in zip(a, b, strict=True)), (t, a, b)
    assert _at(vm, 2.25)[2][0] > 1530 and _at(vm, 2.55)[2][1] > 1530
