"""Host clients against a running `hoverfly sim` over socket:// URLs: the MSP, CLI and maintenance
clients (gcs/link.py), `hoverfly connect`, `hoverfly params get|set|dump|diff|save|restore` and
`hoverfly maint read|motors|set|save|command`; user mistakes and dead links are one-line errors."""

import io
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from hoverfly.cli import main
from hoverfly.core.config.params import PARAMS, row
from hoverfly.gcs.link import CliSession, MaintClient, MspClient, Refused, open_link
from hoverfly.paramtext import changes_to, parse_set_text
from hoverfly.protocols import maintenance as mp
from hoverfly.protocols import msp

pytest.importorskip("serial")

HOVERFLY = str(Path(sys.executable).parent / "hoverfly")
_PORTS = re.compile(r"CLI\+MSP on 127\.0\.0\.1:(\d+), maintenance on 127\.0\.0\.1:(\d+)")


class Sim:
    """`hoverfly sim` in a subprocess on free ports (port 0: the first output line names them)."""

    def __init__(self, storage):
        self.proc = subprocess.Popen([HOVERFLY, "sim", "--msp-port", "0", "--maint-port", "0", "--storage",
                                      storage, "--duration", "60"], stdout=subprocess.PIPE, text=True)
        line = self.proc.stdout.readline()
        m = _PORTS.search(line)
        if m is None:
            self.stop()
            raise AssertionError("no ports in: %r" % line)
        self.cli_url = "socket://127.0.0.1:%s" % m.group(1)
        self.maint_url = "socket://127.0.0.1:%s" % m.group(2)

    def stop(self):
        self.proc.terminate()
        self.proc.wait(10)
        self.proc.stdout.close()


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    s = Sim(str(tmp_path_factory.mktemp("hc") / "params.bin"))
    yield s
    s.stop()


def run(capsys, *argv, stdin=None, monkeypatch=None):
    if stdin is not None:
        monkeypatch.setattr(sys, "stdin", io.StringIO(stdin))
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code, err, *words):
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hoverfly: error: "), err
    assert "Traceback" not in err
    for w in words:
        assert w in lines[0], lines[0]


def cli_value(capsys, sim, name):
    code, out, _ = run(capsys, "params", "get", name, "--port", sim.cli_url)
    assert code == 0
    return out.splitlines()[0]


# ------------------------------------------------------------------------------------ link clients
def test_msp_client_asks_in_v1_v2_and_v2_over_v1_and_raises_on_error_replies(sim):
    port = open_link(sim.cli_url)
    try:
        client = MspClient(port)
        assert msp.unpack_api_version(client.request(msp.MSP_API_VERSION)) == (0, 1, 46)
        assert msp.unpack_fc_variant(client.request(msp.MSP_FC_VARIANT, version=2)) == "HVFL"
        pid = msp.unpack_pid(client.request(msp.MSP_PID, version=2, encapsulated=True))
        assert len(pid) >= 3
        with pytest.raises(Refused):
            client.request(77)  # not an MSP command hoverfly knows
    finally:
        port.close()


def test_cli_session_collects_output_holding_prompt_like_lines_and_raises_on_errors(sim):
    port = open_link(sim.cli_url)
    try:
        with CliSession(port) as cli:
            dump = cli.command("dump")
            assert dump[0] == "# dump" and "# version" in dump  # '# ' lines do not end the output early
            assert sum(1 for line in dump if line.startswith("set ")) == len(PARAMS)
            with pytest.raises(Refused, match="out of range"):
                cli.command("set p_roll = 999", check=True)  # the controller's own refusal
            assert cli.command("get p_roll")[0].startswith("p_roll = ")
        assert not cli.active
        # after 'exit' the port speaks MSP again
        assert msp.unpack_api_version(MspClient(port).request(msp.MSP_API_VERSION)) == (0, 1, 46)
    finally:
        port.close()


def test_maint_client_parses_reply_fields_by_name(sim):
    port = open_link(sim.maint_url)
    try:
        client = MaintClient(port)
        values = client.read(["sw_ver", "motors_armed", "body_roll", "PID_params"])
        assert list(values) == ["body_roll", "motors_armed", "PID_params", "sw_ver"]  # header order
        assert values["motors_armed"] == 0 and len(values["PID_params"]) == 18 and len(values["sw_ver"]) == 4
        with pytest.raises(Refused):
            client.command(mp.CMD_SET_MOTOR1, (1200,))  # no props-off acknowledgement (command 6) first
    finally:
        port.close()


# ------------------------------------------------------------------------------- hoverfly connect
def test_connect_passes_stdin_lines_to_the_cli_and_exit_ends_it(sim, capsys, monkeypatch):
    code, out, _ = run(capsys, "connect", sim.cli_url, stdin="get p_roll\nstatus\nbogus\nexit\nget p_roll\n",
                       monkeypatch=monkeypatch)
    assert code == 0
    assert "Allowed range: 0 - 250" in out and "Armed: no" in out
    assert "###ERROR: unknown command 'bogus'" in out
    assert out.rstrip().endswith("Leaving CLI mode")  # the line after exit was not sent


def test_connect_ends_at_end_of_input(sim, capsys, monkeypatch):
    code, out, _ = run(capsys, "connect", sim.cli_url, stdin="help\n", monkeypatch=monkeypatch)
    assert code == 0 and "diff [all]" in out


# -------------------------------------------------------------------------------- hoverfly params
def test_params_get_shows_range_and_default_of_one_name(sim, capsys):
    # f_yaw: neither the airframe's tune nor another test here changes it
    code, out, _ = run(capsys, "params", "get", "f_yaw", "--port", sim.cli_url)
    assert code == 0
    assert out.splitlines()[:3] == ["f_yaw = %s" % row("f_yaw")[1], "Allowed range: 0 - 1000",
                                    "Default value: %s" % row("f_yaw")[1]]


def test_params_set_changes_the_controller(sim, capsys):
    code, out, _ = run(capsys, "params", "set", "p_yaw=51", "i_yaw=91", "--port", sim.cli_url)
    assert code == 0 and "p_yaw set to 51" in out and "i_yaw set to 91" in out
    assert cli_value(capsys, sim, "p_yaw") == "p_yaw = 51"
    assert cli_value(capsys, sim, "i_yaw") == "i_yaw = 91"


@pytest.mark.parametrize("argv, words", [
    (("set", "p_roll=999"), ("p_roll = 999 is out of range 0 .. 250",)),
    (("set", "no_such_name=1"), ("unknown parameter 'no_such_name'",)),
    (("set", "p_roll"), ("NAME=VALUE",)),
    (("set", "p_roll=3", "d_roll=-1"), ("d_roll",)),
    (("get", "zzz_nothing"), ("no parameter matches 'zzz_nothing'",)),
])
def test_params_mistakes_are_one_line_errors_and_change_nothing(sim, capsys, argv, words):
    before = cli_value(capsys, sim, "p_roll")
    code, _, err = run(capsys, "params", *argv, "--port", sim.cli_url)
    assert_one_line_error(code, err, *words)
    assert cli_value(capsys, sim, "p_roll") == before  # all values are checked before any is sent


def test_params_dump_and_diff_are_set_lines(sim, capsys):
    run(capsys, "params", "set", "d_yaw=7", "--port", sim.cli_url)
    code, dump, _ = run(capsys, "params", "dump", "--port", sim.cli_url)
    assert code == 0 and sum(1 for line in dump.splitlines() if line.startswith("set ")) == len(PARAMS)
    code, diff, _ = run(capsys, "params", "diff", "--port", sim.cli_url)
    assert code == 0 and diff.startswith("# diff all") and "set d_yaw = 7" in diff.splitlines()
    assert "set f_yaw = " not in diff  # defaults are left out


def test_restore_preview_shows_the_diff_and_leaves_the_controller_unchanged(sim, capsys, monkeypatch,
                                                                             tmp_path):
    run(capsys, "params", "set", "p_roll=44", "d_pitch=45", "--port", sim.cli_url)
    f = tmp_path / "tune.txt"
    f.write_text("# dump\nbatch start\nset p_roll = 66\nset d_pitch = 45\nfeature TELEMETRY\nbatch end\n")
    code, out, err = run(capsys, "params", "restore", f, "--preview", "--port", sim.cli_url)
    assert code == 0
    assert "p_roll" in out and "44 -> 66" in out and "d_pitch" not in out  # only what differs
    assert "preview only" in out and "line 5 skipped" in err
    assert cli_value(capsys, sim, "p_roll") == "p_roll = 44"
    # without --yes it asks; anything but y applies nothing
    code, out, _ = run(capsys, "params", "restore", f, "--port", sim.cli_url, stdin="n\n",
                       monkeypatch=monkeypatch)
    assert code == 1 and "not applied" in out
    assert cli_value(capsys, sim, "p_roll") == "p_roll = 44"
    code, out, _ = run(capsys, "params", "restore", f, "--port", sim.cli_url, stdin="y\n",
                       monkeypatch=monkeypatch)
    assert code == 0 and "applied 1 change and saved" in out
    assert cli_value(capsys, sim, "p_roll") == "p_roll = 66"
    code, out, _ = run(capsys, "params", "restore", f, "--yes", "--port", sim.cli_url)
    assert code == 0 and "already matches" in out


def test_a_set_file_is_read_one_way_for_the_cli_and_the_ground_station():
    text = "# diff all\nbatch start\nset p_roll = 60\nfeature ESC_SENSOR\nset p_pitch 3\nset nosuch = 1\nsave\n"
    values, is_diff, skipped, errors = parse_set_text(text)
    assert values == {"p_roll": 60} and is_diff
    assert skipped == [(4, "feature ESC_SENSOR")]
    assert [n for n, _ in errors] == [5, 6] and "use set name = value" in errors[0][1]
    assert "unknown parameter" in errors[1][1]
    # `defaults nosave` makes a dump a diff: what came before it is dropped
    values, is_diff, _, _ = parse_set_text("set p_roll = 70\ndefaults nosave\nset i_roll = 80\n")
    assert values == {"i_roll": 80} and is_diff


def test_a_bad_line_in_a_restore_file_stops_before_anything_is_sent(tmp_path, capsys):
    f = tmp_path / "bad.txt"
    f.write_text("set p_roll = 60\nset p_roll = 9999\n")
    code, out, err = run(capsys, "params", "restore", str(f), "--preview", "--port", "tcp://127.0.0.1:9")
    assert_one_line_error(code, err, "bad.txt line 2:")


def test_a_diff_file_restores_unlisted_parameters_to_their_defaults():
    current = {"p_roll": 50, "i_roll": 99, "d_roll": row("d_roll")[1]}
    changes = changes_to(current, {"p_roll": 60}, is_diff=True)
    assert changes == [("p_roll", 50, 60), ("i_roll", 99, row("i_roll")[1])]
    assert changes_to(current, {"p_roll": 60}, is_diff=False) == [("p_roll", 50, 60)]


def test_restore_refuses_a_bad_file_before_connecting(capsys, tmp_path):
    f = tmp_path / "bad.txt"
    f.write_text("set p_roll = 60\nset p_roll = 9999\n")
    code, _, err = run(capsys, "params", "restore", f, "--preview", "--port", "socket://127.0.0.1:1")
    assert_one_line_error(code, err, "line 2", "out of range")
    code, _, err = run(capsys, "params", "restore", tmp_path / "missing.txt", "--port", "socket://127.0.0.1:1")
    assert_one_line_error(code, err, "cannot read")


# --------------------------------------------------------------------------------- hoverfly maint
def test_maint_read_gives_header_fields_by_name(sim, capsys):
    code, out, _ = run(capsys, "maint", "--port", sim.maint_url, "read", "sw_ver", "body_pitch",
                       "motors_armed", "--json")
    assert code == 0
    values = json.loads(out)
    assert list(values) == ["body_pitch", "motors_armed", "sw_ver"]
    assert values["motors_armed"] == 0 and abs(values["body_pitch"]) < 10 and len(values["sw_ver"]) == 4
    code, out, _ = run(capsys, "maint", "--port", sim.maint_url, "read")
    assert code == 0 and len(out.splitlines()) == mp.FIELD_COUNT


def test_maint_props_off_motor_test_spins_then_stops_and_releases(sim, capsys):
    code, out, _ = run(capsys, "maint", "--port", sim.maint_url, "--json", "motors", "--props-off",
                       "1100,1150,1200,1250", "--seconds", "0.3")
    assert code == 0
    result = json.loads(out)
    last = result["last"]
    assert [last["motor%d_signal" % k] for k in (1, 2, 3, 4)] == [1100, 1150, 1200, 1250]
    assert last["motors_armed"] == 0
    values = json.loads(run(capsys, "maint", "--port", sim.maint_url, "--json", "read", "motor1_signal")[1])
    assert values["motor1_signal"] == 1000
    # motor control was released: a motor command alone is refused again
    code, _, err = run(capsys, "maint", "--port", sim.maint_url, "command", "set_motor1", "1200")
    assert_one_line_error(code, err, "refused set_motor1")


def test_maint_set_updates_a_parameter_the_cli_then_shows(sim, capsys):
    code, out, _ = run(capsys, "maint", "--port", sim.maint_url, "set", "i_pitch", "77")
    assert code == 0 and out.startswith("i_pitch = 77")
    assert cli_value(capsys, sim, "i_pitch") == "i_pitch = 77"
    code, out, _ = run(capsys, "maint", "--port", sim.maint_url, "--json", "set", "gyro_lpf1_hz", "200")
    assert code == 0 and json.loads(out) == {"gyro_lpf1_hz": 200}
    assert cli_value(capsys, sim, "gyro_lpf1_hz") == "gyro_lpf1_hz = 200"


def test_maint_command_runs_any_seed_command(sim, capsys):
    code, out, _ = run(capsys, "maint", "--port", sim.maint_url, "command", "set_pt1_magn", "0", "0", "0",
                       "--read", "imu_type")
    assert code == 0 and "set_pt1_magn: ok" in out and "imu_type" in out
    code, _, err = run(capsys, "maint", "--port", sim.maint_url, "command", "20", "0.1", "0.1", "0.1")
    assert_one_line_error(code, err, "refused set_pt1_magn")  # no magnetometer filter: only 0 is taken


@pytest.mark.parametrize("argv, words", [
    (("set", "p_roll", "999"), ("out of range",)),
    (("set", "no_such", "1"), ("cannot be set over the maintenance protocol",)),
    (("read", "no_such_field"), ("unknown maintenance field 'no_such_field'",)),
    (("motors", "--props-off", "1100,2500,1100,1100"), ("outside 1000..2000",)),
    (("motors", "--props-off", "1100,1100"), ("4 values",)),
    (("command", "99"), ("unknown maintenance command",)),
    (("command", "set_motor1"), ("takes 1 argument",)),
])
def test_maint_mistakes_are_one_line_errors(sim, capsys, argv, words):
    code, _, err = run(capsys, "maint", "--port", sim.maint_url, *argv)
    assert_one_line_error(code, err, *words)


# ------------------------------------------------------------------------------------ dead links
@pytest.mark.parametrize("url, words", [
    ("socket://127.0.0.1:1", ("cannot open socket://127.0.0.1:1", "refused")),
    ("socket://localhost", ("bad URL",)),
    ("nosuch://x", ("cannot open nosuch://x",)),
    ("/dev/hoverfly-no-such-port", ("cannot open /dev/hoverfly-no-such-port",)),
])
def test_bad_or_refused_urls_are_one_line_errors(capsys, url, words):
    for argv in (("params", "get", "p_roll", "--port", url), ("maint", "--port", url, "read"),
                 ("connect", url)):
        code, _, err = run(capsys, *argv)
        assert_one_line_error(code, err, *words)


def test_the_wrong_port_is_a_one_line_error_without_traceback(sim):
    # The CLI/MSP port also answers the maintenance protocol (as the Pico's USB does); the UART's
    # maintenance-only port has no CLI.
    r = subprocess.run([HOVERFLY, "params", "get", "p_roll", "--port", sim.maint_url, "--timeout", "0.2"],
                       capture_output=True, text=True, timeout=20)
    assert r.returncode == 2 and r.stderr.startswith("hoverfly: error: no CLI prompt")
    assert len(r.stderr.strip().splitlines()) == 1


def test_the_cli_and_msp_port_also_answers_the_maintenance_protocol(sim):
    r = subprocess.run([HOVERFLY, "maint", "--port", sim.cli_url, "--timeout", "2", "read", "body_roll"],
                       capture_output=True, text=True, timeout=20)
    assert r.returncode == 0 and r.stdout.startswith("body_roll"), r.stderr


# ------------------------------------------------------------------------------------ persistence
def test_set_and_save_survive_a_restart_with_the_same_storage(capsys, tmp_path):
    storage = str(tmp_path / "params.bin")
    first = Sim(storage)
    try:
        assert run(capsys, "params", "set", "p_roll=61", "--save", "--port", first.cli_url)[0] == 0
        assert run(capsys, "params", "set", "i_roll=71", "--port", first.cli_url)[0] == 0
        assert run(capsys, "params", "save", "--port", first.cli_url)[0] == 0
        assert run(capsys, "maint", "--port", first.maint_url, "set", "d_pitch", "33")[0] == 0
        assert run(capsys, "maint", "--port", first.maint_url, "save")[0] == 0
    finally:
        first.stop()
    second = Sim(storage)
    try:
        assert cli_value(capsys, second, "p_roll") == "p_roll = 61"
        assert cli_value(capsys, second, "i_roll") == "i_roll = 71"
        out = run(capsys, "maint", "--port", second.maint_url, "--json", "read", "PID_params")[1]
        values = json.loads(out)
        assert values["PID_params"][6 + mp.PID_BD] == 33
    finally:
        second.stop()
