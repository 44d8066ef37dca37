"""`hoverfly params`: the parameter table (schema, list) and a controller's parameters over a link.

`schema` and `list` read the table (core/config/params.py). `get`, `set`, `dump`, `diff`, `save` and
`restore` talk to a controller through its CLI (gcs/link.py CliSession on `--port URL`), as a
Betaflight user would by hand: a `diff` or `dump` file is a list of `set` lines, and `restore`
replays the ones that differ from the controller after showing them (`--preview` shows only;
applying needs `--yes` or a typed `y`). Values are checked against the table before anything is
sent, and a refusal from the controller (`###ERROR: ...###`) becomes a one-line error.
"""

import json
import sys

from hoverfly.core.config.params import PARAMS, REBOOT, check, is_choice, row
from hoverfly.core.links.cliserver import format_value
from hoverfly.errors import UserError
from hoverfly.paramtext import changes_to, parse_dump, parse_set_text


def schema():
    """Every parameter row as a dict (what the ground station and docs are built from)."""
    out = []
    for r in PARAMS:
        name, default, lo, hi, unit, applies, help_text = r
        d = {"name": name, "default": default, "reboot": applies == REBOOT, "description": help_text}
        if is_choice(r):
            d["type"] = "choice"
            d["choices"] = list(unit)
        else:
            d["type"] = "float" if isinstance(default, float) else "int"
            d["min"] = lo
            d["max"] = hi
            d["unit"] = unit
        out.append(d)
    return {"count": len(out), "params": out}


def run_schema(args):
    print(json.dumps(schema(), indent=1 if args.pretty else None))
    return 0


def run_list(args):
    for r in PARAMS:
        if args.filter and args.filter not in r[0]:
            continue
        rng = "|".join(r[4]) if is_choice(r) else "%s..%s %s" % (r[2], r[3], r[4])
        note = " (reboot)" if r[5] == REBOOT else ""
        print("%-18s %-10s %-24s %s%s" % (r[0], r[1], rng.strip(), r[6], note))
    return 0


# ------------------------------------------------------------------------------ over a link
def _session(args):
    from hoverfly.gcs.link import CliSession, open_link

    if not args.timeout > 0:
        raise UserError("--timeout must be more than 0 s")
    port = open_link(args.port, args.timeout)
    return port, CliSession(port, args.timeout)


# What a refused save means when the controller has nowhere to write: the simulator keeps its parameters
# only in the file given with --storage, a board in its flash.
NO_STORAGE_HINT = ("the controller has no parameter storage it can write: a `hoverfly sim` keeps parameters only "
                   "when started with --storage PATH (e.g. hoverfly sim --storage params.bin)")


def _refused(what, exc, applied=()):
    text = "the controller refused '%s': %s" % (what, exc)
    if what == "save" and "storage" in str(exc):
        text += "; " + NO_STORAGE_HINT
    if applied:
        text += " (applied for this session, not saved: %s)" % ", ".join(applied)
    return UserError(text)


def _run_lines(args, line):
    from hoverfly.gcs.link import Refused

    port, cli = _session(args)
    try:
        with cli:
            try:
                lines = cli.command(line, check=True)
            except Refused as exc:
                raise UserError(str(exc)) from None
    finally:
        port.close()
    for text in lines:
        print(text)
    return 0


def run_get(args):
    return _run_lines(args, "get %s" % args.name if args.name else "get")


def run_dump(args):
    return _run_lines(args, "dump")


def run_diff(args):
    return _run_lines(args, "diff all")


def run_save(args):
    from hoverfly.gcs.link import Refused

    port, cli = _session(args)
    try:
        with cli:
            try:
                cli.save()
            except Refused as exc:
                raise _refused("save", exc) from None
    finally:
        port.close()
    print("saved")
    return 0


def parse_assignment(text, where="", value_text=None):
    """(hoverfly name, checked value, as typed) for `name=value` or (name, value); UserError if bad."""
    if value_text is None:
        if "=" not in text:
            raise UserError("%suse NAME=VALUE, not '%s'" % (where, text))
        text, value_text = text.split("=", 1)
    given = text.strip().lower()
    value_text = value_text.strip()
    name, v, err = check(given, value_text)  # the table's one check: names, aliases, finite, range
    if err is not None:
        if name is None and err.startswith("unknown parameter") and "did you mean" not in err:
            err += " (hoverfly params list shows them)"
        raise UserError(where + err)
    return name, v, value_text


def run_set(args):
    from hoverfly.gcs.link import Refused

    checked = [parse_assignment(a) for a in args.assignments]  # all checked before any is sent
    port, cli = _session(args)
    done = []
    try:
        with cli:
            for name, v, _ in checked:
                line = "set %s = %s" % (name, format_value(v))
                try:
                    done.extend(cli.command(line, check=True))
                except Refused as exc:
                    note = " (earlier values in this command are set, not saved)" if done else ""
                    raise UserError("the controller refused '%s': %s%s" % (line, exc, note)) from None
            if args.save:
                try:
                    cli.save()
                except Refused as exc:
                    raise _refused("save", exc, ["%s = %s" % (n, format_value(v)) for n, v, _ in checked]) from None
                done.append("saved")
    finally:
        port.close()
    for text in done:
        print(text)
    return 0


def read_set_file(path):
    """{name: value} from a dump/diff file's `set` lines, and True if unlisted names mean defaults
    (a `diff` file, or one holding `defaults nosave`). Other lines are skipped with a note; a bad
    `set` line stops it with a one-line error before anything is sent."""
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except OSError as exc:
        raise UserError("cannot read %s: %s" % (path, exc.strerror or exc)) from None
    except UnicodeError:
        raise UserError("%s is not a text file of set lines" % path) from None
    values, is_diff, skipped, errors = parse_set_text(text)
    if errors:
        n, err = errors[0]
        if err.startswith("unknown parameter") and "did you mean" not in err:
            err += " (hoverfly params list shows them)"
        raise UserError("%s line %d: %s" % (path, n, err))
    for n, line in skipped:
        print("hoverfly: note: %s line %d skipped (not a set line): %s" % (path, n, line), file=sys.stderr)
    return values, is_diff


def _confirm(count):
    print("apply %d change%s and save? [y/N] " % (count, "" if count == 1 else "s"), end="", file=sys.stderr,
          flush=True)
    answer = sys.stdin.readline()
    return answer.strip().lower() in ("y", "yes")


def run_restore(args):
    from hoverfly.gcs.link import Refused

    wanted, is_diff = read_set_file(args.file)
    port, cli = _session(args)
    try:
        with cli:
            current = parse_dump(cli.command("dump", check=True))
            if not current:
                raise UserError("the controller's dump had no set lines")
            changes = changes_to(current, wanted, is_diff)
            if not changes:
                print("the controller already matches %s" % args.file)
                return 0
            print("%d change%s from %s%s:" % (len(changes), "" if len(changes) == 1 else "s", args.file,
                                            " (unlisted parameters back to defaults)" if is_diff else ""))
            for name, old, new in changes:
                note = "  (after a reboot)" if row(name)[5] == REBOOT else ""
                print("  %-16s %s -> %s%s" % (name, format_value(old), format_value(new), note))
            if args.preview:
                print("preview only: nothing written")
                return 0
            if not args.yes and not _confirm(len(changes)):
                print("not applied")
                return 1
            for name, _, new in changes:
                line = "set %s = %s" % (name, format_value(new))
                try:
                    cli.command(line, check=True)
                except Refused as exc:
                    raise UserError("the controller refused '%s': %s (earlier lines are set, not saved)"
                                    % (line, exc)) from None
            try:
                cli.save()
            except Refused as exc:
                raise _refused("save", exc) from None
    finally:
        port.close()
    print("applied %d change%s and saved" % (len(changes), "" if len(changes) == 1 else "s"))
    return 0


def _link_args(p):
    p.add_argument("--port", required=True, metavar="URL",
                   help="the controller's CLI/MSP port: /dev/ttyACM0, socket://127.0.0.1:5761, /dev/rfcomm0")
    p.add_argument("--timeout", type=float, default=2.0, metavar="S",
                   help="seconds to wait for an answer (2)")


def register(sub):
    p = sub.add_parser("params", help="the parameter table (schema, list) and a controller's parameters")
    ps = p.add_subparsers(dest="params_command")
    s = ps.add_parser("schema",
                      help="print every parameter (name, type, default, range, unit, reboot, help) as JSON")
    s.add_argument("--pretty", action="store_true", help="indented JSON")
    s.set_defaults(func=run_schema)
    ls = ps.add_parser("list", help="print the parameter table")
    ls.add_argument("filter", nargs="?", default="", help="only names containing this")
    ls.set_defaults(func=run_list)
    g = ps.add_parser("get", help="a controller's parameters: all, or those whose name contains NAME")
    g.add_argument("name", nargs="?", default="",
                   help="a name or part of one (one exact name shows its range)")
    _link_args(g)
    g.set_defaults(func=run_get)
    st = ps.add_parser("set", help="change parameters on a controller (checked first; --save to keep them)")
    st.add_argument("assignments", nargs="+", metavar="NAME=VALUE")
    st.add_argument("--save", action="store_true", help="save to the controller's storage afterwards")
    _link_args(st)
    st.set_defaults(func=run_set)
    d = ps.add_parser("dump", help="every parameter of a controller as set lines")
    _link_args(d)
    d.set_defaults(func=run_dump)
    df = ps.add_parser("diff",
                       help="a controller's parameters that differ from the defaults (a restore file)")
    _link_args(df)
    df.set_defaults(func=run_diff)
    sv = ps.add_parser("save", help="write a controller's parameters to its storage")
    _link_args(sv)
    sv.set_defaults(func=run_save)
    rs = ps.add_parser("restore", help="replay a dump/diff file's set lines: shows the changes, applies on y")
    rs.add_argument("file",
                    help="a file of set lines (hoverfly params diff/dump output, a Betaflight-style diff)")
    rs.add_argument("--preview", action="store_true", help="only show what would change; write nothing")
    rs.add_argument("--yes", action="store_true", help="apply and save without asking")
    _link_args(rs)
    rs.set_defaults(func=run_restore)
