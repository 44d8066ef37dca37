"""MSP at the companion's rate (seed 004, issue 25): SET_RAW_RC and sensor polls over TCP to `hoverfly sim`.

A companion computer on 127.0.0.1 sends MSP_SET_RAW_RC at --rc-hz and polls MSP_ATTITUDE and MSP_RAW_IMU,
each at --poll-hz, for --seconds over one TCP connection to an in-process SimServer (the real sockets,
links task and MSP server; its flight runs in real time in a thread). Each RC frame carries a sequence
number in AUX4 (1000 + n % 1000 µs); the flight's on_msp_rc is wrapped to record what reaches the
controller, so the check is by sequence: every frame, in order, none twice. The autopilot is enabled
as seed 004's pilot does (autopilot switch, then arm switch), so the frames are also taken by it
(the companion's arm channel stays low: nothing arms). Prints one JSON line:
frames sent/taken/in order/accepted, polls sent/answered, reply latency p50/p99/max in ms (from the
send to the whole reply read back), error replies, and the links' counters.

    .venv/bin/python bench/msp_rate.py                      # 400 Hz RC + 2 x 400 Hz polls, 10 s, serial_update_hz 2000
    .venv/bin/python bench/msp_rate.py --serial-hz 100      # Betaflight's default links rate
"""

import argparse
import json
import socket
import sys
import threading
import time

from hoverfly.core.board import SERIAL_CONFIG
from hoverfly.core.scheduler import PS_PASSES
from hoverfly.protocols import msp
from hoverfly.sim.server import SimServer

SEQ_CH = 7  # AUX4 (channel 8, 0-based 7): the sequence number's channel
AP_ENABLED = 2  # core/command/autopilot.py's state once the pilot has enabled it


def _percentile(sorted_values, q):
    if not sorted_values:
        return None
    k = min(len(sorted_values) - 1, int(round(q * (len(sorted_values) - 1))))
    return sorted_values[k]


def measure(seconds=10.0, rc_hz=400, poll_hz=400, serial_hz=2000, settle_s=0.5):
    server = SimServer("5inch", 0, 0, None, duration_s=seconds + 30, overrides=(("serial_update_hz", serial_hz),))
    flight = server.flight
    taken = []
    accepted = [0]
    original = flight.on_msp_rc

    def recording(now_us, channels_us, count):
        taken.append(channels_us[SEQ_CH] - 1000 if count > SEQ_CH else -1)
        reason = original(now_us, channels_us, count)
        if not reason:
            accepted[0] += 1
        return reason

    flight.on_msp_rc = recording
    t = threading.Thread(target=server.serve, daemon=True)
    t.start()
    # Seed 004's enabling procedure on the pilot's transmitter: the autopilot switch, then the arm switch.
    pilot = server.run.pilot
    ap_ch = flight.params.get("ap_ch")
    arm_ch = flight.params.get("arm_ch")
    pilot.overrides_us[ap_ch - 1] = 2000
    time.sleep(0.2)
    pilot.overrides_us[arm_ch - 1] = 2000
    time.sleep(settle_s)
    ap_state = flight.autopilot.state

    sock = socket.create_connection(server.ports.address(SERIAL_CONFIG), timeout=5)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    sent = []  # (cmd, send time) in the order sent: replies come back in this order
    lock = threading.Lock()
    done = threading.Event()
    replies = {"ok": 0, "error": 0, "lat_ms": [], "cmds": []}

    def reader():
        p = msp.MspParser(queue_depth=256)
        sock.settimeout(0.1)
        k = 0
        while not (done.is_set() and k >= len(sent)):
            try:
                data = sock.recv(65536)
            except TimeoutError:
                if done.is_set() and time.monotonic() > done.deadline:
                    return
                continue
            if not data:
                return
            now = time.perf_counter()
            p.feed(data)
            while p.pop():
                with lock:
                    cmd, t0 = sent[k]
                k += 1
                replies["cmds"].append((cmd, p.cmd))
                if p.direction == msp.DIR_ERROR:
                    replies["error"] += 1
                else:
                    replies["ok"] += 1
                if cmd != msp.MSP_SET_RAW_RC:
                    replies["lat_ms"].append((now - t0) * 1000.0)

    rd = threading.Thread(target=reader, daemon=True)
    rd.start()
    channels = [1500, 1500, 1500, 1000, 1000, 1000, 1000, 1000]  # AETR, throttle low, AUX1 (arm) low
    tick_s = 1.0 / max(rc_hz, poll_hz)
    rc_every = max(1, int(round(max(rc_hz, poll_hz) / rc_hz)))
    poll_every = max(1, int(round(max(rc_hz, poll_hz) / poll_hz)))
    n_ticks = int(seconds / tick_s)
    rc_sent = polls_sent = 0
    passes0 = flight.scheduler.stats[PS_PASSES]
    start = time.perf_counter()
    for k in range(n_ticks):
        due = start + k * tick_s
        while True:
            d = due - time.perf_counter()
            if d <= 0:
                break
            time.sleep(d if d > 0.0005 else 0)
        out = []
        if k % rc_every == 0:
            channels[SEQ_CH] = 1000 + rc_sent % 1000
            out.append((msp.MSP_SET_RAW_RC, msp.encode_request(msp.MSP_SET_RAW_RC, msp.pack_set_raw_rc(channels))))
            rc_sent += 1
        if k % poll_every == 0:
            out.append((msp.MSP_ATTITUDE, msp.encode_request(msp.MSP_ATTITUDE)))
            out.append((msp.MSP_RAW_IMU, msp.encode_request(msp.MSP_RAW_IMU)))
            polls_sent += 2
        now = time.perf_counter()
        with lock:
            for cmd, _ in out:
                sent.append((cmd, now))
        sock.sendall(b"".join(frame for _, frame in out))
    wall_s = time.perf_counter() - start
    done.deadline = time.monotonic() + 10.0  # the last replies (a loaded machine's sim may lag behind)
    done.set()
    rd.join(5)
    sock.close()
    links = server.links
    server.stop()
    t.join(10)

    in_order = all(taken[i] == i % 1000 for i in range(len(taken)))
    answered_in_order = all(a == b for a, b in replies["cmds"])
    lat = sorted(replies["lat_ms"])
    polls_answered = len(lat)
    return {
        "bench": "msp_rate", "seconds": seconds, "wall_s": round(wall_s, 2), "rc_hz": rc_hz, "poll_hz": poll_hz,
        "polls": "MSP_ATTITUDE + MSP_RAW_IMU, each at poll_hz", "serial_update_hz": serial_hz,
        "autopilot_enabled": ap_state == AP_ENABLED,
        "rc_sent": rc_sent, "rc_taken": len(taken), "rc_in_order": in_order, "rc_accepted": accepted[0],
        "polls_sent": polls_sent, "polls_answered": polls_answered,
        "replies": replies["ok"] + replies["error"], "error_replies": replies["error"],
        "replies_in_order": answered_in_order,
        "latency_ms_p50": round(_percentile(lat, 0.5), 2) if lat else None,
        "latency_ms_p99": round(_percentile(lat, 0.99), 2) if lat else None,
        "latency_ms_max": round(lat[-1], 2) if lat else None,
        "links_held_back": links.held_back, "frames_dropped": links.config.dropped(),
        "reply_bytes_dropped": links.dropped_bytes, "partial_timeouts": links.partial_timeouts,
        "loop_passes_per_s": round((flight.scheduler.stats[PS_PASSES] - passes0) / wall_s, 1),
        "loop_overruns": flight.scheduler.overruns,
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--rc-hz", type=int, default=400)
    ap.add_argument("--poll-hz", type=int, default=400)
    ap.add_argument("--serial-hz", type=int, default=2000, help="serial_update_hz of the simulated controller")
    a = ap.parse_args(argv)
    print(json.dumps(measure(a.seconds, a.rc_hz, a.poll_hz, a.serial_hz)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
