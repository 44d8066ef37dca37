"""`hoverfly fly`: fly a scenario on the simulator and judge the flight."""

import json
import sys

from hoverfly.cli_live import event_text
from hoverfly.core.config.params import check
from hoverfly.core.stages.output import PROTOCOLS
from hoverfly.errors import UserError
from hoverfly.logs.steps import step_line


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
    if args.scenario is None:
        args.scenario = _default_scenario(args.airframe)
    if args.realtime and not args.json:
        return _fly_live(args)
    result = fly(args.scenario, args.airframe, args.seed, _parse_set(args.set), args.duration, args.realtime,
                 firmware=args.firmware, micropython=args.micropython, rx=args.rx,
                 esc=args.esc, log_path=args.log, hil=args.hil, baud=args.baud, bundle=args.bundle)
    if args.json:
        json.dump(result, sys.stdout)
        sys.stdout.write("\n")
    else:
        print(summary(result))
    return 0


def _default_scenario(airframe):
    """With no --scenario: the demo for a multirotor, the box circuit (hand launch, climb, four turns) for a plane."""
    from hoverfly.sim.airframes import load_airframe

    return "box" if load_airframe(airframe).get("kind") == "plane" else "demo"


def _fly_live(args):
    """--realtime: the flight paced to the wall clock under a live panel (cli_live.py); the summary at the end,
    or where it stood when Ctrl-C stopped it (exit 130, the log closed and readable)."""
    from hoverfly.cli_live import LiveView
    from hoverfly.sim.runner import SimRun

    run = SimRun(args.airframe, args.scenario, args.seed, _parse_set(args.set), args.duration, True,
                 firmware=args.firmware, micropython=args.micropython, rx=args.rx, esc=args.esc, log_path=args.log,
                 hil=args.hil, baud=args.baud, bundle=args.bundle)
    view = LiveView(run)
    try:
        with view:
            result = run.run()
    except KeyboardInterrupt:
        print(view.interrupted_summary())
        return 130
    if run.log is not None:
        result["log"] = run.log.stats()
    if run.firmware_stats is not None:
        result["firmware"] = run.firmware_stats
    print(summary(result))
    return 0


def _m(x):
    """Metres for a person: no '-0.00 m' for a value that rounds to nothing."""
    x = round(x, 2)
    return "%.2f m" % (x + 0.0 if x != 0 else 0.0)


def summary(r):
    alt = r["altitude_m"]
    o = r.get("outputs") or {}
    fw = r.get("firmware_runtime") or "cpython"
    lines = [
        "%s on %s (seed %d), receiver %s, ESCs %s, firmware on %s" % (
            r["scenario"], r["airframe"], r["seed"], r.get("receiver", "?"), o.get("esc", "?"),
            {"cpython": "this Python", "micropython": "MicroPython (bridge)", "hil": "the device (HIL)"}.get(fw, fw)),
        "  %.1f s flown in %.2f s wall (%.0fx real time, %s), loop %d Hz"
        % (r["sim_time_s"], r["wall_time_s"], r["realtime_factor"] or 0, r["loop"].get("timing", "lockstep"),
           r["loop_hz"]),
        "  %s, ended %s; tilt RMS %.2f deg (max %.1f deg); altitude %s..%s, final %s; drift %s"
        % ("CRASHED" if r["crashed"] else "no crash", "armed" if r["armed"] else "disarmed", r["tilt_rms_deg"],
           r["max_tilt_deg"], _m(alt["min"]), _m(alt["max"]), _m(alt["final"]), _m(r["horizontal_drift_m"])),
    ]
    a = r.get("airspeed_m_s")
    if a:  # a plane: its airspeed against its stall speed, and what the judging saw
        lines.append("  airspeed %.1f..%.1f m/s (mean %.1f, stall %.1f); max bank %.1f deg; %s"
                     % (a["min"], a["max"], a["mean"], r["stall_speed_m_s"], r["max_bank_deg"],
                        "%d stall(s), %d spin(s)" % (len(r["stalls"]), len(r["spins"]))
                        if r["stalls"] or r["spins"] else "no stall, no spin"))
    b = r.get("battery")
    if b:
        lines.append("  battery %.2f V at the end, %.0f mAh drawn" % (b["voltage_v"], b["mah_drawn"]))
    for st in r["steps"]:
        lines.append("  " + step_line(st))
    for d in r.get("disturbances", []):
        lines.append("  %s at %.2f s: pushed %.1f deg off, back within 2 deg %s"
                     % (d["kind"], d["t_s"], d["peak_deg"],
                        "never" if d["back_within_2deg_ms"] is None else "after %g ms" % d["back_within_2deg_ms"]))
    for f in r.get("flips", []):
        lines.append("  flip %s: %d ms, lost %s of height, ended %.1f deg from level"
                     % (f["axis"], f["duration_ms"], _m(f["alt_loss_m"]), f["end_tilt_deg"]))
    lines.append("  events: " + ("; ".join(event_text(e) for e in r["events"]) or "none"))
    if o:
        lines.append("  outputs: %s ESCs, %d frames read, %d rejected, output failsafe tripped %d time(s)%s"
                     % (o["esc"], o["frames"], o["errors"], o["failsafe_trips"],
                        ", RPM " + "/".join(str(x) for x in o["rpm"]) if o.get("rpm") else ""))
    lp = r["loop"]
    if lp.get("overruns") is None:
        # Lockstep: the simulated clock steps exactly one period a pass; the wall time a pass takes is this
        # computer's speed, not the flight's, so no "overrun" count here.
        lines.append("  flight loop: lockstep at %d Hz on the simulated clock, scheduler jitter max %s us; "
                     "%.1f us of this computer per pass (mean)" % (r["loop_hz"], lp.get("cycle_jitter_max_us", 0),
                                                                 lp["mean_us"]))
    else:
        lines.append("  flight loop: %.1f us mean, %.0f us max, %d overruns of the %d us period (wall clock)"
                     % (lp["mean_us"], lp["max_us"], lp["overruns"], round(1e6 / r["loop_hz"])))
    log = r.get("log")
    if log:
        lines.append("  log written to %s (%d bytes, %d dropped; `hoverfly log report %s`)"
                     % (log["path"], log["bytes"], log["dropped"], log["path"]))
    return "\n".join(lines)


def _builtins_text():
    """The --help epilog: every built-in scenario and airframe with its one-line description."""
    import textwrap
    import tomllib

    from hoverfly.sim import airframes, scenario

    def rows(folder, names):
        out = []
        for name in names:
            try:
                desc = tomllib.loads((folder / (name + ".toml")).read_text()).get("description", "")
            except (OSError, ValueError):
                desc = ""
            out.append(textwrap.fill(desc, 100, initial_indent="  %-16s " % name, subsequent_indent=" " * 19))
        return out

    return "\n".join(["built-in scenarios (--scenario NAME, or a .toml file; its keys: hoverfly/sim/scenario.py):"]
                     + rows(scenario.HERE, scenario.builtin_names())
                     + ["", "built-in airframes (--airframe NAME, or a .toml file):"]
                     + rows(airframes.HERE, airframes.builtin_names()))


def register(sub):
    import argparse

    p = sub.add_parser("fly", help="fly a scenario on the simulator (default: the demo on the 5inch)",
                       description="Fly a scenario on the simulator in lockstep (or --realtime) and judge the "
                                   "flight: tilt, altitude, drift, each commanded step's response, events.",
                       epilog=_builtins_text(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--airframe", default="5inch", help="built-in airframe name or a .toml file")
    p.add_argument("--scenario", default=None,
                   help="built-in scenario name or a .toml file (default: demo; box for a plane)")
    p.add_argument("--duration", type=float, default=None, help="seconds to fly (default: the scenario's)")
    p.add_argument("--seed", type=int, default=1, help="random seed for sensor noise")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="override a parameter for this flight")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--realtime", action="store_true",
                   help="pace the flight to the wall clock, with a live panel (attitude, altitude, mode, events); "
                        "Ctrl-C stops it with a summary")
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
