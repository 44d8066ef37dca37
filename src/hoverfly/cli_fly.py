"""`hoverfly fly`: fly a scenario on the simulator and judge the flight."""

import json
import sys

from hoverfly.core.output import PROTOCOLS
from hoverfly.core.params import check
from hoverfly.errors import UserError


def _parse_set(items):
    pairs = []
    for item in items or ():
        if "=" not in item:
            raise UserError("--set expects name=value, got '%s'" % item)
        name, value = item.split("=", 1)
        _, _, err = check(name.strip(), value.strip())  # the table's one check, aliases included
        if err:
            raise UserError("--set %s: %s" % (item.strip()[:60], err))
        pairs.append((name.strip(), value.strip()))
    return pairs


def run_fly(args):
    from hoverfly.sim.runner import fly

    if args.seed < 0:
        raise UserError("--seed must be 0 or more")
    if args.hil and args.firmware != "cpython":
        raise UserError("--hil runs the firmware on the device at the port: leave out --firmware")
    if args.baud <= 0:
        raise UserError("--baud must be a positive rate")
    result = fly(args.scenario, args.airframe, args.seed, _parse_set(args.set), args.duration, args.realtime,
                 firmware=args.firmware, micropython=args.micropython, rx=args.rx,
                 esc=args.esc, log_path=args.log, hil=args.hil, baud=args.baud, bundle=args.bundle)
    if args.json:
        json.dump(result, sys.stdout)
        sys.stdout.write("\n")
    else:
        print(summary(result))
    return 0


def summary(r):
    alt = r["altitude_m"]
    lines = [
        "%s on %s (seed %d): %.1f s flown in %.2f s wall (%.0fx real time), loop %d Hz"
        % (r["scenario"], r["airframe"], r["seed"], r["sim_time_s"], r["wall_time_s"],
           r["realtime_factor"] or 0, r["loop_hz"]),
        "  %s, ended %s; tilt RMS %.2f deg (max %.1f); altitude %.2f..%.2f m, final %.2f m; drift %.2f m"
        % ("CRASHED" if r["crashed"] else "no crash", "armed" if r["armed"] else "disarmed", r["tilt_rms_deg"],
           r["max_tilt_deg"], alt["min"], alt["max"], alt["final"], r["horizontal_drift_m"]),
    ]
    for s in r["steps"]:
        lines.append("  step %s %s %g->%g %s: rise %s ms, 90%% at %s ms, overshoot %.1f %%, settle %s ms, error %s"
                     % (s["axis"], s["mode"], s["from"], s["to"], s["unit"], s["rise_ms"], s["t90_ms"],
                        s["overshoot_pct"], s["settle_ms"], s["steady_error"]))
    for f in r.get("flips", []):
        lines.append("  flip %s: %d ms, lost %.2f m, ended %.1f deg from level"
                     % (f["axis"], f["duration_ms"], f["alt_loss_m"], f["end_tilt_deg"]))
    ev = ", ".join("%s %s@%.2fs" % (e["event"], e["detail"], e["t_s"]) for e in r["events"]
                   if e["event"] not in ("mode", "airmode"))
    lines.append("  events: " + ev)
    o = r.get("outputs")
    if o:
        lines.append("  outputs: %s ESCs, %d frames read, %d rejected, output failsafe tripped %d time(s)%s"
                     % (o["esc"], o["frames"], o["errors"], o["failsafe_trips"],
                        ", RPM " + "/".join(str(x) for x in o["rpm"]) if o.get("rpm") else ""))
    lp = r["loop"]
    lines.append("  flight loop: %.1f us mean, %.0f us max, %d overruns" % (lp["mean_us"], lp["max_us"],
                                                                            lp["overruns"]))
    return "\n".join(lines)


def register(sub):
    p = sub.add_parser("fly", help="fly a scenario on the simulator (default: the demo on the 5inch)")
    p.add_argument("--airframe", default="5inch", help="built-in airframe name or a .toml file")
    p.add_argument("--scenario", default="demo", help="built-in scenario name or a .toml file")
    p.add_argument("--duration", type=float, default=None, help="seconds to fly (default: the scenario's)")
    p.add_argument("--seed", type=int, default=1, help="random seed for sensor noise")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a parameter for this flight")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--realtime", action="store_true", help="pace the flight to the wall clock")
    p.add_argument("--firmware", choices=("cpython", "micropython"), default="cpython",
                   help="where the flight firmware runs: in this process, or under MicroPython over the bridge")
    p.add_argument("--micropython", metavar="PATH", default=None,
                   help="the MicroPython VM for --firmware micropython (default: micropython on PATH)")
    p.add_argument("--bundle", metavar="DIR", default=None,
                   help="with --firmware micropython: run the firmware from a flash bundle, precompiled as a "
                        "board gets it (hoverfly flash --out DIR --chip unix-x64)")
    p.add_argument("--hil", metavar="PORT", default=None,
                   help="hardware in the loop: the firmware on a device at this serial port or pyserial URL "
                        "(a Pico running boards/rp2/hil.py; docs/hil.md)")
    p.add_argument("--baud", type=int, default=115200,
                   help="baud rate for --hil (USB CDC ignores it; default 115200)")
    p.add_argument("--rx", choices=("crsf", "sbus", "ibus", "ppm", "pwm"), default="crsf",
                   help="receiver protocol on the simulated wire (default crsf: ExpressLRS 250 Hz)")
    p.add_argument("--esc", choices=PROTOCOLS, default="dshot600",
                   help="ESC protocol on the simulated motor wires (default dshot600)")
    p.add_argument("--log", metavar="PATH.ulg", default=None,
                   help="write a flight log (PX4 ULog) at blackbox_rate_hz; see `hoverfly log`")
    p.set_defaults(func=run_fly)
