"""The heaviest passes on MicroPython: callgrind counts of bench/core_loop.py's pass by its place in the tasks' cycle.

Run: `.venv/bin/python bench/pass_peaks.py` (needs `valgrind` and the MicroPython VM; about two minutes on two
cores).

bench/core_loop.py's flight runs its slow tasks at divided rates of the 1 kHz loop: the receiver at 500 Hz
(a CRSF frame every other run: every 4th pass), arming and failsafe at 100 Hz, the battery at 50 Hz (and the
LED at 10 Hz, a few hundred instructions, left out of the cycle). So the pass repeats every CYCLE = 20 passes,
and which tasks share a pass decides the longest pass: the one that sets the loop's jitter and, on a board near
its budget, the overruns. For each place k in the cycle (the passes whose time in ms is k mod 20) this counts
the instructions of those passes alone, as bench/stage_instructions.py counts a stage (the pass made from
inside the builtin `map`'s iterator, callgrind collecting only there, so about 1.6k of each figure is that
call), collections and looks at the free heap taken out. Prints one JSON object:
{cycle, cycles, ir_by_place: [20 figures, instructions a pass], ir_max, ir_mean, place_of_max}.
"""

import sys

CYCLE = 20
CYCLES = 30


def _child(place, cycles):
    from core_instructions import fly
    from core_loop import armed_flight

    board, f, t = armed_flight()
    real = f.step

    def step(now_us):
        if (now_us // 1000) % CYCLE == place:
            for r in map(real, [now_us]):
                return r
        return real(now_us)

    f.step = step
    fly(board, f, t, cycles * CYCLE)


def main():
    import json

    from stage_instructions import child_counts

    counts, error = child_counts(__file__, [(str(k), str(CYCLES)) for k in range(CYCLE)])
    if error:
        print(json.dumps({"error": error}))
        return 1
    ir = [round(c / CYCLES) for c in counts]
    top = max(ir)
    print(json.dumps({"cycle": CYCLE, "cycles": CYCLES, "ir_by_place": ir, "ir_max": top,
                      "ir_mean": round(sum(ir) / CYCLE), "place_of_max": ir.index(top)}))
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--child":
        _child(int(sys.argv[2]), int(sys.argv[3]))
    else:
        sys.exit(main())
