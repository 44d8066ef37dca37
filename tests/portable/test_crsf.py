"""CRSF codec: the reference vectors (reference/protocols.md §1) both ways, framing, telemetry scheduling.

Plain asserts: runs under pytest and under MicroPython (tests/portable/mprun.py).
"""

from hoverfly.protocols import crsf
from hoverfly.protocols.rxfactory import make_decoder

RC_CENTRE = bytes.fromhex("C8 18 16 E0 03 1F F8 C0 07 3E F0 81 0F 7C E0 03 1F F8 C0 07 3E F0 81 0F 7C AD")
RC_MIXED = bytes.fromhex("C8 18 16 AC 98 38 F8 7E 01 70 FA A0 8F BB 00 F8 3F 2B C0 37 71 F0 B1 02 7C A4")
RC_MIXED_RAW = [172, 1811, 992, 191, 1792, 500, 1000, 1500, 0, 2047, 172, 992, 1811, 992, 172, 992]
LINK_1 = bytes.fromhex("C8 0C 14 3C 41 64 09 00 04 03 46 62 FE CD")
LINK_2 = bytes.fromhex("C8 0C 14 69 6E 23 F9 01 02 01 5A 32 F6 17")
DEG = 0.017453292519943295


def _fed(*chunks):
    d = crsf.CrsfDecoder()
    done = 0
    for c in chunks:
        done += d.feed(c)
    return d, done


def test_all_centre_vector_decodes_to_992_ticks_and_1500_us():
    d, done = _fed(RC_CENTRE)
    assert done == 1 and d.frames == 1
    assert list(d.channels_raw) == [992] * 16
    assert list(d.channels_us) == [1500] * 16
    assert d.crc_errors == 0 and d.resyncs == 0 and d.bytes == 26 and d.last_type == 0x16


def test_mixed_vector_decodes_channel_1_first():
    d, done = _fed(RC_MIXED)
    assert done == 1
    assert list(d.channels_raw) == RC_MIXED_RAW
    assert list(d.channels_us[:5]) == [988, 2011, 1500, 1000, 2000]


def test_vectors_encode_byte_exact():
    assert bytes(crsf.encode_rc_frame([1500] * 16)) == RC_CENTRE
    assert bytes(crsf.encode_rc_frame([])) == RC_CENTRE  # missing channels are 1500 µs
    assert bytes(crsf.encode_rc_frame_raw(RC_MIXED_RAW)) == RC_MIXED


def test_ticks_to_us_follows_the_tbs_integer_formula():
    # reference/protocols.md §1.3 table, TBS column
    table = ((0, 880), (172, 988), (191, 1000), (992, 1500), (1792, 2000), (1811, 2011), (2047, 2159))
    for ticks, us in table:
        assert crsf.us_of_ticks(ticks) == us, ticks
        assert crsf.US_OF_TICKS[ticks] == us


def test_us_to_ticks_matches_the_reference_reverse_points():
    assert crsf.ticks_of_us(1000) == 192
    assert crsf.ticks_of_us(1500) == 992
    assert crsf.ticks_of_us(2000) == 1792


def test_decode_of_encode_is_exact_over_the_whole_tick_range():
    for us in range(880, 2160):
        assert crsf.us_of_ticks(crsf.ticks_of_us(us)) == us, us
    assert crsf.ticks_of_us(500) == 0 and crsf.ticks_of_us(3000) == 2047


def test_round_trip_through_frames_keeps_every_us_value_from_988_to_2012():
    d = crsf.CrsfDecoder()
    out = bytearray(26)
    for base in range(988, 2013, 16):
        chans = [min(base + k, 2012) for k in range(16)]
        crsf.encode_rc_frame(chans, out)
        assert d.feed(out) == 1
        assert list(d.channels_us) == chans


def test_link_statistics_vectors_decode():
    d, done = _fed(LINK_1)
    assert done == 0 and d.frames == 0 and d.link_stats_frames == 1 and d.last_type == 0x14
    assert (d.rssi1_dbm, d.rssi2_dbm, d.rssi_dbm) == (-60, -65, -60)
    assert (d.link_quality_pct, d.snr_db, d.active_antenna, d.rf_mode) == (100, 9, 0, 4)
    assert (d.tx_power, d.tx_power_mw) == (3, 100)
    assert (d.downlink_rssi_dbm, d.downlink_link_quality_pct, d.downlink_snr_db) == (-70, 98, -2)
    d.feed(LINK_2)
    assert d.link_stats_frames == 2
    assert (d.rssi1_dbm, d.rssi2_dbm, d.rssi_dbm) == (-105, -110, -110)  # antenna 2 active
    assert (d.link_quality_pct, d.snr_db, d.rf_mode, d.tx_power_mw) == (35, -7, 2, 10)
    assert (d.downlink_rssi_dbm, d.downlink_link_quality_pct, d.downlink_snr_db) == (-90, 50, -10)


def test_link_statistics_vectors_encode():
    a = crsf.encode_link_statistics(-60, -65, 100, 9, 0, 4, 3, -70, 98, -2)
    b = crsf.encode_link_statistics(-105, -110, 35, -7, 1, 2, 1, -90, 50, -10)
    assert bytes(a) == LINK_1 and bytes(b) == LINK_2


def test_battery_vectors():
    out = bytearray(64)
    n = crsf.encode_battery(out, 16.8, 12.3, 1234, 75)
    assert bytes(out[:n]) == bytes.fromhex("C8 0A 08 00 A8 00 7B 00 04 D2 4B C8")
    n = crsf.encode_battery(out, 25.2, 0.0, 0, 100)
    assert bytes(out[:n]) == bytes.fromhex("C8 0A 08 00 FC 00 00 00 00 00 64 8E")


def test_attitude_vectors_pitch_first_yaw_wrapped():
    out = bytearray(64)
    n = crsf.encode_attitude(out, 10.0 * DEG, -5.5 * DEG, 90.0 * DEG)
    assert bytes(out[:n]) == bytes.fromhex("C8 08 1E 06 D1 FC 41 3D 5B 09")
    n = crsf.encode_attitude(out, -30.0 * DEG, 179.9 * DEG, 270.0 * DEG)
    assert bytes(out[:n]) == bytes.fromhex("C8 08 1E EB 8D 7A A6 C2 A5 27")


def test_flight_mode_vectors():
    out = bytearray(64)
    n = crsf.encode_flight_mode(out, "ACRO*")
    assert bytes(out[:n]) == bytes.fromhex("C8 08 21 41 43 52 4F 2A 00 14")
    n = crsf.encode_flight_mode(out, b"ANGL")
    assert bytes(out[:n]) == bytes.fromhex("C8 07 21 41 4E 47 4C 00 A7")
    n = crsf.encode_flight_mode(out, "ACRO!")
    assert bytes(out[:n]) == bytes.fromhex("C8 08 21 41 43 52 4F 21 00 51")
    assert crsf.encode_flight_mode(out, "X" * 40) == 15 + 5  # cut to 15 characters + NUL


def test_gps_vectors():
    out = bytearray(64)
    n = crsf.encode_gps(out, 473977419, 85455938, 10.0, 123.4 * DEG, 500.0, 12)
    assert bytes(out[:n]) == bytes.fromhex("C8 11 02 1C 40 52 4B 05 17 F4 42 01 68 30 34 05 DC 0C 4F")
    n = crsf.encode_gps(out, -338688197, 1512092955, 0.0, 0.0, -20.0, 5)
    assert bytes(out[:n]) == bytes.fromhex("C8 11 02 EB D0 07 3B 5A 20 B5 1B 00 00 00 00 03 D4 05 65")


def test_telemetry_frames_decode_as_other_frames():
    out = bytearray(64)
    d = crsf.CrsfDecoder()
    n = crsf.encode_battery(out, 16.8, 12.3, 1234, 75)
    assert d.feed(out, n) == 0
    assert d.other_frames == 1 and d.last_type == 0x08 and d.crc_errors == 0


def test_extended_frames_are_counted_with_their_addresses():
    ping = bytes.fromhex("C8 04 28 00 EA 54")
    bind = bytes.fromhex("C8 07 32 EC C8 10 01 9E E8")
    msp = bytes.fromhex("C8 07 7A C8 EA 30 00 01 BD")
    d, done = _fed(ping)
    assert done == 0 and d.extended_frames == 1 and (d.last_type, d.last_dest, d.last_origin) == (0x28, 0x00, 0xEA)
    d.feed(bind)
    assert (d.last_type, d.last_dest, d.last_origin) == (0x32, 0xEC, 0xC8)
    d.feed(msp + RC_CENTRE)
    assert d.extended_frames == 3 and d.frames == 1 and d.crc_errors == 0 and d.resyncs == 0


def test_frame_split_at_every_byte_boundary_decodes():
    for cut in range(1, 26):
        d, done = _fed(RC_MIXED[:cut], RC_MIXED[cut:])
        assert done == 1 and list(d.channels_raw) == RC_MIXED_RAW, cut
        assert d.resyncs == 0 and d.crc_errors == 0 and d.bytes == 26


def test_byte_at_a_time_decodes_every_frame():
    stream = RC_CENTRE + LINK_1 + RC_MIXED
    d = crsf.CrsfDecoder()
    done = 0
    for b in stream:
        done += d.feed(bytes((b,)))
    assert done == 2 and d.link_stats_frames == 1 and list(d.channels_raw) == RC_MIXED_RAW


def test_garbage_before_and_between_frames_is_skipped_and_counted():
    garbage = bytes((0x55, 0x01, 0xFF, 0x16, 0x18))  # no sync bytes
    d, done = _fed(garbage + RC_CENTRE + garbage + RC_MIXED)
    assert done == 2 and d.frames == 2
    assert d.resyncs == 10 and d.crc_errors == 0
    assert list(d.channels_raw) == RC_MIXED_RAW


def test_bad_crc_is_counted_and_the_next_frame_decodes():
    bad = bytearray(RC_CENTRE)
    bad[10] ^= 0x40
    d, done = _fed(bytes(bad) + RC_MIXED)
    assert done == 1 and d.crc_errors == 1 and d.frames == 1
    assert list(d.channels_raw) == RC_MIXED_RAW


def test_truncated_frame_followed_by_a_good_one_recovers():
    d, done = _fed(RC_CENTRE[:14] + RC_MIXED + RC_MIXED)
    assert d.crc_errors >= 1
    assert d.frames >= 1 and list(d.channels_raw) == RC_MIXED_RAW


def test_impossible_length_byte_counts_a_length_error():
    d, done = _fed(bytes((0xC8, 0x01, 0xC8, 0x50)) + RC_CENTRE)
    assert done == 1 and d.length_errors == 2 and d.resyncs == 4  # both syncs and both lengths skipped


def test_rc_frame_too_short_for_16_channels_is_a_length_error():
    out = bytearray(64)
    out[2] = 0x16
    for k in range(3, 13):
        out[k] = 0x11
    n = crsf._finish(out, 14)  # a 10-byte "RC" payload with a good CRC
    d, done = _fed(bytes(out[:n]) + RC_CENTRE)
    assert done == 1 and d.length_errors == 1 and d.crc_errors == 0


def test_longer_rc_payload_from_a_newer_sender_is_accepted():
    out = bytearray(64)
    frame = crsf.encode_rc_frame_raw(RC_MIXED_RAW)
    for k in range(2, 25):
        out[k] = frame[k]
    out[25] = 0x77  # one extra payload byte
    n = crsf._finish(out, 27)
    d, done = _fed(bytes(out[:n]))
    assert done == 1 and list(d.channels_raw) == RC_MIXED_RAW


def test_other_sync_bytes_are_accepted():
    for sync in (0xEA, 0xEC, 0xEE, 0x00):
        d, done = _fed(bytes(crsf.encode_rc_frame_raw(RC_MIXED_RAW, sync=sync)))
        assert done == 1, sync


def test_feed_takes_only_the_first_n_bytes_of_a_memoryview():
    buf = bytearray(64)
    buf[: len(RC_CENTRE)] = RC_CENTRE
    d = crsf.CrsfDecoder()
    assert d.feed(memoryview(buf), 26) == 1 and d.bytes == 26
    assert d.feed(memoryview(buf), 0) == 0 and d.bytes == 26


def test_idle_drops_a_partial_frame():
    d, _ = _fed(RC_CENTRE[:10])
    d.idle()
    assert d.length_errors == 1
    assert d.feed(RC_MIXED) == 1


def test_scheduler_sends_nothing_without_an_rc_frame_or_data():
    s = crsf.CrsfTelemetryScheduler()
    out = bytearray(64)
    assert s.poll(0, 1, out) == 0  # no data yet
    s.set_battery(16.8, 12.3, 1234, 75)
    assert s.poll(0, 0, out) == 0  # no RC frame this pass
    assert s.poll(0, 1, out) == 12
    assert bytes(out[:12]) == bytes.fromhex("C8 0A 08 00 A8 00 7B 00 04 D2 4B C8")


def test_scheduler_round_robins_over_kinds_with_data_at_its_interval():
    s = crsf.CrsfTelemetryScheduler(interval_us=10000)
    out = bytearray(64)
    s.set_battery(16.8, 12.3, 1234, 75)
    s.set_flight_mode(b"ACRO*")
    s.set_attitude(0.1, 0.0, 0.0)
    kinds = []
    t = 1000
    for _ in range(40):  # RC at 1 kHz for 40 ms: 4 frames at most
        if s.poll(t, 1, out):
            kinds.append(out[2])
        t += 1000
    assert kinds == [0x08, 0x1E, 0x21, 0x08]
    s.clear(crsf.KIND_BATTERY)
    s.set_gps(473977419, 85455938, 10.0, 0.0, 500.0, 12)
    kinds = []
    for _ in range(40):
        if s.poll(t, 1, out):
            kinds.append(out[2])
        t += 1000
    assert 0x08 not in kinds and 0x02 in kinds and len(kinds) == 4


def test_make_decoder_builds_each_protocol():
    assert make_decoder("crsf").feed(RC_CENTRE) == 1
    for name in ("sbus", "ibus", "ppm", "pwm"):
        assert make_decoder(name).frames == 0
    try:
        make_decoder("dsm")
        raised = False
    except ValueError:
        raised = True
    assert raised


def test_telemetry_encoders_take_nan_and_infinity_without_raising_or_hanging():
    # given values a failing sensor or estimator could hand over, when each telemetry frame is encoded,
    # then it is a valid frame with the field at 0 or clamped: never an exception in the receiver task,
    # never an endless angle wrap
    from hoverfly.protocols.crsf import encode_attitude, encode_battery, encode_gps

    nan = float("nan")
    inf = float("inf")
    out = bytearray(32)
    for bad in (nan, inf, -inf, 1e300, -1e300):
        assert encode_battery(out, bad, bad, bad, bad) == 12
        assert out[11] == crsf.crc8_dvb_s2(out[2:11])
        assert encode_attitude(out, bad, bad, bad) == 10
        assert encode_gps(out, bad, bad, bad, bad, bad, bad) == 19
    encode_battery(out, nan, inf, -inf, nan)
    assert out[3:11] == bytes([0, 0, 0xFF, 0xFF, 0, 0, 0, 0])  # NaN 0, +inf clamped, -inf 0
    encode_attitude(out, nan, inf, 0.5)
    assert out[3:9] == bytes([0, 0, 0, 0, 0x13, 0x88])  # no angle for NaN/inf; 0.5 rad is 5000
    # integer degrees x 1e7 pass as they are (a float would lose their last digits on a float32 port)
    encode_gps(out, 473977418, -1223312345, 0.0, 0.0, 0.0, 7)
    assert out[3:7] == (473977418).to_bytes(4, "big")
    assert out[7:11] == (-1223312345 & 0xFFFFFFFF).to_bytes(4, "big")
