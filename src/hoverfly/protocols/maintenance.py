"""Seed-001 maintenance protocol codec (the RP2040 drone controller's debug link), byte-exact.

Takes the bytes of a maintenance port (USB or UART 115200 8N1) in any chunking through
`MaintenanceParser.feed`: requests on the server side, replies on the client side. Gives the
decoded request (wanted-field mask, command id and arguments, REMOTE_CONTROL_TAG) or the reply's
values in header order. Encodes both (`encode_request`, `encode_reply`) and checks command
arguments (`validate_command`, `validate_remote_control`) so the server can refuse with a
reason. The server logic (which values to answer, what a command does) is not here.
It sits between board.serial and the maintenance server, next to MSP.

Frame (both directions): `0xFF` sync, 8 header bytes, payload, XOR checksum over everything
but the sync byte. The header holds 57 "send me this value" bits (FIELDS, in the seed's order)
and a 7-bit command id. A request's payload is the command's arguments (COMMANDS) followed by
the 9-byte REMOTE_CONTROL_TAG; a reply echoes the header and its payload is the requested
values in header order (no REMOTE_CONTROL_TAG). Multi-byte values are little-endian, as the
seed's RP2040 sends its raw structs. Where the seed contradicts itself, the choice made here is
documented in docs/maintenance-protocol.md (header bit order, PID layout, imu_offset size).
"""

from struct import calcsize, pack_into, unpack_from

from hoverfly.compat import const
from hoverfly.protocols.crc import xor8
from hoverfly.protocols.msp import FrameScanner

SYNC = const(0xFF)
HEADER_LEN = const(8)
RC_TAG_LEN = const(9)
MAX_CMD_ID = const(25)

# Header bit layouts. SEED: the seed's table, field k at bit 7 - k%8 of header byte k//8 (first
# field in the MSB), cmd id in bits 6..0 of byte 7. FIRMWARE: the seed project's C code, a GCC
# little-endian uint64 bitfield: field k at bit k%8 of byte k//8, cmd id in bits 7..1 of byte 7.
LAYOUT_SEED = const(0)
LAYOUT_FIRMWARE = const(1)

# IMU type enum (command 21, field imu_type)
IMU_LSM9DS1 = const(0)
IMU_MPU6050 = const(1)
IMU_BNO055 = const(2)
IMU_TYPE_NAMES = ("LSM9DS1", "MPU6050", "BNO055")

# sw_ver release type
RELEASE_BETA = const(0)
RELEASE_RELEASE = const(1)

# Row layouts of the array fields (flat, row-major in the payload).
MOTOR_PARAM_ENABLED = const(0)  # motor_params: per motor 1..4: enabled, min pulse µs, max pulse µs
MOTOR_PARAM_MIN_US = const(1)
MOTOR_PARAM_MAX_US = const(2)
PID_KP = const(0)  # PID_params: per axis roll, pitch, yaw: KP KI KT SAT AD BD
PID_KI = const(1)
PID_KT = const(2)
PID_SAT = const(3)
PID_AD = const(4)
PID_BD = const(5)

# The 57 header fields in the seed's order: (name, struct code, count). Sizes: f 4, H 2, B 1, I 4.
FIELDS = (
    ("raw_accel_x", "f", 1), ("raw_accel_y", "f", 1), ("raw_accel_z", "f", 1),
    ("raw_gyro_x", "f", 1), ("raw_gyro_y", "f", 1), ("raw_gyro_z", "f", 1),
    ("raw_magn_x", "f", 1), ("raw_magn_y", "f", 1), ("raw_magn_z", "f", 1),
    ("filtered_accel_x", "f", 1), ("filtered_accel_y", "f", 1), ("filtered_accel_z", "f", 1),
    ("filtered_gyro_x", "f", 1), ("filtered_gyro_y", "f", 1), ("filtered_gyro_z", "f", 1),
    ("filtered_magn_x", "f", 1), ("filtered_magn_y", "f", 1), ("filtered_magn_z", "f", 1),
    ("throttle_signal", "H", 1), ("roll_signal", "H", 1), ("pitch_signal", "H", 1),
    ("throttle_set_point", "H", 1), ("roll_set_point", "f", 1), ("pitch_set_point", "f", 1),
    ("body_roll", "f", 1), ("body_pitch", "f", 1), ("body_yaw", "f", 1),
    ("roll_PID_error", "f", 1), ("roll_PID_p", "f", 1), ("roll_PID_i", "f", 1),
    ("roll_PID_d", "f", 1), ("roll_PID_u", "f", 1),
    ("pitch_PID_error", "f", 1), ("pitch_PID_p", "f", 1), ("pitch_PID_i", "f", 1),
    ("pitch_PID_d", "f", 1), ("pitch_PID_u", "f", 1),
    ("yaw_PID_error", "f", 1), ("yaw_PID_p", "f", 1), ("yaw_PID_i", "f", 1),
    ("yaw_PID_d", "f", 1), ("yaw_PID_u", "f", 1),
    ("motor1_signal", "H", 1), ("motor2_signal", "H", 1), ("motor3_signal", "H", 1),
    ("motor4_signal", "H", 1), ("motors_armed", "B", 1), ("builtin_test_status", "I", 1),
    ("motor_params", "I", 12),  # uint32[4][3]: enabled, min µs, max µs per motor
    ("js_params", "f", 6),  # float[3][2]: alpha, beta for throttle, roll, pitch
    ("PID_params", "f", 18),  # float[3][6]: KP KI KT SAT AD BD for roll, pitch, yaw
    ("ptf1_params", "f", 9),  # float[3][3]: time constant x, y, z for accel, gyro, magn
    ("imu_type", "B", 1), ("i2c_read", "B", 1),
    ("sw_ver", "B", 4),  # major, minor, stage, release type
    ("imu_offset", "f", 3),  # roll, pitch, reserved: the seed's 12 bytes (its type says float[2])
    ("throttle_params", "H", 3),  # descend, hovering, climb µs
)
FIELD_COUNT = const(57)

# Command table, index = command id: (name, struct format of the arguments, argument names).
COMMANDS = (
    ("none", "", ()),
    ("set_motor1", "H", ("pulse_us",)),
    ("set_motor2", "H", ("pulse_us",)),
    ("set_motor3", "H", ("pulse_us",)),
    ("set_motor4", "H", ("pulse_us",)),
    ("set_all_motors", "H", ("pulse_us",)),
    ("control_motors", "B", ("enable",)),
    ("flash_write", "", ()),
    ("set_motor1_params", "BHH", ("enabled", "min_pulse_us", "max_pulse_us")),
    ("set_motor2_params", "BHH", ("enabled", "min_pulse_us", "max_pulse_us")),
    ("set_motor3_params", "BHH", ("enabled", "min_pulse_us", "max_pulse_us")),
    ("set_motor4_params", "BHH", ("enabled", "min_pulse_us", "max_pulse_us")),
    ("set_js_throttle", "ff", ("alpha", "beta")),
    ("set_js_roll", "ff", ("alpha", "beta")),
    ("set_js_pitch", "ff", ("alpha", "beta")),
    ("set_roll_pid", "ffffff", ("kp", "ki", "kt", "sat", "ad", "bd")),
    ("set_pitch_pid", "ffffff", ("kp", "ki", "kt", "sat", "ad", "bd")),
    ("set_yaw_pid", "ffffff", ("kp", "ki", "kt", "sat", "ad", "bd")),
    ("set_pt1_accel", "fff", ("tau_x_s", "tau_y_s", "tau_z_s")),
    ("set_pt1_gyro", "fff", ("tau_x_s", "tau_y_s", "tau_z_s")),
    ("set_pt1_magn", "fff", ("tau_x_s", "tau_y_s", "tau_z_s")),
    ("set_imu_type", "B", ("imu_type",)),
    ("i2c_read", "BBB", ("channel", "address", "register")),
    ("i2c_write", "BBBB", ("channel", "address", "register", "value")),
    ("reset_imu_offset", "", ()),
    ("set_throttle_params", "HHH", ("descend_us", "hover_us", "climb_us")),
)
CMD_NONE = const(0)
CMD_SET_MOTOR1 = const(1)
CMD_SET_MOTOR2 = const(2)
CMD_SET_MOTOR3 = const(3)
CMD_SET_MOTOR4 = const(4)
CMD_SET_ALL_MOTORS = const(5)
CMD_CONTROL_MOTORS = const(6)
CMD_FLASH_WRITE = const(7)
CMD_SET_MOTOR1_PARAMS = const(8)
CMD_SET_MOTOR2_PARAMS = const(9)
CMD_SET_MOTOR3_PARAMS = const(10)
CMD_SET_MOTOR4_PARAMS = const(11)
CMD_SET_JS_THROTTLE = const(12)
CMD_SET_JS_ROLL = const(13)
CMD_SET_JS_PITCH = const(14)
CMD_SET_ROLL_PID = const(15)
CMD_SET_PITCH_PID = const(16)
CMD_SET_YAW_PID = const(17)
CMD_SET_PT1_ACCEL = const(18)
CMD_SET_PT1_GYRO = const(19)
CMD_SET_PT1_MAGN = const(20)
CMD_SET_IMU_TYPE = const(21)
CMD_I2C_READ = const(22)
CMD_I2C_WRITE = const(23)
CMD_RESET_IMU_OFFSET = const(24)
CMD_SET_THROTTLE_PARAMS = const(25)

PULSE_MIN_US = const(1000)
PULSE_MAX_US = const(2000)
_MAX_ARGS = const(6)


def _sizes():
    field_size = bytearray(FIELD_COUNT)
    for k in range(FIELD_COUNT):
        f = FIELDS[k]
        field_size[k] = calcsize("<" + f[1]) * f[2]
    arg_size = bytearray(MAX_CMD_ID + 1)
    for c in range(MAX_CMD_ID + 1):
        arg_size[c] = calcsize("<" + COMMANDS[c][1])
    return bytes(field_size), bytes(arg_size)


FIELD_SIZE, ARG_SIZE = _sizes()
MAX_REPLY_PAYLOAD = sum(FIELD_SIZE)  # 377 bytes with every field requested

_FIELD_INDEX = {}
for _k in range(FIELD_COUNT):
    _FIELD_INDEX[FIELDS[_k][0]] = _k
_FIELD_INDEX["pt1f_params"] = _FIELD_INDEX["ptf1_params"]  # the seed's reply table spells it so


def field_index(name_or_index):
    """Index of a header field given its name (or the index itself); -1 if unknown."""
    if isinstance(name_or_index, int):
        return name_or_index if 0 <= name_or_index < FIELD_COUNT else -1
    return _FIELD_INDEX.get(name_or_index, -1)


def request_size(cmd_id):
    """Bytes after the header of a request: arguments + REMOTE_CONTROL_TAG + checksum (the seed's
    'Payload size' column); -1 for an unknown command."""
    if cmd_id < 0 or cmd_id > MAX_CMD_ID:
        return -1
    return ARG_SIZE[cmd_id] + RC_TAG_LEN + 1


# -- header ----------------------------------------------------------------------------------------------


def _bit(k, layout):
    if layout == LAYOUT_FIRMWARE:
        return 1 << (k & 7)
    return 0x80 >> (k & 7)


def header_cmd(header, layout=LAYOUT_SEED, offset=0):
    """The 7-bit command id of a header."""
    b = header[offset + 7]
    return (b >> 1) if layout == LAYOUT_FIRMWARE else (b & 0x7F)


def header_wants(header, k, layout=LAYOUT_SEED, offset=0):
    """True if field index k is requested."""
    return (header[offset + (k >> 3)] & _bit(k, layout)) != 0


def header_fields(header, layout=LAYOUT_SEED, offset=0):
    """Indices of the requested fields, in header order."""
    return [k for k in range(FIELD_COUNT) if header[offset + (k >> 3)] & _bit(k, layout)]


def header_mask(header, layout=LAYOUT_SEED, offset=0):
    """(lo, hi): fields 0..28 in bits 0..28 of lo, fields 29..56 in bits 0..27 of hi. Both stay below
    2**30 (rp2 small ints)."""
    lo = 0
    hi = 0
    for k in range(FIELD_COUNT):
        if header[offset + (k >> 3)] & _bit(k, layout):
            if k < 29:
                lo |= 1 << k
            else:
                hi |= 1 << (k - 29)
    return lo, hi


def encode_header(fields_wanted, cmd_id, layout=LAYOUT_SEED):
    """8 header bytes: fields_wanted (names or indices; 'all' for every field) and a command id."""
    if cmd_id < 0 or cmd_id > 127:
        raise ValueError("maintenance command id must be 0..127")
    h = bytearray(HEADER_LEN)
    if fields_wanted == "all":
        fields_wanted = range(FIELD_COUNT)
    for f in fields_wanted:
        k = field_index(f)
        if k < 0:
            raise ValueError("unknown maintenance field %r" % (f,))
        h[k >> 3] |= _bit(k, layout)
    if layout == LAYOUT_FIRMWARE:
        h[7] |= cmd_id << 1
    else:
        h[7] |= cmd_id
    return h


def reply_payload_size(header, layout=LAYOUT_SEED, offset=0):
    """Bytes of values a reply to this header carries (without the checksum)."""
    n = 0
    size = FIELD_SIZE
    for k in range(FIELD_COUNT):
        if header[offset + (k >> 3)] & _bit(k, layout):
            n += size[k]
    return n


# -- validation -------------------------------------------------------------------------------------------


def _finite(x):
    return x - x == 0  # False for nan and +-inf


def _pulse_ok(v):
    return PULSE_MIN_US <= v <= PULSE_MAX_US


def validate_remote_control(override, armed_us, roll_us, pitch_us, throttle_us):
    """None if the REMOTE_CONTROL_TAG is acceptable, else the reason. Pulse widths are only checked
    when override is 1 (a client not overriding may send zeros)."""
    if override != 0 and override != 1:
        return "radio override flag must be 0 or 1"
    if override:
        if not (_pulse_ok(armed_us) and _pulse_ok(roll_us) and _pulse_ok(pitch_us)
                and _pulse_ok(throttle_us)):
            return "override pulse widths must be 1000..2000 us"
    return None


def validate_command(cmd_id, args):
    """None if the command and its arguments are acceptable, else a one-line reason."""
    if cmd_id < 0 or cmd_id > MAX_CMD_ID:
        return "unknown command id %d" % cmd_id
    if len(args) < len(COMMANDS[cmd_id][2]):
        return "%s needs %d arguments" % (COMMANDS[cmd_id][0], len(COMMANDS[cmd_id][2]))
    if CMD_SET_MOTOR1 <= cmd_id <= CMD_SET_ALL_MOTORS:
        if not _pulse_ok(args[0]):
            return "motor pulse width must be 1000..2000 us"
    elif cmd_id == CMD_CONTROL_MOTORS:
        if args[0] != 0 and args[0] != 1:
            return "motor control flag must be 0 or 1"
    elif CMD_SET_MOTOR1_PARAMS <= cmd_id <= CMD_SET_MOTOR4_PARAMS:
        if args[0] != 0 and args[0] != 1:
            return "motor enabled flag must be 0 or 1"
        if not (_pulse_ok(args[1]) and _pulse_ok(args[2])):
            return "motor min/max pulse widths must be 1000..2000 us"
        if args[1] >= args[2]:
            return "motor min pulse width must be below max"
    elif CMD_SET_JS_THROTTLE <= cmd_id <= CMD_SET_JS_PITCH:
        if not (_finite(args[0]) and _finite(args[1])):
            return "joystick alpha/beta must be finite numbers"
    elif CMD_SET_ROLL_PID <= cmd_id <= CMD_SET_YAW_PID:
        for k in range(6):
            if not _finite(args[k]):
                return "PID parameters must be finite numbers"
        if args[0] < 0 or args[1] < 0 or args[2] < 0 or args[3] < 0:
            return "PID KP, KI, KT and SAT must not be negative"
    elif CMD_SET_PT1_ACCEL <= cmd_id <= CMD_SET_PT1_MAGN:
        for k in range(3):
            if not _finite(args[k]) or args[k] < 0:
                return "pt1 time constants must be finite and not negative"
    elif cmd_id == CMD_SET_IMU_TYPE:
        if args[0] < 0 or args[0] > IMU_BNO055:
            return "IMU type must be 0 (LSM9DS1), 1 (MPU6050) or 2 (BNO055)"
    elif cmd_id == CMD_I2C_READ or cmd_id == CMD_I2C_WRITE:
        if args[0] != 0 and args[0] != 1:
            return "I2C channel must be 0 or 1"
        if args[1] < 0 or args[1] > 0x7F:
            return "I2C address must be 7-bit (0..127)"
        for k in range(2, len(COMMANDS[cmd_id][2])):
            if args[k] < 0 or args[k] > 255:
                return "I2C register and value must be 0..255"
    elif cmd_id == CMD_SET_THROTTLE_PARAMS:
        if not (_pulse_ok(args[0]) and _pulse_ok(args[1]) and _pulse_ok(args[2])):
            return "throttle descend/hover/climb must be 1000..2000 us"
        if not (args[0] <= args[1] <= args[2]):
            return "throttle params must be descend <= hover <= climb"
    return None


# -- encoders ---------------------------------------------------------------------------------------------


def _put(fmt_code, buf, p, v):
    # Range-check before struct.pack (MicroPython packs out-of-range ints silently).
    if fmt_code == "f":
        pack_into("<f", buf, p, float(v))
        return 4
    v = int(v)
    if fmt_code == "B":
        hi = 0xFF
    elif fmt_code == "H":
        hi = 0xFFFF
    else:
        hi = 0xFFFFFFFF
    if v < 0 or v > hi:
        raise ValueError("maintenance value %d out of range 0..%d" % (v, hi))
    pack_into("<" + fmt_code, buf, p, v)
    return calcsize("<" + fmt_code)


def encode_request(fields_wanted, cmd_id=CMD_NONE, cmd_args=(), remote_control=None, layout=LAYOUT_SEED):
    """A whole request frame: sync, header, arguments, REMOTE_CONTROL_TAG, checksum.

    remote_control: (override 0/1, armed_us, roll_us, pitch_us, throttle_us) or None (all zero).
    Raises ValueError on a bad command id, argument count or a value that does not fit its field
    (the caller's mistake; validate_command checks the meaning)."""
    if cmd_id < 0 or cmd_id > MAX_CMD_ID:
        raise ValueError("maintenance command id must be 0..%d" % MAX_CMD_ID)
    spec = COMMANDS[cmd_id]
    if len(cmd_args) != len(spec[2]):
        raise ValueError("%s takes %d arguments" % (spec[0], len(spec[2])))
    header = encode_header(fields_wanted, cmd_id, layout)
    out = bytearray(1 + HEADER_LEN + request_size(cmd_id))
    out[0] = SYNC
    for k in range(HEADER_LEN):
        out[1 + k] = header[k]
    p = 9
    fmt = spec[1]
    for k in range(len(fmt)):
        p += _put(fmt[k], out, p, cmd_args[k])
    rc = remote_control if remote_control is not None else (0, 0, 0, 0, 0)
    p += _put("B", out, p, rc[0])
    for k in range(1, 5):
        p += _put("H", out, p, rc[k])
    out[p] = xor8(out, 1, p)
    return bytes(out)


def _value(values_by_field, name, count):
    v = values_by_field.get(name)
    if v is None and name == "ptf1_params":
        v = values_by_field.get("pt1f_params")
    if v is None:
        return 0
    return v


def encode_reply_into(buf, header, values_by_field, layout=LAYOUT_SEED):
    """Write a reply frame for `header` into buf; return its length. Missing values are sent as 0;
    array fields take a flat sequence (row-major) of their element count."""
    buf[0] = SYNC
    for k in range(HEADER_LEN):
        buf[1 + k] = header[k]
    p = 9
    for k in range(FIELD_COUNT):
        if not header[k >> 3] & _bit(k, layout):
            continue
        name, code, count = FIELDS[k]
        v = _value(values_by_field, name, count)
        if count == 1:
            p += _put(code, buf, p, v)
        else:
            for j in range(count):
                p += _put(code, buf, p, v[j] if v != 0 and j < len(v) else 0)
    buf[p] = xor8(buf, 1, p)
    return p + 1


def encode_reply(header, values_by_field, layout=LAYOUT_SEED):
    """A whole reply frame (bytes) echoing `header`, values in header order."""
    buf = bytearray(1 + HEADER_LEN + reply_payload_size(header, layout) + 1)
    encode_reply_into(buf, header, values_by_field, layout)
    return bytes(buf)


def decode_reply(header, payload, length=-1, layout=LAYOUT_SEED, offset=0):
    """Values of a reply payload (without checksum) as a list of (name, value) in header order;
    arrays as tuples. None if the length does not match the header."""
    if length < 0:
        length = len(payload) - offset
    if length != reply_payload_size(header, layout):
        return None
    out = []
    p = offset
    for k in range(FIELD_COUNT):
        if not header[k >> 3] & _bit(k, layout):
            continue
        name, code, count = FIELDS[k]
        if count == 1:
            v = unpack_from("<" + code, payload, p)[0]
        else:
            v = unpack_from("<%d%s" % (count, code), payload, p)
        p += FIELD_SIZE[k]
        out.append((name, v))
    return out


# -- parser -----------------------------------------------------------------------------------------------


class MaintenanceParser(FrameScanner):
    """Streaming maintenance-protocol parser, for requests (server) or replies (client).

        parser = MaintenanceParser()                      # server side
        parser.feed(data)
        while parser.pop():
            reason = validate_command(parser.cmd_id, parser.args)
            ...  parser.header, parser.wants(k), parser.rc_override, parser.rc_throttle_us ...

        client = MaintenanceParser(replies=True, expected_header=sent_header)
        client.feed(data)
        while client.pop():
            client.values                                 # [(name, value), ...] in header order

    A request with an unknown command id (26..127) cannot be framed (its length is unknown): it
    counts in `unknown_commands` and the parser resynchronises. A reply whose header differs from
    `expected_header` counts in `header_mismatches` and is skipped. Bad checksums count in
    `crc_errors`; see FrameScanner for the other counters. Never raises on input bytes.
    """

    def __init__(self, replies=False, expected_header=None, queue_depth=2, layout=LAYOUT_SEED):
        if replies:
            max_frame = 1 + HEADER_LEN + MAX_REPLY_PAYLOAD + 1
        else:
            max_frame = 1 + HEADER_LEN + max(ARG_SIZE) + RC_TAG_LEN + 1  # widest: 6 floats (PID), 43 bytes
        FrameScanner.__init__(self, SYNC, max_frame, queue_depth)
        self.replies = replies
        self.layout = layout
        self.expected = None
        if expected_header is not None:
            self.expect(expected_header)
        self.header = bytearray(HEADER_LEN)
        self.cmd_id = 0
        self.args = [0] * _MAX_ARGS
        self.arg_count = 0
        self.rc_override = 0
        self.rc_armed_us = 0
        self.rc_roll_us = 0
        self.rc_pitch_us = 0
        self.rc_throttle_us = 0
        self.payload = bytearray(max_frame)  # reply values (without checksum) after pop()
        self.length = 0
        self.values = None
        self.unknown_commands = 0
        self.header_mismatches = 0

    def expect(self, header):
        """Replies: accept only frames echoing this header (None = any header)."""
        if header is None:
            self.expected = None
        else:
            self.expected = bytes(header[:HEADER_LEN])

    def wants(self, k):
        """True if the popped request asks for field index k."""
        return (self.header[k >> 3] & _bit(k, self.layout)) != 0

    def mask(self):
        """(lo, hi) small-int mask of the popped header, see header_mask."""
        return header_mask(self.header, self.layout)

    def pop(self):
        """Decode the oldest queued frame into the attributes; False when none is waiting."""
        f = self._next()
        if f is None:
            return False
        total = self._frame_total
        h = self.header
        for k in range(HEADER_LEN):
            h[k] = f[1 + k]
        self.cmd_id = header_cmd(h, self.layout)
        if self.replies:
            n = total - 10
            out = self.payload
            for k in range(n):
                out[k] = f[9 + k]
            self.length = n
            self.values = decode_reply(h, out, n, self.layout)
            return True
        cmd = self.cmd_id
        fmt = COMMANDS[cmd][1]
        p = 9
        args = self.args
        for k in range(len(fmt)):
            code = fmt[k]
            args[k] = unpack_from("<" + code, f, p)[0]
            p += 4 if code == "f" else (2 if code == "H" else 1)
        for k in range(len(fmt), _MAX_ARGS):
            args[k] = 0
        self.arg_count = len(fmt)
        self.rc_override = f[p]
        self.rc_armed_us = f[p + 1] | (f[p + 2] << 8)
        self.rc_roll_us = f[p + 3] | (f[p + 4] << 8)
        self.rc_pitch_us = f[p + 5] | (f[p + 6] << 8)
        self.rc_throttle_us = f[p + 7] | (f[p + 8] << 8)
        return True

    def _frame_len(self, src, i, avail):
        if avail < 1 + HEADER_LEN:
            return -1
        if self.replies:
            exp = self.expected
            if exp is not None:
                for k in range(HEADER_LEN):
                    if src[i + 1 + k] != exp[k]:
                        self.header_mismatches += 1
                        return 0
            return 1 + HEADER_LEN + reply_payload_size(src, self.layout, i + 1) + 1
        cmd = header_cmd(src, self.layout, i + 1)
        if cmd > MAX_CMD_ID:
            self.unknown_commands += 1
            self.length_errors += 1
            return 0
        return 1 + HEADER_LEN + ARG_SIZE[cmd] + RC_TAG_LEN + 1

    def _check(self, src, i, total):
        end = i + total - 1
        if xor8(src, i + 1, end) != src[end]:
            self.crc_errors += 1
            return -1
        return 1
