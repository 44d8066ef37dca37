"""The configuration servers under fuzzed and hostile input, through the links task of a real Flight.

Given a Flight on the in-memory board (tests/portable/configfakes.py) with its links task attached
as `hoverfly sim` attaches it, when random bytes, damaged frames, or well-formed requests carrying
NaN, inf, huge, negative and out-of-range values arrive on the CLI+MSP port and the maintenance
port (any chunking, pipelined), then after every pass:
- nothing raised anywhere (the loop's boundaries caught no error: loop_errors() == 0),
- the craft is not armed and no motor turns unless a props-off motor test is running, within
  its cap (motor_test_pct),
- every stored parameter still passes the parameter table's own check (finite, in range),
and once the client has gone and another connects, a good request is answered.

CI-sized (a few hundred examples in all); bench/fuzz.py runs the same against a real `hoverfly sim`
over TCP at 10^5..10^6 inputs. Remote control through the maintenance protocol (which may arm by
design) is not sent here.
"""

import math
import struct
import sys
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).parent / "portable"))
from configfakes import make_flight  # noqa: E402

from hoverfly.compat import ticks_add  # noqa: E402
from hoverfly.core.board import SERIAL_CONFIG, SERIAL_MAINT  # noqa: E402
from hoverfly.core.config.params import PARAMS, check  # noqa: E402
from hoverfly.core.config.storage import Storage  # noqa: E402
from hoverfly.core.links.task import attach  # noqa: E402
from hoverfly.protocols import maintenance as mp  # noqa: E402
from hoverfly.protocols import msp  # noqa: E402

SERVER_FUZZ = settings(max_examples=60, derandomize=True, deadline=None,
                       suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
PASS_US = 1000
NAMES = [r[0] for r in PARAMS]
HOSTILE_TEXT = ("nan", "NaN", "inf", "-inf", "+inf", "1e308", "-1e308", "1e999", "-1e999", "1e-320", "-0",
                "0x10", "99999999999999999999999", "-99999999999999999999", "", "=", "1.5.5", "1e", "3,5",
                "hexx", "quadx", "on", "TRUE", "\x00", "9" * 400)
HOSTILE_FLOATS = (float("nan"), float("inf"), float("-inf"), 3.4e38, -3.4e38, 1e-45, -0.0, 0.0, 1e9, -1e9)


class Rig:
    """A booted Flight with storage and the links task; passes at 1 kHz with the checks above."""

    def __init__(self):
        self.flight, self.board = make_flight(seams=False)
        self.storage = Storage(self.board)
        self.storage.load(self.flight.params)
        self.links = attach(self.flight, self.storage)

    def run(self, passes):
        f = self.flight
        b = self.board
        for _ in range(passes):
            b.t_us = ticks_add(b.t_us, PASS_US)
            # The outputs come before the slow tasks in a pass: a test the links task ends in this
            # pass still drove this pass's outputs.
            testing = f.motor_test.active
            f.step(b.t_us)
            self.check(testing)

    def check(self, testing=False):
        f = self.flight
        # Where the loop catches what its slow tasks raise it counts it; where it does not, it raises here.
        if hasattr(f, "loop_errors"):
            assert f.loop_errors() == 0, f.loop_errors_line()
        assert not f.arming.armed, "armed by configuration input"
        mt = f.motor_test
        out = f.signals.motor_out
        if mt.active or testing:
            cap = max(mt.max_norm, mt.idle) + 1e-6
            assert all(0.0 <= v <= cap for v in out), list(out)
        else:
            assert all(v == 0.0 for v in out), list(out)

    def params_intact(self):
        for name, value in self.flight.params.values.items():
            key, stored, err = check(name, value)
            assert err is None and stored == value, (name, value, err)
            if isinstance(value, float):
                assert math.isfinite(value), (name, value)

    def send(self, port, chunks):
        for c in chunks:
            self.board.rx[port] += c
            self.run(3)

    def reconnect(self, port):
        self.board.gone[port] = True
        self.run(20)
        self.board.take(port)


def _chunked(draw, data):
    out = []
    p = 0
    while p < len(data):
        n = draw(st.integers(1, 200))
        out.append(bytes(data[p : p + n]))
        p += n
    return out


def _mutate(draw, data):
    d = bytearray(data)
    for _ in range(draw(st.integers(0, 4))):
        if not d:
            break
        p = draw(st.integers(0, len(d) - 1))
        op = draw(st.sampled_from(("flip", "insert", "delete", "cut")))
        if op == "flip":
            d[p] ^= 1 << draw(st.integers(0, 7))
        elif op == "insert":
            d[p:p] = draw(st.binary(min_size=1, max_size=12))
        elif op == "delete":
            del d[p : p + draw(st.integers(1, 6))]
        else:
            d = d[:p]
    return bytes(d)


# ---------------------------------------------------------------------------------- requests
hostile_float = st.one_of(st.sampled_from(HOSTILE_FLOATS), st.floats(width=32))


@st.composite
def cli_line(draw):
    kind = draw(st.sampled_from(("set", "set", "set", "alias", "get", "map", "misc", "junk")))
    if kind == "set":
        return "set %s = %s" % (draw(st.sampled_from(NAMES)),
                                draw(st.one_of(st.sampled_from(HOSTILE_TEXT), st.integers(-10**12, 10**12).map(str),
                                               st.floats().map(repr))))
    if kind == "alias":
        return "set %s = %s" % (draw(st.sampled_from(("roll_rc_rate", "gyro_lowpass_hz", "failsafe_delay",
                                                       "small_angle", "vbat_min_cell_voltage", "nonsense"))),
                                draw(st.sampled_from(HOSTILE_TEXT)))
    if kind == "get":
        return "get " + draw(st.text(max_size=20))
    if kind == "map":
        return "map " + draw(st.text(alphabet="AETR12345678xyz", max_size=10))
    if kind == "misc":
        return draw(st.sampled_from(("dump", "diff", "diff all", "status", "help", "defaults nosave", "save", "set",
                                     "exit", "#", "")))
    return draw(st.text(max_size=60))


def _u16s(draw, n):
    return struct.pack("<%dH" % n, *[draw(st.sampled_from((0, 1, 999, 1000, 1100, 1500, 2000, 2001, 0xFFFF)))
                                     for _ in range(n)])


@st.composite
def msp_request(draw):
    kind = draw(st.sampled_from(("pid", "raw_rc", "motor", "props_off", "mode_range", "any_set", "random")))
    if kind == "pid":
        payload = draw(st.binary(min_size=0, max_size=40))
        cmd = msp.MSP_SET_PID
    elif kind == "raw_rc":
        cmd, payload = msp.MSP_SET_RAW_RC, _u16s(draw, draw(st.integers(0, 20)))
    elif kind == "motor":
        cmd, payload = msp.MSP_SET_MOTOR, _u16s(draw, draw(st.integers(0, 10)))
    elif kind == "props_off":
        cmd, payload = msp.MSP_SET_ARMING_DISABLED, draw(st.binary(max_size=3))
    elif kind == "mode_range":
        cmd, payload = msp.MSP_SET_MODE_RANGE, draw(st.binary(min_size=4, max_size=6))
    elif kind == "any_set":
        cmd = draw(st.sampled_from((msp.MSP_SET_NAME, msp.MSP_SET_FEATURE_CONFIG, msp.MSP_SET_ARMING_CONFIG,
                                    msp.MSP_ACC_CALIBRATION, msp.MSP_EEPROM_WRITE)))
        payload = draw(st.binary(max_size=40))
    else:
        cmd, payload = draw(st.integers(0, 0xFFFF)), draw(st.binary(max_size=64))
    version = 2 if cmd > 255 else draw(st.sampled_from((1, 2)))
    return msp.encode_request(cmd, payload, version)


@st.composite
def maint_request(draw):
    cmd = draw(st.integers(0, len(mp.COMMANDS) - 1))
    args = []
    for code in mp.COMMANDS[cmd][1]:
        if code == "f":
            args.append(draw(hostile_float))
        elif code == "H":
            args.append(draw(st.sampled_from((0, 1, 999, 1000, 1100, 1500, 2000, 2001, 0xFFFF))))
        else:
            args.append(draw(st.integers(0, 255)))
    fields = draw(st.lists(st.sampled_from([f[0] for f in mp.FIELDS]), max_size=6, unique=True))
    return bytes(mp.encode_request(fields, cmd, tuple(args)))


# ---------------------------------------------------------------------------------- good requests afterwards
def _msp_answers(rig, cmd=msp.MSP_API_VERSION):
    rig.board.rx[SERIAL_CONFIG] += msp.encode_request(cmd)
    rig.run(30)
    p = msp.MspParser(queue_depth=64)
    p.feed(rig.board.take(SERIAL_CONFIG))
    got = []
    while p.pop():
        got.append(p.cmd)
    return cmd in got


def _cli_answers(rig):
    rig.board.rx[SERIAL_CONFIG] += b"#\r\nget loop_hz\r\nexit\r\n"
    rig.run(40)
    return b"loop_hz" in rig.board.take(SERIAL_CONFIG)


def _maint_answers(rig):
    req = bytes(mp.encode_request(["body_roll", "body_pitch"]))
    rig.board.rx[SERIAL_MAINT] += req
    rig.run(30)
    p = mp.MaintenanceParser(replies=True, expected_header=req[1 : 1 + mp.HEADER_LEN])
    p.feed(rig.board.take(SERIAL_MAINT))
    return p.pop()


def _still_serves(rig):
    rig.reconnect(SERIAL_CONFIG)
    rig.reconnect(SERIAL_MAINT)
    assert _msp_answers(rig), "no MSP answer after the fuzzed client left"
    assert _cli_answers(rig), "no CLI answer after the fuzzed client left"
    assert _msp_answers(rig), "no MSP answer after the CLI session"
    assert _maint_answers(rig), "no maintenance answer after the fuzzed client left"
    rig.params_intact()


# ---------------------------------------------------------------------------------- properties
@SERVER_FUZZ
@given(data=st.data())
def test_cli_lines_with_hostile_values_never_crash_arm_or_store_a_bad_value(data):
    rig = Rig()
    lines = data.draw(st.lists(cli_line(), min_size=1, max_size=12))
    text = ("#\r\n" + "\r\n".join(lines) + "\r\n").encode("utf-8", "replace")
    rig.send(SERIAL_CONFIG, _chunked(data.draw, text))
    rig.run(20)
    rig.params_intact()
    _still_serves(rig)


@SERVER_FUZZ
@given(data=st.data())
def test_msp_requests_with_hostile_payloads_pipelined_never_crash_arm_or_spin_a_motor(data):
    rig = Rig()
    reqs = data.draw(st.lists(msp_request(), min_size=1, max_size=20))
    stream = b"".join(_mutate(data.draw, r) if data.draw(st.booleans()) else r for r in reqs)
    rig.send(SERIAL_CONFIG, _chunked(data.draw, stream))
    rig.run(50)
    _still_serves(rig)


@SERVER_FUZZ
@given(data=st.data())
def test_maintenance_commands_with_hostile_values_never_crash_arm_or_spin_a_motor_unasked(data):
    rig = Rig()
    reqs = data.draw(st.lists(maint_request(), min_size=1, max_size=12))
    stream = b"".join(_mutate(data.draw, r) if data.draw(st.booleans()) else r for r in reqs)
    port = data.draw(st.sampled_from((SERIAL_MAINT, SERIAL_CONFIG)))
    rig.send(port, _chunked(data.draw, stream))
    rig.run(50)
    _still_serves(rig)


@SERVER_FUZZ
@given(data=st.data())
def test_random_bytes_on_both_ports_never_crash_and_the_servers_answer_the_next_client(data):
    rig = Rig()
    for _ in range(data.draw(st.integers(1, 3))):
        port = data.draw(st.sampled_from((SERIAL_CONFIG, SERIAL_MAINT)))
        rig.send(port, _chunked(data.draw, data.draw(st.binary(max_size=700))))
        if data.draw(st.booleans()):
            rig.board.gone[port] = True  # a connect/disconnect storm between bursts
    rig.run(150)  # past the partial-frame timeout
    _still_serves(rig)


def test_a_props_off_motor_test_over_msp_is_the_only_way_a_disarmed_motor_turns():
    # the invariant the properties hold is not vacuous: with the acknowledgement the motors do turn
    rig = Rig()
    rig.send(SERIAL_CONFIG, [msp.encode_request(msp.MSP_SET_MOTOR, struct.pack("<8H", *([1100] * 4 + [1000] * 4)))])
    rig.run(20)
    assert not rig.flight.motor_test.active and all(v == 0.0 for v in rig.flight.signals.motor_out)
    rig.send(SERIAL_CONFIG, [msp.encode_request(msp.MSP_SET_ARMING_DISABLED, b"\x01\x00"),
                             msp.encode_request(msp.MSP_SET_MOTOR, struct.pack("<8H", *([1100] * 4 + [1000] * 4)))])
    rig.run(20)
    assert rig.flight.motor_test.active and any(v > 0.0 for v in rig.flight.signals.motor_out)
    rig.reconnect(SERIAL_CONFIG)  # the client leaves: its test ends with its session
    rig.run(5)
    assert not rig.flight.motor_test.active and all(v == 0.0 for v in rig.flight.signals.motor_out)


@SERVER_FUZZ
@given(data=st.data())
def test_each_servers_own_feed_takes_any_bytes_and_then_answers_a_good_request(data):
    from hoverfly.core.links.cliserver import CliServer
    from hoverfly.core.links.maintserver import MaintServer
    from hoverfly.core.links.mspserver import MspServer
    from hoverfly.core.links.task import ConfigPort

    rig = Rig()
    f, st_ = rig.flight, rig.storage
    kind = data.draw(st.sampled_from(("msp", "cli", "maint", "config")))
    server = {"msp": MspServer, "cli": CliServer, "maint": MaintServer, "config": ConfigPort}[kind](f, st_)
    out = []
    if kind == "cli":
        server.enter(out.append)
    make = {"msp": msp_request(), "maint": maint_request(), "cli": cli_line().map(lambda x: (x + "\r\n").encode()),
            "config": st.one_of(msp_request(), maint_request())}[kind]
    stream = b"".join(_mutate(data.draw, r) if data.draw(st.booleans()) else r
                      for r in data.draw(st.lists(make, max_size=10))) + data.draw(st.binary(max_size=200))
    for chunk in _chunked(data.draw, stream):
        server.feed(chunk, len(chunk), out.append)
        rig.run(1)
    server.close()  # the client went away: a new one starts clean
    out.clear()
    if kind == "cli":
        server.enter(out.append)
        server.feed(b"get loop_hz\r\n", 13, out.append)
        assert b"loop_hz" in b"".join(out)
    elif kind == "maint":
        req = bytes(mp.encode_request(["body_roll"]))
        server.feed(req, len(req), out.append)
        p = mp.MaintenanceParser(replies=True, expected_header=req[1 : 1 + mp.HEADER_LEN])
        p.feed(b"".join(out))
        assert p.pop()
    else:
        req = msp.encode_request(msp.MSP_API_VERSION)
        server.feed(req, len(req), out.append)
        p = msp.MspParser()
        p.feed(b"".join(out))
        assert p.pop() and p.cmd == msp.MSP_API_VERSION
    rig.params_intact()
