"""Scenario and airframe files (issue 30): every key checked (finite, in range, right type, required keys
present, unknown keys named with the nearest known one), one clear UserError line each, and nothing
flies on a bad file. A property test mutates the built-in files: each mutant is a one-line UserError
or a flight that runs, never another exception."""

import copy
import json
import math
import tomllib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hoverfly.cli import main
from hoverfly.errors import UserError
from hoverfly.sim import airframes, scenario
from hoverfly.sim.airframes import load_airframe
from hoverfly.sim.runner import SimRun
from hoverfly.sim.scenario import load_scenario, parse_scenario

SCENARIOS = sorted(p.name for p in scenario.HERE.glob("*.toml"))
AIRFRAMES = sorted(p.name for p in airframes.HERE.glob("*.toml"))


# ------------------------------------------------------------------------------ a small TOML writer
def _value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if v != v:
            return "nan"
        if v in (math.inf, -math.inf):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join("%s = %s" % (json.dumps(k), _value(x)) for k, x in v.items()) + " }"
    raise TypeError(v)


def to_toml(doc):
    """TOML text for a parsed document: scalars first, then [tables] and [[arrays of tables]]."""
    lines = []
    tables = []
    for k, v in doc.items():
        if isinstance(v, dict) or (isinstance(v, list) and v and all(isinstance(x, dict) for x in v)):
            tables.append((k, v))
        else:
            lines.append("%s = %s" % (json.dumps(k), _value(v)))
    for k, v in tables:
        for entry in ([v] if isinstance(v, dict) else v):
            lines.append(("[%s]" if isinstance(v, dict) else "[[%s]]") % json.dumps(k))
            for kk, vv in entry.items():
                lines.append("%s = %s" % (json.dumps(kk), _value(vv)))
    return "\n".join(lines) + "\n"


def test_the_writer_round_trips_every_built_in_file():
    for folder, names in ((scenario.HERE, SCENARIOS), (airframes.HERE, AIRFRAMES)):
        for name in names:
            doc = tomllib.loads((folder / name).read_text())
            assert tomllib.loads(to_toml(doc)) == doc, name


# ------------------------------------------------------------------------------ mutations
BAD_VALUES = (math.nan, math.inf, -math.inf, 0, 0.0, -1, -1.0e9, 1.0e30, 2 ** 62, "x", "", True, False, [], [1, 2],
              {}, {"a": 1})
DELETE = object()
UNKNOWN = object()
HALF = object()  # a number halved or doubled: a different craft or timeline that may well fly
DOUBLE = object()
MUTATIONS = BAD_VALUES + (DELETE, UNKNOWN, HALF, DOUBLE, HALF, DOUBLE, HALF, DOUBLE)


def _paths(doc, prefix=()):
    """Every key path in a document, tables and array entries included, in a fixed order."""
    out = []
    if isinstance(doc, dict):
        for k in sorted(doc):
            out.append(prefix + (k,))
            out.extend(_paths(doc[k], prefix + (k,)))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            if isinstance(v, (dict, list)):
                out.extend(_paths(v, prefix + (i,)))
    return out


def _mutate(doc, path, how):
    parent = doc
    for k in path[:-1]:
        parent = parent[k]
    key = path[-1]
    if how is DELETE:
        if isinstance(parent, dict):
            del parent[key]
        else:
            parent.pop(key)
    elif how is UNKNOWN:
        if isinstance(parent, dict):
            parent["durration" if key == "duration_s" else key + "_x"] = 1
    elif how is HALF or how is DOUBLE:
        v = parent[key]
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            parent[key] = type(v)(v * (0.5 if how is HALF else 2))
    else:
        parent[key] = copy.deepcopy(how)  # the values are shared between examples: never mutate them


def _compress(doc, span_s=1.5):
    # every event into the first span_s, so a short flight meets each one
    d = doc.get("duration_s", 10.0)
    for ev in doc.get("at", []):
        t = ev.get("t")
        if isinstance(t, (int, float)) and not isinstance(t, bool):
            ev["t"] = round(t * span_s / d, 3)
    doc["duration_s"] = 2.0
    if "judge_from_s" in doc:
        doc["judge_from_s"] = 1.0


def _non_finite(doc):
    if isinstance(doc, float):
        return doc - doc != 0.0
    if isinstance(doc, dict):
        return any(_non_finite(v) for v in doc.values())
    if isinstance(doc, list):
        return any(_non_finite(v) for v in doc)
    return False


def _one_line(exc):
    text = str(exc)
    assert text and "\n" not in text and "Traceback" not in text and len(text) < 400, text


def _fly(airframe, sc):
    run = SimRun(airframe, sc, seed=1, duration_s=min(2.0, sc["duration_s"]))
    result = run.run()
    assert result["sim_time_s"] > 0


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_a_mutated_built_in_scenario_is_one_error_line_or_a_flight(data):
    name = data.draw(st.sampled_from(SCENARIOS))
    doc = tomllib.loads((scenario.HERE / name).read_text())
    _compress(doc)
    for _ in range(data.draw(st.integers(1, 2))):
        paths = _paths(doc)
        if not paths:
            break
        _mutate(doc, data.draw(st.sampled_from(paths)), data.draw(st.sampled_from(MUTATIONS)))
    try:
        sc = parse_scenario(to_toml(doc), name)
    except UserError as exc:
        _one_line(exc)
        return
    assert not _non_finite(doc), "a NaN or infinity in a scenario was accepted"
    try:
        _fly("5inch", sc)
    except UserError as exc:
        _one_line(exc)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_a_mutated_built_in_airframe_is_one_error_line_or_a_flight(data, tmp_path_factory):
    name = data.draw(st.sampled_from(AIRFRAMES))
    doc = tomllib.loads((airframes.HERE / name).read_text())
    for _ in range(data.draw(st.integers(1, 2))):
        paths = _paths(doc)
        if not paths:
            break
        _mutate(doc, data.draw(st.sampled_from(paths)), data.draw(st.sampled_from(MUTATIONS)))
    path = tmp_path_factory.mktemp("af") / "mutant.toml"
    path.write_text(to_toml(doc))
    try:
        af = load_airframe(str(path))
    except UserError as exc:
        _one_line(exc)
        return
    assert not _non_finite(doc), "a NaN or infinity in an airframe was accepted"
    try:
        _fly(af, load_scenario("hover"))
    except UserError as exc:
        _one_line(exc)


# ------------------------------------------------------------------------------ the reported inputs
def _airframe_error(tmp_path, edit):
    doc = tomllib.loads((airframes.HERE / "5inch.toml").read_text())
    edit(doc)
    path = tmp_path / "af.toml"
    path.write_text(to_toml(doc))
    with pytest.raises(UserError) as exc:
        load_airframe(str(path))
    _one_line(exc.value)
    return str(exc.value)


def test_airframe_values_that_crashed_the_sim_are_one_line(tmp_path):
    assert "cells" in _airframe_error(tmp_path, lambda d: d["battery"].update(cells=0))  # ZeroDivisionError
    assert "lacks gyro_range_dps" in _airframe_error(tmp_path, lambda d: d["imu"].pop("gyro_range_dps"))  # KeyError
    assert "battery must be a table" in _airframe_error(tmp_path, lambda d: d.update(battery=3))  # TypeError
    assert "finite" in _airframe_error(tmp_path, lambda d: d.update(mass_kg=math.nan))
    assert "kt" in _airframe_error(tmp_path, lambda d: d.update(kt=0.0))
    assert "motor_tau_up_s" in _airframe_error(tmp_path, lambda d: d.update(motor_tau_up_s=-0.1))
    assert "inertia_kg_m2" in _airframe_error(tmp_path, lambda d: d.update(inertia_kg_m2=[1e-3, math.inf, 1e-3]))
    assert "did you mean mass_kg?" in _airframe_error(tmp_path, lambda d: d.update(mas_kg=1.0))
    assert "did you mean cells?" in _airframe_error(tmp_path, lambda d: d["battery"].update(cell=3))
    assert "p_roll" in _airframe_error(tmp_path, lambda d: d["params"].update(p_roll=math.inf))
    assert "did you mean p_roll?" in _airframe_error(tmp_path, lambda d: d["params"].update(p_rol=40))


def _scenario_error(text):
    with pytest.raises(UserError) as exc:
        parse_scenario(text, "t")
    _one_line(exc.value)
    return str(exc.value)


def test_scenario_values_that_flew_are_refused():
    assert "finite" in _scenario_error('duration_s = 5\n[[at]]\nt = 1\nstep = { axis = "roll", to = nan }\n')
    assert "finite" in _scenario_error("duration_s = 5\n[[at]]\nt = 1\nstall_ms = nan\n")
    assert "finite" in _scenario_error("duration_s = nan\n")
    assert "finite" in _scenario_error("duration_s = 5\n[[at]]\nt = nan\n")
    assert "finite" in _scenario_error("duration_s = 5\n[[at]]\nt = 1\nthrottle = inf\n")
    assert "finite" in _scenario_error("duration_s = 5\n[[at]]\nt = 1\nkick = { roll_dps = nan }\n")
    assert "finite" in _scenario_error("duration_s = 5\n[[at]]\nt = 1\nset = { p_roll = inf }\n")
    assert "finite" in _scenario_error("duration_s = 5\n[params]\nd_roll = nan\n")
    assert "judge_from_s" in _scenario_error('duration_s = 5\njudge_from_s = "soon"\n')


def test_unknown_scenario_keys_name_the_nearest_one():
    err = _scenario_error("durration = 5\n")
    assert "unknown key 'durration'" in err and "did you mean duration_s?" in err
    assert "did you mean throttle?" in _scenario_error("duration_s = 5\n[[at]]\nt = 1\nthrotle = 0.5\n")
    assert "did you mean unit?" in _scenario_error('duration_s = 5\n[[at]]\nt = 1\nstep = { axis = "roll", to = 5, '
                                                   'unti = "dps" }\n')
    assert "unknown key 'wheather'" in _scenario_error("duration_s = 5\n[wheather]\nwind = 3\n")


def test_scenario_set_takes_aliases_and_refuses_reboot_parameters_in_flight():
    sc = parse_scenario("duration_s = 5\n[params]\nfailsafe_procedure = \"drop\"\n[[at]]\nt = 1\n"
                        "set = { failsafe_delay = 3 }\n")
    assert sc["params"] == {"failsafe_procedure": "drop"}
    assert "applies after a reboot" in _scenario_error("duration_s = 5\n[[at]]\nt = 1\nset = { loop_hz = 2000 }\n")
    assert parse_scenario("duration_s = 5\n[params]\nloop_hz = 2000\n")["params"] == {"loop_hz": 2000}


def test_hoverfly_fly_with_a_bad_file_flies_nothing(capsys, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("duration_s = 5\n[[at]]\nt = 1\nstall_ms = nan\n")
    assert main(["fly", "--scenario", str(bad), "--json"]) != 0
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.startswith("hoverfly: error:") and "finite" in captured.err
    af = tmp_path / "af.toml"
    doc = tomllib.loads((airframes.HERE / "5inch.toml").read_text())
    doc["battery"]["cells"] = 0
    af.write_text(to_toml(doc))
    assert main(["fly", "--airframe", str(af), "--json"]) != 0
    captured = capsys.readouterr()
    assert captured.out == "" and "cells" in captured.err and captured.err.count("\n") == 1
