"""`hoverfly tune --airframe FILE`: find rate and angle gains in the simulator; print and save a diff."""

import os
import sys

from hoverfly.errors import UserError

_ROWS = (  # metric, label, lower is better
    ("rate_t90_ms", "rate step: 90 % at (ms)"),
    ("rate_overshoot_pct", "rate step: overshoot (%)"),
    ("rate_settle_ms", "rate step: settled at (ms)"),
    ("angle_t90_ms", "angle step: 90 % at (ms)"),
    ("angle_overshoot_pct", "angle step: overshoot (%)"),
    ("angle_settle_ms", "angle step: settled at (ms)"),
    ("kick_peak_deg", "knock: largest tilt (deg)"),
    ("kick_tilt_deg_s", "knock: tilt over 1 s (deg s)"),
    ("motor_jitter_pct", "hover: motor jitter (% per pass)"),
)


def comparison_table(result):
    """[(label, hand, tuned)] rows of the check on unseen seeds, and the scores."""
    hand = result["hand_check"]
    tuned = result["tuned_check"]
    rows = []
    for key, label in _ROWS:
        rows.append((label, "-" if hand is None else "%g" % hand[key], "%g" % tuned[key]))
    rows.append(("score (lower is better)", "%g" % result["hand_check_score"] if hand else "unflyable",
                 "%g" % result["tuned_check_score"]))
    return rows


def _print_comparison(result, airframe_name):
    from rich.console import Console
    from rich.table import Table

    print("%s: the hand tune against the tuned gains on check seeds %s (not tuned on), %d trials"
          % (airframe_name, ", ".join(str(s) for s in result["check_seeds"]), result["trials"]))
    t = Table()
    t.add_column("")
    t.add_column("hand tune", justify="right")
    t.add_column("tuned", justify="right")
    for row in comparison_table(result):
        t.add_row(*row)
    Console(file=sys.stdout, width=120).print(t)


def run_tune(args):
    from hoverfly.sim import tune
    from hoverfly.sim.airframes import load_airframe

    airframe = load_airframe(args.airframe)
    if not (1 <= args.trials <= 10000):
        raise UserError("--trials: 1 to 10000")
    if args.workers is not None and not (1 <= args.workers <= 512):
        raise UserError("--workers: 1 to 512")
    if args.seeds < 1 or args.check_seeds < 1:
        raise UserError("--seeds and --check-seeds: 1 or more")
    out = args.out or tune.default_out_path(airframe)
    if os.path.dirname(out) and not os.path.isdir(os.path.dirname(out)):
        raise UserError("no directory for %s" % out)
    train = tuple(range(1, 1 + args.seeds))
    check = tuple(range(1001, 1001 + args.check_seeds))  # never among the training seeds
    workers = args.workers or os.cpu_count() or 1
    progress, stop = _progress(args.trials, args.quiet)
    try:
        result = tune.tune(airframe, trials=args.trials, train_seeds=train, check_seeds=check, workers=workers,
                           sampler_seed=args.sampler_seed, progress=progress,
                           start_from_hand=not args.from_defaults)
    finally:
        stop()
    if result["interrupted"]:
        best = result["best"]
        print("stopped after %d trials; not checked on unseen seeds, so no diff saved" % result["trials"])
        if best is not None:
            print("best so far (trial %d, score %g): %s" % (best["trial"], best["score"], " ".join(
                "%s=%s" % kv for kv in best["values"].items())))
        return 130
    values = result["values"]
    tune.check_values(values)
    note = ["%d trials on seeds %s; checked on seeds %s" % (result["trials"], ", ".join(map(str, train)),
                                                              ", ".join(map(str, check)))]
    lines = tune.diff_lines(airframe, values, note)
    try:
        with open(out, "w", encoding="utf-8") as fh:
            fh.write("\n".join(lines) + "\n")
    except OSError as exc:
        raise UserError("cannot write %s: %s" % (out, exc.strerror or exc)) from None
    _print_comparison(result, airframe["name"])
    print("\n".join(lines))
    print("saved: %s   (apply: hoverfly params restore %s --port URL)" % (out, out))
    return 0


def _progress(total, quiet):
    if quiet or not sys.stderr.isatty():
        return None, (lambda: None)
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    bar = Progress("trials", BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                   TextColumn("best {task.fields[best]}"), auto_refresh=False, transient=True)
    task = bar.add_task("trials", total=total, best="-")
    bar.start()

    def update(done, total, best):
        bar.update(task, completed=done, best="%.3g" % best)
        bar.refresh()

    return update, bar.stop


def register(sub):
    p = sub.add_parser("tune", help="tune rate and angle gains and filters in the simulator; saves a diff")
    p.add_argument("--airframe", required=True, help="built-in airframe name or a .toml file")
    p.add_argument("--trials", type=int, default=40, help="proposals the search flies (default 40)")
    p.add_argument("--seeds", type=int, default=2, help="training seeds per proposal (default 2)")
    p.add_argument("--check-seeds", type=int, default=3, help="unseen seeds the result is checked on (default 3)")
    p.add_argument("--workers", type=int, default=None, help="local worker processes (default: one per core)")
    p.add_argument("--sampler-seed", type=int, default=0, help="the search's own seed (default 0)")
    p.add_argument("--from-defaults", action="store_true",
                   help="start the search from the default gains, not the airframe's [params]")
    p.add_argument("--out", metavar="FILE", help="where to save the diff (default: AIRFRAME-tune.txt here)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run_tune)
