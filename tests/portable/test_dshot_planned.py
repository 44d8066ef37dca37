"""The board codec's one-call DShot encode (protocols/dshot.py `encode_planned`, its viper twin
accel/dshot.py `encode_planned` on the float32 bits, and `OutputEncoder.write` on them) gives the words
made one motor at a time (`DshotEncoder._value` and the frame), their count and the clamp count for the
same commands.

Portable: on CPython (pytest) the Python twin is checked against that reference; under MicroPython
(tests/portable/mprun.py) the viper twin must be the one chosen and must give the Python twin's bits
on every input (NaN, infinities, below 0, above 1, subnormals, 1.0 and its neighbours), with the
float32 product rounding of a float32 port checked against a float32 reference (`_f32`: a product
of two float32 values is exact in a double, so one rounding through struct's 'f' is the float32
product).
"""

import struct
from array import array

from fastpathkit import heap_bytes
from test_viper_twins import Lcg

from hoverfly.compat import IS_MICROPYTHON, ticks_add
from hoverfly.core.config.params import Params
from hoverfly.core.stages.output import OutputEncoder
from hoverfly.protocols import dshot
from hoverfly.protocols.dshot import (
    DshotCommandQueue,
    DshotEncoder,
    dshot_frame,
    encode_planned,
    frame_value,
)

if IS_MICROPYTHON:
    from hoverfly.accel import dshot as dshot_viper
else:
    dshot_viper = None

NAN = float("nan")
INF = float("inf")
# DShot values 0, 48, 2047 and their neighbours, NaN, the infinities, subnormals, 1.0's neighbours
EDGES = (0.0, -0.0, 1.0, 1e-9, 1.0 - 1e-7, -1e-9, 1.0000001, NAN, INF, -INF, 0.5, 2.0 ** -16, 1.0 / 1999,
         1998.0 / 1999, 1.0 - 2.0 ** -12, 2.0 ** -30, 1e-40, -1e-40, 1e30, -1e30, 2.0, 0.99999994, 5.9e-8)
ORDERS = (b"\x00\x01\x02\x03\x04\x05\x06\x07", b"\x01\x00\x03\x02\x04\x05\x06\x07",
          b"\x03\x02\x01\x00\x07\x06\x05\x04", b"\x07\x00\x06\x01\x05\x02\x04\x03")


def _f32(x):
    return struct.unpack("<f", struct.pack("<f", x))[0]


def _todays_words(enc, norm, lines, words):
    """The words made one motor at a time (DshotEncoder._value and the frame, as the encoder's armed
    loop made them before the planned encode), motor k's word put on line k; returns how many are not
    the stop word, and counts the clamps on enc."""
    moving = 0
    stop = dshot_frame(0, 0, enc.bidir)
    for k in range(enc.motor_count):
        w = dshot_frame(enc._value(norm[k], enc._low_fp, enc._span_fp), 1 if k == enc.telemetry_motor else 0,
                        enc.bidir)
        words[lines[k]] = w
        if w != stop:
            moving += 1
    return moving


def _configs():
    rnd = Lcg(5)
    for bidir in (False, True):
        for stop in (False, True):
            for idle in (0.0, 5.5, 3.3, 37.1, 100.0):
                for tm in (-1, 0, 3):
                    count = 1 + rnd.below(8)
                    yield count, bidir, idle, stop, tm, ORDERS[rnd.below(len(ORDERS))]


def _commands(rnd, count, k):
    """count commands: -0.2 .. 1.2 at random, every third set partly from EDGES."""
    m = array("f", [0.0] * count)
    for i in range(count):
        if k % 3 == 2 and rnd.below(2):
            m[i] = EDGES[rnd.below(len(EDGES))]
        else:
            m[i] = (rnd.below(140001) - 20000) / 100000.0
    return m


def test_micropython_picks_the_viper_planned_encode_and_cpython_the_python_one():
    if IS_MICROPYTHON:
        assert dshot.encode_planned_f32 is dshot_viper.encode_planned
        assert dshot_viper.FLOAT32 == 0  # the generated twin's look at the port's float: the unix VM's are doubles
    else:
        assert dshot.encode_planned_f32 is None


def test_planned_encode_gives_encode_motors_words_and_clamp_counts():
    rnd = Lcg(11)
    for count, bidir, idle, stop, tm, lines in _configs():
        enc = DshotEncoder(count, bidir, idle, stop)
        enc.telemetry_motor = tm
        plan = enc.plan(lines)
        for k in range(60 if IS_MICROPYTHON else 20):
            m = _commands(rnd, count, k)
            want = array("H", [0xBEEF] * 8)
            got = array("H", [0xBEEF] * 8)
            enc.clamped = 0
            r = _todays_words(enc, m, lines, want)
            g = encode_planned(m, count, plan, got)
            assert list(got) == list(want), (count, bidir, idle, stop, tm, list(m), list(got), list(want))
            assert g & 0xFF == r and g >> 8 == enc.clamped, (list(m), g, r, enc.clamped)


def test_planned_encode_stops_at_the_count_it_is_given():
    enc = DshotEncoder(4, False, 5.5, True)
    plan = enc.plan(b"\x00\x01\x02\x03")
    words = array("H", [7] * 4)
    assert encode_planned(array("f", [0.5, 0.5, 2.0, 2.0]), 2, plan, words) == 2
    assert list(words[2:]) == [7, 7] and frame_value(words[0]) > 48


def _viper_against_python(plan, m, count):
    a = array("H", [0xBEEF] * 8)
    b = array("H", [0xBEEF] * 8)
    ra = encode_planned(m, count, plan, a)
    rb = dshot_viper.encode_planned(m, count, plan, b)
    assert ra == rb and list(a) == list(b), (list(plan), list(m), ra, rb, list(a), list(b))


def test_viper_planned_encode_gives_the_python_twins_bits():
    if not IS_MICROPYTHON:
        return
    rnd = Lcg(29)
    for count, bidir, idle, stop, tm, lines in _configs():
        enc = DshotEncoder(count, bidir, idle, stop)
        enc.telemetry_motor = tm
        plan = enc.plan(lines)
        for k in range(300):
            _viper_against_python(plan, _commands(rnd, count, k), count)
        for k in range(0, len(EDGES), count):
            m = array("f", [0.0] * count)
            for i in range(count):
                m[i] = EDGES[(k + i) % len(EDGES)]
            _viper_against_python(plan, m, count)
    # every float32 just below 1.0 and above 0 that a Q16 motor command can be, on one motor
    enc = DshotEncoder(1, False, 0.0, False)
    plan = enc.plan(b"\x00")
    m = array("f", [0.0])
    for c in range(0, 65537, 7):
        m[0] = c / 65536.0
        _viper_against_python(plan, m, 1)


def _float32_value(low_fp, span_fp, stop, t):
    """The DShot value a float32 port gives: span_fp * t rounded to float32, truncated."""
    if t > 1.0:
        t = 1.0
    elif not (t >= 0.0):
        if stop:
            return 0
        t = 0.0
    elif t == 0.0 and stop:
        return 0
    v = (low_fp + int(_f32(span_fp * t))) >> 16
    return 2047 if v > 2047 else v


def _tie_commands(span_fp, rnd):
    """float32 commands t whose exact product span_fp * t lies half-way between two float32 values:
    span_fp = so * 2**z (so odd), t = j * 2**-a with so * j an odd 25-bit number."""
    so = span_fp
    while so and not so & 1:
        so >>= 1
    out = []
    if not so:
        return out
    j0 = ((1 << 24) + so - 1) // so
    j1 = (1 << 25) // so
    for _ in range(40):
        if j1 <= j0:
            break
        j = j0 + rnd.below(j1 - j0)
        j |= 1
        if (so * j) >> 24 != 1 or j >= 1 << 24:
            continue
        a = 0
        while j * 2.0 ** -a > 1.0:
            a += 1
        a += rnd.below(3)
        out.append(j * 2.0 ** -a)
    return out


def test_viper_float32_products_round_as_a_float32_ports_do():
    if not IS_MICROPYTHON:
        return
    # the generated twin asks its module's FLOAT32 at every call: set, it rounds as a float32 port (a Pico)
    dshot_viper.FLOAT32 = 1
    try:
        _float32_products()
    finally:
        dshot_viper.FLOAT32 = 0


def _float32_products():
    rnd = Lcg(41)
    spans = [1999 * 65536, 2047 * 65536, 131006464, 3 << 24, 0x5F5E1 << 7, 12345677, 1]
    for idle in (0.0, 5.5, 3.3, 37.1):
        spans.append(DshotEncoder(1, False, idle, True)._span_fp)
    ties = 0
    for span_fp in spans:
        span_fp = int(_f32(span_fp))  # a float32 port's span_fp came from a float32
        for stop in (False, True):
            enc = DshotEncoder(4, False, 5.5, stop)
            low_fp = enc._low_fp
            plan = enc.plan(b"\x00\x01\x02\x03")
            plan[2] = span_fp
            tests = _tie_commands(span_fp, rnd)
            ties += len(tests)
            for _ in range(400):
                tests.append((rnd.below(1 << 24) + 1) * 2.0 ** -(24 + rnd.below(4)))
            tests.extend(EDGES)
            words = array("H", [0] * 4)
            m = array("f", [0.0] * 4)
            for t in tests:
                m[0] = t
                dshot_viper.encode_planned(m, 1, plan, words)
                assert frame_value(words[0]) == _float32_value(low_fp, span_fp, stop, m[0]), (span_fp, t)
    assert ties > 100, ties


def _product_seen(plan, m, fp_want):
    """True when the viper's floor(span_fp * t) is exactly fp_want: low_fp is put right at a DShot step
    above fp_want (so one unit less shows as a step down), then one unit lower (one unit more shows
    as a step up). The >> 16 of a word alone would hide most product errors."""
    c = (fp_want >> 16) + 1
    if c > 2047:
        return True  # the value clamps: nothing to see
    words = array("H", [0])
    plan[1] = (c << 16) - fp_want
    dshot_viper.encode_planned(m, 1, plan, words)
    at = frame_value(words[0])
    plan[1] -= 1
    dshot_viper.encode_planned(m, 1, plan, words)
    return at == c and frame_value(words[0]) == c - 1


def test_viper_products_are_the_ports_float_products_exactly():
    if not IS_MICROPYTHON:
        return
    rnd = Lcg(67)
    m = array("f", [0.0])
    for span_fp in (1999 * 65536, 2046 * 65536, 131006464, 3 << 24, 12345677, 1, 0x7FFFFFF // 65536 * 65535,
                    390625, 1000003, 390625 << 3, 8191, 4097 << 12, 6001 << 12, 3001 << 13, 8191 << 12):
        for float32 in (False, True):
            if float32:
                span_fp = int(_f32(span_fp))
            plan = DshotEncoder(1, False, 0.0, False).plan(b"\x00")
            plan[2] = span_fp
            dshot_viper.FLOAT32 = 1 if float32 else 0
            tests = _tie_commands(span_fp, rnd) + list(EDGES)
            for _ in range(300):
                tests.append((rnd.below(1 << 24) + 1) * 2.0 ** -(24 + rnd.below(30)))
            for t in tests:
                m[0] = t
                t = m[0]
                if not (0.0 < t <= 1.0):
                    continue
                p = span_fp * t  # exact in a double: at most 51 significant bits
                want = int(_f32(p)) if float32 else int(p)
                ok = _product_seen(plan, m, want)
                dshot_viper.FLOAT32 = 0
                assert ok, (span_fp, float32, t, want)
                dshot_viper.FLOAT32 = 1 if float32 else 0
    dshot_viper.FLOAT32 = 0


# ------------------------------------------------------------------------- the board codec

def _params(**values):
    p = Params()
    for name in values:
        assert p.set(name, values[name]) is None, name
    return p


def test_output_encoder_write_gives_todays_words_and_clamp_counts():
    rnd = Lcg(53)
    for order, n in ((0, 4), (2143, 4), (4321, 4), (0, 8), (321, 3)):
        for bidir in (0, 1):
            codec = OutputEncoder()
            codec.configure(_params(motor_order=order, dshot_bidir=bidir), n, 0, 0)
            codec.commands.clear()
            ref = DshotEncoder(n, bool(bidir), 0.0, True)
            want = array("H", [0] * 8)
            t = 0
            for k in range(200):
                m = _commands(rnd, n, k)
                t += 1000
                before = codec.clamped
                ref.clamped = 0
                _todays_words(ref, m, codec.line_of_motor, want)
                codec.write(m, n, t)
                assert list(codec.words[:n]) == list(want[:n]), (order, bidir, list(m))
                assert codec.clamped - before == ref.clamped
                if k % 5 == 0:  # a list (no float32 bits to read) gives the same words
                    codec.write(list(m), n, t)
                    assert list(codec.words[:n]) == list(want[:n])


def test_the_viper_write_gives_the_python_writes_words_and_counts():
    # OutputEncoder.write on MicroPython is the viper generated from it (accel/output.py): on two codecs alike
    # (boot commands queued, so their repeats go out over the stopped passes), the same words, clamp counts,
    # writes and command state as the Python write
    from hoverfly.core.stages import output as outmod

    if not IS_MICROPYTHON:
        assert OutputEncoder.write is outmod.write_python
        return
    from hoverfly.accel import output as out_viper

    assert OutputEncoder.write is out_viper.write
    assert out_viper.FLOAT32 == 0
    rnd = Lcg(61)
    for order, n, bidir, rev in ((0, 4, 0, 0), (2143, 4, 1, 5), (321, 3, 0, 2), (0, 8, 1, 0)):
        codecs = []
        for _ in range(2):
            c = OutputEncoder()
            c.configure(_params(motor_order=order, dshot_bidir=bidir, motor_reversed=rev), n, 0, 0)
            codecs.append(c)
        a, b = codecs
        t = 0
        for k in range(300):
            m = _commands(rnd, n, k) if k % 4 else array("f", [0.0] * n)  # stopped: commands go out
            t += 1000
            outmod.write_python(a, m, n, t)
            b.write(m, n, t)
            assert list(a.words) == list(b.words), (order, k, list(m))
            assert (a.clamped, a.writes, a.failsafe) == (b.clamped, b.writes, b.failsafe), (order, k)
            assert a.commands.pending == b.commands.pending and a.commands.sent == b.commands.sent, (order, k)
        assert a.commands.sent > 0  # the boot commands went out on both


def test_the_viper_write_rounds_as_a_float32_port_does():
    # Set, FLOAT32 makes the write's products round as on a float32 port (a Pico), as the planned encode's
    # viper twin does (its own float32 rounding is checked above against a float32 model)
    if not IS_MICROPYTHON:
        return
    from hoverfly.accel import output as out_viper

    rnd = Lcg(67)
    out_viper.FLOAT32 = 1
    dshot_viper.FLOAT32 = 1
    try:
        for order, n, bidir in ((0, 4, 0), (2143, 4, 1), (0, 8, 1)):
            c = OutputEncoder()
            c.configure(_params(motor_order=order, dshot_bidir=bidir), n, 0, 0)
            c.commands.clear()
            want = array("H", [0] * 8)
            for k in range(300):
                m = _commands(rnd, n, k)
                before = c.clamped
                r = dshot_viper.encode_planned(m, n, c._plan, want)
                c.write(m, n, 1000 * k)
                assert list(c.words) == list(want), (order, k, list(m))
                assert c.clamped - before == r >> 8, (order, k)
    finally:
        out_viper.FLOAT32 = 0
        dshot_viper.FLOAT32 = 0


def test_output_encoder_write_allocates_nothing_on_micropython():
    codec = OutputEncoder()
    codec.configure(_params(dshot_bidir=1, motor_order=2143), 4, 0, 0)
    codec.commands.clear()
    m = array("f", [0.3, 1.5, float("nan"), 0.7])
    codec.write(m, 4, 1000)
    assert heap_bytes(lambda: codec.write(m, 4, 2000), 50) == 0


def test_pending_is_busy_through_push_repeats_waits_and_arming():
    q = DshotCommandQueue(False, 4)
    words = array("H", [0] * 4)
    t = ticks_add(0, -20000)
    assert q.pending is False and not q.busy()
    q.push(dshot.CMD_BEEP1, False)
    q.push(dshot.CMD_3D_MODE_OFF, False, 2)
    seen_busy = 0
    for k in range(2000):  # 500 ms: the beep's 260 ms wait, then ten 3D-off repeats 1 ms apart
        t = ticks_add(t, 250)
        q.apply(t, False, words)
        assert q.pending == q.busy(), k
        seen_busy += q.busy()
    assert not q.busy() and 0 < seen_busy < 2000 and q.sent == 11, (seen_busy, q.sent)
    q.push(dshot.CMD_BEEP2, False)
    assert q.pending
    q.apply(ticks_add(t, 250), True, words)  # armed: dropped
    assert not q.pending and not q.busy() and q.aborted == 1
    q.push(dshot.CMD_BEEP2, False)
    q.clear()
    assert not q.pending and not q.busy()


def test_an_idle_queue_is_skipped_and_a_pushed_command_still_goes_out():
    codec = OutputEncoder()
    codec.configure(_params(), 4, 0, 0)
    stop = array("f", [0.0] * 4)
    t = 0
    for _ in range(30):
        t += 1000
        codec.write(stop, 4, t)
    assert not codec.commands.pending and codec.commands.sent == 10
    assert codec.words[0] == dshot_frame(0)
    codec.commands.push(dshot.CMD_BEEP3, False, 1)
    codec.write(stop, 4, t + 1000)
    assert frame_value(codec.words[1]) == dshot.CMD_BEEP3 and codec.words[0] == dshot_frame(0)


def test_a_reconfigured_encoder_forgets_the_array_it_read_as_dshot():
    codec = OutputEncoder()
    codec.configure(_params(), 4, 0, 0)
    m = array("f", [0.5, 0.5, 0.5, 0.5])
    codec.write(m, 4, 1000)
    assert frame_value(codec.words[0]) > 48
    codec.configure(_params(motor_protocol="pwm"), 4, 0, 2000)
    words = list(codec.words)
    codec.write(m, 4, 3000)  # the same array: now pulse widths, the words untouched
    assert abs(codec.pulse_us[0] - 1500.0) < 1e-3 and list(codec.words) == words
    assert codec.writes == 2 and not codec.failsafe
