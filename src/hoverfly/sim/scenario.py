"""Scenarios: a TOML timeline a user can write, checked before anything flies.

    name = "hover"
    duration_s = 12
    mode = "angle"                 # starting position of the mode switch: acro | angle | horizon
    [[at]]
    t = 0.5
    arm = true                     # the arm switch
    [[at]]
    t = 1.0
    hold_altitude_m = 2.0          # the pilot holds this altitude with the throttle stick

Keys an `[[at]]` entry may hold (several at once):
    arm (bool), mode (str), throttle (0..1), throttle_us, roll / pitch / yaw (stick -1..1, pitch
    forward positive as on the transmitter), roll_us / pitch_us / yaw_us, hold_altitude_m (number,
    or false to hand the throttle back), fly_to ([north_m, east_m], angle mode), land (true: descend,
    touch down, disarm), step ({axis, to, unit: "dps" in acro or "deg" in angle/horizon; pitch up is
    positive}), kick ({roll_dps, pitch_dps, yaw_dps}: an instant change of body rate), gust
    ({north_m_s, east_m_s, down_m_s, duration_s, turbulence_m_s: random wind of that RMS on top, seeded,
    for the gust's duration}), wind ({north_m_s, east_m_s, down_m_s}), torque ({roll_nm, pitch_nm,
    yaw_nm, duration_s}: an outside torque on the body, FRD, for that long), flip
    ("roll" or "pitch": a full 360° in acro, flown as a pilot would), rx_lost (bool), imu_freeze (bool),
    stall_ms (the flight controller stalls this long: no pass runs, the board's output timer does),
    set ({name = value}: change parameters in flight),
    imu_stuck (bool: the IMU keeps delivering its last sample), autopilot_switch (bool: the
    pilot's autopilot switch on AUX ap_ch), msp_rc ({roll, pitch, yaw: -1..1, pitch forward
    positive; throttle 0..1; arm (bool); rate_hz; channels}: a companion computer sends MSP
    SET_RAW_RC at rate_hz from now on, flying the throttle itself with hold_altitude_m; false: it
    falls silent), config_session (0..7: open
    configuration sessions, 1 CLI, 2 MSP, 4 maintenance),
    channel ({ch = 5..16, us = 800..2200}: hold that channel at that pulse width from now on,
    e.g. an AUX mode switch; the pilot's own arm/mode switches are overridden too),
    throw (a plane's hand launch: true, or {forward_m_s2, up_m_s2, duration_s} of the arm's push),
    acc_calibration (true: the pilot calibrates the accelerometer on the ground as in the configurator,
    an MSP_ACC_CALIBRATION to the flight's MSP server, which stores the attitude it reads as
    acc_trim_roll / acc_trim_pitch; refused while armed, the refusal in the events).
A plane's scenario may start in flight: [start] altitude_m, airspeed_m_s, heading_deg.

Every key is checked before anything flies: numbers finite and in range, the right type, required
keys present, parameters through the table's one check (core/config/params.check, aliases included; a
reboot parameter belongs in [params], not in a `set` event). Anything wrong is one UserError line
naming the key (an unknown key with the nearest known one).
"""

import pathlib
import tomllib

from hoverfly.core.config.params import REBOOT, check, nearest, row, show
from hoverfly.errors import UserError

HERE = pathlib.Path(__file__).parent / "scenarios"

_EVENT_KEYS = {
    "t", "arm", "mode", "throttle", "throttle_us", "roll", "pitch", "yaw", "roll_us", "pitch_us", "yaw_us",
    "hold_altitude_m", "fly_to", "land", "step", "kick", "gust", "wind", "flip", "rx_lost", "imu_freeze",
    "set", "note", "stall_ms", "torque",
    "imu_stuck", "autopilot_switch", "msp_rc", "config_session", "channel", "throw", "acc_calibration",
}
_MSP_RC_KEYS = ("roll", "pitch", "yaw", "throttle", "arm", "rate_hz", "channels", "hold_altitude_m")
_TOP_KEYS = ("name", "description", "duration_s", "mode", "at", "params", "judge_from_s", "airframe", "start")
_THROW_KEYS = ("forward_m_s2", "up_m_s2", "duration_s")  # a plane's hand launch (sim/plane.HandLaunch)
_START_KEYS = ("altitude_m", "airspeed_m_s", "heading_deg")  # a plane that starts in flight
_STEP_KEYS = ("axis", "to", "unit")
_MODES = ("acro", "angle", "horizon")
_AXES = ("roll", "pitch", "yaw")


def builtin_names():
    return sorted(p.stem for p in HERE.glob("*.toml"))


def unknown_key(where, key, known, what="key"):
    """The UserError for a key a table does not have, naming the nearest known one."""
    guess = nearest(key, known) if isinstance(key, str) else None
    hint = " (did you mean %s?)" % guess if guess else " (known: %s)" % ", ".join(sorted(known))
    return UserError("%s: unknown %s '%s'%s" % (where, what, show(key), hint))


def _num(where, key, value, lo, hi):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UserError("%s: %s must be a number, not %s" % (where, key, show(value)))
    if isinstance(value, float) and value - value != 0.0:
        raise UserError("%s: %s must be a finite number, not %s" % (where, key, show(value)))
    if value < lo or value > hi:
        raise UserError("%s: %s = %s is out of range %s .. %s" % (where, key, show(value), lo, hi))
    return float(value)


def _params(where, table, in_flight):
    """Each name = value through the parameter table's check (names and aliases as every surface)."""
    if not isinstance(table, dict):
        raise UserError("%s must be a table of parameter = value" % where)
    for name, value in table.items():
        key, _, err = check(name, value)
        if err:
            raise UserError("%s: %s" % (where, err))
        if in_flight and row(key)[5] == REBOOT:
            raise UserError("%s: %s applies after a reboot: set it in the scenario's [params]" % (where, key))


def _check_event(where, ev, duration_s):
    unknown = sorted(set(ev) - _EVENT_KEYS)
    if unknown:
        raise unknown_key(where, unknown[0], _EVENT_KEYS)
    if "t" not in ev:
        raise UserError("%s: every [[at]] needs a time t" % where)
    _num(where, "t", ev["t"], 0.0, duration_s)
    for key in ("arm", "land", "rx_lost", "imu_freeze", "imu_stuck", "autopilot_switch", "acc_calibration"):
        if key in ev and not isinstance(ev[key], bool):
            raise UserError("%s: %s must be true or false" % (where, key))
    if "mode" in ev and ev["mode"] not in _MODES:
        raise UserError("%s: mode must be one of %s" % (where, ", ".join(_MODES)))
    if "throttle" in ev:
        _num(where, "throttle", ev["throttle"], 0.0, 1.0)
    if "stall_ms" in ev:
        _num(where, "stall_ms", ev["stall_ms"], 0.0, 60000.0)
    if "config_session" in ev:
        cs = ev["config_session"]
        if isinstance(cs, bool) or not isinstance(cs, int) or not 0 <= cs <= 7:
            raise UserError("%s: config_session must be 0..7 (1 CLI, 2 MSP, 4 maintenance)" % where)
    if "channel" in ev:
        c = ev["channel"]
        if not isinstance(c, dict) or set(c) != {"ch", "us"}:
            raise UserError("%s: channel must be a table {ch = 5..16, us = pulse width}" % where)
        if isinstance(c["ch"], bool) or not isinstance(c["ch"], int) or not 5 <= c["ch"] <= 16:
            raise UserError("%s: channel.ch must be a whole number 5..16 (AUX1 = 5)" % where)
        _num(where, "channel.us", c["us"], 800, 2200)
    if "msp_rc" in ev and ev["msp_rc"] is not False:
        m = ev["msp_rc"]
        if not isinstance(m, dict):
            raise UserError("%s: msp_rc must be a table or false" % where)
        for k, v in m.items():
            if k not in _MSP_RC_KEYS:
                raise UserError("%s: msp_rc has no field '%s' (%s)" % (where, k, ", ".join(_MSP_RC_KEYS)))
            if k == "arm":
                if not isinstance(v, bool):
                    raise UserError("%s: msp_rc.arm must be true or false" % where)
            elif k == "throttle":
                _num(where, "msp_rc.throttle", v, 0.0, 1.0)
            elif k == "hold_altitude_m":
                _num(where, "msp_rc.hold_altitude_m", v, 0.0, 500.0)
            elif k == "rate_hz":
                _num(where, "msp_rc.rate_hz", v, 1.0, 1000.0)
            elif k == "channels":
                if isinstance(v, bool) or not isinstance(v, int) or not 4 <= v <= 18:
                    raise UserError("%s: msp_rc.channels must be 4..18" % where)
            else:
                _num(where, "msp_rc." + k, v, -1.0, 1.0)
    for key in ("throttle_us", "roll_us", "pitch_us", "yaw_us"):
        if key in ev:
            _num(where, key, ev[key], 800, 2200)
    for key in _AXES:
        if key in ev:
            _num(where, key, ev[key], -1.0, 1.0)
    if "hold_altitude_m" in ev and ev["hold_altitude_m"] is not False:
        _num(where, "hold_altitude_m", ev["hold_altitude_m"], 0.0, 500.0)
    if "fly_to" in ev:
        ft = ev["fly_to"]
        if not isinstance(ft, list) or len(ft) != 2:
            raise UserError("%s: fly_to must be [north_m, east_m]" % where)
        for v in ft:
            _num(where, "fly_to", v, -10000, 10000)
    if "step" in ev:
        st = ev["step"]
        if not isinstance(st, dict) or st.get("axis") not in _AXES or "to" not in st:
            raise UserError("%s: step needs axis (roll, pitch, yaw) and to" % where)
        for k in st:
            if k not in _STEP_KEYS:
                raise unknown_key(where + " step", k, _STEP_KEYS, "field")
        if st.get("unit", "dps") not in ("dps", "deg"):
            raise UserError("%s: step unit must be dps or deg" % where)
        _num(where, "step.to", st["to"], -2000, 2000)
    for key, allowed, lim in (("kick", ("roll_dps", "pitch_dps", "yaw_dps"), 3000),
                              ("gust", ("north_m_s", "east_m_s", "down_m_s", "duration_s", "turbulence_m_s"), 100),
                              ("torque", ("roll_nm", "pitch_nm", "yaw_nm", "duration_s"), 100),
                              ("wind", ("north_m_s", "east_m_s", "down_m_s"), 100)):
        if key in ev:
            tab = ev[key]
            if not isinstance(tab, dict):
                raise UserError("%s: %s must be a table" % (where, key))
            for k, v in tab.items():
                if k not in allowed:
                    raise UserError("%s: %s has no field '%s' (%s)" % (where, key, k, ", ".join(allowed)))
                _num(where, key + "." + k, v, 0.0 if k in ("duration_s", "turbulence_m_s") else -lim, lim)
    if "throw" in ev and ev["throw"] is not True:
        th = ev["throw"]
        if not isinstance(th, dict):
            raise UserError("%s: throw must be true or a table {%s}" % (where, ", ".join(_THROW_KEYS)))
        for k, v in th.items():
            if k not in _THROW_KEYS:
                raise UserError("%s: throw has no field '%s' (%s)" % (where, k, ", ".join(_THROW_KEYS)))
            _num(where, "throw." + k, v, 0.01 if k == "duration_s" else 0.0, 2.0 if k == "duration_s" else 100.0)
    if "flip" in ev and ev["flip"] not in ("roll", "pitch"):
        raise UserError("%s: flip must be roll or pitch" % where)
    if "note" in ev and not isinstance(ev["note"], str):
        raise UserError("%s: note must be text" % where)
    if "set" in ev:
        _params(where + " set", ev["set"], True)


def parse_scenario(text, origin="scenario"):
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError("%s is not valid TOML: %s" % (origin, exc)) from None
    unknown = sorted(set(data) - set(_TOP_KEYS))
    if unknown:
        raise unknown_key(origin, unknown[0], _TOP_KEYS)
    for key in ("name", "description", "airframe"):
        if key in data and not isinstance(data[key], str):
            raise UserError("%s: %s must be text" % (origin, key))
    duration = _num(origin, "duration_s", data.get("duration_s", 10.0), 0.1, 3600.0)
    judge_from = _num(origin, "judge_from_s", data.get("judge_from_s", 0.0), 0.0, duration)
    mode = data.get("mode", "angle")
    if mode not in _MODES:
        raise UserError("%s: mode must be one of %s" % (origin, ", ".join(_MODES)))
    events = data.get("at", [])
    if not isinstance(events, list):
        raise UserError("%s: [[at]] entries expected" % origin)
    for i, ev in enumerate(events):
        if not isinstance(ev, dict):
            raise UserError("%s: [[at]] entry %d is not a table" % (origin, i + 1))
        _check_event("%s [[at]] #%d" % (origin, i + 1), ev, duration)
    events = sorted(events, key=lambda e: e["t"])
    extra = data.get("params", {})
    _params("%s [params]" % origin, extra, False)
    start = data.get("start")
    if start is not None:
        if not isinstance(start, dict):
            raise UserError("%s: [start] must be a table {%s}" % (origin, ", ".join(_START_KEYS)))
        for k, v in start.items():
            if k not in _START_KEYS:
                raise unknown_key(origin + " [start]", k, _START_KEYS)
            start[k] = _num(origin + " [start]", k, v, -360.0 if k == "heading_deg" else 0.0,
                            360.0 if k == "heading_deg" else 1000.0)
    return {
        "name": data.get("name", origin),
        "description": data.get("description", ""),
        "duration_s": duration,
        "mode": mode,
        "events": events,
        "params": extra,
        "judge_from_s": judge_from,
        "airframe": data.get("airframe"),
        "start": start,
    }


def load_scenario(name_or_path):
    path = pathlib.Path(name_or_path)
    if path.suffix == ".toml" or "/" in str(name_or_path):
        if not path.exists():
            raise UserError("scenario file %s does not exist" % path)
    else:
        path = HERE / (str(name_or_path) + ".toml")
        if not path.exists():
            guess = nearest(str(name_or_path), builtin_names())
            raise UserError("unknown scenario '%s'%s (built in: %s, or a .toml file)"
                            % (name_or_path, " (did you mean %s?)" % guess if guess else "",
                               ", ".join(builtin_names())))
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError("cannot read scenario %s: %s" % (path, exc)) from None
    return parse_scenario(text, path.stem)
