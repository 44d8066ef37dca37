"""The fixed-wing models' flying qualities, measured open-loop in JSBSim beside the figures they should match.

Prints one JSON object per airframe (trainer, wing): trim speed (power off, elevator centred), best
glide ratio and its speed (a sweep of fixed elevator settings), the power-off stall (CLmax reached
as the elevator is eased back, the 1 g stall speed it gives, the lowest airspeed seen), the roll rate
at full aileron from wings level at cruise, the climb at a fixed throttle, the physics' CPU cost per step
at 1 kHz (process time); and `expected`: the ranges such airplanes show, with where each comes from.

    .venv/bin/python bench/plane_model.py [--airframe trainer|wing|FILE] [--loop-hz 1000]
"""

import argparse
import json
import time

from hoverfly.sim import plane as P
from hoverfly.sim.airframes import load_airframe

# Ranges for the class (see docs/fixed-wing.md "Simulator" and the models' XML comments). Stall and
# glide from V_s = sqrt(2W / (rho S CLmax)) and (L/D)max = 0.5 sqrt(pi e AR / CD0) with class-typical
# inputs (Anderson; Raymer; Selig's UIUC low-speed airfoil data); roll rates from p = -(Cl_da da /
# Cl_p) 2V/b and INAV's fixed-wing tuning wiki (agile planes about 360 deg/s, trainers slower).
EXPECTED = {
    "trainer": {"cruise_m_s": [12.0, 15.0], "stall_speed_m_s": [6.5, 8.5], "glide_ratio": [8.0, 12.0],
                "roll_rate_dps": [120.0, 240.0], "cruise_speed": 13.0},
    "wing": {"cruise_m_s": [15.0, 20.0], "stall_speed_m_s": [7.0, 9.5], "glide_ratio": [6.0, 10.0],
             "roll_rate_dps": [200.0, 360.0], "cruise_speed": 16.0},
}


def measure(name, loop_hz):
    plane = P.Plane(load_airframe(name), loop_hz)
    cruise = EXPECTED.get(name, EXPECTED["trainer"])["cruise_speed"]
    trim = P.glide(plane)
    glides = [(P.glide(plane, elevator=e), e) for e in (-0.05, -0.1, -0.15, -0.2, -0.25)]
    best, best_e = max(glides, key=lambda g: g[0]["glide_ratio"])
    stall = P.stall(plane)
    roll = P.roll_rate(plane, cruise)
    climb = P.level_flight(plane, cruise, 0.5)
    plane.reset(altitude_m=300.0, airspeed_m_s=cruise)
    n = 5000
    t0 = time.process_time()  # CPU time: steadier than the wall clock on a shared host
    for _ in range(n):
        plane.step(plane.dt_s, (0.1,))
    step_us = (time.process_time() - t0) / n * 1e6
    r = {
        "airframe": name,
        "loop_hz": loop_hz,
        "trim_speed_m_s": round(trim["airspeed_m_s"], 2),
        "trim_glide_ratio": round(trim["glide_ratio"], 2),
        "best_glide_ratio": round(best["glide_ratio"], 2),
        "best_glide_speed_m_s": round(best["airspeed_m_s"], 2),
        "best_glide_elevator": best_e,
        "min_sink_m_s": round(min(g[0]["sink_m_s"] for g in glides), 2),
        "cl_max": round(stall["cl_max"], 3),
        "stall_alpha_deg": round(stall["alpha_deg"], 1),
        "stall_speed_m_s": round(stall["stall_speed_m_s"], 2),
        "stall_min_airspeed_m_s": round(stall["min_airspeed_m_s"], 2),
        "roll_rate_dps": round(roll["roll_rate_dps"], 1),
        "peak_roll_rate_dps": round(roll["peak_roll_rate_dps"], 1),
        "roll_at_m_s": cruise,
        "climb_m_s_at_half_throttle": round(climb["climb_m_s"], 2),
        "physics_step_us": round(step_us, 2),
        "physics_realtime_factor": round(1e6 / loop_hz / step_us, 1),
    }
    if name in EXPECTED:
        r["expected"] = {k: v for k, v in EXPECTED[name].items() if k != "cruise_speed"}
    return r


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--airframe", action="append")
    ap.add_argument("--loop-hz", type=int, default=1000)
    args = ap.parse_args()
    print(json.dumps([measure(name, args.loop_hz) for name in (args.airframe or ["trainer", "wing"])], indent=1))


if __name__ == "__main__":
    main()
