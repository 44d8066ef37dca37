"""CRSF (TBS Crossfire / ExpressLRS) codec: receiver frames in, telemetry frames out.

Takes the byte stream a CRSF receiver sends the flight controller (420000 baud 8N1, not
inverted; reference/protocols.md §1) in any chunking through `CrsfDecoder.feed`. Gives
16 channels (`channels_raw` wire ticks, `channels_us` microseconds), link statistics from
0x14 frames, and counters. It also encodes the frames the FC sends back on the same UART
(battery 0x08, attitude 0x1E, flight mode 0x21, GPS 0x02, airspeed 0x0A, all with sync 0xC8) and, for the
simulator and tests, the receiver's own frames (RC 0x16, link statistics 0x14).
`CrsfTelemetryScheduler` picks which telemetry frame to send, one right after an RC frame.
It sits in the receiver task (decode) and the telemetry task (encode).

Frame: `[sync] [len] [type] [payload] [crc]`; len counts type + payload + CRC (2..62);
CRC-8/DVB-S2 over type + payload; multi-byte fields big-endian. Accepted sync bytes:
0xC8 (FC), 0xEA (radio), 0xEC (receiver), 0xEE (TX module), 0x00 (broadcast). A longer
payload than a type needs is legal (newer sender): the extra bytes are ignored.

Ticks -> µs mapping: the TBS spec's integer formula `us = (ticks - 992) * 5 / 8 + 1500`
with C truncation toward zero (172 -> 988, 992 -> 1500, 1811 -> 2011, 0 -> 880,
2047 -> 2159). Betaflight's float `0.62477 * ticks + 881` differs by under 1 µs.
The encoder is its exact inverse: it picks the tick that decodes back to the same µs
(1000 -> 192, 1500 -> 992, 2000 -> 1792, 2012 -> 1812), so decode(encode(us)) == us over
880..2159 µs; values outside are clamped to ticks 0..2047.
"""

from array import array

from hoverfly.compat import IS_MICROPYTHON, const, ticks_diff
from hoverfly.protocols.crc import CRC8_DVB_S2_TABLE, crc8_dvb_s2, crc8_dvb_s2_span  # noqa: F401 (crsf.crc8_dvb_s2: the general CRC, for users)
from hoverfly.protocols.rxcodec import (
    SerialRxDecoder,
    check_unpack11,
    fill_raw,
    new_channels,
    pack11,
    unpack11,
)

SYNC_FC = const(0xC8)
TYPE_GPS = const(0x02)
TYPE_BATTERY = const(0x08)
TYPE_AIRSPEED = const(0x0A)
TYPE_HEARTBEAT = const(0x0B)
TYPE_LINK_STATISTICS = const(0x14)
TYPE_RC_CHANNELS = const(0x16)
TYPE_ATTITUDE = const(0x1E)
TYPE_FLIGHT_MODE = const(0x21)
TYPE_EXTENDED_FIRST = const(0x28)  # types from here on carry dest, origin first

RC_FRAME_LEN = const(26)
LINK_STATISTICS_LEN = const(14)
MAX_FRAME_LEN = const(64)
TICKS_MIN = const(0)
TICKS_MAX = const(2047)
TICKS_CENTRE = const(992)

# Uplink TX power index -> mW (reference/protocols.md §1.4).
TX_POWER_MW = (0, 10, 25, 100, 500, 1000, 2000, 250, 50)

TYPE_NAMES = {
    0x02: "gps", 0x03: "gps_time", 0x06: "gps_extended", 0x07: "vario", 0x08: "battery",
    0x09: "baro_altitude", 0x0A: "airspeed", 0x0B: "heartbeat", 0x0C: "rpm", 0x0D: "temperature",
    0x0E: "voltages", 0x14: "link_statistics", 0x16: "rc", 0x17: "rc_subset", 0x1C: "link_stats_rx",
    0x1D: "link_stats_tx", 0x1E: "attitude", 0x21: "flight_mode", 0x28: "device_ping",
    0x29: "device_info", 0x2B: "parameter_entry", 0x2C: "parameter_read", 0x2D: "parameter_write",
    0x32: "command", 0x7A: "msp_request", 0x7B: "msp_response", 0x7C: "msp_write",
    0x7D: "displayport", 0x80: "ardupilot_passthrough",
}

_CRC = CRC8_DVB_S2_TABLE

# The per-frame byte loops: rxcodec's channel unpacking and crc.py's frame CRC, each on MicroPython the
# viper generated from it (accel/rxcodec.py, accel/crc.py: about 10x faster on the RC frame), the Python
# everywhere else or where viper is missing; tests/portable/test_viper_twins.py holds them equal. The CRC's
# twin is chosen here, not in crc.py: it reads crc.py's table, so crc.py cannot import it while loading.
_check_unpack11 = check_unpack11
_unpack11 = unpack11
_crc8 = crc8_dvb_s2_span
if IS_MICROPYTHON:
    try:
        from hoverfly.accel.crc import crc8_dvb_s2_span as _crc8
    except (ImportError, SyntaxError, NameError, ValueError, TypeError):  # TypeError: ViperTypeError
        pass


def _sync_table():
    t = bytearray(256)
    for b in (0xC8, 0xEA, 0xEC, 0xEE, 0x00):
        t[b] = 1
    return bytes(t)


_SYNC_OK = _sync_table()


def us_of_ticks(ticks):
    """TBS integer mapping, truncating toward zero like C."""
    d = (ticks - 992) * 5
    if d < 0:
        return 1500 - ((-d) >> 3)
    return 1500 + (d >> 3)


def ticks_of_us(us):
    """Exact inverse of us_of_ticks where one exists; clamped to 0..2047."""
    d = int(round(us)) - 1500
    if d < 0:
        t = 992 - ((-8 * d + 4) // 5)
    else:
        t = 992 + (8 * d + 4) // 5
    if t < 0:
        return 0
    if t > 2047:
        return 2047
    return t


def _us_table():
    # 4 KB: one lookup per channel beats the arithmetic in the hot decode on both Pythons.
    t = array("H")
    for v in range(2048):
        t.append(us_of_ticks(v))
    return t


US_OF_TICKS = _us_table()


class CrsfDecoder(SerialRxDecoder):
    """Streaming CRSF decoder; see the module docstring and rxcodec.SerialRxDecoder."""

    _SYNC = _SYNC_OK
    _HEADER = 2
    _MAX_FRAME = MAX_FRAME_LEN

    def __init__(self):
        super().__init__()
        self.last_type = -1  # frame type of the last valid frame of any kind
        self.last_dest = -1  # extended frames: destination and origin addresses
        self.last_origin = -1
        self.link_stats_frames = 0
        self.extended_frames = 0
        self.other_frames = 0  # valid frames that are neither RC nor link statistics
        # Link statistics (0x14), receiver's view of the uplink and the TX's of the downlink.
        self.rssi_dbm = 0  # active antenna
        self.rssi1_dbm = 0
        self.rssi2_dbm = 0
        self.link_quality_pct = 0
        self.snr_db = 0
        self.active_antenna = 0
        self.rf_mode = 0
        self.tx_power = 0  # index, see TX_POWER_MW
        self.tx_power_mw = 0
        self.downlink_rssi_dbm = 0
        self.downlink_link_quality_pct = 0
        self.downlink_snr_db = 0

    def _frame_len(self, src, i):
        n = src[i + 1]
        if n < 2 or n > 62:
            return 0
        return n + 2

    def feed(self, data, n=-1):
        """Take the first n bytes of data (all if n < 0); return how many new RC frames completed.

        Fast path for the usual read, one whole RC frame and nothing else; everything else
        (and a fast-path frame that fails its CRC) goes through the shared framer.
        """
        size = len(data)
        if n < 0 or n > size:
            n = size
        if (n == RC_FRAME_LEN and not self._pos and data[1] == 24 and data[2] == TYPE_RC_CHANNELS
                and _SYNC_OK[data[0]]
                and _check_unpack11(data, 2, self.channels_raw, self.channels_us, US_OF_TICKS, _CRC)):
            self.bytes += RC_FRAME_LEN
            self.last_type = TYPE_RC_CHANNELS
            self.frames += 1
            return 1
        self.bytes += n
        self._new = 0
        self._scan(data, 0, n)
        return self._new

    def _take(self, src, i, total):
        if total == RC_FRAME_LEN and src[i + 2] == TYPE_RC_CHANNELS:
            if _check_unpack11(src, i + 2, self.channels_raw, self.channels_us, US_OF_TICKS, _CRC):
                self.last_type = TYPE_RC_CHANNELS
                self.frames += 1
                return 1
            self.crc_errors += 1
            return -1
        end = i + total - 1
        if _crc8(src, i + 2, end) != src[end]:
            self.crc_errors += 1
            return -1
        ftype = src[i + 2]
        self.last_type = ftype
        if ftype == TYPE_RC_CHANNELS:
            if total < RC_FRAME_LEN:
                self.length_errors += 1
                return 0
            _unpack11(src, i + 3, self.channels_raw, self.channels_us, US_OF_TICKS)
            self.frames += 1
            return 1
        if ftype == TYPE_LINK_STATISTICS:
            if total < LINK_STATISTICS_LEN:
                self.length_errors += 1
                return 0
            self._link_statistics(src, i + 3)
            return 0
        if ftype >= TYPE_EXTENDED_FIRST:
            if total < 6:
                self.length_errors += 1
                return 0
            self.last_dest = src[i + 3]
            self.last_origin = src[i + 4]
            self.extended_frames += 1
        self.other_frames += 1
        return 0

    def _link_statistics(self, src, p):
        r1 = -src[p]
        r2 = -src[p + 1]
        self.rssi1_dbm = r1
        self.rssi2_dbm = r2
        self.link_quality_pct = src[p + 2]
        s = src[p + 3]
        self.snr_db = s - 256 if s > 127 else s
        ant = src[p + 4]
        self.active_antenna = ant
        self.rssi_dbm = r2 if ant else r1
        self.rf_mode = src[p + 5]
        power = src[p + 6]
        self.tx_power = power
        self.tx_power_mw = TX_POWER_MW[power] if power < 9 else 0
        self.downlink_rssi_dbm = -src[p + 7]
        self.downlink_link_quality_pct = src[p + 8]
        s = src[p + 9]
        self.downlink_snr_db = s - 256 if s > 127 else s
        self.link_stats_frames += 1


# -- encoders --------------------------------------------------------------------------

_RAW = new_channels()  # encoder scratch: not re-entrant, not used by the decoder


def _finish(out, length, sync=SYNC_FC):
    """Sync, length byte and CRC around out[2:length-1]; returns length."""
    out[0] = sync
    out[1] = length - 2
    out[length - 1] = _crc8(out, 2, length - 1)
    return length


def _clamp(v, lo, hi):
    if v < lo:
        return lo
    if v > hi:
        return hi
    return v


def _put_u16(out, p, v):
    out[p] = (v >> 8) & 0xFF
    out[p + 1] = v & 0xFF


def _put_u24(out, p, v):
    out[p] = (v >> 16) & 0xFF
    out[p + 1] = (v >> 8) & 0xFF
    out[p + 2] = v & 0xFF


def _put_u32(out, p, v):
    out[p] = (v >> 24) & 0xFF
    out[p + 1] = (v >> 16) & 0xFF
    out[p + 2] = (v >> 8) & 0xFF
    out[p + 3] = v & 0xFF


_BIG = 2147483647.0  # past every field: a value beyond it (or infinite) is clamped before int()


def _round(x):
    """Round half away from zero to int (the firmware's +0.5 idiom, symmetric); NaN 0, beyond +-2**31 clamped
    (the fields clamp further)."""
    if x < 0:
        if x < -_BIG:
            return -2147483647
        return -int(-x + 0.5)
    if x >= 0:
        if x > _BIG:
            return 2147483647
        return int(x + 0.5)
    return 0  # NaN


def encode_rc_frame_raw(channels_raw, out=None, sync=SYNC_FC):
    """RC_CHANNELS_PACKED from 16 wire ticks (each masked to 11 bits) -> 26-byte buffer."""
    if out is None:
        out = bytearray(RC_FRAME_LEN)
    out[2] = TYPE_RC_CHANNELS
    pack11(channels_raw, out, 3)
    _finish(out, RC_FRAME_LEN, sync)
    return out


def encode_rc_frame(channels_us, out=None, sync=SYNC_FC):
    """RC_CHANNELS_PACKED from up to 16 µs values (missing ones 1500 µs) -> 26-byte buffer."""
    fill_raw(channels_us, _RAW, ticks_of_us, TICKS_CENTRE)
    return encode_rc_frame_raw(_RAW, out, sync)


def encode_link_statistics(rssi1_dbm=-60, rssi2_dbm=-60, link_quality_pct=100, snr_db=0, active_antenna=0,
                           rf_mode=0, tx_power=0, downlink_rssi_dbm=-60, downlink_link_quality_pct=100,
                           downlink_snr_db=0, out=None, sync=SYNC_FC):
    """LINK_STATISTICS 0x14 (RSSI sent as -dBm, SNR as i8) -> 14-byte buffer. Values clamped to the fields."""
    if out is None:
        out = bytearray(LINK_STATISTICS_LEN)
    out[2] = TYPE_LINK_STATISTICS
    out[3] = _clamp(-rssi1_dbm, 0, 255)
    out[4] = _clamp(-rssi2_dbm, 0, 255)
    out[5] = _clamp(link_quality_pct, 0, 255)
    out[6] = _clamp(snr_db, -128, 127) & 0xFF
    out[7] = _clamp(active_antenna, 0, 255)
    out[8] = _clamp(rf_mode, 0, 255)
    out[9] = _clamp(tx_power, 0, 255)
    out[10] = _clamp(-downlink_rssi_dbm, 0, 255)
    out[11] = _clamp(downlink_link_quality_pct, 0, 255)
    out[12] = _clamp(downlink_snr_db, -128, 127) & 0xFF
    _finish(out, LINK_STATISTICS_LEN, sync)
    return out


def _whole(x):
    """An integer field's value: an int as it is (a float32 cannot hold degrees x 1e7 to the unit), a float
    truncated toward zero as int() does, NaN 0, infinities clamped."""
    if isinstance(x, int):
        return x
    if x != x:
        return 0
    if x > _BIG:
        return 2147483647
    if x < -_BIG:
        return -2147483647
    return int(x)


def _ufield(x, hi):
    """_clamp(_round(x), 0, hi) in one call: an unsigned field, rounded half up, clamped (NaN 0)."""
    if not (x > 0):  # below 0, 0, or NaN
        return 0
    if x >= hi:  # and infinity
        return hi
    v = int(x + 0.5)
    return hi if v > hi else v


def encode_battery(out, voltage_v, current_a, used_mah, remaining_pct):
    """BATTERY_SENSOR 0x08 into out (>= 12 bytes); returns 12.

    Voltage and current in 0.1 V / 0.1 A, rounded (Betaflight rounds the voltage);
    capacity used u24 mAh; remaining %. Everything clamped to its field.
    """
    # The fields written in place, not through _put_u16/_clamp: it runs in the receiver task, and each
    # call is a frame on MicroPython.
    out[2] = TYPE_BATTERY
    v = _ufield(voltage_v * 10, 0xFFFF)
    out[3] = v >> 8
    out[4] = v & 0xFF
    v = _ufield(current_a * 10, 0xFFFF)
    out[5] = v >> 8
    out[6] = v & 0xFF
    v = _ufield(used_mah, 0xFFFFFF)
    out[7] = v >> 16
    out[8] = (v >> 8) & 0xFF
    out[9] = v & 0xFF
    out[10] = _ufield(remaining_pct, 100)
    out[0] = SYNC_FC
    out[1] = 10
    out[11] = _crc8(out, 2, 11)
    return 12


def _angle_wire(angle_rad):
    # Wrap into [-pi, pi], then 100 µrad units truncated toward zero (Betaflight's int16 cast).
    if not (-1000.0 < angle_rad < 1000.0):  # NaN or infinite (the wrap below would never end): no angle
        return 0
    while angle_rad > 3.141592653589793:
        angle_rad -= 6.283185307179586
    while angle_rad < -3.141592653589793:
        angle_rad += 6.283185307179586
    v = int(angle_rad * 10000)
    if v > 31416:
        return 31416
    if v < -31416:
        return -31416 & 0xFFFF
    return v & 0xFFFF


def encode_attitude(out, pitch_rad, roll_rad, yaw_rad):
    """ATTITUDE 0x1E into out (>= 10 bytes); returns 10. Pitch first, i16 BE in 100 µrad each."""
    out[2] = TYPE_ATTITUDE
    v = _angle_wire(pitch_rad)
    out[3] = v >> 8
    out[4] = v & 0xFF
    v = _angle_wire(roll_rad)
    out[5] = v >> 8
    out[6] = v & 0xFF
    v = _angle_wire(yaw_rad)
    out[7] = v >> 8
    out[8] = v & 0xFF
    out[0] = SYNC_FC
    out[1] = 8
    out[9] = _crc8(out, 2, 9)
    return 10


FLIGHT_MODE_MAX_CHARS = const(15)  # ELRS reserves 16 bytes including the NUL


def encode_flight_mode(out, mode):
    """FLIGHT_MODE 0x21 into out: NUL-terminated ASCII (str or bytes, cut to 15 chars); returns its length.

    Pass bytes to avoid the str -> bytes conversion on MicroPython.
    """
    if isinstance(mode, str):
        mode = mode.encode()
    n = len(mode)
    if n > FLIGHT_MODE_MAX_CHARS:
        n = FLIGHT_MODE_MAX_CHARS
    out[2] = TYPE_FLIGHT_MODE
    for k in range(n):
        out[3 + k] = mode[k]
    out[3 + n] = 0
    out[0] = SYNC_FC
    out[1] = n + 3
    out[n + 4] = _crc8(out, 2, n + 4)
    return n + 5


def encode_gps(out, lat_deg_e7, lon_deg_e7, ground_speed_m_s, course_rad, altitude_m, satellites):
    """GPS 0x02 into out (>= 19 bytes); returns 19.

    Latitude/longitude as integer degrees × 1e7 (what GPS receivers report; a float32 on the
    Pico cannot hold them to the centimetre); ground speed -> 0.1 km/h; course -> 0.01°
    (0..35999); altitude -> metres + 1000 (u16); satellites u8.
    """
    out[2] = TYPE_GPS
    _put_u32(out, 3, _clamp(_whole(lat_deg_e7), -900000000, 900000000) & 0xFFFFFFFF)
    _put_u32(out, 7, _clamp(_whole(lon_deg_e7), -1800000000, 1800000000) & 0xFFFFFFFF)
    _put_u16(out, 11, _clamp(_round(ground_speed_m_s * 36), 0, 0xFFFF))
    course = _round(course_rad * 5729.5779513082320876) % 36000  # rad -> centidegrees
    _put_u16(out, 13, course)
    _put_u16(out, 15, _clamp(_round(altitude_m) + 1000, 0, 0xFFFF))
    out[17] = _clamp(_whole(satellites), 0, 255)
    return _finish(out, 19)


def encode_airspeed(out, airspeed_m_s):
    """AIRSPEED 0x0A into out (>= 6 bytes); returns 6. u16 in 0.1 km/h (TBS CRSF spec), as the GPS speed."""
    out[2] = TYPE_AIRSPEED
    _put_u16(out, 3, _clamp(_round(airspeed_m_s * 36), 0, 0xFFFF))
    return _finish(out, 6)


# -- telemetry scheduling --------------------------------------------------------------

KIND_BATTERY = const(0)
KIND_ATTITUDE = const(1)
KIND_FLIGHT_MODE = const(2)
KIND_GPS = const(3)
KIND_AIRSPEED = const(4)
_KINDS = const(5)
KIND_NAMES = ("battery", "attitude", "flight_mode", "gps", "airspeed")


class CrsfTelemetryScheduler:
    """Which telemetry frame goes to the receiver next, and when.

    A CRSF receiver expects FC frames in the gap after it has sent an RC frame, so `poll`
    only answers when the receiver pass just completed an RC frame (`rc_frames` > 0, the
    value `feed` returned): telemetry can never crowd out RC input. At most one frame per
    `interval_us` (default 25 ms: 40 frames/s, ~10 Hz per kind with all four, Betaflight's
    rate), round-robin over the kinds that have data (`set_*` gives data, `clear` removes it).
    """

    def __init__(self, interval_us=25000):
        self.interval_us = interval_us
        self.sent = 0
        self.last_kind = -1
        self._has = bytearray(_KINDS)
        self._next = 0
        self._last_us = 0
        self._sent_any = False
        self._battery = [0.0, 0.0, 0, 0]
        self._attitude = [0.0, 0.0, 0.0]
        self._mode = b""
        self._gps = [0, 0, 0.0, 0.0, 0.0, 0]
        self._airspeed = [0.0]

    def set_battery(self, voltage_v, current_a, used_mah, remaining_pct):
        b = self._battery
        b[0] = voltage_v
        b[1] = current_a
        b[2] = used_mah
        b[3] = remaining_pct
        self._has[KIND_BATTERY] = 1

    def set_attitude(self, pitch_rad, roll_rad, yaw_rad):
        a = self._attitude
        a[0] = pitch_rad
        a[1] = roll_rad
        a[2] = yaw_rad
        self._has[KIND_ATTITUDE] = 1

    def set_flight_mode(self, mode):
        self._mode = mode
        self._has[KIND_FLIGHT_MODE] = 1

    def set_gps(self, lat_deg_e7, lon_deg_e7, ground_speed_m_s, course_rad, altitude_m, satellites):
        g = self._gps
        g[0] = lat_deg_e7
        g[1] = lon_deg_e7
        g[2] = ground_speed_m_s
        g[3] = course_rad
        g[4] = altitude_m
        g[5] = satellites
        self._has[KIND_GPS] = 1

    def set_airspeed(self, airspeed_m_s):
        self._airspeed[0] = airspeed_m_s
        self._has[KIND_AIRSPEED] = 1

    def clear(self, kind=-1):
        """Stop sending one kind (KIND_*), or all with -1."""
        if kind < 0:
            for k in range(_KINDS):
                self._has[k] = 0
        elif kind < _KINDS:
            self._has[kind] = 0

    def upcoming(self):
        """The kind the next frame will carry (KIND_*), -1 while no kind has data: a caller may refresh
        only that kind's data before `poll`."""
        has = self._has
        k = self._next
        for _ in range(_KINDS):
            if has[k]:
                return k
            k = (k + 1) % _KINDS
        return -1

    def poll(self, now_us, rc_frames, out):
        """Length of the frame written into out (>= 64 bytes) to send now, or 0 for nothing."""
        if rc_frames <= 0:
            return 0
        if self._sent_any and ticks_diff(now_us, self._last_us) < self.interval_us:
            return 0
        has = self._has
        k = self._next
        for _ in range(_KINDS):
            if has[k]:
                break
            k = (k + 1) % _KINDS
        else:
            return 0
        self._next = (k + 1) % _KINDS
        if k == KIND_BATTERY:
            b = self._battery
            n = encode_battery(out, b[0], b[1], b[2], b[3])
        elif k == KIND_ATTITUDE:
            a = self._attitude
            n = encode_attitude(out, a[0], a[1], a[2])
        elif k == KIND_FLIGHT_MODE:
            n = encode_flight_mode(out, self._mode)
        elif k == KIND_GPS:
            g = self._gps
            n = encode_gps(out, g[0], g[1], g[2], g[3], g[4], g[5])
        else:
            n = encode_airspeed(out, self._airspeed[0])
        self._last_us = now_us
        self._sent_any = True
        self.sent += 1
        self.last_kind = k
        return n
