"""Every wire parser under mutated streams: it never raises, and a good frame after the damage is read.

Given a stream of valid frames of each protocol (CRSF, SBUS, iBUS, MSP, maintenance, the firmware
bridge) that has been damaged (bits flipped, bytes inserted, deleted, duplicated, cut, huge
lengths written over a header) and is fed in arbitrary chunks, when the parser takes it, then no
exception escapes, its counters stay sane, and after the line goes quiet (`idle()`, or for the
bridge a run of filler as long as its largest frame) the next good frame is decoded exactly.
The same for DShot replies (random 21-bit line codes, words and pulse trains), PWM/PPM capture
(random edge trains, then a clean train) and, in tests/test_log_reader_fuzz.py, ULog files.

What exists elsewhere and is not repeated here: random bytes and chunking invariance for the RC
decoders (test_rx_fuzz.py), MSP and maintenance framing properties (test_msp_props.py,
test_maintenance_props.py), DShot single-bit errors (test_esc_props.py), the bridge's queue
(test_bridge_integrity.py). bench/fuzz.py runs these mutations at 10^6 inputs per parser.
"""

from hypothesis import given, settings
from hypothesis import strategies as st

from hoverfly.compat import TICKS_MAX, ticks_add
from hoverfly.protocols import bridge, crsf, dshot, ibus, maintenance, msp, pulsetrain, sbus
from hoverfly.protocols.pulses import PpmCapture, PwmCapture, ppm_edges, pwm_edges

FUZZ = settings(max_examples=150, derandomize=True, deadline=None)

raw_channels = st.lists(st.integers(0, 1400), min_size=16, max_size=16)
_MAINT_REQUESTS = [
    bytes(maintenance.encode_request(["body_roll", "body_pitch"])),
    bytes(maintenance.encode_request([], maintenance.CMD_SET_ALL_MOTORS, (0,))),
    bytes(maintenance.encode_request(["raw_gyro_x", "throttle_signal"], maintenance.CMD_SET_ROLL_PID,
                                     (1.0, 0.1, 0.01, 0.0, 0.0, 0.0))),
]


# ------------------------------------------------------------------ one adapter per byte parser
class _Rc:
    """CRSF / SBUS / iBUS: good frame = 16 channels; read back = the decoder's raw channels."""

    def __init__(self, make, encode, n, offset=0):
        self.make, self.encode, self.n, self.offset = make, encode, n, offset

    def good(self, raw):
        return bytes(self.encode(raw))

    def feed(self, p, chunk):
        p.feed(chunk)

    def quiet(self, p):
        p.idle()
        return b""

    def read_back(self, p, before):
        return p.frames > before


class _Msp:
    def make(self):
        return msp.MspParser()

    def good(self, raw):
        return msp.encode_request(raw[0] % 256, bytes(v & 0xFF for v in raw[: raw[1] % 17]))

    def feed(self, p, chunk):
        p.feed(chunk)
        while p.pop():
            pass

    def quiet(self, p):
        p.idle()
        return b""


class _Maint:
    def make(self):
        return maintenance.MaintenanceParser()

    def good(self, raw):
        return _MAINT_REQUESTS[raw[0] % len(_MAINT_REQUESTS)]

    def feed(self, p, chunk):
        p.feed(chunk)
        while p.pop():
            pass

    def quiet(self, p):
        p.idle()
        return b""


class _Bridge:
    def make(self):
        return bridge.BridgeDecoder()

    def good(self, raw):
        return bridge.frame(bridge.KINDS[raw[0] % len(bridge.KINDS)], bytes(v & 0xFF for v in raw[: raw[1] % 17]))

    def feed(self, p, chunk):
        p.feed(chunk)
        while p.pop() >= 0:
            pass

    def quiet(self, p):
        # No idle on a lockstep link: a false length swallows at most a largest frame's worth.
        return b"\x00" * (bridge.MAX_PAYLOAD + bridge.OVERHEAD)


PARSERS = {
    "crsf": _Rc(crsf.CrsfDecoder, crsf.encode_rc_frame_raw, 16),
    "sbus": _Rc(sbus.SbusDecoder, sbus.encode_rc_frame_raw, 16),
    "ibus": _Rc(ibus.IbusDecoder, lambda raw: ibus.encode_rc_frame_raw([v + 800 for v in raw[:14]]), 14, 800),
    "msp": _Msp(),
    "maintenance": _Maint(),
    "bridge": _Bridge(),
}


@st.composite
def mutated(draw, good):
    """A stream of good frames, then damaged: the kinds of damage a UART, a socket or a fuzzer makes."""
    d = bytearray()
    for _ in range(draw(st.integers(1, 5))):
        d += good(draw(raw_channels))
    for _ in range(draw(st.integers(1, 8))):
        op = draw(st.sampled_from(("flip", "insert", "delete", "dup", "huge", "byte")))
        p = draw(st.integers(0, max(0, len(d) - 1)))
        if op == "flip" and d:
            d[p] ^= 1 << draw(st.integers(0, 7))
        elif op == "insert":
            d[p:p] = draw(st.binary(min_size=1, max_size=40))
        elif op == "delete":
            del d[p : p + draw(st.integers(1, 8))]
        elif op == "dup":
            d[p:p] = d[p : p + draw(st.integers(1, 30))]
        elif op == "huge" and len(d) > p + 1:
            d[p : p + 2] = b"\xff\xff"
        elif op == "byte" and d:
            d[p] = draw(st.sampled_from((0x00, 0x0F, 0x20, 0x24, 0x23, 0xB5, 0xC8, 0xFF)))
    if draw(st.booleans()):
        d = d[: draw(st.integers(0, len(d)))]
    return bytes(d)


def _chunks(draw, data):
    out = []
    p = 0
    while p < len(data):
        n = draw(st.integers(1, 80))
        out.append(data[p : p + n])
        p += n
    return out


@FUZZ
@given(name=st.sampled_from(sorted(PARSERS)), data=st.data())
def test_a_mutated_stream_never_raises_and_the_next_good_frame_after_a_quiet_line_is_read(name, data):
    a = PARSERS[name]
    p = a.make()
    stream = data.draw(mutated(a.good))
    for chunk in _chunks(data.draw, stream):
        a.feed(p, chunk)
    filler = a.quiet(p)
    raw = data.draw(raw_channels)
    good = a.good(raw)
    if name in ("crsf", "sbus", "ibus"):
        before = p.frames
        p.feed(filler + good)
        assert p.frames == before + 1
        assert list(p.channels_raw[: a.n]) == [v + a.offset for v in raw[: a.n]]
    elif name == "msp":
        p.feed(good)
        assert p.pop() and p.cmd == raw[0] % 256 and p.message() == bytes(v & 0xFF for v in raw[: raw[1] % 17])
    elif name == "maintenance":
        p.feed(good)
        assert p.pop() and bytes(p.header) == good[1 : 1 + maintenance.HEADER_LEN]
    else:
        while p.pop() >= 0:  # frames the damaged stream completed before the filler
            pass
        p.feed(filler)
        while p.pop() >= 0:  # a damaged frame the filler completed: its CRC-8 matches one time in 256
            pass
        p.feed(good)
        kind = p.pop()
        assert kind == good[1] and bytes(p.payload[: p.length]) == good[bridge.HEADER : -1]
        assert p.pop() == -1


@FUZZ
@given(name=st.sampled_from(sorted(PARSERS)), data=st.binary(max_size=600))
def test_random_bytes_in_any_parser_never_raise(name, data):
    a = PARSERS[name]
    p = a.make()
    a.feed(p, data)
    a.feed(p, data[::-1])


# ------------------------------------------------------------------ DShot replies
@FUZZ
@given(codes=st.lists(st.integers(0, (1 << 21) - 1), max_size=50), words=st.lists(st.integers(0, 0xFFFF), max_size=50),
       erpm=st.integers(0, 200000), edt=st.booleans())
def test_dshot_reply_decoder_takes_any_code_or_word_and_then_reads_a_good_reply(codes, words, erpm, edt):
    d = dshot.ErpmDecoder(edt=edt)
    for c in codes:
        d.decode_code(c)
    for w in words:
        d.decode_word(w)
    assert d.frames + d.crc_errors + d.gcr_errors == len(codes) + len(words)
    word = dshot.erpm_reply_word(erpm)
    d.edt = False
    assert d.decode_code(dshot.gcr_encode(word)) == dshot.KIND_ERPM
    assert d.erpm == dshot.decode_reply(word, edt=False)[1][1]


@FUZZ
@given(pulses=st.lists(st.tuples(st.integers(-1, 2), st.integers(-5, 20000)), max_size=60),
       speed=st.sampled_from((150, 300, 600, 1200)), word=st.integers(0, 0xFFFF))
def test_dshot_pulse_decoders_take_any_pulse_train_and_still_read_a_clean_one(pulses, speed, word):
    dec = pulsetrain.DshotPulseDecoder(speed, False)
    dec.decode(pulses)
    reply = pulsetrain.ReplyPulseDecoder(speed)
    reply.decode_code(pulses)
    frame = dshot.dshot_frame(word & 0x7FF, word >> 15 & 1)
    assert dec.decode(pulsetrain.render_dshot(frame, speed)) == frame


# ------------------------------------------------------------------ PWM / PPM capture
@FUZZ
@given(events=st.lists(st.tuples(st.integers(-3, 20), st.integers(0, 1), st.integers(0, 60000)), max_size=150),
       chans=st.lists(st.integers(800, 2200), min_size=4, max_size=8), t0=st.integers(0, TICKS_MAX))
def test_pwm_and_ppm_capture_take_any_edges_then_read_a_clean_train(events, chans, t0):
    pwm = PwmCapture(len(chans))
    ppm = PpmCapture()
    t = t0
    for ch, lv, dt in events:
        t = ticks_add(t, dt)
        pwm.edge(ch, lv, t)
        ppm.edge(lv, t)
    t = ticks_add(t, 30000)  # a gap longer than a frame: the next train starts clean
    got_pwm = 0
    for _ in range(2):
        for c, lv, tt in pwm_edges(chans, t):
            got_pwm += pwm.edge(c, lv, tt)
        t = ticks_add(t, 25000)
    assert got_pwm >= 1 and list(pwm.channels_us[: len(chans)]) == chans
    got_ppm = sum(ppm.edge(lv, tt) for lv, tt in ppm_edges(chans, t, frame_us=22500, frames=3))
    assert got_ppm >= 1 and list(ppm.channels_us[: len(chans)]) == chans


def test_the_adapters_read_their_own_good_frames():
    # the property above is only as good as its frames: each adapter's good frame decodes clean
    raw = list(range(100, 1700, 100))
    for name, a in PARSERS.items():
        p = a.make()
        if name in ("crsf", "sbus", "ibus"):
            p.feed(a.good(raw))
            assert p.frames == 1, name
        elif name == "bridge":
            p.feed(a.good(raw))
            assert p.pop() >= 0
        else:
            p.feed(a.good(raw))
            assert p.pop(), name
