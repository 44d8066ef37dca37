"""`hoverfly sim`: run the simulator in real time and serve CLI+MSP and the maintenance protocol on TCP."""

import sys

from hoverfly.errors import UserError


def run_sim(args):
    from hoverfly.sim.airframes import load_airframe
    from hoverfly.sim.server import SimServer

    for name, port in (("--msp-port", args.msp_port), ("--maint-port", args.maint_port)):
        if not (0 <= port <= 65535):
            raise UserError("%s must be 0..65535" % name)
    if args.msp_port == args.maint_port and args.msp_port != 0:
        raise UserError("--msp-port and --maint-port must differ")
    if args.duration is not None and args.duration <= 0:
        raise UserError("--duration must be more than 0 s")
    load_airframe(args.airframe)  # an unknown airframe is a UserError before any port opens
    server = SimServer(args.airframe, args.msp_port, args.maint_port, args.storage, args.duration,
                       log_path=args.log)
    print(server.describe(), flush=True)
    try:
        server.serve()
    except KeyboardInterrupt:
        pass
    print("hoverfly sim: stopped", file=sys.stderr)
    return 0


def register(sub):
    p = sub.add_parser("sim", help="run the simulator in real time; serve CLI+MSP and maintenance on TCP")
    p.add_argument("--airframe", default="5inch", help="airframe name (default 5inch)")
    p.add_argument("--msp-port", type=int, default=5761, help="TCP port for CLI + MSP on 127.0.0.1 (5761)")
    p.add_argument("--maint-port", type=int, default=5762,
                   help="TCP port for the seed-001 maintenance protocol on 127.0.0.1 (5762)")
    p.add_argument("--storage", default=None, metavar="PATH",
                   help="parameter storage file (loaded at start, written by save); none = not kept")
    p.add_argument("--duration", type=float, default=None, metavar="S", help="stop after S seconds")
    p.add_argument("--log", default=None, metavar="PATH.ulg", help="write a ULog flight log (closed on exit)")
    p.set_defaults(func=run_sim)
