"""MSP (MultiWii Serial Protocol) v1/v2 codec, as Betaflight speaks it (reference/protocols.md §6).

Takes the bytes of an MSP port (UART, USB CDC, TCP in the simulator) in any chunking through
`MspParser.feed` and gives whole messages, one `pop()` at a time: version (1 or 2), direction
(`<` request, `>` reply, `!` error), command id, flags, payload. Encodes frames both ways
(`encode_v1`, `encode_v2`, `encode_v2_over_v1`, `encode_reply`, `encode_request`) and packs or
unpacks the payloads of the commands hoverfly answers, in Betaflight's layouts and wire units.
It sits between board.serial and the MSP server (which chooses the values; not here).

Framing (all multi-byte fields little-endian):
  v1  `$ M dir size cmd payload xor`, xor over size, cmd, payload; size 255 = jumbo: a u16
      real size follows cmd and the xor covers it too.
  v2  `$ X dir flags cmd(u16) size(u16) payload crc`, CRC-8/DVB-S2 over flags..payload.
  v2 over v1: a v1 frame with cmd 255 whose payload is a whole v2 body (flags..crc).
`FrameScanner` is the streaming framer (also used by the maintenance codec): it hunts for the
sync byte, waits for the whole frame, and when a candidate fails its check skips only that
sync byte and searches the bytes after it again, so a real frame behind a false `$` is found.
Nothing raises on bad input; counters say what was dropped.
"""

from array import array
from struct import pack, pack_into, unpack_from

from hoverfly.compat import const
from hoverfly.protocols.crc import CRC8_DVB_S2_TABLE, crc8_dvb_s2, xor8

# -- command ids (reference/protocols.md §6.3; MODE_RANGES and SET_NAME from Betaflight msp_protocol.h,
#    also yamspy's table) -----------------------------------------------------------------------------
MSP_API_VERSION = const(1)
MSP_FC_VARIANT = const(2)
MSP_FC_VERSION = const(3)
MSP_BOARD_INFO = const(4)
MSP_BUILD_INFO = const(5)
MSP_NAME = const(10)
MSP_SET_NAME = const(11)
MSP_MODE_RANGES = const(34)
MSP_SET_MODE_RANGE = const(35)
MSP_FEATURE_CONFIG = const(36)
MSP_SET_FEATURE_CONFIG = const(37)
MSP_RX_CONFIG = const(44)
MSP_ARMING_CONFIG = const(61)
MSP_SET_ARMING_CONFIG = const(62)
MSP_REBOOT = const(68)
MSP_SET_ARMING_DISABLED = const(99)
MSP_STATUS = const(101)
MSP_RAW_IMU = const(102)
MSP_SERVO = const(103)
MSP_MOTOR = const(104)
MSP_RC = const(105)
MSP_ATTITUDE = const(108)
MSP_ALTITUDE = const(109)
MSP_ANALOG = const(110)
MSP_RC_TUNING = const(111)
MSP_PID = const(112)
MSP_BOXNAMES = const(116)
MSP_BOXIDS = const(119)
MSP_SERVO_CONFIGURATIONS = const(120)
MSP_MOTOR_CONFIG = const(131)
MSP_STATUS_EX = const(150)
MSP_UID = const(160)
MSP_SET_RAW_RC = const(200)
MSP_SET_PID = const(202)
MSP_ACC_CALIBRATION = const(205)
MSP_MAG_CALIBRATION = const(206)
MSP_SET_SERVO_CONFIGURATION = const(212)
MSP_SET_MOTOR = const(214)
MSP_EEPROM_WRITE = const(250)
MSP_V2_FRAME = const(255)  # v1 cmd 255: a v2 frame inside
MSP2_INAV_AIR_SPEED = const(0x2009)
MSP2_INAV_SERVO_MIXER = const(0x2020)
MSP2_INAV_SET_SERVO_MIXER = const(0x2021)
MSP2_SEND_DSHOT_COMMAND = const(0x3003)
# hoverfly's own (docs/msp.md "hoverfly commands"): at the top of the 0x3000 block, far from the ids
# Betaflight hands out from 0x3000 upwards, so a Betaflight client never meets it by accident.
MSP2_HOVERFLY_AUTOPILOT = const(0x3F00)

# Directions are the wire characters.
DIR_REQUEST = const(0x3C)  # '<'
DIR_REPLY = const(0x3E)  # '>'
DIR_ERROR = const(0x21)  # '!'

JUMBO_SIZE = const(255)  # v1 size byte meaning "u16 size follows"
BETAFLIGHT_RX_BUFFER = const(192)  # Betaflight drops requests longer than this (reference §6.2)

# API version hoverfly can claim: Betaflight 4.5 = 1.46 (reference §6.3).
API_PROTOCOL = const(0)
API_MAJOR = const(1)
API_MINOR = const(46)

# Arming-disable flags, bit = index (Betaflight 4.5, 26 flags; reference §6.4). Later versions insert
# CRASHFLIP/ALTHOLD/POSHOLD/AUTOPILOT before ARM_SWITCH; clients read the count byte.
ARMING_DISABLE_FLAGS = (
    "NO_GYRO", "FAILSAFE", "RX_FAILSAFE", "NOT_DISARMED", "BOXFAILSAFE", "RUNAWAY_TAKEOFF",
    "CRASH_DETECTED", "THROTTLE", "ANGLE", "BOOT_GRACE_TIME", "NOPREARM", "LOAD", "CALIBRATING",
    "CLI", "CMS_MENU", "BST", "MSP", "PARALYZE", "GPS", "RESC", "DSHOT_TELEM", "REBOOT_REQUIRED",
    "DSHOT_BITBANG", "ACC_CALIBRATION", "MOTOR_PROTOCOL", "ARM_SWITCH",
)
# The names Betaflight's CLI and configurator show, same order.
ARMING_DISABLE_CLI_NAMES = (
    "NOGYRO", "FAILSAFE", "RXLOSS", "NOT_DISARMED", "BOXFAILSAFE", "RUNAWAY", "CRASH", "THROTTLE",
    "ANGLE", "BOOTGRACE", "NOPREARM", "LOAD", "CALIB", "CLI", "CMS", "BST", "MSP", "PARALYZE", "GPS",
    "RESCUE_SW", "DSHOT_TELEM", "REBOOT_REQD", "DSHOT_BBANG", "NO_ACC_CAL", "MOTOR_PROTO", "ARMSWITCH",
)
ARMING_FLAG_COUNT = const(26)  # what 4.5 sends before the u32 (29 in 2025.12, 30 in 2026.6)
ARMING_DISABLED_MSP = const(16)  # bit set by MSP_SET_ARMING_DISABLED

# Permanent mode ids (MSP_BOXIDS) in Betaflight 4.5, reference §6.3. (id, name) pairs.
BOX_IDS = (
    (0, "ARM"), (1, "ANGLE"), (2, "HORIZON"), (4, "ANTI GRAVITY"), (5, "MAG"), (6, "HEADFREE"),
    (7, "HEADADJ"), (8, "CAMSTAB"), (12, "PASSTHRU"), (13, "BEEPER"), (15, "LEDLOW"), (17, "CALIB"),
    (19, "OSD DISABLE"), (20, "TELEMETRY"), (23, "SERVO1"), (24, "SERVO2"), (25, "SERVO3"),
    (26, "BLACKBOX"), (27, "FAILSAFE"), (28, "AIR MODE"), (29, "3D"), (30, "FPV ANGLE MIX"),
    (31, "BLACKBOX ERASE"), (32, "CAMERA CONTROL 1"), (33, "CAMERA CONTROL 2"),
    (34, "CAMERA CONTROL 3"), (35, "FLIP OVER AFTER CRASH"), (36, "PREARM"),
    (37, "GPS BEEP SATELLITE COUNT"), (39, "VTX PIT MODE"), (40, "USER1"), (41, "USER2"),
    (42, "USER3"), (43, "USER4"), (44, "PID AUDIO"), (45, "PARALYZE"), (46, "GPS RESCUE"),
    (47, "ACRO TRAINER"), (48, "VTX CONTROL DISABLE"), (49, "LAUNCH CONTROL"), (50, "MSP OVERRIDE"),
    (51, "STICK COMMANDS DISABLE"), (52, "BEEPER MUTE"), (53, "READY"), (54, "LAP TIMER RESET"),
)

_CRC = CRC8_DVB_S2_TABLE


def arming_flag_names(flags, names=ARMING_DISABLE_FLAGS):
    """Names of the set bits of an arming-disable mask, lowest bit first (unknown bits as 'BIT<n>')."""
    out = []
    bit = 0
    while flags and bit < 32:
        if flags & 1:
            out.append(names[bit] if bit < len(names) else "BIT%d" % bit)
        flags >>= 1
        bit += 1
    return out


# -- the streaming framer -------------------------------------------------------------------------------


class FrameScanner:
    """Sync-hunting streaming framer with a small queue of whole frames.

    A subclass gives `_frame_len(src, i, avail)` (-1 = need more header bytes, 0 = impossible header,
    counted by the subclass, else the frame's total length) and `_check(src, i, total)` (-1 = bad,
    counted; 0 = valid but nothing to deliver; 1 = deliver). Delivered frames are copied whole into
    one of `queue_depth` preallocated slots; `_next()` hands the oldest out. `feed` takes every byte:
    when the queue is full the oldest frame is overwritten and counted in `dropped`. A server that
    must answer every request uses `feed_some` instead: it stops at a full queue and says how far it
    got, so the caller pops, answers and feeds the rest (nothing is overwritten). Bytes a failed
    candidate had swallowed are then kept (`carrying()`) and scanned first at the next feed_some,
    before any new byte, even with no new bytes (`feed_some(data, n, n)`).

    Counters: `frames` (delivered), `crc_errors`, `resyncs` (bytes skipped hunting for a frame
    start, plus false syncs), `length_errors` (impossible headers), `dropped`, `bytes`.
    """

    def __init__(self, sync, max_frame, queue_depth):
        self._sync_byte = sync
        self._buf = bytearray(max_frame)
        self._scratch = bytearray(max_frame)
        self._max_frame = max_frame
        depth = queue_depth if queue_depth > 0 else 1
        self._slots = [bytearray(max_frame) for _ in range(depth)]
        self._slot_len = array("H", [0] * depth)
        self._depth = depth
        self._head = 0
        self._count = 0
        self._pos = 0  # bytes of a partial frame held in _buf
        self._want = 0  # its total length once known, else 0
        self._new = 0
        self._hold = False  # feed_some: stop scanning at a full queue
        self._carry = 0  # feed_some: bytes of a failed candidate in _scratch still to scan (from _carry_at)
        self._carry_at = 0
        self._frame_total = 0  # length of the frame _next() handed out
        self.frames = 0
        self.crc_errors = 0
        self.resyncs = 0
        self.length_errors = 0
        self.dropped = 0
        self.bytes = 0

    def feed(self, data, n=-1):
        """Take the first n bytes of data (all if n < 0); return how many frames completed."""
        size = len(data)
        if n < 0 or n > size:
            n = size
        self.bytes += n
        self._new = 0
        self._scan(data, 0, n)
        return self._new

    def feed_some(self, data, start, n):
        """Take data[start:n] until the queue is full; return where it stopped (n when all was taken).
        The bytes from there on were not looked at: hand them in again once frames have been popped."""
        self._new = 0
        self._hold = True
        i = start
        while True:
            if self._carry:
                # what a failed candidate swallowed comes before data[i:] in the stream
                m = self._carry
                self._carry = 0
                c = self._scan(self._scratch, self._carry_at, m)
                if c < m:
                    self._carry = m
                    self._carry_at = c
                    break  # the queue is full
            if i >= n:
                break
            i = self._scan(data, i, n)
            if not self._carry:
                break  # all taken, or the queue is full
        self._hold = False
        self.bytes += i - start
        return i

    def carrying(self):
        """feed_some: bytes already taken and not yet scanned (a failed candidate's) are waiting."""
        return self._carry != 0

    def in_frame(self):
        """True while a frame is half received (or taken bytes wait to be scanned: they come first)."""
        return self._pos != 0 or self._carry != 0

    def pending(self):
        """Frames waiting in the queue."""
        return self._count

    def idle(self):
        """The line went quiet: a partial frame will never complete. Drop it and count it."""
        if self._pos:
            self.length_errors += 1
            self.resyncs += self._pos
            self._pos = 0
            self._want = 0

    def reset(self):
        """Forget any partial frame and the queue (counters stay)."""
        self._pos = 0
        self._want = 0
        self._head = 0
        self._count = 0
        self._carry = 0

    def reset_counters(self):
        self.frames = self.crc_errors = self.resyncs = self.length_errors = self.dropped = self.bytes = 0

    def _next(self):
        """The oldest queued frame's slot (its length in self._frame_total), or None."""
        if not self._count:
            return None
        k = self._head
        self._head = k + 1 if k + 1 < self._depth else 0
        self._count -= 1
        self._frame_total = self._slot_len[k]
        return self._slots[k]

    def _scan(self, src, i, n):
        """Scan src[i:n]; return where it stopped: n, or (feed_some) the first byte not taken."""
        sync = self._sync_byte
        while i < n:
            if self._hold and (self._count >= self._depth or self._carry):
                return i  # the queue is full, or a failed candidate's bytes must be scanned first
            if self._pos:
                i = self._assemble(src, i, n)
                continue
            if src[i] != sync:
                self.resyncs += 1
                i += 1
                continue
            total = self._frame_len(src, i, n - i)
            if total < 0:
                self._stash(src, i, n, 0)
                return n
            if total == 0 or total > self._max_frame:
                self.resyncs += 1
                i += 1
                continue
            if n - i < total:
                self._stash(src, i, n, total)
                return n
            r = self._check(src, i, total)
            if r < 0:
                self.resyncs += 1  # skip only the false sync byte and search the rest again
                i += 1
            else:
                if r:
                    self._deliver(src, i, total)
                i += total
        return n

    def _stash(self, src, i, n, total):
        buf = self._buf
        pos = 0
        while i < n:
            buf[pos] = src[i]
            pos += 1
            i += 1
        self._pos = pos
        self._want = total

    def _assemble(self, src, i, n):
        buf = self._buf
        pos = self._pos
        want = self._want
        if want == 0:
            while i < n:
                buf[pos] = src[i]
                pos += 1
                i += 1
                want = self._frame_len(buf, 0, pos)
                if want >= 0:
                    break
            self._pos = pos
            if want < 0:
                return i
            if want == 0 or want > self._max_frame:
                self._rescan(pos)
                return i
            self._want = want
        while pos < want and i < n:
            buf[pos] = src[i]
            pos += 1
            i += 1
        if pos < want:
            self._pos = pos
            return i
        self._pos = 0
        self._want = 0
        r = self._check(buf, 0, want)
        if r < 0:
            self._rescan(want)
        elif r:
            self._deliver(buf, 0, want)
        return i

    def _rescan(self, m):
        # As the one-chunk path does: drop the sync byte, search buf[1:m] again. The rescan starts
        # with no partial frame, so it can only stash (never complete) one: no recursion. Under
        # feed_some the bytes are carried instead: scanned before any new byte, as the queue has room.
        self.resyncs += 1
        buf = self._buf
        scratch = self._scratch
        for k in range(1, m):
            scratch[k - 1] = buf[k]
        self._pos = 0
        self._want = 0
        if self._hold:
            self._carry = m - 1
            self._carry_at = 0
            return
        self._scan(scratch, 0, m - 1)

    def _deliver(self, src, i, total):
        depth = self._depth
        if self._count == depth:
            self.dropped += 1  # overwrite the oldest
            self._head = self._head + 1 if self._head + 1 < depth else 0
            self._count -= 1
        k = self._head + self._count
        if k >= depth:
            k -= depth
        slot = self._slots[k]
        for j in range(total):
            slot[j] = src[i + j]
        self._slot_len[k] = total
        self._count += 1
        self.frames += 1
        self._new += 1

    def _frame_len(self, src, i, avail):
        return 0

    def _check(self, src, i, total):
        return -1


# -- MSP parser -----------------------------------------------------------------------------------------

_DOLLAR = const(0x24)
_M = const(0x4D)
_X = const(0x58)


class MspParser(FrameScanner):
    """Streaming MSP v1/v2 parser (requests, replies and error replies alike).

        n = parser.feed(data)
        while parser.pop():
            handle(parser.version, parser.direction, parser.cmd, parser.payload, parser.length)

    After `pop()` the message is in `version` (1, or 2 also for v2-over-v1), `encapsulated`
    (True for v2 inside a v1 cmd-255 frame: answer the same way), `direction` (DIR_REQUEST,
    DIR_REPLY, DIR_ERROR), `cmd`, `flags` (v2), `payload` (preallocated bytearray, valid until the
    next pop) and `length`. Payloads longer than `max_payload` are dropped and counted in
    `oversize`; a bad inner v2 CRC of a v2-over-v1 frame counts in `crc_errors`.
    """

    def __init__(self, max_payload=512, queue_depth=4):
        # v2 header 8 + crc 1 is the largest overhead; v1 jumbo is 7 + 1; v2-over-v1 fits in v1's.
        FrameScanner.__init__(self, _DOLLAR, max_payload + 9, queue_depth)
        self.max_payload = max_payload
        self.payload = bytearray(max_payload)
        self.length = 0
        self.version = 0
        self.encapsulated = False
        self.direction = 0
        self.cmd = 0
        self.flags = 0
        self.oversize = 0

    def message(self):
        """The popped payload as bytes (allocates: host tools and tests)."""
        return bytes(self.payload[: self.length])

    def pop(self):
        """Move the oldest queued message into the attributes; False when none is waiting."""
        f = self._next()
        if f is None:
            return False
        total = self._frame_total
        if f[1] == _M:
            size = f[3]
            p = 5
            if size == JUMBO_SIZE:
                size = f[5] | (f[6] << 8)
                p = 7
            cmd = f[4]
            self.direction = f[2]
            if cmd == MSP_V2_FRAME:
                # checked in _check: flags, cmd u16, size u16, payload, crc
                self.version = 2
                self.encapsulated = True
                self.flags = f[p]
                self.cmd = f[p + 1] | (f[p + 2] << 8)
                size = f[p + 3] | (f[p + 4] << 8)
                p += 5
            else:
                self.version = 1
                self.encapsulated = False
                self.flags = 0
                self.cmd = cmd
        else:
            self.version = 2
            self.encapsulated = False
            self.direction = f[2]
            self.flags = f[3]
            self.cmd = f[4] | (f[5] << 8)
            size = total - 9
            p = 8
        out = self.payload
        for j in range(size):
            out[j] = f[p + j]
        self.length = size
        return True

    def _frame_len(self, src, i, avail):
        if avail < 3:
            if avail == 2 and src[i + 1] != _M and src[i + 1] != _X:
                self.length_errors += 1
                return 0
            return -1
        v = src[i + 1]
        d = src[i + 2]
        if (v != _M and v != _X) or (d != DIR_REQUEST and d != DIR_REPLY and d != DIR_ERROR):
            self.length_errors += 1
            return 0
        if v == _M:
            if avail < 5:
                return -1
            size = src[i + 3]
            head = 5
            if size == JUMBO_SIZE:
                if avail < 7:
                    return -1
                size = src[i + 5] | (src[i + 6] << 8)
                head = 7
        else:
            if avail < 8:
                return -1
            size = src[i + 6] | (src[i + 7] << 8)
            head = 8
        if size > self.max_payload:
            self.oversize += 1
            return 0
        return head + size + 1

    def _check(self, src, i, total):
        end = i + total - 1
        if src[i + 1] == _M:
            if xor8(src, i + 3, end) != src[end]:
                self.crc_errors += 1
                return -1
            if src[i + 4] != MSP_V2_FRAME:
                return 1
            p = i + 7 if src[i + 3] == JUMBO_SIZE else i + 5
            inner = end - p  # flags .. crc
            if inner < 6 or (src[p + 3] | (src[p + 4] << 8)) != inner - 6:
                self.length_errors += 1
                return 0  # the outer frame was sound: consume it, deliver nothing
            t = _CRC
            crc = 0
            for k in range(p, end - 1):
                crc = t[crc ^ src[k]]
            if crc != src[end - 1]:
                self.crc_errors += 1
                return 0
            return 1
        t = _CRC
        crc = 0
        for k in range(i + 3, end):
            crc = t[crc ^ src[k]]
        if crc != src[end]:
            self.crc_errors += 1
            return -1
        return 1


# -- encoders -------------------------------------------------------------------------------------------


def _dir_code(direction, error):
    if error:
        return DIR_ERROR
    if isinstance(direction, str):
        direction = ord(direction)
    if direction != DIR_REQUEST and direction != DIR_REPLY and direction != DIR_ERROR:
        raise ValueError("MSP direction must be '<', '>' or '!'")
    return direction


def encode_v1(cmd, payload=b"", direction=DIR_REPLY, error=False):
    """One v1 frame; jumbo (size 255 + u16) when the payload is 255 bytes or more."""
    d = _dir_code(direction, error)
    if cmd < 0 or cmd > 255:
        raise ValueError("MSP v1 command id must be 0..255")
    size = len(payload)
    if size > 0xFFFF:
        raise ValueError("MSP payload longer than 65535 bytes")
    if size < JUMBO_SIZE:
        out = bytearray(6 + size)
        out[3] = size
        out[4] = cmd
        p = 5
    else:
        out = bytearray(8 + size)
        out[3] = JUMBO_SIZE
        out[4] = cmd
        out[5] = size & 0xFF
        out[6] = size >> 8
        p = 7
    out[0] = _DOLLAR
    out[1] = _M
    out[2] = d
    for j in range(size):
        out[p + j] = payload[j]
    out[p + size] = xor8(out, 3, p + size)
    return bytes(out)


def _v2_body(cmd, payload, flags):
    # flags, cmd u16, size u16, payload, crc: the part after '$X<' (and what v2-over-v1 wraps)
    if cmd < 0 or cmd > 0xFFFF:
        raise ValueError("MSP v2 command id must be 0..65535")
    if flags < 0 or flags > 255:
        raise ValueError("MSP v2 flags must be 0..255")
    size = len(payload)
    if size > 0xFFFF:
        raise ValueError("MSP payload longer than 65535 bytes")
    out = bytearray(6 + size)
    out[0] = flags
    out[1] = cmd & 0xFF
    out[2] = cmd >> 8
    out[3] = size & 0xFF
    out[4] = size >> 8
    for j in range(size):
        out[5 + j] = payload[j]
    out[5 + size] = crc8_dvb_s2(out, 0, 5 + size)
    return out


def encode_v2(cmd, payload=b"", direction=DIR_REPLY, error=False, flags=0):
    """One native v2 frame `$X`."""
    d = _dir_code(direction, error)
    return bytes(bytearray((_DOLLAR, _X, d))) + bytes(_v2_body(cmd, payload, flags))


def encode_v2_over_v1(cmd, payload=b"", direction=DIR_REPLY, error=False, flags=0):
    """A v2 frame carried in a v1 frame with cmd 255 (outer XOR covers the whole v2 body)."""
    return encode_v1(MSP_V2_FRAME, _v2_body(cmd, payload, flags), direction, error)


def encode_reply(version, cmd, payload=b"", error=False, encapsulated=False):
    """The answer to a request, in the version/encapsulation it was asked in (Betaflight does so)."""
    if version == 1:
        return encode_v1(cmd, payload, DIR_REPLY, error)
    if encapsulated:
        return encode_v2_over_v1(cmd, payload, DIR_REPLY, error)
    return encode_v2(cmd, payload, DIR_REPLY, error)


def encode_request(cmd, payload=b"", version=1, encapsulated=False):
    """A request frame (host client, simulator tests)."""
    if version == 1:
        return encode_v1(cmd, payload, DIR_REQUEST)
    if encapsulated:
        return encode_v2_over_v1(cmd, payload, DIR_REQUEST)
    return encode_v2(cmd, payload, DIR_REQUEST)


# -- payloads (wire units; the server converts from SI once) ---------------------------------------------


def _clamp(v, lo, hi):
    v = int(v)
    if v < lo:
        return lo
    if v > hi:
        return hi
    return v


def _u8(v):
    return _clamp(v, 0, 255)


def _u16(v):
    return _clamp(v, 0, 0xFFFF)


def _i16(v):
    return _clamp(v, -32768, 32767)


def _u32(v):
    return _clamp(v, 0, 0xFFFFFFFF)


def _i32(v):
    return _clamp(v, -0x80000000, 0x7FFFFFFF)


def _ascii(text, n):
    # Fixed-width ASCII field: cut or pad with NUL to n bytes.
    b = text.encode() if isinstance(text, str) else bytes(text)
    if len(b) >= n:
        return b[:n]
    return b + bytes(n - len(b))


def _text(payload, start, end):
    return bytes(payload[start:end]).decode()


def pack_api_version(protocol=API_PROTOCOL, major=API_MAJOR, minor=API_MINOR):
    """MSP_API_VERSION reply: u8 protocol, u8 API major, u8 API minor (1.46 = Betaflight 4.5)."""
    return pack("<BBB", _u8(protocol), _u8(major), _u8(minor))


def unpack_api_version(payload):
    return unpack_from("<BBB", payload, 0)


def pack_fc_variant(identifier):
    """MSP_FC_VARIANT reply: 4 ASCII characters ('BTFL', 'INAV'...)."""
    return _ascii(identifier, 4)


def unpack_fc_variant(payload):
    return _text(payload, 0, 4)


def pack_fc_version(major, minor, patch, version_string=None):
    """MSP_FC_VERSION: u8 ×3 (4.5 form); with a string, the 2025.12+ form adds u8 length + text."""
    out = pack("<BBB", _u8(major), _u8(minor), _u8(patch))
    if version_string is not None:
        s = _ascii(version_string, min(len(version_string), 255))
        out += pack("<B", len(s)) + s
    return out


def unpack_fc_version(payload):
    """(major, minor, patch, version string or None)."""
    major, minor, patch = unpack_from("<BBB", payload, 0)
    s = None
    if len(payload) > 3:
        n = payload[3]
        s = _text(payload, 4, 4 + n)
    return major, minor, patch, s


def pack_board_info(board_id, hw_revision=0, board_type=0, capabilities=0, target_name="",
                    board_name="", manufacturer_id="", signature=b"", mcu_type=0,
                    configuration_state=0, gyro_rate_hz=0, problems=0, spi_devices=0, i2c_devices=0):
    """MSP_BOARD_INFO reply, Betaflight 4.5 layout (reference §6.3)."""
    def counted(s):
        b = s.encode() if isinstance(s, str) else bytes(s)
        b = b[:255]
        return pack("<B", len(b)) + b

    return (
        _ascii(board_id, 4)
        + pack("<HBB", _u16(hw_revision), _u8(board_type), _u8(capabilities))
        + counted(target_name) + counted(board_name) + counted(manufacturer_id)
        + _ascii(signature, 32)
        + pack("<BBHIBB", _u8(mcu_type), _u8(configuration_state), _u16(gyro_rate_hz), _u32(problems),
               _u8(spi_devices), _u8(i2c_devices))
    )


def unpack_board_info(payload):
    """dict of the MSP_BOARD_INFO fields (tolerates a longer payload)."""
    d = {"board_id": _text(payload, 0, 4)}
    d["hw_revision"], d["board_type"], d["capabilities"] = unpack_from("<HBB", payload, 4)
    p = 8
    for key in ("target_name", "board_name", "manufacturer_id"):
        n = payload[p]
        d[key] = _text(payload, p + 1, p + 1 + n)
        p += 1 + n
    d["signature"] = bytes(payload[p:p + 32])
    p += 32
    (d["mcu_type"], d["configuration_state"], d["gyro_rate_hz"], d["problems"], d["spi_devices"],
     d["i2c_devices"]) = unpack_from("<BBHIBB", payload, p)
    return d


def pack_build_info(date, time, git_hash, build_options=()):
    """MSP_BUILD_INFO: char[11] 'Mmm dd yyyy', char[8] 'hh:mm:ss', char[7] git hash, u16 options."""
    out = _ascii(date, 11) + _ascii(time, 8) + _ascii(git_hash, 7)
    for o in build_options:
        out += pack("<H", _u16(o))
    return out


def unpack_build_info(payload):
    n = (len(payload) - 26) // 2
    options = [unpack_from("<H", payload, 26 + 2 * k)[0] for k in range(n)]
    return _text(payload, 0, 11), _text(payload, 11, 19), _text(payload, 19, 26), options


def pack_name(name):
    """MSP_NAME: craft name, 0..16 bytes, no terminator."""
    b = name.encode() if isinstance(name, str) else bytes(name)
    return b[:16]


def unpack_name(payload):
    return bytes(payload).decode()


def _status(cycle_time_us, i2c_errors, sensors, mode_flags, pid_profile, cpu_load_pct, middle,
            arming_disable_flags, arming_flag_count, config_state, cpu_temp_c, extra_mode_bytes):
    extra = bytes(extra_mode_bytes)[:15]
    return (
        pack("<HHHIBH", _u16(cycle_time_us), _u16(i2c_errors), _u16(sensors), _u32(mode_flags),
             _u8(pid_profile), _u16(cpu_load_pct))
        + middle
        + pack("<B", len(extra)) + extra
        + pack("<BIBH", _u8(arming_flag_count), _u32(arming_disable_flags), _u8(config_state),
               _u16(cpu_temp_c))
    )


def pack_status(cycle_time_us, i2c_errors=0, sensors=0, mode_flags=0, pid_profile=0, cpu_load_pct=0,
                arming_disable_flags=0, arming_flag_count=ARMING_FLAG_COUNT, config_state=0,
                cpu_temp_c=0, extra_mode_bytes=b""):
    """MSP_STATUS (API 1.46, 24 bytes with no extra mode bytes).

    sensors: bit0 acc, 1 baro, 2 mag, 3 GPS, 4 rangefinder, 5 gyro. mode_flags: bit i = i-th entry
    of the MSP_BOXIDS list. config_state bit0 = reboot required.
    """
    return _status(cycle_time_us, i2c_errors, sensors, mode_flags, pid_profile, cpu_load_pct,
                   pack("<H", 0), arming_disable_flags, arming_flag_count, config_state, cpu_temp_c,
                   extra_mode_bytes)


def pack_status_ex(cycle_time_us, i2c_errors=0, sensors=0, mode_flags=0, pid_profile=0, cpu_load_pct=0,
                   arming_disable_flags=0, arming_flag_count=ARMING_FLAG_COUNT, config_state=0,
                   cpu_temp_c=0, extra_mode_bytes=b"", pid_profile_count=1, rate_profile=0):
    """MSP_STATUS_EX: as MSP_STATUS with the u16 0 replaced by u8 PID-profile count, u8 rate profile."""
    return _status(cycle_time_us, i2c_errors, sensors, mode_flags, pid_profile, cpu_load_pct,
                   pack("<BB", _u8(pid_profile_count), _u8(rate_profile)), arming_disable_flags,
                   arming_flag_count, config_state, cpu_temp_c, extra_mode_bytes)


def unpack_status(payload, ex=False):
    """dict of MSP_STATUS / MSP_STATUS_EX fields (older, shorter replies give what they carry)."""
    d = {}
    (d["cycle_time_us"], d["i2c_errors"], d["sensors"], d["mode_flags"], d["pid_profile"],
     d["cpu_load_pct"]) = unpack_from("<HHHIBH", payload, 0)
    if ex:
        d["pid_profile_count"], d["rate_profile"] = unpack_from("<BB", payload, 13)
    p = 15
    if len(payload) <= p:
        return d
    n = payload[p] & 0x0F  # Betaflight: the low 4 bits hold the byte count
    d["extra_mode_bytes"] = bytes(payload[p + 1:p + 1 + n])
    p += 1 + n
    d["arming_flag_count"], d["arming_disable_flags"], d["config_state"] = unpack_from("<BIB", payload, p)
    p += 6
    if len(payload) >= p + 2:
        d["cpu_temp_c"] = unpack_from("<H", payload, p)[0]
    return d


def pack_raw_imu(acc, gyro, mag=(0, 0, 0)):
    """MSP_RAW_IMU: 3 × i16 acc (LSB, 1 g = acc_1G e.g. 2048), 3 × i16 gyro (sensor LSB, ~16.4 per
    deg/s on a +-2000 deg/s part; the configurator scales by 4/16.4), 3 × i16 mag raw."""
    return pack("<hhhhhhhhh", _i16(acc[0]), _i16(acc[1]), _i16(acc[2]), _i16(gyro[0]), _i16(gyro[1]),
                _i16(gyro[2]), _i16(mag[0]), _i16(mag[1]), _i16(mag[2]))


def unpack_raw_imu(payload):
    v = unpack_from("<hhhhhhhhh", payload, 0)
    return v[0:3], v[3:6], v[6:9]


def _pack_u16s(values, count=-1):
    n = len(values) if count < 0 else count
    out = bytearray(2 * n)
    for k in range(n):
        pack_into("<H", out, 2 * k, _u16(values[k]) if k < len(values) else 0)
    return bytes(out)


def _unpack_u16s(payload, length=-1):
    if length < 0:
        length = len(payload)
    return [unpack_from("<H", payload, 2 * k)[0] for k in range(length // 2)]


def pack_motor(motors_us):
    """MSP_MOTOR: 8 × u16 on the 1000..2000 scale, 0 for absent motors (padded to 8)."""
    return _pack_u16s(motors_us, 8)


def unpack_motor(payload):
    return _unpack_u16s(payload)


def pack_rc(channels_us):
    """MSP_RC: N × u16 µs in roll, pitch, yaw, throttle, aux1... order (after the channel map)."""
    return _pack_u16s(channels_us)


def unpack_rc(payload):
    return _unpack_u16s(payload)


def pack_attitude(roll_decideg, pitch_decideg, yaw_deg):
    """MSP_ATTITUDE: i16 roll 0.1 deg, i16 pitch 0.1 deg, i16 heading whole degrees 0..359 (wrapped)."""
    heading = int(yaw_deg) % 360
    return pack("<hhh", _i16(roll_decideg), _i16(pitch_decideg), heading)


def unpack_attitude(payload):
    """(roll_decideg, pitch_decideg, yaw_deg)."""
    return unpack_from("<hhh", payload, 0)


def pack_altitude(altitude_cm, vario_cm_s):
    """MSP_ALTITUDE: i32 estimated altitude cm, i16 vario cm/s."""
    return pack("<ih", _i32(altitude_cm), _i16(vario_cm_s))


def unpack_altitude(payload):
    return unpack_from("<ih", payload, 0)


def pack_analog(voltage_cv, mah_drawn, rssi=0, current_ca=0):
    """MSP_ANALOG: u8 battery 0.1 V (rounded, clamped 0..255), u16 mAh drawn, u16 RSSI 0..1023,
    i16 current 0.01 A, u16 battery 0.01 V. Takes the battery voltage in 0.01 V (centivolts)."""
    v = _u16(voltage_cv)
    return pack("<BHHhH", _u8((v + 5) // 10), _u16(mah_drawn), _clamp(rssi, 0, 1023), _i16(current_ca), v)


def unpack_analog(payload):
    """(voltage_dv, mah_drawn, rssi, current_ca, voltage_cv); voltage_cv is None in a 7-byte reply."""
    dv, mah, rssi, ca = unpack_from("<BHHh", payload, 0)
    cv = unpack_from("<H", payload, 7)[0] if len(payload) >= 9 else None
    return dv, mah, rssi, ca, cv


RC_TUNING_FIELDS = (
    # (name, struct code): wire order of MSP_RC_TUNING (API 1.46); rates/expo are x100.
    ("roll_rc_rate", "B"), ("roll_rc_expo", "B"), ("roll_rate", "B"), ("pitch_rate", "B"),
    ("yaw_rate", "B"), ("_zero0", "B"), ("throttle_mid", "B"), ("throttle_expo", "B"), ("_zero1", "H"),
    ("yaw_expo", "B"), ("yaw_rc_rate", "B"), ("pitch_rc_rate", "B"), ("pitch_expo", "B"),
    ("throttle_limit_type", "B"), ("throttle_limit_pct", "B"), ("roll_rate_limit_dps", "H"),
    ("pitch_rate_limit_dps", "H"), ("yaw_rate_limit_dps", "H"), ("rates_type", "B"),
)
_RC_TUNING_FORMAT = "<" + "".join(f[1] for f in RC_TUNING_FIELDS)


def pack_rc_tuning(values):
    """MSP_RC_TUNING (23 bytes) from a dict keyed by RC_TUNING_FIELDS names; missing = 0."""
    args = []
    for name, code in RC_TUNING_FIELDS:
        v = values.get(name, 0)
        args.append(_u8(v) if code == "B" else _u16(v))
    return pack(_RC_TUNING_FORMAT, *args)


def unpack_rc_tuning(payload):
    v = unpack_from(_RC_TUNING_FORMAT, payload, 0)
    d = {}
    for k in range(len(RC_TUNING_FIELDS)):
        name = RC_TUNING_FIELDS[k][0]
        if name[0] != "_":
            d[name] = v[k]
    return d


def pack_pid(gains):
    """MSP_PID / MSP_SET_PID: 5 × (u8 P, u8 I, u8 D) for roll, pitch, yaw, level, mag (15 bytes).

    gains: up to 5 (p, i, d) triples, Betaflight gain scale; missing rows are 0."""
    out = bytearray(15)
    for r in range(min(len(gains), 5)):
        g = gains[r]
        out[3 * r] = _u8(g[0])
        out[3 * r + 1] = _u8(g[1])
        out[3 * r + 2] = _u8(g[2])
    return bytes(out)


def unpack_pid(payload):
    """List of (p, i, d) triples, one per 3 bytes present."""
    return [(payload[3 * r], payload[3 * r + 1], payload[3 * r + 2]) for r in range(len(payload) // 3)]


def pack_boxnames(names):
    """MSP_BOXNAMES: 'NAME;' per active mode."""
    return "".join(n + ";" for n in names).encode()


def unpack_boxnames(payload):
    s = bytes(payload).decode()
    return [n for n in s.split(";") if n]


def pack_boxids(ids):
    """MSP_BOXIDS: u8 permanent id per active mode, same order as MSP_BOXNAMES."""
    return bytes(bytearray(_u8(i) for i in ids))


def unpack_boxids(payload):
    return list(bytes(payload))


def step_of_us(pulse_us):
    """Mode-range step: (clamp(us, 900, 2100) - 900) / 25, as Betaflight's CHANNEL_VALUE_TO_STEP."""
    return (_clamp(pulse_us, 900, 2100) - 900) // 25


def us_of_step(step):
    return 900 + 25 * step


def pack_mode_ranges(ranges, slots=20):
    """MSP_MODE_RANGES: per slot u8 permanent box id, u8 aux channel index, u8 start step, u8 end step.

    Betaflight sends all 20 slots (MAX_MODE_ACTIVATION_CONDITION_COUNT), unused ones zero. Not in
    the reference table: layout from Betaflight's msp.c; yamspy reads it the same way."""
    out = bytearray(4 * slots)
    for k in range(min(len(ranges), slots)):
        r = ranges[k]
        out[4 * k] = _u8(r[0])
        out[4 * k + 1] = _u8(r[1])
        out[4 * k + 2] = _clamp(r[2], 0, 48)
        out[4 * k + 3] = _clamp(r[3], 0, 48)
    return bytes(out)


def unpack_mode_ranges(payload):
    return [tuple(payload[4 * k:4 * k + 4]) for k in range(len(payload) // 4)]


MODE_RANGE_SLOTS = const(20)  # Betaflight's MAX_MODE_ACTIVATION_CONDITION_COUNT
MODE_RANGE_MAX_STEP = const(48)  # 2100 us


def pack_set_mode_range(index, box_id, aux, start_step, end_step, logic=None, linked_box=None):
    """MSP_SET_MODE_RANGE request: u8 slot, u8 permanent box id, u8 aux channel index (0 = AUX1),
    u8 start step, u8 end step; Betaflight 3.4+ configurators add u8 mode logic (0 OR, 1 AND) and
    u8 linked box id (0 = none). Layout from Betaflight's msp.c."""
    out = pack("<BBBBB", _u8(index), _u8(box_id), _u8(aux), _u8(start_step), _u8(end_step))
    if logic is not None:
        out += pack("<BB", _u8(logic), _u8(linked_box or 0))
    return out


def unpack_set_mode_range(payload, length=-1):
    """(slot, box id, aux index, start step, end step, logic, linked box) of a SET_MODE_RANGE request;
    logic and linked box read as 0 when the short (5-byte) form came. None when under 5 bytes."""
    if length < 0:
        length = len(payload)
    if length < 5:
        return None
    logic = payload[5] if length > 5 else 0
    linked = payload[6] if length > 6 else 0
    return payload[0], payload[1], payload[2], payload[3], payload[4], logic, linked


# MSP2_HOVERFLY_AUTOPILOT reply: seed 004's privilege state (core/command/autopilot.py) for the companion.
AUTOPILOT_FORMAT = "<BBBBBBHHBBHII"
AUTOPILOT_SIZE = const(22)
AUTOPILOT_FIELDS = ("state", "privilege", "flier", "override", "soft_axes", "latch", "latch_throttle_us",
                    "throttle_us", "last_result", "last_arm_reason", "last_frame_age_ms", "frames", "rejected")
FLIER_NAMES = ("nobody", "pilot", "autopilot", "failsafe", "motor_test")  # "flier" values
OVERRIDE_KIND_NAMES = ("none", "soft", "hard")  # "override" values


def pack_autopilot(state, privilege, flier, override, soft_axes, latch, latch_throttle_us, throttle_us,
                   last_result, last_arm_reason, last_frame_age_ms, frames, rejected):
    """MSP2_HOVERFLY_AUTOPILOT reply (22 bytes): u8 autopilot state (0 off, 1 waiting for the arm
    switch, 2 enabled, 3 silent), u8 privilege bits (1 RC accepted, 2 may arm, 4 in control, 8 soft
    override, 16 throttle latched), u8 who flies (FLIER_NAMES), u8 override kind (0 none, 1 soft,
    2 hard), u8 soft-override axes (1 roll, 2 pitch, 4 throttle cap), u8 latch cause (0 none, 1 hard
    override, 2 autopilot timeout), u16 latched throttle us (0 = none), u16 the autopilot's last
    throttle us (0 = no frame since enabled), u8 last MSP RC result (0 taken, else the refusal code),
    u8 arming reason bit that refused its last arm request (255 none), u16 ms since its last taken
    frame (65535 = none or longer), u32 frames taken, u32 frames refused."""
    return pack(AUTOPILOT_FORMAT, _u8(state), _u8(privilege), _u8(flier), _u8(override), _u8(soft_axes),
                _u8(latch), _u16(latch_throttle_us), _u16(throttle_us), _u8(last_result),
                _u8(last_arm_reason), _u16(last_frame_age_ms), _u32(frames), _u32(rejected))


def unpack_autopilot(payload, length=-1):
    """dict of AUTOPILOT_FIELDS; None when the payload is short (a later version may add fields)."""
    if length < 0:
        length = len(payload)
    if length < AUTOPILOT_SIZE:
        return None
    values = unpack_from(AUTOPILOT_FORMAT, payload, 0)
    out = {}
    for k in range(len(AUTOPILOT_FIELDS)):
        out[AUTOPILOT_FIELDS[k]] = values[k]
    return out


def pack_uid(uid0, uid1, uid2):
    """MSP_UID: 3 × u32 MCU unique id."""
    return pack("<III", _u32(uid0), _u32(uid1), _u32(uid2))


def unpack_uid(payload):
    return unpack_from("<III", payload, 0)


def pack_set_raw_rc(channels_us):
    """MSP_SET_RAW_RC request: N <= 18 × u16 µs in receiver (AETR1234) order."""
    return _pack_u16s(channels_us[:18])


def unpack_set_raw_rc(payload, length=-1):
    """Channels of an MSP_SET_RAW_RC request (list, at most 18; an odd trailing byte is ignored)."""
    if length < 0:
        length = len(payload)
    n = length // 2
    if n > 18:
        n = 18
    return [payload[2 * k] | (payload[2 * k + 1] << 8) for k in range(n)]


def unpack_set_raw_rc_into(payload, length, out):
    """As unpack_set_raw_rc into a preallocated array/list; returns the channel count. No allocation."""
    n = length >> 1
    if n > len(out):
        n = len(out)
    if n > 18:
        n = 18
    for k in range(n):
        out[k] = payload[2 * k] | (payload[2 * k + 1] << 8)
    return n


def pack_set_motor(motors_us):
    """MSP_SET_MOTOR request: u16 per motor on the 1000..2000 scale (configurators send 8)."""
    return _pack_u16s(motors_us, 8)


# Servos, in INAV's layouts (INAV's fc_msp.c): MSP_SERVO's widths, MSP_SERVO_CONFIGURATIONS' 14 bytes a servo
# (the last 7 are fields INAV keeps for old configurators: 0, 0, 255, u32 0), and MSP2_INAV_SERVO_MIXER's
# 6 bytes a rule (the last a logic condition id, 255 = always).
SERVO_CONFIG_BYTES = const(14)
SERVO_RULE_BYTES = const(6)


def pack_servo(widths_us):
    """MSP_SERVO: u16 µs per servo."""
    return _pack_u16s(widths_us)


def pack_air_speed(airspeed_cm_s):
    """MSP2_INAV_AIR_SPEED: u32 airspeed in cm/s, INAV's fc_msp.c (getAirspeedEstimate(); 0 without a pitot)."""
    return pack("<I", _u32(airspeed_cm_s))


def unpack_air_speed(payload, length=-1):
    """The cm/s of an MSP2_INAV_AIR_SPEED reply, or None when it is shorter than its 4 bytes."""
    if length < 0:
        length = len(payload)
    if length < 4:
        return None
    return unpack_from("<I", payload, 0)[0]


def pack_servo_configurations(servos):
    """MSP_SERVO_CONFIGURATIONS: per servo (min_us, max_us, mid_us, rate %): u16 min, u16 max, u16 middle,
    i8 rate, then 0, 0, 255, u32 0."""
    out = bytearray()
    for lo, hi, mid, rate in servos:
        out += pack("<HHHbBBBI", lo & 0xFFFF, hi & 0xFFFF, mid & 0xFFFF, max(-128, min(127, rate)), 0, 0, 255, 0)
    return bytes(out)


def unpack_servo_configurations(payload):
    """[(min_us, max_us, mid_us, rate %)] from an MSP_SERVO_CONFIGURATIONS payload."""
    return [unpack_from("<HHHb", payload, k) for k in range(0, len(payload) - SERVO_CONFIG_BYTES + 1,
                                                            SERVO_CONFIG_BYTES)]


def pack_set_servo_configuration(index, lo, hi, mid, rate):
    """MSP_SET_SERVO_CONFIGURATION request: u8 index, then one servo as MSP_SERVO_CONFIGURATIONS has it."""
    return pack("<B", _u8(index)) + pack_servo_configurations(((lo, hi, mid, rate),))


def unpack_set_servo_configuration(payload, length=-1):
    """(index, min_us, max_us, mid_us, rate %) from MSP_SET_SERVO_CONFIGURATION, or None unless it is the 15
    bytes INAV takes."""
    if length < 0:
        length = len(payload)
    if length != 1 + SERVO_CONFIG_BYTES:
        return None
    return unpack_from("<BHHHb", payload, 0)


def pack_servo_mixer(rules):
    """MSP2_INAV_SERVO_MIXER: per rule (servo, input, rate %, speed): u8 servo, u8 input, i16 rate, u8 speed,
    u8 condition (255: hoverfly has no logic conditions)."""
    out = bytearray()
    for servo, source, rate, speed in rules:
        out += pack("<BBhBB", _u8(servo), _u8(source), _i16(rate), _u8(speed), 255)
    return bytes(out)


def unpack_servo_mixer(payload):
    """[(servo, input, rate %, speed, condition)] from an MSP2_INAV_SERVO_MIXER payload."""
    return [unpack_from("<BBhBB", payload, k) for k in range(0, len(payload) - SERVO_RULE_BYTES + 1,
                                                             SERVO_RULE_BYTES)]


def pack_set_servo_mixer(index, servo, source, rate, speed, condition=255):
    """MSP2_INAV_SET_SERVO_MIXER request: u8 rule index, then one rule as MSP2_INAV_SERVO_MIXER has it."""
    return pack("<BBBhBB", _u8(index), _u8(servo), _u8(source), _i16(rate), _u8(speed), _u8(condition))


def unpack_set_servo_mixer(payload, length=-1):
    """(index, servo, input, rate %, speed, condition) from MSP2_INAV_SET_SERVO_MIXER, or None unless it is the
    7 bytes INAV takes."""
    if length < 0:
        length = len(payload)
    if length != 1 + SERVO_RULE_BYTES:
        return None
    return unpack_from("<BBBhBB", payload, 0)


def unpack_set_motor(payload, length=-1):
    if length < 0:
        length = len(payload)
    return [payload[2 * k] | (payload[2 * k + 1] << 8) for k in range(length // 2)]


def pack_reboot(mode=None):
    """MSP_REBOOT request: optional u8 mode (0 firmware, 1 ROM bootloader, 2 MSC, 3 MSC UTC, 4 flash
    bootloader). The reply carries the same u8 mode."""
    return b"" if mode is None else pack("<B", _u8(mode))


def unpack_reboot(payload, length=-1):
    """The requested mode; 0 (firmware) when the request is empty."""
    if length < 0:
        length = len(payload)
    return payload[0] if length > 0 else 0


def pack_set_arming_disabled(disable, runaway_takeoff_disabled=None):
    """MSP_SET_ARMING_DISABLED request: u8 1 = block arming / 0 = release; optional u8 runaway flag."""
    out = pack("<B", 1 if disable else 0)
    if runaway_takeoff_disabled is not None:
        out += pack("<B", 1 if runaway_takeoff_disabled else 0)
    return out


def unpack_set_arming_disabled(payload, length=-1):
    """(disable, runaway_takeoff_disabled); missing bytes read as 0."""
    if length < 0:
        length = len(payload)
    disable = payload[0] if length > 0 else 0
    runaway = payload[1] if length > 1 else 0
    return disable, runaway
