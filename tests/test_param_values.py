"""Parameter values enter through one check (core/config/params.check): finite numbers, whole numbers where the
table says so, ranges, choices, the same names and aliases on every surface, and reboot parameters
stored but never applied to a running flight (issues 30 and 25)."""

from configfakes import make_flight
from hypothesis import given, settings
from hypothesis import strategies as st

from hoverfly.cli import main
from hoverfly.cli_params import parse_assignment
from hoverfly.core.config.params import ALIASES, INDEX, PARAMS, Params, check, check_value, is_choice, nearest
from hoverfly.core.config.storage import Storage, parse_record
from hoverfly.core.links.cliserver import CliServer
from hoverfly.core.links.maintserver import ERROR_CMD, MaintServer
from hoverfly.errors import UserError
from hoverfly.protocols import maintenance as mp
from hoverfly.sim.runner import SimRun, build_params

HOSTILE = (float("inf"), float("-inf"), float("nan"), 1e308, -1e308, 10 ** 400, -(10 ** 400), 10 ** 5000,
           "inf", "-inf", "nan", "1e308", "1e400", "9" * 5000, "", " ", "0x10", "1,5", None, b"12", [1], {"a": 1},
           (1, 2), object(), 1j)
NAMES = [r[0] for r in PARAMS] + sorted(ALIASES)


def _assert_reason(err):
    assert isinstance(err, str) and err and "\n" not in err and "\r" not in err and len(err) < 240, err


def _assert_stored_value_ok(key, v):
    r = PARAMS[INDEX[key]]
    if is_choice(r):
        assert v in r[4]
    else:
        assert type(v) is type(r[1]) and r[2] <= v <= r[3] and v - v == 0


# ------------------------------------------------------------------------------ the check itself
@settings(max_examples=400, deadline=None)
@given(st.sampled_from(NAMES) | st.text(max_size=30) | st.none() | st.binary(max_size=8) | st.integers(),
       st.floats(allow_nan=True, allow_infinity=True) | st.integers(min_value=-(10 ** 600), max_value=10 ** 600)
       | st.text(max_size=40) | st.booleans() | st.none() | st.binary(max_size=8) | st.lists(st.integers(), max_size=3)
       | st.sampled_from(HOSTILE))
def test_check_never_raises_and_answers_a_stored_value_or_one_line(name, value):
    key, v, err = check(name, value)
    if err is None:
        _assert_stored_value_ok(key, v)
    else:
        assert key is None and v is None
        _assert_reason(err)


def test_every_row_refuses_every_hostile_value_with_a_reason():
    for r in PARAMS:
        for value in HOSTILE:
            key, v, err = check(r[0], value)
            if err is None:  # a choice row takes a whole-number index; nothing else non-finite gets in
                _assert_stored_value_ok(key, v)
                assert not isinstance(value, float) or value - value == 0
            else:
                _assert_reason(err)


def test_the_values_that_killed_the_sim_get_a_reason():
    assert "finite" in check_value("p_roll", float("inf"))[1]
    assert "finite" in check_value("d_roll", float("nan"))[1]
    assert "finite" in check_value("failsafe_delay", 1e308)[1]  # x100 into fs_delay_ms: inf
    assert "finite" in check_value("failsafe_delay", "1e308")[1]
    assert "out of range" in check_value("fs_delay_ms", 1e308)[1]
    assert "huge" in check_value("loop_hz", 10 ** 5000)[1]  # never str() of a 5000-digit int


def test_numbers_convert_to_the_row_type():
    assert check_value("p_roll", "45") == (45, None)
    assert check_value("p_roll", 45.0) == (45, None)
    assert "whole number" in check_value("p_roll", 45.5)[1]
    assert check_value("motor_idle_pct", 6) == (6.0, None) and isinstance(check_value("motor_idle_pct", 6)[0], float)
    assert check_value("mixer_type", "HEXX") == ("hexx", None)


def test_a_misspelt_name_gets_the_nearest_one():
    assert "did you mean p_roll?" in check("p_rol", 3)[2]
    assert "did you mean gyro_lpf1_hz?" in check("gyro_lpf_hz", 3)[2]
    assert "did you mean failsafe_procedure?" in check("failsafe_procedur", "drop")[2]
    assert nearest("zzzzzzzzzzzzzzzz") is None
    assert "did you mean" not in check("x" * 500, 1)[2]


# ------------------------------------------------------------------------------ every surface
def _cli_flight():
    flight, board = make_flight(seams=False)
    storage = Storage(board)
    storage.load(flight.params)
    cli = CliServer(flight, storage)
    cli.enter(lambda b: None)
    return cli, flight, storage


def _type(cli, text):
    out = []
    data = text.encode()
    cli.feed(data, len(data), out.append)
    return b"".join(out).decode()


def test_cli_set_of_non_finite_values_is_one_error_line_and_changes_nothing():
    cli, f, _ = _cli_flight()
    before = dict(f.params.values)
    for line in ("set p_roll = inf", "set d_roll = nan", "set failsafe_delay = 1e308", "set p_roll = 1e400",
                 "set loop_hz = " + "9" * 200, "set dshot_idle_value = nan", "set mixer_type = 1e308"):
        text = _type(cli, line + "\r")
        errors = [x for x in text.split("\r\n") if "###ERROR" in x]
        assert len(errors) == 1, text
    assert f.params.values == before and not f.params.pending


def test_msp_and_maintenance_paths_refuse_non_finite_values():
    f, board = make_flight()
    before = dict(f.params.values)
    # MSP's writes and the maintenance commands go through Params.update (all or nothing)
    _assert_reason(f.params.update((("p_roll", 50), ("d_roll", float("nan")))))
    assert f.params.values == before
    server = MaintServer(f, Storage(board))
    frame = mp.encode_request([], 15, (float("nan"), 60.0, 0.25, 300.0, 0.5, 30.0), None)
    out = []
    server.feed(frame, len(frame), out.append)
    raw = b"".join(out)
    assert raw and mp.header_cmd(raw[1:9]) == ERROR_CMD
    assert f.params.values == before


def test_hoverfly_fly_set_with_a_non_finite_value_is_one_line(capsys):
    for item in ("p_roll=inf", "d_roll=nan", "failsafe_delay=1e308"):
        assert main(["fly", "--duration", "0.5", "--set", item]) != 0
        err = capsys.readouterr().err.strip()
        assert err.startswith("hoverfly: error: --set") and "finite" in err and "\n" not in err


def test_params_set_on_the_host_checks_before_sending():
    for text in ("p_roll=inf", "d_roll=nan", "failsafe_delay=1e308", "p_rol=3"):
        try:
            parse_assignment(text)
        except UserError as exc:
            _assert_reason(str(exc))
        else:
            raise AssertionError(text)
    assert parse_assignment("failsafe_procedure=drop")[:2] == ("fs_procedure", "drop")


def test_every_surface_takes_the_betaflight_names():
    # --set (and the airframe/scenario layers): build_params through Params.set
    af = {"name": "t", "frame": "quadx", "params": {"failsafe_delay": 5}}
    p = build_params(af, {"params": {"dshot_idle_value": 600}}, [("failsafe_procedure", "drop")])
    assert (p.get("fs_procedure"), p.get("fs_delay_ms"), p.get("motor_idle_pct")) == ("drop", 500, 6.0)
    # CLI
    cli, f, _ = _cli_flight()
    assert "fs_procedure set to drop" in _type(cli, "set failsafe_procedure = drop\r")
    # MSP / maintenance (Params.update), and storage (a record's names go through the same check)
    assert f.params.update((("failsafe_procedure", "glide"), ("FAILSAFE_DELAY", 3))) is None
    assert (f.params.get("fs_procedure"), f.params.get("fs_delay_ms")) == ("glide", 300)
    assert "fs_procedure" in f.params.values and "failsafe_procedure" not in f.params.values


# ------------------------------------------------------------------------------ reboot parameters
def test_a_reboot_parameter_set_after_boot_is_stored_not_applied():
    cli, f, storage = _cli_flight()
    n_motors = f.mixer.n
    text = _type(cli, "set mixer_type = hexx\r")
    assert "mixer_type set to hexx" in text and "applies after a reboot" in text
    assert f.params.get("mixer_type") == "quadx" and f.params.pending == {"mixer_type": "hexx"}
    t = f.board.now_us()
    for _ in range(300):  # the slow tasks re-configure on the change: the mixer keeps its boot frame
        t += 1000
        f.board.t_us = t
        f.step(t)
    assert f.mixer.n == n_motors
    assert "mixer_type = hexx  (applies after reboot; running quadx)" in _type(cli, "get mixer_type\r")
    assert "set mixer_type = hexx" in _type(cli, "diff\r")
    assert "# mixer_type applies after reboot (running quadx)" in _type(cli, "dump\r")
    assert "Saving" in _type(cli, "save\r")
    _, _, entries = parse_record(storage.image, storage.slot * 8192)
    assert ("mixer_type", "hexx") in entries
    # and the next boot runs it
    q = Params()
    Storage(f.board).load(q)
    assert q.get("mixer_type") == "hexx" and not q.pending


def test_setting_a_reboot_parameter_back_clears_the_pending_value():
    f, _ = make_flight()
    assert f.params.set("loop_hz", 2000) is None and f.params.pending == {"loop_hz": 2000}
    assert f.params.set("loop_hz", 1000) is None and f.params.pending == {}
    f.params.reset()
    assert f.params.pending == {} and f.params.get("loop_hz") == 1000


def test_reboot_parameters_apply_before_boot():
    p = Params()
    assert p.set("mixer_type", "hexx") is None and p.get("mixer_type") == "hexx" and not p.pending


def test_set_mixer_hexx_in_the_running_loop_on_the_5inch_then_it_arms_and_hovers():
    # issue 30: `set mixer_type = hexx` on the 5-inch (in range, "applies after a reboot") raised
    # IndexError in the running loop. Typed while the loop runs disarmed, the craft then arms and hovers.
    run = SimRun("5inch", "hover", seed=3, duration_s=8.0)
    sent = []

    def cli_while_disarmed(r):
        if not sent and r.board.now_us() > 1_000_000:
            assert not r.flight.arming.armed
            cli = CliServer(r.flight)
            cli.enter(lambda b: None)
            out = []
            cli.feed(b"set mixer_type = hexx\r", 22, out.append)
            cli.close()
            sent.append(b"".join(out))

    run.on_step = cli_while_disarmed
    result = run.run()
    assert sent and b"applies after a reboot" in sent[0]
    assert result["armed"] and not result["crashed"]
    assert result["max_tilt_deg"] < 30.0 and 1.0 < result["altitude_m"]["final"] < 3.0
    assert run.flight.mixer.n == 4 and run.params.get("mixer_type") == "quadx"
    assert run.params.pending == {"mixer_type": "hexx"}


def test_hoverfly_sim_over_tcp_answers_the_lines_that_killed_it_and_keeps_running(tmp_path):
    import socket
    import threading
    import time

    from hoverfly.core.board import SERIAL_CONFIG
    from hoverfly.sim.server import SimServer

    server = SimServer("5inch", 0, 0, str(tmp_path / "params.bin"), duration_s=60)
    th = threading.Thread(target=server.serve, daemon=True)
    th.start()
    try:
        s = socket.create_connection(server.ports.address(SERIAL_CONFIG), timeout=5)
        s.sendall(b"#")
        lines = (b"set p_roll = inf", b"set d_roll = nan", b"set failsafe_delay = 1e308", b"set mixer_type = hexx",
                 b"set failsafe_procedure = drop", b"set p_rol = 3")
        s.sendall(b"\r\n".join(lines) + b"\r\nget mixer_type\r\n")
        text = b""
        end = time.monotonic() + 10
        while time.monotonic() < end and b"running quadx" not in text:
            try:
                text += s.recv(65536)
            except TimeoutError:
                break
        text = text.decode()
        assert text.count("###ERROR") == 4 and "finite" in text and "did you mean p_roll?" in text
        assert "fs_procedure set to drop" in text and "mixer_type = hexx  (applies after reboot; running quadx)" in text
        assert th.is_alive() and server.run.flight.mixer.n == 4
        before_us = server.run.board.now_us()
        time.sleep(0.3)
        assert th.is_alive() and server.run.board.now_us() - before_us > 100_000  # the loop goes on
        s.close()
    finally:
        server.stop()
        th.join(5)
    assert not th.is_alive()


def test_check_never_raises_under_micropython():
    from test_micropython import MICROPYTHON, run_micropython

    if MICROPYTHON is None:
        return
    code = """
from hoverfly.core.config.params import PARAMS, ALIASES, check, Params
values = (float("inf"), float("-inf"), float("nan"), 1e308, -1e308, 10 ** 400, -(10 ** 400), "inf", "nan", "1e308",
          "1e400", "9" * 400, "", " 12 ", "0x10", None, b"12", [1], {"a": 1}, (1, 2), True, 3, 3.5, "hexx", "DROP")
names = [r[0] for r in PARAMS] + [a for a in ALIASES] + ["p_rol", "", None, 7]
ok = bad = 0
for n in names:
    for v in values:
        key, got, err = check(n, v)
        if err is None:
            ok += 1
        else:
            assert "\\n" not in err
            bad += 1
p = Params()
assert p.set("failsafe_procedure", "drop") is None and p.get("fs_procedure") == "drop"
assert p.set("p_roll", float("inf")) is not None and p.get("p_roll") == 45
p.latch_boot()
assert p.set("mixer_type", "hexx") is None and p.get("mixer_type") == "quadx" and p.pending["mixer_type"] == "hexx"
print("checked", ok, bad)
"""
    res = run_micropython(code, heap="4m", timeout=300)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    assert res.stdout.startswith("checked")


def _full_distance(a, b):
    prev = list(range(len(b) + 1))
    for i in range(1, len(a) + 1):
        cur = [i] + [0] * len(b)
        for j in range(1, len(b) + 1):
            cur[j] = min(prev[j - 1] + (a[i - 1] != b[j - 1]), prev[j] + 1, cur[j - 1] + 1)
        prev = cur
    return prev[len(b)]


@settings(max_examples=500, deadline=None)
@given(st.text("ab_cd", max_size=12), st.text("ab_cd", max_size=12), st.integers(0, 4))
def test_the_banded_distance_is_the_edit_distance_up_to_its_limit(a, b, limit):
    from hoverfly.core.config.params import _distance

    full = _full_distance(a, b)
    assert _distance(a, b, limit) == (full if full <= limit else limit + 1)


def test_a_new_flight_on_the_same_params_boots_with_the_waiting_reboot_values():
    # the firmware bridge keeps its Params across sessions and boots a new Flight on them
    from configfakes import FakeBoard

    from hoverfly.core.flight import Flight

    p = Params()
    Flight(FakeBoard(), p).start(1000)
    assert p.set("loop_hz", 2000) is None and p.get("loop_hz") == 1000
    f = Flight(FakeBoard(), p)
    f.start(1000)
    assert p.get("loop_hz") == 2000 and f.loop_hz == 2000 and not p.pending
