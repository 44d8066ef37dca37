"""The ground station end to end: Debian's chromium (headless, driven by Playwright) on the page that
`hoverfly gcs` serves, against a real simulator on 127.0.0.1.

What a user does, judged on what the controller did: connect; change a parameter, save, restart the
simulator and see it kept; a value out of range refused in the table with nothing sent; import a diff
and see its preview; the props-off motor test and its dead-man; a scripted gamepad (an init script
standing in for navigator.getGamepads) arms, takes off, hovers and lands the quad, judged on the sim's
own flight report; and losing the gamepad in a hover ends in the controller's failsafe. Screenshots of
every screen go to out/gcs/ (look at them).
"""

import json
import shutil
import socket
import subprocess
import sys
import threading
import time

import pytest

pytest.importorskip("playwright")
pytest.importorskip("starlette")

from test_gcs_api import REPO, Sim, _free_port  # noqa: E402

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
if CHROMIUM is None:
    pytest.skip("Debian's chromium is not installed (./dev test installs it)", allow_module_level=True)

from playwright.sync_api import expect, sync_playwright  # noqa: E402

OUT = REPO / "out" / "gcs"
SCREENS = ("status", "params", "receiver", "motors", "sensors", "maint", "fly", "logs")

# A gamepad the test holds: the page polls navigator.getGamepads() (docs/gcs.md "UI", Fly). Standard
# mapping, mode 2: axes[0] yaw, [1] throttle (+1 = stick down = zero), [2] roll, [3] pitch.
GAMEPAD_STUB = """
window.__pad = {id: "hoverfly test pad (STANDARD GAMEPAD)", index: 0, connected: true, mapping: "standard",
                timestamp: 0, axes: [0, 1, 0, 0], buttons: []};
navigator.getGamepads = () => (window.__pad && window.__pad.connected) ? [window.__pad] : [];
"""


class GcsProcess:
    """`hoverfly gcs` as a user starts it; its URL (with the token) from what it prints."""

    def __init__(self, url, logs_dir=None):
        self.http_port = _free_port()
        port = ["--port", url] if url else []
        logs = ["--logs", str(logs_dir)] if logs_dir else []
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "hoverfly.cli", "gcs"] + port + logs
            + ["--http-port", str(self.http_port), "--no-browser"],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=REPO)
        self.url = None
        deadline = time.monotonic() + 20
        while self.url is None and time.monotonic() < deadline:
            line = self.proc.stdout.readline()
            if not line:
                break
            if "open http" in line:
                self.url = line.split("open ", 1)[1].strip()
        assert self.url, "hoverfly gcs printed no URL"
        self.token = self.url.split("token=")[1]
        self.base = "http://127.0.0.1:%d" % self.http_port

    def api(self, path, body=None):
        import httpx

        headers = {"X-Hoverfly-Token": self.token}
        if body is None:
            r = httpx.get(self.base + path, headers=headers, timeout=10)
        else:
            r = httpx.post(self.base + path, headers=headers, json=body, timeout=10)
        return r

    def param(self, name):
        return {p["name"]: p["value"] for p in self.api("/api/params").json()}[name]

    def stop(self):
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(10)


@pytest.fixture(scope="module")
def browser():
    OUT.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True)
        yield b
        b.close()


def _page(browser, url, gamepad=False):
    ctx = browser.new_context(viewport={"width": 1366, "height": 800})
    if gamepad:
        ctx.add_init_script(GAMEPAD_STUB)
    page = ctx.new_page()
    page.goto(url)
    expect(page.locator("#link-state")).to_have_attribute("data-state", "connected", timeout=15000)
    return page


def _shot(page, name):
    page.screenshot(path=str(OUT / ("%s.png" % name)))


@pytest.fixture
def sim(tmp_path):
    s = Sim(tmp_path)
    s.start()
    yield s
    s.stop()


# ---------------------------------------------------------------------------------- configurator
def test_every_screen_shows_and_is_kept_as_a_screenshot(browser, sim):
    g = GcsProcess(sim.url("msp"))
    try:
        page = _page(browser, g.url)
        expect(page.locator("#status-protocol")).to_contain_text("msp", ignore_case=True)
        for name in SCREENS:
            page.click("#nav-" + name)
            expect(page.locator("#screen-" + name)).to_be_visible()
            if name == "params":
                expect(page.locator("[data-param=p_roll]")).to_be_visible(timeout=10000)
            if name == "sensors":
                page.wait_for_timeout(1500)  # a second and a half of plots
            else:
                page.wait_for_timeout(300)
            _shot(page, name)
        for name in SCREENS:
            assert (OUT / ("%s.png" % name)).stat().st_size > 10000, name
        page.context.close()
    finally:
        g.stop()


def test_a_port_that_is_no_flight_controller_is_named_in_the_page(browser, sim):
    printer = socket.socket()  # accepts, and answers anything with text: not MSP, not the maintenance protocol
    printer.bind(("127.0.0.1", 0))
    printer.listen(2)
    stop = threading.Event()

    def serve():
        printer.settimeout(0.1)
        while not stop.is_set():
            try:
                conn, _ = printer.accept()
            except OSError:
                continue
            conn.settimeout(0.1)
            while not stop.is_set():
                try:
                    if not conn.recv(256):
                        break
                    conn.sendall(b"READY\r\n")
                except TimeoutError:
                    continue
                except OSError:
                    break
            conn.close()

    threading.Thread(target=serve, daemon=True).start()
    g = GcsProcess(None)
    try:
        ctx = browser.new_context(viewport={"width": 1366, "height": 800})
        page = ctx.new_page()
        page.goto(g.url)
        expect(page.locator("#link-state")).to_have_attribute("data-state", "disconnected", timeout=10000)
        page.fill("#connect-url", "socket://127.0.0.1:%d" % printer.getsockname()[1])
        page.click("#connect-btn")
        expect(page.locator("#link-state")).to_contain_text("neither MSP nor the seed-001", timeout=10000)
        expect(page.locator("#messages")).to_contain_text("neither MSP nor the seed-001")
        _shot(page, "not-a-controller")
        page.fill("#connect-url", sim.url("msp"))  # and the right port afterwards: nothing stuck
        page.click("#connect-btn")
        expect(page.locator("#link-state")).to_have_attribute("data-state", "connected", timeout=15000)
        ctx.close()
    finally:
        stop.set()
        g.stop()
        printer.close()


def test_a_parameter_changed_and_saved_is_kept_across_a_sim_restart(browser, sim):
    g = GcsProcess(sim.url("msp"))
    try:
        page = _page(browser, g.url)
        page.click("#nav-params")
        page.fill("#param-search", "p_roll")
        box = page.locator("[data-param=p_roll]")
        expect(box).to_be_visible(timeout=10000)
        before = g.param("p_roll")
        # out of range: the row says why, nothing can be sent
        box.fill("300")
        box.dispatch_event("change")
        expect(page.locator("tr[data-name=p_roll]")).to_have_class(__import__("re").compile("invalid"))
        expect(page.locator("#param-save")).to_be_disabled()
        assert g.param("p_roll") == before
        _shot(page, "params-invalid")
        box.fill("66")
        box.dispatch_event("change")
        expect(page.locator("#param-save")).to_be_enabled()
        page.click("#param-save")
        expect(page.locator("#messages .msg.info").last).to_be_visible(timeout=10000)
        assert g.param("p_roll") == 66
        sim.stop()
        expect(page.locator("#link-state")).not_to_have_attribute("data-state", "connected", timeout=10000)
        _shot(page, "link-lost")
        sim.start()
        expect(page.locator("#link-state")).to_have_attribute("data-state", "connected", timeout=20000)
        page.click("#param-reload")
        expect(page.locator("[data-param=p_roll]")).to_have_value("66", timeout=10000)
        page.context.close()
    finally:
        g.stop()


def test_an_imported_diff_is_previewed_before_anything_is_sent(browser, sim):
    g = GcsProcess(sim.url("msp"))
    try:
        page = _page(browser, g.url)
        page.click("#nav-params")
        before = g.param("p_pitch")
        page.fill("#diff-text", "# a diff from another quad\nset p_pitch = 57\nset no_such_thing = 1\n")
        page.click("#diff-preview-btn")
        expect(page.locator("#diff-preview-table tr[data-name=p_pitch]")).to_be_visible(timeout=10000)
        expect(page.locator("#diff-errors")).to_contain_text("no_such_thing")
        expect(page.locator("#diff-apply")).to_be_disabled()  # a file with errors is not applied
        _shot(page, "params-diff-preview")
        assert g.param("p_pitch") == before  # the preview sent nothing
        page.fill("#diff-text", "set p_pitch = 57\n")
        page.click("#diff-preview-btn")
        expect(page.locator("#diff-apply")).to_be_enabled(timeout=10000)
        page.click("#diff-apply")
        expect(page.locator("[data-param=p_pitch]")).to_have_value("57", timeout=10000)
        assert g.param("p_pitch") == 57
        page.context.close()
    finally:
        g.stop()


def test_the_maintenance_screen_reads_header_fields_and_runs_seed_commands(browser, sim):
    g = GcsProcess(sim.url("maint"))
    try:
        page = _page(browser, g.url)
        expect(page.locator("#status-protocol")).to_contain_text("maint", ignore_case=True)
        page.click("#nav-maint")
        page.check("#maint-fields input[data-field=sw_ver]")
        page.check("#maint-fields input[data-field=PID_params]")
        page.click("#maint-read")
        expect(page.locator("#maint-reply")).to_contain_text("sw_ver", timeout=5000)
        expect(page.locator("#maint-reply")).to_contain_text("PID_params")
        # a pulse out of the seed's range: refused with the reason, nothing sent
        form = page.locator("form.maint-cmd[data-command=set_motor1]")
        form.locator("[data-arg=pulse_us]").fill("2500")
        form.locator("button[type=submit]").click()
        expect(page.locator("#messages .msg").last).to_contain_text("set_motor1", timeout=5000)
        # the roll PID through the seed's command: P (KP) 52 reads back as p_roll
        pid = page.locator("form.maint-cmd[data-command=set_roll_pid]")
        for arg, value in (("kp", "52"), ("ki", "80"), ("kt", "0"), ("sat", "400"), ("ad", "0"), ("bd", "40")):
            pid.locator("[data-arg=%s]" % arg).fill(value)
        pid.locator("button[type=submit]").click()
        expect(page.locator("#maint-reply")).to_contain_text("set_roll_pid: ok", timeout=5000)
        assert g.param("p_roll") == 52
        _shot(page, "maint")
        page.context.close()
    finally:
        g.stop()


def test_the_logs_screen_lists_a_flight_log_and_shows_its_report(browser, sim, tmp_path):
    from hoverfly.sim.runner import SimRun

    SimRun("5inch", "hover", seed=4, duration_s=3.0, log_path=str(tmp_path / "hover.ulg")).run()
    g = GcsProcess(sim.url("msp"), tmp_path)
    try:
        page = _page(browser, g.url)
        page.click("#nav-logs")
        expect(page.locator("#logs-body tr[data-log='hover.ulg']")).to_be_visible(timeout=10000)
        page.click("button[data-report='hover.ulg']")
        frame = page.frame_locator("#log-report")
        expect(frame.locator("h1")).to_contain_text("Flight log hover.ulg", timeout=60000)
        _shot(page, "logs")
        page.context.close()
    finally:
        g.stop()


def _motors(g):
    """The controller's motor outputs (MSP_MOTOR through the app's WebSocket, as the page sees them)."""
    from websockets.sync.client import connect

    with connect("ws://127.0.0.1:%d/ws?token=%s" % (g.http_port, g.token),
                 origin="http://127.0.0.1:%d" % g.http_port) as ws:
        for _ in range(20):
            m = json.loads(ws.recv(5))
            if m.get("t") == "telemetry" and m.get("motors"):
                return m["motors"]
    return []


def test_the_motor_test_needs_the_props_off_confirmation_and_stops_on_its_dead_man(browser, sim):
    g = GcsProcess(sim.url("msp"))
    try:
        page = _page(browser, g.url)
        page.click("#nav-motors")
        slider = page.locator("#motor-slider-1")
        # the sliders end at the controller's cap, and the page says whose cap it is
        expect(page.locator("#motor-cap")).to_contain_text("30 % by the controller's motor_test_pct", timeout=5000)
        expect(slider).to_have_attribute("max", "30")
        expect(slider).to_be_disabled()
        page.check("#motor-props-removed")
        expect(slider).to_be_enabled()
        slider.focus()
        for _ in range(15):
            page.keyboard.press("ArrowUp")
        expect(page.locator("#motor-state")).to_contain_text("running", timeout=5000)
        page.wait_for_timeout(300)
        assert _motors(g)[0] > 1050
        _shot(page, "motors-running")
        slider.blur()  # the pointer lets go: the slider drops and the test stops
        expect(page.locator("#motor-state")).to_contain_text("stopped", timeout=5000)
        time.sleep(0.3)
        assert all(m <= 1000 for m in _motors(g))
        # The page goes away mid-test (a crashed tab sends nothing more): the backend's dead-man stops it.
        slider.focus()
        for _ in range(15):
            page.keyboard.press("ArrowUp")
        expect(page.locator("#motor-state")).to_contain_text("running", timeout=5000)
        page.context.close()
        t0 = time.monotonic()
        while time.monotonic() - t0 < 3.0 and not all(m <= 1000 for m in _motors(g)):
            time.sleep(0.1)
        assert all(m <= 1000 for m in _motors(g)), "motors still running after the page went away"
        assert time.monotonic() - t0 < 1.5
    finally:
        g.stop()


# --------------------------------------------------------------------------------------- flying
class InProcessSim:
    """The simulator in this process (real TCP ports on 127.0.0.1), so the test pilot can see the craft
    and the flight report is the sim's own (SimServer.serve's summary at the end of its duration)."""

    def __init__(self, duration_s):
        from hoverfly.core.board import SERIAL_MAINT
        from hoverfly.sim.server import SimServer

        # rx_timeout_ms 300 instead of 100: this machine runs several test suites at once, and a realtime
        # sim that stalls and catches up sees a gap in the override's frames that no link had.
        self.server = SimServer("5inch", 0, 0, None, duration_s, overrides=(("rx_timeout_ms", 300),))
        self.vehicle = self.server.run.vehicle
        self.url = "socket://127.0.0.1:%d" % self.server.ports.address(SERIAL_MAINT)[1]
        self.hover = self.server.run.pilot.hover_guess / 0.9
        self.thread = threading.Thread(target=self.server.serve, daemon=True)
        self.thread.start()

    def t_s(self):
        return self.server.run.board.sim_us * 1e-6

    def report(self, timeout_s):
        self.thread.join(timeout_s)
        assert not self.thread.is_alive(), "the simulator did not finish"
        return self.server.result


def _throttle_axis(page, thr):
    page.evaluate("v => { window.__pad.axes[1] = v; window.__pad.timestamp += 1; }", 1.0 - 2.0 * thr)


def _fly_to(page, sim, target_m, secs):
    """The test pilot: throttle from the altitude it sees, as a person on the sticks would."""
    end = time.monotonic() + secs
    v = sim.vehicle
    while time.monotonic() < end:
        thr = sim.hover + 0.08 * (target_m - v.altitude_m()) + 0.06 * v.vd
        _throttle_axis(page, max(0.04, min(0.9, thr)))
        time.sleep(0.04)


def _land(page, sim, descent_m_s, secs):
    """Down at a steady rate until the craft sits on the ground, as a pilot lands."""
    end = time.monotonic() + secs
    v = sim.vehicle
    while time.monotonic() < end and not (v.on_ground and v.altitude_m() < 0.05):
        thr = sim.hover + 0.15 * (v.vd - descent_m_s)
        _throttle_axis(page, max(0.04, min(0.9, thr)))
        time.sleep(0.04)


def _events(report, name):
    return [e for e in report["events"] if e["event"] == name]


def test_a_scripted_gamepad_arms_takes_off_hovers_and_lands(browser):
    sim = InProcessSim(30.0)
    g = GcsProcess(sim.url)
    try:
        page = _page(browser, g.url, gamepad=True)
        page.click("#nav-fly")
        expect(page.locator("#fly-state")).to_have_attribute("data-state", "ready", timeout=10000)
        while sim.t_s() < 1.3:  # the controller's boot grace
            time.sleep(0.1)
        page.click("#fly-arm")
        expect(page.locator("#fly-state")).to_have_attribute("data-state", "armed", timeout=5000)
        _fly_to(page, sim, 1.5, 5.0)
        _shot(page, "fly")
        _fly_to(page, sim, 1.5, 4.0)  # hover
        _land(page, sim, 0.5, 10.0)
        impact_m_s = sim.vehicle.impact_m_s
        _throttle_axis(page, 0.0)
        page.wait_for_timeout(500)
        page.click("#fly-arm")  # DISARM
        expect(page.locator("#fly-state")).not_to_have_attribute("data-state", "armed", timeout=5000)
        report = sim.report(40.0)
    finally:
        g.stop()
    armed = _events(report, "armed")
    assert armed and armed[0]["detail"] == "switch", report["events"]
    assert 1.0 <= report["altitude_m"]["max"] <= 2.5, report["altitude_m"]
    assert report["altitude_m"]["final"] < 0.1
    events = [(e["t_s"], e["event"], e["detail"]) for e in report["events"]]
    assert report["max_tilt_deg"] < 10.0 and not report["armed"], events
    assert not report["crashed"] and impact_m_s < 1.5, impact_m_s
    assert not _events(report, "failsafe_stage2")


def test_losing_the_gamepad_in_a_hover_ends_in_the_controllers_failsafe(browser):
    sim = InProcessSim(30.0)
    g = GcsProcess(sim.url)
    try:
        page = _page(browser, g.url, gamepad=True)
        page.click("#nav-fly")
        expect(page.locator("#fly-state")).to_have_attribute("data-state", "ready", timeout=10000)
        while sim.t_s() < 1.3:
            time.sleep(0.1)
        page.click("#fly-arm")
        expect(page.locator("#fly-state")).to_have_attribute("data-state", "armed", timeout=5000)
        _fly_to(page, sim, 2.0, 6.0)
        lost_at = sim.t_s()
        page.evaluate("window.__pad.connected = false")  # unplugged
        expect(page.locator("#fly-state")).to_have_attribute("data-state", "lost", timeout=2000)
        page.wait_for_timeout(1000)
        _shot(page, "fly-lost")
        page.context.close()
        report = sim.report(40.0)
    finally:
        g.stop()
    stage1 = [e for e in _events(report, "failsafe_stage1") if e["t_s"] > lost_at]
    assert stage1, report["events"]
    assert stage1[0]["t_s"] - lost_at < 1.2  # sticks stale in 250 ms, the link watch rx_timeout_ms later
    assert [e for e in _events(report, "failsafe_stage2") if e["t_s"] > lost_at]
    assert not report["crashed"] and not report["armed"]  # landed by the failsafe and disarmed
    assert report["altitude_m"]["final"] < 0.1
    assert report["max_tilt_deg"] < 15.0
