"""ESC codecs against independent implementations and properties (CPython, hypothesis)."""

import math
from array import array

from hypothesis import given, settings
from hypothesis import strategies as st

from hoverfly.compat import ticks_add
from hoverfly.protocols import analog, dshot, pulsetrain

FAST = settings(max_examples=300, derandomize=True, deadline=None)


# --- independent implementations, written from the reference text ------------------------------

def ref_frame(value, telemetry, bidir):
    """Bit-string form of protocols.md §4.1: 11 value bits, t, CRC of the three nibbles."""
    bits12 = format(value, "011b") + ("1" if telemetry else "0")
    n = [int(bits12[i:i + 4], 2) for i in (0, 4, 8)]
    crc = n[0] ^ n[1] ^ n[2]
    if bidir:
        crc ^= 0xF
    return int(bits12 + format(crc, "04b"), 2)


GCR_QUINTETS = ("11001", "11011", "10010", "10011", "11101", "10101", "10110", "10111",
                "11010", "01001", "01010", "01011", "11110", "01101", "01110", "01111")
GCR = dict(zip("0123456789ABCDEF", GCR_QUINTETS, strict=True))


def ref_line_code(word):
    return int("1" + "".join(GCR[c] for c in "%04X" % word), 2)


def ref_levels(word):
    level, out = 1, ""
    for b in format(ref_line_code(word), "021b"):
        if b == "1":
            level ^= 1
        out += str(level)
    return int(out, 2)


def test_frame_matches_independent_encoder_for_every_value():
    for value in range(2048):
        for t in (0, 1):
            for bidir in (False, True):
                assert dshot.dshot_frame(value, t, bidir) == ref_frame(value, t, bidir)


def test_every_single_bit_flip_of_a_command_frame_fails_its_crc():
    for value in range(0, 2048, 3):
        for bidir in (False, True):
            w = dshot.dshot_frame(value, 0, bidir)
            for b in range(16):
                assert not dshot.frame_crc_ok(w ^ (1 << b), bidir)


def test_gcr_matches_independent_line_code_for_every_reply():
    for v12 in range(4096):
        w = dshot.reply_word(v12)
        assert dshot.gcr_encode(w) == ref_line_code(w)
        assert dshot.code_to_levels(dshot.gcr_encode(w)) == ref_levels(w)
        assert dshot.gcr_decode(ref_line_code(w)) == w


def test_single_bit_errors_on_a_reply_exhaustively():
    """What holds, checked over all 4096 valid replies:
    - a flipped bit of the 16-bit word is always rejected (nibble XOR catches any 1-bit change);
    - a flipped bit of the 21-bit line code is always rejected (one quintet changes: GCR or CRC);
    - a flipped sampled level toggles two adjacent transitions; 384 of 86016 such flips (0.45 %)
      decode to a different CRC-valid word, the rest are rejected. Never the same word."""
    accepted_levels = 0
    for v12 in range(4096):
        w = dshot.reply_word(v12)
        code = dshot.gcr_encode(w)
        levels = dshot.code_to_levels(code)
        for b in range(16):
            assert not dshot.reply_crc_ok(w ^ (1 << b))
        for b in range(21):
            d = dshot.gcr_decode(code ^ (1 << b))
            assert d < 0 or not dshot.reply_crc_ok(d)
            d = dshot.gcr_decode(dshot.levels_to_code(levels ^ (1 << b)))
            if d >= 0 and dshot.reply_crc_ok(d):
                assert d != w
                accepted_levels += 1
    assert accepted_levels == 384


@FAST
@given(st.integers(0, 4095), st.integers(0, 20))
def test_flipped_level_is_rejected_or_a_different_valid_word(v12, bit):
    w = dshot.reply_word(v12)
    dec = dshot.ErpmDecoder()
    levels = dshot.code_to_levels(dshot.gcr_encode(w)) ^ (1 << bit)
    kind = dec.decode_levels(levels)
    if kind == dshot.KIND_INVALID:
        assert dec.crc_errors + dec.gcr_errors == 1
    else:
        assert dshot.gcr_decode(dshot.levels_to_code(levels)) != w


@FAST
@given(st.integers(918, 2_000_000))
def test_erpm_reply_round_trips_within_mantissa_precision(erpm):
    w = dshot.erpm_reply_word(erpm)
    assert dshot.reply_crc_ok(w)
    v = (w >> 4) & 0xFFF
    e, m = v >> 9, v & 0x1FF
    if e:
        assert m >= 256  # smallest exponent: the mantissa uses its top bit
    period = dshot.reply_period_us(w)
    exact = 60e6 / erpm
    assert abs(period - exact) <= (1 << e) + 0.5
    kind, (p, back, rpm) = dshot.decode_reply(w, 14)
    assert kind == dshot.KIND_ERPM and p == period
    assert abs(back - erpm) / erpm <= 1 / 256 + 0.6 / exact + 1 / erpm


@FAST
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=4, max_size=4),
       st.floats(0, 20), st.booleans(), st.booleans())
def test_encoder_never_leaves_0_to_2047_and_never_wraps(motors, idle_pct, bidir, stop_at_zero):
    enc = dshot.DshotEncoder(4, bidir=bidir, idle_pct=idle_pct, stop_at_zero=stop_at_zero)
    out = array("H", [0] * 4)
    enc.encode_motors(motors, True, out)
    low = 48 + round(1999 * idle_pct / 100)
    bad = 0
    for m, w in zip(motors, out, strict=True):
        assert dshot.frame_crc_ok(w, bidir)
        v = dshot.frame_value(w)
        if math.isnan(m) or m < 0 or m > 1:
            bad += 1
        if m >= 1:
            assert v == 2047
        elif math.isnan(m) or m <= 0:
            assert v == (0 if stop_at_zero else low)
        else:
            assert abs(v - (low + (2047 - low) * m)) <= 1
    assert enc.clamped == bad


@FAST
@given(st.integers(-100000, 100000))
def test_dshot_frame_clamps_any_integer(value):
    dshot.reset_frame_clamped()
    v = dshot.frame_value(dshot.dshot_frame(value))
    assert v == min(max(value, 0), 2047)
    assert dshot.frame_clamped() == (0 if 0 <= value <= 2047 else 1)


@FAST
@given(st.integers(1, 47), st.lists(st.integers(50, 3000), min_size=400, max_size=400),
       st.integers(0, (1 << 30) - 1))
def test_command_queue_sends_exact_repeats_with_gaps_at_any_frame_timing(cmd, steps_us, start_us):
    q = dshot.DshotCommandQueue()
    assert q.push(cmd, False) is True
    word = dshot.dshot_frame(cmd, 1)
    now, t, sent = start_us, 0, []
    for step in steps_us:
        if q.word(now, False, 0) == word:
            sent.append(t)
        now = ticks_add(now, step)
        t += step
    need = dshot.command_repeats(cmd)
    assert len(sent) <= need
    if t > need * 4000:
        assert len(sent) == need
    assert all(b - a >= dshot.REPEAT_GAP_US for a, b in zip(sent, sent[1:], strict=False))


@FAST
@given(st.integers(1, 47), st.integers(0, 30))
def test_command_never_reaches_an_armed_esc(cmd, arm_after):
    q = dshot.DshotCommandQueue()
    q.push(cmd, False)
    now = 0
    for i in range(100):
        armed = i >= arm_after
        w = q.word(now, armed, 0x1111)
        if armed:
            assert w == 0x1111
        now += 500


@FAST
@given(st.sampled_from(dshot.SPEEDS_KBIT), st.booleans(), st.integers(0, 0xFFFF),
       st.lists(st.integers(-8, 8), min_size=32, max_size=32))
def test_pulse_decoder_accepts_jitter_within_tolerance(speed, bidir, word, jitter_pct):
    bit_ns = dshot.dshot_timing(speed)[0]
    p = pulsetrain.render_dshot(word, speed, bidir)
    # move each edge by up to 4 % of a bit: high time and period stay within 12 %
    jittered = [(lvl, d + bit_ns * j // 200) for (lvl, d), j in zip(p, jitter_pct, strict=True)]
    assert pulsetrain.DshotPulseDecoder(speed, bidir).decode(jittered) == word


@FAST
@given(st.sampled_from((analog.PWM, analog.ONESHOT125, analog.ONESHOT42, analog.MULTISHOT)),
       st.floats(allow_nan=True, allow_infinity=True))
def test_analog_width_stays_in_range_for_any_command(proto, t):
    lo, hi = analog.pulse_range_us(proto)
    w = analog.pulse_us(proto, t)
    assert lo <= w <= hi
    dec = pulsetrain.AnalogPulseDecoder(proto)
    assert dec.decode(pulsetrain.render_analog(analog.pulse_ns(proto, t), int(hi * 1000) + 1000)) is not None
