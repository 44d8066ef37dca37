"""The fixed-wing physics (sim/plane.py on JSBSim): the models fly like their class, deterministically,
with the quad physics' signs and frames, and bad airframe files are refused with one line.

Open-loop: scripted surfaces and throttle; the closed-loop flights wait for the fixed-wing core."""

import json
import math

import pytest

from hoverfly.cli import main
from hoverfly.errors import UserError
from hoverfly.sim import plane as P
from hoverfly.sim.airframes import load_airframe
from hoverfly.sim.physics import Vehicle
from hoverfly.sim.sensors import ImuModel

pytest.importorskip("jsbsim")

_CRUISE = {"trainer": 13.0, "wing": 16.0}


@pytest.fixture(scope="module", params=["trainer", "wing"])
def plane(request):
    return P.Plane(load_airframe(request.param), 1000)


def _name(plane):
    return plane.airframe["name"]


def _fly(plane, seconds, throttle=0.0):
    for _ in range(int(seconds / plane.dt_s)):
        plane.step(plane.dt_s, (throttle,))


# --------------------------------------------------------------------------- flying qualities
def test_with_the_elevator_centred_each_model_trims_to_its_class_cruise_speed_wings_level(plane):
    g = P.glide(plane, seconds=30.0, settle_s=15.0)
    lo, hi = {"trainer": (11.0, 15.0), "wing": (14.0, 19.0)}[_name(plane)]
    assert lo <= g["airspeed_m_s"] <= hi
    assert abs(g["bank_deg"]) < 2.0  # a symmetric model does not wander off into a bank


def test_the_best_power_off_glide_ratio_is_what_such_airplanes_glide(plane):
    elevator = {"trainer": -0.1, "wing": -0.15}[_name(plane)]
    g = P.glide(plane, elevator=elevator, seconds=30.0, settle_s=15.0)
    lo, hi = {"trainer": (8.0, 12.0), "wing": (6.0, 10.0)}[_name(plane)]
    assert lo <= g["glide_ratio"] <= hi
    # the best glide is slower than the trim speed and well above the stall
    assert plane.airframe["stall_speed_m_s"] < g["airspeed_m_s"] < _CRUISE[_name(plane)]


def test_easing_the_elevator_back_stalls_the_wing_at_its_class_stall_speed(plane):
    s = P.stall(plane)
    lo, hi = {"trainer": (6.5, 8.5), "wing": (7.0, 9.5)}[_name(plane)]
    assert lo <= s["stall_speed_m_s"] <= hi
    assert 10.0 <= s["alpha_deg"] <= 16.0  # the lift peaks at a low-Reynolds section's stall angle
    assert abs(s["stall_speed_m_s"] - plane.airframe["stall_speed_m_s"]) < 0.3  # what the judging uses


def test_full_aileron_rolls_both_ways_at_a_class_roll_rate(plane):
    right = P.roll_rate(plane, _CRUISE[_name(plane)])
    left = P.roll_rate(plane, _CRUISE[_name(plane)], direction=-1.0)
    lo, hi = {"trainer": (120.0, 240.0), "wing": (200.0, 360.0)}[_name(plane)]
    assert lo <= right["roll_rate_dps"] <= hi
    assert right["bank_at_0_3_s_deg"] > 30.0
    assert left["roll_rate_dps"] == pytest.approx(-right["roll_rate_dps"], rel=0.02)


def test_power_makes_it_climb_and_none_makes_it_sink(plane):
    cruise = _CRUISE[_name(plane)]
    climbing = P.level_flight(plane, cruise, 0.5, seconds=6.0)
    gliding = P.level_flight(plane, cruise, 0.0, seconds=6.0)
    assert climbing["climb_m_s"] > 2.0
    assert gliding["climb_m_s"] < -0.5
    assert abs(climbing["bank_deg"]) < 5.0  # a steep climb, but no spiral


# --------------------------------------------------------------------------- determinism
def _trace(name, seed):
    plane = P.Plane(load_airframe(name), 1000)
    plane.reset(altitude_m=100.0, airspeed_m_s=_CRUISE[name])
    imu = ImuModel(plane.airframe["imu"], seed, 1000, plane.hover_omega(), 1)
    gyro = [0.0] * 3
    accel = [0.0] * 3
    out = []
    for k in range(1500):
        plane.servo_pos[0] = 0.5 if 300 <= k < 600 else 0.0
        plane.step(plane.dt_s, (0.3,))
        imu.sample(plane, gyro, accel)
        out.append((plane.p, plane.fz, plane.pn, gyro[0], accel[2]))
    return out


def test_a_flight_is_the_same_for_the_same_seed_and_its_sensor_noise_differs_by_seed():
    a = _trace("trainer", 3)
    assert a == _trace("trainer", 3)
    b = _trace("trainer", 4)
    assert [x[:3] for x in a] == [x[:3] for x in b]  # the physics has no randomness of its own
    assert [x[3:] for x in a] != [x[3:] for x in b]  # the IMU's noise and bias come from the seed


# --------------------------------------------------------------------------- signs and frames
def test_at_rest_on_its_belly_the_imu_reads_what_a_level_quad_on_the_ground_reads(plane):
    plane.reset()
    _fly(plane, 1.0)
    assert plane.on_ground and not plane.crashed
    assert plane.fz == pytest.approx(-9.81, abs=0.15)  # FRD: the accelerometer reads -g on z
    assert abs(plane.fx) < 0.5 and abs(plane.fy) < 0.2
    assert abs(plane.p) < 0.05 and abs(plane.q) < 0.05 and abs(plane.r) < 0.05  # settled on its contacts
    assert 0.0 <= plane.altitude_m() < 0.1
    quad = Vehicle(load_airframe("5inch"), "quadx")
    quad.reset()
    quad.step(0.001, [0.0] * 4)
    assert plane.fz == pytest.approx(quad.fz, abs=0.15)


def _response(plane, surface_pos, seconds=0.15):
    plane.reset(altitude_m=200.0, airspeed_m_s=_CRUISE[_name(plane)])
    for servo, pos in surface_pos.items():
        plane.servo_pos[servo] = pos
    _fly(plane, seconds, 0.2)
    rates = (plane.p, plane.q, plane.r)
    for i in range(len(plane.servo_pos)):
        plane.servo_pos[i] = 0.0
    return rates


def test_the_trainer_servos_towards_max_roll_right_pitch_up_and_yaw_right():
    plane = P.Plane(load_airframe("trainer"), 1000)
    p, _, _ = _response(plane, {0: 1.0})
    assert p > 1.0  # rad/s, right roll is positive as in the quad physics (FRD)
    _, q, _ = _response(plane, {1: 1.0})
    assert q > 0.3  # pitch up
    _, _, r = _response(plane, {2: 1.0})
    assert r > 0.1  # yaw right
    p, _, _ = _response(plane, {0: -1.0})
    assert p < -1.0


def test_the_wing_elevons_mix_into_pitch_and_roll():
    plane = P.Plane(load_airframe("wing"), 1000)
    p, q, _ = _response(plane, {0: 1.0, 1: 1.0})  # both trailing edges up
    assert q > 0.3 and abs(p) < 0.2
    p, q, _ = _response(plane, {0: -1.0, 1: 1.0})  # left down, right up: roll right
    assert p > 1.0 and abs(q) < 0.5
    p, _, _ = _response(plane, {0: 1.0, 1: -1.0})
    assert p < -1.0


def test_the_attitude_quaternion_the_board_gets_agrees_with_the_euler_angles(plane):
    plane.reset(altitude_m=200.0, airspeed_m_s=_CRUISE[_name(plane)])
    plane.servo_pos[0] = 0.6
    _fly(plane, 0.4, 0.2)
    plane.servo_pos[0] = 0.0
    quad = Vehicle(load_airframe("5inch"), "quadx")
    quad.qw, quad.qx, quad.qy, quad.qz = plane.qw, plane.qx, plane.qy, plane.qz
    for a, b in zip(quad.euler_rad(), plane.euler_rad(), strict=True):
        assert a == pytest.approx(b, abs=1e-6)
    assert abs(plane.roll_rad) > math.radians(20)
    # level flight: the velocity is mostly along the heading, in NED
    assert math.hypot(plane.vn, plane.ve) > 8.0


def test_a_headwind_slows_the_ground_speed_but_not_the_airspeed():
    plane = P.Plane(load_airframe("trainer"), 1000)
    plane.reset(altitude_m=200.0, airspeed_m_s=13.0)  # heading north
    plane.wind_n = -5.0  # wind from the north, blowing south
    _fly(plane, 8.0, 0.15)
    assert 11.0 < plane.airspeed_m_s < 15.5
    assert plane.vn < plane.airspeed_m_s - 3.5


def test_a_throw_launches_it_off_the_ground_with_an_acceleration_a_launch_detector_sees():
    plane = P.Plane(load_airframe("trainer"), 1000)
    plane.reset()
    _fly(plane, 0.5)
    assert plane.on_ground
    peak_fx = 0.0
    plane.throw(forward_n=plane.mass_kg * 40.0, up_n=plane.mass_kg * 12.0)
    for _ in range(300):  # 0.3 s of arm swing
        plane.step(plane.dt_s, (0.0,))
        peak_fx = max(peak_fx, plane.fx)
    plane.throw(0.0, 0.0)
    assert peak_fx > 1.9 * 9.81  # above INAV's nav_fw_launch_accel default
    assert not plane.on_ground
    assert plane.airspeed_m_s > 10.0
    _fly(plane, 1.0, 0.6)
    assert not plane.on_ground and plane.altitude_m() > 1.0


def test_a_hard_arrival_on_the_ground_is_a_crash(plane):
    plane.reset(altitude_m=30.0, pitch_rad=-1.2, airspeed_m_s=15.0)
    for _ in range(10000):
        plane.step(plane.dt_s, (0.5,))
        if plane.on_ground:
            break
    assert plane.on_ground and plane.crashed and plane.impact_m_s > 4.0


# --------------------------------------------------------------------------- bad airframes
_GOOD = '''
name = "mine"
kind = "plane"
model = "trainer"
[servos]
aileron = { servo = 0, direction = 1 }
elevator = { servo = 1, direction = -1 }
[battery]
cells = 3
capacity_mah = 2200
r_int_ohm = 0.02
[imu]
gyro_noise_rad_s_rthz = 8.7e-5
gyro_bias_sigma_rad_s = 0.0087
gyro_bias_walk_rad_s_rts = 3.9e-5
accel_noise_m_s2_rthz = 3.9e-3
accel_bias_sigma_m_s2 = 0.03
gyro_vibration_rad_s = 0.02
accel_vibration_m_s2 = 1.5
gyro_range_dps = 2000
accel_range_g = 16
[params]
mixer_type = "airplane"
'''


def _airframe(tmp_path, text, xml=None):
    if xml is not None:
        (tmp_path / "mine.xml").write_text(xml)
    f = tmp_path / "mine.toml"
    f.write_text(text)
    return str(f)


def _trainer_xml():
    return (P.ROOT / "aircraft" / "trainer" / "trainer.xml").read_text()


def test_a_plane_of_your_own_in_toml_or_a_jsbsim_xml_loads(tmp_path):
    a = load_airframe(_airframe(tmp_path, _GOOD))
    assert a["kind"] == "plane" and a["frame"] == "airplane"
    a = load_airframe(_airframe(tmp_path, _GOOD.replace('model = "trainer"', 'xml = "mine.xml"'), _trainer_xml()))
    assert a["xml"].endswith("mine.xml")
    P.Plane(a, 500).step(0.002, (0.0,))  # JSBSim flies it with hoverfly's engines
    assert load_airframe(str(tmp_path / "mine.xml"))["kind"] == "plane"


@pytest.mark.parametrize("change, says", [
    (('[servos]\n', '[servos]\nrudder = { servo = 9, direction = 1 }\n'), "servo 9, which does not exist"),
    (('elevator = { servo = 1', 'elevator = { servo = 0'), "servo 0 drives both"),
    (('aileron = { servo = 0, direction = 1 }',
      'aileron = { servo = 0, direction = 1, min_us = 2000, max_us = 1000 }'), "min_us < mid_us < max_us"),
    (('elevator = { servo = 1, direction = -1 }', 'elevator = { servo = 1, direction = 2 }'),
     "direction must be 1 or -1"),
    (('aileron =', 'flaperon ='), "unknown key 'flaperon'"),
    (('model = "trainer"', 'model = "cessna"'), "unknown JSBSim model 'cessna'"),
    (('model = "trainer"\n', ''), "lacks model"),
    (('[servos]\naileron = { servo = 0, direction = 1 }\nelevator = { servo = 1, direction = -1 }\n', ''),
     "lacks [servos]"),
    (('kind = "plane"\n', 'kind = "plane"\nkt = 1e-5\n'), "unknown key 'kt'"),
    (('mixer_type = "airplane"', 'mixer_type = "octox"'), "mixer_type"),
])
def test_a_bad_plane_airframe_is_one_clear_line(tmp_path, change, says):
    text = _GOOD.replace(*change)
    assert text != _GOOD
    with pytest.raises(UserError) as e:
        load_airframe(_airframe(tmp_path, text))
    assert says in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("change, says", [
    (('<wingarea unit="M2"> 0.30 </wingarea>', '<wingarea unit="M2"> -0.30 </wingarea>'),
     "metrics/wingarea = -0.30 must be a positive number"),
    (('<wingspan unit="M"> 1.40 </wingspan>', '<wingspan unit="M"> wide </wingspan>'), "must be a number"),
    (('<emptywt unit="KG"> 1.20 </emptywt>', ''), "lacks mass_balance/emptywt"),
    (('<axis name="LIFT">', '<axis name="LIFTX">'), "lacks the LIFT axis"),
    (('<fdm_config name="trainer"', '<fdm_config name="trainer" <'), "not valid XML"),
    (('engine file="motor_trainer"', 'engine file="no_such_motor"'), "engine file 'no_such_motor' is not in"),
    (('thruster file="prop_10x6"', 'thruster file="prop_99"'), "thruster file 'prop_99' is not in"),
])
def test_missing_or_nonsense_aero_data_is_refused_before_jsbsim_flies_it(tmp_path, change, says):
    xml = _trainer_xml()
    assert change[0] in xml
    path = _airframe(tmp_path, _GOOD.replace('model = "trainer"', 'xml = "mine.xml"'), xml.replace(*change))
    with pytest.raises(UserError) as e:
        load_airframe(path)
    assert says in str(e.value) and "\n" not in str(e.value)


def test_fly_with_a_plane_flies_it_now_that_the_core_mixes_planes(capsys):
    # the runner's refusal went with the plane mixers (issue 23): the trainer flies its default scenario
    rc = main(["fly", "--airframe", "trainer", "--duration", "3", "--json"])
    out, err = capsys.readouterr()
    assert rc == 0 and "Traceback" not in err
    result = json.loads(out)
    assert result["airframe"] == "trainer" and "airspeed_m_s" in result


# --------------------------------------------------------------------------- scenarios and judging
PLANE_SCENARIOS = ("launch", "bank-steps", "pitch-steps", "box", "glide", "wind")


@pytest.mark.parametrize("name", PLANE_SCENARIOS)
def test_the_plane_scenarios_load_and_are_refused_on_a_quad_in_one_line(name):
    from hoverfly.sim.runner import SimRun
    from hoverfly.sim.scenario import load_scenario

    sc = load_scenario(name)
    assert sc["airframe"] == "trainer"
    assert sc["start"] or any("throw" in e for e in sc["events"])
    with pytest.raises(UserError) as e:
        SimRun("5inch", sc)
    assert "flown by a plane" in str(e.value) and "\n" not in str(e.value)


def test_the_bank_steps_are_30_degree_angle_steps_in_the_quads_step_format():
    from hoverfly.sim.scenario import load_scenario

    steps = [e["step"] for e in load_scenario("bank-steps")["events"] if "step" in e]
    assert [s["to"] for s in steps] == [30, 0, -30, 0]
    assert all(s["axis"] == "roll" and s["unit"] == "deg" for s in steps)


@pytest.mark.parametrize("text, says", [
    ('[[at]]\nt = 1\nthrow = { speed = 3 }\n', "throw has no field 'speed'"),
    ('[[at]]\nt = 1\nthrow = false\n', "throw must be true or a table"),
    ('[[at]]\nt = 1\nthrow = { duration_s = 5 }\n', "throw.duration_s"),
    ('[start]\naltitude_m = -5\n', "altitude_m = -5 is out of range"),
    ('[start]\nairspeed = 13\n', "unknown key 'airspeed'"),
])
def test_a_bad_plane_scenario_is_one_clear_line(text, says):
    from hoverfly.sim.scenario import parse_scenario

    with pytest.raises(UserError) as e:
        parse_scenario('name = "x"\nduration_s = 5\n' + text)
    assert says in str(e.value) and "\n" not in str(e.value)


def test_a_hand_launch_throws_the_plane_and_lets_go():
    plane = P.Plane(load_airframe("wing"), 1000)
    plane.reset()
    _fly(plane, 0.5)
    throw = P.HandLaunch(plane)
    throw.start(0.0)
    k = 0
    pushing = []
    while k < 1000:
        k += 1
        pushing.append(throw.tick(k * plane.dt_s))
        plane.step(plane.dt_s, (0.8,))
    assert pushing.count(True) == pytest.approx(300, abs=2)  # 0.3 s of push, then the hand is gone
    assert plane.hand_forward_n == 0.0 and plane.hand_up_n == 0.0
    assert not plane.on_ground and plane.airspeed_m_s > 9.0


def test_the_judge_reports_airspeed_bank_and_a_stall_as_a_pilot_sees_them():
    plane = P.Plane(load_airframe("trainer"), 1000)
    judge = P.PlaneJudge(plane.airframe["stall_speed_m_s"])
    plane.reset(altitude_m=150.0, airspeed_m_s=13.0)
    for k in range(3000):  # cruise, then a 45 degree bank
        plane.servo_pos[0] = 0.5 if 1000 <= k < 1300 else 0.0
        plane.step(plane.dt_s, (0.2,))
        judge.add(k * plane.dt_s, plane)
    r = judge.result()
    assert r["stalls"] == [] and r["spins"] == []
    assert 10.0 < r["airspeed_m_s"]["min"] <= r["airspeed_m_s"]["mean"] <= r["airspeed_m_s"]["max"] < 20.0
    assert 20.0 < r["max_bank_deg"] < 120.0
    for k in range(3000, 9000):  # full up elevator, power off: the wing stalls
        plane.servo_pos[1] = 1.0
        plane.step(plane.dt_s, (0.0,))
        judge.add(k * plane.dt_s, plane)
    assert len(judge.result()["stalls"]) >= 1
    assert judge.result()["airspeed_m_s"]["min"] < plane.airframe["stall_speed_m_s"]


class _State:
    on_ground = False
    roll_rad = 0.3
    pd = -50.0


def test_the_judge_calls_a_stalled_autorotation_a_spin_but_not_a_fast_turn():
    judge = P.PlaneJudge(7.5)
    s = _State()
    for k in range(3000):  # a fast turn at speed: no spin
        s.airspeed_m_s, s.r = 14.0, 1.5
        judge.add(k * 0.001, s)
    assert judge.result()["spins"] == [] and judge.result()["stalls"] == []
    for k in range(3000, 5000):  # slow and yawing hard for 2 s: a spin
        s.airspeed_m_s, s.r = 5.0, 2.0
        judge.add(k * 0.001, s)
    r = judge.result()
    assert r["stalls"] == [3.0] and r["spins"] == [3.2]  # a spin is counted from the stall on
    judge.add(5.0, type("Landed", (), {"on_ground": True})())
    assert judge.result()["airspeed_m_s"]["min"] == 5.0


def test_the_runner_flies_a_plane_and_reports_its_airspeed_and_bank_in_the_json():
    """Plumbing only, until the fixed-wing core exists: the quad core's outputs drive the plane (its
    servos stay centred, motor 1 is the throttle), so this checks the runner's plane wiring, the
    [start] in flight, the throw and the plane's part of the result, not how the flight is flown."""
    from hoverfly.sim.runner import SimRun

    af = load_airframe("trainer")
    af["frame"] = "quadx"
    af["params"] = {}
    r = SimRun(af, "bank-steps", seed=1, duration_s=3.0).run()
    assert not r["crashed"]
    a = r["airspeed_m_s"]
    assert 9.0 < a["min"] <= a["mean"] <= a["max"] < 16.0  # started in flight at 13 m/s
    assert r["altitude_m"]["max"] == pytest.approx(80.0, abs=1.0)
    assert r["max_bank_deg"] < 10.0 and r["stalls"] == [] and r["spins"] == []
    r = SimRun(af, "launch", seed=1, duration_s=3.0).run()
    assert r["airspeed_m_s"]["max"] > 10.0  # the throw at 2 s
    assert r["altitude_m"]["max"] > 0.3


def test_what_jsbsim_itself_refuses_is_one_line_and_its_own_messages_stay_off_the_output(tmp_path, capfd):
    xml = _trainer_xml().replace('engine file="motor_trainer"', 'engine file="no_such_motor"')
    (tmp_path / "mine.xml").write_text(xml)
    af = load_airframe("trainer")
    af["xml"] = str(tmp_path / "mine.xml")  # past the airframe check, straight to JSBSim
    with pytest.raises(UserError) as e:
        P.Plane(af, 1000)
    assert "Could not open file: no_such_motor" in str(e.value) and "\n" not in str(e.value)
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    P.Plane(load_airframe("trainer"), 1000)
    out, err = capfd.readouterr()
    assert "JSBSim" not in out  # no banner in front of fly --json
