"""The ground station's web app: the page, the JSON API and the telemetry WebSocket (docs/gcs.md "API").

Takes a Session (gcs/session.py: the link) and the start's token; gives a Starlette app. Every
/api call and the WebSocket must carry the token (header X-Hoverfly-Token or ?token=), and the
WebSocket's Origin must be the app's own: the server listens on 127.0.0.1 only, but any page in
the user's browser can reach 127.0.0.1, and this app can spin motors. The session's calls block
on the serial link, so they run in worker threads; the WebSocket pushes telemetry at 50 Hz and
takes the sticks, and its closing ends the sticks and the motor test it may have been driving.
"""

import asyncio
import json
import secrets
import time
from pathlib import Path

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, PlainTextResponse
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from hoverfly.errors import UserError
from hoverfly.gcs.session import GcsError, Session

STATIC_DIR = Path(__file__).parent / "static"
TOKEN_HEADER = "X-Hoverfly-Token"
TELEMETRY_PERIOD_S = 0.02  # 50 Hz to the page
STATUS_PERIOD_S = 1.0
JITTER_REFRESH_S = 10.0


def new_token():
    return secrets.token_urlsafe(24)


def _error(message, status):
    return JSONResponse({"error": message}, status_code=status)


class LogReports:
    """The Logs screen's data: the flight logs (*.ulg) in one directory, and `hoverfly log report` pages
    made from them on request. A report is served under /reports/KEY/ with KEY a random name given
    out by the token-checked API (the report's own page links its plots by relative names)."""

    def __init__(self, logs_dir):
        import tempfile

        self.logs_dir = Path(logs_dir) if logs_dir else None
        self.out_root = Path(tempfile.mkdtemp(prefix="hoverfly-gcs-reports-"))
        self.reports = {}  # key -> directory
        self.by_name = {}  # log name -> key

    def list(self):
        if self.logs_dir is None or not self.logs_dir.is_dir():
            return []
        out = []
        for p in self.logs_dir.glob("*.ulg"):
            try:
                st = p.stat()
            except OSError:
                continue
            out.append({"name": p.name, "size_bytes": st.st_size, "modified": int(st.st_mtime),
                        "report": ("/reports/%s/index.html" % self.by_name[p.name]) if p.name in self.by_name
                        else None})
        out.sort(key=lambda d: -d["modified"])
        return out

    def report(self, name):
        from hoverfly.logs.data import load
        from hoverfly.logs.report import write_report

        if not isinstance(name, str) or name not in {d["name"] for d in self.list()}:
            raise GcsError("no flight log named %r in %s" % (name, self.logs_dir))
        key = secrets.token_urlsafe(12)
        out = self.out_root / key
        try:
            log = load(str(self.logs_dir / name))
            r = write_report(log, str(out))
        except UserError as exc:
            raise GcsError("%s: %s" % (name, exc)) from None
        except (OSError, ValueError) as exc:
            raise GcsError("%s cannot be read: %s" % (name, exc)) from None
        self.reports[key] = out
        self.by_name[name] = key
        return {"name": name, "url": "/reports/%s/index.html" % key, "warnings": list(log.warnings),
                "steps": len(r["steps"])}

    def file(self, key, filename):
        d = self.reports.get(key)
        if d is None or "/" in filename or "\\" in filename or filename.startswith("."):
            return None
        p = d / filename
        return p if p.is_file() else None


def make_app(session, token, allowed_origins=(), logs_dir=None):
    """The Starlette app over `session`. allowed_origins: the Origin values the WebSocket accepts
    (the server's own http://127.0.0.1:N and http://localhost:N). logs_dir: where the Logs screen
    finds flight logs (*.ulg); None for none."""
    origins = set(allowed_origins)
    state = {"jitter_at": 0.0, "sockets": 0}
    logs = LogReports(logs_dir)

    def token_ok(conn):
        given = conn.headers.get(TOKEN_HEADER) or conn.query_params.get("token") or ""
        return secrets.compare_digest(given.encode(), token.encode())

    def api(fn, body=False):
        async def endpoint(request: Request):
            if not token_ok(request):
                return _error("missing or wrong token: open the URL that hoverfly gcs printed", 401)
            args = ()
            if body:
                try:
                    data = await request.json()
                except (json.JSONDecodeError, UnicodeDecodeError, ValueError):
                    return _error("the request body must be JSON", 400)
                args = (data,)
            try:
                result = await run_in_threadpool(fn, *args)
            except GcsError as exc:
                return _error(str(exc), exc.status)
            if isinstance(result, str):
                return PlainTextResponse(result)
            return JSONResponse(result)

        return endpoint

    def status():
        now = time.monotonic()
        if now - state["jitter_at"] > JITTER_REFRESH_S and session.override != "sending":
            state["jitter_at"] = now
            session.refresh_loop_stats()
        return session.status()

    def need_dict(data, *keys):
        if not isinstance(data, dict):
            raise GcsError("send a JSON object")
        return [data.get(k) for k in keys]

    def connect(data):
        (url,) = need_dict(data, "url")
        if not isinstance(url, str) or not url.strip():
            raise GcsError("url: a port such as /dev/ttyACM0 or socket://127.0.0.1:5761")
        return session.connect(url.strip())

    def disconnect():
        session.disconnect()
        return {"ok": True}

    def set_params(data):
        return session.set_params(data)

    def diff_preview(data):
        return session.diff_preview(need_dict(data, "text")[0])

    def diff_apply(data):
        return session.diff_apply(need_dict(data, "text")[0])

    def motor_test(data):
        props, values = need_dict(data, "props_removed", "values")
        return session.motor_test(props, values)

    def maint_command(data):
        name, args = need_dict(data, "name", "args")
        return session.maint_command(name, args if args is not None else [])

    def maint_read(data):
        return session.maint_read(need_dict(data, "fields")[0])

    def maint_fields():
        from hoverfly.protocols import maintenance as mp

        return [f[0] for f in mp.FIELDS]

    def rc_arm(data):
        return session.set_arm(need_dict(data, "arm")[0])

    def log_report(data):
        return logs.report(need_dict(data, "name")[0])

    async def report_file(request: Request):
        p = logs.file(request.path_params["key"], request.path_params["filename"])
        if p is None:
            return PlainTextResponse("no such report", status_code=404)
        return FileResponse(p)

    async def index(request: Request):
        if not token_ok(request):
            return PlainTextResponse("Open the URL that `hoverfly gcs` printed: it carries this start's token.",
                                     status_code=401)
        return FileResponse(STATIC_DIR / "index.html")

    async def ws_endpoint(ws: WebSocket):
        origin = ws.headers.get("origin")
        if not token_ok(ws) or origin not in origins:
            await ws.close(code=1008)  # refused before the handshake completes: HTTP 403
            return
        await ws.accept()
        state["sockets"] += 1
        closed = asyncio.Event()

        async def push():
            last_status = 0.0
            while not closed.is_set():
                await ws.send_text(json.dumps(session.telemetry))
                now = time.monotonic()
                if now - last_status >= STATUS_PERIOD_S:
                    last_status = now
                    body = session.status()
                    body["t"] = "status"
                    await ws.send_text(json.dumps(body))
                await asyncio.sleep(TELEMETRY_PERIOD_S)

        sender = asyncio.create_task(push())
        try:
            while True:
                text = await ws.receive_text()
                try:
                    msg = json.loads(text)
                except ValueError:
                    await ws.send_text(json.dumps({"t": "error", "error": "not JSON"}))
                    continue
                if isinstance(msg, dict) and msg.get("t") == "sticks":
                    err = session.set_sticks(msg)
                    if err:
                        await ws.send_text(json.dumps({"t": "error", "error": err}))
                else:
                    await ws.send_text(json.dumps({"t": "error", "error": "unknown message"}))
        except (WebSocketDisconnect, RuntimeError):
            pass
        finally:
            closed.set()
            sender.cancel()
            state["sockets"] -= 1
            # SAFETY: the page is gone: its sticks stop now (the controller's link watch takes over) and a
            # motor test it drove stops.
            session.sticks_gone()
            await run_in_threadpool(_stop_motors, session)

    routes = [
        Route("/", index),
        Route("/api/status", api(status)),
        Route("/api/connect", api(connect, True), methods=["POST"]),
        Route("/api/disconnect", api(disconnect), methods=["POST"]),
        Route("/api/params", api(session.params)),
        Route("/api/params", api(set_params, True), methods=["POST"]),
        Route("/api/save", api(session.save), methods=["POST"]),
        Route("/api/diff", api(session.diff_text)),
        Route("/api/diff/preview", api(diff_preview, True), methods=["POST"]),
        Route("/api/diff/apply", api(diff_apply, True), methods=["POST"]),
        Route("/api/motor_test", api(motor_test, True), methods=["POST"]),
        Route("/api/motor_test/stop", api(session.motor_stop), methods=["POST"]),
        Route("/api/maint/commands", api(session.maint_commands)),
        Route("/api/maint/command", api(maint_command, True), methods=["POST"]),
        Route("/api/maint/fields", api(maint_fields)),
        Route("/api/maint/read", api(maint_read, True), methods=["POST"]),
        Route("/api/rc/arm", api(rc_arm, True), methods=["POST"]),
        Route("/api/logs", api(logs.list)),
        Route("/api/logs/report", api(log_report, True), methods=["POST"]),
        Route("/reports/{key}/{filename}", report_file),
        WebSocketRoute("/ws", ws_endpoint),
    ]
    if STATIC_DIR.is_dir():
        routes.append(Mount("/static", StaticFiles(directory=STATIC_DIR), name="static"))
    app = Starlette(routes=routes)
    app.state.session = session
    app.state.token = token
    app.state.logs = logs
    return app


def _stop_motors(session):
    if session.motor_values is not None or session.motor_props:
        try:
            session.motor_stop()
        except GcsError:
            pass


__all__ = ["make_app", "new_token", "Session"]
