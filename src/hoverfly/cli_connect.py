"""`hoverfly connect URL`: the controller's CLI from a terminal (or a script), over any serial link.

Opens the URL (gcs/link.py), enters the CLI with `#`, then passes each stdin line to it and prints
what it answers. `exit` or end of input leaves the CLI (the controller returns to MSP); `save`
(or `defaults`) ends the session too, as on Betaflight. Used by people at a terminal and by
scripts piping commands in; `hoverfly params` is the scripted form for parameters.
"""

import sys

from hoverfly.errors import UserError
from hoverfly.gcs.link import CliSession, open_link


def run_connect(args):
    if not args.timeout > 0:
        raise UserError("--timeout must be more than 0 s")
    port = open_link(args.url, args.timeout)
    try:
        cli = CliSession(port, args.timeout)
        banner = cli.enter()
        interactive = sys.stdin.isatty()
        if interactive:
            print(banner)
        while cli.active:
            if interactive:
                print("# ", end="", flush=True)
            line = sys.stdin.readline()
            if not line:  # end of input
                break
            line = line.strip()
            if not line:
                continue
            for text in cli.command(line):
                print(text)
            sys.stdout.flush()
        if cli.active:
            cli.exit()
    finally:
        port.close()
    return 0


def register(sub):
    p = sub.add_parser("connect",
                       help="the controller's CLI over a serial link (stdin lines in, replies out)")
    p.add_argument("url",
                   help="pyserial URL: /dev/ttyACM0, socket://127.0.0.1:5761 (hoverfly sim), /dev/rfcomm0")
    p.add_argument("--timeout", type=float, default=2.0, metavar="S",
                   help="seconds to wait for an answer (2)")
    p.set_defaults(func=run_connect)
