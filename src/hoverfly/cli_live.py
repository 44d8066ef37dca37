"""`hoverfly fly --realtime`'s live view: a panel that follows the flight as it happens (rich).

Takes a SimRun about to fly at wall-clock pace; gives, on the terminal, one panel refreshed about
ten times a second (sim time, armed and mode, attitude, altitude, speed over ground, battery, the
loop's rate and what each pass costs this computer) and each event printed above it as it happens.
It reads the run through its `on_step` hook and keeps only what the panel and a Ctrl-C summary need:
the work per pass is a counter unless a tenth of a second has passed.
"""

import math
import time

from hoverfly.core.stages.control import MODE_NAMES

_DEG = 180.0 / math.pi
_REFRESH_S = 0.1


def event_text(e):
    """`2.00 s armed (switch)`: the event in words, its detail only where it says something."""
    name = e["event"].replace("_", " ")
    detail = str(e["detail"])
    if e["event"] == "mode":
        return "%.2f s %s mode" % (e["t_s"], detail)
    if e["event"] == "airmode":
        return "%.2f s air mode %s" % (e["t_s"], "on" if detail not in ("0", "off") else "off")
    if detail in ("", "0"):
        return "%.2f s %s" % (e["t_s"], name)
    return "%.2f s %s (%s)" % (e["t_s"], name, detail.replace("_", " "))


class LiveView:
    def __init__(self, run, console=None):
        from rich.console import Console

        self.run = run
        self.console = console or Console(highlight=False)
        self.live = None
        self.passes = 0
        self.t_s = 0.0
        self.max_tilt_deg = 0.0
        self.alt_max_m = 0.0
        self._events_shown = 0
        self._next_wall = 0.0
        self._wall0 = None

    # ------------------------------------------------------------------ hook
    def __enter__(self):
        from rich.live import Live

        self.live = Live(self._panel(), console=self.console, refresh_per_second=1.0 / _REFRESH_S, transient=False)
        self.live.__enter__()
        self.run.on_step = self.step
        return self

    def __exit__(self, *exc):
        self._refresh()
        self.live.__exit__(*exc)
        return False

    def step(self, run):
        self.passes += 1
        now = time.perf_counter()
        if self._wall0 is None:
            self._wall0 = now
        if now < self._next_wall:
            return
        self._next_wall = now + _REFRESH_S
        self._refresh()

    def _refresh(self):
        run = self.run
        v = run.vehicle
        self.t_s = run.board.sim_us * 1e-6 if hasattr(run.board, "sim_us") else self.t_s
        roll, pitch, _ = v.euler_rad()
        c = math.cos(roll) * math.cos(pitch)
        tilt = math.acos(max(-1.0, min(1.0, c))) * _DEG
        self.max_tilt_deg = max(self.max_tilt_deg, tilt if not v.on_ground else 0.0)
        self.alt_max_m = max(self.alt_max_m, v.altitude_m())
        events = run.events_out
        for e in events[self._events_shown:]:
            self.console.print("  " + event_text(e), markup=False)
        self._events_shown = len(events)
        if self.live is not None:
            self.live.update(self._panel())

    def _state(self):
        f = self.run.flight
        armed = bool(getattr(getattr(f, "arming", None), "armed", False))
        mode = getattr(getattr(getattr(f, "signals", None), "setpoint", None), "mode", None)
        mode_name = MODE_NAMES[mode] if isinstance(mode, int) and 0 <= mode < len(MODE_NAMES) else "?"
        return armed, mode_name

    def _panel(self):
        from rich.table import Table

        run = self.run
        v = run.vehicle
        armed, mode = self._state()
        roll, pitch, yaw = v.euler_rad()
        speed = math.sqrt(v.vn * v.vn + v.ve * v.ve)
        wall = (time.perf_counter() - self._wall0) if self._wall0 is not None else 0.0
        t = Table.grid(padding=(0, 2))
        t.add_row("[bold]%s[/] on %s" % (run.scenario["name"], run.airframe["name"]),
                  "%.2f s of %.1f s" % (self.t_s, run.duration_s),
                  "[bold red]ARMED[/]" if armed else "[green]disarmed[/]",
                  "%s mode%s" % (mode, " [bold red]CRASHED[/]" if v.crashed else ""))
        t.add_row("roll %+.1f deg" % (roll * _DEG), "pitch %+.1f deg" % (pitch * _DEG), "yaw %+.1f deg" % (yaw * _DEG),
                  "tilt max %.1f deg" % self.max_tilt_deg)
        t.add_row("altitude %.2f m" % (v.altitude_m() + 0.0), "speed %.2f m/s" % speed,
                  "battery %.2f V" % v.battery.voltage_v, "%.0f mAh drawn" % v.battery.mah_drawn)
        t.add_row("loop %d Hz" % run.loop_hz, "%s, %s" % (run.params.get("rx_provider"), run.board.esc_protocol),
                  "%.2fx real time" % (self.t_s / wall if wall > 0.5 else 1.0), "")
        return t

    def interrupted_summary(self):
        """What a pilot wants to know after Ctrl-C: where the flight stood and what happened."""
        run = self.run
        v = run.vehicle
        armed, mode = self._state()
        lines = ["stopped (Ctrl-C) at %.2f s of %.1f s: %s, %s, %s mode" % (
            self.t_s, run.duration_s, "CRASHED" if v.crashed else "no crash", "armed" if armed else "disarmed", mode),
            "  altitude %.2f m (max %.2f m), max tilt %.1f deg, battery %.2f V, %.0f mAh drawn" % (
                v.altitude_m() + 0.0, self.alt_max_m + 0.0, self.max_tilt_deg, v.battery.voltage_v,
                v.battery.mah_drawn),
            "  %d events" % len(run.events_out)]
        if run.log is not None:
            lines.append("  log written to %s (closed: everything up to the stop is readable)" % run.log.path)
        return "\n".join(lines)
