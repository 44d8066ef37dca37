"""`hoverfly log info|params|csv|plot|report|replay FILE`: look into a flight log (ULog).

A file that cannot be read is one error line (exit 2); a file read in part (cut off,
corrupt messages skipped) prints its warnings on stderr and carries on with what it has.
"""

import json
import os
import sys

from hoverfly.errors import UserError
from hoverfly.logs.steps import step_line


def _load(args, topics=None):
    from hoverfly.logs.data import load

    log = load(args.file, topics)
    for w in log.warnings:
        print("hoverfly: warning: %s: %s" % (args.file, w), file=sys.stderr)
    return log


def _out_dir(args, suffix):
    if args.out:
        return args.out
    stem = os.path.splitext(os.path.basename(args.file))[0]
    return stem + suffix


def run_info(args):
    from hoverfly.logs.ulogread import read_summary

    s = read_summary(args.file)
    for w in s["warnings"]:
        print("hoverfly: warning: %s: %s" % (args.file, w), file=sys.stderr)
    if args.json:
        json.dump(s, sys.stdout, default=str)
        sys.stdout.write("\n")
        return 0
    info = s["info"]
    print("%s: %s on %s, software %s; %.2f s logged%s" % (
        args.file, info.get("sys_name", "?"), info.get("ver_hw", "?"), info.get("ver_sw", "?"),
        s["duration_s"],
        " (file corruption: partial read)" if s["file_corruption"] else ""))
    print("  %-28s %9s %10s" % ("topic", "samples", "rate Hz"))
    for t in s["topics"]:
        name = t["name"] + ("" if t["multi_id"] == 0 else ".%02d" % t["multi_id"])
        print("  %-28s %9d %10.1f" % (name, t["samples"], t["rate_hz"]))
    print("  %d parameters, %d changed in flight; %d messages; %d dropouts" % (
        len(s["params"]), len(s["changed_params"]), len(s["messages"]), len(s["dropouts"])))
    for m in s["messages"]:
        print("  %9.3f s  %-8s %s" % ((m["timestamp_us"] - s["start_us"]) * 1e-6, m["level"], m["text"]))
    return 0


def run_params(args):
    from hoverfly.logs.data import params_table

    log = _load(args, topics=[])
    rows = params_table(log)
    if args.changed:
        rows = [r for r in rows if r[4]]
    if args.json:
        json.dump({"params": {r[0]: r[1] for r in rows},
                   "changes": [[(t - log.start_us) * 1e-6, k, v] for t, k, v in log.changed_params]},
                  sys.stdout)
        sys.stdout.write("\n")
        return 0
    for name, value, default, _unit, note in rows:
        print("%-18s %-12s %s" % (name, value, ("(default %s)" % default) if note == "changed" else note))
    for t, k, v in log.changed_params:
        print("at %.3f s: %s = %s" % ((t - log.start_us) * 1e-6, k, v))
    return 0


def _writing(out_dir, fn, *args):
    """fn(*args) writing into out_dir: a directory that cannot be made or written is one error line."""
    try:
        return fn(*args)
    except OSError as exc:
        raise UserError("cannot write to %s: %s" % (out_dir, exc.strerror or exc)) from None


def run_csv(args):
    from hoverfly.logs.csvexport import write_csv

    log = _load(args)
    out = _out_dir(args, "_csv")
    paths = _writing(out, write_csv, log, out, args.topic)
    if not paths:
        raise UserError("%s: no topic to export%s" % (args.file, " (asked for: %s)" % ", ".join(args.topic)
                                                       if args.topic else ""))
    for p in paths:
        print(p)
    return 0


def run_plot(args):
    from hoverfly.logs.plot import NAMES, plot_all

    for n in args.only or ():
        if n not in NAMES:
            raise UserError("--only %s: no such plot (one of %s)" % (n, ", ".join(NAMES)))
    log = _load(args)
    out = _out_dir(args, "_plots")
    done = _writing(out, plot_all, log, out, args.only)
    if not done:
        raise UserError("%s: nothing to plot (no hoverfly/PX4 topics with data)" % args.file)
    for _, _, p in done:
        print(p)
    return 0


def run_report(args):
    from hoverfly.logs.report import write_report

    log = _load(args)
    out = _out_dir(args, "_report")
    r = _writing(out, write_report, log, out)
    print(r["index"])
    for st in r["steps"]:
        print("  " + step_line(st))
    if not r["steps"]:
        print("  no held stick step in the log: no step response measured")
    return 0


def run_replay(args):
    from hoverfly.cli_fly import _parse_set
    from hoverfly.logs.replay import plot_replay, replay

    overrides = _parse_set(args.set)
    log = _load(args)
    result = replay(log, overrides)
    for w in result.warnings:
        print("hoverfly: warning: %s" % w, file=sys.stderr)
    out = _out_dir(args, "_replay")
    paths = _writing(out, plot_replay, result, out, log.motor_count())
    d = result.to_dict()
    d["plots"] = paths
    d["steps"] = result.steps(log)
    d["open_loop"] = True
    if args.json:
        json.dump(d, sys.stdout)
        sys.stdout.write("\n")
        return 0
    changes = ", ".join("%s=%s" % (n, v) for n, v in overrides) or "the logged parameters"
    print("%s: replayed %d passes with %s" % (args.file, d["passes"], changes))
    print("  open loop: the craft moves as logged, whatever the new outputs would have done; the figures below "
          "are what the controller would have commanded")
    print("  %-14s %12s %12s %12s" % ("signal", "RMS logged", "RMS replay", "max |diff|"))
    for k in sorted(d["max_abs_diff"]):
        print("  %-14s %12.6f %12.6f %12.3g" % (k, d["rms_old"][k], d["rms_new"][k], d["max_abs_diff"][k]))
    for st in d["steps"]:
        print("  logged response, replayed set point: " + step_line(st))
    for p in paths:
        print(p)
    return 0


def register(sub):
    p = sub.add_parser("log", help="flight logs (ULog): info, params, csv, plot, report, replay")
    lsub = p.add_subparsers(dest="log_command", parser_class=type(p))

    def add(name, help_text, fn):
        q = lsub.add_parser(name, help=help_text)
        q.add_argument("file", metavar="FILE", help="a .ulg flight log")
        q.set_defaults(func=fn)
        return q

    q = add("info", "summary: system, duration, topics and rates, messages", run_info)
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q = add("params", "the logged parameters and their changes in flight", run_params)
    q.add_argument("--changed", action="store_true", help="only those that differ from the defaults")
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q = add("csv", "one CSV file per topic", run_csv)
    q.add_argument("--out", metavar="DIR", help="directory (default: FILE's name + _csv)")
    q.add_argument("--topic", action="append", metavar="NAME", help="only this topic (repeatable)")
    q = add("plot", "PNG plots", run_plot)
    q.add_argument("--out", metavar="DIR", help="directory (default: FILE's name + _plots)")
    q.add_argument("--only", action="append", metavar="NAME", help="only this plot (repeatable)")
    q = add("report", "all plots and step-response numbers with an index.html", run_report)
    q.add_argument("--out", metavar="DIR", help="directory (default: FILE's name + _report)")
    q = add("replay", "run the logged sensors and sticks through the controller with changed parameters",
            run_replay)
    q.add_argument("--set", action="append", metavar="NAME=VALUE", help="change a parameter for the replay")
    q.add_argument("--out", metavar="DIR", help="directory for the plots (default: FILE's name + _replay)")
    q.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])
