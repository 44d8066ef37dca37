"""Airframes as editable TOML data files: built-in ones in sim/airframes/, or a path.

Every key is checked before anything flies (the physics divides by several of them): numbers finite,
positive where a zero or a negative is no craft, and within a range a multirotor can have; the right
type; required keys present; unknown keys refused with the nearest known one; [params] through the
parameter table's one check (core/params.check). Anything wrong is one UserError line.
"""

import pathlib
import tomllib

from hoverfly.core.mixer import MIXER_TABLES
from hoverfly.core.params import check, nearest, show
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
    if path.suffix == ".toml" or "/" in str(name_or_path):
        if not path.exists():
            raise UserError("airframe file %s does not exist" % path)
    else:
        path = HERE / (str(name_or_path) + ".toml")
        if not path.exists():
            from hoverfly.core.params import nearest

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
    return check_airframe(data, "airframe " + path.name)
