"""`hoverfly sweep`: fly a scenario over many seeds and grids, in parallel, and sum the flights up."""

import json
import os
import sys
import time

from hoverfly.errors import UserError


def _fmt(v):
    if v is None:
        return "-"
    if isinstance(v, float):
        return "%.3g" % (v + 0.0)  # + 0.0: a -0.0 reads as 0
    return str(v)


def print_table(summary, scenario, wall_s, flights, workers_text, interrupted, file=None):
    from rich.console import Console
    from rich.table import Table

    from hoverfly.sim.sweep import STAT_METRICS, grid_names

    console = Console(file=file or sys.stdout, width=200)
    names = grid_names(summary and [{k: v for k, v in s.items() if not isinstance(v, dict)
                                     and k not in ("flights", "crashed", "ended_armed")} for s in summary] or [])
    shown = [m for m in STAT_METRICS if any(s[m]["n"] for s in summary)]
    table = Table(title="%s: %d flights in %.1f s (%s)%s" % (scenario, flights, wall_s, workers_text,
                                                              ", INTERRUPTED: the flights done so far"
                                                              if interrupted else ""))
    for n in names:
        table.add_column(n, justify="right")
    table.add_column("flights", justify="right")
    table.add_column("crashed", justify="right")
    table.add_column("ended armed", justify="right")
    for m in shown:
        table.add_column(m + "\np50 / p95 / max", justify="right")
    for s in summary:
        cells = [_fmt(s[n]) for n in names] + [str(s["flights"]), str(s["crashed"]), str(s["ended_armed"])]
        for m in shown:
            st = s[m]
            cells.append("%s / %s / %s" % (_fmt(st["p50"]), _fmt(st["p95"]), _fmt(st["max"])) if st["n"] else "-")
        table.add_row(*cells)
    console.print(table)


def run_sweep(args):
    from hoverfly.sim import sweep
    from hoverfly.sim.airframes import load_airframe
    from hoverfly.sim.scenario import load_scenario

    load_scenario(args.scenario)  # a bad name or file: one error line before any worker starts
    load_airframe(args.airframe)
    if args.duration is not None and not (0 < args.duration <= 3600):
        raise UserError("--duration must be between 0 and 3600 s")
    if args.workers is not None and not (1 <= args.workers <= 512):
        raise UserError("--workers: 1 to 512")
    jobs = sweep.make_jobs(
        args.scenario, args.airframe, args.seeds, sweep.parse_set_grid(args.set),
        wind=sweep.parse_values(args.wind, "--wind") if args.wind else None,
        noise=sweep.parse_values(args.noise, "--noise") if args.noise else None,
        battery=sweep.parse_values(args.battery, "--battery") if args.battery else None,
        duration_s=args.duration, first_seed=args.first_seed)
    for path in (args.csv, args.json):
        if path and os.path.dirname(path) and not os.path.isdir(os.path.dirname(path)):
            raise UserError("no directory for %s" % path)
    workers = args.workers or os.cpu_count() or 1
    progress, stop_progress = _progress(len(jobs), args.quiet)
    t0 = time.perf_counter()
    try:
        if args.ray:
            rows, interrupted = sweep.run_ray(jobs, args.ray, progress, num_cpus=args.workers)
            workers_text = "Ray at %s" % args.ray
        else:
            rows, interrupted = sweep.run_local(jobs, workers, progress)
            workers_text = "%d worker%s" % (workers, "" if workers == 1 else "s")
    finally:
        stop_progress()
    wall = time.perf_counter() - t0
    rows.sort(key=lambda r: r["job"])
    summary = sweep.summarise(rows)
    name = os.path.splitext(os.path.basename(args.scenario))[0]
    if args.csv:
        sweep.write_csv(rows, args.csv)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump({"scenario": name, "airframe": args.airframe, "flights": len(rows), "planned": len(jobs),
                       "interrupted": interrupted, "wall_s": round(wall, 3), "runner": workers_text,
                       "summary": summary, "rows": rows}, fh, indent=1)
    plots = sweep.plot(rows, args.plot, name) if args.plot else []
    print_table(summary, name, wall, len(rows), workers_text, interrupted)
    if interrupted:
        print("stopped: %d of %d flights done" % (len(rows), len(jobs)))
    for p in plots:
        print("plot: %s" % p)
    return 130 if interrupted else 0


def _progress(total, quiet):
    """(callback(done, total), stop()) drawing a rich progress bar on stderr; no thread (the pool forks)."""
    if quiet or not sys.stderr.isatty():
        return (lambda done, total: None), (lambda: None)
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn, TimeRemainingColumn

    bar = Progress("flights", BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(), TimeRemainingColumn(),
                   auto_refresh=False, transient=True)
    task = bar.add_task("flights", total=total)
    bar.start()

    def update(done, total):
        bar.update(task, completed=done)
        bar.refresh()

    return update, bar.stop


def register(sub):
    p = sub.add_parser("sweep", help="fly a scenario over many seeds and parameter grids, in parallel")
    p.add_argument("scenario", help="built-in scenario name or a .toml file")
    p.add_argument("--airframe", default="5inch", help="built-in airframe name or a .toml file")
    p.add_argument("--seeds", type=int, default=10, help="seeds per grid point (default 10)")
    p.add_argument("--first-seed", type=int, default=1, help="the first seed (default 1)")
    p.add_argument("--set", action="append", metavar="NAME=LO:HI:STEP",
                   help="a parameter grid: lo:hi:step (hi included) or a,b,c; repeat for more axes")
    p.add_argument("--wind", metavar="M_S", help="steady wind speeds (m/s; direction from the seed): lo:hi:step or a,b")
    p.add_argument("--noise", metavar="X", help="IMU noise and vibration scale (1 = the airframe's): lo:hi:step or a,b")
    p.add_argument("--battery", metavar="PCT", help="battery charge at take-off (%%): lo:hi:step or a,b")
    p.add_argument("--duration", type=float, default=None, help="seconds to fly (default: the scenario's)")
    p.add_argument("--workers", type=int, default=None, help="local worker processes (default: one per core)")
    p.add_argument("--ray", metavar="ADDRESS", default=None,
                   help="run on a Ray cluster: 'auto', host:port, or 'local' to start Ray on this machine")
    p.add_argument("--csv", metavar="FILE", help="write every flight's row as CSV")
    p.add_argument("--json", metavar="FILE", help="write the rows and the summary as JSON")
    p.add_argument("--plot", metavar="DIR", help="write distribution plots (PNG) into DIR")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run_sweep)
