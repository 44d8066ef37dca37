"""The viper accel twins give the same bytes and bits as their pure-Python twins.

Portable: under MicroPython (tests/portable/mprun.py) each viper twin (accel/rxcodec.py and
accel/crc.py, generated from protocols/rxcodec.py and crc.py by hoverfly.fastgen; accel/dshot.py)
must be the one its module chose, and is run side by side with the Python twin
on pseudo-random inputs (an LCG: the same sequence on every port) plus edge cases; every output
must match. On CPython (pytest) there is no viper: the modules must have kept the Python twins,
and those must still decode and encode.
The MPU-6050 read's twins: tests/portable/test_mpu6050_twins.py.
"""

from array import array

from hoverfly.compat import IS_MICROPYTHON
from hoverfly.protocols import crc, crsf, dshot, rxcodec

if IS_MICROPYTHON:
    from hoverfly.accel import crc as crc_viper
    from hoverfly.accel import dshot as dshot_viper
    from hoverfly.accel import rxcodec as rx_viper
else:
    crc_viper = rx_viper = dshot_viper = None


class Lcg:
    """Deterministic integers (the constants of tests/portable/fastpathkit.py's Rand)."""

    def __init__(self, seed):
        self.s = seed

    def below(self, n):
        self.s = (self.s * 1103515245 + 12345) & 0x7FFFFFFF
        return (self.s >> 8) % n

    def fill(self, buf, start, end):
        for k in range(start, end):
            buf[k] = self.below(256)


def _channels(fill):
    return array("H", [fill] * 16)


# ---------------------------------------------------------------------------------------- CRSF

def _rc_frame(raw, at=0, size=26):
    """A valid CRSF RC frame from 16 wire values, placed at `at` in a buffer of `size` bytes."""
    buf = bytearray(size)
    frame = crsf.encode_rc_frame_raw(raw)
    for k in range(26):
        buf[at + k] = frame[k]
    return buf


def _check_both(buf, p):
    """Both check_unpack11 twins on buf at p, from the same pre-filled arrays; asserts they agree."""
    ra, ua = _channels(0xAAAA), _channels(0x5555)
    rb, ub = _channels(0xAAAA), _channels(0x5555)
    got_py = rxcodec._check_unpack11_indexed(buf, p, ra, ua, crsf.US_OF_TICKS, crc.CRC8_DVB_S2_TABLE)
    got_v = rx_viper.check_unpack11(buf, p, rb, ub, crsf.US_OF_TICKS, crc.CRC8_DVB_S2_TABLE)
    assert got_py == got_v, (bytes(buf), p)
    assert list(ra) == list(rb) and list(ua) == list(ub), (bytes(buf), p, list(ra), list(rb))
    return got_py


def test_micropython_picks_the_viper_twins_and_cpython_the_python_ones():
    if IS_MICROPYTHON:
        assert rxcodec.check_unpack11 is rx_viper.check_unpack11
        assert rxcodec.unpack11 is rx_viper.unpack11
        assert crsf._check_unpack11 is rx_viper.check_unpack11
        assert crsf._unpack11 is rx_viper.unpack11
        assert crsf._crc8 is crc_viper.crc8_dvb_s2_span
        assert dshot.encode_planned_f32 is dshot_viper.encode_planned
    else:
        assert crsf._check_unpack11 is rxcodec.check_unpack11 is rxcodec._check_unpack11_struct
        assert crsf._unpack11 is rxcodec.unpack11 is rxcodec._unpack11_struct
        assert crsf._crc8 is crc.crc8_dvb_s2_span
        assert dshot.encode_planned_f32 is None


def test_crsf_decoder_decodes_an_rc_frame_through_the_chosen_twin():
    dec = crsf.CrsfDecoder()
    us = [988, 2011, 1500, 1000, 2000, 1193, 1505, 1817, 1200, 1800, 988, 1500, 2011, 1500, 988, 1500]
    assert dec.feed(crsf.encode_rc_frame(us)) == 1
    assert list(dec.channels_us) == us
    # the framer's path: garbage first, then the frame, then a link statistics frame
    data = bytearray(b"\x01\x02") + crsf.encode_rc_frame(us[::-1]) + crsf.encode_link_statistics(rssi1_dbm=-70)
    assert dec.feed(data) == 1
    assert list(dec.channels_us) == us[::-1]
    assert dec.rssi1_dbm == -70 and dec.link_stats_frames == 1 and dec.crc_errors == 0


def test_crsf_check_unpack11_twins_agree_on_random_frames():
    if not IS_MICROPYTHON:
        return
    rnd = Lcg(7)
    good = bad = 0
    for n in range(400):
        at = rnd.below(8)
        raw = array("H", [rnd.below(2048) for _ in range(16)])
        buf = _rc_frame(raw, at, 26 + 8)
        kind = n % 4
        if kind == 1:  # one flipped bit anywhere in type, channels or CRC: a CRC error
            k = at + 2 + rnd.below(24)
            buf[k] ^= 1 << rnd.below(8)
        elif kind == 2:  # random bytes: almost always a CRC error, now and then a pass
            rnd.fill(buf, at + 2, at + 26)
        if _check_both(buf, at + 2):
            good += 1
        else:
            bad += 1
    assert good >= 200 and bad >= 150, (good, bad)


def test_crsf_check_unpack11_twins_agree_on_edge_frames():
    if not IS_MICROPYTHON:
        return
    for v in (0, 2047, 172, 992, 1811):
        assert _check_both(_rc_frame(array("H", [v] * 16)), 2) == 1
    alt = array("H", [0, 2047] * 8)
    assert _check_both(_rc_frame(alt), 2) == 1
    assert _check_both(_rc_frame(array("H", [2047, 0] * 8)), 2) == 1
    assert _check_both(_rc_frame(array("H", [1 << (c % 11) for c in range(16)])), 2) == 1
    zeros = bytearray(26)  # type 0, channels 0, CRC 0: CRC-8 of 23 zero bytes is 0, so it passes
    assert _check_both(zeros, 2) == 1
    ones = bytearray(b"\xff" * 26)
    _check_both(ones, 2)
    ones[25] = crc.crc8_dvb_s2(ones, 2, 25)  # the same bytes with their right CRC
    assert _check_both(ones, 2) == 1


def test_crsf_unpack11_and_crc8_twins_agree():
    if not IS_MICROPYTHON:
        return
    rnd = Lcg(11)
    buf = bytearray(40)
    for n in range(300):
        if n == 0:
            fill = 0
        elif n == 1:
            fill = 0xFF
        else:
            fill = -1
        for k in range(40):
            buf[k] = fill if fill >= 0 else rnd.below(256)
        p = rnd.below(18)
        ra, ua, rb, ub = _channels(1), _channels(2), _channels(1), _channels(2)
        rxcodec._unpack11_indexed(buf, p, ra, ua, crsf.US_OF_TICKS)
        rx_viper.unpack11(buf, p, rb, ub, crsf.US_OF_TICKS)
        assert list(ra) == list(rb) and list(ua) == list(ub), (bytes(buf), p)
        start = rnd.below(40)
        end = start + rnd.below(41 - start)
        want = crc.crc8_dvb_s2(buf, start, end)
        assert crc.crc8_dvb_s2_span(buf, start, end) == want, (bytes(buf), start, end)
        assert crc_viper.crc8_dvb_s2_span(buf, start, end) == want, (bytes(buf), start, end)
    assert crc_viper.crc8_dvb_s2_span(b"123456789", 0, 9) == 0xBC  # the CRC-8/DVB-S2 check value


# --------------------------------------------------------------------------------------- DShot

def _encode_both(enc, motor_norm):
    """encode_motors, and the same words made one motor at a time (DshotEncoder._value and the frame);
    asserts the words and the clamp count agree. Returns the words. (The viper twin of the codec's
    encode, accel/dshot.py encode_planned, is held to its Python twin in test_dshot_planned.py.)"""
    n = enc.motor_count
    wa = array("H", [0xBEEF] * 8)
    enc.clamped = 0
    ra = enc.encode_motors(motor_norm, True, wa)
    ca = enc.clamped
    enc.clamped = 0
    want = [dshot.dshot_frame(enc._value(motor_norm[i], enc._low_fp, enc._span_fp),
                              1 if i == enc.telemetry_motor else 0, enc.bidir) for i in range(n)]
    assert list(wa[:n]) == want, (list(motor_norm)[:n], list(wa), want)
    assert ra == len([w for w in want if w != dshot.dshot_frame(0, 0, enc.bidir)])
    assert ca == enc.clamped, (list(motor_norm)[:n], ca, enc.clamped)
    return wa


def test_dshot_encode_gives_stop_min_and_max_values():
    enc = dshot.DshotEncoder(4, False, 0.0, True)
    enc.telemetry_motor = 1
    w = _encode_both(enc, array("f", [0.0, 2.0 ** -20, 1.0, 7.0]))
    assert [dshot.frame_value(x) for x in w[:4]] == [0, 48, 2047, 2047]
    assert [dshot.frame_telemetry(x) for x in w[:4]] == [0, 1, 0, 0]
    assert dshot.frame_crc_ok(w[0]) and dshot.frame_crc_ok(w[1]) and dshot.frame_crc_ok(w[3])
    assert enc.clamped == 1  # the 7.0
    enc = dshot.DshotEncoder(4, True, 0.0, True)
    w = _encode_both(enc, array("f", [0.0, 0.0, 1.0, 0.0]))
    assert dshot.frame_crc_ok(w[2], True) and not dshot.frame_crc_ok(w[2], False)
    assert w[0] == dshot.dshot_frame(0, 0, True)
