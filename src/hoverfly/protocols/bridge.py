"""Lockstep firmware bridge codec: the simulator and a flight firmware in another process.

Takes and gives the byte frames both ends of the bridge exchange once per simulated step
over any byte stream (stdin/stdout pipes to a MicroPython or CPython process, or USB
serial to a real Pico for hardware-in-the-loop). The simulator (sim/bridge.py) sends the
step's IMU sample, the receiver's bytes and the battery; the firmware
(boards/bridge_fw.py) runs one flight pass and answers with the motor outputs, the LED,
status flags and the events recorded since the last answer. Portable: both ends use it.

Frame: `B5 kind len_lo len_hi payload... crc`; len is the payload length (0..1024),
the CRC is CRC-8/DVB-S2 (the CRSF polynomial 0xD5) over kind, both length bytes and the
payload. All fields little-endian. `BridgeDecoder.feed` takes any chunking, resyncs on
garbage and counts (frames, crc_errors, length_errors, kind_errors, resyncs); it never raises.
A frame is delivered only when its kind is one of KINDS, its length at most MAX_PAYLOAD and
its CRC right; a sync byte followed by an unknown kind is garbage (hunting goes on from there).

Kinds and payloads:
- HELLO host->fw  text VERSION: start a new session (the firmware forgets any parameters and
  flight of an earlier one); the firmware answers HELLO with its own VERSION.
- BOOT  host->fw  u32 sim_us: build the flight with the parameters sent so far and start it.
- PARAMS host->fw text `name=value` lines; the firmware answers ACK with "" or the refusal.
- STEP  host->fw  STEP_FMT (sim_us, flags, gyro xyz rad/s, accel xyz m/s², attitude
  quaternion w x y z of an IMU's own fusion, battery V, A) then the receiver's bytes.
  flags: STEP_IMU_FRESH, and the open configuration sessions (flight.config_session,
  1 CLI, 2 MSP, 4 maintenance) in bits 1..3.
- OUT   fw->host  OUT_HEAD_FMT (flags, motors n, servos m, firmware pass µs, autopilot
  state, autopilot privilege bits), n + m f32 (motor_out, servo pulse widths in µs), 4 f32 attitude
  quaternion, u8 k, k events EVENT_FMT.
- MSP_RC host->fw MSP_RC_HEAD_FMT (sim_us when it arrived, count) then count u16 channel
  pulses µs (at most MAX_RC_CHANNELS, MSP SET_RAW_RC's limit): the companion computer's MSP
  RC, handed to flight.on_msp_rc at once; answered by RC_ANSWER.
- RC_ANSWER fw->host RC_ANSWER_FMT (OUT flags, autopilot state, privilege bits) then the
  refusal as text ("" = taken).
- QUIT  host->fw  end; the firmware answers ACK and exits.
- ACK   fw->host  text ("" = ok).
- ERROR fw->host  text: the firmware failed (its exception, one line).
"""

from struct import pack_into

from hoverfly.compat import IS_MICROPYTHON, const
from hoverfly.protocols.crc import CRC8_DVB_S2_TABLE, crc8_dvb_s2_span

SYNC = const(0xB5)
HEADER = const(4)  # sync, kind, len_lo, len_hi
OVERHEAD = const(5)  # header + crc
MAX_PAYLOAD = const(1024)

BOOT = const(0x42)  # 'B'
PARAMS = const(0x50)  # 'P'
STEP = const(0x53)  # 'S'
OUT = const(0x4D)  # 'M'
QUIT = const(0x51)  # 'Q'
ACK = const(0x41)  # 'A'
ERROR = const(0x45)  # 'E'
HELLO = const(0x48)  # 'H'
MSP_RC = const(0x52)  # 'R'
RC_ANSWER = const(0x43)  # 'C'
KINDS = (BOOT, PARAMS, STEP, OUT, QUIT, ACK, ERROR, HELLO, MSP_RC, RC_ANSWER)
# Both ends say which frames they speak; a new field or kind bumps it.
VERSION = "hoverfly-bridge 2"

# STEP flags
STEP_IMU_FRESH = const(0x01)  # a new IMU sample is in this step
STEP_SESSION_SHIFT = const(1)  # flight.config_session (3 bits) sits above the IMU flag
STEP_SESSION_MASK = const(0x07)
STEP_FMT = "<IB6f4f2f"
STEP_SIZE = const(53)  # struct.calcsize(STEP_FMT); receiver bytes follow

# OUT flags
OUT_ARMED = const(0x01)
OUT_LED = const(0x02)
OUT_IMU_OK = const(0x04)
OUT_RX_OK = const(0x08)
OUT_CALIBRATED = const(0x10)
OUT_HEAD_FMT = "<BBBHBB"
OUT_HEAD_SIZE = const(7)
EVENT_FMT = "<iBi"  # time (µs since boot, sim clock), event code, detail
EVENT_SIZE = const(9)
MAX_EVENTS = const(32)  # per OUT frame; more wait for the next step

MSP_RC_HEAD_FMT = "<IB"  # sim_us, channel count; count u16 pulses follow
MSP_RC_HEAD_SIZE = const(5)
MAX_RC_CHANNELS = const(18)  # protocols/msp.py unpacks at most 18 from a SET_RAW_RC
RC_ANSWER_FMT = "<BBB"  # OUT flags, autopilot state, privilege bits; the refusal text follows
RC_ANSWER_SIZE = const(3)

_CRC = CRC8_DVB_S2_TABLE

# crc8(buf, start, end): CRC-8/DVB-S2 of buf[start:end] (end within buf), allocating nothing. Every frame both
# ends send or take is checked with it, so on MicroPython it is the viper twin generated from crc.py's Python
# (accel/crc.py, as protocols/crsf.py uses it: the byte loop is most of a frame's cost in bytecode); the Python
# everywhere else or where viper is missing. tests/portable/test_viper_twins.py holds the two equal.
crc8 = crc8_dvb_s2_span
if IS_MICROPYTHON:
    try:
        from hoverfly.accel.crc import crc8_dvb_s2_span as crc8
    except (ImportError, SyntaxError, NameError, ValueError, TypeError):  # TypeError: ViperTypeError
        pass


def frame_crc_ok(buf, n):
    """True if the frame at buf[0:n + OVERHEAD] (n payload bytes, buf holding at least that much) ends in
    the CRC of its kind, length and payload. For a reader that has already framed the stream by its
    lengths (the firmware's serve loop): the CRC alone, without the decoder's byte-wise hunt."""
    end = HEADER + n
    return crc8(buf, 1, end) == buf[end]


def finish(buf, kind, payload_len):
    """Write the header and CRC around a payload already at buf[4:4 + payload_len]; total length.

    A payload longer than MAX_PAYLOAD (or a buffer too short) is a programming error: ValueError.
    """
    if payload_len < 0 or payload_len > MAX_PAYLOAD or len(buf) < payload_len + OVERHEAD:
        raise ValueError("bridge payload of %d bytes does not fit" % payload_len)
    buf[0] = SYNC
    buf[1] = kind
    buf[2] = payload_len & 0xFF
    buf[3] = payload_len >> 8
    end = HEADER + payload_len
    buf[end] = crc8(buf, 1, end)
    return end + 1


def encode(buf, kind, payload=b""):
    """Copy `payload` (bytes-like) into a frame in buf; total length (configuration messages)."""
    n = len(payload)
    if n > MAX_PAYLOAD or len(buf) < n + OVERHEAD:
        raise ValueError("bridge payload of %d bytes does not fit" % n)
    for i in range(n):
        buf[HEADER + i] = payload[i]
    return finish(buf, kind, n)


def frame(kind, payload=b""):
    """A new frame as bytes (tests, configuration messages)."""
    buf = bytearray(len(payload) + OVERHEAD)
    encode(buf, kind, payload)
    return bytes(buf)


def put_event(buf, p, t_us, event, detail):
    """One event record at buf[p]; detail is clamped to the signed 32-bit range."""
    if detail > 0x7FFFFFFF:
        detail = 0x7FFFFFFF
    elif detail < -0x80000000:
        detail = -0x80000000
    if t_us > 0x7FFFFFFF:
        t_us = 0x7FFFFFFF
    elif t_us < -0x80000000:
        t_us = -0x80000000
    pack_into(EVENT_FMT, buf, p, t_us, event & 0xFF, detail)
    return p + EVENT_SIZE


def put_msp_rc(buf, sim_us, channels_us, count):
    """An MSP_RC frame in buf; total length. At most MAX_RC_CHANNELS go (the rest are not
    sent, as MSP's own parser drops them); pulses are clamped to 0..65535 and the time to u32."""
    if count > MAX_RC_CHANNELS:
        count = MAX_RC_CHANNELS
    if count > len(channels_us):
        count = len(channels_us)
    if count < 0:
        count = 0
    if sim_us < 0:
        sim_us = 0
    elif sim_us > 0xFFFFFFFF:
        sim_us = 0xFFFFFFFF
    pack_into(MSP_RC_HEAD_FMT, buf, HEADER, sim_us, count)
    p = HEADER + MSP_RC_HEAD_SIZE
    for i in range(count):
        v = channels_us[i]
        if v < 0:
            v = 0
        elif v > 0xFFFF:
            v = 0xFFFF
        buf[p] = v & 0xFF
        buf[p + 1] = v >> 8
        p += 2
    return finish(buf, MSP_RC, p - HEADER)


def read_msp_rc(payload, length, channels_us):
    """The channels of an MSP_RC payload into channels_us; their count, or -1 when the
    payload is short, claims more than MAX_RC_CHANNELS or more than channels_us holds."""
    if length < MSP_RC_HEAD_SIZE:
        return -1
    count = payload[4]
    if count > MAX_RC_CHANNELS or count > len(channels_us) or length < MSP_RC_HEAD_SIZE + 2 * count:
        return -1
    p = MSP_RC_HEAD_SIZE
    for i in range(count):
        channels_us[i] = payload[p] | (payload[p + 1] << 8)
        p += 2
    return count


_HUNT = const(0)
_KIND = const(1)
_LEN_LO = const(2)
_LEN_HI = const(3)
_BODY = const(4)


class BridgeDecoder:
    """Streaming frame decoder: feed bytes, then take each complete frame with `pop()`.

    Complete good frames wait in a small queue (`depth`, oldest dropped and counted in
    `overruns` when it is full); `pop()` returns the kind (-1 when none is waiting) and
    leaves the payload in `payload[0:length]`.

    A frame is assembled in a buffer of its own (`_rx`) and enters the queue only once its
    CRC has passed, by swapping buffers with the slot it takes: whatever the queue holds, a
    frame still arriving or one that fails its CRC never writes over a waiting frame.
    """

    def __init__(self, depth=4):
        self.depth = depth
        self.frames = 0
        self.crc_errors = 0
        self.length_errors = 0
        self.kind_errors = 0
        self.resyncs = 0
        self.overruns = 0
        self.bytes = 0
        self.payload = bytearray(MAX_PAYLOAD)
        self.length = 0
        self._q = [bytearray(MAX_PAYLOAD + OVERHEAD) for _ in range(depth)]
        # SAFETY: the frame being received lives here until its CRC passes, not in the queue's
        # next slot: on a full queue that slot is the oldest waiting frame, and a frame that then
        # failed its CRC would already have overwritten one about to be delivered (wrong sensor
        # data or motor commands on a HIL link).
        self._rx = bytearray(MAX_PAYLOAD + OVERHEAD)
        self._qlen = [0] * depth
        self._qkind = [0] * depth
        self._head = 0
        self._count = 0
        self._state = _HUNT
        self._kind = 0
        self._want = 0
        self._got = 0
        self._crc = 0

    def pending(self):
        return self._count

    def feed(self, data, n=-1):
        """Take the first n bytes of data (all if n < 0); return how many good frames completed."""
        size = len(data)
        if n < 0 or n > size:
            n = size
        self.bytes += n
        t = _CRC
        done = 0
        state = self._state
        for i in range(n):
            b = data[i]
            if state == _HUNT:
                if b == SYNC:
                    state = _KIND
                else:
                    self.resyncs += 1
            elif state == _KIND:
                if b in KINDS:
                    self._kind = b
                    self._crc = t[b]
                    state = _LEN_LO
                elif b == SYNC:
                    self.kind_errors += 1  # a second sync: it may be the real start
                else:
                    self.kind_errors += 1
                    state = _HUNT
            elif state == _LEN_LO:
                self._want = b
                self._crc = t[self._crc ^ b]
                state = _LEN_HI
            elif state == _LEN_HI:
                self._want |= b << 8
                self._crc = t[self._crc ^ b]
                if self._want > MAX_PAYLOAD:
                    self.length_errors += 1
                    state = _HUNT
                else:
                    self._got = 0
                    state = _BODY
            else:
                if self._got < self._want:
                    self._rx[self._got] = b
                    self._got += 1
                    self._crc = t[self._crc ^ b]
                else:
                    state = _HUNT
                    if b == self._crc:
                        self._push()
                        done += 1
                    else:
                        self.crc_errors += 1
        self._state = state
        return done

    def _whole(self, data):
        """The payload length when data is exactly one good frame (its length and CRC checked, without the
        byte-wise hunt) and nothing is half-received or waiting; -1 otherwise."""
        n = len(data)
        if self._state != _HUNT or self._count or n < OVERHEAD or data[0] != SYNC or data[1] not in KINDS:
            return -1
        want = data[2] | (data[3] << 8)
        if want > MAX_PAYLOAD or n != want + OVERHEAD or crc8(data, 1, n - 1) != data[n - 1]:
            return -1
        return want

    def feed_frame(self, data):
        """feed(data) for a chunk that is likely one whole frame (a pipe's or port's read of the answer
        to a request): when it is exactly one good frame (_whole) it is queued in one copy. Anything else
        goes through feed(), so the result and the counts are feed()'s."""
        want = self._whole(data)
        if want < 0:
            return self.feed(data)
        self.bytes += len(data)
        self._rx[0:want] = data[HEADER:HEADER + want]
        self._want = want
        self._kind = data[1]
        self._push()
        return 1

    def take_frame(self, data):
        """The kind of data when it is exactly one good frame (_whole), counted as feed() counts it but queued
        nowhere: its payload is read where it is, data[HEADER:len(data) - 1]. -1 when it is anything else,
        and then nothing is taken or counted (feed it)."""
        want = self._whole(data)
        if want < 0:
            return -1
        self.bytes += len(data)
        self.frames += 1
        return data[1]

    def _push(self):
        self.frames += 1
        h = self._head
        # The checked frame takes slot h by a swap (no copy, no allocation); the slot's old
        # buffer (free, or the oldest frame a full queue drops) receives the next frame.
        q = self._q
        q[h], self._rx = self._rx, q[h]
        self._qlen[h] = self._want
        self._qkind[h] = self._kind
        h += 1
        if h >= self.depth:
            h = 0
        self._head = h
        if self._count < self.depth:
            self._count += 1
        else:
            self.overruns += 1

    def pop(self):
        """Kind of the oldest waiting frame (payload copied into `payload`), or -1."""
        if self._count == 0:
            return -1
        i = self._head - self._count
        if i < 0:
            i += self.depth
        self._count -= 1
        n = self._qlen[i]
        self.payload[0:n] = self._q[i][0:n]
        self.length = n
        return self._qkind[i]

    def text(self):
        """The waiting payload as str (ACK, ERROR, PARAMS messages)."""
        return bytes(self.payload[: self.length]).decode()
