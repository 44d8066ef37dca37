"""Analog ESC / servo codec: protocols.md §5 worked example, clamping, rate limits, timer counts."""

from hoverfly.protocols import analog
from hoverfly.protocols.analog import (
    MULTISHOT,
    ONESHOT42,
    ONESHOT125,
    PWM,
    SERVO,
    AnalogEncoder,
    ServoEncoder,
)


def _close(a, b, tol=1e-3):
    return abs(a - b) <= tol


def test_worked_example_motor_value_1234():
    assert _close(analog.pulse_us_from_external(PWM, 1234), 1234.0)
    assert _close(analog.pulse_us_from_external(ONESHOT125, 1234), 154.25)
    assert _close(analog.pulse_us_from_external(ONESHOT42, 1234), 51.828)
    assert _close(analog.pulse_us_from_external(MULTISHOT, 1234), 9.68)


def test_mincommand_and_midpoint_widths():
    for proto, lo, mid, hi in ((PWM, 1000, 1500, 2000), (ONESHOT125, 125, 187.5, 250),
                               (ONESHOT42, 42, 63, 84), (MULTISHOT, 5, 15, 25)):
        assert _close(analog.pulse_us(proto, 0.0), lo)
        assert _close(analog.pulse_us(proto, 0.5), mid)
        assert _close(analog.pulse_us(proto, 1.0), hi)
        assert analog.pulse_range_us(proto) == (lo, hi)


def test_pulse_ns_is_rounded_integer():
    assert analog.pulse_ns(ONESHOT125, 0.5) == 187500
    assert analog.pulse_ns(ONESHOT42, 0.234) == 51828
    assert analog.pulse_ns(MULTISHOT, 0.234) == 9680


def test_out_of_range_commands_are_clamped_and_counted():
    analog.reset_pulse_clamped()
    assert _close(analog.pulse_us(PWM, 1.5), 2000)
    assert _close(analog.pulse_us(PWM, -0.5), 1000)
    assert _close(analog.pulse_us(ONESHOT125, float("nan")), 125)
    assert analog.pulse_clamped() == 3
    analog.pulse_us(PWM, 0.3)
    assert analog.pulse_clamped() == 3


def test_rate_limits_per_protocol():
    assert analog.validate_rate(PWM, 490) is None and analog.validate_rate(PWM, 50) is None
    err = analog.validate_rate(PWM, 491)
    assert "50..490" in err and "pwm" in err
    assert analog.validate_rate(PWM, 49) is not None
    assert analog.validate_rate(ONESHOT125, 4000) is None and analog.validate_rate(ONESHOT125, 4001)
    assert analog.validate_rate(ONESHOT42, 11904) is None and analog.validate_rate(ONESHOT42, 12000)
    assert analog.validate_rate(MULTISHOT, 32000) is None and analog.validate_rate(MULTISHOT, 40001)
    assert analog.validate_rate(SERVO, 333) is None and analog.validate_rate(SERVO, 334)
    assert "unknown" in analog.validate_rate(9, 50)


def test_longest_pulse_fits_the_fastest_period():
    for proto in (PWM, ONESHOT125, ONESHOT42, MULTISHOT):
        hi_hz = analog.rate_limits_hz(proto)[1]
        assert analog.pulse_range_us(proto)[1] <= 1e6 / hi_hz, proto


def test_protocol_names():
    assert analog.protocol_id("OneShot125") == ONESHOT125 and analog.protocol_id("pwm") == PWM
    assert analog.protocol_id("dshot600") == -1


def test_encoder_timer_counts_pwm_on_the_rp2_clock():
    enc = AnalogEncoder(PWM, 480, 125000000, motor_count=4)
    assert enc.error == ""
    assert enc.period_counts == 260417  # 125e6 / 480
    assert enc.compare_counts(0.5) == 187500  # 1500 µs
    assert enc.compare_counts(1.0) == 250000 and enc.compare_counts(0.7, armed=False) == 125000
    out = enc.new_output()
    out[0] = enc.period_counts  # wide enough for counts above 65535
    assert out[0] == 260417
    enc.encode_motors([0.0, 0.25, 1.0, 2.0], True, out)
    assert list(out) == [125000, 156250, 250000, 250000] and enc.clamped == 1
    enc.encode_motors([0.5] * 4, False, out)
    assert list(out) == [125000] * 4


def test_encoder_idle_floor_and_ns_counts():
    enc = AnalogEncoder(ONESHOT125, 2000, 1000000000, idle_pct=10.0, stop_at_zero=False)
    assert enc.compare_counts(0.0) == 137500  # 125 + 12.5 µs, in ns
    assert enc.compare_counts(1.0) == 250000
    assert enc.period_counts == 500000


def test_encoder_bad_rate_is_clamped_and_reported_not_raised():
    enc = AnalogEncoder(PWM, 1000, 1000000)
    assert "50..490" in enc.error and enc.rate_hz == 490
    assert enc.period_counts == 2041
    assert len(enc.new_output()) == 4


def test_servo_maps_each_side_to_its_end_point():
    assert _close(analog.servo_pulse_us(-1.0), 1000) and _close(analog.servo_pulse_us(0.0), 1500)
    assert _close(analog.servo_pulse_us(1.0), 2000)
    assert _close(analog.servo_pulse_us(0.5, 900, 1400, 2100), 1750)
    assert _close(analog.servo_pulse_us(-0.5, 900, 1400, 2100), 1150)
    assert _close(analog.servo_pulse_us(3.0), 2000)
    s = ServoEncoder(50, 1000000, 1000, 1520, 2000)
    assert s.error == "" and s.period_counts == 20000
    assert s.compare_counts(0.0) == 1520 and s.compare_counts(-1.0) == 1000 and s.compare_counts(1.0) == 2000
    assert s.compare_counts(float("nan")) == 1520 and s.clamped == 1


def test_servo_settings_are_validated():
    assert analog.validate_servo(50) is None
    assert "min_us" in analog.validate_servo(50, 1600, 1500, 2000)
    assert analog.validate_servo(400) is not None
    s = ServoEncoder(50, 1000000, 1600, 1500, 2000)
    assert s.error and s.compare_counts(0.0) == 1500
