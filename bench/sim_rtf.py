"""Simulator real-time factor: the 5-inch hover at a 1 kHz loop, flight core included.

Prints one JSON object: {airframe, scenario, loop_hz, sim_time_s, wall_time_s, realtime_factor,
core_us_per_pass}. Best of three runs.   python3 bench/sim_rtf.py
"""

import json

from hoverfly.sim.runner import fly


def main():
    best = None
    for _ in range(3):
        r = fly("hover", "5inch", seed=1)
        if best is None or r["realtime_factor"] > best["realtime_factor"]:
            best = r
    print(json.dumps({
        "airframe": best["airframe"], "scenario": best["scenario"], "loop_hz": best["loop_hz"],
        "sim_time_s": best["sim_time_s"], "wall_time_s": best["wall_time_s"],
        "realtime_factor": best["realtime_factor"], "core_us_per_pass": best["loop"]["mean_us"],
    }))


if __name__ == "__main__":
    main()
