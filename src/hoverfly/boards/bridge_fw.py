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
from hoverfly.core.scheduler import HeapWatch
from hoverfly.protocols import bridge as B

# Garbage is collected in the slack between answering a step and the next one arriving, never inside the
# flight pass, as the rp2 main loop does it: core/scheduler.py HeapWatch, once half of what the last
# collection left free is used up. gc.mem_free() walks the heap's whole allocation table (about 100 us on
# the VM's 768 KB heap, more than the flight pass), so the watch looks at the heap only as often as the
# steps' measured allocation makes it worth it.
GC_FREE_FRACTION = 2

# The frame's floats are little-endian float32, as the board's float arrays hold them on a little-endian
# MicroPython (the Pico, the unix VM): there they are moved as bytes, struct's "Ns" copying n bytes from one
# buffer into another (an array's memory too), so a step makes no float object, and no garbage for the heap
# care to collect. CPython, whose "s" takes only bytes objects, and a big-endian port unpack and pack them:
# the same float32 values either way.
RAW_FLOATS = IS_MICROPYTHON and sys.byteorder == "little"
_BYTES = ("0s", "4s", "8s", "12s", "16s", "20s", "24s", "28s", "32s")  # _BYTES[k]: k float32s as bytes
# Where the STEP payload's floats sit (protocols/bridge.py STEP_FMT): gyro and accel, then the quaternion
# and the battery's volts and amps.
_STEP_IMU_AT = 5
_STEP_REST_AT = 29
RX_SIZE = B.MAX_PAYLOAD + B.OVERHEAD  # the receive buffer: one frame
END = -1  # FrameReader.next: the stream ended
BAD = -2  # FrameReader.next: a frame failed its CRC


class BridgeBoard(SampledBoard):
    """The Board the bridged flight runs on: every input arrives in the step frame."""

    name = "bridge"

    def __init__(self):
        SampledBoard.__init__(self)
        # What a STEP frame brings, as its payload lays it out: gyro xyz, accel xyz (STEP_IMU_FRESH only),
        # then the quaternion, battery V and A; gyro, accel and quaternion are views of it.
        inputs = self.inputs = array("f", [0.0, 0.0, 0.0, 0.0, 0.0, -9.80665, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        view = memoryview(inputs)
        self.gyro = view[0:3]
        self.accel = view[3:6]
        self.quaternion = view[6:10]
        self.rx_buf = bytearray(B.MAX_PAYLOAD)
        self._rx_view = memoryview(self.rx_buf)
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

    def read_imu(self, gyro_rad_s, accel_m_s2):
        if not self.imu_fresh:
            return False
        if RAW_FLOATS:
            pack_into("12s", gyro_rad_s, 0, self.gyro)
            pack_into("12s", accel_m_s2, 0, self.accel)
        else:
            SampledBoard.read_imu(self, gyro_rad_s, accel_m_s2)
        self.imu_fresh = False
        return True

    def read_attitude(self, q_out):
        if RAW_FLOATS:
            pack_into("16s", q_out, 0, self.quaternion)
            return True
        return SampledBoard.read_attitude(self, q_out)

    def read_rx(self, buf):
        """The receiver bytes of this step into buf; their count (0 when none)."""
        n = self.rx_len
        if n > len(buf):
            n = len(buf)
        if n:
            buf[0:n] = self._rx_view[0:n]
        self.rx_len = 0
        return n

    def write_motors(self, motor_out, count):
        m = self.motor_out
        if count > len(m):
            count = len(m)
        if RAW_FLOATS:
            pack_into(_BYTES[count], m, 0, motor_out)
        else:
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
        signals.battery_v = self.inputs[10]
        signals.current_a = self.inputs[11]

    def set_led(self, on):
        self.led = on


class Firmware:
    """One bridged flight: frames in, frames out (no I/O here: `serve` moves the bytes)."""

    def __init__(self, board=None):
        from hoverfly.core.config.params import Params

        self.board = board if board is not None else BridgeBoard()
        self.params = Params()
        self.flight = None
        # The frame being answered sits at rx[0:] (serve's FrameReader reads into it), its payload in `body`.
        self.rx = bytearray(RX_SIZE)
        view = memoryview(self.rx)
        self.body = view[B.HEADER:]
        at = B.HEADER + _STEP_IMU_AT
        self._step_imu = view[at:at + 24]
        at = B.HEADER + _STEP_REST_AT
        self._step_rest = view[at:at + 24]
        self.out = bytearray(B.MAX_PAYLOAD + B.OVERHEAD)
        self.rc_channels_us = array("H", [0] * B.MAX_RC_CHANNELS)
        self.msp_rc_frames = 0
        self.steps = 0
        self.gc_runs = 0
        self._ev_seen = 0
        self.heap = HeapWatch(mem_free, GC_FREE_FRACTION) if IS_MICROPYTHON else None
        self._collect = True  # slack() collects and starts the watch's cycle afresh
        self.reader = None  # serve()'s FrameReader: its counts
        self.done = False

    def handle(self, kind, payload, length):
        """Answer one frame whose payload is payload[0:length]: the number of bytes of the reply now in
        self.out. serve() hands over `body`, where the frame already is; any other payload is copied there."""
        if payload is not self.body:
            if length < 0 or length > B.MAX_PAYLOAD or length > len(payload):
                return self._error("bridge payload of %d bytes" % length)
            self.body[0:length] = payload[0:length]
            payload = self.body
        if kind == B.STEP:
            return self.step(payload, length)
        if kind == B.MSP_RC:  # the companion's RC: like a step's, in the watch's measured rate
            return self.msp_rc(payload, length)
        self._collect = True  # a configuration frame may allocate a lot (BOOT builds the flight)
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
        """A STEP whose payload is in `body` (handle puts it there): the inputs to the board, one flight pass."""
        flight = self.flight
        if flight is None:
            return self._error("STEP before BOOT")
        board = self.board
        if length < B.STEP_SIZE:
            return self._error("short STEP frame (%d bytes)" % length)
        flags = payload[4]
        board.sim_us = payload[0] | (payload[1] << 8) | (payload[2] << 16) | (payload[3] << 24)
        flight.config_session = (flags >> B.STEP_SESSION_SHIFT) & B.STEP_SESSION_MASK
        inputs = board.inputs
        if RAW_FLOATS:
            if flags & B.STEP_IMU_FRESH:
                pack_into("24s", inputs, 0, self._step_imu)
            pack_into("24s", inputs, 24, self._step_rest)
        else:
            v = unpack_from(B.STEP_FMT, payload, 0)
            first = 0 if flags & B.STEP_IMU_FRESH else 6
            for i in range(first, 12):
                inputs[i] = v[2 + i]
        if flags & B.STEP_IMU_FRESH:
            board.imu_fresh = True
        n_rx = length - B.STEP_SIZE
        if n_rx > 0:
            k = board.rx_len
            room = len(board.rx_buf) - k
            if n_rx > room:
                n_rx = room
            board.rx_buf[k:k + n_rx] = payload[B.STEP_SIZE:B.STEP_SIZE + n_rx]
            board.rx_len = k + n_rx
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
        q = flight.signals.attitude.q
        if RAW_FLOATS:
            if n:
                pack_into(_BYTES[n], out, p, board.motor_out)
                p += 4 * n
            if m:
                pack_into(_BYTES[m], out, p, board.servo_us)
                p += 4 * m
            pack_into("16s", out, p, q)
            p += 16
        else:
            mo = board.motor_out
            for i in range(n):
                pack_into("<f", out, p, mo[i])
                p += 4
            so = board.servo_us
            for i in range(m):
                pack_into("<f", out, p, so[i])
                p += 4
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
        heap = self.heap
        if heap is None:
            return
        if self._collect:
            self._collect = False
        elif not heap.due() or not heap.need():
            return
        collect_garbage()
        self.gc_runs += 1
        heap.collected()


class FrameReader:
    """Frames the bridge stream into one buffer (`buf`, a Firmware's rx): each good frame at its start, its
    payload length in `length`.

    A read asks only for what the frame still lacks, its header and then the rest its length gives: a
    stream's readinto (MicroPython's on a pipe or a Pico's USB, CPython's buffered one) waits until all it
    asked for has come, so asking past the frame would wait for the next one, which the host sends only
    after this one's answer. Resynchronises as BridgeDecoder does: garbage before a sync byte, an unknown
    kind and a length past MAX_PAYLOAD are skipped and counted; a frame that fails its CRC is skipped whole
    and reported (BAD)."""

    def __init__(self, readinto, buf):
        self.readinto = readinto
        self.buf = buf
        self.body = memoryview(buf)[B.HEADER:]
        self.have = 0  # bytes in buf
        self.taken = 0  # bytes of the frame handed out last, dropped by the next call
        self.length = 0
        self.frames = 0
        self.crc_errors = 0
        self.length_errors = 0
        self.kind_errors = 0
        self.resyncs = 0

    def next(self):
        """The kind of the next frame, at buf[0:length + OVERHEAD]: BAD when it failed its CRC, END when the
        stream ended first."""
        if self.taken:
            self._drop(self.taken)
            self.taken = 0
        buf = self.buf
        while True:
            if self.have < B.HEADER and not self._fill(B.HEADER):
                return END
            if buf[0] != B.SYNC:
                i = 1
                while i < self.have and buf[i] != B.SYNC:
                    i += 1
                self.resyncs += i
                self._drop(i)
                continue
            # As the decoder: an unknown kind or a length past MAX_PAYLOAD is no frame; the hunt goes on
            # from the byte after the sync.
            if buf[1] not in B.KINDS:
                self.kind_errors += 1
                self._drop(1)
                continue
            n = buf[2] | (buf[3] << 8)
            if n > B.MAX_PAYLOAD:
                self.length_errors += 1
                self._drop(1)
                continue
            total = n + B.OVERHEAD
            if self.have < total and not self._fill(total):
                return END
            self.taken = total
            self.length = n
            if not B.frame_crc_ok(buf, n):
                self.crc_errors += 1
                return BAD
            self.frames += 1
            return buf[1]

    def _fill(self, need):
        """Read until buf holds `need` bytes; False at the end of the stream."""
        readinto = self.readinto
        while self.have < need:
            have = self.have
            ask = need - have
            if IS_MICROPYTHON and have == 0:
                k = readinto(self.buf, ask)
            elif IS_MICROPYTHON and have == B.HEADER:  # the usual rest of a frame, into a view made once
                k = readinto(self.body, ask)
            else:
                k = readinto(memoryview(self.buf)[have:have + ask])
            if not k:
                return False
            self.have = have + k
        return True

    def _drop(self, n):
        """Forget the first n bytes of buf; what follows them moves to its start."""
        have = self.have
        if n >= have:
            self.have = 0
            return
        self.buf[0:have - n] = self.buf[n:have]
        self.have = have - n


def serve(stream_in, stream_out, firmware=None, flush=True):
    """Answer frames from stream_in on stream_out until QUIT or end of stream; exit status.
    flush: stream_out.flush() after each answer, where it has one (flush=False: its writes are unbuffered)."""
    fw = firmware if firmware is not None else Firmware()
    reader = FrameReader(stream_in.readinto, fw.rx)
    fw.reader = reader
    body = fw.body
    write = stream_out.write
    flush = getattr(stream_out, "flush", None) if flush else None
    while not fw.done:
        kind = reader.next()
        if kind == END:
            return 0
        if kind == BAD:
            total = fw._error("bridge frame failed its CRC (%d so far)" % reader.crc_errors)
        else:
            try:
                total = fw.handle(kind, body, reader.length)
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


def main():
    if IS_MICROPYTHON:
        try:
            import micropython

            micropython.kbd_intr(-1)  # a 0x03 byte in a frame must not raise KeyboardInterrupt
        except (ImportError, AttributeError):
            pass
    # MicroPython's stdout writes straight to its file descriptor, and its flush is an fsync, which a pipe
    # refuses: a system call a step for nothing. CPython's is buffered.
    return serve(sys.stdin.buffer, sys.stdout.buffer, flush=not IS_MICROPYTHON)


if __name__ == "__main__":
    sys.exit(main())
