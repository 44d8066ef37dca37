"""Line-level round trips: encoders -> pulse train -> ESC-side decode, for every protocol and speed."""

from array import array

from hoverfly.protocols import analog, dshot, pulsetrain
from hoverfly.protocols.pulsetrain import (
    AnalogPulseDecoder,
    DshotPulseDecoder,
    ReplyPulseDecoder,
    render_analog,
    render_dshot,
    render_reply,
)

SAMPLE_VALUES = tuple(range(0, 2048, 41)) + (1, 47, 48, 1046, 2047)


def test_rendered_frame_has_nominal_timings():
    p = render_dshot(0x82C6, 600)
    assert len(p) == 32
    assert p[0] == (1, 1250) and p[1][0] == 0  # first bit a 1: T1H high
    assert p[2] == (1, 625)  # second bit a 0: T0H high
    assert sum(d for _, d in p) == 26667
    q = render_dshot(0x82C9, 600, bidir=True)
    assert q[0] == (0, 1250) and q[1][0] == 1  # inverted: a bit is a low pulse


def test_dshot_round_trip_every_speed_normal_and_bidirectional():
    for speed in dshot.SPEEDS_KBIT:
        for bidir in (False, True):
            dec = DshotPulseDecoder(speed, bidir)
            for value in SAMPLE_VALUES:
                for t in (0, 1):
                    w = dshot.dshot_frame(value, t, bidir)
                    assert dec.decode(render_dshot(w, speed, bidir)) == w, (speed, bidir, value, t)
            assert dec.rejected == 0


def test_other_senders_duty_cycles_decode_too():
    for duty in (pulsetrain.DUTY_BETAFLIGHT_DMA, pulsetrain.DUTY_BITBANG, pulsetrain.DUTY_BETAFLIGHT_PIO):
        for speed in dshot.SPEEDS_KBIT:
            dec = DshotPulseDecoder(speed)
            w = dshot.dshot_frame(1046, 0)
            assert dec.decode(render_dshot(w, speed, duty=duty, trailing_idle_bits=2)) == w, (duty, speed)


def test_pulse_far_from_t0h_and_t1h_is_rejected_and_counted():
    dec = DshotPulseDecoder(600)
    p = render_dshot(dshot.dshot_frame(1046), 600)
    p[2] = (1, 930)  # 56 % of the bit: neither 37.5 % nor 75 %
    p[3] = (0, 1667 - 930)
    assert dec.decode(p) is None and dec.rejected == 1 and "T0H" in dec.last_error
    short = render_dshot(dshot.dshot_frame(1046), 600)[:20]
    assert dec.decode(short) is None and dec.rejected == 2
    wrong_speed = render_dshot(dshot.dshot_frame(1046), 300)
    assert dec.decode(wrong_speed) is None and dec.rejected == 3
    assert dec.decode(render_dshot(dshot.dshot_frame(1046), 600, bidir=True)) is None


def test_motor_encoder_end_to_end_through_the_line():
    for speed in dshot.SPEEDS_KBIT:
        for bidir in (False, True):
            enc = dshot.DshotEncoder(4, bidir=bidir, idle_pct=5.5, stop_at_zero=False)
            dec = DshotPulseDecoder(speed, bidir)
            out = array("H", [0] * 4)
            motors = array("f", [0.0, 0.33, 0.8, 1.0])
            enc.encode_motors(motors, True, out)
            for i in range(4):
                w = dec.decode(render_dshot(out[i], speed, bidir))
                assert w is not None and dshot.frame_crc_ok(w, bidir)
                assert dshot.frame_value(w) == enc.throttle_to_value(motors[i])


def test_reply_line_round_trip_and_vector_levels():
    for speed in (300, 600, 1200):
        dec = ReplyPulseDecoder(speed)
        for word in (0x5F41, 0x32C2, 0xFFF0, 0x22D2, dshot.erpm_reply_word(12345)):
            code = dec.decode_code(render_reply(word, speed))
            assert dshot.gcr_decode(code) == word, (speed, hex(word))
    # the line sampled at bit centres gives the vector's levels
    levels = 0
    p = render_reply(0x5F41, 600)
    for i in range(21):
        centre = i * 1333 + 666
        acc = 0
        for level, d in p:
            if acc <= centre < acc + d:
                levels = (levels << 1) | level
                break
            acc += d
    assert levels == int("011001101010100101101", 2)


def test_short_reply_line_is_rejected():
    dec = ReplyPulseDecoder(600)
    assert dec.decode_code(render_reply(0x5F41, 600)[:4]) is None and dec.rejected == 1


def test_analog_round_trip_every_protocol():
    for proto in (analog.PWM, analog.ONESHOT125, analog.ONESHOT42, analog.MULTISHOT):
        hi_hz = analog.rate_limits_hz(proto)[1]
        period_ns = 1000000000 // hi_hz
        dec = AnalogPulseDecoder(proto)
        for k in range(0, 1001, 50):
            width = analog.pulse_ns(proto, k / 1000.0)
            assert dec.decode(render_analog(width, period_ns)) == width, (proto, k)
        assert dec.rejected == 0


def test_analog_encoder_end_to_end_on_a_timer():
    clock_hz = 125000000
    for proto, rate in ((analog.PWM, 480), (analog.ONESHOT125, 2000), (analog.ONESHOT42, 8000),
                        (analog.MULTISHOT, 32000)):
        enc = analog.AnalogEncoder(proto, rate, clock_hz)
        dec = AnalogPulseDecoder(proto)
        period_ns = enc.period_counts * 8  # 8 ns per count at 125 MHz
        for t in (0.0, 0.1, 0.5, 0.9, 1.0):
            c = enc.compare_counts(t)
            got = dec.decode(render_analog(c * 8, period_ns))
            assert got is not None
            assert abs(got - analog.pulse_ns(proto, t)) <= 4, (proto, t, got)  # half a count


def test_analog_width_outside_the_range_is_rejected():
    dec = AnalogPulseDecoder(analog.ONESHOT125)
    assert dec.decode(render_analog(300000, 500000)) is None
    assert dec.decode(render_analog(100000, 500000)) is None
    assert dec.decode([(1, 150000), (0, 100), (1, 100)]) is None
    assert dec.rejected == 3 and dec.frames == 0
