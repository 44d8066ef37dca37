"""Host side of the controller's serial links: open a port by URL, then talk MSP, CLI or maintenance.

Takes a pyserial URL (`/dev/ttyACM0`, `socket://127.0.0.1:5761` for `hoverfly sim`, an HC-05
`/dev/rfcomm0`, anything `serial.serial_for_url` accepts) and gives three small clients on the
open port: `MspClient` (request/reply with retries, MSP v1, v2 and v2-over-v1), `CliSession`
(enter the CLI with `#`, run a line, collect its output, leave with `exit` or `save`, as
Betaflight's CLI works) and `MaintClient` (the seed-001 maintenance protocol: requests built with
protocols/maintenance.py, replies parsed back into header fields by name, parameter updates
through the seed's commands). Host-only (CPython, pyserial); the ground-station commands
`hoverfly connect`, `hoverfly params get|set|...` and `hoverfly maint` sit on top of it.

Every failure a user can cause (a bad URL, a refused connection, no answer, a refusal from the
controller) raises LinkError, a UserError: the CLI prints it as one line.
"""

import re
import time

from hoverfly.core.command.autopilot import PRIV_NAMES, RES_ARM_REFUSED, RESULT_TEXTS, STATE_NAMES, arm_refusal_text
from hoverfly.errors import UserError
from hoverfly.protocols import maintenance as mp
from hoverfly.protocols import msp

DEFAULT_BAUD = 115200  # Betaflight's USB VCP / UART default; the seed's maintenance port (115200 8N1)
DEFAULT_TIMEOUT_S = 2.0
_POLL_S = 0.02  # one blocking read waits at most this long, so deadlines are kept to ~20 ms


class LinkError(UserError):
    """The link could not be opened, went silent or closed, or the controller refused a request."""


class Refused(LinkError):
    """The controller answered, and the answer was no (MSP error frame, CLI ###ERROR###, maintenance 127)."""


def _reason(exc):
    text = str(exc)
    k = text.rfind("[Errno")
    if k >= 0:
        j = text.find("]", k)
        text = text[j + 1:].strip()
    elif text.startswith("Could not open port"):
        text = text.split(": ", 1)[-1]
    return text[:1].lower() + text[1:] if text else exc.__class__.__name__


_SOCKET_URL = re.compile(r"^socket://([^:/?]+):(\d+)(/?(\?.*)?)?$")


def open_link(url, timeout_s=DEFAULT_TIMEOUT_S, baud=DEFAULT_BAUD):
    """The open pyserial port for `url`; raises LinkError naming the URL and the reason."""
    import serial

    if not url:
        raise LinkError("no port given: use --port URL (/dev/ttyACM0, socket://127.0.0.1:5761, /dev/rfcomm0)")
    if url.startswith("socket://"):
        m = _SOCKET_URL.match(url)
        if m is None or not (1 <= int(m.group(2)) <= 65535):
            raise LinkError("bad URL '%s': use socket://HOST:PORT with a port 1..65535" % url)
    try:
        port = serial.serial_for_url(url, baudrate=baud, timeout=_POLL_S, write_timeout=timeout_s)
    except (serial.SerialException, ValueError, OSError) as exc:
        raise LinkError("cannot open %s: %s" % (url, _reason(exc))) from None
    port.hoverfly_url = url
    port.hoverfly_timeout_s = timeout_s
    return port


def _url(port):
    return getattr(port, "hoverfly_url", None) or getattr(port, "port", None) or "the link"


def _read_some(port):
    """Whatever the port has (waits up to _POLL_S); b'' if nothing came."""
    import serial

    try:
        waiting = port.in_waiting
        return port.read(waiting if waiting > 0 else 1)
    except (serial.SerialException, OSError) as exc:
        raise LinkError("%s closed: %s" % (_url(port), _reason(exc))) from None


def _write(port, data):
    import serial

    try:
        port.write(data)
        port.flush()
    except (serial.SerialException, OSError) as exc:
        raise LinkError("cannot write to %s: %s" % (_url(port), _reason(exc))) from None


def _drain(port):
    """Drop bytes that arrived before our request (stale replies, telemetry, a banner)."""
    while True:
        try:
            waiting = port.in_waiting
        except OSError:
            return
        if waiting <= 0:
            return
        _read_some(port)


# --------------------------------------------------------------------------------------------- MSP
class MspClient:
    """Request/reply MSP over an open port.

        client = MspClient(port)
        payload = client.request(msp.MSP_API_VERSION)            # bytes of the reply
        client.request(msp.MSP_PID, version=2)                  # native v2 ($X)
        client.request(msp.MSP_STATUS, version=2, encapsulated=True)  # v2 inside v1 cmd 255

    A timeout re-sends the request (`retries` more times); an error reply (`!`) raises Refused.
    """

    def __init__(self, port, version=1, timeout_s=1.0, retries=2):
        self.port = port
        self.version = version
        self.timeout_s = timeout_s
        self.retries = retries
        self.parser = msp.MspParser(max_payload=4096, queue_depth=8)
        self.sent = 0
        self.timeouts = 0

    def request(self, cmd, payload=b"", version=None, encapsulated=False):
        version = self.version if version is None else version
        frame = msp.encode_request(cmd, bytes(payload), version, encapsulated)
        p = self.parser
        for _ in range(self.retries + 1):
            _drain(self.port)
            p.reset()
            _write(self.port, frame)
            self.sent += 1
            deadline = time.monotonic() + self.timeout_s
            while time.monotonic() < deadline:
                data = _read_some(self.port)
                if data:
                    p.feed(data)
                while p.pop():
                    if p.cmd != cmd or p.direction == msp.DIR_REQUEST:
                        continue  # a stale reply to an earlier request, or our own echo
                    if p.direction == msp.DIR_ERROR:
                        raise Refused("the controller refused MSP command %d" % cmd)
                    return p.message()
            self.timeouts += 1
        raise LinkError("no MSP reply to command %d from %s" % (cmd, _url(self.port)))

    def autopilot(self):
        """Seed 004's privilege state (MSP2_HOVERFLY_AUTOPILOT, docs/msp.md): msp.AUTOPILOT_FIELDS as a
        dict, plus their names: state_name, flier_name, override_name, privilege_names, last_reason."""
        payload = self.request(msp.MSP2_HOVERFLY_AUTOPILOT, version=2)
        st = msp.unpack_autopilot(payload)
        if st is None:
            raise LinkError("short MSP2_HOVERFLY_AUTOPILOT reply (%d bytes) from %s" % (len(payload), _url(self.port)))

        def name(names, i):
            return names[i] if 0 <= i < len(names) else str(i)

        st["state_name"] = name(STATE_NAMES, st["state"])
        st["flier_name"] = name(msp.FLIER_NAMES, st["flier"])
        st["override_name"] = name(msp.OVERRIDE_KIND_NAMES, st["override"])
        st["privilege_names"] = [PRIV_NAMES[b] for b in range(len(PRIV_NAMES)) if st["privilege"] & (1 << b)]
        code = st["last_result"]
        st["last_reason"] = (arm_refusal_text(st["last_arm_reason"]) if code == RES_ARM_REFUSED
                             else name(RESULT_TEXTS, code))
        return st


# --------------------------------------------------------------------------------------------- CLI
_BANNER = b"Entering CLI Mode"
_PROMPT = b"\r\n# "
_LEAVING = b"Leaving CLI mode"
_ERROR_PROMPT = b"###\r\n\r\n# "  # an ###ERROR### line followed by the prompt: the CLI stayed open


def _closing(line):
    """True if this CLI line ends the session on success (Betaflight: exit, save, defaults)."""
    words = line.strip().lower().split()
    if not words:
        return False
    if words[0] in ("exit", "save"):
        return True
    return words[0] == "defaults" and words[1:] != ["nosave"]


class CliSession:
    """A Betaflight-style CLI session on the CLI/MSP port.

        with CliSession(port) as cli:        # sends '#', waits for the prompt
            lines = cli.command("get p_roll")  # output lines, echo and prompt removed
            cli.command("set p_roll = 50", check=True)   # '###ERROR: ...###' raises Refused
        # leaving the block sends 'exit' (unless save already left the CLI)

    The end of a command's output is found by a marker comment line sent right after it (the
    CLI echoes it and ignores it), so output that itself holds '# ' lines cannot end it early.
    """

    def __init__(self, port, timeout_s=DEFAULT_TIMEOUT_S):
        self.port = port
        self.timeout_s = timeout_s
        self.active = False
        self._buf = bytearray()
        self._marks = 0

    def __enter__(self):
        self.enter()
        return self

    def __exit__(self, exc_type, exc, tb):
        if self.active:
            try:
                self.exit()
            except LinkError:
                if exc_type is None:
                    raise

    def _read_until(self, patterns, timeout_s=None, start=0):
        """Read until one of `patterns` is in the buffer (from `start`); (which, end offset) or (-1, -1)."""
        deadline = time.monotonic() + (self.timeout_s if timeout_s is None else timeout_s)
        buf = self._buf
        while True:
            for k, pat in enumerate(patterns):
                at = buf.find(pat, start)
                if at >= 0:
                    return k, at + len(pat)
            if time.monotonic() >= deadline:
                return -1, -1
            buf += _read_some(self.port)

    def _take(self, end):
        out = bytes(self._buf[:end])
        del self._buf[:end]
        return out

    def enter(self):
        """Send '#' and wait for the prompt; returns the banner text."""
        _drain(self.port)
        self._buf = bytearray()
        _write(self.port, b"#")
        k, end = self._read_until((_BANNER,), min(self.timeout_s, 1.0))
        if k < 0:
            # No banner: the CLI may already be open from an earlier session (a serial port has no
            # disconnect); the '#' is then a comment line we finish, which answers with a prompt.
            _write(self.port, b"\r")
            end = 0
        k, end = self._read_until((_PROMPT,), start=end)
        if k < 0:
            raise LinkError("no CLI prompt from %s (is it a hoverfly or Betaflight CLI/MSP port?)"
                            % _url(self.port))
        text = self._take(end)
        self.active = True
        return text.decode("ascii", "replace").strip().rstrip("#").strip()

    def command(self, line, check=False):
        """Run one CLI line; its output lines. check=True raises Refused on an ###ERROR### line."""
        if not self.active:
            raise LinkError("the CLI session is closed")
        line = line.strip()
        data = line.encode("ascii", "replace")
        if b"\r" in data or b"\n" in data:
            raise LinkError("one CLI line at a time")
        if _closing(line):
            _write(self.port, data + b"\r")
            k, end = self._read_until((_LEAVING + b"\r\n", _ERROR_PROMPT))
            if k < 0:
                raise LinkError("no answer to '%s' from %s" % (line, _url(self.port)))
            text = self._take(end)
            if k == 0:
                self.active = False
                self._buf = bytearray()
            lines = self._lines(text, prompt=k == 1)
        else:
            self._marks += 1
            mark = b"#hoverfly-%d" % self._marks
            _write(self.port, data + b"\r" + mark + b"\r")
            # the marker line's echo, its CRLF and a fresh prompt: everything before belongs to `line`
            k, end = self._read_until((mark + b"\r\n" + _PROMPT,))
            if k < 0:
                raise LinkError("no answer to '%s' from %s" % (line, _url(self.port)))
            text = self._take(end)
            lines = self._lines(text[:text.rfind(mark)], prompt=True)
        if check:
            for text_line in lines:
                if text_line.startswith("###ERROR"):
                    raise Refused(text_line.strip("#").replace("ERROR: ", "", 1).strip())
        return lines

    @staticmethod
    def _lines(raw, prompt):
        text = raw.decode("ascii", "replace")
        if prompt and text.endswith("\r\n# "):
            text = text[:-4]
        parts = text.split("\r\n")
        out = parts[1:]  # parts[0] is the echo of what we typed
        if out and out[-1] == "":
            out.pop()
        return out

    def exit(self):
        """Leave the CLI (the controller returns to MSP)."""
        if self.active:
            self.command("exit")
            self.active = False

    def save(self):
        """Write the parameters to storage; the CLI closes (Betaflight's `save`)."""
        return self.command("save", check=True)


# ---------------------------------------------------------------------------- maintenance protocol
ERROR_CMD = 127  # the server's "refused" command id in a reply header (core/links/maintserver.py)

# hoverfly parameter -> the seed command that carries it (what `maint set NAME VALUE` can change)
_PID_AXES = ("roll", "pitch", "yaw")
MAINT_SETTABLE = tuple(
    ["p_" + a for a in _PID_AXES] + ["i_" + a for a in _PID_AXES] + ["d_" + a for a in _PID_AXES]
    + ["iterm_limit", "gyro_lpf1_hz", "acc_lpf_hz"])
_TWO_PI = 6.283185307179586


def command_id(name_or_id):
    """Seed command id for a name ('flash_write') or a number ('7'); -1 if unknown."""
    text = str(name_or_id).strip().lower()
    if text.isdigit():
        n = int(text)
        return n if 0 <= n <= mp.MAX_CMD_ID else -1
    for k, spec in enumerate(mp.COMMANDS):
        if spec[0] == text:
            return k
    return -1


class MaintReply:
    """One parsed reply: `cmd_id` (as sent, or 127 if refused), `refused`, `values` [(name, value)]."""

    def __init__(self, cmd_id, values):
        self.cmd_id = cmd_id
        self.refused = cmd_id == ERROR_CMD
        self.values = values

    def as_dict(self):
        out = {}
        for name, v in self.values:
            out[name] = list(v) if isinstance(v, tuple) else v
        return out


class MaintClient:
    """The seed-001 maintenance protocol from the host side.

        client = MaintClient(port)
        client.read(["body_roll", "motor1_signal"])            # {'body_roll': 0.3, ...}
        client.command(mp.CMD_CONTROL_MOTORS, (1,))            # Refused if the reply says 127
        client.set_param("p_roll", 60)                         # through set_roll_pid
        client.command(mp.CMD_FLASH_WRITE)

    A reply is matched to its request by the header's field bits and command id (or 127); a
    timeout re-sends (the seed's commands all set state, so sending twice does no harm).
    """

    def __init__(self, port, timeout_s=1.0, retries=2, layout=mp.LAYOUT_SEED):
        self.port = port
        self.timeout_s = timeout_s
        self.retries = retries
        self.layout = layout
        self.parser = mp.MaintenanceParser(replies=True, queue_depth=4, layout=layout)
        self.timeouts = 0

    def request(self, fields=(), cmd=mp.CMD_NONE, args=(), remote_control=None):
        """Send one request; the MaintReply (refusals are returned, not raised)."""
        for f in fields:
            if mp.field_index(f) < 0:
                raise LinkError("unknown maintenance field '%s'" % (f,))
        try:
            frame = mp.encode_request(list(fields), cmd, tuple(args), remote_control, self.layout)
        except ValueError as exc:
            raise LinkError(str(exc)) from None
        want = mp.header_mask(frame, self.layout, 1)
        p = self.parser
        for _ in range(self.retries + 1):
            _drain(self.port)
            p.reset()
            _write(self.port, frame)
            deadline = time.monotonic() + self.timeout_s
            while time.monotonic() < deadline:
                data = _read_some(self.port)
                if data:
                    p.feed(data)
                while p.pop():
                    if p.mask() != want or p.values is None:
                        continue
                    if p.cmd_id != cmd and p.cmd_id != ERROR_CMD:
                        continue
                    return MaintReply(p.cmd_id, list(p.values))
            self.timeouts += 1
        raise LinkError("no maintenance reply from %s (is it the maintenance port?)" % _url(self.port))

    def read(self, fields):
        """{name: value} of the named header fields, in header order (arrays as tuples)."""
        reply = self.request(fields)
        return dict(reply.values)

    def command(self, cmd, args=(), fields=()):
        """Run a seed command; its MaintReply, or Refused naming the command."""
        reason = mp.validate_command(cmd, args) if 0 <= cmd <= mp.MAX_CMD_ID else "unknown command %d" % cmd
        if reason is not None:
            raise LinkError(reason)
        reply = self.request(fields, cmd, args)
        if reply.refused:
            raise Refused("the controller refused %s %s" % (mp.COMMANDS[cmd][0], _args_text(args)))
        return reply

    def set_param(self, name, value):
        """Change one hoverfly parameter through the seed command that carries it (MAINT_SETTABLE).
        Returns the value read back. Does not save: command(CMD_FLASH_WRITE) does."""
        if name not in MAINT_SETTABLE:
            raise LinkError("'%s' cannot be set over the maintenance protocol; it carries: %s"
                            % (name, ", ".join(MAINT_SETTABLE)))
        if name in ("gyro_lpf1_hz", "acc_lpf_hz"):
            # the seed sends a PT1 time constant per axis; hoverfly filters all axes at one cutoff
            tau_s = 1.0 / (_TWO_PI * value) if value > 0 else 0.0
            cmd = mp.CMD_SET_PT1_GYRO if name == "gyro_lpf1_hz" else mp.CMD_SET_PT1_ACCEL
            self.command(cmd, (tau_s, tau_s, tau_s))
        else:
            pid = list(self.read(["PID_params"])["PID_params"])
            if name == "iterm_limit":
                axes = (0,)
                col = mp.PID_SAT
            else:
                axes = (_PID_AXES.index(name[2:]),)
                col = {"p": mp.PID_KP, "i": mp.PID_KI, "d": mp.PID_BD}[name[0]]
            for axis in axes:
                row = pid[axis * 6:axis * 6 + 6]
                row[col] = float(value)
                self.command(mp.CMD_SET_ROLL_PID + axis, tuple(row))
        return self.get_param(name)

    def get_param(self, name):
        """The value of a MAINT_SETTABLE parameter as the maintenance protocol reports it."""
        if name in ("gyro_lpf1_hz", "acc_lpf_hz"):
            tau = self.read(["ptf1_params"])["ptf1_params"][3 if name == "gyro_lpf1_hz" else 0]
            return int(1.0 / (_TWO_PI * tau) + 0.5) if tau > 0 else 0
        pid = self.read(["PID_params"])["PID_params"]
        if name == "iterm_limit":
            v = pid[mp.PID_SAT]
        else:
            col = {"p": mp.PID_KP, "i": mp.PID_KI, "d": mp.PID_BD}[name[0]]
            v = pid[_PID_AXES.index(name[2:]) * 6 + col]
        return int(v) if v == int(v) else v


def _args_text(args):
    return "(%s)" % ", ".join("%g" % a if isinstance(a, float) else str(a) for a in args)
