"""The receiver stage (core/stages/receiver.py) and the RC input options it feeds (throttle bands,
alpha-beta smoothing), on a fake board: bytes or edges in, channels and the link watch out,
CRSF telemetry back. Portable: pytest on CPython, tests/portable/mprun.py under MicroPython.
"""

from array import array

from hoverfly.compat import IS_MICROPYTHON, collect_garbage, disable_gc, enable_gc, mem_alloc, ticks_add
from hoverfly.core.board import Board
from hoverfly.core.config.params import Params
from hoverfly.core.signals import Setpoint, Signals
from hoverfly.core.stages.control import MODE_ACRO, MODE_ANGLE, MODE_HORIZON
from hoverfly.core.stages.rc import RcInput
from hoverfly.core.stages.receiver import Receiver, battery_remaining_pct, cell_count, flight_mode_text
from hoverfly.protocols import crsf, ibus, sbus
from hoverfly.protocols.pulses import ppm_edges, pwm_edges

T0 = 1073741824 - 2000000  # 2 s before the 2**30 tick wrap: every test crosses it
CH = [1100, 1900, 1000, 1500, 2000, 1000, 1500, 1234, 1500, 1500, 1500, 1500, 1500, 1500, 1500, 1500]


class FakeBoard(Board):
    """Bytes or edges queued by the test come out of read_rx / read_rx_edges; telemetry is kept."""

    def __init__(self):
        self.rx = bytearray(512)
        self.rx_len = 0
        self.edges = []
        self.sent = bytearray()

    def queue(self, data):
        for b in data:
            self.rx[self.rx_len] = b
            self.rx_len += 1

    def read_rx(self, buf):
        n = self.rx_len
        if n > len(buf):
            n = len(buf)
        src = self.rx
        for i in range(n):
            buf[i] = src[i]
        for i in range(n, self.rx_len):
            src[i - n] = src[i]
        self.rx_len -= n
        return n

    def read_rx_edges(self, edges):
        n = 0
        while self.edges and n < len(edges) // 2:
            code, t = self.edges.pop(0)
            edges[2 * n] = code
            edges[2 * n + 1] = t
            n += 1
        return n

    def write_rx(self, data, n):
        self.sent += bytes(data[:n])


def _receiver(provider="crsf", **values):
    p = Params()
    p.set("rx_provider", provider)
    for name in values:
        p.set(name, values[name])
    rx = Receiver()
    rx.configure(p)
    rx.start(T0)
    return rx


def test_crsf_frame_gives_the_channels_and_stamps_the_frame():
    rx = _receiver()
    b = FakeBoard()
    assert rx.update(T0, b) == 0
    b.queue(crsf.encode_rc_frame(CH))
    now = ticks_add(T0, 4000)
    assert rx.update(now, b) == 1
    assert list(rx.channels_us) == CH
    assert rx.frames == 1 and rx.last_frame_us == now and rx.frame_age_us(ticks_add(now, 500)) == 500
    out = array("H", [0] * 18)
    rc = RcInput()  # the frame into the pilot's channels, as Flight._take_frame hands it over
    rc.configure(Params(), 1000)
    rc.new_frame(out, rx.channels_us)
    assert list(out[:16]) == CH


def test_every_serial_protocol_decodes_through_the_stage():
    for provider, frame in (("crsf", crsf.encode_rc_frame(CH)), ("sbus", sbus.encode_rc_frame(CH)),
                            ("ibus", ibus.encode_rc_frame(CH[:14]))):
        rx = _receiver(provider)
        b = FakeBoard()
        b.queue(frame)
        b.queue(frame)
        assert rx.update(T0, b) == 2, provider
        assert list(rx.channels_us[:14]) == CH[:14], provider


def test_a_frame_split_across_reads_completes_on_the_second():
    rx = _receiver("sbus")
    b = FakeBoard()
    f = sbus.encode_rc_frame(CH)
    b.queue(f[:10])
    assert rx.update(T0, b) == 0
    b.queue(f[10:])
    assert rx.update(ticks_add(T0, 2000), b) == 1
    assert rx.last_frame_us == ticks_add(T0, 2000)


def test_more_bytes_than_one_read_are_all_taken():
    rx = _receiver()
    b = FakeBoard()
    for _ in range(6):  # 156 bytes: three 64-byte reads
        b.queue(crsf.encode_rc_frame(CH))
    assert rx.update(T0, b) == 6 and b.rx_len == 0


def test_sbus_failsafe_frames_count_as_lost_not_as_sticks():
    rx = _receiver("sbus")
    b = FakeBoard()
    b.queue(sbus.encode_rc_frame(CH))
    assert rx.update(T0, b) == 1
    # the receiver lost its radio: it sends its failsafe positions, flagged
    b.queue(sbus.encode_rc_frame([1500] * 16, frame_lost=True, failsafe=True))
    later = ticks_add(T0, 9000)
    assert rx.update(later, b) == 0
    assert rx.rx_failsafe and rx.failsafe_frames == 1 and rx.frames == 1
    assert rx.last_frame_us == T0  # the link watch keeps counting from the last real frame
    # radio back
    b.queue(sbus.encode_rc_frame(CH))
    assert rx.update(ticks_add(T0, 18000), b) == 1 and not rx.rx_failsafe


def test_sbus_repeated_frames_still_fly_but_lower_the_link_quality():
    rx = _receiver("sbus")
    b = FakeBoard()
    t = T0
    for k in range(100):
        b.queue(sbus.encode_rc_frame(CH, frame_lost=(k % 10 == 0)))
        t = ticks_add(t, 10000)
        rx.update(t, b)
    assert rx.frames == 100 and rx.lost_frames == 10
    assert rx.link_quality_pct == 90  # the first full second: 100 frames, 10 of them repeats
    assert rx.frame_rate_hz == 100


def test_crc_errors_count_and_the_next_frame_decodes():
    rx = _receiver()
    b = FakeBoard()
    bad = bytearray(crsf.encode_rc_frame(CH))
    bad[10] ^= 0x40
    b.queue(bad)
    b.queue(b"\x01\x02\x03garbage")
    b.queue(crsf.encode_rc_frame(CH))
    assert rx.update(T0, b) == 1
    assert rx.errors >= 1 and list(rx.channels_us) == CH


def test_link_quality_of_serial_protocols_is_good_over_all_frames():
    rx = _receiver("ibus")
    b = FakeBoard()
    good = ibus.encode_rc_frame(CH[:14])
    bad = bytearray(good)
    bad[5] ^= 1
    t = T0
    for k in range(100):
        b.queue(bad if k % 4 == 0 else good)
        t = ticks_add(t, 10000)
        rx.update(t, b)
    assert rx.errors == 25
    assert rx.link_quality_pct == 75 and rx.frame_rate_hz == 75
    # a silent second reads 0
    t = ticks_add(t, 1000000)
    rx.update(t, b)
    assert rx.frame_rate_hz == 0 and rx.link_quality_pct == 0


def test_crsf_link_quality_and_rssi_come_from_link_statistics_and_go_stale():
    rx = _receiver()
    b = FakeBoard()
    b.queue(crsf.encode_rc_frame(CH))
    b.queue(crsf.encode_link_statistics(rssi1_dbm=-70, rssi2_dbm=-80, link_quality_pct=87, snr_db=5))
    rx.update(T0, b)
    assert rx.link_quality_pct == 87 and rx.rssi_dbm == -70 and rx.snr_db == 5
    t = ticks_add(T0, 250000)
    rx.update(t, b)
    assert rx.link_quality_pct == 87  # 250 ms: still fresh
    rx.update(ticks_add(t, 2000), b)
    assert rx.link_quality_pct == 0 and rx.rssi_dbm == 0  # Betaflight: stale after 250 ms


def test_ppm_and_pwm_edges_become_frames():
    rx = _receiver("ppm")
    b = FakeBoard()
    for level, t in ppm_edges(CH[:8], T0, frames=3):
        b.edges.append((level, t))
    # the first frame only finds the sync; the second completes at the third's first edge
    assert rx.update(ticks_add(T0, 70000), b) == 1
    assert list(rx.channels_us[:8]) == CH[:8]
    rx = _receiver("pwm", rx_pwm_channels=6)
    b = FakeBoard()
    for c, level, t in pwm_edges(CH[:6], T0):
        b.edges.append((c * 2 + level, t))
    assert rx.update(ticks_add(T0, 20000), b) == 1
    assert list(rx.channels_us[:6]) == CH[:6]
    assert rx.errors == 0


def test_bad_pulses_are_errors():
    rx = _receiver("pwm", rx_pwm_channels=2)
    b = FakeBoard()
    b.edges.extend([(1, T0), (0, ticks_add(T0, 3000)), (3, T0), (2, ticks_add(T0, 1500))])
    assert rx.update(T0, b) == 0
    assert rx.errors == 1


def test_changing_other_parameters_keeps_the_decoder_and_its_counters():
    p = Params()
    rx = Receiver()
    rx.configure(p)
    rx.start(T0)
    b = FakeBoard()
    b.queue(crsf.encode_rc_frame(CH))
    rx.update(T0, b)
    dec = rx.decoder
    p.set("deadband", 10)
    rx.configure(p)
    assert rx.decoder is dec and rx.frames == 1
    p.set("rx_provider", "sbus")
    rx.configure(p)
    assert rx.decoder is not dec and rx.telemetry is None


def test_telemetry_goes_out_right_after_an_rc_frame_at_most_every_25_ms():
    rx = _receiver()
    b = FakeBoard()
    s = Signals()
    s.battery_v = 16.0
    s.current_a = 12.3
    s.attitude.pitch_rad = 0.1
    t = T0
    sent = 0
    for k in range(100):  # 250 Hz RC frames for 200 ms, receiver task at 500 Hz
        if k % 2 == 0:
            b.queue(crsf.encode_rc_frame(CH))
        t = ticks_add(t, 2000)
        rx.update(t, b)
        if rx.telemetry_due(t):
            assert rx.new_frames > 0
            sent += 1
            rx.send_telemetry(t, b, s, MODE_ANGLE, True, False, True, 0)
    assert 7 <= sent <= 9 and rx.telemetry_frames == sent
    d = crsf.CrsfDecoder()
    d.feed(b.sent)
    assert d.crc_errors == 0 and d.other_frames == sent


def test_telemetry_refreshing_only_the_next_kind_sends_the_frames_of_refreshing_all():
    # send_telemetry sets only the kind the next frame carries; a scheduler fed every kind before each
    # poll (as it was) must give the very same bytes, with the battery, attitude and mode changing
    if not IS_MICROPYTHON:  # const() names with an underscore are no module attributes on MicroPython
        from hoverfly.core.stages import receiver as receiver_mod

        assert (receiver_mod._KIND_BATTERY, receiver_mod._KIND_ATTITUDE, receiver_mod._KIND_FLIGHT_MODE) == (
            crsf.KIND_BATTERY, crsf.KIND_ATTITUDE, crsf.KIND_FLIGHT_MODE)
    rx = _receiver()
    rx.start(T0)
    b = FakeBoard()
    ref = crsf.CrsfTelemetryScheduler(rx.telemetry.interval_us)
    out = bytearray(64)
    want = bytearray()
    s = Signals()
    t = T0
    cells = 0
    for k in range(200):
        b.queue(crsf.encode_rc_frame(CH))
        t = ticks_add(t, 4000)
        s.battery_v = 0.0 if k < 5 else 16.8 - 0.01 * k
        s.current_a = 0.1 * k
        s.mah_drawn = 2.5 * k
        s.attitude.roll_rad = 0.01 * k
        s.attitude.pitch_rad = -0.02 * k
        s.attitude.yaw_rad = 0.03 * k
        mode = k // 40
        armed = k % 3 == 0
        rx.update(t, b)
        if rx.telemetry_due(t):
            rx.send_telemetry(t, b, s, mode, k % 5 == 0, k > 150, armed, k & 6)
            v = s.battery_v
            if cells == 0 and v > 0.5:
                cells = cell_count(v)
            ref.set_battery(v, s.current_a, s.mah_drawn, battery_remaining_pct(v, cells))
            ref.set_attitude(s.attitude.pitch_rad, s.attitude.roll_rad, s.attitude.yaw_rad)
            ref.set_flight_mode(flight_mode_text(mode, k % 5 == 0, k > 150, armed, k & 6))
            n = ref.poll(t, rx.new_frames, out)
            want += out[:n]
    assert rx.telemetry_frames > 20 and bytes(b.sent) == bytes(want)


def test_no_telemetry_without_crsf_or_when_switched_off():
    b = FakeBoard()
    for rx in (_receiver("sbus"), _receiver("crsf", crsf_telemetry=0)):
        b.queue(sbus.encode_rc_frame(CH) if rx.provider == "sbus" else crsf.encode_rc_frame(CH))
        assert rx.update(T0, b) == 1
        assert not rx.telemetry_due(T0)


def test_flight_mode_text_follows_betaflight():
    assert flight_mode_text(MODE_ANGLE, True, False, True, 0) == b"ANGL"
    assert flight_mode_text(MODE_HORIZON, True, False, True, 0) == b"HOR"
    assert flight_mode_text(MODE_ACRO, True, False, True, 0) == b"AIR"
    assert flight_mode_text(MODE_ACRO, False, False, False, 0) == b"ACRO*"
    assert flight_mode_text(MODE_ACRO, False, False, False, 1 << 25) == b"ACRO*"  # only the switch toggle
    assert flight_mode_text(MODE_ACRO, False, False, False, 1 << 9) == b"ACRO!"  # booting: blocked
    assert flight_mode_text(MODE_ANGLE, False, True, True, 0) == b"!FS!"
    out = bytearray(64)
    n = crsf.encode_flight_mode(out, flight_mode_text(MODE_ACRO, False, False, False, 0))
    assert bytes(out[:n]) == bytes([0xC8, 0x08, 0x21, 0x41, 0x43, 0x52, 0x4F, 0x2A, 0x00, 0x14])  # reference §1.5


def test_battery_remaining_estimate():
    assert cell_count(16.8) == 4 and cell_count(12.6) == 3 and cell_count(25.2) == 6
    assert battery_remaining_pct(0.0, 4) == 0 and battery_remaining_pct(15.0, 0) == 0
    assert battery_remaining_pct(16.8, 4) == 100
    assert battery_remaining_pct(12.6, 3) == 100
    assert 45 <= battery_remaining_pct(4 * 3.75, 4) <= 55
    assert battery_remaining_pct(4 * 3.2, 4) == 0


def test_receiving_a_crsf_frame_allocates_nothing():
    rx = _receiver()
    b = FakeBoard()
    frame = crsf.encode_rc_frame(CH)
    b.queue(frame)
    rx.update(T0, b)
    collect_garbage()
    disable_gc()
    try:
        t = T0
        a0 = mem_alloc()
        for _ in range(20):
            b.queue(frame)
            t = ticks_add(t, 4000)
            rx.update(t, b)
        grown = mem_alloc() - a0
    finally:
        enable_gc()
    assert rx.frames == 21
    if IS_MICROPYTHON:
        assert grown == 0, grown


# -- the RC input options issue 3 asks for ------------------------------------------------


def _rc(**values):
    p = Params()
    for name in values:
        p.set(name, values[name])
    rc = RcInput()
    rc.configure(p, 1000)
    return rc


def _frame(throttle_us):
    ch = array("H", [1500] * 18)
    ch[2] = throttle_us
    ch[4] = 1000
    return ch


def test_raw_throttle_is_the_stick_percentage():
    rc = _rc()
    for us, norm in ((1000, 0.0), (1250, 0.25), (1900, 0.9), (2000, 1.0)):
        rc.new_frame(_frame(us))
        assert abs(rc.throttle_raw - norm) < 1e-9


def test_throttle_bands_pick_descend_hover_or_climb():
    rc = _rc(thr_mode="bands", thr_descend_us=1300, thr_hover_us=1450, thr_climb_us=1600)
    for us, norm in ((1000, 0.3), (1332, 0.3), (1333, 0.45), (1665, 0.45), (1666, 0.6), (2000, 0.6)):
        rc.new_frame(_frame(us))
        assert abs(rc.throttle_raw - norm) < 1e-6, us
    rc.new_frame(_frame(1000))
    assert rc.throttle_low()  # arming still reads the stick itself


def test_alpha_beta_smoothing_follows_a_step_and_alpha_one_passes_through():
    rc = _rc(rc_smooth_type="alphabeta", ab_thr_alpha=0.1, ab_thr_beta=0.005)
    sp = Setpoint()
    rc.new_frame(_frame(2000))
    for _ in range(3):
        rc.update(sp)
    assert 0.0 < sp.throttle_norm < 0.5
    for _ in range(500):
        rc.update(sp)
    assert abs(sp.throttle_norm - 1.0) < 0.01
    rc = _rc(rc_smooth_type="alphabeta", ab_thr_alpha=1.0, ab_thr_beta=0.0)
    rc.new_frame(_frame(1700))
    rc.update(sp)
    assert abs(sp.throttle_norm - 0.7) < 1e-6


def test_pt1_smoothing_is_a_choice_too():
    rc = _rc(rc_smooth_type="pt1", rc_smoothing_hz=20)
    sp = Setpoint()
    rc.new_frame(_frame(2000))
    rc.update(sp)
    assert 0.0 < sp.throttle_norm < 0.2
