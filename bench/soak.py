"""Soak: a real `hoverfly sim` served for N minutes to clients that poll and drop, loop rate and memory watched.

    .venv/bin/python bench/soak.py                 # 10 minutes
    .venv/bin/python bench/soak.py --minutes 3

`hoverfly sim` runs as a subprocess on 127.0.0.1 (ports chosen by the OS, storage in a temporary
directory). Two clients poll it as a configurator and a ground station would, and hang up and come
back at random every 2-10 s:
- on the CLI+MSP port: MSP_STATUS, MSP_RAW_IMU, MSP_ATTITUDE, MSP_RC, MSP_MOTOR every ~20 ms, and
  every `--sample-s` seconds CLI `status` in the same session (the loop-rate sample, below);
- on the maintenance port: a read of attitude, gyro, motor and PID fields every ~20 ms.
Every request waits for its answer (3 s); one not answered counts in `unanswered`.

Loop rate: the sim runs the flight at loop_hz of simulated time and keeps simulated time on the
wall clock, so its passes per wall second are loop_hz x (simulated seconds / wall seconds).
Simulated seconds come from the sim's own counter in CLI `status` ("Link: up, N frames, ..., R Hz":
N receiver frames at R per simulated second); min and mean over the samples. MSP_STATUS's cycle
time is simulated time (always 1/loop_hz in the sim), so it is reported but says nothing of the wall.
RSS: /proc/PID/status VmRSS every 5 s; slope by least squares over the samples after the first
minute (start-up allocations), KB/min.

Prints one JSON object: minutes, loop_hz {min, mean, samples}, rss_kb {first, last, max, slope_kb_min},
requests, answered, unanswered, reconnects, exceptions (the sim's loop errors + tracebacks on its
stderr), deaths (the sim exited; it is started again), hangs (a fresh client not answered in 5 s).
Every thread and the subprocess end in a finally.
"""

import argparse
import json
import os
import random
import re
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from fuzz import MaintClient, MspClient, Sim, loop_errors, recv_some, sim_answers  # noqa: E402
from hoverfly.protocols import msp  # noqa: E402

POLL_S = 0.02
MSP_POLLS = (msp.MSP_STATUS, msp.MSP_RAW_IMU, msp.MSP_ATTITUDE, msp.MSP_RC, msp.MSP_MOTOR)
MAINT_FIELDS = ["body_roll", "body_pitch", "body_yaw", "raw_gyro_x", "motor1_signal", "roll_PID_u",
                "motors_armed"]
LINK_RE = re.compile(r"Link: \w+, (\d+) frames, \d+ errors, (\d+) Hz")
LOOP_RE = re.compile(r"Loop: (\d+) Hz")


class Counts:
    def __init__(self):
        self.lock = threading.Lock()
        self.requests = 0
        self.answered = 0
        self.reconnects = 0
        self.armed_seen = 0
        self.cycle_us = []
        self.samples = []  # (wall s, sim frames, frame rate Hz, loop Hz)

    def add(self, ok, n=1):
        with self.lock:
            self.requests += n
            if ok:
                self.answered += n


def _status(client, timeout_s=5.0):
    """CLI `status` inside the MSP client's session: its text ('' if it did not come)."""
    sock = client.sock
    sock.sendall(b"#\r\nstatus\r\nexit\r\n")
    text = b""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end and b"Links:" not in text:
        d = recv_some(sock, 0.2)
        if d is None:
            break
        text += d
    time.sleep(0.05)
    recv_some(sock, 0.05)  # the prompt after exit
    client.parser = msp.MspParser(queue_depth=256)
    return text.decode(errors="replace")


def msp_poller(sim, counts, stop, rng, sample_s):
    c = None
    drop_at = 0.0
    next_sample = time.monotonic() + 2.0
    try:
        while not stop.is_set():
            now = time.monotonic()
            if c is None or now >= drop_at:
                if c is not None:
                    c.close()
                    counts.reconnects += 1
                try:
                    c = MspClient(sim.msp_port)
                except OSError:
                    c = None
                    time.sleep(0.2)
                    continue
                drop_at = now + rng.uniform(2.0, 10.0)
            try:
                if now >= next_sample:
                    next_sample = now + sample_s
                    text = _status(c)
                    m = LINK_RE.search(text)
                    lm = LOOP_RE.search(text)
                    counts.add(m is not None)
                    if m and lm:
                        with counts.lock:
                            counts.samples.append((time.monotonic(), int(m.group(1)), int(m.group(2)),
                                                   int(lm.group(1))))
                    continue
                cmd = rng.choice(MSP_POLLS)
                got = c.ask(cmd, timeout_s=3.0)
                counts.add(got is not None)
                if got is not None and cmd == msp.MSP_STATUS:
                    st = msp.unpack_status(got[1])
                    with counts.lock:
                        counts.cycle_us.append(st["cycle_time_us"])
                        counts.armed_seen += st["mode_flags"] & 1
                if len(c.replies) > 1000:
                    c.replies.clear()
            except OSError:
                c = None
            time.sleep(POLL_S)
    finally:
        if c is not None:
            c.close()


def maint_poller(sim, counts, stop, rng):
    c = None
    drop_at = 0.0
    try:
        while not stop.is_set():
            now = time.monotonic()
            if c is None or now >= drop_at:
                if c is not None:
                    c.close()
                    counts.reconnects += 1
                try:
                    c = MaintClient(sim.maint_port)
                except OSError:
                    c = None
                    time.sleep(0.2)
                    continue
                drop_at = now + rng.uniform(2.0, 10.0)
            try:
                v = c.read(MAINT_FIELDS, timeout_s=3.0)
                counts.add(v is not None)
                if v is not None and v.get("motors_armed"):
                    with counts.lock:
                        counts.armed_seen += 1
            except OSError:
                c = None
            time.sleep(POLL_S)
    finally:
        if c is not None:
            c.close()


def slope_per_min(points):
    """Least-squares slope of (seconds, value) points, per minute; None for fewer than 3."""
    if len(points) < 3:
        return None
    n = len(points)
    mx = sum(p[0] for p in points) / n
    my = sum(p[1] for p in points) / n
    sxx = sum((p[0] - mx) ** 2 for p in points)
    if sxx == 0:
        return None
    return sum((p[0] - mx) * (p[1] - my) for p in points) / sxx * 60.0


def loop_rates(samples):
    """Passes per wall second between consecutive status samples."""
    rates = []
    for (t0, n0, r0, hz0), (t1, n1, r1, _) in zip(samples[:-1], samples[1:], strict=True):
        rate = r0 if r0 > 0 else r1
        if t1 > t0 and rate > 0 and n1 >= n0:
            rates.append(hz0 * ((n1 - n0) / rate) / (t1 - t0))
    return rates


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--sample-s", type=float, default=10.0, help="seconds between loop-rate samples")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    sim = Sim()
    counts = Counts()
    stop = threading.Event()
    threads = []
    rss = []
    hangs = 0
    t_start = time.monotonic()
    try:
        sim.start()
        threads = [threading.Thread(target=msp_poller, args=(sim, counts, stop, random.Random(args.seed),
                                                             args.sample_s), daemon=True),
                   threading.Thread(target=maint_poller, args=(sim, counts, stop, random.Random(args.seed + 1)),
                                    daemon=True)]
        for t in threads:
            t.start()
        end = t_start + args.minutes * 60.0
        while time.monotonic() < end:
            time.sleep(min(5.0, max(0.0, end - time.monotonic())))
            if not sim.check("soak"):  # counted in sim.deaths, started again
                continue
            kb = sim.rss_kb()
            if kb is not None:
                rss.append((time.monotonic() - t_start, kb))
        stop.set()
        for t in threads:
            t.join(10)
        if not sim_answers(sim):
            hangs += 1
        errors, line = loop_errors(sim)
        tracebacks = sim.tracebacks()
    finally:
        stop.set()
        for t in threads:
            t.join(10)
        deaths = list(sim.deaths)
        sim.cleanup()
    rates = loop_rates(counts.samples)
    settled = [p for p in rss if p[0] >= 60.0] or rss
    report = {
        "minutes": args.minutes,
        "loop_hz": {"min": round(min(rates), 1) if rates else None,
                    "mean": round(sum(rates) / len(rates), 1) if rates else None,
                    "samples": len(rates)},
        "msp_status_cycle_us": {"min": min(counts.cycle_us) if counts.cycle_us else None,
                                "max": max(counts.cycle_us) if counts.cycle_us else None,
                                "note": "simulated time"},
        "rss_kb": {"first": rss[0][1] if rss else None, "last": rss[-1][1] if rss else None,
                   "max": max(p[1] for p in rss) if rss else None,
                   "slope_kb_min": round(slope_per_min(settled), 2) if slope_per_min(settled) is not None else None,
                   "samples": len(rss)},
        "requests": counts.requests,
        "answered": counts.answered,
        "unanswered": counts.requests - counts.answered,
        "reconnects": counts.reconnects,
        "armed_polls": counts.armed_seen,
        "exceptions": (errors or 0) + tracebacks,
        "loop_errors_line": line,
        "deaths": len(deaths),
        "death_details": deaths,
        "hangs": hangs,
    }
    json.dump(report, sys.stdout, indent=1)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
