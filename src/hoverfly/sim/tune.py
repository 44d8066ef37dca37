"""Automatic tuning in the simulator: rate and angle gains and filter cut-offs from an airframe file.

The search (Optuna's TPE sampler, seeded) proposes roll/pitch rate P, I, D and feed-forward (pitch
scaled from roll by the airframe's inertia ratio), the angle-mode gain and the gyro and D-term
low-pass cut-offs. Each proposal flies one tuning flight per training seed (TUNE_SCENARIO: a hover,
rate steps in acro, angle steps, then knocks on roll and pitch) and is scored on:
- steps: time to 90 %, overshoot and settling of the rate and the angle steps;
- disturbance: how far the knocks tilt the craft and how long it takes to come back (tilt
  integrated over the second after each knock);
- noise: how much the motor commands jitter in the quiet hover before the steps (what D and the
  filters let through to the motors; hot motors on a real craft).
A flight that crashes, tips over, loses height or ends disarmed makes the proposal unflyable.

The airframe's own [params] (its hand tune, or the defaults) are the first proposal, so the search
starts from them (or from the defaults: `start_from_hand=False`). The best proposals are then
flown on check seeds the search never saw; the first that flies every one of them is the result,
shown against the hand tune. If none does, or nothing the search tried could fly, tune() raises
UserError: never gains that crash.
CPython only.
"""

import os

from hoverfly.core.config.params import PARAMS, check
from hoverfly.core.links.cliserver import format_value
from hoverfly.errors import UserError
from hoverfly.sim.physics import G_M_S2

# The tuning flight: hover, rate steps, angle steps, knocks. Times in s.
TUNE_SCENARIO = """
name = "tune"
description = "hover, acro rate steps, angle steps, knocks: the flight the tuner scores"
duration_s = 13.2
mode = "angle"
[[at]]
t = 1.0
arm = true
[[at]]
t = 1.5
hold_altitude_m = 4.0
[[at]]
t = 4.5
mode = "acro"
[[at]]
t = 5.0
step = { axis = "roll", to = 400, unit = "dps" }
[[at]]
t = 5.3
step = { axis = "roll", to = -400, unit = "dps" }
[[at]]
t = 5.6
step = { axis = "roll", to = 0, unit = "dps" }
[[at]]
t = 6.2
step = { axis = "pitch", to = 400, unit = "dps" }
[[at]]
t = 6.5
step = { axis = "pitch", to = -400, unit = "dps" }
[[at]]
t = 6.8
step = { axis = "pitch", to = 0, unit = "dps" }
[[at]]
t = 7.4
mode = "angle"
[[at]]
t = 7.9
step = { axis = "roll", to = 30, unit = "deg" }
[[at]]
t = 8.7
step = { axis = "roll", to = 0, unit = "deg" }
[[at]]
t = 9.5
step = { axis = "pitch", to = 30, unit = "deg" }
[[at]]
t = 10.3
step = { axis = "pitch", to = 0, unit = "deg" }
[[at]]
t = 11.2
kick = { roll_dps = 300 }
[[at]]
t = 12.2
kick = { pitch_dps = 300 }
"""
NOISE_WINDOW_S = (3.0, 4.5)  # quiet hover: motor jitter measured here
KICKS_S = (11.2, 12.2)  # each knock judged over the second after it
RATE_WINDOW_MS = 300.0  # a rate step that never settles counts as this
ANGLE_WINDOW_MS = 800.0

# The search space, Betaflight scales: (parameter, low, high). Pitch follows roll (see _proposal).
SPACE = (
    ("p_roll", 15, 160),
    ("i_roll", 15, 160),
    ("d_roll", 5, 150),
    ("f_roll", 0, 500),
    ("angle_p_gain", 20, 200),
    ("gyro_lpf1_hz", 60, 500),
    ("dterm_lpf1_hz", 30, 250),
)
_PITCH_OF = {"p_roll": "p_pitch", "i_roll": "i_pitch", "d_roll": "d_pitch", "f_roll": "f_pitch"}

# Score: each metric over its scale, weighted (lower is better; the steps weigh most).
_SCORE = (  # metric, scale, weight
    ("rate_t90_ms", 50.0, 1.0),
    ("rate_overshoot_pct", 5.0, 1.0),
    ("rate_settle_ms", 100.0, 1.0),
    ("angle_t90_ms", 150.0, 1.0),
    ("angle_overshoot_pct", 5.0, 1.0),
    ("angle_settle_ms", 200.0, 1.0),
    ("kick_peak_deg", 20.0, 0.5),
    ("kick_tilt_deg_s", 5.0, 0.5),
    ("motor_jitter_pct", 0.5, 0.5),
)
UNFLYABLE = 1.0e6
_TABLE = {r[0]: r for r in PARAMS}


def check_airframe(airframe):
    """UserError if the airframe cannot hover with margin: nothing to tune."""
    from hoverfly.core.stages.mixer import MIXER_TABLES

    frame = airframe.get("frame", "quadx")
    if frame not in MIXER_TABLES:
        raise UserError("airframe %s: unknown frame %s" % (airframe["name"], frame))
    n = len(MIXER_TABLES[frame])
    b = airframe["battery"]
    omega_max = airframe["omega_per_volt"] * b["cells"] * 3.7
    thrust_n = n * airframe["kt"] * omega_max * omega_max
    tw = thrust_n / (airframe["mass_kg"] * G_M_S2)
    if tw < 1.3:
        raise UserError("airframe %s: thrust/weight %.2f at a loaded battery; it cannot hover with margin "
                        "(1.3 at least): nothing to tune" % (airframe["name"], tw))
    return tw


def _proposal(trial_or_values, airframe):
    """{param: value} for a proposal: Optuna's suggestions (or given roll values), pitch from roll."""
    vals = {}
    for name, lo, hi in SPACE:
        if isinstance(trial_or_values, dict):
            v = int(trial_or_values[name])
        else:
            v = trial_or_values.suggest_int(name, lo, hi)
        vals[name] = v
    ixx, iyy = airframe["inertia_kg_m2"][0], airframe["inertia_kg_m2"][1]
    ratio = iyy / ixx if ixx > 0 else 1.0
    for roll, pitch in _PITCH_OF.items():
        hi = _TABLE[pitch][3]
        vals[pitch] = int(min(hi, max(0, round(vals[roll] * ratio))))
    return vals


def hand_tune(airframe):
    """The airframe's own values (or the defaults) of the searched parameters."""
    from hoverfly.core.config.params import Params

    p = Params()
    for name, value in airframe.get("params", {}).items():
        p.set(name, value)
    return {name: p.get(name) for name, _lo, _hi in SPACE}


def fly_tune(airframe, values, seed):
    """One tuning flight: its metrics (a dict), 'unflyable' set with the reason when it is."""
    from hoverfly.sim.runner import SimRun
    from hoverfly.sim.scenario import parse_scenario

    scenario = parse_scenario(TUNE_SCENARIO, "tune")
    run = SimRun(airframe, scenario, seed, list(values.items()))
    v = run.vehicle
    cmd = run.board.motor_cmd
    n = len(cmd)
    dt = 1.0 / run.loop_hz
    w0, w1 = NOISE_WINDOW_S
    acc = {"jitter": 0.0, "jn": 0, "last": None, "peak": [0.0] * len(KICKS_S), "iae": [0.0] * len(KICKS_S)}

    def watch(r):
        t = r.board.sim_us * 1e-6
        if w0 <= t < w1:
            last = acc["last"]
            if last is not None:
                acc["jitter"] += sum(abs(cmd[i] - last[i]) for i in range(n))
                acc["jn"] += 1
            acc["last"] = list(cmd)
        for k, tk in enumerate(KICKS_S):
            if tk <= t < tk + 1.0:
                tilt = v.tilt_rad() * 57.29577951308232
                if tilt > acc["peak"][k]:
                    acc["peak"][k] = tilt
                acc["iae"][k] += tilt * dt

    run.on_step = watch
    try:
        r = run.run()
    except (ArithmeticError, ValueError) as exc:  # a diverging flight: unflyable, not a traceback
        return {"unflyable": "the flight diverged (%s)" % exc}
    m = {"unflyable": None}
    rate = [s for s in r["steps"] if s["mode"] == "rate"]
    angle = [s for s in r["steps"] if s["mode"] == "angle"]
    for key, steps, window in (("rate", rate, RATE_WINDOW_MS), ("angle", angle, ANGLE_WINDOW_MS)):
        m[key + "_t90_ms"] = _mean([window if s["t90_ms"] is None else s["t90_ms"] for s in steps], window)
        m[key + "_overshoot_pct"] = _mean([s["overshoot_pct"] for s in steps], 100.0)
        m[key + "_settle_ms"] = _mean([window if s["settle_ms"] is None else s["settle_ms"] for s in steps], window)
    m["kick_peak_deg"] = round(max(acc["peak"]), 2)
    m["kick_tilt_deg_s"] = round(sum(acc["iae"]) / len(KICKS_S), 3)
    m["motor_jitter_pct"] = round(100.0 * acc["jitter"] / max(1, acc["jn"]) / n, 4)
    m["alt_final_m"] = r["altitude_m"]["final"]
    if r["crashed"]:
        m["unflyable"] = "crashed"
    elif not r["armed"]:
        m["unflyable"] = "ended disarmed"
    elif r["altitude_m"]["final"] < 1.0:
        m["unflyable"] = "lost its height (%.1f m at the end)" % r["altitude_m"]["final"]
    elif m["kick_peak_deg"] > 75.0:
        m["unflyable"] = "a knock tipped it to %.0f deg" % m["kick_peak_deg"]
    elif len(rate) != 6 or len(angle) != 4 or any(s["t90_ms"] is None for s in rate + angle):
        m["unflyable"] = "did not follow the steps"
    return m


def _mean(xs, empty):
    return round(sum(xs) / len(xs), 3) if xs else empty


def score(metrics_list):
    """The proposal's score over its flights (mean of each metric); UNFLYABLE if any flight was."""
    for m in metrics_list:
        if m.get("unflyable"):
            return UNFLYABLE
    total = 0.0
    for key, scale, weight in _SCORE:
        total += weight * (sum(m[key] for m in metrics_list) / len(metrics_list)) / scale
    return round(total, 6)


def mean_metrics(metrics_list):
    keys = [k for k, _s, _w in _SCORE]
    return {k: round(sum(m[k] for m in metrics_list) / len(metrics_list), 3) for k in keys}


def _fly_job(job):
    airframe, values, seed = job
    return fly_tune(airframe, values, seed)


class _Flights:
    """Flies (airframe, values, seed) jobs: here, or on a pool of worker processes."""

    def __init__(self, workers):
        self.pool = None
        if workers > 1:
            import multiprocessing

            from hoverfly.sim.sweep import _worker_ignores_ctrl_c

            ctx = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods()
                                              else None)
            self.pool = ctx.Pool(workers, initializer=_worker_ignores_ctrl_c)

    def map(self, jobs):
        if self.pool is None:
            return [_fly_job(j) for j in jobs]
        return self.pool.map(_fly_job, jobs, chunksize=1)

    def close(self, wait=True):
        """End the workers: after the last flight, or at once on Ctrl-C (flights under way are dropped)."""
        if self.pool is not None:
            if wait:
                self.pool.close()
            else:
                self.pool.terminate()
            self.pool.join()


def tune(airframe, trials=40, train_seeds=(1, 2), check_seeds=(101, 102, 103), workers=1, sampler_seed=0,
         progress=None, candidates=5, start_from_hand=True):
    """Search, then check on unseen seeds. Returns a dict: values, hand, table rows, trials, interrupted.

    progress(done, total, best_score) after each proposal. On KeyboardInterrupt the search stops
    and the result says so (`interrupted`): the best so far, not yet checked, and no values."""
    import optuna

    check_airframe(airframe)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    sampler = optuna.samplers.TPESampler(seed=sampler_seed, n_startup_trials=min(10, max(1, trials // 3)),
                                         multivariate=True)
    study = optuna.create_study(direction="minimize", sampler=sampler)
    hand = hand_tune(airframe)
    # The first proposal: the hand tune, or (start_from_hand False) the defaults, so a search can show
    # what it finds from the airframe's physics alone.
    first = hand if start_from_hand else hand_tune({"params": {}})
    study.enqueue_trial({name: min(hi, max(lo, first[name])) for name, lo, hi in SPACE})
    flights = _Flights(workers)
    batch = max(1, workers // max(1, len(train_seeds)))
    done = 0
    interrupted = False
    history = []
    try:
        while done < trials:
            asked = [study.ask() for _ in range(min(batch, trials - done))]
            props = [_proposal(t, airframe) for t in asked]
            jobs = [(airframe, p, s) for p in props for s in train_seeds]
            results = flights.map(jobs)
            k = len(train_seeds)
            for i, t in enumerate(asked):
                ms = results[i * k:(i + 1) * k]
                sc = score(ms)
                why = next((m["unflyable"] for m in ms if m.get("unflyable")), None)
                t.set_user_attr("unflyable", why)
                study.tell(t, sc)
                history.append({"trial": t.number, "score": sc, "unflyable": why, "values": props[i]})
                done += 1
                if progress is not None:
                    progress(done, trials, study.best_value)
        ranked = sorted((h for h in history if h["score"] < UNFLYABLE), key=lambda h: (h["score"], h["trial"]))
        if not ranked:
            reasons = sorted({h["unflyable"] for h in history if h["unflyable"]})
            raise UserError("nothing the search tried could fly the tuning flight (%s): no gains to give"
                            % "; ".join(reasons[:3]))
        hand_props = _proposal(hand, airframe)
        hand_check = flights.map([(airframe, hand_props, s) for s in check_seeds])
        chosen = None
        rejected = []
        for h in ranked[:candidates]:
            ms = flights.map([(airframe, h["values"], s) for s in check_seeds])
            why = next((m["unflyable"] for m in ms if m.get("unflyable")), None)
            if why is None:
                chosen = (h, ms)
                break
            rejected.append((h["trial"], why))
        if chosen is None:
            raise UserError("the best %d gains found did not fly every check seed (%s): no gains to give"
                            % (len(rejected), "; ".join("trial %d %s" % r for r in rejected)))
    except KeyboardInterrupt:
        interrupted = True
    finally:
        flights.close(wait=not interrupted)
    if interrupted:
        best = None
        ok = [h for h in history if h["score"] < UNFLYABLE]
        if ok:
            best = min(ok, key=lambda h: (h["score"], h["trial"]))
        return {"interrupted": True, "trials": len(history), "best": best, "values": None}
    h, ms = chosen
    hand_ok = not any(m.get("unflyable") for m in hand_check)
    return {
        "interrupted": False,
        "trials": len(history),
        "unflyable_trials": sum(1 for x in history if x["unflyable"]),
        "best_trial": h["trial"],
        "train_score": h["score"],
        "values": h["values"],
        "hand": hand_props,
        "check_seeds": list(check_seeds),
        "train_seeds": list(train_seeds),
        "tuned_check": mean_metrics(ms),
        "tuned_check_score": score(ms),
        "hand_check": mean_metrics(hand_check) if hand_ok else None,
        "hand_check_score": score(hand_check),
        "hand_unflyable": None if hand_ok else next(m["unflyable"] for m in hand_check if m.get("unflyable")),
        "rejected": rejected,
    }


def diff_lines(airframe, values, note=()):
    """A Betaflight-style `diff all` for the airframe's parameters with `values` on top: what
    `hoverfly params restore FILE` applies (unlisted names go back to their defaults)."""
    from hoverfly import __version__
    from hoverfly.sim.runner import build_params

    params = build_params(airframe, {"params": {}}, [(k, format_value(v)) for k, v in values.items()])
    out = ["# diff all", "", "# version", "# hoverfly %s / tuned in the simulator" % __version__]
    out.extend("# " + line for line in note)
    out.extend(["", "batch start", "", "# master"])
    for name, v in params.diff():
        out.append("set %s = %s" % (name, format_value(v)))
    out.extend(["", "batch end", "", "save"])
    return out


def check_values(values):
    """Every value through the parameter table's check (the diff must restore as it is)."""
    for name, v in values.items():
        _key, _v, err = check(name, str(v))
        if err:
            raise UserError("tuned %s: %s" % (name, err))


def default_out_path(airframe):
    return os.path.join(os.getcwd(), "%s-tune.txt" % airframe["name"])
