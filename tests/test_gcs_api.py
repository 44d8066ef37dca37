"""The ground station's backend against a real `hoverfly sim` on 127.0.0.1: token and Origin, a port
that is no flight controller, a link that drops, parameters checked before anything is sent, save
kept across a restart, diff preview, the motor test's dead-man and its refusals, and the sticks:
arming only at zero throttle, and a lost gamepad ending in the controller's failsafe."""

import socket
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import pytest

pytest.importorskip("starlette")
pytest.importorskip("httpx")

with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # starlette's note that TestClient will move to httpx2
    from starlette.testclient import TestClient  # noqa: E402
from starlette.websockets import WebSocketDisconnect  # noqa: E402

from hoverfly.gcs.app import make_app, new_token  # noqa: E402
from hoverfly.gcs.link import MspClient, open_link  # noqa: E402
from hoverfly.gcs.session import Session  # noqa: E402
from hoverfly.protocols import msp  # noqa: E402

ORIGIN = "http://testserver"  # the TestClient's own origin, standing in for http://127.0.0.1:N
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
    raise AssertionError("nothing listens on 127.0.0.1:%d" % port)


class Sim:
    """`hoverfly sim` as a user runs it, in its own process, with a storage file: stop() and start()
    are a power cycle that keeps the ports."""

    def __init__(self, tmp_path):
        self.msp_port = _free_port()
        self.maint_port = _free_port()
        self.storage = tmp_path / "sim.bin"
        self.proc = None

    def start(self):
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "hoverfly.cli", "sim", "--msp-port", str(self.msp_port), "--maint-port",
             str(self.maint_port), "--storage", str(self.storage), "--duration", "600"],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, cwd=REPO)
        _wait_port(self.msp_port)
        _wait_port(self.maint_port)

    def stop(self):
        if self.proc is not None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)
            self.proc = None

    def url(self, which):
        return "socket://127.0.0.1:%d" % (self.msp_port if which == "msp" else self.maint_port)

    def msp_status(self):
        """The controller's own MSP_STATUS from a second client on the MSP port: (armed, failsafe)."""
        port = open_link(self.url("msp"), 1.0)
        try:
            d = msp.unpack_status(MspClient(port).request(msp.MSP_STATUS))
        finally:
            port.close()
        return bool(d["mode_flags"] & 1), bool(d["mode_flags"] & 16), d.get("arming_disable_flags", 0)


@pytest.fixture
def sim(tmp_path):
    s = Sim(tmp_path)
    s.start()
    yield s
    s.stop()


class Gcs:
    def __init__(self, url):
        self.token = new_token()
        self.session = Session(url)
        self.session.start()
        self.app = make_app(self.session, self.token, (ORIGIN,))
        self.client = TestClient(self.app)
        self.client.headers["X-Hoverfly-Token"] = self.token

    def get(self, path):
        return self.client.get(path)

    def post(self, path, body=None):
        return self.client.post(path, json=body if body is not None else {})

    def param(self, name):
        r = self.get("/api/params")
        assert r.status_code == 200, r.text
        return {p["name"]: p["value"] for p in r.json()}[name]

    def telemetry(self):
        return self.session.telemetry

    def close(self):
        self.client.close()
        self.session.close()


@pytest.fixture
def gcs_msp(sim):
    g = Gcs(sim.url("msp"))
    yield g
    g.close()


@pytest.fixture
def gcs_maint(sim):
    g = Gcs(sim.url("maint"))
    yield g
    g.close()


def _until(cond, timeout_s=5.0, step_s=0.05):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        v = cond()
        if v:
            return v
        time.sleep(step_s)
    return cond()


# ------------------------------------------------------------------------------------ security
def test_api_calls_without_the_token_or_with_another_are_refused(gcs_msp):
    c = TestClient(gcs_msp.app)
    for path in ("/api/status", "/api/params", "/api/diff"):
        r = c.get(path)
        assert r.status_code == 401 and "token" in r.json()["error"]
        assert c.get(path, headers={"X-Hoverfly-Token": "guess"}).status_code == 401
    before = gcs_msp.param("p_roll")
    r = c.post("/api/params", json={"p_roll": 99})
    assert r.status_code == 401
    r = c.post("/api/motor_test", json={"props_removed": True, "values": [0.2] * 4})
    assert r.status_code == 401 and gcs_msp.session.motor_values is None
    assert gcs_msp.param("p_roll") == before
    assert c.get("/", params={"token": "guess"}).status_code == 401
    assert c.get("/api/status", params={"token": gcs_msp.token}).status_code == 200
    assert gcs_msp.get("/api/status").json()["link"]["protocol"] == "msp"


def test_websocket_from_another_origin_or_without_the_token_is_refused(gcs_msp):
    c = TestClient(gcs_msp.app)
    for url, origin in (("/ws?token=" + gcs_msp.token, "http://evil.example"), ("/ws?token=" + gcs_msp.token, None),
                        ("/ws?token=guess", ORIGIN), ("/ws", ORIGIN)):
        headers = {"origin": origin} if origin else {}
        with pytest.raises(WebSocketDisconnect), c.websocket_connect(url, headers=headers) as ws:
            ws.receive_text()
    assert _until(lambda: gcs_msp.telemetry()["link_ok"])
    with c.websocket_connect("/ws?token=" + gcs_msp.token, headers={"origin": ORIGIN}) as ws:
        seen = [ws.receive_json() for _ in range(5)]
    assert any(m["t"] == "telemetry" and m["link_ok"] for m in seen)


def test_hoverfly_gcs_listens_on_loopback_only(sim):
    proc = subprocess.Popen([sys.executable, "-m", "hoverfly.cli", "gcs", "--port", sim.url("msp"), "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=REPO)
    try:
        lines = [proc.stdout.readline() for _ in range(2)]
        url = [x for x in lines if "open http" in x][0].split("open ", 1)[1].strip()
        assert url.startswith("http://127.0.0.1:") and "?token=" in url
        port = int(url.split(":")[2].split("/")[0])
        listening = []
        for table in ("/proc/net/tcp", "/proc/net/tcp6"):
            try:
                rows = Path(table).read_text().splitlines()[1:]
            except OSError:
                continue
            for row in rows:
                local, state = row.split()[1], row.split()[3]
                if state == "0A" and int(local.split(":")[1], 16) == port:
                    listening.append(local.split(":")[0])
        assert listening == ["0100007F"], listening  # 127.0.0.1, and nothing else
        import httpx

        token = url.split("token=")[1]
        r = httpx.get("http://127.0.0.1:%d/api/status" % port, headers={"X-Hoverfly-Token": token}, timeout=5)
        assert r.json()["link"]["connected"]
    finally:
        proc.terminate()
        proc.wait(10)


# ----------------------------------------------------------------------------------- bad input
def test_a_port_that_is_no_flight_controller_is_named_and_nothing_sticks(tmp_path):
    # A TCP service that accepts and answers garbage: not MSP, not the maintenance protocol.
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    stop = threading.Event()

    def serve():
        srv.settimeout(0.1)
        while not stop.is_set():
            try:
                conn, _ = srv.accept()
            except OSError:
                continue
            conn.settimeout(0.1)
            while not stop.is_set():
                try:
                    if not conn.recv(256):
                        break
                    conn.sendall(b"hello, I am a printer\r\n")
                except TimeoutError:
                    continue
                except OSError:
                    break
            conn.close()

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    g = Gcs(None)
    try:
        r = g.post("/api/connect", {"url": "socket://127.0.0.1:%d" % srv.getsockname()[1]})
        assert r.status_code == 502
        assert "neither MSP nor the seed-001 maintenance protocol" in r.json()["error"]
        st = g.get("/api/status").json()
        assert not st["link"]["connected"] and "neither MSP" in st["link"]["error"]
        r = g.post("/api/connect", {"url": "socket://127.0.0.1:%d" % _free_port()})
        assert r.status_code == 502 and "cannot open" in r.json()["error"]
        assert g.post("/api/connect", {"url": "socket://127.0.0.1:99999"}).status_code == 502
        r = g.get("/api/params")
        assert r.status_code == 409 and "not connected" in r.json()["error"]
        assert g.get("/api/status").status_code == 200  # nothing stuck: the app still answers
    finally:
        stop.set()
        g.close()
        srv.close()


def test_a_link_that_drops_mid_session_is_reported_and_comes_back(sim, gcs_msp):
    assert _until(lambda: gcs_msp.telemetry()["link_ok"])
    sim.stop()
    st = _until(lambda: (lambda s: s if not s["link"]["connected"] else None)(gcs_msp.get("/api/status").json()))
    assert st["link"]["error"], st
    r = gcs_msp.get("/api/params")
    assert r.status_code in (409, 502) and r.json()["error"]
    assert not gcs_msp.telemetry()["link_ok"]
    sim.start()
    st = _until(lambda: (lambda s: s if s["link"]["connected"] else None)(gcs_msp.get("/api/status").json()), 10.0)
    assert st["link"]["protocol"] == "msp" and st["link"]["error"] is None
    assert gcs_msp.param("p_roll") is not None


def test_an_out_of_range_parameter_is_refused_and_nothing_is_sent(gcs_msp):
    before = (gcs_msp.param("p_roll"), gcs_msp.param("p_pitch"))
    r = gcs_msp.post("/api/params", {"p_pitch": 51, "p_roll": 500})
    assert r.status_code == 400
    err = r.json()["error"]
    assert "p_roll" in err and "0 .. 250" in err and "nothing was sent" in err
    r = gcs_msp.post("/api/params", {"no_such_param": 1})
    assert r.status_code == 400 and "unknown parameter" in r.json()["error"]
    r = gcs_msp.client.post("/api/params", content=b'{"p_roll": NaN}', headers={"content-type": "application/json"})
    assert r.status_code == 400
    assert (gcs_msp.param("p_roll"), gcs_msp.param("p_pitch")) == before


def test_a_changed_parameter_saved_is_kept_across_a_restart(sim, gcs_msp):
    rows = {p["name"]: p for p in gcs_msp.get("/api/params").json()}
    assert rows["p_roll"]["min"] == 0 and rows["p_roll"]["max"] == 250 and rows["p_roll"]["group"]
    assert rows["rx_provider"]["choices"]
    r = gcs_msp.post("/api/params", {"p_roll": 77})
    assert r.status_code == 200 and r.json()["applied"] == ["p_roll"]
    assert gcs_msp.param("p_roll") == 77
    assert gcs_msp.post("/api/save").status_code == 200
    sim.stop()
    sim.start()
    assert _until(lambda: gcs_msp.get("/api/status").json()["link"]["connected"], 10.0)
    assert gcs_msp.param("p_roll") == 77
    assert "set p_roll = 77" in gcs_msp.get("/api/diff").text


def test_a_diff_file_is_previewed_without_sending_anything(gcs_msp):
    text = "# diff all\nbatch start\nset p_roll = 61\nset p_pitch = 999\nset nonsense = 3\nbatch end\n"
    before = gcs_msp.param("p_roll")
    r = gcs_msp.post("/api/diff/preview", {"text": text})
    assert r.status_code == 200
    body = r.json()
    assert {"name": "p_roll", "old": before, "new": 61, "reboot": False} in body["changes"]
    lines = {e["line"] for e in body["errors"]}
    assert lines == {4, 5}
    assert gcs_msp.param("p_roll") == before
    r = gcs_msp.post("/api/diff/apply", {"text": text})  # a file with errors applies nothing
    assert r.status_code == 400 and "nothing was applied" in r.json()["error"]
    assert gcs_msp.param("p_roll") == before
    good = "set p_roll = 61\n"
    assert gcs_msp.post("/api/diff/apply", {"text": good}).json()["applied"] == ["p_roll"]
    assert gcs_msp.param("p_roll") == 61


# ---------------------------------------------------------------------------------- motor test
def _motors(g):
    return g.telemetry()["motors"] or []


def test_motor_test_needs_the_props_off_confirmation(gcs_msp):
    r = gcs_msp.post("/api/motor_test", {"values": [0.2] * 4})
    assert r.status_code == 400 and "propellers" in r.json()["error"]
    r = gcs_msp.post("/api/motor_test", {"props_removed": True, "values": [1.5, 0, 0, 0]})
    assert r.status_code == 400
    time.sleep(0.2)
    assert all(m <= 1000 for m in _motors(gcs_msp))


@pytest.mark.parametrize("link", ["msp", "maint"])
def test_motor_test_dead_man_stops_the_motors_when_the_page_stops_refreshing(sim, link):
    g = Gcs(sim.url(link))
    try:
        r = g.post("/api/motor_test", {"props_removed": True, "values": [0.15, 0.15, 0.15, 0.15]})
        assert r.status_code == 200, r.text
        assert _until(lambda: all(m > 1050 for m in _motors(g)), 2.0), _motors(g)
        t0 = time.monotonic()
        assert _until(lambda: all(m <= 1000 for m in _motors(g)), 3.0), _motors(g)
        stopped_after_s = time.monotonic() - t0
        assert 0.3 <= stopped_after_s <= 1.5, stopped_after_s
        assert g.session.motor_stops == 1 and not g.session.motor_props
    finally:
        g.close()


def test_closing_the_page_stops_the_motor_test(gcs_msp):
    c = TestClient(gcs_msp.app)
    with c.websocket_connect("/ws?token=" + gcs_msp.token, headers={"origin": ORIGIN}) as ws:
        ws.receive_json()
        assert gcs_msp.post("/api/motor_test", {"props_removed": True, "values": [0.15] * 4}).status_code == 200
        assert _until(lambda: all(m > 1050 for m in _motors(gcs_msp)), 2.0)
    # the socket closed well inside the dead-man's 500 ms: the close itself stopped it
    assert _until(lambda: all(m <= 1000 for m in _motors(gcs_msp)), 0.45), _motors(gcs_msp)


# ------------------------------------------------------------------------------------- sticks
def _sticks(g, thr, arm, secs, roll=0.0):
    end = time.monotonic() + secs
    err = None
    while time.monotonic() < end:
        err = g.session.set_sticks({"t": "sticks", "roll": roll, "pitch": 0, "yaw": 0, "throttle": thr, "arm": arm})
        time.sleep(0.02)
    return err


class Gamepad:
    """Sticks sent from a thread at 50 Hz, as the page sends them, until stop()."""

    def __init__(self, g, throttle=0.0, arm=True):
        self.g = g
        self.throttle = throttle
        self.arm = arm
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self):
        while not self._stop.is_set():
            self.g.session.set_sticks({"t": "sticks", "roll": 0, "pitch": 0, "yaw": 0, "throttle": self.throttle,
                                       "arm": self.arm})
            time.sleep(0.02)

    def stop(self):
        self._stop.set()
        self._t.join()


def test_arming_needs_the_throttle_at_zero(sim, gcs_maint):
    _sticks(gcs_maint, 0.0, False, 1.3)  # past the boot grace, arm switch seen off
    assert _sticks(gcs_maint, 0.4, True, 0.5) == "arming needs the throttle at zero"
    assert not sim.msp_status()[0]
    assert gcs_maint.post("/api/rc/arm", {"arm": True}).status_code == 409
    pad = Gamepad(gcs_maint, 0.0, True)
    try:
        assert _until(lambda: sim.msp_status()[0], 2.0), sim.msp_status()
    finally:
        pad.stop()


def test_motor_test_and_parameter_writes_are_refused_while_armed(sim, gcs_maint):
    _sticks(gcs_maint, 0.0, False, 1.3)
    pad = Gamepad(gcs_maint, 0.0, True)
    try:
        assert _until(lambda: sim.msp_status()[0] and gcs_maint.get("/api/status").json()["armed"], 2.0)
        r = gcs_maint.post("/api/motor_test", {"props_removed": True, "values": [0.2] * 4})
        assert r.status_code == 409 and "armed" in r.json()["error"]
        r = gcs_maint.post("/api/params", {"p_roll": 50})
        assert r.status_code == 409 and "armed" in r.json()["error"]
        assert gcs_maint.post("/api/save").status_code == 409
        r = gcs_maint.post("/api/disconnect")  # the link it flies on is not dropped by a click in flight
        assert r.status_code == 409 and "disarm first" in r.json()["error"]
        assert gcs_maint.get("/api/status").json()["link"]["connected"]
    finally:
        pad.stop()


def test_sticks_that_stop_in_flight_end_in_the_controllers_failsafe(sim, gcs_maint):
    _sticks(gcs_maint, 0.0, False, 1.3)
    _sticks(gcs_maint, 0.0, True, 0.5)
    _sticks(gcs_maint, 0.45, True, 1.0)
    assert gcs_maint.session.override == "sending"
    armed, failsafe, _ = sim.msp_status()
    assert armed and not failsafe
    t_lost = time.monotonic()  # the gamepad is gone: no more sticks messages
    assert _until(lambda: sim.msp_status()[1], 2.0), "no failsafe after the sticks stopped"
    assert time.monotonic() - t_lost < 1.0
    assert gcs_maint.session.override == "stopped"


# ------------------------------------------------------------ the override path, flown in lockstep
def _fly_override(maint_override, stop_at_s, duration_s=14.0):
    """A lockstep sim whose radio holds the arm switch off, and a maintenance client sending the seed-001
    override at 50 Hz: arm switch off until 1.5 s, then armed at zero throttle, up to a 2 m hover, until stop_at_s."""
    from hoverfly.core.links.maintserver import MaintServer
    from hoverfly.protocols import maintenance as mp
    from hoverfly.sim.runner import SimRun

    scenario = {"name": "override", "duration_s": duration_s, "mode": "angle", "events": [], "params": {}}
    run = SimRun("5inch", scenario, seed=3, overrides=(("maint_override", maint_override),))
    server = MaintServer(run.flight)
    replies = []
    hover = run.pilot.hover_guess / 0.9

    def on_step(r):
        t = r.board.sim_us * 1e-6
        if r.board.sim_us % 20000 or t < 1.0 or t >= stop_at_s:
            return
        arm = 2000 if t >= 1.5 else 1000
        v = r.vehicle  # the pilot holds 2 m on the throttle, as the browser test's pilot does
        thr = 1000 if t < 2.0 else 1000 + int(1000 * min(0.9, max(0.0, hover + 0.08 * (2.0 - v.altitude_m())
                                                                     + 0.06 * v.vd)))
        frame = mp.encode_request([], 0, (), (1, arm, 1500, 1500, thr))
        out = []
        server.feed(frame, len(frame), out.append)
        replies.append(mp.header_cmd(out[0][1:9]))

    run.on_step = on_step
    return run.run(), server, replies


def _ev(report, name):
    return [e["t_s"] for e in report["events"] if e["event"] == name]


def test_the_override_flies_in_place_of_the_radio_and_its_silence_is_a_failsafe():
    report, server, replies = _fly_override(1, stop_at_s=5.0)
    assert set(replies) == {0}  # every override taken
    armed = _ev(report, "armed")
    assert armed and 1.5 <= armed[0] < 1.7  # the radio's arm switch is off all along: the override armed it
    assert report["altitude_m"]["max"] > 1.0
    lost = _ev(report, "rx_lost")
    assert lost and 4.95 <= lost[-1] < 5.0  # the loss is stamped with the last frame taken
    stage1 = [t for t in _ev(report, "failsafe_stage1") if t >= 5.0]
    assert stage1 and stage1[0] <= 5.0 + 0.1 + 0.03  # rx_timeout_ms after it, at the 100 Hz safety task
    assert [t for t in _ev(report, "failsafe_stage2") if t >= 5.0]
    disarmed = _ev(report, "disarmed")
    assert disarmed and disarmed[-1] > 5.5 and not report["armed"] and not report["crashed"]
    assert report["altitude_m"]["final"] < 0.1
    # landed and disarmed: the radio has the craft again
    assert [t for t in _ev(report, "rx_restored") if t > disarmed[-1]]
    assert server.flight.receiver.released == 1


def test_the_override_is_refused_without_maint_override_and_nothing_arms():
    report, server, replies = _fly_override(0, stop_at_s=4.0, duration_s=5.0)
    assert replies and set(replies) == {127}
    assert server.last_error == "autopilot switch is off"
    assert not _ev(report, "armed") and report["altitude_m"]["max"] == 0.0


def test_sticks_on_an_msp_port_say_why_the_controller_refuses_them(sim, gcs_msp):
    assert _until(lambda: gcs_msp.telemetry()["link_ok"])
    pad = Gamepad(gcs_msp, 0.0, False)
    try:
        refusal = _until(lambda: gcs_msp.get("/api/status").json()["override_refusal"], 3.0)
    finally:
        pad.stop()
    # MSP_SET_RAW_RC is the companion computer's source (seed 004): refused until its procedure runs
    assert refusal and "autopilot switch is off" in refusal
    assert not sim.msp_status()[0]


# ------------------------------------------------------------------------------------------ logs
def test_the_logs_screen_lists_flight_logs_and_serves_their_report(tmp_path):
    from hoverfly.sim.runner import SimRun

    SimRun("5inch", "hover", seed=2, duration_s=3.0, log_path=str(tmp_path / "hover.ulg")).run()
    (tmp_path / "notes.txt").write_text("not a log")
    session = Session(None)
    token = new_token()
    client = TestClient(make_app(session, token, (ORIGIN,), tmp_path))
    assert client.get("/api/logs").status_code == 401
    client.headers["X-Hoverfly-Token"] = token
    logs = client.get("/api/logs").json()
    assert [d["name"] for d in logs] == ["hover.ulg"] and logs[0]["size_bytes"] > 1000
    r = client.post("/api/logs/report", json={"name": "../hover.ulg"})
    assert r.status_code == 400 and "no flight log" in r.json()["error"]
    r = client.post("/api/logs/report", json={"name": "hover.ulg"})
    assert r.status_code == 200, r.text
    url = r.json()["url"]
    page = client.get(url)
    assert page.status_code == 200 and "Flight log hover.ulg" in page.text
    assert client.get("/api/logs").json()[0]["report"] == url
    assert client.get(url.replace("index.html", "..%2F..%2Fhover.ulg")).status_code == 404
    assert client.get("/reports/guess/index.html").status_code == 404
