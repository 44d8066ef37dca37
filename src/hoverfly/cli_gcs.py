"""`hoverfly gcs`: the ground station in the browser (docs/gcs.md).

Opens the link (`--port URL`, any pyserial URL; optional: the page can connect later), serves the
web app on 127.0.0.1 only with a per-start token, prints the URL with the token and opens it in the
browser (unless --no-browser). Ctrl-C stops it; a motor test still running is stopped on the way out.
"""

import socket
import sys

from hoverfly.errors import UserError

HOST = "127.0.0.1"  # loopback only, by design: the app can spin motors


def listen_socket(port):
    """A listening TCP socket on 127.0.0.1:port (0 = any free port); UserError naming the reason."""
    if not (0 <= port <= 65535):
        raise UserError("--http-port must be 0..65535")
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        s.bind((HOST, port))
    except OSError as exc:
        s.close()
        raise UserError("cannot serve on %s:%d: %s" % (HOST, port, exc.strerror or exc)) from None
    s.listen(64)
    return s


def run_gcs(args):
    try:
        import uvicorn

        from hoverfly.gcs.app import make_app, new_token
        from hoverfly.gcs.session import Session
    except ImportError as exc:
        raise UserError("the ground station needs starlette and uvicorn: pip install -e . (%s)" % exc) from None
    if not args.timeout > 0:
        raise UserError("--timeout must be more than 0 s")
    sock = listen_socket(args.http_port)
    port = sock.getsockname()[1]
    token = new_token()
    session = Session(args.port, args.timeout)
    session.start()
    origins = ("http://%s:%d" % (HOST, port), "http://localhost:%d" % port)
    app = make_app(session, token, origins, args.logs)
    url = "http://%s:%d/?token=%s" % (HOST, port, token)
    link = session.link_state()
    if args.port is None:
        what = "no link yet (connect from the page)"
    elif link["connected"]:
        what = "%s speaks %s" % (args.port, "MSP + CLI" if link["protocol"] == "msp" else "seed-001 maintenance")
    else:
        what = "%s: %s (retrying every second)" % (args.port, link["error"])
    print("hoverfly gcs: %s" % what, flush=True)
    print("hoverfly gcs: open %s" % url, flush=True)
    if not args.no_browser:
        import webbrowser

        try:
            webbrowser.open(url)
        except Exception:  # noqa: BLE001 - no browser is not an error: the URL is printed
            pass
    config = uvicorn.Config(app, log_level="warning", lifespan="off", ws="websockets-sansio")
    server = uvicorn.Server(config)
    try:
        server.run(sockets=[sock])
    except KeyboardInterrupt:
        pass
    finally:
        session.close()
        sock.close()
        import shutil

        shutil.rmtree(app.state.logs.out_root, ignore_errors=True)
    print("hoverfly gcs: stopped", file=sys.stderr)
    return 0


def register(sub):
    p = sub.add_parser("gcs", help="the ground station in the browser: status, parameters, motors, sensors, fly")
    p.add_argument("--port", default=None, metavar="URL",
                   help="the controller's port: /dev/ttyACM0, socket://127.0.0.1:5762 (hoverfly sim), /dev/rfcomm0")
    p.add_argument("--http-port", type=int, default=0, metavar="N",
                   help="the web app's port on 127.0.0.1 (default: any free port)")
    p.add_argument("--no-browser", action="store_true", help="print the URL, do not open a browser")
    p.add_argument("--timeout", type=float, default=1.0, metavar="S", help="seconds to wait for the controller (1)")
    p.add_argument("--logs", default=".", metavar="DIR",
                   help="where the Logs screen finds flight logs (*.ulg) and makes their reports (default: here)")
    p.set_defaults(func=run_gcs)
