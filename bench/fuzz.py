"""Fuzz campaign: every wire parser in-process, then the servers of a real `hoverfly sim` over TCP.

    .venv/bin/python bench/fuzz.py                       # 10^6 inputs per parser, servers at 10^5 requests
    .venv/bin/python bench/fuzz.py --count 100000        # a shorter run
    .venv/bin/python bench/fuzz.py --count 2000 --servers cli,msp   # a smoke run

Parsers (CRSF, SBUS, iBUS, MSP, maintenance, the firmware bridge, DShot reply codes and pulse
trains, PWM/PPM capture, ULog): `--count` inputs each (ULog: `--ulog-count`, default count/100,
since one input is a whole file read), half mutated streams of valid frames (bits flipped, bytes
inserted, deleted, duplicated, 0xFFFF lengths, sync bytes, cuts), half random bytes, fed in random
chunks to a parser that carries its state across 1 000 inputs. An input that raises is an
exception; one that takes longer than `--hang-s` is a hang (an interval timer interrupts it).

Servers: `hoverfly sim --msp-port 0 --maint-port 0` as a subprocess on 127.0.0.1 (ports from its
start line, storage in a temporary directory), fed:
- cli:   `set` lines with NaN/inf/huge/negative/out-of-range values, aliases, junk lines, pipelined;
- msp:   SET_PID/SET_RAW_RC/SET_MOTOR/SET_ARMING_DISABLED/SET_MODE_RANGE/... with hostile payloads
         and random commands (MSP_REBOOT left out: it restarts the flight), pipelined 1..50 deep,
         some damaged;
- maint: every maintenance command with NaN/inf floats and out-of-range pulses (no remote control:
         it may arm by design), pipelined, some damaged;
- flood: one client floods a port with garbage and requests while another polls the other port:
         the poller's worst reply latency;
- storm: connect/disconnect storms and clients replaced mid-frame, a props-off motor command from
         a client that then vanishes.
A monitor on the other port (maintenance `motors_armed`/motor signals, or MSP_STATUS/MSP_MOTOR)
counts arming events and motor outputs while disarmed. The sim's own caught errors (CLI `status`
"Loop errors") and tracebacks on its stderr are exceptions; a sim that exits is a death (it is
started again); a sim that is alive but does not answer a fresh client within 5 s is a hang.

Prints one JSON object: per parser {inputs, exceptions, hangs, worst_ms (the slowest input),
failures}, per server campaign {inputs, requests, answered, unanswered, ...}, and totals {inputs,
exceptions, hangs, deaths, arming_events, unanswered}. Only 127.0.0.1; every subprocess is ended in a finally.
"""

import argparse
import json
import os
import random
import re
import select
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
import traceback

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "src"))

from hoverfly.compat import ticks_add  # noqa: E402
from hoverfly.protocols import bridge, crsf, dshot, ibus, maintenance, msp, pulsetrain, sbus  # noqa: E402
from hoverfly.protocols.pulses import PpmCapture, PwmCapture, ppm_edges, pwm_edges  # noqa: E402

HOST = "127.0.0.1"
STREAM_INPUTS = 1000  # a parser keeps its state across this many inputs, then a fresh one
MAX_FAILURES = 5  # recorded per campaign (input and traceback)


class Hang(BaseException):
    """The interval timer fired: a BaseException, so no `except Exception` in the code under test hides it."""


def _on_alarm(*_):
    raise Hang()


# ---------------------------------------------------------------------------------- inputs
def mutate(rng, d):
    d = bytearray(d)
    for _ in range(rng.randrange(1, 8)):
        if not d:
            d += bytes(rng.randrange(256) for _ in range(rng.randrange(1, 16)))
            continue
        p = rng.randrange(len(d))
        op = rng.randrange(7)
        if op == 0:
            d[p] ^= 1 << rng.randrange(8)
        elif op == 1:
            d[p:p] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 12)))
        elif op == 2:
            del d[p : p + rng.randrange(1, 8)]
        elif op == 3:
            d[p:p] = d[p : p + rng.randrange(1, 30)]
        elif op == 4 and len(d) > p + 1:
            d[p : p + 2] = b"\xff\xff"
        elif op == 5:
            d[p] = rng.choice((0x00, 0x0F, 0x20, 0x24, 0x23, 0xB5, 0xC8, 0xFF))
        else:
            d = d[:p]
    return bytes(d)


def _raw16(rng):
    return [rng.randrange(0, 2048) for _ in range(16)]


def _good_stream(rng, good):
    return b"".join(good(rng) for _ in range(rng.randrange(1, 4)))


_MAINT_GOOD = None


def _maint_good(rng):
    global _MAINT_GOOD
    if _MAINT_GOOD is None:
        _MAINT_GOOD = [bytes(maintenance.encode_request(["body_roll", "body_pitch"])),
                       bytes(maintenance.encode_request([], maintenance.CMD_SET_ALL_MOTORS, (0,))),
                       bytes(maintenance.encode_request(["raw_gyro_x"], maintenance.CMD_SET_ROLL_PID,
                                                        (1.0, 0.1, 0.01, 0.0, 0.0, 0.0)))]
    return rng.choice(_MAINT_GOOD)


class ByteParser:
    """A streaming byte parser: make(), feed(p, chunk) (popping what completed), good(rng) frames."""

    def __init__(self, make, feed, good):
        self.make, self.feed, self.good = make, feed, good

    def input(self, rng):
        if rng.random() < 0.5:
            return mutate(rng, _good_stream(rng, self.good))
        return bytes(rng.randrange(256) for _ in range(rng.randrange(0, 300)))

    def run(self, p, rng, data):
        i = 0
        while i < len(data):
            n = rng.randrange(1, 80)
            self.feed(p, data[i : i + n])
            i += n


def _feed_rc(p, chunk):
    p.feed(chunk)


def _feed_pop(p, chunk):
    p.feed(chunk)
    while p.pop():
        pass


def _feed_bridge(p, chunk):
    p.feed(chunk)
    while p.pop() >= 0:
        pass


class DshotCodes:
    """DShot replies: a random 21-bit line code or 16-bit word per input, with an edt switch now and then."""

    def make(self):
        return dshot.ErpmDecoder()

    def input(self, rng):
        return rng.randrange(1 << 21)

    def run(self, p, rng, code):
        if code & 1:
            p.decode_code(code)
        else:
            p.decode_word(code >> 5)
        if code % 97 == 0:
            p.edt = not p.edt


class DshotPulses:
    """DShot command frames and replies as pulse trains: rendered frames damaged, or random pulses."""

    def make(self):
        return (pulsetrain.DshotPulseDecoder(600, False), pulsetrain.ReplyPulseDecoder(600))

    def input(self, rng):
        if rng.random() < 0.5:
            train = pulsetrain.render_dshot(rng.randrange(1 << 16), 600)
            for _ in range(rng.randrange(1, 4)):
                k = rng.randrange(len(train))
                level, ns = train[k]
                train[k] = (level ^ rng.randrange(2), max(-5, ns + rng.randrange(-900, 900)))
            return train
        return [(rng.randrange(-1, 3), rng.randrange(-10, 20000)) for _ in range(rng.randrange(0, 40))]

    def run(self, p, rng, pulses):
        p[0].decode(pulses)
        p[1].decode_code(pulses)


class Edges:
    """PWM and PPM capture: edge trains from the generators with damage, or random edges, any tick time."""

    def make(self):
        return (PwmCapture(8), PpmCapture())

    def input(self, rng):
        t0 = rng.randrange(1 << 30)
        if rng.random() < 0.5:
            chans = [rng.randrange(700, 2300) for _ in range(rng.randrange(4, 9))]
            ppm = ppm_edges(chans, t0, frames=2)
            pwm = pwm_edges(chans, t0)
            for _ in range(rng.randrange(1, 4)):
                k = rng.randrange(len(ppm))
                ppm[k] = (ppm[k][0] ^ 1, ticks_add(ppm[k][1], rng.randrange(-3000, 3000)))
            return ppm, pwm
        ev = []
        t = t0
        for _ in range(rng.randrange(0, 60)):
            t = ticks_add(t, rng.randrange(0, 40000))
            ev.append((rng.randrange(-3, 20), rng.randrange(2), t))
        return [(lv, t) for _, lv, t in ev], ev

    def run(self, p, rng, edges):
        ppm, pwm = edges
        for lv, t in ppm:
            p[1].edge(lv, t)
        for e in pwm:
            p[0].edge(*e)


class Ulog:
    """ULog: a log written by the simulator, mutated, written to a file and read as `hoverfly log info` reads it."""

    def __init__(self):
        self.dir = tempfile.mkdtemp(prefix="hoverfly-fuzz-")
        self.path = os.path.join(self.dir, "m.ulg")
        self.data = None

    def make(self):
        if self.data is None:
            from hoverfly.sim.runner import fly

            src = os.path.join(self.dir, "hover.ulg")
            fly("hover", "5inch", seed=3, duration_s=0.3, log_path=src)
            with open(src, "rb") as f:
                self.data = f.read()
        return None

    def input(self, rng):
        d = mutate(rng, self.data)
        if rng.random() < 0.3:
            d = mutate(rng, d)
        return d

    def run(self, p, rng, data):
        from hoverfly.logs.ulogread import LogReadError, read_summary

        with open(self.path, "wb") as f:
            f.write(data)
        try:
            read_summary(self.path)
        except LogReadError:
            pass


def parsers(names):
    table = {
        "crsf": ByteParser(crsf.CrsfDecoder, _feed_rc, lambda rng: bytes(crsf.encode_rc_frame_raw(_raw16(rng)))),
        "sbus": ByteParser(sbus.SbusDecoder, _feed_rc, lambda rng: bytes(sbus.encode_rc_frame_raw(_raw16(rng)))),
        "ibus": ByteParser(ibus.IbusDecoder, _feed_rc,
                           lambda rng: bytes(ibus.encode_rc_frame_raw([v + 800 for v in _raw16(rng)[:14]]))),
        "msp": ByteParser(msp.MspParser, _feed_pop,
                          lambda rng: msp.encode_request(rng.randrange(256),
                                                         bytes(rng.randrange(256) for _ in range(rng.randrange(17))),
                                                         rng.choice((1, 2)))),
        "maintenance": ByteParser(maintenance.MaintenanceParser, _feed_pop, _maint_good),
        "bridge": ByteParser(bridge.BridgeDecoder, _feed_bridge,
                             lambda rng: bridge.frame(rng.choice(bridge.KINDS),
                                                      bytes(rng.randrange(256) for _ in range(rng.randrange(40))))),
        "dshot_codes": DshotCodes(),
        "dshot_pulses": DshotPulses(),
        "pwm_ppm": Edges(),
        "ulog": Ulog(),
    }
    if names == "all":
        return table
    return {n: table[n] for n in names.split(",") if n}


def _short(x, n=300):
    if isinstance(x, (bytes, bytearray)):
        return x[:n].hex() + ("..." if len(x) > n else "")
    s = repr(x)
    return s[:n] + ("..." if len(s) > n else "")


def fuzz_parser(name, parser, count, seed, hang_s):
    rng = random.Random("%s-%d" % (name, seed))
    out = {"inputs": 0, "exceptions": 0, "hangs": 0, "seconds": 0.0, "worst_ms": 0.0, "failures": []}
    worst = 0.0
    t0 = time.perf_counter()
    p = None
    for i in range(count):
        if i % STREAM_INPUTS == 0:
            p = parser.make()
        x = parser.input(rng)
        signal.setitimer(signal.ITIMER_REAL, hang_s)
        w0 = time.perf_counter()
        try:
            parser.run(p, rng, x)
        except Hang:
            out["hangs"] += 1
            p = parser.make()
            if len(out["failures"]) < MAX_FAILURES:
                out["failures"].append({"input": i, "hang": True, "data": _short(x)})
        except Exception as exc:  # noqa: BLE001 - what the campaign counts
            out["exceptions"] += 1
            p = parser.make()
            if len(out["failures"]) < MAX_FAILURES:
                out["failures"].append({"input": i, "data": _short(x),
                                        "traceback": "".join(traceback.format_exception(exc))[-1500:]})
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            took = time.perf_counter() - w0
            if took > worst:
                worst = took
        out["inputs"] += 1
    out["seconds"] = round(time.perf_counter() - t0, 1)
    out["worst_ms"] = round(worst * 1000, 2)
    return out


# ---------------------------------------------------------------------------------- the sim
class Sim:
    """`hoverfly sim` as a child process on 127.0.0.1 with OS-chosen ports; restarted after a death."""

    START_RE = re.compile(r"CLI\+MSP on 127\.0\.0\.1:(\d+), maintenance on 127\.0\.0\.1:(\d+)")

    def __init__(self, extra=()):
        self.dir = tempfile.mkdtemp(prefix="hoverfly-sim-")
        self.extra = list(extra)
        self.proc = None
        self.deaths = []
        self.starts = 0
        self.msp_port = self.maint_port = 0
        self._err = None

    def start(self):
        self._err = open(os.path.join(self.dir, "stderr%d.txt" % self.starts), "w+b")  # noqa: SIM115
        env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "hoverfly.cli", "sim", "--msp-port", "0", "--maint-port", "0",
             "--storage", os.path.join(self.dir, "params.bin")] + self.extra,
            stdout=subprocess.PIPE, stderr=self._err, env=env, cwd=self.dir)
        self.starts += 1
        line = b""
        end = time.monotonic() + 60
        while time.monotonic() < end and b"\n" not in line:
            r, _, _ = select.select([self.proc.stdout], [], [], 1.0)
            if r:
                b = os.read(self.proc.stdout.fileno(), 4096)
                if not b:
                    break
                line += b
        m = self.START_RE.search(line.decode(errors="replace"))
        if not m:
            self.stop()
            raise RuntimeError("hoverfly sim did not start: %r %s" % (line, self.stderr_tail()))
        self.msp_port, self.maint_port = int(m.group(1)), int(m.group(2))

    def stderr_tail(self, n=1500):
        if self._err is None:
            return ""
        self._err.flush()
        self._err.seek(0)
        return self._err.read().decode(errors="replace")[-n:]

    def tracebacks(self):
        return self.stderr_tail(10**7).count("Traceback")

    def alive(self):
        return self.proc is not None and self.proc.poll() is None

    def check(self, phase):
        """True if alive; else record the death and start again."""
        if self.alive():
            return True
        self.deaths.append({"phase": phase, "exit": self.proc.returncode if self.proc else None,
                            "stderr": self.stderr_tail()})
        self.start()
        return False

    def stop(self):
        p = self.proc
        if p is None:
            return
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
            try:
                p.wait(5)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(5)
        p.stdout.close()
        self.proc = None

    def cleanup(self):
        """Remove the temporary directory (storage, stderr): after the last stderr_tail()."""
        self.stop()
        if self._err is not None:
            self._err.close()
            self._err = None
        shutil.rmtree(self.dir, ignore_errors=True)

    def rss_kb(self):
        try:
            with open("/proc/%d/status" % self.proc.pid) as f:
                for line in f:
                    if line.startswith("VmRSS:"):
                        return int(line.split()[1])
        except (OSError, AttributeError):
            pass
        return None


def connect(port, timeout_s=3.0):
    s = socket.create_connection((HOST, port), timeout=timeout_s)
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return s


def recv_some(sock, timeout_s):
    r, _, _ = select.select([sock], [], [], timeout_s)
    if not r:
        return b""
    try:
        data = sock.recv(65536)
    except OSError:
        return None
    return data if data else None


class MspClient:
    def __init__(self, port):
        self.sock = connect(port)
        self.parser = msp.MspParser(queue_depth=256)
        self.replies = []  # (direction, cmd, payload)

    def send(self, data):
        self.sock.sendall(data)

    def pump(self, timeout_s):
        data = recv_some(self.sock, timeout_s)
        if data is None:
            return False
        if data:
            self.parser.feed(data)
            while self.parser.pop():
                self.replies.append((self.parser.direction, self.parser.cmd, self.parser.message()))
        return True

    def wait(self, count, timeout_s):
        end = time.monotonic() + timeout_s
        while len(self.replies) < count and time.monotonic() < end:
            if not self.pump(min(0.2, max(0.0, end - time.monotonic()))):
                break
        return len(self.replies) >= count

    def ask(self, cmd, payload=b"", timeout_s=5.0):
        n = len(self.replies)
        self.send(msp.encode_request(cmd, payload))
        self.wait(n + 1, timeout_s)
        for d, c, p in self.replies[n:]:
            if c == cmd:
                return d, p
        return None

    def close(self):
        try:
            self.sock.close()
        except OSError:
            pass


class MaintClient:
    def __init__(self, port):
        self.sock = connect(port)
        self.replies = 0
        self._parser = maintenance.MaintenanceParser(replies=True, queue_depth=64)

    def send(self, data):
        self.sock.sendall(data)

    def pump(self, timeout_s):
        data = recv_some(self.sock, timeout_s)
        if data is None:
            return False
        if data:
            self._parser.feed(data)
            while self._parser.pop():
                self.replies += 1
        return True

    def wait(self, count, timeout_s):
        end = time.monotonic() + timeout_s
        while self.replies < count and time.monotonic() < end:
            if not self.pump(min(0.2, max(0.0, end - time.monotonic()))):
                break
        return self.replies >= count

    def read(self, fields, timeout_s=3.0):
        """{field: value} of one request for `fields`, or None."""
        req = bytes(maintenance.encode_request(fields))
        p = maintenance.MaintenanceParser(replies=True, expected_header=req[1 : 1 + maintenance.HEADER_LEN])
        self.sock.sendall(req)
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            data = recv_some(self.sock, 0.2)
            if data is None:
                return None
            if data:
                p.feed(data)
                if p.pop():
                    return dict(p.values)
        return None

    def close(self):
        try:
            self.sock.close()
        except OSError:
            pass


class Monitor:
    """Polls arming and motor outputs over the port the campaign is not using (one client per port)."""

    MOTORS = ["motors_armed", "motor1_signal", "motor2_signal", "motor3_signal", "motor4_signal"]

    def __init__(self, sim, use_maint):
        self.sim = sim
        self.use_maint = use_maint
        self.client = None
        self.arming_events = 0
        self.motor_polls = 0
        self.polls = 0
        self._armed = False
        self._next = 0.0

    def poll(self, force=False):
        now = time.monotonic()
        if not force and now < self._next:
            return
        self._next = now + 0.1
        try:
            if self.client is None:
                self.client = MaintClient(self.sim.maint_port) if self.use_maint else MspClient(self.sim.msp_port)
            if self.use_maint:
                v = self.client.read(self.MOTORS)
                if v is None:
                    return
                armed = bool(v["motors_armed"])
                spinning = any(v["motor%d_signal" % i] > 1000 for i in range(1, 5))
            else:
                st = self.client.ask(msp.MSP_STATUS, timeout_s=2.0)
                mo = self.client.ask(msp.MSP_MOTOR, timeout_s=2.0)
                if st is None or mo is None:
                    return
                armed = bool(msp.unpack_status(st[1])["mode_flags"] & 1)
                spinning = any(v > 1000 for v in struct.unpack_from("<%dH" % (len(mo[1]) // 2), mo[1]))
        except OSError:
            self.close()
            return
        self.polls += 1
        if armed and not self._armed:
            self.arming_events += 1
        self._armed = armed
        if spinning and not armed:
            self.motor_polls += 1

    def close(self):
        if self.client is not None:
            self.client.close()
            self.client = None


def sim_answers(sim, timeout_s=5.0):
    """A fresh client's MSP_API_VERSION is answered (the sim is not hung)."""
    try:
        c = MspClient(sim.msp_port)
        try:
            return c.ask(msp.MSP_API_VERSION, timeout_s=timeout_s) is not None
        finally:
            c.close()
    except OSError:
        return False


def loop_errors(sim):
    """The count in CLI status's "Loop errors" line (0 for "none"), and the line; (None, "") if unread."""
    try:
        s = connect(sim.msp_port)
    except OSError:
        return None, ""
    try:
        s.sendall(b"#\r\nstatus\r\nexit\r\n")
        text = b""
        end = time.monotonic() + 5
        while time.monotonic() < end and b"Links:" not in text:
            d = recv_some(s, 0.3)
            if d is None:
                break
            text += d
    finally:
        s.close()
    for line in text.decode(errors="replace").splitlines():
        if line.startswith("Loop errors:"):
            if "none" in line:
                return 0, line
            return sum(int(n) for n in re.findall(r"(\d+) \(last", line)) or 1, line
    return None, ""


# ---------------------------------------------------------------------------------- server campaigns
NAMES = None
HOSTILE_TEXT = ("nan", "NaN", "inf", "-inf", "+inf", "1e308", "-1e308", "1e999", "-1e999", "1e-320", "-0", "0x10",
                "99999999999999999999999", "-99999999999999999999", "", "1.5.5", "1e", "3,5", "hexx", "on", "TRUE",
                "-1", "0", "65536", "4294967296", "9" * 300)
HOSTILE_FLOATS = (float("nan"), float("inf"), float("-inf"), 3.4e38, -3.4e38, 1e-45, -0.0, 1e9, -1e9)
PULSES = (0, 1, 999, 1000, 1100, 1500, 2000, 2001, 0xFFFF)


def cli_line(rng):
    global NAMES
    if NAMES is None:
        from hoverfly.core.config.params import PARAMS

        NAMES = [r[0] for r in PARAMS] + ["roll_rc_rate", "gyro_lowpass_hz", "failsafe_delay", "small_angle",
                                          "vbat_min_cell_voltage", "nonsense"]
    k = rng.randrange(10)
    if k < 7:
        v = rng.choice(HOSTILE_TEXT) if k < 5 else repr(rng.uniform(-1e6, 1e6)) if k == 5 else str(
            rng.randrange(-10**12, 10**12))
        return "set %s = %s" % (rng.choice(NAMES), v)
    if k == 7:
        return "get " + rng.choice(NAMES)[: rng.randrange(1, 8)]
    if k == 8:
        return "map " + "".join(rng.choice("AETR12345678x") for _ in range(rng.randrange(0, 10)))
    return "".join(chr(rng.randrange(32, 127)) for _ in range(rng.randrange(0, 60))).replace("#", "")


def msp_request(rng):
    k = rng.randrange(8)
    if k == 0:
        cmd, payload = msp.MSP_SET_PID, bytes(rng.randrange(256) for _ in range(rng.randrange(0, 40)))
    elif k == 1:
        cmd, payload = msp.MSP_SET_RAW_RC, struct.pack("<%dH" % (n := rng.randrange(0, 20)),
                                                       *[rng.choice(PULSES) for _ in range(n)])
    elif k == 2:
        cmd, payload = msp.MSP_SET_MOTOR, struct.pack("<%dH" % (n := rng.randrange(0, 10)),
                                                      *[rng.choice(PULSES) for _ in range(n)])
    elif k == 3:
        cmd, payload = msp.MSP_SET_ARMING_DISABLED, bytes(rng.randrange(3) for _ in range(rng.randrange(0, 3)))
    elif k == 4:
        cmd, payload = msp.MSP_SET_MODE_RANGE, bytes(rng.randrange(256) for _ in range(rng.randrange(3, 7)))
    elif k == 5:
        cmd = rng.choice((msp.MSP_SET_NAME, msp.MSP_SET_FEATURE_CONFIG, msp.MSP_SET_ARMING_CONFIG,
                          msp.MSP_ACC_CALIBRATION, msp.MSP_EEPROM_WRITE, msp.MSP_STATUS, msp.MSP_RAW_IMU))
        payload = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 40)))
    else:
        cmd = rng.randrange(0x10000) if k == 7 else rng.randrange(256)
        if cmd == msp.MSP_REBOOT:
            cmd = msp.MSP_STATUS
        payload = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 64)))
    return msp.encode_request(cmd, payload, 2 if cmd > 255 else rng.choice((1, 2)))


def maint_request(rng):
    cmd = rng.randrange(len(maintenance.COMMANDS))
    args = []
    for code in maintenance.COMMANDS[cmd][1]:
        if code == "f":
            args.append(rng.choice(HOSTILE_FLOATS) if rng.random() < 0.6 else rng.uniform(-1e3, 1e3))
        elif code == "H":
            args.append(rng.choice(PULSES))
        else:
            args.append(rng.randrange(256))
    fields = rng.sample([f[0] for f in maintenance.FIELDS], rng.randrange(0, 6))
    return bytes(maintenance.encode_request(fields, cmd, tuple(args)))


def _campaign(name, count):
    return {"campaign": name, "inputs": 0, "requests": 0, "answered": 0, "unanswered": 0, "deaths": 0,
            "hangs": 0, "arming_events": 0, "motor_polls_disarmed": 0, "loop_errors": None, "seconds": 0.0}


def run_cli(sim, count, rng):
    out = _campaign("cli", count)
    mon = Monitor(sim, use_maint=True)
    sent = 0
    s = None
    t0 = time.perf_counter()
    try:
        while sent < count:
            if s is None:
                s = connect(sim.msp_port)
                s.sendall(b"#\r\n")
                got = b""
                end = time.monotonic() + 5
                while b"\n# " not in got and time.monotonic() < end:
                    d = recv_some(s, 0.3)
                    if d is None:
                        break
                    got += d
            batch = [cli_line(rng) for _ in range(min(rng.randrange(1, 20), count - sent))]
            text = "".join(x + "\r\n" for x in batch).encode("utf-8", "replace")
            try:
                s.sendall(text)
                prompts = 0
                got = b""
                end = time.monotonic() + 5
                while prompts < len(batch) and time.monotonic() < end:
                    d = recv_some(s, 0.3)
                    if d is None:
                        break
                    got += d
                    prompts = got.count(b"\n# ")
            except OSError:
                prompts = 0
                s = None
            sent += len(batch)
            out["requests"] += len(batch)
            out["answered"] += min(prompts, len(batch))
            out["unanswered"] += max(0, len(batch) - prompts)
            mon.poll()
            if not sim.check("cli"):
                out["deaths"] += 1
                s = None
    finally:
        if s is not None:
            s.close()
        mon.close()
    out["inputs"] = sent
    out["arming_events"] = mon.arming_events
    out["motor_polls_disarmed"] = mon.motor_polls
    out["seconds"] = round(time.perf_counter() - t0, 1)
    return out


def _count(c):
    return len(c.replies) if isinstance(c.replies, list) else c.replies


def _probe(c, good):
    """After damage: past the partial-frame timeout, out of a CLI a stray '#' may have opened, one good
    request must be answered. True if it was."""
    time.sleep(0.15)
    base = _count(c)
    c.send(b"\r\nexit\r\n" if isinstance(c, MspClient) else b"")
    time.sleep(0.05)
    if isinstance(c, MspClient):
        c.pump(0.05)
        c.replies.clear()
        base = 0
    c.send(good)
    return c.wait(base + 1, 3.0)


def _pipelined(sim, count, rng, name, make, client_cls, port_attr, use_maint_monitor, good):
    """Batches 1..50 deep. A clean batch: every request must be answered, in its batch. A batch with
    damaged requests (15 %): its answers are not counted (a damaged frame may swallow the next, a '#'
    opens the CLI), then one good request must be answered."""
    out = _campaign(name, count)
    out["damaged_batches"] = 0
    mon = Monitor(sim, use_maint=use_maint_monitor)
    c = None
    sent = 0
    t0 = time.perf_counter()
    try:
        while sent < count:
            if c is None:
                c = client_cls(getattr(sim, port_attr))
            depth = min(rng.randrange(1, 51), count - sent)
            reqs = [make(rng) for _ in range(depth)]
            damaged = rng.random() < 0.3
            if damaged:
                reqs = [mutate(rng, r) if rng.random() < 0.3 else r for r in reqs]
            base = _count(c)
            try:
                c.send(b"".join(reqs))
                if damaged:
                    c.wait(base + depth, 1.0)
                    ok = _probe(c, good)
                    want, got = 1, int(ok)
                    out["damaged_batches"] += 1
                else:
                    c.wait(base + depth, 5.0)
                    want, got = depth, _count(c) - base
            except OSError:
                c = None
                want, got = (1 if damaged else depth), 0
            if c is not None and isinstance(c.replies, list) and len(c.replies) > 4096:
                c.replies.clear()
            sent += depth
            out["requests"] += want
            out["answered"] += min(got, want)
            out["unanswered"] += max(0, want - got)
            mon.poll()
            if not sim.check(name):
                out["deaths"] += 1
                c = None
    finally:
        if c is not None:
            c.close()
        mon.close()
    out["inputs"] = sent
    out["arming_events"] = mon.arming_events
    out["motor_polls_disarmed"] = mon.motor_polls
    out["seconds"] = round(time.perf_counter() - t0, 1)
    return out


def run_msp(sim, count, rng):
    r = _pipelined(sim, count, rng, "msp", msp_request, MspClient, "msp_port", True,
                   msp.encode_request(msp.MSP_API_VERSION))
    r["note"] = "motor outputs while disarmed may be props-off motor tests the fuzzed MSP_SET_MOTOR asked for"
    return r


def run_maint(sim, count, rng):
    r = _pipelined(sim, count, rng, "maint", maint_request, MaintClient, "maint_port", False,
                   bytes(maintenance.encode_request(["body_roll"])))
    r["note"] = "motor outputs while disarmed may be props-off motor tests (command 6 then 1-5) the fuzz asked for"
    return r


def run_flood(sim, count, rng):
    """A client floods one port with garbage and requests; a poller on the other port times its replies
    (`count` polls each way)."""
    out = _campaign("flood", count)
    out["worst_latency_ms"] = 0.0
    out["polls"] = 0
    out["note"] = "each poll follows up to 16 x (20 requests + up to 400 bytes of garbage), until the socket is full"
    t0 = time.perf_counter()
    for flood_maint in (False, True):
        flooder = None
        poller = None
        try:
            flooder = connect(sim.maint_port if flood_maint else sim.msp_port)
            flooder.setblocking(False)
            poller = MspClient(sim.msp_port) if flood_maint else MaintClient(sim.maint_port)
            for _ in range(count):
                junk = b"".join(maint_request(rng) if flood_maint else msp_request(rng) for _ in range(20))
                junk += bytes(rng.randrange(256) for _ in range(rng.randrange(0, 400)))
                bursts = 0
                try:
                    for _ in range(16):  # until the socket is full: the sim reads at its own pace
                        flooder.send(junk)
                        bursts += 1
                except (BlockingIOError, InterruptedError):
                    pass
                except OSError:
                    break
                try:
                    while flooder.recv(65536):
                        pass
                except (BlockingIOError, InterruptedError):
                    pass
                except OSError:
                    break
                w0 = time.perf_counter()
                if flood_maint:
                    ok = poller.ask(msp.MSP_STATUS, timeout_s=3.0) is not None
                else:
                    ok = poller.read(["body_roll"], timeout_s=3.0) is not None
                lat = (time.perf_counter() - w0) * 1000
                out["polls"] += 1
                out["requests"] += 1
                out["answered" if ok else "unanswered"] += 1
                out["worst_latency_ms"] = max(out["worst_latency_ms"], round(lat, 1))
                out["inputs"] += 20 * bursts
                if not sim.check("flood"):
                    out["deaths"] += 1
                    break
        except OSError:
            pass
        finally:
            for x in (flooder, poller):
                if x is not None:
                    x.close()
    out["seconds"] = round(time.perf_counter() - t0, 1)
    return out


def run_storm(sim, count, rng):
    """Connect/disconnect storms, replaced clients, half frames, a props-off motor test left behind."""
    out = _campaign("storm", count)
    t0 = time.perf_counter()
    ack = msp.encode_request(msp.MSP_SET_ARMING_DISABLED, b"\x01\x00")
    motor = msp.encode_request(msp.MSP_SET_MOTOR, struct.pack("<8H", *([1100] * 4 + [1000] * 4)))
    for i in range(count):
        port = sim.msp_port if i % 2 == 0 else sim.maint_port
        try:
            a = connect(port, 2.0)
            k = rng.randrange(5)
            if k == 0:
                a.sendall(b"$M<\xc8")  # half an MSP frame
            elif k == 1 and port == sim.msp_port:
                a.sendall(ack + motor)  # a motor test, then gone (or replaced)
            elif k == 2:
                a.sendall(b"#\r\nset p_roll = 50\r\n")  # a CLI session left open
            elif k == 3:
                a.sendall(mutate(rng, maint_request(rng)))
            if rng.random() < 0.5:
                b = connect(port, 2.0)  # replaces a while it is still connected
                b.sendall(mutate(rng, msp_request(rng)))
                b.close()
            a.close()
        except OSError:
            pass
        out["inputs"] += 1
        if i % 50 == 49 and not sim.check("storm"):
            out["deaths"] += 1
    # A client starts a props-off motor test and vanishes: its session (and the test) must end with
    # the link, well before the test's own 1 s expiry.
    ab = {"tried": 0, "spinning_seen": 0, "stopped_within_300ms": 0}
    watch = None
    try:
        # the campaigns before may have left any valid setting (motor_test_pct = 0 would hide the test)
        c = connect(sim.msp_port, 2.0)
        c.sendall(b"#\r\ndefaults nosave\r\nexit\r\n")
        time.sleep(0.5)
        c.close()
        time.sleep(0.1)
        watch = MaintClient(sim.maint_port)
        for _ in range(5):
            a = connect(sim.msp_port, 2.0)
            a.sendall(ack + motor)
            time.sleep(0.1)
            ab["tried"] += 1
            v = watch.read(Monitor.MOTORS)
            if v is not None and any(v["motor%d_signal" % i] > 1000 for i in range(1, 5)):
                ab["spinning_seen"] += 1
            a.close()
            time.sleep(0.3)
            v = watch.read(Monitor.MOTORS)
            if v is not None and all(v["motor%d_signal" % i] <= 1000 for i in range(1, 5)):
                ab["stopped_within_300ms"] += 1
            time.sleep(0.2)
    except OSError:
        pass
    finally:
        if watch is not None:
            watch.close()
    out["abandoned_motor_tests"] = ab
    time.sleep(1.5)  # past the motor test's expiry and every partial-frame timeout
    mon = Monitor(sim, use_maint=True)
    for _ in range(3):
        mon.poll(force=True)
    out["motor_polls_disarmed"] = mon.motor_polls
    out["arming_events"] = mon.arming_events
    mon.close()
    ok = sim_answers(sim)
    out["requests"] = 1
    out["answered"] = int(ok)
    out["unanswered"] = int(not ok)
    out["seconds"] = round(time.perf_counter() - t0, 1)
    return out


SERVER_CAMPAIGNS = {"cli": run_cli, "msp": run_msp, "maint": run_maint, "flood": run_flood, "storm": run_storm}


def fuzz_servers(names, count, seed):
    results = {}
    sim = Sim()
    try:
        sim.start()
        for name in names:
            rng = random.Random("%s-%d" % (name, seed))
            # flood: count/20 polls per direction, each after 20 flooded requests and up to 400 bytes of
            # garbage; storm: count/20 connections
            n = count if name not in ("flood", "storm") else max(20, count // 20)
            r = SERVER_CAMPAIGNS[name](sim, n, rng)
            alive = sim.check(name + " end")
            if not alive:
                r["deaths"] += 1
            if not sim_answers(sim):
                r["hangs"] += 1
            r["loop_errors"], r["loop_errors_line"] = loop_errors(sim)
            results[name] = r
        results["sim"] = {"starts": sim.starts, "deaths": sim.deaths, "stderr_tracebacks": sim.tracebacks(),
                          "rss_kb_end": sim.rss_kb()}
    finally:
        sim.cleanup()
    return results


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--count", type=int, default=1000000, help="inputs per parser (default 10^6)")
    ap.add_argument("--ulog-count", type=int, default=None, help="ULog files (default count/100)")
    ap.add_argument("--parsers", default="all", help="comma list, 'all' or 'none'")
    ap.add_argument("--servers", default="cli,msp,maint,flood,storm", help="comma list or 'none'")
    ap.add_argument("--server-count", type=int, default=None,
                    help="requests per server campaign (default count/10, at most 100000)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--hang-s", type=float, default=10.0, help="an input taking longer is a hang")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    old = signal.signal(signal.SIGALRM, _on_alarm)
    report = {"seed": args.seed, "count": args.count, "parsers": {}, "servers": {}}
    try:
        if args.parsers != "none":
            for name, parser in parsers(args.parsers).items():
                n = args.count
                if name == "ulog":
                    n = args.ulog_count if args.ulog_count is not None else max(1, args.count // 100)
                report["parsers"][name] = fuzz_parser(name, parser, n, args.seed, args.hang_s)
                if isinstance(parser, Ulog):
                    shutil.rmtree(parser.dir, ignore_errors=True)
    finally:
        signal.signal(signal.SIGALRM, old)
    if args.servers != "none":
        n = args.server_count if args.server_count is not None else min(100000, max(10, args.count // 10))
        report["servers"] = fuzz_servers([s for s in args.servers.split(",") if s], n, args.seed)
    camps = [v for k, v in report["servers"].items() if k != "sim"]
    sim = report["servers"].get("sim", {})
    report["totals"] = {
        "inputs": sum(p["inputs"] for p in report["parsers"].values()) + sum(c["inputs"] for c in camps),
        "exceptions": sum(p["exceptions"] for p in report["parsers"].values())
        + max([c["loop_errors"] or 0 for c in camps] + [0]) + sim.get("stderr_tracebacks", 0),
        "hangs": sum(p["hangs"] for p in report["parsers"].values()) + sum(c["hangs"] for c in camps),
        "deaths": len(sim.get("deaths", [])),
        "arming_events": sum(c["arming_events"] for c in camps),
        "unanswered": sum(c["unanswered"] for c in camps),
        "requests": sum(c["requests"] for c in camps),
    }
    report["seconds"] = round(time.perf_counter() - t0, 1)
    json.dump(report, sys.stdout, indent=1)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
