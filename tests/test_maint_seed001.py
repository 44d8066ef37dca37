"""Seed 001's maintenance protocol as the seed's own client would speak it (issue 25, "must show").

The client here is written from the seed's tables alone (/work/shared/seeds/001_*.txt), with
`struct` by hand, not hoverfly's codec: a 0xFF sync, 8 header bytes (the reply fields' request
bits in the table's order, first field in bit 7 of byte 0; the command id in bits 6..0 of byte 7),
the command's arguments, the 9-byte REMOTE_CONTROL_TAG, and an XOR checksum of everything after
the sync; little-endian, as the seed's RP2040 sends its structs. Where the seed's tables disagree
with themselves the client follows the size columns (PID commands: 34 bytes = 6 floats KP KI KT SAT
AD BD, as the reply's PID_params; imu_offset: 12 bytes), as docs/maintenance-protocol.md says.

It sets each command's values, reads them back in telemetry, writes flash, and reads them again
after a restart, against (a) `hoverfly sim` over TCP on 127.0.0.1 with a --storage file and (b) the
rp2 board's own main loop under MicroPython off-hardware (tests/rp2fakes); and it reads every field
from the rp2 loop mid-flight, which must keep flying.
"""

import json
import math
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from test_rp2_board import needs_mp, run_board  # noqa: E402

HOVERFLY = str(Path(sys.executable).parent / "hoverfly")

# --- the seed's reply table: (field, struct code, count), in header order ---------------------------------
F32, U16, U8, U32 = "f", "H", "B", "I"
SEED_FIELDS = (
    [(n, F32, 1) for n in ("raw_accel_x", "raw_accel_y", "raw_accel_z", "raw_gyro_x", "raw_gyro_y", "raw_gyro_z",
                           "raw_magn_x", "raw_magn_y", "raw_magn_z", "filtered_accel_x", "filtered_accel_y",
                           "filtered_accel_z", "filtered_gyro_x", "filtered_gyro_y", "filtered_gyro_z",
                           "filtered_magn_x", "filtered_magn_y", "filtered_magn_z")]
    + [("throttle_signal", U16, 1), ("roll_signal", U16, 1), ("pitch_signal", U16, 1), ("throttle_set_point", U16, 1),
       ("roll_set_point", F32, 1), ("pitch_set_point", F32, 1), ("body_roll", F32, 1), ("body_pitch", F32, 1),
       ("body_yaw", F32, 1)]
    + [("%s_PID_%s" % (a, t), F32, 1) for a in ("roll", "pitch", "yaw") for t in ("error", "p", "i", "d", "u")]
    + [("motor%d_signal" % k, U16, 1) for k in (1, 2, 3, 4)]
    + [("motors_armed", U8, 1), ("builtin_test_status", U32, 1), ("motor_params", U32, 12), ("js_params", F32, 6),
       ("PID_params", F32, 18), ("pt1f_params", F32, 9), ("imu_type", U8, 1), ("i2c_read", U8, 1),
       ("sw_ver", U8, 4), ("imu_offset", F32, 3), ("throttle_params", U16, 3)]
)
NAMES = [f[0] for f in SEED_FIELDS]
assert len(SEED_FIELDS) == 57

# --- the seed's command table: id -> argument struct ------------------------------------------------------
SEED_COMMANDS = {0: "", 1: "H", 2: "H", 3: "H", 4: "H", 5: "H", 6: "B", 7: "", 8: "BHH", 9: "BHH", 10: "BHH",
                 11: "BHH", 12: "ff", 13: "ff", 14: "ff", 15: "ffffff", 16: "ffffff", 17: "ffffff", 18: "fff",
                 19: "fff", 20: "fff", 21: "B", 22: "BBB", 23: "BBBB", 24: "", 25: "HHH"}
PAYLOAD_SIZE = {0: 10, 1: 12, 2: 12, 3: 12, 4: 12, 5: 12, 6: 11, 7: 10, 8: 15, 9: 15, 10: 15, 11: 15, 12: 18,
                13: 18, 14: 18, 15: 34, 16: 34, 17: 34, 18: 22, 19: 22, 20: 22, 21: 11, 22: 13, 23: 14, 24: 10,
                25: 16}  # the seed's "Payload size" column


def xor(data):
    c = 0
    for b in data:
        c ^= b
    return c


def header(fields, cmd):
    h = bytearray(8)
    for name in fields:
        k = NAMES.index(name)
        h[k // 8] |= 0x80 >> (k % 8)
    h[7] |= cmd
    return bytes(h)


def request(fields=(), cmd=0, args=()):
    body = header(fields, cmd) + struct.pack("<" + SEED_COMMANDS[cmd], *args) + struct.pack("<BHHHH", 0, 0, 0, 0, 0)
    assert len(body) - 8 + 1 == PAYLOAD_SIZE[cmd]
    return b"\xff" + body + bytes((xor(body),))


def reply_size(fields):
    return 1 + 8 + sum(struct.calcsize("<%d%s" % (n, c)) for name, c, n in SEED_FIELDS if name in fields) + 1


def decode(frame, fields):
    """(command id, {field: value}) of one reply frame to a request for `fields`."""
    assert frame[0] == 0xFF and xor(frame[1:-1]) == frame[-1], frame.hex()
    assert frame[1:8] == header(fields, 0)[:7] and frame[8] & 0x80 == header(fields, 0)[7] & 0x80
    p = 9
    out = {}
    for name, code, n in SEED_FIELDS:
        if name in fields:
            v = struct.unpack_from("<%d%s" % (n, code), frame, p)
            p += struct.calcsize("<%d%s" % (n, code))
            out[name] = v[0] if n == 1 else v
    assert p == len(frame) - 1
    return frame[8] & 0x7F, out


def f32(x):
    return struct.unpack("<f", struct.pack("<f", x))[0]


# --- what the client sets: every command with values, and what each reads back as ------------------------
ACC_TAU_S = 1 / (2 * math.pi * 20)  # time constants of whole-Hz cutoffs: hoverfly's filters take Hz
GYRO_TAU_S = 1 / (2 * math.pi * 100)
SETS = [
    (8, (1, 1100, 1900)), (9, (1, 1150, 1850)), (10, (1, 1050, 1950)), (11, (0, 1000, 2000)),
    (12, (0.5, 0.25)), (13, (0.75, 0.125)), (14, (0.625, 0.0625)),
    (15, (50.0, 60.0, 0.25, 300.0, 0.5, 30.0)), (16, (51.0, 61.0, 0.75, 300.0, -1.5, 31.0)),
    (17, (40.0, 70.0, 2.0, 300.0, 0.125, 0.0)),
    (18, (ACC_TAU_S,) * 3), (19, (GYRO_TAU_S,) * 3), (20, (0.0,) * 3),
    (21, (2,)), (25, (1300, 1500, 1700)),
]
KEPT = {  # field -> value after the sets, stored in flash
    "motor_params": (1, 1100, 1900, 1, 1150, 1850, 1, 1050, 1950, 0, 1000, 2000),
    "js_params": (0.5, 0.25, 0.75, 0.125, 0.625, 0.0625),
    "PID_params": (50.0, 60.0, 0.25, 300.0, 0.5, 30.0, 51.0, 61.0, 0.75, 300.0, -1.5, 31.0,
                   40.0, 70.0, 2.0, 300.0, 0.125, 0.0),
    "pt1f_params": tuple(f32(t) for t in (ACC_TAU_S,) * 3 + (GYRO_TAU_S,) * 3 + (0.0,) * 3),
    "throttle_params": (1300, 1500, 1700),
}
MOTORS = ["motor%d_signal" % k for k in (1, 2, 3, 4)]
I2C = [(23, (0, 0x68, 0x19, 0x07)), (22, (0, 0x68, 0x19)), (22, (0, 0x68, 0x75))]  # SMPLRT_DIV, WHO_AM_I


def session():
    """The client's requests in order: (frame, fields asked, command, args)."""
    out = []

    def add(cmd, args=(), fields=()):
        out.append((request(fields, cmd, args), list(fields), cmd, args))

    add(6, (1,))  # props removed: motor control on
    add(1, (1200,), MOTORS)
    add(5, (1250,), MOTORS)
    add(5, (1800,), MOTORS)  # above the props-off test's cap: runs capped
    add(5, (1000,), MOTORS)
    add(6, (0,))
    for cmd, args in SETS:
        add(cmd, args)
    for cmd, args in I2C:
        add(cmd, args, ["i2c_read"])
    add(24, (), ["imu_offset", "body_roll", "body_pitch"])
    add(0, (), NAMES)
    add(7)  # flash write
    return out


def check_session(replies, imu_type_read):
    """Judge the replies to session() as the seed's user would."""
    reqs = session()
    assert len(replies) == len(reqs), (len(replies), len(reqs))
    got = []
    for (_frame, fields, cmd, _args), raw in zip(reqs, replies, strict=True):
        assert len(raw) == reply_size(fields), (cmd, len(raw), reply_size(fields))
        rcmd, values = decode(raw, fields)
        assert rcmd == cmd, "command %d refused (reply id %d)" % (cmd, rcmd)
        got.append(values)
    by = dict(enumerate(got))
    assert [by[1][m] for m in MOTORS] == [1200, 1000, 1000, 1000]
    assert [by[2][m] for m in MOTORS] == [1250] * 4
    assert [by[3][m] for m in MOTORS] == [1300] * 4  # motor_test_pct 30 %: the cap reads back
    assert [by[4][m] for m in MOTORS] == [1000] * 4
    n = 6 + len(SETS)
    assert by[n + 1]["i2c_read"] == 0x07 and by[n + 2]["i2c_read"] == 0x68  # written, WHO_AM_I
    offset = by[n + 3]
    assert offset["imu_offset"][0] == pytest.approx(offset["body_roll"], abs=0.05)
    assert offset["imu_offset"][1] == pytest.approx(offset["body_pitch"], abs=0.05)
    full = by[n + 4]
    check_kept(full, imu_type_read)
    assert full["i2c_read"] == 0x68
    assert full["imu_offset"][:2] == offset["imu_offset"][:2]
    return full


def check_kept(v, imu_type_read):
    for name, want in KEPT.items():
        assert v[name] == want, (name, v[name], want)
    assert v["imu_type"] == imu_type_read
    assert v["motors_armed"] == 0 and v["sw_ver"][3] in (0, 1)
    assert v["raw_accel_z"] == pytest.approx(-9.8, abs=0.5)  # resting: the live IMU, 1 g up in FRD
    assert v["filtered_accel_z"] == pytest.approx(-9.8, abs=0.5)
    assert [v[m] for m in MOTORS] == [1000] * 4


# --- (a) hoverfly sim over TCP --------------------------------------------------------------------------
def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start_sim(storage):
    msp_port, maint_port = _free_port(), _free_port()
    proc = subprocess.Popen([HOVERFLY, "sim", "--msp-port", str(msp_port), "--maint-port", str(maint_port),
                             "--storage", storage, "--duration", "60"], stdout=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    assert "hoverfly sim" in line, line
    return proc, maint_port


def _ask(sock, frame, fields):
    sock.sendall(frame)
    want = reply_size(fields)
    buf = b""
    deadline = time.monotonic() + 5
    while len(buf) < want and time.monotonic() < deadline:
        buf += sock.recv(want - len(buf))
    assert len(buf) == want, (frame.hex(), buf.hex())
    return buf


def test_a_seed_client_sets_every_command_and_reads_it_back_after_a_restart_of_hoverfly_sim(tmp_path):
    storage = str(tmp_path / "params.bin")
    proc, port = _start_sim(storage)
    try:
        time.sleep(0.3)  # the IMU settles on the ground
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            replies = [_ask(s, frame, fields) for frame, fields, _, _ in session()]
    finally:
        proc.terminate()
        proc.wait(10)
    full = check_session(replies, imu_type_read=2)  # the simulator's IMU is the imu_type parameter
    proc, port = _start_sim(storage)
    try:
        time.sleep(0.3)
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            _, after = decode(_ask(s, request(NAMES), NAMES), NAMES)
    finally:
        proc.terminate()
        proc.wait(10)
    check_kept(after, imu_type_read=2)
    assert after["imu_offset"] == full["imu_offset"]
    assert after["i2c_read"] == 0  # no I2C read since the restart


# --- (b) the rp2 board's own loop under MicroPython -------------------------------------------------------
def _rp2_body(frames, t0_s=1.0, step_s=0.05, extra=""):
    lines = ["maint_frames = %r" % [f.hex() for f in frames]]
    lines.append("def _send(i):\n    return lambda w: machine.uart(0).inject(bytes.fromhex(maint_frames[i]))")
    lines.append("for _i in range(len(maint_frames)):\n    world.at(%r + %r * _i, _send(_i))" % (t0_s, step_s))
    lines.append("def extra(flight):\n    r = {'tx': bytes(machine.uart(0).tx).hex(), 'imu_type': flight.params.stored("
                 "'imu_type')}\n%s    return r" % extra)
    return "\n".join(lines) + "\n"


def _split(tx, sizes):
    out = []
    p = 0
    for n in sizes:
        out.append(tx[p:p + n])
        p += n
    assert p == len(tx), (p, len(tx))
    return out


@needs_mp
def test_a_seed_client_sets_every_command_and_reads_it_back_after_a_restart_of_the_rp2_loop(tmp_path):
    reqs = session()
    r = run_board(tmp_path, _rp2_body([q[0] for q in reqs]), seconds=1.0 + 0.05 * len(reqs) + 0.5)
    tx = bytes.fromhex(r["tx"])
    full = check_session(_split(tx, [reply_size(q[1]) for q in reqs]),
                         imu_type_read=1)  # the IMU running: an MPU-6050 until the next boot
    assert r["imu_type"] == "bno055"  # command 21: the reboot parameter
    r = run_board(tmp_path, _rp2_body([request(NAMES)]), seconds=1.5)
    _, after = decode(bytes.fromhex(r["tx"]), NAMES)
    check_kept(after, imu_type_read=1)
    assert r["imu_type"] == "bno055" and after["imu_offset"] == full["imu_offset"]


@needs_mp
def test_a_full_maintenance_read_mid_flight_on_the_rp2_loop_keeps_it_flying(tmp_path):
    # given the rp2 loop hovering, when a client asks every field (the default read, imu_type included)
    # three times, then each is answered with the live values and the loop flies on to the end
    frames = [request(NAMES)] * 3
    body = "world.at(2.0, arm)\nworld.at(2.5, hold(2.0))\n" + _rp2_body(frames, t0_s=4.0, step_s=0.5)
    r = run_board(tmp_path, body, seconds=7.0, judge=4.5)
    assert r["passes"] == 3500 and r["armed"] and not r["crashed"]
    assert r["tilt_rms_deg"] <= 1.5 and 1.5 <= r["alt_m"] <= 2.5
    replies = _split(bytes.fromhex(r["tx"]), [reply_size(NAMES)] * 3)
    for raw in replies:
        cmd, v = decode(raw, NAMES)
        assert cmd == 0
        assert v["motors_armed"] == 1 and v["imu_type"] == 1
        assert all(1050 <= v[m] <= 2000 for m in MOTORS)  # spinning: armed at idle or above
        assert abs(v["body_roll"]) < 10 and abs(v["body_pitch"]) < 10
        assert v["raw_accel_z"] == pytest.approx(-9.8, abs=3.0)
    print(json.dumps({k: r[k] for k in ("passes", "tilt_rms_deg", "alt_m")}))


# --- hoverfly maint set: every parameter the seed's commands carry ----------------------------------------
def test_maint_set_carries_every_seed_parameter_and_lists_them_in_its_help(capsys, tmp_path):
    from hoverfly.cli_maint import settable
    from test_host_clients import Sim, assert_one_line_error, cli_value, run

    s = Sim(str(tmp_path / "params.bin"))
    try:
        for name, value, shown in (("motor2_min_us", 1150, "1150"), ("motor3_max_us", 1800, "1800"),
                                   ("motor_enable", 0b1011, "11"), ("ab_roll_alpha", 0.5, "0.5"),
                                   ("ab_thr_beta", 0.125, "0.125"), ("pid_kt_pitch", 2.5, "2.5"),
                                   ("pid_ad_yaw", -0.25, "-0.25"), ("thr_hover_us", 1450, "1450"),
                                   ("imu_type", "bno055", "bno055"), ("p_roll", 48, "48")):
            code, out, err = run(capsys, "maint", "--port", s.maint_url, "set", name, str(value))
            assert code == 0, err
            assert out.startswith("%s = %s" % (name, shown)), out
            if name == "motor_enable":  # the seed's link carries motors 1-4: bits 4-7 (motors 5-8) stay set
                shown = str(0xF0 | value)
            # the CLI sees the same parameter (a reboot parameter's line goes on to say what runs now)
            assert cli_value(capsys, s, name).split("  (")[0] == "%s = %s" % (name, shown)
        code, _, err = run(capsys, "maint", "--port", s.maint_url, "set", "motor_enable", "255")
        assert_one_line_error(code, err, "motors 1-4")
        code, _, err = run(capsys, "maint", "--port", s.maint_url, "set", "thr_hover_us", "1900")
        assert_one_line_error(code, err, "descend <= hover <= climb")  # above climb (1650)
    finally:
        s.stop()
    with pytest.raises(SystemExit):
        run(capsys, "maint", "set", "--help")
    out = capsys.readouterr().out
    for name in settable():
        assert name in out.replace("\n", " ")
