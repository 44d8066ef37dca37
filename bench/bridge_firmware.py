"""Where a bridged flight's step goes: the host's end, the pipe, and the firmware's end in the MicroPython VM.

Flies the 5-inch hover with `--firmware micropython` (sim/bridge.py <-> boards/bridge_fw.py over pipes),
recording every byte the host sends, then replays that recording into the VM from a file (no host, no pipe
wake-ups) to take the firmware's own costs apart. Prints one JSON object:
- live: the flight's realtime_factor, and per step the host's bridge call (step_us: pack, CRC, write, wait,
  decode, apply), the part of it spent waiting for the answer (wait_us), and the rest of the lockstep step
  (physics, IMU and wire models, pilot, judging: sim_us);
- vm: the firmware's loop per step fed from the file (loop_us: read, CRC, unpack, the pass, reply, write,
  the between-steps heap care), the pass itself (pass_us), the heap care (slack_us, gc_runs), a gc.mem_free()
  call (mem_free_us: it walks the heap's allocation table), and what a step allocates (alloc_bytes mean and
  max, from gc.mem_alloc() deltas with a collection before each step: boards/bridge_fw.py's STEP_ALLOC_MAX
  must stay above the max).

    .venv/bin/python bench/bridge_firmware.py [--duration 6]
"""

import argparse
import json
import os
import subprocess
import tempfile
import time

from hoverfly.sim.bridge import firmware_command
from hoverfly.sim.runner import SimRun

_VM_DRIVER = """
import sys, time, gc
from hoverfly.boards import bridge_fw
from hoverfly.compat import mem_free
ticks = time.ticks_us
diff = time.ticks_diff
fw = bridge_fw.Firmware()
T = [0, 0, 0]
A = [0, 0, 0]
alloc = MEASURE_ALLOC
oslack = fw.slack
def slack():
    t0 = ticks()
    oslack()
    T[0] += diff(ticks(), t0)
fw.slack = slack
orep = fw._reply
def rep(pass_us):
    T[1] += pass_us
    return orep(pass_us)
fw._reply = rep
if alloc:
    ohandle = fw.handle
    def handle(kind, payload, n):
        gc.collect()
        a0 = gc.mem_alloc()
        r = ohandle(kind, payload, n)
        d = gc.mem_alloc() - a0
        if kind == 0x53:
            A[0] += d
            A[1] += 1
            if d > A[2]:
                A[2] = d
        return r
    fw.handle = handle
t0 = ticks()
bridge_fw.serve(sys.stdin.buffer, sys.stdout.buffer, fw)
loop = diff(ticks(), t0)
n = fw.steps or 1
t1 = ticks()
for i in range(200):
    mem_free()
mf = diff(ticks(), t1) / 200
sys.stderr.write("RESULT %d %.2f %.2f %.2f %d %.1f %.1f %d\\n" % (
    fw.steps, loop / n, T[1] / n, T[0] / n, fw.gc_runs, mf, A[0] / (A[1] or 1), A[2]))
"""


def live(duration_s):
    """One bridged flight, timed around the bridge's step and its wait; returns (figures, recorded bytes)."""
    run = SimRun("5inch", "hover", 1, duration_s=duration_s, firmware="micropython")
    f = run.flight
    rec = bytearray()
    acc = {"step": 0.0, "wait": 0.0, "in_step": False}
    perf = time.perf_counter
    transport = f.transport
    open_ = transport.open

    def opened():
        open_()
        write = transport.write

        def recording(data):
            rec.extend(data)
            write(data)

        transport.write = recording

    transport.open = opened
    step = f.step
    receive = f._receive

    def timed_step(now_us):
        acc["in_step"] = True
        t0 = perf()
        step(now_us)
        acc["step"] += perf() - t0
        acc["in_step"] = False

    def timed_receive(kind, timeout_s):
        t0 = perf()
        r = receive(kind, timeout_s)
        if acc["in_step"]:  # not the start's answers (BOOT compiles the core)
            acc["wait"] += perf() - t0
        return r

    f.step = timed_step
    f._receive = timed_receive
    r = run.run()
    n = run.firmware_stats["steps"]
    wall = r["wall_time_s"]
    return {
        "realtime_factor": r["realtime_factor"],
        "step_us": round(acc["step"] / n * 1e6, 1),
        "wait_us": round(acc["wait"] / n * 1e6, 1),
        "sim_us": round((wall - acc["step"]) / n * 1e6, 1),
        "firmware_pass_mean_us": run.firmware_stats["pass_mean_us"],
    }, bytes(rec)


def vm(recording, measure_alloc):
    argv, env = firmware_command("micropython")
    argv = argv[:-2] + ["-c", _VM_DRIVER.replace("MEASURE_ALLOC", "True" if measure_alloc else "False")]
    with tempfile.TemporaryFile() as f:
        f.write(recording)
        f.seek(0)
        p = subprocess.run(argv, env=env, stdin=f, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, timeout=600)
    line = [ln for ln in p.stderr.decode().splitlines() if ln.startswith("RESULT")]
    if not line:
        raise SystemExit("the VM run failed:\n" + p.stderr.decode()[-2000:])
    steps, loop, pass_us, slack, gc_runs, mem_free_us, alloc_mean, alloc_max = line[0].split()[1:]
    return {"steps": int(steps), "loop_us": float(loop), "pass_us": float(pass_us), "slack_us": float(slack),
            "gc_runs": int(gc_runs), "mem_free_us": float(mem_free_us),
            "alloc_bytes": {"mean": float(alloc_mean), "max": int(alloc_max)}}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration", type=float, default=6.0)
    args = ap.parse_args()
    figures, recording = live(args.duration)
    timed = vm(recording, False)
    alloc = vm(recording, True)["alloc_bytes"]
    timed["alloc_bytes"] = alloc
    print(json.dumps({"load_avg_1min": round(os.getloadavg()[0], 2), "live": figures, "vm": timed}))


if __name__ == "__main__":
    main()
