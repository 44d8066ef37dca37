"""Output stage and the board's output codec: idle/max, clamps that count, motor order, DShot boot
commands, the output failsafe, and eRPM replies checked by their CRC."""

from array import array

from hoverfly.compat import ticks_add
from hoverfly.core.config.params import Params
from hoverfly.core.stages.output import OutputEncoder, OutputStage, parse_motor_order
from hoverfly.protocols.dshot import (
    CMD_3D_MODE_OFF,
    CMD_SPIN_DIRECTION_NORMAL,
    CMD_SPIN_DIRECTION_REVERSED,
    DshotCommandQueue,
    dshot_frame,
    erpm_reply_word,
    frame_crc_ok,
    frame_value,
    gcr_encode,
)

T0 = ticks_add(0, -3000000)  # start just below the tick wrap


def _params(**values):
    p = Params()
    for name in values:
        assert p.set(name, values[name]) is None, name
    return p


def _encoder(n=4, servos=0, **values):
    enc = OutputEncoder()
    enc.configure(_params(**values), n, servos, T0)
    return enc


def _stage(n=4, **values):
    st = OutputStage()
    st.configure(_params(**values), n)
    return st


def _drain_boot_commands(enc, now_us):
    """Run stop frames until the boot commands are out; returns the time after."""
    stop = array("f", [0.0] * enc.motor_count)
    for _ in range(400):
        enc.write(stop, enc.motor_count, now_us)
        now_us = ticks_add(now_us, 1000)
    assert not enc.commands.busy()
    return now_us


# ------------------------------------------------------------------ output stage (core side)

def test_armed_output_runs_from_idle_to_max():
    st = _stage(motor_idle_pct=5.0, motor_max_pct=90.0)
    out = array("f", [9.0] * 8)
    st.update(array("f", [0.0, 0.5, 1.0, 0.25]), True, out)
    assert abs(out[0] - 0.05) < 1e-6
    assert abs(out[1] - 0.475) < 1e-6
    assert abs(out[2] - 0.9) < 1e-6
    assert abs(out[3] - 0.2625) < 1e-6


def test_disarmed_output_is_stop_whatever_the_mixer_says():
    st = _stage()
    out = array("f", [9.0] * 8)
    st.update(array("f", [1.0, 1.0, 1.0, 1.0]), False, out)
    assert list(out[:4]) == [0.0, 0.0, 0.0, 0.0]


def test_out_of_range_demand_is_clamped_and_counted_never_wrapped():
    st = _stage(motor_idle_pct=5.0)
    out = array("f", [0.0] * 8)
    st.update(array("f", [1.5, -0.5, float("nan"), 0.5]), True, out)
    assert abs(out[0] - 1.0) < 1e-6  # above 1: full, not a wrap to low
    assert abs(out[1] - 0.05) < 1e-6  # below 0: idle
    assert abs(out[2] - 0.05) < 1e-6  # NaN: idle, never full
    assert st.clamped == 3


def test_servos_centre_while_disarmed_and_clamp_when_armed():
    st = _stage()
    out = array("f", [0.5, 0.5])
    st.servos(array("f", [0.7, 3.0]), 2, False, out)
    assert list(out) == [0.0, 0.0]
    st.servos(array("f", [0.7, 3.0]), 2, True, out)
    assert abs(out[0] - 0.7) < 1e-6 and out[1] == 1.0
    assert st.clamped == 1


def test_erpm_replies_become_rpm_and_a_corrupted_reply_is_rejected_by_its_crc():
    st = _stage(dshot_bidir=1, motor_poles=14)
    assert st.bidir
    erpm = array("i", [0] * 8)
    rpm = array("i", [0] * 8)
    words = (erpm_reply_word(70000), erpm_reply_word(140000), erpm_reply_word(0), erpm_reply_word(35000))
    for i in range(4):
        st.reply_codes[i] = gcr_encode(words[i])
    st.decode_replies(4, erpm, rpm)
    assert abs(erpm[0] - 70000) <= 70000 // 500  # period quantisation: 9 bits of mantissa
    assert abs(rpm[1] - 20000) <= 40  # 140000 eRPM / 7 pole pairs
    assert erpm[2] == 0 and rpm[2] == 0  # stopped code
    good = rpm[0]
    # Flip one bit of motor 0's word (CRC nibble left as it was): the GCR code is valid, the CRC is not.
    st.reply_codes[0] = gcr_encode(words[0] ^ 0x0100)
    st.decode_replies(1, erpm, rpm)
    assert st.reply_errors == 1
    assert rpm[0] == good  # the last good value holds
    # A line code that is not GCR at all.
    st.reply_codes[0] = 0
    st.decode_replies(1, erpm, rpm)
    assert st.reply_errors == 2 and rpm[0] == good


def test_bidir_is_off_for_analog_protocols():
    assert not _stage(motor_protocol="pwm", dshot_bidir=1).bidir


# ------------------------------------------------------------------------ motor order

def test_motor_order_maps_motors_to_output_lines():
    assert parse_motor_order(0, 4) == (bytes([0, 1, 2, 3]), "")
    assert parse_motor_order(2143, 4) == (bytes([1, 0, 3, 2]), "")
    assert parse_motor_order(312, 3) == (bytes([2, 0, 1]), "")


def test_bad_motor_order_falls_back_to_in_order_with_a_reason():
    for value in (1123, 123, 12345, 1250):
        order, err = parse_motor_order(value, 4)
        assert order == bytes([0, 1, 2, 3]) and "motor_order" in err, value


def test_encoder_writes_each_motor_on_its_line():
    enc = _encoder(motor_order=2143, motor_protocol="pwm")
    enc.write(array("f", [0.1, 0.2, 0.3, 0.4]), 4, T0)
    assert [round(x) for x in enc.pulse_us[:4]] == [1200, 1100, 1400, 1300]
    assert list(enc.motor_of_line[:4]) == [1, 0, 3, 2]


# ------------------------------------------------------------------------------ codecs

def test_dshot_lines_carry_frames_for_the_board_contract():
    enc = _encoder(motor_protocol="dshot300")
    assert enc.dshot and enc.speed_kbit == 300
    now = _drain_boot_commands(enc, T0)
    enc.write(array("f", [0.0, 0.055, 0.5, 1.0]), 4, now)
    w = enc.words
    assert [frame_value(w[i]) for i in range(4)] == [0, 158, 1048, 2047]
    assert all(frame_crc_ok(w[i]) for i in range(4))


def test_bidir_frames_carry_the_inverted_crc():
    enc = _encoder(dshot_bidir=1)
    now = _drain_boot_commands(enc, T0)
    enc.write(array("f", [0.5, 0.5, 0.5, 0.5]), 4, now)
    assert frame_crc_ok(enc.words[0], True) and not frame_crc_ok(enc.words[0], False)


def test_analog_widths_follow_each_protocols_range():
    for name, lo, hi in (("pwm", 1000, 2000), ("oneshot125", 125, 250), ("oneshot42", 42, 84),
                         ("multishot", 5, 25)):
        enc = _encoder(motor_protocol=name, motor_pwm_rate=50)
        assert enc.error == "", enc.error
        enc.write(array("f", [0.0, 0.5, 1.0, 0.25]), 4, T0)
        p = enc.pulse_us
        assert abs(p[0] - lo) < 1e-3 and abs(p[2] - hi) < 1e-3, name
        assert abs(p[1] - (lo + hi) / 2) < 1e-3, name


def test_encoder_clamps_and_counts_out_of_range_commands():
    enc = _encoder(motor_protocol="oneshot125", motor_pwm_rate=2000)
    enc.write(array("f", [2.0, -1.0, float("nan"), 0.5]), 4, T0)
    assert abs(enc.pulse_us[0] - 250.0) < 1e-3
    assert abs(enc.pulse_us[1] - 125.0) < 1e-3
    assert abs(enc.pulse_us[2] - 125.0) < 1e-3
    assert enc.clamped == 3
    d = _encoder()
    now = _drain_boot_commands(d, T0)
    d.write(array("f", [2.0, float("nan"), 0.5, 0.5]), 4, now)
    assert frame_value(d.words[0]) == 2047 and frame_value(d.words[1]) == 0  # full, and stop for NaN
    assert d.clamped == 2


def test_pwm_rate_outside_the_protocol_is_clamped_and_explained():
    enc = _encoder(motor_protocol="pwm", motor_pwm_rate=8000)
    assert enc.rate_hz == 490 and "490" in enc.error


def test_servo_widths_pass_through_clamped_to_what_a_servo_takes_and_bad_end_points_are_named():
    enc = _encoder(servos=2)
    enc.write_servos(array("H", [1700, 1250]), 2, T0)
    assert list(enc.servo_us[:2]) == [1700, 1250] and enc.clamped == 0
    enc.write_servos(array("H", [3000, 100]), 2, T0)
    assert list(enc.servo_us[:2]) == [2500, 500] and enc.clamped == 2
    enc.write_servos(array("f", [float("nan"), 1712.6]), 2, T0)  # a bridge's floats: NaN is the servo's mid
    assert list(enc.servo_us[:2]) == [1500, 1712] and enc.clamped == 3
    bad = _encoder(servos=1, servo0_min_us=1600, servo0_mid_us=1500)
    assert "servo 0" in bad.error
    assert bad.servo_mid[0] == 1500  # the failsafe width stays the servo's own mid


def test_each_servo_line_disarms_to_its_own_mid():
    enc = _encoder(servos=2, servo0_mid_us=1450, servo1_mid_us=1560)
    assert list(enc.servo_us[:2]) == [1450, 1560]


# ------------------------------------------------------------------ DShot boot commands

def _commands_seen(enc, now_us, steps=400):
    seen = []
    stop = array("f", [0.0] * enc.motor_count)
    for _ in range(steps):
        enc.write(stop, enc.motor_count, now_us)
        for line in range(enc.motor_count):
            v = frame_value(enc.words[line])
            if 0 < v < 48:
                seen.append((line, v))
        now_us = ticks_add(now_us, 1000)
    return seen


def test_boot_turns_3d_off_and_sets_spin_direction_of_reversed_motors():
    enc = _encoder(motor_reversed=0b0101, motor_order=2143)
    seen = _commands_seen(enc, T0)
    assert seen.count((0, CMD_3D_MODE_OFF)) == 10  # every line, ten times
    # motor 1 (bit 0) sits on line 1, motor 3 on line 3: reversed; motors 2 and 4 normal
    assert seen.count((1, CMD_SPIN_DIRECTION_REVERSED)) == 10
    assert seen.count((3, CMD_SPIN_DIRECTION_REVERSED)) == 10
    assert seen.count((0, CMD_SPIN_DIRECTION_NORMAL)) == 10
    assert (0, CMD_SPIN_DIRECTION_REVERSED) not in seen


def test_no_spin_commands_when_no_motor_is_reversed_and_none_for_analog():
    seen = _commands_seen(_encoder(), T0)
    assert set(v for _, v in seen) == {CMD_3D_MODE_OFF}
    assert _encoder(motor_protocol="pwm", motor_reversed=1).commands.busy() is False


def test_a_spinning_motor_drops_the_boot_commands():
    enc = _encoder(motor_reversed=1)
    enc.write(array("f", [0.2, 0.0, 0.0, 0.0]), 4, T0)
    assert not enc.commands.busy() and enc.commands.aborted == 1
    assert frame_value(enc.words[0]) > 47


def test_dshot_command_outside_1_to_47_is_refused():
    q = DshotCommandQueue()
    for bad in (0, 48, -1, 2047):
        assert isinstance(q.push(bad, False), str)
    assert q.refused == 4
    assert q.push(CMD_3D_MODE_OFF, False) is True


# ------------------------------------------------------------------------ output failsafe

def test_output_failsafe_disarms_every_output_after_100_ms_without_a_command():
    enc = _encoder(servos=1, motor_protocol="pwm")
    enc.write(array("f", [0.6, 0.6, 0.6, 0.6]), 4, T0)
    enc.write_servos(array("H", [1900]), 1, T0)
    assert not enc.tick(ticks_add(T0, 100000))  # exactly 100 ms: still fresh
    assert abs(enc.pulse_us[0] - 1600) < 1e-3 and enc.servo_us[0] == 1900
    assert enc.tick(ticks_add(T0, 101000))
    assert enc.failsafe and enc.failsafe_trips == 1
    assert list(enc.pulse_us[:4]) == [1000.0] * 4
    assert enc.servo_us[0] == 1500
    # a fresh command brings the outputs back
    enc.write(array("f", [0.3, 0.3, 0.3, 0.3]), 4, ticks_add(T0, 150000))
    assert not enc.failsafe and not enc.tick(ticks_add(T0, 151000))
    assert abs(enc.pulse_us[0] - 1300) < 1e-3


def test_output_failsafe_sends_dshot_stop_and_follows_its_parameter():
    enc = _encoder(output_fs_ms=20)
    now = _drain_boot_commands(enc, T0)
    enc.write(array("f", [0.6, 0.6, 0.6, 0.6]), 4, now)
    assert not enc.tick(ticks_add(now, 20000))
    assert enc.tick(ticks_add(now, 20001))
    assert all(enc.words[i] == dshot_frame(0) for i in range(4))


def test_output_failsafe_does_not_count_before_the_first_command():
    enc = _encoder()
    assert enc.tick(ticks_add(T0, 500000))  # held disarmed (they are anyway)
    assert enc.failsafe_trips == 0
