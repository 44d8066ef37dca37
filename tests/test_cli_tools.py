"""The terminal explains itself: the firmware bridge started from a user's folder, help that lists names,
scenario files checked key by key, "did you mean" for a misspelt name, the fly summary a pilot reads.

Given what a new user types (from the folder they cloned into, a typo, a bare `save`), when the CLI
runs, then it does what was asked or says in one line what to do instead.
"""

import json
import os
import subprocess
import sys
import threading

import pytest

from hoverfly.cli import main
from hoverfly.core.board import SERIAL_CONFIG, SERIAL_MAINT
from hoverfly.sim.server import SimServer
from test_micropython import MICROPYTHON

HOVERFLY = os.path.join(os.path.dirname(sys.executable), "hoverfly")
needs_mp = pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")


def _user_folder(tmp_path):
    """A folder like the one a user cloned into: it holds a hoverfly/ folder that is not the package."""
    folder = tmp_path / "clone"
    (folder / "hoverfly").mkdir(parents=True)
    (folder / "hoverfly" / "__init__.py").write_text("raise ImportError('the user folder was imported')\n")
    return folder


@needs_mp
def test_fly_on_the_micropython_firmware_from_a_folder_holding_a_hoverfly_folder(tmp_path):
    folder = _user_folder(tmp_path)
    r = subprocess.run([HOVERFLY, "fly", "--scenario", "hover", "--duration", "2", "--firmware", "micropython",
                        "--micropython", MICROPYTHON], cwd=folder, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "user folder" not in r.stderr and "no crash" in r.stdout


@needs_mp
def test_fly_from_a_flash_bundle_from_a_folder_holding_a_hoverfly_folder(tmp_path, unix_bundle):
    folder = _user_folder(tmp_path)
    r = subprocess.run([HOVERFLY, "fly", "--scenario", "hover", "--duration", "2", "--firmware", "micropython",
                        "--micropython", MICROPYTHON, "--bundle", str(unix_bundle)], cwd=folder,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "user folder" not in r.stderr and "no crash" in r.stdout


@pytest.fixture
def sim_without_storage():
    """`hoverfly sim` as a user starts it first: no --storage, ports picked by the system, on 127.0.0.1."""
    server = SimServer("5inch", 0, 0, None, duration_s=60)
    t = threading.Thread(target=server.serve, daemon=True)
    t.start()
    yield server
    server.stop()
    t.join(5)


def _url(server, which):
    return "socket://127.0.0.1:%d" % server.ports.address(which)[1]


def _one_line_error(capsys, argv):
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code != 0 and err.startswith("hoverfly: error:") and "\n" not in err and "Traceback" not in err
    return err


def test_saving_on_a_sim_without_storage_says_how_to_get_storage_and_exits_non_zero(sim_without_storage,
                                                                                   capsys):
    cfg = _url(sim_without_storage, SERIAL_CONFIG)
    err = _one_line_error(capsys, ["params", "set", "p_roll=50", "--save", "--port", cfg])
    assert "--storage" in err and "applied for this session, not saved: p_roll = 50" in err
    assert "--storage" in _one_line_error(capsys, ["params", "save", "--port", cfg])
    err = _one_line_error(capsys, ["maint", "--port", _url(sim_without_storage, SERIAL_MAINT), "save"])
    assert "--storage" in err and "armed" in err


def test_the_motor_test_says_when_and_why_it_capped_a_value(sim_without_storage, capsys):
    maint = _url(sim_without_storage, SERIAL_MAINT)
    assert main(["maint", "--port", maint, "motors", "--props-off", "1500,1200,1020,1000", "--seconds", "0.3"]) == 0
    out = capsys.readouterr().out
    assert "motor 1 ran at 1300 us, not 1500: capped by the props-off test limit motor_test_pct (1300 us = 30 %" in out
    assert "motor 3 ran at 1055 us, not 1020: raised to the motor's floor" in out
    assert "motor 2 ran" not in out and "motor 4 ran" not in out  # ran as asked: nothing to explain


def test_misspelt_parameter_names_get_a_did_you_mean_everywhere(sim_without_storage, capsys, tmp_path):
    cfg = _url(sim_without_storage, SERIAL_CONFIG)
    assert "did you mean p_roll?" in _one_line_error(capsys, ["params", "set", "p_rol=50", "--port", cfg])
    maint = _url(sim_without_storage, SERIAL_MAINT)
    assert "did you mean p_roll?" in _one_line_error(capsys, ["maint", "--port", maint, "set", "p_rol", "40"])
    assert "did you mean p_roll?" in _one_line_error(capsys, ["fly", "--set", "p_rol=40"])
    scenario = tmp_path / "s.toml"
    scenario.write_text("duration_s = 2\n[params]\np_rol = 40\n")
    assert "did you mean p_roll?" in _one_line_error(capsys, ["fly", "--scenario", str(scenario)])


def test_unknown_scenario_keys_tables_and_names_are_refused_with_the_nearest(capsys, tmp_path):
    scenario = tmp_path / "s.toml"
    scenario.write_text("durration = 5\n")
    assert "unknown key 'durration' (did you mean duration_s?)" in _one_line_error(
        capsys, ["fly", "--scenario", str(scenario)])
    scenario.write_text("duration_s = 5\n[parms]\np_roll = 40\n")
    assert "unknown key 'parms' (did you mean params?)" in _one_line_error(capsys, ["fly", "--scenario", str(scenario)])
    assert "did you mean rate-steps?" in _one_line_error(capsys, ["fly", "--scenario", "rate-step"])
    assert "did you mean 5inch?" in _one_line_error(capsys, ["fly", "--airframe", "5inc"])
    assert "airframe file %s does not exist" % (tmp_path / "x.toml") in _one_line_error(
        capsys, ["fly", "--airframe", str(tmp_path / "x.toml")])
    assert "scenario file %s does not exist" % (tmp_path / "x.toml") in _one_line_error(
        capsys, ["fly", "--scenario", str(tmp_path / "x.toml")])


def _help(capsys, argv):
    with pytest.raises(SystemExit):
        main(argv + ["--help"])
    return capsys.readouterr().out


def test_help_lists_every_name_a_command_takes(capsys):
    from hoverfly.sim import airframes, scenario

    fly_help = _help(capsys, ["fly"])
    for name in scenario.builtin_names() + airframes.builtin_names():
        assert "\n  %s " % name in fly_help, name
    assert "5-inch FPV racer" in fly_help
    set_help = _help(capsys, ["maint", "set"])
    assert "p_roll" in set_help and "thr_hover_us" in set_help
    command_help = _help(capsys, ["maint", "command"])
    assert "set_motor1" in command_help and "i2c_write" in command_help and "a command's name or id" in command_help
    for argv in (["rx", "decode"], ["rx", "encode"]):
        assert "ExpressLRS" in _help(capsys, argv)
    assert "kbit/s" in _help(capsys, ["esc", "encode"])


def test_the_fly_summary_says_what_was_flown_with_units_and_events_in_words(capsys, tmp_path):
    log = str(tmp_path / "rs.ulg")
    assert main(["fly", "--scenario", "rate-steps", "--seed", "7", "--log", log]) == 0
    out = capsys.readouterr().out
    assert "rate-steps on 5inch (seed 7), receiver crsf, ESCs dshot600" in out
    assert "-0.00" not in out
    assert "overrun" not in out and "lockstep at 1000 Hz on the simulated clock" in out
    assert "steady error 0.54 deg/s" in out  # every figure with its unit
    assert "2.00 s armed (switch)" in out and "5.00 s acro mode" in out and "0@" not in out
    assert "battery" in out and " V at the end" in out and "mAh drawn" in out
    assert "log written to %s" % log in out
    assert main(["fly", "--scenario", "hover", "--duration", "1.5", "--rx", "sbus", "--esc", "oneshot125"]) == 0
    assert "receiver sbus, ESCs oneshot125" in capsys.readouterr().out


def test_lockstep_json_has_no_wall_clock_overrun_count(capsys):
    assert main(["fly", "--scenario", "hover", "--duration", "1", "--json"]) == 0
    loop = json.loads(capsys.readouterr().out)["loop"]
    assert loop["overruns"] is None and loop["timing"] == "lockstep"


def _run_in_pty(argv, interrupt_on=None, timeout_s=120):
    """Run the CLI on a pseudo-terminal as a user's shell would; optionally press Ctrl-C (SIGINT) once the
    output shows `interrupt_on`. Returns (exit code, everything it wrote)."""
    import pty
    import select
    import signal
    import time

    leader, follower = pty.openpty()
    proc = subprocess.Popen(argv, stdin=follower, stdout=follower, stderr=follower, close_fds=True)
    os.close(follower)
    out = b""
    start = time.monotonic()
    sent = False
    while True:
        if interrupt_on is not None and not sent and interrupt_on in out:
            proc.send_signal(signal.SIGINT)
            sent = True
        ready, _, _ = select.select([leader], [], [], 0.1)
        if ready:
            try:
                chunk = os.read(leader, 65536)
            except OSError:  # the child closed the terminal
                break
            if not chunk:
                break
            out += chunk
        elif proc.poll() is not None:
            break
        assert time.monotonic() - start < timeout_s, out[-2000:]
    os.close(leader)
    return proc.wait(timeout=10), out.decode("utf-8", "replace")


def test_realtime_shows_a_live_panel_and_events_and_ends_with_the_summary(tmp_path):
    code, out = _run_in_pty([HOVERFLY, "fly", "--realtime", "--scenario", "hover", "--duration", "3"])
    assert code == 0
    assert "hover on 5inch" in out and "altitude" in out and "real time" in out and "ARMED" in out
    assert "2.00 s armed (switch)" in out  # the event printed as it happened
    assert out.count("of 3.0 s") >= 10  # the panel was redrawn as the flight went (about 10 times a second)
    assert "3.0 s flown in" in out and "(wall clock)" in out


def test_ctrl_c_on_a_realtime_flight_stops_it_with_a_summary_and_a_readable_log(tmp_path):
    log = tmp_path / "stopped.ulg"
    # pressed once the panel shows the craft armed (the hover scenario arms at 2 s and flies 12 s)
    code, out = _run_in_pty([HOVERFLY, "fly", "--realtime", "--scenario", "hover", "--log", str(log)],
                            interrupt_on=b"ARMED")
    assert code == 130
    assert "stopped (Ctrl-C) at" in out and "no crash, armed, angle mode" in out and "Traceback" not in out
    assert "log written to %s" % log in out
    from hoverfly.logs.ulogread import read_summary

    assert 2.0 < read_summary(str(log))["duration_s"] < 11.0
