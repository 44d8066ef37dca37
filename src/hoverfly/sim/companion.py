"""A scripted companion computer: sends MSP SET_RAW_RC at a rate, as seed 004's autopilot does.

The scenario sets what it sends (`msp_rc = {roll, pitch, yaw, throttle, arm, rate_hz,
hold_altitude_m}`, or `msp_rc = false` to fall silent); with `hold_altitude_m` it flies the
throttle itself from the craft's altitude, as a companion with its own height sensor would.

With a board (the in-process flight), the companion is wired to the flight controller's
CLI/MSP port as a real one would be to a UART: each frame is an MSP v1 SET_RAW_RC request in
bytes, followed by an MSP2_HOVERFLY_AUTOPILOT poll, written into the board's serial seam
(`CompanionPort` as board.serial); the flight's links task (core/links/task.py, `attach`) parses
and answers them in its own time, and the companion reads the reply bytes back at its next
tick. A `!` reply to SET_RAW_RC is a refusal; the poll answered after it says why (the
autopilot's last result code, worded as core/command/autopilot.py words it).

Without a board (the firmware bridge, sim/bridge.py: it carries no serial bytes) each frame
is the same request's bytes, parsed here as the MSP server parses them, its channels handed to
`flight.on_msp_rc`, which the bridge sends across at once as an MSP_RC frame.
It counts what was taken and why the rest was refused.
"""

from hoverfly.core.board import SERIAL_CONFIG
from hoverfly.core.command.autopilot import RES_ARM_REFUSED, RES_TAKEN, RESULT_TEXTS, arm_refusal_text
from hoverfly.core.links.task import attach
from hoverfly.core.stages.rc import aux_channel, map_channels
from hoverfly.errors import UserError
from hoverfly.protocols import msp


def _clamp(x, lo, hi):
    return lo if x < lo else (hi if x > hi else x)


class CompanionPort:
    """The wire between the companion and the flight controller's port `port`, in the board's serial
    seam (read(port, buf) / write(port, data, n), as sim/server.py's TcpPorts): bytes the companion
    wrote wait in `to_fc` until the links task reads them; the replies wait in `from_fc`."""

    def __init__(self, port=SERIAL_CONFIG):
        self.port = port
        self.to_fc = bytearray()
        self.from_fc = bytearray()
        self.links = None  # the flight's core.links.task.ConfigLinks serving the port (wire_up)

    def read(self, port, buf):
        if port != self.port:
            return 0
        n = min(len(buf), len(self.to_fc))
        buf[:n] = self.to_fc[:n]
        del self.to_fc[:n]
        return n

    def write(self, port, data, n=-1):
        if port != self.port:
            return 0
        if n < 0:
            n = len(data)
        self.from_fc += bytes(data[:n])
        return n


def wire_up(flight, board):
    """Wire a companion to the in-process flight's CLI/MSP port and start its links task; the port."""
    if board.serial is not None:
        raise UserError("msp_rc: the CLI/MSP port is already served (hoverfly sim): the companion needs it")
    port = CompanionPort()
    board.serial = port
    port.links = attach(flight, getattr(flight, "storage", None))
    return port


class Companion:
    def __init__(self, flight, params, hover_guess=0.35, board=None):
        self.flight = flight
        # the in-process flight: MSP bytes through the board's serial port; else (bridge) on_msp_rc
        self.port = wire_up(flight, board) if board is not None else None
        self._replies = msp.MspParser(max_payload=64, queue_depth=16)
        self._bridge_parser = msp.MspParser(max_payload=64, queue_depth=1)
        self._waiting_reason = 0  # SET_RAW_RC refusals whose poll reply is still to come
        self._counted = 0  # the autopilot's frames + rejected at the last poll reply
        self.status = None  # the last MSP2_HOVERFLY_AUTOPILOT reply (msp.unpack_autopilot)
        self.answered = 0  # SET_RAW_RC replies read back
        self.other_replies = []  # (direction, cmd, payload) of replies to requests it did not send itself
        self.hover_guess = hover_guess
        self.hold_altitude_m = None
        self._alt_i = 0.0
        self._last_t = 0.0
        rc = flight.rc  # the channel map the flight reads MSP RC with, as the receiver's (Betaflight's rcmap)
        self.map = (rc.roll_ch, rc.pitch_ch, rc.yaw_ch, rc.throttle_ch)
        # its arm channel: AUX1 of its frame wherever the map puts the arm switch's AUX (as the autopilot reads it)
        self.arm_ch = aux_channel(map_channels(params.get("rc_map")), params.get("arm_ch"))
        self.sending = False
        self.rate_hz = 100.0
        self.roll = 0.0
        self.pitch = 0.0  # forward positive, as a transmitter
        self.yaw = 0.0
        self.throttle = 0.0
        self.arm = False
        self.channels = 8
        self._next_s = 0.0
        self.sent = 0
        self.taken = 0
        self.refusals = {}

    def set(self, spec, t):
        if spec is False:
            self.sending = False
            return
        if "throttle" in spec:
            self.hold_altitude_m = None
        for key in ("roll", "pitch", "yaw", "throttle", "arm", "rate_hz", "channels", "hold_altitude_m"):
            if key in spec:
                setattr(self, key, spec[key])
        if not self.sending:
            self._next_s = t
        self.sending = True

    def frame_us(self):
        ch = [1500] * int(self.channels)
        m = self.map
        ch[m[0]] = int(1500 + 500 * _clamp(self.roll, -1.0, 1.0))
        ch[m[1]] = int(1500 + 500 * _clamp(self.pitch, -1.0, 1.0))
        ch[m[2]] = int(1500 + 500 * _clamp(self.yaw, -1.0, 1.0))
        ch[m[3]] = int(1000 + 1000 * _clamp(self.throttle, 0.0, 1.0))
        if 0 < self.arm_ch <= len(ch):
            ch[self.arm_ch - 1] = 2000 if self.arm else 1000
        return ch

    def tick(self, t, now_us, vehicle=None):
        """Read the replies that came, then send the frames due by time t (s)."""
        if self.port is not None:
            self.read_replies()
        if not self.sending or t + 1e-9 < self._next_s:
            return
        if self.hold_altitude_m is not None and vehicle is not None:
            dt = t - self._last_t if self._last_t > 0.0 else 0.01
            err = self.hold_altitude_m - vehicle.altitude_m()
            if not vehicle.on_ground:
                self._alt_i = _clamp(self._alt_i + err * dt * 0.15, -0.3, 0.3)
            self.throttle = _clamp(self.hover_guess + self._alt_i + 0.12 * err + 0.10 * vehicle.vd, 0.0, 0.9)
        self._last_t = t
        self._next_s += 1.0 / self.rate_hz
        if self._next_s <= t:
            self._next_s = t + 1.0 / self.rate_hz
        payload = msp.pack_set_raw_rc(self.frame_us())
        self.sent += 1
        if self.port is not None:
            # the request and a privilege poll, back to back in one write as a companion's UART sends them
            self.port.to_fc += msp.encode_request(msp.MSP_SET_RAW_RC, payload)
            self.port.to_fc += msp.encode_request(msp.MSP2_HOVERFLY_AUTOPILOT, b"", 2)
            return
        # the bridge: the request's bytes parsed as the MSP server parses them, its channels handed across
        frame = msp.encode_request(msp.MSP_SET_RAW_RC, payload)
        p = self._bridge_parser
        p.feed(frame)
        if not p.pop():
            self._result("the SET_RAW_RC frame did not parse")
            return
        channels = msp.unpack_set_raw_rc(p.payload, p.length)
        fn = getattr(self.flight, "on_msp_rc", None)
        self._result("no MSP RC in this firmware" if fn is None else fn(now_us, channels, len(channels)))

    def _result(self, reason):
        if reason is None:
            self.taken += 1
        else:
            self.refusals[reason] = self.refusals.get(reason, 0) + 1

    def read_replies(self):
        """Decode the reply bytes the flight controller wrote: SET_RAW_RC acks and refusals, polls."""
        port = self.port
        if not port.from_fc:
            return
        p = self._replies
        p.feed(port.from_fc)
        port.from_fc = bytearray()
        while p.pop():
            if p.direction == msp.DIR_REQUEST:
                continue
            if p.cmd != msp.MSP_SET_RAW_RC and p.cmd != msp.MSP2_HOVERFLY_AUTOPILOT:
                self.other_replies.append((p.direction, p.cmd, p.message()))
            elif p.cmd == msp.MSP_SET_RAW_RC:
                self.answered += 1
                if p.direction == msp.DIR_REPLY:
                    self.taken += 1
                else:
                    self._waiting_reason += 1  # the poll after it says why
            elif p.cmd == msp.MSP2_HOVERFLY_AUTOPILOT and p.direction == msp.DIR_REPLY:
                st = msp.unpack_autopilot(p.payload, p.length)
                if st is None:
                    continue
                counted = st["frames"] + st["rejected"]
                fresh = counted != self._counted  # the autopilot saw a frame since the last poll
                self._counted = counted
                self.status = st
                if self._waiting_reason:
                    self._waiting_reason -= 1
                    self._result(self._reason(st) if fresh else "refused by the MSP server")

    @staticmethod
    def _reason(st):
        code = st["last_result"]
        if code == RES_ARM_REFUSED:
            return arm_refusal_text(st["last_arm_reason"])
        if code == RES_TAKEN or code >= len(RESULT_TEXTS):
            return "refused (result %d)" % code
        return RESULT_TEXTS[code]

    def report(self):
        if self.port is not None:
            self.read_replies()
        ap = getattr(self.flight, "autopilot", None)
        r = {"sent": self.sent, "taken": self.taken, "refused": dict(self.refusals)}
        if self.port is not None:
            r["unanswered"] = self.sent - self.answered  # still on the wire when the flight ended
        if ap is not None:
            r["state"] = ap.state_name()
            r["privilege"] = ap.privilege()
        return r
