"""Simulator real-time factor: the 5-inch hover at a 1 kHz loop, wire, ESCs and IMU noise included.

Prints one JSON object:
- realtime_factor (simulated s per wall s of the flight loop, best of --runs), realtime_factor_cpu
  (per CPU s of this process: steadier when other work shares the host), steps_per_s, setup_s (making
  the flight: airframe, parameters, the IMU's noise table; it counts in a sweep of short flights);
- shares_pct (and us_per_step): where one flight's time goes, each part timed around its own calls in a
  separate run (the timer's own cost taken off): the flight core (Flight.step without the board's wire models),
  physics, IMU model, receiver wire, ESC model (DShot decode), pilot, and the runner's loop and judging;
- profile_shares_pct: the same flight under cProfile, its own time per area (cProfile adds a fixed cost
  per call, so it overstates areas made of many small calls: the timed shares are the measure); only when
  the flight ran on the .py files (--python, or no twins built): cProfile does not see into compiled code.

    .venv/bin/python bench/sim_rtf.py [--scenario hover] [--airframe 5inch] [--runs 3] [--no-profile]
    .venv/bin/python bench/sim_rtf.py --firmware micropython [--duration 6]
    .venv/bin/python bench/sim_rtf.py --bridge   # both: the bridged flight's figures under "bridge"
    .venv/bin/python bench/sim_rtf.py --airframe trainer   # a plane (bank-steps): JSBSim and the fixed-wing core
    .venv/bin/python bench/sim_rtf.py --airframe trainer --plane-side   # a plane: JSBSim + IMU model only
    .venv/bin/python bench/sim_rtf.py --python    # on the .py files alone (HOVERFLY_NATIVE=0)

A flight runs on hoverfly/native.py's compiled twins wherever they are built and current (`./dev` builds them; by
hand: python -m hoverfly.native build), as `hoverfly fly` does: that is the default path. native_modules says how
many of native.MODULES ran compiled (0: all from their .py files); --python measures the .py files alone.

With --firmware micropython the flight core runs in a MicroPython process over the lockstep bridge
(sim/bridge.py): then the JSON gives the real-time factor and, per step, the CPU time of this process
(physics, wire models, the bridge's host end) and of the firmware process (its pass, the bridge's
firmware end, its start-up spread over the flight), and the firmware's own pass time. The two
processes take turns, so the step costs about their sum plus two pipe wake-ups; sim/bridge.py keeps
both on one CPU, where a wake-up is a plain switch (HOVERFLY_BRIDGE_SAME_CPU=0 leaves them to the
scheduler, and each wake-up then crosses CPUs). The figure follows the host's load (load_avg_1min).
"""

import argparse
import cProfile
import json
import os
import pstats
import sys
import time

if "--python" in sys.argv:  # before hoverfly is imported: it installs the twins' finder at import
    os.environ["HOVERFLY_NATIVE"] = "0"
elif "--native" in sys.argv:
    os.environ["HOVERFLY_NATIVE"] = "1"

from hoverfly import native  # noqa: E402
from hoverfly.sim.airframes import load_airframe  # noqa: E402
from hoverfly.sim.runner import SimRun, fly  # noqa: E402

_AREAS = (  # path part -> area, first match wins
    ("/core/", "flight core"),
    ("/protocols/dshot", "flight core"),  # the core's output codec; the ESC's decode is in sim/esc.py
    ("/protocols/rxcodec", "flight core"),  # the core's receiver parsing
    ("/protocols/crsf", "receiver wire"),
    ("/compat", "flight core"),
    ("/sim/physics", "physics"),
    ("/sim/sensors", "imu model"),
    ("/sim/rxlink", "receiver wire"),
    ("/sim/esc", "esc model"),
    ("/sim/board", "esc model"),
    ("/sim/pilot", "pilot"),
    ("/sim/runner", "runner loop and judging"),
)


def _area(filename, name):
    for part, area in _AREAS:
        if part in filename:
            return area
    if filename == "~":
        return "builtins"
    return "other"


def profile_shares(scenario, airframe):
    prof = cProfile.Profile()
    prof.enable()
    fly(scenario, airframe, seed=1)
    prof.disable()
    totals = {}
    for (filename, _line, name), (_cc, _nc, tottime, _ct, _callers) in pstats.Stats(prof).stats.items():
        a = _area(filename, name)
        totals[a] = totals.get(a, 0.0) + tottime
    whole = sum(totals.values()) or 1.0
    return {a: round(100.0 * t / whole, 1) for a, t in sorted(totals.items(), key=lambda x: -x[1])}


def timed_shares(scenario, airframe):
    """One flight with a timer around each part's calls; the timer's own cost measured and removed."""
    perf = time.perf_counter
    acc = {}
    calls = {}

    def wrap(obj, name, key):
        f = getattr(obj, name)

        def timed(*a):
            t0 = perf()
            r = f(*a)
            acc[key] = acc.get(key, 0.0) + perf() - t0
            calls[key] = calls.get(key, 0) + 1
            return r

        setattr(obj, name, timed)

    class _Probe:
        def nothing(self):
            return None

    probe = _Probe()
    wrap(probe, "nothing", "probe")
    for _ in range(50000):
        probe.nothing()
    cost = acc.pop("probe") / calls.pop("probe")

    run = SimRun(airframe, scenario, 1)
    b = run.board
    wrap(run.flight, "step", "flight.step")
    wrap(b, "_send_lines", "esc model")
    wrap(b.rx_link, "advance", "receiver wire")
    wrap(b.rx_link, "take_bytes", "receiver wire")
    wrap(run.vehicle, "step", "physics")
    wrap(run.vehicle, "euler_rad", "pilot")  # the attitude the pilot sees
    wrap(run.imu, "sample", "imu model")
    wrap(run.pilot, "update", "pilot")
    t0 = perf()
    r = run.run()
    whole = perf() - t0
    net = {k: acc[k] - cost * calls[k] for k in acc}
    # the wire models run inside Flight.step (the board's read_rx / write_motors)
    net["flight core"] = net.pop("flight.step") - net["esc model"] - net["receiver wire"]
    timed = sum(net.values())
    net["runner loop and judging"] = whole - timed - cost * sum(calls.values())
    steps = round(r["sim_time_s"] * r["loop_hz"])
    return ({k: round(100.0 * v / whole, 1) for k, v in sorted(net.items(), key=lambda x: -x[1])},
            {k: round(v / steps * 1e6, 2) for k, v in sorted(net.items(), key=lambda x: -x[1])})


def bridge(args, duration_s=None):
    """The bridged flight's figures, best of --runs."""
    import resource

    best = None
    for _ in range(args.runs):
        c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        s0 = resource.getrusage(resource.RUSAGE_SELF)
        r = fly(args.scenario, args.airframe, seed=1, duration_s=duration_s or args.duration, firmware="micropython")
        c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        s1 = resource.getrusage(resource.RUSAGE_SELF)
        steps = r["firmware"]["steps"]
        out = {
            "airframe": r["airframe"], "scenario": r["scenario"], "firmware": "micropython",
            "sim_time_s": r["sim_time_s"], "wall_time_s": r["wall_time_s"], "realtime_factor": r["realtime_factor"],
            "host_cpu_us_per_step": round((s1.ru_utime - s0.ru_utime + s1.ru_stime - s0.ru_stime) / steps * 1e6, 1),
            "firmware_cpu_us_per_step": round((c1.ru_utime - c0.ru_utime + c1.ru_stime - c0.ru_stime) / steps * 1e6,
                                              1),
            "firmware_pass_mean_us": r["firmware"]["pass_mean_us"],
            "native_modules": len(native.report().get("native", ())),
            "load_avg_1min": round(os.getloadavg()[0], 2),  # a bridged step follows the host's load (below)
        }
        if best is None or out["realtime_factor"] > best["realtime_factor"]:
            best = out
    return best


def plane_side(args):
    """A plane (issue 23): the simulator's side of each lockstep step, JSBSim physics and the IMU
    model, at a 1 kHz loop, with the aileron stepping every second, no flight core (--plane-side; without it a
    plane flies its scenario through SimRun with the fixed-wing core, as the quads do)."""
    from hoverfly.sim.plane import Plane
    from hoverfly.sim.sensors import ImuModel

    af = load_airframe(args.airframe)
    duration_s = args.duration or 10.0
    best = None
    for _ in range(args.runs):
        plane = Plane(af, 1000)
        plane.reset(altitude_m=200.0, airspeed_m_s=13.0)
        imu = ImuModel(af["imu"], 1, 1000, plane.hover_omega(), 1)
        gyro = [0.0] * 3
        accel = [0.0] * 3
        n = int(duration_s * 1000)
        w0 = time.perf_counter()
        c0 = time.process_time()
        for k in range(n):
            plane.servo_pos[0] = 0.3 if (k // 1000) % 2 else -0.3
            plane.step(0.001, (0.3,))
            imu.sample(plane, gyro, accel)
        wall = time.perf_counter() - w0
        cpu = time.process_time() - c0
        r = {"airframe": af["name"], "loop_hz": 1000, "sim_time_s": duration_s,
             "realtime_factor": round(duration_s / wall, 1), "realtime_factor_cpu": round(duration_s / cpu, 1),
             "us_per_step_cpu": round(cpu / n * 1e6, 2), "flight_core_included": False}
        if best is None or r["realtime_factor_cpu"] > best["realtime_factor_cpu"]:
            best = r
    print(json.dumps(best))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenario", default=None, help="default: hover, bank-steps for a plane")
    ap.add_argument("--airframe", default="5inch")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--no-profile", action="store_true")
    ap.add_argument("--firmware", choices=("cpython", "micropython"), default="cpython")
    ap.add_argument("--duration", type=float, default=None, help="seconds to fly (default: the scenario's)")
    ap.add_argument("--python", action="store_true", help="the flight on the .py files alone, not on "
                    "hoverfly.native's compiled twins (as HOVERFLY_NATIVE=0)")
    ap.add_argument("--native", action="store_true", help="look for the twins even where none were ever built "
                    "(as HOVERFLY_NATIVE=1; the default uses them wherever built)")
    ap.add_argument("--bridge", action="store_true",
                    help="also fly 6 s over the firmware bridge (MicroPython) and add its figures as 'bridge'")
    ap.add_argument("--plane-side", action="store_true", help="a plane: the simulator's side alone (JSBSim, IMU)")
    args = ap.parse_args()
    plane = load_airframe(args.airframe).get("kind") == "plane"
    if args.scenario is None:
        args.scenario = "bank-steps" if plane else "hover"
    if args.firmware == "micropython":
        print(json.dumps(bridge(args)))
        return
    if plane and args.plane_side:
        plane_side(args)
        return
    best = None
    best_cpu = 0.0
    setup_s = 1e9
    for _ in range(args.runs):
        w0 = time.perf_counter()
        run = SimRun(args.airframe, args.scenario, 1)
        setup_s = min(setup_s, time.perf_counter() - w0)
        c0 = time.process_time()
        r = run.run()
        cpu = time.process_time() - c0
        best_cpu = max(best_cpu, r["sim_time_s"] / cpu)
        if best is None or r["realtime_factor"] > best["realtime_factor"]:
            best = r
    shares, us_per_step = timed_shares(args.scenario, args.airframe)
    out = {
        "airframe": best["airframe"], "scenario": best["scenario"], "loop_hz": best["loop_hz"],
        "sim_time_s": best["sim_time_s"], "wall_time_s": best["wall_time_s"],
        "realtime_factor": best["realtime_factor"],
        "realtime_factor_cpu": round(best_cpu, 2),
        "steps_per_s": round(best["sim_time_s"] * best["loop_hz"] / best["wall_time_s"]),
        "core_us_per_pass": best["loop"]["mean_us"],
        "setup_s": round(setup_s, 3),  # airframe, parameters, the IMU's noise table: once per flight
        "native_modules": len(native.report().get("native", ())),
        "shares_pct": shares,
        "us_per_step": us_per_step,
    }
    if args.bridge:
        out["bridge"] = bridge(args, 6.0)
    if not args.no_profile and not out["native_modules"]:  # cProfile does not see into compiled modules
        out["profile_shares_pct"] = profile_shares(args.scenario, args.airframe)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
