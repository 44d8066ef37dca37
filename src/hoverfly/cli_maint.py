"""`hoverfly maint --port URL ...`: the seed-001 maintenance protocol from the host.

Takes a maintenance port URL (gcs/link.py MaintClient) and gives: `read [FIELD...]` (telemetry
by header-bitmask field name, all fields by default), `fields` (the names), `motors --props-off
V1,V2,V3,V4` (a props-off motor test in pulse µs: control_motors 1, the motor commands refreshed
for `--seconds`, then all motors 1000 and control_motors 0, also on Ctrl-C), `set NAME VALUE`
(a hoverfly parameter through the seed command carrying it: SETTABLE, listed in `maint set --help`),
`save` (command 7, flash write) and `command NAME|ID [ARG...]` (any of the seed's commands 0-25,
listed with their arguments in `maint command --help`). `--json` prints machine-readable output.
What each command does in hoverfly, units and capping: docs/maintenance-protocol.md.
"""

import json
import time

from hoverfly.core.config.params import check_value
from hoverfly.errors import UserError
from hoverfly.protocols import maintenance as mp

MOTOR_REFRESH_S = 0.25  # the motor test expires after 1 s without a refresh (core/command/motortest.py)

_AXES = ("roll", "pitch", "yaw")
_STICKS = ("thr", "roll", "pitch")  # commands 12-14 (the seed has no yaw stick filter)
_IMU_NAMES = ("lsm9ds1", "mpu6050", "bno055")  # command 21's ids
# Parameters `maint set` carries beyond gcs.link.MAINT_SETTABLE: name -> (telemetry field, command of
# the first row, row length, column). The row is read, the one value changed, the row sent back.
_ROWS = {"motor_enable": ("motor_params", mp.CMD_SET_MOTOR1_PARAMS, 3, mp.MOTOR_PARAM_ENABLED)}
for _k in range(4):
    _ROWS["motor%d_min_us" % (_k + 1)] = ("motor_params", mp.CMD_SET_MOTOR1_PARAMS + _k, 3, mp.MOTOR_PARAM_MIN_US)
    _ROWS["motor%d_max_us" % (_k + 1)] = ("motor_params", mp.CMD_SET_MOTOR1_PARAMS + _k, 3, mp.MOTOR_PARAM_MAX_US)
for _k in range(3):
    _ROWS["ab_%s_alpha" % _STICKS[_k]] = ("js_params", mp.CMD_SET_JS_THROTTLE + _k, 2, 0)
    _ROWS["ab_%s_beta" % _STICKS[_k]] = ("js_params", mp.CMD_SET_JS_THROTTLE + _k, 2, 1)
    _ROWS["pid_kt_" + _AXES[_k]] = ("PID_params", mp.CMD_SET_ROLL_PID + _k, 6, mp.PID_KT)
    _ROWS["pid_ad_" + _AXES[_k]] = ("PID_params", mp.CMD_SET_ROLL_PID + _k, 6, mp.PID_AD)
for _k, _name in enumerate(("thr_descend_us", "thr_hover_us", "thr_climb_us")):
    _ROWS[_name] = ("throttle_params", mp.CMD_SET_THROTTLE_PARAMS, 3, _k)
_ROWS["imu_type"] = ("imu_type", mp.CMD_SET_IMU_TYPE, 1, 0)


def settable():
    """Every parameter `maint set` takes, in the order the help lists them."""
    from hoverfly.gcs.link import MAINT_SETTABLE

    return tuple(MAINT_SETTABLE) + tuple(n for n in _ROWS if n not in MAINT_SETTABLE)


def _set_row(client, name, value):
    """Set `name` through its seed command (read the row, change one value, send it); the value read back."""
    field, cmd, width, col = _ROWS[name]
    if name == "imu_type":
        client.command(cmd, (_IMU_NAMES.index(value),))
        return value  # a reboot parameter: imu_type telemetry shows the IMU running until the next boot
    current = client.read([field])[field]
    if name == "motor_enable":
        for k in range(4):
            row = list(current[3 * k:3 * k + 3])
            on = 1 if value & (1 << k) else 0
            if row[0] != on:
                row[0] = on
                client.command(cmd + k, tuple(row))
        got = client.read([field])[field]
        return sum(1 << k for k in range(4) if got[3 * k])
    if field == "PID_params":
        first = (cmd - mp.CMD_SET_ROLL_PID) * width
    elif field == "js_params":
        first = (cmd - mp.CMD_SET_JS_THROTTLE) * width
    elif field == "motor_params":
        first = (cmd - mp.CMD_SET_MOTOR1_PARAMS) * width
    else:
        first = 0
    row = list(current[first:first + width])
    row[col] = value
    client.command(cmd, tuple(row))
    got = client.read([field])[field][first + col]
    return int(got) if isinstance(value, int) else got


def _client(args):
    from hoverfly.gcs.link import MaintClient, open_link

    if not args.port:
        raise UserError("maint needs --port URL (the maintenance port, e.g. socket://127.0.0.1:5762)")
    if not args.timeout > 0:
        raise UserError("--timeout must be more than 0 s")
    port = open_link(args.port, args.timeout)
    return port, MaintClient(port, args.timeout)


def _text(v):
    if isinstance(v, float):
        return "%.6g" % v
    if isinstance(v, (tuple, list)):
        return ", ".join(_text(x) for x in v)
    return str(v)


def _print_values(values, as_json):
    if as_json:
        print(json.dumps({name: (list(v) if isinstance(v, tuple) else v) for name, v in values}))
        return
    for name, v in values:
        print("%-20s %s" % (name, _text(v)))


def _field_names(names):
    if not names:
        return [f[0] for f in mp.FIELDS]
    for name in names:
        if mp.field_index(name) < 0:
            raise UserError("unknown maintenance field '%s' (hoverfly maint fields lists them)" % name)
    return names


def run_read(args):
    fields = _field_names(args.fields)
    port, client = _client(args)
    try:
        reply = client.request(fields)
    finally:
        port.close()
    _print_values(reply.values, args.json)
    return 0


def run_fields(args):
    if args.json:
        print(json.dumps([{"name": n, "type": code, "count": count} for n, code, count in mp.FIELDS]))
        return 0
    for k, (name, code, count) in enumerate(mp.FIELDS):
        print("%2d %-20s %s%s" % (k, name, {"f": "float", "H": "u16", "B": "u8", "I": "u32"}[code],
                                  "[%d]" % count if count > 1 else ""))
    return 0


def parse_motor_values(text):
    """[pulse_us] x 4 from 'V1,V2,V3,V4' (one value = all four); UserError if not 1000..2000 µs."""
    parts = [p.strip() for p in text.split(",")]
    try:
        values = [int(p) for p in parts]
    except ValueError:
        raise UserError("--props-off takes pulse widths in us, e.g. 1100,1100,1100,1100") from None
    if len(values) == 1:
        values = values * 4
    if len(values) != 4:
        raise UserError("--props-off takes 4 values (motor 1..4) or one for all, got %d" % len(values))
    for v in values:
        if not mp.PULSE_MIN_US <= v <= mp.PULSE_MAX_US:
            raise UserError("motor pulse %d us is outside 1000..2000 us" % v)
    return values


def run_motors(args):
    from hoverfly.gcs.link import LinkError, Refused

    values = parse_motor_values(args.props_off)
    if not 0 < args.seconds <= 60:
        raise UserError("--seconds must be more than 0 and at most 60")
    fields = ["motor1_signal", "motor2_signal", "motor3_signal", "motor4_signal", "motors_armed"]
    port, client = _client(args)
    readings = []
    try:
        try:
            client.command(mp.CMD_CONTROL_MOTORS, (1,))
        except Refused as exc:
            raise UserError("%s (is it armed?)" % exc) from None
        try:
            end = time.monotonic() + args.seconds
            while True:
                reply = None
                for k in range(4):
                    try:
                        reply = client.command(mp.CMD_SET_MOTOR1 + k, (values[k],), fields)
                    except Refused as exc:
                        raise UserError(str(exc)) from None
                readings.append(dict(reply.values))
                if time.monotonic() >= end:
                    break
                time.sleep(min(MOTOR_REFRESH_S, max(0.0, end - time.monotonic())))
        finally:
            # SAFETY: whatever happened above (a refusal, Ctrl-C), stop the motors and release control
            try:
                client.command(mp.CMD_SET_ALL_MOTORS, (mp.PULSE_MIN_US,))
            except LinkError:
                pass  # still release motor control (the controller also stops an unrefreshed test in 1 s)
            client.command(mp.CMD_CONTROL_MOTORS, (0,))
    finally:
        port.close()
    last = readings[-1]
    notes = motor_notes(values, [last["motor%d_signal" % (k + 1)] for k in range(4)])
    if args.json:
        print(json.dumps({"commanded_us": values, "seconds": args.seconds, "last": last,
                          "readings": len(readings), "notes": notes}))
    else:
        print("motor test (props off): commanded %s us for %g s"
              % (", ".join(str(v) for v in values), args.seconds))
        print("last reading: %s us; motors stopped, control released"
              % ", ".join(str(last["motor%d_signal" % (k + 1)]) for k in range(4)))
        for n in notes:
            print("  " + n)
    return 0


def motor_notes(commanded_us, read_us):
    """Why a motor ran at another pulse than asked: the controller carries the command out at its limit
    (core/links/maintserver.py) and the seed's reply has no room for the reason, so it is named here."""
    notes = []
    for k, (want, got) in enumerate(zip(commanded_us, read_us, strict=True)):
        if not isinstance(got, int) or got == want or want <= 1000:
            continue
        if got < want:
            notes.append("motor %d ran at %d us, not %d: capped by the props-off test limit motor_test_pct "
                         "(%d us = %g %%; hoverfly params set motor_test_pct=N raises it) or by motor%d_max_us"
                         % (k + 1, got, want, got, (got - 1000) / 10.0, k + 1))
        else:
            notes.append("motor %d ran at %d us, not %d: raised to the motor's floor (motor_idle_pct, motor%d_min_us)"
                         % (k + 1, got, want, k + 1))
    return notes


def run_set(args):
    from hoverfly.gcs.link import MAINT_SETTABLE, LinkError, Refused

    name = args.name.strip().lower()
    if name not in settable():
        from hoverfly.core.config.params import nearest

        guess = nearest(name, settable())
        raise UserError("'%s' cannot be set over the maintenance protocol%s; it carries: %s"
                        % (name, " (did you mean %s?)" % guess if guess else "", ", ".join(settable())))
    value, err = check_value(name, args.value)
    if err is not None:
        raise UserError(err)
    if name == "imu_type" and value not in _IMU_NAMES:
        raise UserError("the maintenance protocol carries imu_type %s only" % ", ".join(_IMU_NAMES))
    if name == "motor_enable" and value > 15:
        raise UserError("the maintenance protocol carries motor_enable for motors 1-4 only (0..15)")
    port, client = _client(args)
    try:
        try:
            got = client.set_param(name, value) if name in MAINT_SETTABLE else _set_row(client, name, value)
        except Refused as exc:
            raise UserError(str(exc)) from None
        except LinkError as exc:
            raise UserError(str(exc)) from None
    finally:
        port.close()
    if args.json:
        print(json.dumps({name: got}))
    else:
        print("%s = %s (not saved: hoverfly maint save writes flash)" % (name, _text(got)))
    return 0


def run_save(args):
    from hoverfly.gcs.link import Refused

    port, client = _client(args)
    try:
        try:
            client.command(mp.CMD_FLASH_WRITE)
        except Refused as exc:
            from hoverfly.cli_params import NO_STORAGE_HINT

            # The seed's reply carries no reason; a flash write is refused when armed or with no storage.
            raise UserError("%s: not saved; it is refused while armed, or %s" % (exc, NO_STORAGE_HINT)) from None
    finally:
        port.close()
    print("saved (flash write)")
    return 0


def run_command(args):
    from hoverfly.gcs.link import Refused, command_id

    cmd = command_id(args.name)
    if cmd < 0:
        raise UserError("unknown maintenance command '%s': %s or 0..%d"
                        % (args.name, ", ".join(c[0] for c in mp.COMMANDS), mp.MAX_CMD_ID))
    fmt = mp.COMMANDS[cmd][1]
    names = mp.COMMANDS[cmd][2]
    if len(args.args) != len(fmt):
        raise UserError("%s takes %d argument%s%s" % (mp.COMMANDS[cmd][0], len(fmt),
                                                        "" if len(fmt) == 1 else "s",
                                                        (": " + " ".join(names)) if names else ""))
    values = []
    for code, text in zip(fmt, args.args, strict=True):
        try:
            values.append(float(text) if code == "f" else int(text, 0))
        except ValueError:
            raise UserError("%s: '%s' is not a %s" % (mp.COMMANDS[cmd][0], text,
                                                     "number" if code == "f" else "whole number")) from None
    fields = _field_names(args.read) if args.read else []
    port, client = _client(args)
    try:
        try:
            reply = client.command(cmd, tuple(values), fields)
        except Refused as exc:
            raise UserError(str(exc)) from None
    finally:
        port.close()
    if args.json:
        print(json.dumps({"command": mp.COMMANDS[cmd][0], "ok": True, "values": reply.as_dict()}))
    else:
        print("%s: ok" % mp.COMMANDS[cmd][0])
        _print_values(reply.values, False)
    return 0


def register(sub):
    import argparse

    p = sub.add_parser("maint",
                       help="the seed-001 maintenance protocol: read telemetry, motor test, set, save")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--port", metavar="URL", default=argparse.SUPPRESS,
                        help="the maintenance port: socket://127.0.0.1:5762 (hoverfly sim), /dev/ttyUSB0")
    common.add_argument("--timeout", type=float, default=argparse.SUPPRESS, metavar="S",
                        help="seconds to wait for a reply (1)")
    common.add_argument("--json", action="store_true", default=argparse.SUPPRESS, help="print JSON")
    p.add_argument("--port", metavar="URL", default=None,
                   help="the maintenance port: socket://127.0.0.1:5762 (hoverfly sim), /dev/ttyUSB0")
    p.add_argument("--timeout", type=float, default=1.0, metavar="S", help="seconds to wait for a reply (1)")
    p.add_argument("--json", action="store_true", default=False, help="print JSON")
    ps = p.add_subparsers(dest="maint_command")
    r = ps.add_parser("read", parents=[common], help="telemetry values by header field name (all by default)")
    r.add_argument("fields", nargs="*", metavar="FIELD")
    r.set_defaults(func=run_read)
    f = ps.add_parser("fields", parents=[common], help="the header field names, in header order")
    f.set_defaults(func=run_fields)
    m = ps.add_parser("motors", parents=[common], help="props-off motor test: --props-off V1,V2,V3,V4 (us)")
    m.add_argument("--props-off", required=True, metavar="V1,V2,V3,V4",
                   help="props removed: pulse widths in us (1000..2000) for motors 1-4, or one for all")
    m.add_argument("--seconds", type=float, default=2.0, metavar="S", help="how long to run them (2)")
    m.set_defaults(func=run_motors)
    s = ps.add_parser("set", parents=[common], help="a parameter through the seed command that carries it",
                      epilog="NAME is one of: " + ", ".join(settable()))
    s.add_argument("name", metavar="NAME", help="a hoverfly parameter the seed's commands carry (listed below)")
    s.add_argument("value", metavar="VALUE", help="the new value, in the parameter's unit (hoverfly params list)")
    s.set_defaults(func=run_set)
    sv = ps.add_parser("save", parents=[common], help="flash write (command 7)")
    sv.set_defaults(func=run_save)
    c = ps.add_parser("command", parents=[common], formatter_class=argparse.RawDescriptionHelpFormatter,
                      help="any seed command 0-25 by name or id, with its arguments",
                      epilog="commands (id name arguments):\n" + "\n".join(
                          ("  %2d %-20s %s" % (k, mp.COMMANDS[k][0], " ".join(mp.COMMANDS[k][2]))).rstrip()
                          for k in range(mp.MAX_CMD_ID + 1)))
    c.add_argument("name", metavar="NAME|ID", help="a command's name or id (listed below)")
    c.add_argument("args", nargs="*", metavar="ARG", help="its arguments, in the order listed below")
    c.add_argument("--read", nargs="+", metavar="FIELD", default=None, help="header fields to read with it")
    c.set_defaults(func=run_command)
