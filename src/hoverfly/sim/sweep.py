"""Many flights from one command: a scenario over seeds and grids, judged and summed up.

A sweep is the product of its seeds and its grid axes: parameter values (`p_roll=40:60:5`: from 40
to 60 in steps of 5; `a,b,c`: those values), a steady wind (m/s, from a direction drawn from the
seed, so a sweep over seeds covers the compass), the IMU noise scaled (1 = the airframe's figures)
and the battery's charge at take-off (%). Each flight is one job; a job's row depends only on the
job (the seed fixes the sensor noise and the wind's direction), so the rows, and every statistic
over them, are the same however many workers fly them and in whatever order they finish.

Runners: the local cores (a process pool, the default), or a Ray cluster (`ray_address`: "auto"
or host:port of a running cluster, or "local" for a Ray instance started on this machine). A
KeyboardInterrupt stops the sweep: flights not yet started are dropped and the rows done so far
come back with `interrupted` set. CPython only.
"""

import math
import os
import random
import time

from hoverfly.core.config.params import check
from hoverfly.errors import UserError

# Columns of a row, in order: the job, then what the flight did.
JOB_COLUMNS = ("job", "seed")
METRICS = (
    "crashed", "ended_armed", "tilt_rms_deg", "max_tilt_deg", "alt_min_m", "alt_max_m", "alt_final_m",
    "drift_m", "landed_from_takeoff_m", "rx_lost_s", "failsafe_landing_s", "disarmed_s",
    "rise_ms", "overshoot_pct", "settle_ms", "wall_s",
)
# Summed up per grid point as p50 / p95 / max (over the seeds); the rest as counts.
STAT_METRICS = ("tilt_rms_deg", "max_tilt_deg", "drift_m", "landed_from_takeoff_m", "alt_final_m",
                "failsafe_landing_s", "rise_ms", "overshoot_pct", "settle_ms")
GRID_WIND = "wind_m_s"
GRID_NOISE = "imu_noise_x"
GRID_BATTERY = "battery_pct"


def parse_values(text, what):
    """`lo:hi:step` (hi included) or `a,b,c` or one value -> list of numbers. UserError if not."""
    text = text.strip()
    try:
        if ":" in text:
            parts = text.split(":")
            if len(parts) != 3:
                raise ValueError
            lo, hi, step = (float(p) for p in parts)
            if not (step > 0 and hi >= lo and all(math.isfinite(x) for x in (lo, hi, step))):
                raise UserError("%s: %s needs lo <= hi and a step above 0" % (what, text))
            n = int(math.floor((hi - lo) / step + 1e-9)) + 1
            if n > 1000:
                raise UserError("%s: %s gives %d values (1000 at most)" % (what, text, n))
            vals = [lo + i * step for i in range(n)]
        else:
            vals = [float(p) for p in text.split(",") if p.strip()]
    except ValueError:
        raise UserError("%s: '%s' is not lo:hi:step or a list of numbers" % (what, text)) from None
    if not vals or not all(math.isfinite(v) for v in vals):
        raise UserError("%s: '%s' is not lo:hi:step or a list of numbers" % (what, text))
    return [int(v) if v == int(v) else round(v, 6) for v in vals]


def parse_set_grid(items):
    """[(param name, [values])] from `name=spec` items, every value checked against the table."""
    axes = []
    for item in items or ():
        if "=" not in item:
            raise UserError("--set expects name=lo:hi:step or name=a,b,c, got '%s'" % item)
        name, spec = (s.strip() for s in item.split("=", 1))
        vals = parse_values(spec, "--set " + name)
        key = None
        for v in vals:
            key, _, err = check(name, str(v))
            if err:
                raise UserError("--set %s: %s" % (name, err))
        axes.append((key, vals))
    return axes


def make_jobs(scenario, airframe, seeds, set_axes=(), wind=None, noise=None, battery=None, duration_s=None,
              first_seed=1):
    """Every flight of the sweep as a dict, in a fixed order (grid point, then seed)."""
    axes = list(set_axes)
    for name, vals in ((GRID_WIND, wind), (GRID_NOISE, noise), (GRID_BATTERY, battery)):
        if vals is not None:
            axes.append((name, vals))
    for name, vals in axes:
        if name == GRID_WIND and any(v < 0 or v > 30 for v in vals):
            raise UserError("--wind: speeds from 0 to 30 m/s")
        if name == GRID_NOISE and any(v < 0 or v > 100 for v in vals):
            raise UserError("--noise: a scale from 0 to 100")
        if name == GRID_BATTERY and any(v <= 0 or v > 100 for v in vals):
            raise UserError("--battery: a charge above 0 and up to 100 %")
    if seeds < 1:
        raise UserError("--seeds must be 1 or more")
    points = [{}]
    for name, vals in axes:
        points = [dict(p, **{name: v}) for p in points for v in vals]
    if len(points) * seeds > 1_000_000:
        raise UserError("%d flights: a million at most" % (len(points) * seeds))
    jobs = []
    for point in points:
        for s in range(first_seed, first_seed + seeds):
            jobs.append({"job": len(jobs), "scenario": scenario, "airframe": airframe, "seed": s,
                         "grid": point, "duration_s": duration_s})
    return jobs


def _first_event(events, name):
    for e in events:
        if e["event"] == name:
            return e["t_s"]
    return None


def _mean(xs):
    xs = [x for x in xs if x is not None]
    return round(sum(xs) / len(xs), 3) if xs else None


def fly_job(job):
    """Fly one job and return its row (a flat dict). Runs in a worker process."""
    from hoverfly.sim.airframes import load_airframe
    from hoverfly.sim.runner import SimRun
    from hoverfly.sim.scenario import load_scenario

    grid = job["grid"]
    airframe = load_airframe(job["airframe"]) if isinstance(job["airframe"], str) else dict(job["airframe"])
    scenario = load_scenario(job["scenario"]) if isinstance(job["scenario"], str) else dict(job["scenario"])
    if GRID_NOISE in grid:
        k = grid[GRID_NOISE]
        imu = dict(airframe["imu"])
        for key in ("gyro_noise_rad_s_rthz", "accel_noise_m_s2_rthz", "gyro_vibration_rad_s",
                    "accel_vibration_m_s2"):
            imu[key] = imu[key] * k
        airframe["imu"] = imu
    if grid.get(GRID_WIND):
        # the wind's direction from the seed: a sweep over seeds meets it from every side
        heading = random.Random(job["seed"] * 7919 + 17).uniform(0.0, 2.0 * math.pi)
        speed = grid[GRID_WIND]
        ev = {"t": 0.0, "wind": {"north_m_s": speed * math.cos(heading), "east_m_s": speed * math.sin(heading)}}
        scenario["events"] = [ev] + list(scenario["events"])
    overrides = [(k, v) for k, v in grid.items() if k not in (GRID_WIND, GRID_NOISE, GRID_BATTERY)]
    run = SimRun(airframe, scenario, job["seed"], overrides, job.get("duration_s"))
    if GRID_BATTERY in grid:
        bat = run.vehicle.battery
        bat.soc = grid[GRID_BATTERY] / 100.0
        bat.voltage_v = bat.ocv_v()
        run.pilot.hover_guess = run._hover_throttle_guess()
    t0 = time.perf_counter()
    r = run.run()
    v = run.vehicle
    events = r["events"]
    rx_lost = _first_event(events, "rx_lost")
    stage2 = _first_event(events, "failsafe_stage2")
    steps = r["steps"]
    row = {"job": job["job"], "seed": job["seed"]}
    row.update(grid)
    row.update({
        "crashed": bool(r["crashed"]),
        "ended_armed": bool(r["armed"]),
        "tilt_rms_deg": r["tilt_rms_deg"],
        "max_tilt_deg": r["max_tilt_deg"],
        "alt_min_m": r["altitude_m"]["min"],
        "alt_max_m": r["altitude_m"]["max"],
        "alt_final_m": r["altitude_m"]["final"],
        "drift_m": r["horizontal_drift_m"],
        # the craft takes off from the origin: where it ended up, from there
        "landed_from_takeoff_m": round(math.hypot(v.pn, v.pe), 3),
        "rx_lost_s": rx_lost,
        "failsafe_landing_s": stage2,
        "disarmed_s": _first_event(events, "disarmed"),
        "rise_ms": _mean(s["rise_ms"] for s in steps),
        "overshoot_pct": _mean(s["overshoot_pct"] for s in steps),
        "settle_ms": _mean(s["settle_ms"] for s in steps),
        "wall_s": round(time.perf_counter() - t0, 3),
    })
    return row


# ------------------------------------------------------------------ runners
def _progress_noop(done, total):
    return None


def _worker_ignores_ctrl_c():
    # Ctrl-C reaches every process of the terminal's group: the parent alone decides to stop (and ends
    # the workers), so no worker dies with a traceback of its own.
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


def run_local(jobs, workers, progress=_progress_noop):
    """Fly the jobs on `workers` local processes (1: in this process). Returns (rows, interrupted)."""
    rows = []
    if workers <= 1:
        try:
            for job in jobs:
                rows.append(fly_job(job))
                progress(len(rows), len(jobs))
        except KeyboardInterrupt:
            return rows, True
        return rows, False
    import multiprocessing

    # fork: a worker starts with hoverfly already imported (spawn costs each worker ~0.5 s of imports)
    ctx = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else None)
    interrupted = False
    # Leaving the with-block terminates the workers: on Ctrl-C the flights under way stop at once
    # (their rows are dropped) instead of holding the exit until they land.
    with ctx.Pool(workers, initializer=_worker_ignores_ctrl_c) as pool:
        try:
            for row in pool.imap_unordered(fly_job, jobs):
                rows.append(row)
                progress(len(rows), len(jobs))
        except KeyboardInterrupt:
            interrupted = True
    return rows, interrupted


def run_ray(jobs, address, progress=_progress_noop, num_cpus=None):
    """Fly the jobs as Ray tasks on the cluster at `address` ("local": start one here)."""
    try:
        import ray
    except ImportError:
        raise UserError("--ray needs Ray: pip install 'ray>=2.9'") from None
    kw = {"include_dashboard": False, "log_to_driver": False, "ignore_reinit_error": True}
    if address == "local":
        kw["num_cpus"] = num_cpus or os.cpu_count()
    else:
        kw["address"] = address
    try:
        ray.init(**kw)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise UserError("--ray %s: cannot reach the cluster (%s)" % (address, str(exc).splitlines()[0][:200])) \
            from None
    rows = []
    interrupted = False
    try:
        task = ray.remote(fly_job)
        pending = [task.remote(job) for job in jobs]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            rows.extend(ray.get(done))
            progress(len(rows), len(jobs))
    except KeyboardInterrupt:
        interrupted = True
        for ref in pending:
            ray.cancel(ref, force=True)
    finally:
        ray.shutdown()
    return rows, interrupted


# ------------------------------------------------------------------ results
def percentile(sorted_xs, pct):
    """Nearest-rank percentile of sorted numbers (an element of the data: exact, order-free)."""
    if not sorted_xs:
        return None
    k = max(0, min(len(sorted_xs) - 1, int(math.ceil(pct / 100.0 * len(sorted_xs))) - 1))
    return sorted_xs[k]


def grid_names(rows):
    names = []
    for r in rows:
        for k in r:
            if k not in JOB_COLUMNS and k not in METRICS and k not in names:
                names.append(k)
    return names


def summarise(rows):
    """Per grid point: flights, crashes, ended armed, and p50 / p95 / max of each STAT_METRICS."""
    rows = sorted(rows, key=lambda r: r["job"])
    names = grid_names(rows)
    groups = {}
    order = []
    for r in rows:
        key = tuple(r.get(n) for n in names)
        if key not in groups:
            groups[key] = []
            order.append(key)
        groups[key].append(r)
    out = []
    for key in order:
        g = groups[key]
        s = dict(zip(names, key, strict=True))
        s["flights"] = len(g)
        s["crashed"] = sum(1 for r in g if r["crashed"])
        s["ended_armed"] = sum(1 for r in g if r["ended_armed"])
        for m in STAT_METRICS:
            xs = sorted(r[m] for r in g if r.get(m) is not None)
            s[m] = {"n": len(xs), "p50": percentile(xs, 50), "p95": percentile(xs, 95),
                    "max": xs[-1] if xs else None, "mean": round(sum(xs) / len(xs), 4) if xs else None}
        out.append(s)
    return out


def write_csv(rows, path):
    import csv

    rows = sorted(rows, key=lambda r: r["job"])
    cols = list(JOB_COLUMNS) + grid_names(rows) + list(METRICS)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for r in rows:
            w.writerow(["" if r.get(c) is None else r.get(c) for c in cols])


def plot(rows, directory, scenario):
    """Distributions as PNGs in `directory`; returns the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = sorted(rows, key=lambda r: r["job"])
    names = grid_names(rows)
    os.makedirs(directory, exist_ok=True)
    paths = []
    label = {"landed_from_takeoff_m": "landed from take-off (m)", "drift_m": "largest drift from take-off (m)",
             "tilt_rms_deg": "tilt RMS (deg)", "rise_ms": "rise time 10-90 % (ms)",
             "overshoot_pct": "overshoot (%)", "settle_ms": "settling time (ms)",
             "failsafe_landing_s": "failsafe landing starts (s)"}
    for m in ("landed_from_takeoff_m", "drift_m", "tilt_rms_deg", "rise_ms", "overshoot_pct"):
        xs = sorted(r[m] for r in rows if r.get(m) is not None)
        if len(xs) < 2:
            continue
        fig, ax = plt.subplots(figsize=(7, 4))
        flown = [r[m] for r in rows if r.get(m) is not None and not r["crashed"]]
        crashed = [r[m] for r in rows if r.get(m) is not None and r["crashed"]]
        ax.hist([flown, crashed], bins=min(40, max(5, len(xs) // 5)), stacked=True, color=["#4477aa", "#cc3311"],
                label=["flights (%d)" % len(flown), "crashed (%d)" % len(crashed)])
        for pct, style in ((50, "-"), (95, "--")):
            v = percentile(xs, pct)
            ax.axvline(v, color="k", linestyle=style, label="p%d %.3g" % (pct, v))
        ax.axvline(xs[-1], color="r", linestyle=":", label="max %.3g" % xs[-1])
        ax.set_xlabel(label[m])
        ax.set_ylabel("flights")
        ax.set_title("%s: %d flights" % (scenario, len(xs)))
        ax.legend()
        fig.tight_layout()
        p = os.path.join(directory, "%s_hist.png" % m)
        fig.savefig(p, dpi=90)
        plt.close(fig)
        paths.append(p)
    for n in names:
        vals = sorted({r[n] for r in rows})
        if len(vals) < 2:
            continue
        for m in ("rise_ms", "overshoot_pct", "tilt_rms_deg", "landed_from_takeoff_m"):
            pts = [(r[n], r[m]) for r in rows if r.get(m) is not None]
            if len(pts) < 2:
                continue
            fig, ax = plt.subplots(figsize=(7, 4))
            ax.scatter([p[0] for p in pts], [p[1] for p in pts], s=10, alpha=0.5, color="#4477aa", label="flights")
            med = []
            for v in vals:
                ys = sorted(p[1] for p in pts if p[0] == v)
                if ys:
                    med.append((v, percentile(ys, 50)))
            ax.plot([p[0] for p in med], [p[1] for p in med], "k-o", label="p50")
            ax.set_xlabel(n)
            ax.set_ylabel(label[m])
            ax.set_title("%s: %s against %s" % (scenario, label[m], n))
            ax.legend()
            fig.tight_layout()
            p = os.path.join(directory, "%s_vs_%s.png" % (m, n))
            fig.savefig(p, dpi=90)
            plt.close(fig)
            paths.append(p)
    return paths
