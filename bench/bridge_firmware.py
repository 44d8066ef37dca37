"""Where a bridged flight's step goes: the host's end, the pipe, and the firmware's end in the MicroPython VM.

Flies the 5-inch hover with `--firmware micropython` (sim/bridge.py <-> boards/bridge_fw.py over pipes),
recording every byte the host sends, then replays that recording into the VM from a file (no host, no pipe
wake-ups) to take the firmware's own costs apart. Prints one JSON object:
- live: the flight's realtime_factor, and per step the host's bridge call (step_us: pack, CRC, write, wait,
  decode, apply), the part of it spent waiting for and reading the answer (wait_us) and writing the STEP
  (write_us: the firmware may take the CPU the moment it wakes), the rest, which is the host end's own work
  (host_us: pack, CRC, decode, apply), and the rest of the lockstep step (physics, IMU and wire models,
  pilot, judging: sim_us);
- vm: the firmware's loop per step fed from the file, served as bridge_fw.main serves a pipe (loop_us: read,
  CRC, decode, the pass, reply, write, the between-steps heap care; not the session's start, start_ms:
  HELLO, PARAMS and BOOT, which compiles the core), the pass itself (pass_us), the heap care
  (slack_us, gc_runs, and heap_looks: the HeapWatch's gc.mem_free() calls), the rest, which is the bridge's
  own exchange (exchange_us = loop_us - pass_us - slack_us), a gc.mem_free() call (mem_free_us: it walks the
  heap's allocation table), and what a step allocates (alloc_bytes mean and max, from gc.mem_alloc() deltas
  with a collection before each step);
- with --instructions, vm.instructions_per_step: the same replay counted by callgrind instead of timed (the
  whole recording less its first sixth, divided by the steps between: start-up and compiling cancel out),
  the figure that compares two versions on a shared host, where the timings move with the load.

    .venv/bin/python bench/bridge_firmware.py [--duration 6] [--instructions]
"""

import argparse
import json
import os
import subprocess
import tempfile
import time

from hoverfly.protocols import bridge as B
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
A = [0, 0, 0]  # sum, steps, max
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
S = [0]  # the session's start (HELLO, PARAMS, BOOT: compiling the core), not a step's
ohandle0 = fw.handle
def timed_handle(kind, payload, n):
    if kind == 0x53:
        return ohandle0(kind, payload, n)
    t0 = ticks()
    r = ohandle0(kind, payload, n)
    S[0] += diff(ticks(), t0)
    return r
fw.handle = timed_handle
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
bridge_fw.serve(sys.stdin.buffer, sys.stdout.buffer, fw, flush=False)  # as main() serves a pipe
loop = diff(ticks(), t0) - S[0]
n = fw.steps or 1
t1 = ticks()
for i in range(200):
    mem_free()
mf = diff(ticks(), t1) / 200
sys.stderr.write("RESULT %d %.2f %.2f %.2f %d %.1f %.1f %d %d %d\\n" % (
    fw.steps, loop / n, T[1] / n, T[0] / n, fw.gc_runs, mf, A[0] / (A[1] or 1), A[2], fw.heap.looks, S[0]))
"""


def live(duration_s):
    """One bridged flight, timed around the bridge's step, its writes and its reads; returns (figures,
    recorded bytes)."""
    run = SimRun("5inch", "hover", 1, duration_s=duration_s, firmware="micropython")
    f = run.flight
    rec = bytearray()
    acc = {"step": 0.0, "wait": 0.0, "write": 0.0, "in_step": False}
    perf = time.perf_counter
    transport = f.transport
    open_ = transport.open

    def opened():
        open_()
        write = transport.write
        read = transport.read

        def recording(data):
            rec.extend(data)
            t0 = perf()
            write(data)
            if acc["in_step"]:
                acc["write"] += perf() - t0

        def timed_read(timeout_s):
            t0 = perf()
            data = read(timeout_s)
            if acc["in_step"]:  # not the start's answers (BOOT compiles the core)
                acc["wait"] += perf() - t0
            return data

        transport.write = recording
        transport.read = timed_read

    transport.open = opened
    step = f.step

    def timed_step(now_us):
        acc["in_step"] = True
        t0 = perf()
        step(now_us)
        acc["step"] += perf() - t0
        acc["in_step"] = False

    f.step = timed_step
    r = run.run()
    n = run.firmware_stats["steps"]
    wall = r["wall_time_s"]
    return {
        "realtime_factor": r["realtime_factor"],
        "step_us": round(acc["step"] / n * 1e6, 1),
        "wait_us": round(acc["wait"] / n * 1e6, 1),
        "write_us": round(acc["write"] / n * 1e6, 1),
        "host_us": round((acc["step"] - acc["wait"] - acc["write"]) / n * 1e6, 1),
        "sim_us": round((wall - acc["step"]) / n * 1e6, 1),
        "firmware_pass_mean_us": run.firmware_stats["pass_mean_us"],
    }, bytes(rec)


def vm(recording, measure_alloc, prefix=()):
    """The VM driver fed `recording`; its figures. prefix: a command that runs the VM (callgrind)."""
    argv, env = firmware_command("micropython")
    argv = list(prefix) + argv[:-2] + ["-c", _VM_DRIVER.replace("MEASURE_ALLOC", "True" if measure_alloc else "False")]
    with tempfile.TemporaryFile() as f:
        f.write(recording)
        f.seek(0)
        p = subprocess.run(argv, env=env, stdin=f, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, timeout=3600)
    line = [ln for ln in p.stderr.decode().splitlines() if ln.startswith("RESULT")]
    if not line:
        raise SystemExit("the VM run failed:\n" + p.stderr.decode()[-2000:])
    steps, loop, pass_us, slack, gc_runs, mem_free_us, alloc_mean, alloc_max, heap_looks, start_us = \
        line[0].split()[1:]
    return {"steps": int(steps), "start_ms": round(int(start_us) / 1000.0, 1), "loop_us": float(loop),
            "pass_us": float(pass_us), "slack_us": float(slack),
            "exchange_us": round(float(loop) - float(pass_us) - float(slack), 2),
            "gc_runs": int(gc_runs), "heap_looks": int(heap_looks), "mem_free_us": float(mem_free_us),
            "alloc_bytes": {"mean": float(alloc_mean), "max": int(alloc_max)}}


def _steps_head(recording, steps):
    """The recording up to its `steps`-th STEP frame, and a QUIT."""
    dec = B.BridgeDecoder(depth=4)
    seen = 0
    for i in range(len(recording)):
        if dec.feed(recording[i:i + 1]) and dec.pop() == B.STEP:
            seen += 1
            if seen == steps:
                return recording[:i + 1] + B.frame(B.QUIT)
    return recording


def instructions(recording, steps):
    """Instructions the VM runs a step (callgrind): the whole recording less its first sixth, over the steps
    between."""
    counts = []
    head = steps // 6
    for rec in (_steps_head(recording, head), recording):
        with tempfile.NamedTemporaryFile(suffix=".callgrind") as out:
            vm(rec, False, ("valgrind", "--tool=callgrind", "--callgrind-out-file=" + out.name))
            with open(out.name) as f:
                total = [ln for ln in f if ln.startswith(("summary:", "totals:"))]
        counts.append(int(total[0].split()[1]))
    return round((counts[1] - counts[0]) / (steps - head))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration", type=float, default=6.0)
    ap.add_argument("--instructions", action="store_true",
                    help="also count the VM's instructions a step under callgrind (needs valgrind; minutes)")
    args = ap.parse_args()
    figures, recording = live(args.duration)
    timed = vm(recording, False)
    alloc = vm(recording, True)["alloc_bytes"]
    timed["alloc_bytes"] = alloc
    if args.instructions:
        timed["instructions_per_step"] = instructions(recording, timed["steps"])
    print(json.dumps({"load_avg_1min": round(os.getloadavg()[0], 2), "live": figures, "vm": timed}))


if __name__ == "__main__":
    main()
