"""Airframes as editable TOML data files: built-in ones in sim/airframes/, or a path.

Every key is checked before anything flies (the physics divides by several of them): numbers finite,
positive where a zero or a negative is no craft, and within a range a multirotor can have; the right
type; required keys present; unknown keys refused with the nearest known one; [params] through the
parameter table's one check (core/config/params.check). Anything wrong is one UserError line.
"""

import math
import pathlib
import tomllib
import xml.etree.ElementTree as ElementTree

from hoverfly.core.config.params import check, nearest, show
from hoverfly.core.stages.mixer import MIXER_TABLES
from hoverfly.errors import UserError

HERE = pathlib.Path(__file__).parent / "airframes"

_REQUIRED = ("mass_kg", "arm_m", "inertia_kg_m2", "kt", "kq", "motor_tau_up_s", "motor_tau_down_s",
             "omega_per_volt", "prop_diameter_m", "drag_coef", "battery", "imu")

# key -> (lowest, highest, lowest allowed itself): the ranges a flyable multirotor lives in. A lower
# bound that is not allowed itself keeps zero out of a divisor (mass, inertia, motor lag, thrust).
_NUMBERS = {
    "mass_kg": (0.0, 100.0, False),
    "arm_m": (0.0, 5.0, False),
    "kt": (0.0, 1.0, False),  # N per (rad/s)^2
    "kq": (0.0, 1.0, False),  # N m per (rad/s)^2
    "motor_tau_up_s": (0.0, 5.0, False),
    "motor_tau_down_s": (0.0, 5.0, False),
    "omega_per_volt": (0.0, 10000.0, False),
    "prop_diameter_m": (0.0, 5.0, False),
    "drag_coef": (0.0, 100.0, False),
    "angular_damping": (0.0, 10.0, True),
    "rotor_drag_coef": (0.0, 1.0, True),
    "rotor_height_m": (0.0, 1.0, True),  # rotor plane above the centre of mass: the H-force's lever
    "idle_current_a": (0.0, 200.0, True),
    "figure_of_merit": (0.0, 1.0, False),
    "drive_efficiency": (0.0, 1.0, False),
    "tri_servo_deg": (0.0, 90.0, False),
}
_BATTERY = {"cells": (1, 14), "capacity_mah": (0.0, 1.0e6, False), "r_int_ohm": (0.0, 10.0, True)}
_IMU = {
    "gyro_noise_rad_s_rthz": (0.0, 1.0, True),
    "gyro_bias_sigma_rad_s": (0.0, 1.0, True),
    "gyro_bias_walk_rad_s_rts": (0.0, 1.0, True),
    "accel_noise_m_s2_rthz": (0.0, 10.0, True),
    "accel_bias_sigma_m_s2": (0.0, 10.0, True),
    "gyro_vibration_rad_s": (0.0, 100.0, True),
    "accel_vibration_m_s2": (0.0, 1000.0, True),
    "gyro_range_dps": (0.0, 10000.0, False),
    "accel_range_g": (0.0, 64.0, False),
}
_OTHER = ("name", "description", "frame", "motor_poles", "inertia_kg_m2", "battery", "imu", "params")
_KEYS = tuple(_NUMBERS) + _OTHER


def builtin_names():
    return sorted(p.stem for p in HERE.glob("*.toml"))


def _unknown(where, key, known):
    guess = nearest(key, known) if isinstance(key, str) else None
    hint = " (did you mean %s?)" % guess if guess else ""
    return UserError("%s: unknown key '%s'%s" % (where, show(key), hint))


def _number(where, key, value, spec):
    lo, hi, lo_ok = spec
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UserError("%s: %s must be a number, not %s" % (where, key, show(value)))
    if isinstance(value, float) and value - value != 0.0:
        raise UserError("%s: %s must be a finite number, not %s" % (where, key, show(value)))
    if value < lo or (value == lo and not lo_ok) or value > hi:
        raise UserError("%s: %s = %s must be %s %s and at most %s"
                        % (where, key, show(value), "at least" if lo_ok else "more than", lo, hi))
    return float(value)


def _table(where, data, key, spec):
    t = data[key]
    if not isinstance(t, dict):
        raise UserError("%s: %s must be a table ([%s])" % (where, key, key))
    for k in t:
        if k not in spec:
            raise _unknown("%s [%s]" % (where, key), k, tuple(spec))
    missing = [k for k in spec if k not in t]
    if missing:
        raise UserError("%s [%s] lacks %s" % (where, key, ", ".join(missing)))
    for k, s in spec.items():
        if len(s) == 2:  # a whole number
            v = t[k]
            if isinstance(v, bool) or not isinstance(v, int) or not s[0] <= v <= s[1]:
                raise UserError("%s [%s]: %s must be a whole number %d..%d, not %s"
                                % (where, key, k, s[0], s[1], show(v)))
        else:
            t[k] = _number("%s [%s]" % (where, key), k, t[k], s)


def check_airframe(data, where):
    """The airframe dict checked and completed with its defaults; UserError naming the first bad key."""
    if not isinstance(data, dict):
        raise UserError("%s: an airframe is a table" % where)
    if data.get("kind") == "plane":
        return check_plane(data, where)
    for k in data:
        if k not in _KEYS:
            raise _unknown(where, k, _KEYS)
    missing = [k for k in _REQUIRED if k not in data]
    if missing:
        raise UserError("%s lacks %s" % (where, ", ".join(missing)))
    for k in ("name", "description"):
        if k in data and not isinstance(data[k], str):
            raise UserError("%s: %s must be text" % (where, k))
    data.setdefault("frame", "quadx")
    data.setdefault("params", {})
    data.setdefault("motor_poles", 14)  # the simulated motors' magnet poles (eRPM = RPM x poles / 2)
    poles = data["motor_poles"]
    if not isinstance(poles, int) or isinstance(poles, bool) or not (2 <= poles <= 48) or poles % 2:
        raise UserError("%s: motor_poles must be an even whole number 2..48" % where)
    if not isinstance(data["frame"], str) or data["frame"] not in MIXER_TABLES:
        raise UserError("%s: unknown frame '%s' (%s)" % (where, show(data["frame"]), ", ".join(sorted(MIXER_TABLES))))
    for k, spec in _NUMBERS.items():
        if k in data:
            data[k] = _number(where, k, data[k], spec)
    inertia = data["inertia_kg_m2"]
    if not isinstance(inertia, list) or len(inertia) != 3:
        raise UserError("%s: inertia_kg_m2 must be three positive numbers [ixx, iyy, izz]" % where)
    data["inertia_kg_m2"] = [_number(where, "inertia_kg_m2", v, (0.0, 100.0, False)) for v in inertia]
    _table(where, data, "battery", _BATTERY)
    _table(where, data, "imu", _IMU)
    params = data["params"]
    if not isinstance(params, dict):
        raise UserError("%s: [params] must be a table of parameter = value" % where)
    for name, value in params.items():
        _, _, err = check(name, value)
        if err:
            raise UserError("%s [params]: %s" % (where, err))
    return data


def load_airframe(name_or_path):
    path = pathlib.Path(name_or_path)
    if path.suffix == ".xml":
        if not path.exists():
            raise UserError("airframe file %s does not exist" % path)
        return plane_from_xml(path)
    if path.suffix == ".toml" or "/" in str(name_or_path):
        if not path.exists():
            raise UserError("airframe file %s does not exist" % path)
    else:
        path = HERE / (str(name_or_path) + ".toml")
        if not path.exists():
            from hoverfly.core.config.params import nearest

            guess = nearest(str(name_or_path), builtin_names())
            raise UserError("unknown airframe '%s'%s (built in: %s, or a .toml file)"
                            % (name_or_path, " (did you mean %s?)" % guess if guess else "",
                               ", ".join(builtin_names())))
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UserError("airframe file %s is not valid TOML: %s" % (path, exc)) from None
    except OSError as exc:
        raise UserError("cannot read airframe %s: %s" % (path, exc.strerror or exc)) from None
    data.setdefault("name", path.stem)
    if isinstance(data, dict) and data.get("kind") == "plane":
        data["_dir"] = path.parent  # a plane's xml = "..." is relative to its TOML
    return check_airframe(data, "airframe " + path.name)


# ----------------------------------------------------------------------------- planes
# A plane is a JSBSim model (sim/plane.py) plus its servo wiring; no rotor constants.
PLANE_MIXERS = ("airplane", "flying_wing", "vtail")
_PLANE_KEYS = ("name", "description", "kind", "model", "xml", "servos", "battery", "imu", "params",
               "stall_speed_m_s", "motor_rad_s", "rest_height_m")
_PLANE_NUMBERS = {"stall_speed_m_s": (0.0, 60.0, False), "motor_rad_s": (0.0, 10000.0, False),
                  "rest_height_m": (0.0, 1.0, False)}
_SERVO_OUTPUTS = 4  # the simulated board's servo outputs (sim/board.py)


def _positive(where, root, path, unit_note):
    node = root.find(path)
    if node is None or not (node.text or "").strip():
        raise UserError("%s: the JSBSim model lacks %s (%s)" % (where, path, unit_note))
    try:
        v = float(node.text)
    except ValueError:
        raise UserError("%s: %s must be a number, not %s" % (where, path, show(node.text.strip()))) from None
    if not (v > 0.0) or math.isinf(v):
        raise UserError("%s: %s = %s must be a positive number" % (where, path, show(node.text.strip())))
    return v


def check_plane_xml(path, where):
    """The aero data a flight needs, present and sane, before JSBSim sees the file (JSBSim itself
    flies a model without wings or mass): wing area/span/chord, mass and inertia positive, its engine
    and propeller files there, and lift, drag and the three moments each given by at least one function."""
    try:
        root = ElementTree.parse(str(path)).getroot()
    except ElementTree.ParseError as exc:
        raise UserError("%s: %s is not valid XML: %s" % (where, path.name, exc)) from None
    except OSError as exc:
        raise UserError("%s: cannot read %s: %s" % (where, path, exc.strerror or exc)) from None
    if root.tag != "fdm_config":
        raise UserError("%s: %s is not a JSBSim aircraft (<fdm_config>)" % (where, path.name))
    for p, what in (("metrics/wingarea", "wing area"), ("metrics/wingspan", "span"), ("metrics/chord", "chord"),
                    ("mass_balance/emptywt", "mass"), ("mass_balance/ixx", "roll inertia"),
                    ("mass_balance/iyy", "pitch inertia"), ("mass_balance/izz", "yaw inertia")):
        _positive(where, root, p, what)
    from hoverfly.sim.plane import engine_dir

    engines = engine_dir(path)
    for tag in ("propulsion/engine", "propulsion/engine/thruster"):
        for node in root.findall(tag):
            name = node.get("file", "")
            if not name or not (engines / (name + ".xml")).is_file():
                raise UserError("%s: the JSBSim model's %s file '%s' is not in %s"
                                % (where, tag.rsplit("/", 1)[1], show(name), engines))
    aero = root.find("aerodynamics")
    axes = {} if aero is None else {a.get("name", "").upper(): a for a in aero.findall("axis")}
    for axis in ("LIFT", "DRAG", "ROLL", "PITCH", "YAW"):
        if axis not in axes or not axes[axis].findall("function"):
            raise UserError("%s: the JSBSim model's aerodynamics lacks the %s axis (a <function> in "
                            "<axis name=\"%s\">)" % (where, axis, axis))
    return root


def check_plane(data, where):
    for k in data:
        if k not in _PLANE_KEYS and k != "_dir":
            raise _unknown(where, k, _PLANE_KEYS)
    for k in ("name", "description", "model", "xml"):
        if k in data and not isinstance(data[k], str):
            raise UserError("%s: %s must be text" % (where, k))
    if "model" not in data and "xml" not in data:
        raise UserError("%s lacks model (a built-in JSBSim model: %s) or xml (a JSBSim file of your own)"
                        % (where, ", ".join(builtin_plane_models())))
    if "xml" in data:
        xml = pathlib.Path(data["xml"])
        if not xml.is_absolute() and "_dir" in data:
            xml = data["_dir"] / xml
        data["xml"] = str(xml)
        data.setdefault("model", xml.stem)
        if not xml.exists():
            raise UserError("%s: xml file %s does not exist" % (where, xml))
    else:
        from hoverfly.sim.plane import model_file

        xml = model_file(data)
        if not xml.exists():
            raise UserError("%s: unknown JSBSim model '%s' (built in: %s)"
                            % (where, show(data["model"]), ", ".join(builtin_plane_models())))
    check_plane_xml(xml, where)
    data.pop("_dir", None)
    for k, spec in _PLANE_NUMBERS.items():
        if k in data:
            data[k] = _number(where, k, data[k], spec)
    if "servos" not in data:
        raise UserError("%s lacks [servos] (which servo output drives which surface)" % where)
    from hoverfly.sim.plane import SURFACES

    servos = data["servos"]
    if not isinstance(servos, dict) or not servos:
        raise UserError("%s: [servos] must name the surfaces: %s" % (where, ", ".join(SURFACES)))
    used = {}
    for surface, spec in servos.items():
        if surface not in SURFACES:
            raise _unknown(where + " [servos]", surface, tuple(SURFACES))
        if not isinstance(spec, dict) or set(spec) - {"servo", "direction", "min_us", "mid_us", "max_us"} \
                or "servo" not in spec:
            raise UserError("%s [servos]: %s must be { servo = 0..%d, direction = 1 or -1, and optionally the "
                            "servo's own end points min_us, mid_us, max_us }" % (where, surface, _SERVO_OUTPUTS - 1))
        ends = []
        for k, default in (("min_us", 1000), ("mid_us", 1500), ("max_us", 2000)):
            spec[k] = _number("%s [servos] %s" % (where, surface), k, spec.get(k, default), (500.0, 2500.0, True))
            ends.append(spec[k])
        if not ends[0] < ends[1] < ends[2]:
            raise UserError("%s [servos]: %s end points must be min_us < mid_us < max_us, not %g / %g / %g"
                            % (where, surface, ends[0], ends[1], ends[2]))
        n = spec["servo"]
        if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n < _SERVO_OUTPUTS:
            raise UserError("%s [servos]: %s drives servo %s, which does not exist (servos 0..%d)"
                            % (where, surface, show(n), _SERVO_OUTPUTS - 1))
        if n in used:
            raise UserError("%s [servos]: servo %d drives both %s and %s" % (where, n, used[n], surface))
        used[n] = surface
        d = spec.setdefault("direction", 1)
        if d not in (1, -1) or isinstance(d, bool):
            raise UserError("%s [servos]: %s direction must be 1 or -1, not %s" % (where, surface, show(d)))
    data.setdefault("params", {})
    data.setdefault("stall_speed_m_s", 7.0)
    for key, spec in (("battery", _BATTERY), ("imu", _IMU)):
        if key not in data:
            raise UserError("%s lacks [%s]" % (where, key))
        _table(where, data, key, spec)
    params = data["params"]
    if not isinstance(params, dict):
        raise UserError("%s: [params] must be a table of parameter = value" % where)
    for name, value in params.items():
        _, _, err = check(name, value)
        # a plane mixer the flight core does not know yet is refused when it flies (sim/runner.py)
        if err and not (name == "mixer_type" and value in PLANE_MIXERS):
            raise UserError("%s [params]: %s" % (where, err))
    frame = params.get("mixer_type", "airplane")
    if frame not in PLANE_MIXERS:
        raise UserError("%s [params]: a plane's mixer_type is one of %s, not %s"
                        % (where, ", ".join(PLANE_MIXERS), show(frame)))
    data["frame"] = frame
    return data


def builtin_plane_models():
    from hoverfly.sim.plane import ROOT

    return sorted(p.name for p in (ROOT / "aircraft").iterdir() if (p / (p.name + ".xml")).exists())


def plane_from_xml(path):
    """A user's own JSBSim XML flown as a plane: wired as a conventional airplane, default IMU and battery."""
    trainer = tomllib.loads((HERE / "trainer.toml").read_text())
    data = {"name": path.stem, "kind": "plane", "xml": str(path), "servos": trainer["servos"],
            "battery": trainer["battery"], "imu": trainer["imu"], "params": {"mixer_type": "airplane"}}
    return check_airframe(data, "airframe " + path.name)
