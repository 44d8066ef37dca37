"""The ground station's link at its 50 Hz (issue 24): what `hoverfly gcs` gets through to `hoverfly sim`.

Starts `hoverfly sim` in its own process (real TCP on 127.0.0.1, as a user runs it), then for each of its
two ports (MSP + CLI, and the seed-001 maintenance port) opens a gcs Session with the sticks fed at 50 Hz
(throttle at zero, disarmed) and the app served by uvicorn on 127.0.0.1, with one WebSocket client, for
--seconds. Prints one JSON line per port: pump ticks/s (goal 50), the tick's link time mean/max in ms
(the round trips: MSP sends its 4 or 6 requests at once; maintenance one request with the override and
the telemetry fields), stick frames sent/s, telemetry messages/s the WebSocket delivered, and errors.

    .venv/bin/python bench/gcs_link.py
    .venv/bin/python bench/gcs_link.py --seconds 20
"""

import argparse
import json
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

from hoverfly.gcs.app import make_app, new_token
from hoverfly.gcs.session import Session

REPO = Path(__file__).resolve().parents[1]


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_port(port, timeout_s=20.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                return
        except OSError:
            time.sleep(0.1)
    raise SystemExit("hoverfly sim did not start")


def measure(url, seconds):
    import uvicorn
    from websockets.sync.client import connect

    session = Session(url)
    session.start()
    http_port = _free_port()
    token = new_token()
    origin = "http://127.0.0.1:%d" % http_port
    server = uvicorn.Server(uvicorn.Config(make_app(session, token, (origin,)), host="127.0.0.1", port=http_port,
                                           log_level="warning", lifespan="off", ws="websockets-sansio"))
    threading.Thread(target=server.run, daemon=True).start()
    _wait_port(http_port)
    stop = threading.Event()

    def sticks():
        while not stop.is_set():
            session.set_sticks({"t": "sticks", "roll": 0, "pitch": 0, "yaw": 0, "throttle": 0, "arm": False})
            time.sleep(0.02)

    feeder = threading.Thread(target=sticks, daemon=True)
    time.sleep(1.0)  # connected and pumping
    feeder.start()
    ticks0, sent0, sum0 = session._ticks, session.rc_sent, session.tick_s_sum
    session.tick_s_max = 0.0
    messages = 0
    t0 = time.monotonic()
    with connect("ws://127.0.0.1:%d/ws?token=%s" % (http_port, token), origin=origin) as ws:
        while time.monotonic() - t0 < seconds:
            if json.loads(ws.recv(2)).get("t") == "telemetry":
                messages += 1
    wall = time.monotonic() - t0
    ticks = session._ticks - ticks0
    out = {
        "protocol": session.protocol, "seconds": round(wall, 2),
        "pump_ticks_per_s": round(ticks / wall, 1),
        "tick_link_ms_mean": round((session.tick_s_sum - sum0) / ticks * 1000, 2) if ticks else None,
        "tick_link_ms_max": round(session.tick_s_max * 1000, 2),
        "stick_frames_per_s": round((session.rc_sent - sent0) / wall, 1),
        "ws_telemetry_per_s": round(messages / wall, 1),
        "override_refusal": session.override_refusal, "link_error": session.error,
    }
    stop.set()
    feeder.join()
    server.should_exit = True
    session.close()
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    args = ap.parse_args()
    msp_port, maint_port = _free_port(), _free_port()
    sim = subprocess.Popen([sys.executable, "-m", "hoverfly.cli", "sim", "--msp-port", str(msp_port), "--maint-port",
                            str(maint_port)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=REPO)
    try:
        _wait_port(msp_port)
        _wait_port(maint_port)
        for port in (msp_port, maint_port):
            print(json.dumps(measure("socket://127.0.0.1:%d" % port, args.seconds)), flush=True)
    finally:
        sim.terminate()
        sim.wait(10)


if __name__ == "__main__":
    main()
