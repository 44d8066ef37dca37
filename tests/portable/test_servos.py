"""Servo mixer: INAV's presets and smix rules, servo end points, reversal, trim, speed limit, the disarmed
position and bad input refused with one reason."""

from array import array

from hoverfly.core.config.params import Params
from hoverfly.core.stages.servos import (
    MAX_RULES,
    PRESETS,
    SRC_PITCH,
    SRC_ROLL,
    SRC_THROTTLE,
    SRC_YAW,
    ServoMixer,
    reset_pairs,
    rule_pairs,
    rules_of,
    servo_pairs,
)

DT_US = 1000


def _params(**values):
    p = Params()
    for name in values:
        assert p.set(name, values[name]) is None, name
    return p


def _mixer(p):
    m = ServoMixer()
    m.configure(p)
    return m


def _run(m, roll=0.0, pitch=0.0, yaw=0.0, throttle=0.0, channels=None, armed=True, passes=1):
    torque = array("f", [roll, pitch, yaw])
    ch = channels if channels is not None else array("H", [1500] * 18)
    out = array("H", [0] * 8)
    m.bind(torque, ch, out)
    for _ in range(passes):
        m.update(DT_US, armed, throttle)
    return out


def _set_rules(p, rules):
    for i, (servo, source, rate, speed) in enumerate(rules):
        assert p.update([("smix%d_servo" % i, servo), ("smix%d_input" % i, source), ("smix%d_rate" % i, rate),
                         ("smix%d_speed" % i, speed)]) is None


# ---------------------------------------------------------------------------------- presets

def test_airplane_preset_puts_aileron_elevator_rudder_on_servos_0_1_2():
    m = _mixer(_params(mixer_type="airplane"))
    assert m.count == 3 and m.rules == 3
    assert list(_run(m)[:3]) == [1500, 1500, 1500]
    assert list(_run(m, roll=1.0)[:3]) == [2000, 1500, 1500]
    assert list(_run(m, pitch=-0.5)[:3]) == [1500, 1250, 1500]
    assert list(_run(m, yaw=0.2)[:3]) == [1500, 1500, 1600]


def test_flying_wing_elevons_mix_pitch_and_roll_half_each_as_the_sim_wiring_expects():
    m = _mixer(_params(mixer_type="flying_wing"))
    assert m.count == 2
    # nose up raises both trailing edges (towards max); roll right lowers the left elevon, raises the right
    assert list(_run(m, pitch=1.0)[:2]) == [1750, 1750]
    assert list(_run(m, roll=1.0)[:2]) == [1250, 1750]
    assert list(_run(m, roll=1.0, pitch=1.0)[:2]) == [1500, 2000]


def test_vtail_ruddervators_mix_pitch_and_yaw_and_the_aileron_takes_roll():
    m = _mixer(_params(mixer_type="vtail"))
    assert m.count == 3
    assert list(_run(m, yaw=1.0)[:3]) == [1500, 1250, 1750]
    assert list(_run(m, pitch=1.0)[:3]) == [1500, 1750, 1750]
    assert list(_run(m, roll=-1.0)[:3]) == [1000, 1500, 1500]


def test_a_multirotor_has_no_servo_mix_unless_rules_are_stored():
    assert _mixer(_params()).count == 0
    p = _params()
    _set_rules(p, [(0, 8, 100, 0)])  # a camera tilt on RC channel 5, as INAV allows on any platform
    m = _mixer(p)
    ch = array("H", [1500] * 18)
    ch[4] = 1750
    assert m.count == 1 and _run(m, channels=ch)[0] == 1750


def test_every_preset_names_servos_and_inputs_that_exist():
    for frame in PRESETS:
        for servo, source, rate, speed in PRESETS[frame]:
            assert 0 <= servo < 8 and source in (SRC_ROLL, SRC_PITCH, SRC_YAW) and -125 <= rate <= 125
            assert speed == 0


# ---------------------------------------------------------------------------------- the smix table

def test_stored_rules_replace_the_preset_and_all_zero_rates_bring_it_back():
    p = _params(mixer_type="airplane")
    _set_rules(p, [(3, SRC_ROLL, 100, 0)])
    m = _mixer(p)
    assert m.count == 4 and _run(m, roll=0.5)[3] == 1750
    assert p.update(reset_pairs()) is None
    assert [r[1:] for r in rules_of(p)] == [(0, SRC_ROLL, 100, 0), (1, SRC_PITCH, 100, 0), (2, SRC_YAW, 100, 0)]


def test_editing_one_rule_copies_the_preset_in_first_so_the_others_stay():
    p = _params(mixer_type="airplane")
    pairs, err = rule_pairs(p, 2, 2, SRC_YAW, -80, 0)
    assert err is None and p.update(pairs) is None
    assert [r[1:] for r in rules_of(p)] == [(0, SRC_ROLL, 100, 0), (1, SRC_PITCH, 100, 0), (2, SRC_YAW, -80, 0)]
    assert _run(_mixer(p), yaw=0.5)[2] == 1300


def test_two_rules_on_one_servo_add_and_the_sum_clips_at_the_end_point():
    p = _params(mixer_type="airplane")
    _set_rules(p, [(0, SRC_ROLL, 100, 0), (0, SRC_PITCH, 100, 0)])
    m = _mixer(p)
    assert _run(m, roll=0.3, pitch=0.2)[0] == 1750
    assert _run(m, roll=1.0, pitch=1.0)[0] == 2000


def test_throttle_input_spans_minus_to_plus_full_travel():
    p = _params(mixer_type="airplane")
    _set_rules(p, [(0, SRC_THROTTLE, 100, 0)])
    m = _mixer(p)
    assert _run(m, throttle=0.0)[0] == 1000 and _run(m, throttle=0.5)[0] == 1500 and _run(m, throttle=1.0)[0] == 2000


def test_rc_inputs_follow_rc_map_and_raw_channels_9_to_16_read_as_they_are():
    p = _params(mixer_type="airplane", rc_map=43215678)  # roll on channel 4 (Betaflight's TREA1234)
    _set_rules(p, [(0, 4, 100, 0), (1, 15, 100, 0)])  # RC roll; RC channel 9
    m = _mixer(p)
    ch = array("H", [1500] * 18)
    ch[3] = 1900
    ch[8] = 1100
    out = _run(m, channels=ch)
    assert out[0] == 1900 and out[1] == 1100


def test_one_sided_stabilised_inputs_pass_only_their_side():
    p = _params(mixer_type="airplane")
    _set_rules(p, [(0, 23, 100, 0), (1, 24, 100, 0)])  # roll+, roll-
    m = _mixer(p)
    assert list(_run(m, roll=0.4)[:2]) == [1700, 1500]
    assert list(_run(m, roll=-0.4)[:2]) == [1500, 1300]


# ---------------------------------------------------------------------------------- each servo

def test_servo_rate_scales_and_a_negative_rate_reverses():
    p = _params(mixer_type="airplane", servo0_rate=-100, servo1_rate=50)
    m = _mixer(p)
    out = _run(m, roll=0.5, pitch=0.5)
    assert out[0] == 1250 and out[1] == 1625


def test_mid_is_the_trim_and_the_end_points_clip():
    p = _params(mixer_type="airplane", servo0_mid_us=1550, servo0_min_us=1200, servo0_max_us=1800)
    m = _mixer(p)
    assert _run(m)[0] == 1550
    assert _run(m, roll=1.0)[0] == 1800 and _run(m, roll=-1.0)[0] == 1200
    assert _run(m, roll=0.1)[0] == 1600


def test_servo_with_min_above_mid_is_named_and_held_at_its_mid():
    p = _params(mixer_type="airplane", servo0_min_us=1700)  # set one row at a time: the combination is bad
    m = _mixer(p)
    assert "servo 0" in m.error and "min" in m.error
    assert _run(m, roll=1.0)[0] == 1500 and _run(m, roll=-1.0)[0] == 1500


def test_speed_limits_how_fast_an_input_moves():
    p = _params(mixer_type="airplane")
    _set_rules(p, [(0, SRC_ROLL, 100, 100)])  # 100 x 10 us/s: full travel (500 us) in 0.5 s
    m = _mixer(p)
    assert _run(m, roll=1.0, passes=100)[0] == 1600  # 0.1 s
    assert _run(m, roll=1.0, passes=400)[0] == 2000  # 0.5 s in all
    assert _run(m, roll=1.0, passes=10)[0] == 2000  # there it stays


def test_nan_or_out_of_range_commands_never_wrap_a_servo():
    m = _mixer(_params(mixer_type="airplane"))
    out = _run(m, roll=float("nan"), pitch=7.0, yaw=-1e30)
    assert list(out[:3]) == [1500, 2000, 1000]


# ---------------------------------------------------------------------------------- disarmed

def test_disarmed_every_servo_sits_at_its_mid_whatever_the_commands():
    p = _params(mixer_type="flying_wing", servo1_mid_us=1480)
    m = _mixer(p)
    out = _run(m, roll=1.0, pitch=1.0, armed=False)
    assert out[0] == 1500 and out[1] == 1480 and out[2] == 1500


def test_speed_limits_start_again_from_centre_after_a_disarm():
    p = _params(mixer_type="airplane")
    _set_rules(p, [(0, SRC_ROLL, 100, 100)])
    m = _mixer(p)
    assert _run(m, roll=1.0, passes=600)[0] == 2000
    _run(m, roll=1.0, armed=False)
    assert _run(m, roll=1.0, passes=100)[0] == 1600  # no jump back to where it was


def test_tricopter_tail_from_the_motor_mixer_uses_servo_0s_end_points_and_rate():
    m = _mixer(_params(mixer_type="tri", servo0_min_us=1100, servo0_max_us=1700, servo0_rate=-100))
    assert m.count == 0
    out = array("H", [0] * 8)
    m.from_norm(array("f", [1.0]), 1, out)
    assert out[0] == 1100
    m.from_norm(array("f", [-0.5]), 1, out)
    assert out[0] == 1600
    m.from_norm(array("f", [float("nan")]), 1, out)
    assert out[0] == 1500


# ---------------------------------------------------------------------------------- bad input

def test_a_rule_naming_a_servo_that_does_not_exist_is_refused_with_one_reason():
    p = _params(mixer_type="airplane")
    pairs, err = rule_pairs(p, 0, 4, SRC_ROLL, 100, 0, servo_count=4)
    assert pairs is None and err == "smix: servo 4 does not exist: servos are 0..3"
    assert p.set("smix0_servo", 4) is not None  # the row's own range: servos 0..3


def test_bad_rules_are_refused_and_nothing_changes():
    p = _params(mixer_type="airplane")
    before = rules_of(p)
    for args in ((MAX_RULES, 0, 0, 100, 0), (0, 0, 13, 100, 0), (0, 0, 29, 100, 0), (0, 0, 0, 126, 0),
                 (0, 0, 0, 100, 256)):
        pairs, err = rule_pairs(p, *args)
        assert pairs is None and err and "\n" not in err, args
    assert rules_of(p) == before
    assert "gimbal" in p.set("smix0_input", 12) and "flaps" in p.set("smix0_input", 14)


def test_servo_settings_with_min_above_max_are_refused_with_one_reason():
    pairs, err = servo_pairs(1, 2000, 1000, 1500, 100)
    assert pairs is None and err.startswith("servo 1:") and "min" in err
    assert servo_pairs(1, 1000, 2000, 1500, 130)[0] is None
    assert servo_pairs(9, 1000, 2000, 1500, 100)[0] is None
    pairs, err = servo_pairs(1, 1100, 1900, 1520, -100)
    assert err is None and ("servo1_rate", -100) in pairs and ("servo1_mid_us", 1520) in pairs
