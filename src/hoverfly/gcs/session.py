"""The ground station's hold on one link: detection, telemetry, parameters, motor test and the sticks.

Takes a pyserial URL (gcs/link.py opens it) and gives what the web app (gcs/app.py) serves: the
link's state, a telemetry snapshot refreshed at 50 Hz, the parameter table with the controller's
values, diffs, the props-off motor test and the pilot's sticks. It finds out what the port speaks
by asking: an MSP_API_VERSION request first (a Betaflight-style MSP + CLI port), then a seed-001
maintenance request; a port that answers neither is "not a flight controller" and is closed.

One pump thread owns the timing: every 20 ms it sends the sticks (seed-001 radio override on a
maintenance port, MSP_SET_RAW_RC on an MSP port) while they are fresh, reads the telemetry, runs
the motor test's dead-man and reconnects a dropped link once a second. Requests from the page
(parameters, diffs, commands) take the same lock, so bytes of two requests never interleave on
the wire. pyserial is blocking; the app calls these methods from a worker thread.
"""

import math
import threading
import time

from hoverfly.core.config.params import PARAMS, REBOOT, check, is_choice, row
from hoverfly.core.links.cliserver import format_value
from hoverfly.core.safety.arming import REASONS
from hoverfly.core.safety.bit import CHECK_NAMES
from hoverfly.errors import UserError
from hoverfly.gcs.link import (
    MAINT_SETTABLE,
    CliSession,
    LinkError,
    MaintClient,
    MspClient,
    Refused,
    command_id,
    open_link,
)
from hoverfly.paramtext import changes_to, parse_dump, parse_set_text
from hoverfly.protocols import maintenance as mp
from hoverfly.protocols import msp

PUMP_PERIOD_S = 0.02  # 50 Hz: the sticks and the telemetry
STICKS_STALE_S = 0.25  # no sticks message this long: stop sending, the controller's link watch takes over
ARM_OFF_TICKS = 10  # a new stick stream's first frames (200 ms at 50 Hz) carry the arm switch off
MOTOR_DEADMAN_S = 0.5  # no motor_test call this long: the test stops
RECONNECT_S = 1.0
STATUS_EVERY = 10  # slow MSP reads (status, battery) every this many pump ticks: 5 Hz
THROTTLE_ZERO = 0.02  # throttle share that counts as "at zero" for arming (a gamepad's rest noise)
_G = 9.80665
_DEG = 57.29577951308232
_ACC_1G = 2048.0  # MSP_RAW_IMU scales (core/links/mspserver.py)
_GYRO_LSB_PER_DPS = 16.4
_MODES = ((16, "failsafe"), (2, "angle"), (4, "horizon"))

# The maintenance fields read every tick, and the slow ones.
_MAINT_FAST = ("filtered_accel_x", "filtered_accel_y", "filtered_accel_z", "filtered_gyro_x", "filtered_gyro_y",
               "filtered_gyro_z", "throttle_signal", "roll_signal", "pitch_signal", "body_roll", "body_pitch",
               "body_yaw", "roll_PID_error", "pitch_PID_error", "yaw_PID_error", "motor1_signal", "motor2_signal",
               "motor3_signal", "motor4_signal", "motors_armed", "builtin_test_status")


class GcsError(UserError):
    """A request the app answers with an error: `status` is the HTTP code (400 bad request, 409 not now,
    502 the controller refused or did not answer)."""

    def __init__(self, message, status=400):
        super().__init__(message)
        self.status = status


def param_groups():
    """{name: group} from the section comments of the parameter table ('# --- rates' ...)."""
    import hoverfly.core.config.params as params_module

    groups = {}
    group = "general"
    try:
        with open(params_module.__file__, encoding="utf-8") as fh:
            for line in fh:
                text = line.strip()
                if text.startswith("# ---"):
                    group = text[5:].strip().split("(")[0].strip() or group
                elif text.startswith('("'):
                    groups[text[2:text.index('"', 2)]] = group
    except OSError:
        pass
    return groups


def _finite(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


class Session:
    def __init__(self, url=None, timeout_s=1.0):
        self.url = url
        self.timeout_s = timeout_s
        self.lock = threading.RLock()
        self.port = None
        self.protocol = None
        self.client = None  # MspClient or MaintClient
        self.error = None
        self.want_connected = url is not None
        self.info = {"board": None, "version": None}
        self.telemetry = self._empty_telemetry()
        self.state = {"armed": False, "arming_flags": [], "bit_flags": None, "loop_us": None, "jitter_us": None,
                      "battery_v": None, "rx_lq": None, "mode": None}
        self.params_cache = None  # {name: value} read from the controller
        # sticks
        self.sticks = None  # (roll, pitch, yaw, throttle, aux) of the latest message
        self.sticks_at = 0.0
        self.arm = False
        self._arm_off_ticks = 0  # frames still to send with the arm switch off (see _override_state)
        self.override = "off"  # off / sending / stopped
        self.override_refusal = None
        self.rc_sent = 0
        # motor test
        self.motor_values = None
        self.motor_at = 0.0
        self.motor_props = False
        self.motor_stops = 0
        self._ticks = 0
        self.tick_s_sum = 0.0
        self.tick_s_max = 0.0
        self._reason_at = 0.0
        self._last_try = 0.0
        self._stop = threading.Event()
        self._thread = None

    # ------------------------------------------------------------------ link
    def start(self):
        if self.url:
            try:
                self.connect(self.url)
            except GcsError:
                pass  # the page shows link.error; the pump retries
        self._thread = threading.Thread(target=self._pump, name="hoverfly-gcs-pump", daemon=True)
        self._thread.start()

    def close(self):
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
        with self.lock:
            self._stop_motors_quietly()
            self._close_port()

    def link_state(self):
        return {"url": self.url, "protocol": self.protocol, "connected": self.port is not None, "error": self.error}

    def _refuse_in_flight(self, what):
        # SAFETY: switching or dropping the link ends the sticks this page flies with: not by a click in flight.
        if self.state["armed"] and self.override == "sending":
            raise GcsError("%s refused: the craft is armed and flown from this page; land and disarm first" % what,
                           409)

    def connect(self, url):
        self._refuse_in_flight("connecting another port")
        with self.lock:
            self._stop_motors_quietly()
            self._close_port()
            self.url = url
            self.want_connected = True
            self._last_try = time.monotonic()
            try:
                self._open(url)
            except LinkError as exc:
                self.error = str(exc)
                self._close_port()
                raise GcsError(self.error, 502) from None
            self.error = None
            return self.link_state()

    def disconnect(self):
        self._refuse_in_flight("disconnecting")
        with self.lock:
            self._stop_motors_quietly()
            self.want_connected = False
            self._close_port()
            self.error = None

    def _open(self, url):
        port = open_link(url, self.timeout_s)
        try:
            proto = self._detect(port)
        except LinkError:
            port.close()
            raise
        if proto is None:
            port.close()
            raise LinkError("%s answers neither MSP nor the seed-001 maintenance protocol: is it a flight "
                            "controller's port?" % url)
        # connected (port set) only once the port has answered as a flight controller
        self.error = None
        self.port = port
        self.protocol = proto
        self.params_cache = None
        if proto == "msp":
            self.client = MspClient(port, timeout_s=self.timeout_s, retries=1)
            c = self.client
            variant = msp.unpack_fc_variant(c.request(msp.MSP_FC_VARIANT))
            ver = msp.unpack_fc_version(c.request(msp.MSP_FC_VERSION))
            try:
                board = msp.unpack_board_info(c.request(msp.MSP_BOARD_INFO))
                board_name = board.get("target_name") or board.get("board_id")
            except (LinkError, ValueError, IndexError):
                board_name = None
            self.info = {"board": board_name or variant, "version": "%s %d.%d.%d" % (variant, ver[0], ver[1], ver[2])}
        else:
            self.client = MaintClient(port, timeout_s=self.timeout_s, retries=1)
            v = self.client.read(["sw_ver", "imu_type"])["sw_ver"]
            kind = "beta" if v[3] == mp.RELEASE_BETA else "release"
            self.info = {"board": "seed-001 maintenance port", "version": "%d.%d.%d %s" % (v[0], v[1], v[2], kind)}

    def _detect(self, port):
        try:
            MspClient(port, timeout_s=0.4, retries=1).request(msp.MSP_API_VERSION)
            return "msp"
        except Refused:
            return "msp"
        except LinkError as exc:
            if "closed" in str(exc) or "cannot" in str(exc):
                raise
        try:
            MaintClient(port, timeout_s=0.4, retries=1).read(["sw_ver"])
            return "maint"
        except LinkError as exc:
            if "closed" in str(exc) or "cannot" in str(exc):
                raise
        return None

    def _close_port(self):
        if self.port is not None:
            try:
                self.port.close()
            except Exception:  # noqa: BLE001 - a dead port closing is still closed
                pass
        self.port = None
        self.client = None
        self.protocol = None
        self.telemetry = self._empty_telemetry()

    def _lost(self, exc):
        """The link failed mid-session: close it, say why; the pump reconnects."""
        self.error = str(exc)
        self.motor_values = None
        self.motor_props = False
        self._close_port()

    def _need(self, protocol=None):
        if self.port is None:
            raise GcsError("not connected%s" % (": " + self.error if self.error else ""), 409)
        if protocol is not None and self.protocol != protocol:
            what = "an MSP/CLI port" if protocol == "msp" else "a maintenance port"
            raise GcsError("this needs %s; the link is %s" % (what, self.protocol), 409)

    def _io(self, fn, *args):
        """Run fn on the link; a dropped link becomes a 502 and the pump's reconnect."""
        try:
            return fn(*args)
        except Refused as exc:
            raise GcsError(str(exc), 502) from None
        except LinkError as exc:
            self._lost(exc)
            raise GcsError(str(exc), 502) from None

    # ----------------------------------------------------------------- status
    @staticmethod
    def _empty_telemetry():
        return {"t": "telemetry", "attitude_deg": None, "gyro_dps": None, "acc_g": None, "setpoint_dps": None,
                "motors": None, "rc": None, "armed": False, "mode": None, "link_ok": False, "override": "off"}

    def status(self):
        out = {"link": self.link_state()}
        out.update(self.info)
        out.update(self.state)
        out["override"] = self.override
        out["override_refusal"] = self.override_refusal
        return out

    # ------------------------------------------------------------- parameters
    def _cli(self, fn):
        """fn(cli) inside one CLI session on the MSP port."""
        def run():
            with CliSession(self.port, max(self.timeout_s, 2.0)) as cli:
                return fn(cli)

        with self.lock:
            self._need("msp")
            return self._io(run)

    def _refuse_armed(self, what):
        if self.state["armed"]:
            raise GcsError("%s refused while armed: disarm first" % what, 409)

    def params(self):
        groups = param_groups()
        if self.protocol == "msp":
            current = self._cli(lambda cli: parse_dump(cli.command("dump", check=True)))
            self.params_cache = current
        elif self.protocol == "maint":
            current = {}
            with self.lock:
                self._need("maint")
                for name in MAINT_SETTABLE:
                    current[name] = self._io(self.client.get_param, name)
        else:
            self._need()
            current = {}
        out = []
        for r in PARAMS:
            name, default, lo, hi, unit, applies, help_text = r
            choice = is_choice(r)
            out.append({"name": name, "value": current.get(name), "default": default,
                        "min": None if choice else lo, "max": None if choice else hi,
                        "unit": None if choice else unit, "help": help_text, "group": groups.get(name, "general"),
                        "choices": list(unit) if choice else None, "reboot": applies == REBOOT})
        return out

    def _checked(self, values):
        if not isinstance(values, dict) or not values:
            raise GcsError("send {name: value, ...}")
        checked = []
        errors = []
        for given, value in values.items():
            text = value if isinstance(value, str) else (format_value(value) if _finite(value) else str(value))
            name, v, err = check(str(given).strip().lower(), text)
            if err is not None:
                errors.append(err)
            else:
                checked.append((name, v))
        if errors:
            raise GcsError("; ".join(errors) + " (nothing was sent)")
        return checked

    def set_params(self, values):
        checked = self._checked(values)  # every value checked before anything is sent
        self._need()
        self._refuse_armed("parameter writes")
        if self.protocol == "maint":
            bad = [n for n, _ in checked if n not in MAINT_SETTABLE]
            if bad:
                raise GcsError("the maintenance protocol cannot set %s; it carries: %s (nothing was sent)"
                               % (", ".join(bad), ", ".join(MAINT_SETTABLE)))
            with self.lock:
                self._need("maint")
                for name, v in checked:
                    self._io(self.client.set_param, name, v)
            return {"applied": [n for n, _ in checked]}

        def run(cli):
            for name, v in checked:
                cli.command("set %s = %s" % (name, format_value(v)), check=True)
            return [n for n, _ in checked]

        return {"applied": self._cli(run)}

    def save(self):
        self._need()
        self._refuse_armed("save")
        if self.protocol == "maint":
            with self.lock:
                self._need("maint")
                self._io(self.client.command, mp.CMD_FLASH_WRITE)
        else:
            self._cli(lambda cli: cli.save())
        return {"ok": True}

    def diff_text(self):
        lines = self._cli(lambda cli: cli.command("diff all", check=True))
        return "\n".join(lines) + "\n"

    def diff_preview(self, text):
        if not isinstance(text, str):
            raise GcsError("send {text: the file's text}")
        wanted, is_diff, skipped, bad = parse_set_text(text)
        errors = sorted([{"line": n, "error": "not a 'set name = value' line: %s" % line[:80]} for n, line in skipped]
                        + [{"line": n, "error": err} for n, err in bad], key=lambda e: e["line"])
        current = self._cli(lambda cli: parse_dump(cli.command("dump", check=True)))
        changes = [{"name": name, "old": old, "new": new, "reboot": row(name)[5] == REBOOT}
                   for name, old, new in changes_to(current, wanted, is_diff)]
        return {"changes": changes, "errors": errors, "resets_unlisted": is_diff}

    def diff_apply(self, text):
        preview = self.diff_preview(text)
        if preview["errors"]:
            e = preview["errors"][0]
            raise GcsError("line %d: %s (nothing was applied)" % (e["line"], e["error"]))
        self._refuse_armed("parameter writes")
        changes = preview["changes"]

        def run(cli):
            for c in changes:
                cli.command("set %s = %s" % (c["name"], format_value(c["new"])), check=True)
            return [c["name"] for c in changes]

        return {"applied": self._cli(run) if changes else []}

    # ------------------------------------------------------------- motor test
    def motor_test(self, props_removed, values):
        if props_removed is not True:
            raise GcsError("confirm that the propellers are removed (props_removed: true)")
        if not isinstance(values, list) or not values or len(values) > 8 \
                or not all(_finite(v) and 0.0 <= v <= 1.0 for v in values):
            raise GcsError("values: one number 0..1 per motor (at most 8)")
        self._refuse_armed("motor test")
        with self.lock:
            self._need()
            self._send_motors(values)
            self.motor_values = list(values)
            self.motor_at = time.monotonic()
        return {"ok": True, "values": list(values)}

    def _send_motors(self, values):
        pulses = [1000 + int(v * 1000.0 + 0.5) for v in values]
        c = self.client
        if self.protocol == "msp":
            if not self.motor_props:
                self._io(c.request, msp.MSP_SET_ARMING_DISABLED, msp.pack_set_arming_disabled(1))
                self.motor_props = True
            self._io(c.request, msp.MSP_SET_MOTOR, msp.pack_set_motor(pulses + [1000] * (8 - len(pulses))))
        else:
            if not self.motor_props:
                self._io(c.command, mp.CMD_CONTROL_MOTORS, (1,))
                self.motor_props = True
            for k, us in enumerate(pulses[:4]):
                self._io(c.command, mp.CMD_SET_MOTOR1 + k, (us,))

    def motor_stop(self):
        with self.lock:
            was = self.motor_values is not None or self.motor_props
            self.motor_values = None
            if self.port is None:
                self.motor_props = False
                return {"ok": True}
            c = self.client
            if was:
                self.motor_stops += 1
            if self.protocol == "msp":
                self._io(c.request, msp.MSP_SET_MOTOR, msp.pack_set_motor([1000] * 8))
                self._io(c.request, msp.MSP_SET_ARMING_DISABLED, msp.pack_set_arming_disabled(0))
            else:
                self._io(c.command, mp.CMD_SET_ALL_MOTORS, (1000,))
                self._io(c.command, mp.CMD_CONTROL_MOTORS, (0,))
            self.motor_props = False
        return {"ok": True}

    def _stop_motors_quietly(self):
        # SAFETY: every way out of a session (disconnect, reconnect, shutdown) stops a running test.
        if self.motor_values is not None or self.motor_props:
            try:
                self.motor_stop()
            except GcsError:
                pass

    # ------------------------------------------------------------ maintenance
    @staticmethod
    def maint_commands():
        out = []
        for k, (name, fmt, names) in enumerate(mp.COMMANDS):
            args = []
            for code, arg in zip(fmt, names, strict=False):
                if code == "f":
                    args.append({"name": arg, "type": "float", "min": None, "max": None})
                elif code == "H":
                    lo, hi = (1000, 2000) if arg.endswith("_us") else (0, 65535)
                    args.append({"name": arg, "type": "int", "min": lo, "max": hi})
                else:
                    args.append({"name": arg, "type": "int", "min": 0, "max": 255})
            out.append({"id": k, "name": name, "args": args})
        return out

    def maint_command(self, name, args):
        cmd = command_id(name if name is not None else "")
        if cmd < 0:
            raise GcsError("unknown maintenance command %r" % (name,))
        if not isinstance(args, list) or not all(_finite(a) for a in args):
            raise GcsError("args: a list of numbers")
        fmt = mp.COMMANDS[cmd][1]
        if len(args) != len(fmt):
            raise GcsError("%s takes %d arguments" % (mp.COMMANDS[cmd][0], len(fmt)))
        typed = []
        for code, a in zip(fmt, args, strict=True):
            if code != "f" and a != int(a):
                raise GcsError("%s: whole numbers only" % mp.COMMANDS[cmd][0])
            typed.append(float(a) if code == "f" else int(a))
        reason = mp.validate_command(cmd, tuple(typed))
        if reason is not None:
            raise GcsError(reason + " (nothing was sent)")
        with self.lock:
            self._need("maint")
            reply = self._io(self.client.command, cmd, tuple(typed))
        return {"ok": True, "values": reply.as_dict()}

    def maint_read(self, fields):
        if not isinstance(fields, list) or not fields or not all(isinstance(f, str) for f in fields):
            raise GcsError("fields: a list of header field names")
        bad = [f for f in fields if mp.field_index(f) < 0]
        if bad:
            raise GcsError("unknown field %s" % ", ".join(bad))
        with self.lock:
            self._need("maint")
            reply = self._io(self.client.request, fields)
        return reply.as_dict()

    # ------------------------------------------------------------------ sticks
    def set_sticks(self, msg):
        """A sticks message from the page; None, or why it was not taken."""
        try:
            roll, pitch, yaw, thr = (float(msg.get(k)) for k in ("roll", "pitch", "yaw", "throttle"))
        except (TypeError, ValueError):
            return "sticks need roll, pitch, yaw and throttle numbers"
        if not all(math.isfinite(v) for v in (roll, pitch, yaw, thr)):
            return "sticks must be finite numbers"
        clamp = self._clamp
        aux = msg.get("aux") or []
        aux = [clamp(float(a), -1.0, 1.0) for a in aux[:4] if _finite(a)] if isinstance(aux, list) else []
        s = (clamp(roll, -1.0, 1.0), clamp(pitch, -1.0, 1.0), clamp(yaw, -1.0, 1.0), clamp(thr, 0.0, 1.0), aux)
        arm = msg.get("arm") is True
        with self.lock:
            err = None
            if arm and not self.arm:
                # SAFETY: arming takes the throttle at zero (a gamepad's first values never arm).
                if s[3] > THROTTLE_ZERO:
                    err = "arming needs the throttle at zero"
                else:
                    self.arm = True
            elif not arm:
                self.arm = False
            self.sticks = s
            self.sticks_at = time.monotonic()
        return err

    def set_arm(self, arm):
        with self.lock:
            if arm is not True:
                self.arm = False
                return {"ok": True}
            fresh = self.sticks is not None and time.monotonic() - self.sticks_at < STICKS_STALE_S
            if not fresh:
                raise GcsError("arming needs live sticks (connect a gamepad on the Fly screen)", 409)
            if self.sticks[3] > THROTTLE_ZERO:
                raise GcsError("arming needs the throttle at zero", 409)
            self.arm = True
        return {"ok": True}

    def sticks_gone(self):
        """The page's socket closed: nothing more is sent for it."""
        with self.lock:
            self.sticks = None
            self.arm = False

    @staticmethod
    def _clamp(x, lo, hi):
        return lo if x < lo else (hi if x > hi else x)

    def _pulses(self):
        roll, pitch, yaw, thr, aux = self.sticks
        return (1500 + int(roll * 500.0), 1500 + int(pitch * 500.0), 1500 + int(yaw * 500.0),
                1000 + int(thr * 1000.0), [1500 + int(a * 500.0) for a in aux])

    # -------------------------------------------------------------------- pump
    def _pump(self):
        next_t = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            try:
                self.tick(now)
            except Exception as exc:  # noqa: BLE001 - the pump must outlive any one bad tick
                self.error = "ground station: %s" % exc
            next_t += PUMP_PERIOD_S
            delay = next_t - time.monotonic()
            if delay < 0:
                next_t = time.monotonic()
                delay = 0
            self._stop.wait(delay)

    def tick(self, now):
        with self.lock:
            if self.port is None:
                self.override = "off"
                if self.want_connected and self.url and now - self._last_try >= RECONNECT_S:
                    self._last_try = now
                    try:
                        self._open(self.url)
                        self.error = None
                    except LinkError as exc:
                        self.error = str(exc)
                        self._close_port()
                return
            # SAFETY: dead-man: a motor test the page stopped refreshing stops here.
            if self.motor_values is not None and now - self.motor_at > MOTOR_DEADMAN_S:
                try:
                    self.motor_stop()
                except GcsError:
                    pass
            fresh = self.sticks is not None and now - self.sticks_at < STICKS_STALE_S
            if not fresh and self.arm and not self.state["armed"]:
                # Stale sticks and a disarmed controller (never armed, or the failsafe landed it): the arm
                # request goes, so the next arm needs the throttle at zero again. While the controller is
                # still armed it stays: sticks coming back after a gap must not send a disarm in the air.
                self.arm = False
            self._ticks += 1
            t0 = time.perf_counter()
            try:
                if self.protocol == "maint":
                    self._tick_maint(fresh)
                else:
                    self._tick_msp(fresh)
            except LinkError as exc:
                self._lost(exc)
            took_s = time.perf_counter() - t0  # the link's round trips: bench/gcs_link.py reports them
            self.tick_s_sum += took_s
            if took_s > self.tick_s_max:
                self.tick_s_max = took_s

    def _override_state(self, fresh):
        """Whether this tick's frame may carry the arm switch on."""
        if fresh:
            if self.override != "sending" and not self.state["armed"]:
                # SAFETY and Betaflight's rule alike: a controller that has just met a new stream (or lost one)
                # arms only after it has seen the arm switch off, so a new stream starts with it off.
                self._arm_off_ticks = ARM_OFF_TICKS
            self.override = "sending"
            if self._arm_off_ticks > 0:
                self._arm_off_ticks -= 1
                return False
            return self.arm
        if self.override == "sending":
            self.override = "stopped"
        return False

    def _tick_maint(self, fresh):
        rc = None
        arm = self._override_state(fresh)
        if fresh:
            roll, pitch, _, thr, _ = self._pulses()
            rc = (1, 2000 if arm else 1000, roll, pitch, thr)
        reply = self.client.request(_MAINT_FAST, mp.CMD_NONE, (), rc)
        if rc is not None:
            self.rc_sent += 1
            self.override_refusal = "the controller refused the override" if reply.refused else None
        v = reply.as_dict()
        gyro = [v["filtered_gyro_x"], v["filtered_gyro_y"], v["filtered_gyro_z"]]
        err = [v["roll_PID_error"], v["pitch_PID_error"], v["yaw_PID_error"]]
        armed = v["motors_armed"] == 1
        t = self.telemetry = {
            "t": "telemetry",
            "attitude_deg": [v["body_roll"], v["body_pitch"], v["body_yaw"]],
            "gyro_dps": gyro,
            # z as MSP_RAW_IMU gives it (Betaflight's sign: level at rest reads +1 g), so both links plot alike
            "acc_g": [v["filtered_accel_x"] / _G, v["filtered_accel_y"] / _G, -v["filtered_accel_z"] / _G],
            "setpoint_dps": [err[k] + gyro[k] for k in range(3)],
            "motors": [v["motor%d_signal" % k] for k in range(1, 5)],
            "rc": [v["roll_signal"], v["pitch_signal"], 1500, v["throttle_signal"]],
            "armed": armed, "mode": "angle", "link_ok": True, "override": self.override,
        }
        self.state.update({"armed": armed, "bit_flags": v["builtin_test_status"], "mode": t["mode"]})

    def _tick_msp(self, fresh):
        cmds = [(msp.MSP_ATTITUDE, b""), (msp.MSP_RAW_IMU, b""), (msp.MSP_MOTOR, b""), (msp.MSP_RC, b"")]
        if self._ticks % STATUS_EVERY == 1:
            cmds += [(msp.MSP_STATUS_EX, b""), (msp.MSP_ANALOG, b"")]
        arm = self._override_state(fresh)
        if fresh:
            roll, pitch, yaw, thr, aux = self._pulses()
            # AETR1234, as Betaflight's MSP receiver takes it; AUX1 is the arm switch
            aux = [2000 if arm else 1000] + (aux[1:] + [1500] * 3)[:3]
            cmds.append((msp.MSP_SET_RAW_RC, msp.pack_set_raw_rc([roll, pitch, thr, yaw] + aux[:4])))
        replies, refused = self._msp_batch(cmds)
        if fresh:
            self.rc_sent += 1
            if msp.MSP_SET_RAW_RC in refused:
                self.override_refusal = self._rc_refusal(Refused("the controller refused MSP_SET_RAW_RC"))
            elif msp.MSP_SET_RAW_RC in replies:
                self.override_refusal = None
        t = dict(self.telemetry)
        t["link_ok"] = True
        t["override"] = self.override
        a = replies.get(msp.MSP_ATTITUDE)
        if a is not None:
            r, p, y = msp.unpack_attitude(a)
            t["attitude_deg"] = [r * 0.1, p * 0.1, float(y)]
        imu = replies.get(msp.MSP_RAW_IMU)
        if imu is not None:
            acc, gyro, _ = msp.unpack_raw_imu(imu)
            t["acc_g"] = [x / _ACC_1G for x in acc]
            t["gyro_dps"] = [x / _GYRO_LSB_PER_DPS for x in gyro]
        m = replies.get(msp.MSP_MOTOR)
        if m is not None:
            t["motors"] = [x for x in msp.unpack_motor(m) if x > 0]
        rc = replies.get(msp.MSP_RC)
        if rc is not None:
            t["rc"] = msp.unpack_rc(rc)[:16]
        st = replies.get(msp.MSP_STATUS_EX)
        if st is not None:
            d = msp.unpack_status(st, ex=True)
            flags = d.get("arming_disable_flags", 0)
            modes = d["mode_flags"]
            mode = "acro"
            for bit, name in _MODES:
                if modes & bit:
                    mode = name
                    break
            self.state.update({
                "armed": bool(modes & 1), "loop_us": d["cycle_time_us"], "mode": mode,
                "arming_flags": [{"name": REASONS[b][0], "text": REASONS[b][1]} if b in REASONS
                                 else {"name": "BIT%d" % b, "text": "reason %d" % b}
                                 for b in range(32) if flags & (1 << b)],
            })
        an = replies.get(msp.MSP_ANALOG)
        if an is not None:
            dv, _, rssi, _, cv = msp.unpack_analog(an)
            self.state["battery_v"] = (cv if cv is not None else dv * 10) / 100.0
            self.state["rx_lq"] = round(rssi * 100 / 1023)
        t["armed"] = self.state["armed"]
        t["mode"] = self.state["mode"]
        self.telemetry = t

    def _rc_refusal(self, exc):
        """Why MSP_SET_RAW_RC was refused, in the controller's words (seed 004's autopilot state says; an
        MSP error frame carries none), read at most once a second."""
        now = time.monotonic()
        if now - self._reason_at < 1.0 and self.override_refusal:
            return self.override_refusal
        self._reason_at = now
        try:
            st = self.client.autopilot()
        except LinkError:
            return str(exc)
        return "MSP RC refused: %s (on this port MSP RC follows seed 004's autopilot rules)" % st["last_reason"]

    def _msp_batch(self, cmds):
        """Send every (cmd, payload) request at once and collect the replies: one round trip for the lot.
        ({cmd: reply payload}, {cmds answered with an error frame})."""
        from hoverfly.gcs import link

        port = self.port
        link._drain(port)
        parser = self.client.parser
        parser.reset()
        link._write(port, b"".join(msp.encode_request(c, p) for c, p in cmds))
        want = {c for c, _ in cmds}
        out = {}
        refused = set()
        deadline = time.monotonic() + self.timeout_s
        while want and time.monotonic() < deadline:
            data = link._read_some(port)
            if data:
                parser.feed(data)
            while parser.pop():
                if parser.cmd not in want:
                    continue
                if parser.direction == msp.DIR_REPLY:
                    out[parser.cmd] = bytes(parser.message())
                    want.discard(parser.cmd)
                elif parser.direction == msp.DIR_ERROR:
                    refused.add(parser.cmd)
                    want.discard(parser.cmd)
        if want and not out and not refused:
            raise LinkError("no MSP reply from %s" % self.url)
        return out, refused

    # ---------------------------------------------------------------- jitter
    def refresh_loop_stats(self):
        """CLI `status` for the loop's jitter and the built-in test (MSP carries neither); MSP port, disarmed."""
        if self.protocol != "msp" or self.state["armed"]:
            return
        try:
            lines = self._cli(lambda cli: cli.command("status"))
        except GcsError:
            return
        for line in lines:
            if line.startswith("Built-in test:"):
                failing = [w.strip() for w in line.split(":", 1)[1].split(",")]
                self.state["bit_flags"] = sum(1 << k for k, name in enumerate(CHECK_NAMES) if name in failing)
            if line.startswith("Loop:") and "jitter max" in line:
                try:
                    self.state["jitter_us"] = int(line.split("jitter max")[1].split("us")[0])
                except ValueError:
                    pass
