"""Flight firmware behind the lockstep bridge: the far end of sim/bridge.py.

Takes bridge frames (protocols/bridge.py) on a byte stream — stdin when the simulator
starts it as `micropython -m hoverfly.boards.bridge_fw` (or under CPython), USB serial
on a real Pico for hardware-in-the-loop (boards/rp2/hil.py) — and gives one OUT frame per
STEP: the motor outputs the flight core wrote, the LED, status flags, the autopilot's state
and new events; and one RC_ANSWER per MSP_RC (the companion computer's RC, handed to the
flight's `on_msp_rc` as its MSP server would). The flight core
runs unchanged on `BridgeBoard`, a Board whose IMU sample, receiver bytes, battery and
clock come from the simulator each step. Portable (MicroPython and CPython); nothing is
printed on the stream: status and errors go to stderr, or back as an ERROR frame.
"""

import sys
from array import array
from struct import pack_into, unpack_from

from hoverfly.compat import (
    IS_MICROPYTHON,
    collect_garbage,
    mem_free,
    print_exception,
    ticks_diff,
    ticks_us,
)
from hoverfly.core.board import BOOT_TICKS_US, SampledBoard
from hoverfly.protocols import bridge as B

# Collect in the slack between answering a step and the next one arriving, and only when
# the free heap drops below this: never inside the flight pass.
GC_FREE_BYTES = 32768
# What one STEP may allocate at most, with room: the pass's boxed floats and the frame's values
# (1.3 KB on average, 3.7 KB at most over a 6 s hover on the unix VM: bench/bridge_firmware.py, "alloc_bytes").
# gc.mem_free() walks the heap's whole allocation table (about 85 us on the VM's 768 KB heap, five
# times the flight pass), so the free heap is read again only once the steps since the last reading
# could have used up what stood above GC_FREE_BYTES.
STEP_ALLOC_MAX = 4096


class BridgeBoard(SampledBoard):
    """The Board the bridged flight runs on: every input arrives in the step frame."""

    name = "bridge"

    def __init__(self):
        SampledBoard.__init__(self)
        self.battery_v = 0.0
        self.current_a = 0.0
        self.rx_buf = bytearray(B.MAX_PAYLOAD)
        self.rx_len = 0
        self.motor_out = array("f", [0.0] * 8)
        self.motor_count = 0
        self.servo_us = array("f", [0.0] * 4)  # the servo mixer's pulse widths, µs
        self.servo_count = 0
        self.led = False

    def reset(self):
        """As new, for the next session on a device that stayed up."""
        self.sim_us = 0
        self.imu_fresh = False
        self.rx_len = 0
        self.motor_count = 0
        self.servo_count = 0
        self.set_led(False)

    def read_rx(self, buf):
        """The receiver bytes of this step into buf; their count (0 when none)."""
        n = self.rx_len
        if n > len(buf):
            n = len(buf)
        src = self.rx_buf
        for i in range(n):
            buf[i] = src[i]
        self.rx_len = 0
        return n

    def write_motors(self, motor_out, count):
        m = self.motor_out
        if count > len(m):
            count = len(m)
        for i in range(count):
            m[i] = motor_out[i]
        self.motor_count = count

    def write_servos(self, servo_us, count):
        s = self.servo_us
        if count > len(s):
            count = len(s)
        for i in range(count):
            s[i] = servo_us[i]
        self.servo_count = count

    def read_battery(self, signals):
        signals.battery_v = self.battery_v
        signals.current_a = self.current_a

    def set_led(self, on):
        self.led = on


class Firmware:
    """One bridged flight: frames in, frames out (no I/O here: `serve` moves the bytes)."""

    def __init__(self, board=None):
        from hoverfly.core.config.params import Params

        self.board = board if board is not None else BridgeBoard()
        self.params = Params()
        self.flight = None
        self.out = bytearray(B.MAX_PAYLOAD + B.OVERHEAD)
        self.rc_channels_us = array("H", [0] * B.MAX_RC_CHANNELS)
        self.msp_rc_frames = 0
        self.steps = 0
        self.gc_runs = 0
        self._ev_seen = 0
        self._heap_check_in = 0  # steps until slack() reads the free heap again
        self.done = False

    def handle(self, kind, payload, length):
        """Answer one frame: the number of bytes of the reply now in self.out."""
        if kind == B.STEP:
            return self.step(payload, length)
        self._heap_check_in = 0  # a configuration frame may allocate a lot: the next slack() looks
        if kind == B.MSP_RC:
            return self.msp_rc(payload, length)
        if kind == B.HELLO:
            return self.hello(bytes(payload[:length]).decode())
        if kind == B.PARAMS:
            return self._ack(self.set_params(bytes(payload[:length]).decode()))
        if kind == B.BOOT:
            if length != 4:  # the rest of the buffer is an earlier frame's bytes
                return self._error("malformed BOOT frame (%d bytes)" % length)
            return self._ack(self.boot(unpack_from("<I", payload, 0)[0]))
        if kind == B.QUIT:
            self.done = True
            return self._ack("")
        return self._error("unknown bridge frame kind %d" % kind)

    def hello(self, host_version):
        """A new session: forget the parameters and flight of any earlier one (a device
        stays up between host runs); answer with this end's protocol version."""
        from hoverfly.core.config.params import Params

        self.flight = None
        self.params = Params()
        self.board.reset()
        self._ev_seen = 0
        self.steps = 0
        self.msp_rc_frames = 0
        collect_garbage()
        return B.encode(self.out, B.HELLO, B.VERSION.encode())

    def set_params(self, text):
        for line in text.split("\n"):
            if "=" not in line:
                continue
            name, value = line.split("=", 1)
            err = self.params.set(name.strip(), value.strip())
            if err:
                return err
        return ""

    def boot(self, sim_us):
        from hoverfly.core.flight import Flight

        board = self.board
        board.sim_us = sim_us
        self.flight = None
        collect_garbage()  # an earlier session's flight, on a device that stayed up
        self.flight = Flight(board, self.params)
        self._ev_seen = 0
        self.flight.start(board.now_us())
        return ""

    def step(self, payload, length):
        flight = self.flight
        if flight is None:
            return self._error("STEP before BOOT")
        board = self.board
        if length < B.STEP_SIZE:
            return self._error("short STEP frame (%d bytes)" % length)
        v = unpack_from(B.STEP_FMT, payload, 0)
        board.sim_us = v[0]
        flight.config_session = (v[1] >> B.STEP_SESSION_SHIFT) & B.STEP_SESSION_MASK
        if v[1] & B.STEP_IMU_FRESH:
            g = board.gyro
            a = board.accel
            g[0] = v[2]
            g[1] = v[3]
            g[2] = v[4]
            a[0] = v[5]
            a[1] = v[6]
            a[2] = v[7]
            board.imu_fresh = True
        q = board.quaternion
        q[0] = v[8]
        q[1] = v[9]
        q[2] = v[10]
        q[3] = v[11]
        board.battery_v = v[12]
        board.current_a = v[13]
        n_rx = length - B.STEP_SIZE
        if n_rx > 0:
            dst = board.rx_buf
            k = board.rx_len
            for i in range(n_rx):
                if k < len(dst):
                    dst[k] = payload[B.STEP_SIZE + i]
                    k += 1
            board.rx_len = k
        t0 = ticks_us()
        flight.step(board.now_us())
        pass_us = ticks_diff(ticks_us(), t0)
        self.steps += 1
        return self._reply(pass_us)

    def msp_rc(self, payload, length):
        """The companion's MSP RC at the time it arrived: the flight takes or refuses it now."""
        flight = self.flight
        if flight is None:
            return self._error("MSP_RC before BOOT")
        ch = self.rc_channels_us
        count = B.read_msp_rc(payload, length, ch)
        if count < 0:
            return self._error("malformed MSP_RC frame (%d bytes)" % length)
        board = self.board
        board.sim_us = unpack_from("<I", payload, 0)[0]
        reason = flight.on_msp_rc(board.now_us(), ch, count)
        self.msp_rc_frames += 1
        out = self.out
        ap = flight.autopilot
        pack_into(B.RC_ANSWER_FMT, out, B.HEADER, self._flags(), ap.state, ap.privilege())
        p = B.HEADER + B.RC_ANSWER_SIZE
        if reason:
            text = reason.encode()
            n = len(text)
            if n > B.MAX_PAYLOAD - B.RC_ANSWER_SIZE:
                n = B.MAX_PAYLOAD - B.RC_ANSWER_SIZE
            for i in range(n):
                out[p + i] = text[i]
            p += n
        return B.finish(out, B.RC_ANSWER, p - B.HEADER)

    def _flags(self):
        flight = self.flight
        flags = 0
        if flight.arming.armed:
            flags |= B.OUT_ARMED
        if self.board.led:
            flags |= B.OUT_LED
        if flight.supervisor.imu_ok:
            flags |= B.OUT_IMU_OK
        if flight.rx_ok:
            flags |= B.OUT_RX_OK
        if flight.calibration.calibrated:
            flags |= B.OUT_CALIBRATED
        return flags

    def _reply(self, pass_us):
        flight = self.flight
        board = self.board
        out = self.out
        flags = self._flags()
        n = board.motor_count
        m = board.servo_count
        if pass_us > 65535:
            pass_us = 65535
        elif pass_us < 0:
            pass_us = 0
        p = B.HEADER
        ap = flight.autopilot
        pack_into(B.OUT_HEAD_FMT, out, p, flags, n, m, pass_us, ap.state, ap.privilege())
        p += B.OUT_HEAD_SIZE
        mo = board.motor_out
        for i in range(n):
            pack_into("<f", out, p, mo[i])
            p += 4
        so = board.servo_us
        for i in range(m):
            pack_into("<f", out, p, so[i])
            p += 4
        q = flight.signals.attitude.q
        for i in range(4):
            pack_into("<f", out, p, q[i])
            p += 4
        # Events since the last answer, at most MAX_EVENTS (the rest go with the next step).
        log = flight.events
        waiting = log.count - self._ev_seen
        if waiting > log.size:
            self._ev_seen = log.count - log.size
            waiting = log.size
        k = waiting if waiting < B.MAX_EVENTS else B.MAX_EVENTS
        out[p] = k
        p += 1
        i = log.head - waiting
        if i < 0:
            i += log.size
        for _ in range(k):
            t = ticks_diff(log.t_us[i], BOOT_TICKS_US)
            p = B.put_event(out, p, t, log.event[i], log.detail[i])
            i += 1
            if i >= log.size:
                i = 0
        self._ev_seen += k
        return B.finish(out, B.OUT, p - B.HEADER)

    def _ack(self, text):
        return B.encode(self.out, B.ACK if not text else B.ERROR, text.encode())

    def _error(self, text):
        return B.encode(self.out, B.ERROR, text.encode()[: B.MAX_PAYLOAD])

    def slack(self):
        """Between steps: the host is busy with the physics, the flight pass is not running."""
        if not IS_MICROPYTHON:
            return
        self._heap_check_in -= 1
        if self._heap_check_in > 0:
            return
        free = mem_free()
        if free < GC_FREE_BYTES:
            collect_garbage()
            self.gc_runs += 1
            free = mem_free()
        self._heap_check_in = (free - GC_FREE_BYTES) // STEP_ALLOC_MAX


def serve(stream_in, stream_out, firmware=None):
    """Answer frames from stream_in on stream_out until QUIT or end of stream; exit status."""
    fw = firmware if firmware is not None else Firmware()
    dec = B.BridgeDecoder(depth=2)
    one = bytearray(1)
    head = bytearray(B.HEADER - 1)
    body = bytearray(B.MAX_PAYLOAD + 1)
    readinto = stream_in.readinto
    write = stream_out.write
    flush = getattr(stream_out, "flush", None)
    while not fw.done:
        # Hunt for the sync byte, then read exactly one frame: a pipe or a USB CDC port
        # hands over whatever arrived, so never ask for more than the frame holds.
        if not _read_exact(readinto, one, 1):
            return 0
        if one[0] != B.SYNC:
            dec.resyncs += 1
            continue
        if not _read_exact(readinto, head, B.HEADER - 1):
            return 0
        # Checked here as the decoder checks them, so both frame the stream alike: an unknown
        # kind or a length past MAX_PAYLOAD is no frame, and hunting goes on.
        if head[0] not in B.KINDS:
            dec.kind_errors += 1
            continue
        n = head[1] | (head[2] << 8)
        if n > B.MAX_PAYLOAD:
            dec.length_errors += 1
            continue
        if not _read_exact(readinto, body, n + 1):
            return 0
        # Framed by its lengths already: only the CRC is left to check (the decoder's byte-wise
        # hunt would walk every byte of the frame a second time, on every step).
        if not B.frame_crc_ok(head, body, n):
            dec.crc_errors += 1
            total = fw._error("bridge frame failed its CRC (%d so far)" % dec.crc_errors)
        else:
            dec.frames += 1
            try:
                total = fw.handle(head[0], body, n)
            except Exception as exc:  # the firmware failed: say why, then stop
                print_exception(exc)
                total = fw._error("%s: %s" % (type(exc).__name__, exc))
                fw.done = True
        if IS_MICROPYTHON:
            write(fw.out, total)
        else:
            write(memoryview(fw.out)[:total])
        if flush is not None:
            flush()
        fw.slack()
    return 0


def _read_exact(readinto, buf, n):
    got = 0
    while got < n:
        if got == 0:
            k = readinto(buf, n) if IS_MICROPYTHON else readinto(memoryview(buf)[:n])
        else:
            k = readinto(memoryview(buf)[got:n])
        if not k:
            return False
        got += k
    return True


def main():
    if IS_MICROPYTHON:
        try:
            import micropython

            micropython.kbd_intr(-1)  # a 0x03 byte in a frame must not raise KeyboardInterrupt
        except (ImportError, AttributeError):
            pass
    return serve(sys.stdin.buffer, sys.stdout.buffer)


if __name__ == "__main__":
    sys.exit(main())
