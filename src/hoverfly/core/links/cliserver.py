"""Betaflight-style CLI on a byte stream: help, get, set, dump, diff, map, smix, servo, save, defaults, status, exit.

Takes the bytes typed on the CLI/MSP port after `#` entered the CLI (`CliServer.feed(data, n,
write)`, any chunking; CR or LF ends a line, backspace edits, characters are echoed as
Betaflight does) and the Flight; gives text lines through `write(bytes)`. Every name, range and
default comes from core/config/params.py; Betaflight's long names are accepted where hoverfly's differ
(ALIASES, with the unit conversion). While the CLI is open flight.config_session bit 1 blocks
arming; while armed, set, save, defaults and the smix/servo writes are refused. `smix` and `servo` are
INAV's commands for the servo mixer (core/stages/servos.py), written through the same parameter rows.
Runs from the links task, never in the flight pass.
"""

from hoverfly import __version__
from hoverfly.core.config.params import ALIASES, PARAMS, REBOOT, check, is_choice, row
from hoverfly.core.config.params import resolve as _resolve
from hoverfly.core.config.storage import STATUS_NAMES
from hoverfly.core.links.mspserver import CONFIG_CLI, reason_words
from hoverfly.core.safety.arming import reason_names
from hoverfly.core.scheduler import PS_CYCLE, PS_CYCLE_MAX, PS_JITTER_MAX
from hoverfly.core.stages.output import MAX_SERVOS as SERVO_LINES
from hoverfly.core.stages.rc import map_text, map_value
from hoverfly.core.stages.servos import (
    INPUT_NAMES,
    MAX_RULES,
    reset_pairs,
    rule_pairs,
    rules_of,
    servo_pairs,
    servo_rows,
)

HELP = (
    "help                      this list",
    "get [part of a name]      show matching parameters (range and default for one)",
    "set name = value          change a parameter (set alone lists all)",
    "dump                      every parameter as set lines",
    "diff [all]                only what differs from the defaults",
    "map [AETR1234]            show or set the channel map (rc_map): a letter per receiver channel",
    "smix [reset | N servo input rate speed]  servo mixer rules as INAV's (alone: list them)",
    "servo [N min max mid rate]  servo end points, centre and rate % (negative reverses; alone: list)",
    "save                      write the parameters to storage and leave the CLI",
    "defaults [nosave]         reset to defaults (and save, unless nosave)",
    "status                    arming, loop, sensors, link, storage",
    "exit                      leave the CLI",
)

_MAX_LINE = 256


def format_value(v):
    if isinstance(v, float):
        s = "%.6g" % v
        if "." not in s and "e" not in s and "inf" not in s and "nan" not in s:
            s += ".0"
        return s
    return str(v)


def resolve(name):
    """(hoverfly name, factor) for a hoverfly or Betaflight name, or (None, 1): params.resolve, the
    one name look-up every surface shares."""
    return _resolve(name)


class CliServer:
    def __init__(self, flight, storage=None):
        self.flight = flight
        self.storage = storage
        self.active = False
        self.lines = 0
        self._line = bytearray(_MAX_LINE)
        self._n = 0
        self._overflow = False
        self._last_cr = False

    def _session(self, on):
        s = getattr(self.flight, "config_session", 0)
        self.flight.config_session = (s | CONFIG_CLI) if on else (s & ~CONFIG_CLI)

    def enter(self, write):
        self.active = True
        self._n = 0
        self._overflow = False
        self._session(True)
        write(b"\r\nEntering CLI Mode, type 'exit' to return, or 'help'\r\n\r\n# ")

    def close(self):
        """Leave the CLI (exit, save, or the client went away)."""
        if self.active:
            self.active = False
            self._session(False)
        self._n = 0

    def feed(self, data, n, write):
        if n < 0 or n > len(data):
            n = len(data)
        i = 0
        while i < n and self.active:
            b = data[i]
            i += 1
            if b == 0x0D or b == 0x0A:
                if b == 0x0A and self._last_cr:
                    self._last_cr = False
                    continue
                self._last_cr = b == 0x0D
                line = bytes(self._line[:self._n])
                over = self._overflow
                self._n = 0
                self._overflow = False
                write(b"\r\n")
                if over:
                    write(b"###ERROR: line too long###\r\n")
                else:
                    self._run(line, write)
                if self.active:
                    write(b"\r\n# ")
                continue
            self._last_cr = False
            if b == 0x08 or b == 0x7F:
                if self._n:
                    self._n -= 1
                    write(b"\x08 \x08")
                continue
            if b < 0x20 or b > 0x7E:
                continue
            if self._n < _MAX_LINE:
                self._line[self._n] = b
                self._n += 1
            else:
                self._overflow = True
            write(bytes((b,)))

    # --------------------------------------------------------------- commands
    def _run(self, raw, write):
        try:
            line = raw.decode().strip()
        except UnicodeError:
            line = ""
        self.lines += 1
        if not line or line[0] == "#":
            return
        sp = line.find(" ")
        cmd = (line if sp < 0 else line[:sp]).lower()
        arg = "" if sp < 0 else line[sp + 1:].strip()
        out = []
        if cmd == "help":
            out = list(HELP)
        elif cmd == "get":
            out = self.cmd_get(arg)
        elif cmd == "set":
            out = self.cmd_set(arg)
        elif cmd == "dump":
            out = self.cmd_dump(False)
        elif cmd == "diff":
            out = self.cmd_dump(True)
        elif cmd == "save":
            out = self.cmd_save()
        elif cmd == "defaults":
            out = self.cmd_defaults(arg)
        elif cmd == "status":
            out = self.cmd_status()
        elif cmd == "map":
            out = self.cmd_map(arg)
        elif cmd == "smix":
            out = self.cmd_smix(arg)
        elif cmd == "servo":
            out = self.cmd_servo(arg)
        elif cmd == "batch":
            out = []  # pasted diffs carry 'batch start' / 'batch end': nothing to do
        elif cmd == "exit":
            out = ["Leaving CLI mode"]
            self.close()
        else:
            out = ["###ERROR: unknown command '%s'; try help###" % cmd]
        for text in out:
            write(text.encode() + b"\r\n")

    def _armed_refusal(self, what):
        if self.flight.arming.armed:
            return "###ERROR: %s refused while armed: disarm first###" % what
        return None

    def cmd_get(self, arg):
        part = arg.lower()
        name, _ = resolve(part)
        if name is not None:
            return self._describe(name)
        out = []
        for r in PARAMS:
            if part in r[0]:
                out.append("%s = %s%s" % (r[0], format_value(self.flight.params.stored(r[0])), self._waiting(r[0])))
        for bf, (name, _) in ALIASES.items():
            if part and part in bf:
                out.append("%s = %s   (hoverfly: %s)" % (bf, format_value(self._bf_value(bf)), name))
        if not out:
            out.append("###ERROR: no parameter matches '%s'###" % arg)
        return out

    def _waiting(self, name):
        """The note for a REBOOT row written since boot: stored, not yet what the craft runs."""
        p = self.flight.params
        if name in p.pending:
            return "  (applies after reboot; running %s)" % format_value(p.get(name))
        return ""

    def _bf_value(self, bf):
        name, factor = ALIASES[bf]
        v = self.flight.params.stored(name)
        if factor == 1:
            return v
        v = v / factor
        return int(v + 0.5) if v >= 0 else int(v - 0.5)

    def _describe(self, name):
        r = row(name)
        v = self.flight.params.stored(name)
        out = ["%s = %s%s" % (name, format_value(v), self._waiting(name))]
        if is_choice(r):
            out.append("Allowed values: %s" % ", ".join(r[4]))
        else:
            unit = (" " + r[4]) if r[4] else ""
            out.append("Allowed range: %s - %s%s" % (format_value(r[2]), format_value(r[3]), unit))
        out.append("Default value: %s%s" % (format_value(r[1]), "  (applies after a reboot)" if r[5] == REBOOT else ""))
        out.append(r[6])
        return out

    def cmd_set(self, arg):
        if not arg:
            return ["%s = %s" % (r[0], format_value(self.flight.params.get(r[0]))) for r in PARAMS]
        refused = self._armed_refusal("set")
        if refused:
            return [refused]
        eq = arg.find("=")
        if eq < 0:
            return ["###ERROR: use set name = value###"]
        given = arg[:eq].strip().lower()
        text = arg[eq + 1:].strip()
        # params.check: the one check (names, aliases and their units, finite, range, choices)
        name, v, err = check(given, text)
        if err is not None:
            return ["###ERROR: %s###" % err]
        err = self.flight.params.set(name, v)
        if err is not None:
            return ["###ERROR: %s###" % err]
        note = "  (applies after a reboot)" if row(name)[5] == REBOOT else ""
        return ["%s set to %s%s" % (name, format_value(v), note)]

    def cmd_map(self, arg):
        """Betaflight's `map`: alone it prints the map ("map AETR1234": the function of receiver channels 1..8,
        A E R T = roll pitch yaw throttle, 1..4 = AUX1..4); with 8 letters (any order, each once) it sets
        rc_map, refused while armed."""
        params = self.flight.params
        if arg:
            refused = self._armed_refusal("map")
            if refused:
                return [refused]
            value, err = map_value(arg)
            if err is None:
                err = params.set("rc_map", value)
            if err is not None:
                return ["###ERROR: %s###" % err]
        return ["map %s" % map_text(params.get("rc_map"))]

    def cmd_smix(self, arg):
        """INAV's `smix`: alone, the rules the servo mixer runs (the mixer_type's preset when none is stored);
        `smix reset` clears the stored rules; `smix N servo input rate speed` sets rule N (rate 0 removes it).
        Writes are refused while armed and change nothing on a bad value."""
        params = self.flight.params
        words = arg.split()
        if words:
            refused = self._armed_refusal("smix")
            if refused:
                return [refused]
            if len(words) == 1 and words[0].lower() == "reset":
                err = params.update(reset_pairs())
            else:
                nums = _ints(words)
                if nums is None or len(nums) != 5:
                    return ["###ERROR: use smix N servo input rate speed (whole numbers), or smix reset###"]
                pairs, err = rule_pairs(params, nums[0], nums[1], nums[2], nums[3], nums[4], SERVO_LINES)
                if err is None:
                    err = params.update(pairs)
            if err is not None:
                return ["###ERROR: %s###" % err]
        rules = rules_of(params)
        out = ["# smix: rule servo input rate speed"]
        stored = any(params.stored("smix%d_rate" % i) for i in range(MAX_RULES))
        if rules and not stored:
            out.append("# %s preset (no rules stored)" % params.get("mixer_type"))
        for i, servo, source, rate, speed in rules:
            out.append("smix %d %d %d %d %d  # %s" % (i, servo, source, rate, speed, INPUT_NAMES[source]))
        if not rules:
            out.append("# no rules")
        return out

    def cmd_servo(self, arg):
        """INAV's `servo`: alone, every servo line's `servo N min max mid rate`; with five numbers it sets one
        (refused while armed, and with min > mid or mid > max)."""
        params = self.flight.params
        words = arg.split()
        if words:
            refused = self._armed_refusal("servo")
            if refused:
                return [refused]
            nums = _ints(words)
            if nums is None or len(nums) != 5:
                return ["###ERROR: use servo N min max mid rate (whole numbers, us and %)###"]
            pairs, err = servo_pairs(nums[0], nums[1], nums[2], nums[3], nums[4], SERVO_LINES)
            if err is None:
                err = params.update(pairs)
            if err is not None:
                return ["###ERROR: %s###" % err]
        out = ["# servo: N min max mid rate"]
        for i in range(SERVO_LINES):
            n = servo_rows(i)
            out.append("servo %d %d %d %d %d" % (i, params.stored(n[0]), params.stored(n[2]), params.stored(n[1]),
                                               params.stored(n[3])))
        return out

    def cmd_dump(self, only_changed):
        p = self.flight.params
        board = getattr(self.flight.board, "name", "board")
        out = ["# %s" % ("diff all" if only_changed else "dump"), "", "# version",
               "# hoverfly %s / %s" % (__version__, board), "", "batch start", "", "# master"]
        # The values as stored (a reboot row written since boot: its new value, with a note)
        if only_changed:
            for name, v in p.diff():
                out.append("set %s = %s" % (name, format_value(v)))
        else:
            for r in PARAMS:
                out.append("set %s = %s" % (r[0], format_value(p.stored(r[0]))))
        for name in sorted(p.pending):
            out.append("# %s applies after reboot (running %s)" % (name, format_value(p.get(name))))
        out.append("")
        out.append("batch end")
        return out

    def cmd_save(self):
        refused = self._armed_refusal("save")
        if refused:
            return [refused]
        if self.storage is None:
            return ["###ERROR: no storage on this board###"]
        err = self.storage.save(self.flight.params)
        if err is not None:
            return ["###ERROR: save failed: %s###" % err]
        self.close()
        return ["Saving", "Leaving CLI mode"]

    def cmd_defaults(self, arg):
        refused = self._armed_refusal("defaults")
        if refused:
            return [refused]
        nosave = arg.strip().lower() == "nosave"
        if arg and not nosave:
            return ["###ERROR: defaults takes only 'nosave'###"]
        self.flight.params.reset()
        if nosave:
            return ["Defaults restored (not saved)"]
        out = ["Defaults restored"]
        out.extend(self.cmd_save())
        return out

    def cmd_status(self):
        f = self.flight
        out = []
        flags = f.arming.flags
        out.append("Armed: %s" % ("yes" if f.arming.armed else "no"))
        if flags:
            out.append("Arming disabled: 0x%x %s" % (flags, " ".join(reason_names(flags))))
            for w in reason_words(flags):
                out.append("  " + w)
        else:
            out.append("Arming disabled: no (ready to arm)")
        sch = f.scheduler
        out.append("Loop: %d Hz, cycle %d us (max %d), pass %d us, jitter max %d us, overruns %d"
                   % (f.loop_hz, sch.stats[PS_CYCLE], sch.stats[PS_CYCLE_MAX], f.pass_us, sch.stats[PS_JITTER_MAX],
                      sch.overruns))
        cal = f.calibration.calibrated
        imu_ok = f.supervisor.imu_ok
        sensors = ("Sensors: gyro %s, calibration %s; estimator %s"
                   % ("ok" if imu_ok else "FAULT", "done" if cal else "running", f.params.get("estimator")))
        s = f.signals
        if s.airspeed_valid:  # a plane's pitot
            sensors += "; airspeed %.1f m/s" % s.airspeed_m_s
        out.append(sensors)
        rx = getattr(f, "receiver", None)
        if rx is not None:
            out.append("Link: %s, %s frames, %s errors, %s Hz, LQ %s %%, RSSI %s dBm"
                       % ("up" if f.rx_ok else "LOST", getattr(rx, "frames", "-"), getattr(rx, "errors", "-"),
                          getattr(rx, "frame_rate_hz", "-"), getattr(rx, "link_quality_pct", "-"),
                          getattr(rx, "rssi_dbm", "-")))
        else:
            out.append("Link: %s, %d frames" % ("up" if f.rx_ok else "LOST", f.rc.frames))
        bit = getattr(f, "bit", None)
        if bit is not None:
            names = bit.names()
            out.append("Built-in test: %s" % (", ".join(names) if names else "pass"))
        errs = getattr(f, "loop_errors_line", None)  # what the loop's boundaries caught (Flight)
        if errs is not None:
            out.append(errs())
        st = self.storage
        if st is not None:
            out.append("Storage: %s, sequence %d, slot %d%s" % (STATUS_NAMES[st.status], st.seq, st.slot,
                                                                  ", FAILED" if st.failed else ""))
            if getattr(st, "skipped", 0):
                out.append("Parameters: %d stored value(s) skipped at boot: %s"
                           % (st.skipped, "; ".join(getattr(st, "skip_reasons", ())[:4])))
        servos = getattr(f, "servos", None)
        if servos is not None and servos.count:
            us = f.signals.servo_us
            out.append("Servos: %s us (%s, %d rules)%s" % (" ".join([str(us[i]) for i in range(servos.count)]),
                                                         f.params.get("mixer_type"), servos.rules,
                                                         "; " + servos.error if servos.error else ""))
        line = getattr(f.board, "status_line", None)
        if line is not None:
            out.append("Board: %s" % line())
        out.append("Config session: %d" % getattr(f, "config_session", 0))
        # self.links is set by core/links/task.py: requests, waits and drops of the ports
        if getattr(self, "links", None) is not None:
            out.append(self.links.status_line())
        return out


def _ints(words):
    """The words as whole numbers, or None if one is not."""
    out = []
    for w in words:
        try:
            out.append(int(w))
        except ValueError:
            return None
    return out
