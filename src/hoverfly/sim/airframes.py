"""Airframes as editable TOML data files: built-in ones in sim/airframes/, or a path."""

import pathlib
import tomllib

from hoverfly.core.mixer import MIXER_TABLES
from hoverfly.errors import UserError

HERE = pathlib.Path(__file__).parent / "airframes"

_REQUIRED = ("mass_kg", "arm_m", "inertia_kg_m2", "kt", "kq", "motor_tau_up_s", "motor_tau_down_s",
             "omega_per_volt", "prop_diameter_m", "drag_coef", "battery", "imu")


def builtin_names():
    return sorted(p.stem for p in HERE.glob("*.toml"))


def load_airframe(name_or_path):
    path = pathlib.Path(name_or_path)
    if not (path.suffix == ".toml" and path.exists()):
        path = HERE / (str(name_or_path) + ".toml")
        if not path.exists():
            raise UserError("unknown airframe '%s' (built in: %s, or a .toml file)"
                            % (name_or_path, ", ".join(builtin_names())))
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UserError("airframe file %s is not valid TOML: %s" % (path, exc)) from None
    missing = [k for k in _REQUIRED if k not in data]
    if missing:
        raise UserError("airframe %s lacks %s" % (path.name, ", ".join(missing)))
    data.setdefault("name", path.stem)
    data.setdefault("frame", "quadx")
    data.setdefault("params", {})
    data.setdefault("motor_poles", 14)  # the simulated motors' magnet poles (eRPM = RPM x poles / 2)
    poles = data["motor_poles"]
    if not isinstance(poles, int) or isinstance(poles, bool) or not (2 <= poles <= 48) or poles % 2:
        raise UserError("airframe %s: motor_poles must be an even whole number 2..48" % path.name)
    if data["frame"] not in MIXER_TABLES:
        raise UserError("airframe %s: unknown frame '%s'" % (path.name, data["frame"]))
    try:
        for key in _REQUIRED:
            if key in ("battery", "imu", "inertia_kg_m2"):
                continue
            if float(data[key]) <= 0:
                raise UserError("airframe %s: %s must be positive" % (path.name, key))
        if len(data["inertia_kg_m2"]) != 3 or min(data["inertia_kg_m2"]) <= 0:
            raise UserError("airframe %s: inertia_kg_m2 must be three positive numbers" % path.name)
    except (TypeError, ValueError):
        raise UserError("airframe %s: numbers expected" % path.name) from None
    return data
