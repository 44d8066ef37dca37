"""`hoverfly fly --firmware micropython`: the flight firmware under the MicroPython VM over the bridge.

The physics stays in CPython; each step one STEP frame goes out (IMU sample, CRSF bytes,
battery) and one OUT frame comes back (motor outputs, flags, events). The hover must hold
and match the in-process CPython flight.
"""

import json
import os

import pytest

from hoverfly.cli import main
from hoverfly.sim.runner import fly
from test_micropython import MICROPYTHON

needs_mp = pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")


@needs_mp
def test_hover_under_micropython_holds_and_matches_cpython():
    # the hover scenario, judged from 5 s, shortened to 8 s to keep the test quick
    cp = fly("hover", seed=3, duration_s=8)
    mp = fly("hover", seed=3, duration_s=8, firmware="micropython", micropython=MICROPYTHON)
    assert mp["tilt_rms_deg"] <= 1.5
    assert not mp["crashed"] and mp["armed"]
    # same core, same inputs: the flights agree closely (bit-exact on the 64-bit VM today)
    assert abs(mp["tilt_rms_deg"] - cp["tilt_rms_deg"]) <= 0.05
    assert abs(mp["altitude_m"]["final"] - cp["altitude_m"]["final"]) <= 0.05
    assert abs(mp["horizontal_drift_m"] - cp["horizontal_drift_m"]) <= 0.05
    assert [(e["event"], e["t_s"]) for e in mp["events"]] == [(e["event"], e["t_s"]) for e in cp["events"]]
    fw = mp["firmware"]
    assert fw["runtime"] == "micropython" and fw["steps"] == 8000
    assert fw["crc_errors"] == 0 and fw["pass_mean_us"] > 0


@needs_mp
def test_the_flashed_bundle_flies_as_the_sources_do(unix_bundle):
    # `hoverfly flash`'s bundle, precompiled with NATIVE_MODULES as machine code (built for the unix VM): the
    # native emitter makes the same calls on the same floats, so the flight is the same to the bit.
    src = fly("angle-steps", seed=5, duration_s=6, firmware="micropython", micropython=MICROPYTHON)
    flashed = fly("angle-steps", seed=5, duration_s=6, firmware="micropython", micropython=MICROPYTHON,
                  bundle=str(unix_bundle))
    for key in ("tilt_rms_deg", "max_tilt_deg", "altitude_m", "horizontal_drift_m", "steps", "events", "outputs"):
        assert flashed[key] == src[key], key
    assert flashed["armed"] and not flashed["crashed"] and flashed["firmware"]["crc_errors"] == 0


@needs_mp
def test_a_bundle_that_is_not_one_is_one_line(tmp_path, capsys):
    code = main(["fly", "--scenario", "hover", "--firmware", "micropython", "--bundle", str(tmp_path)])
    assert code == 2
    err = capsys.readouterr().err
    assert "not a hoverfly flash bundle" in err and "Traceback" not in err
    assert main(["fly", "--scenario", "hover", "--bundle", str(tmp_path)]) == 2
    assert "--firmware micropython" in capsys.readouterr().err
    # a bundle built for a board holds ARM machine code this VM cannot load: named before the firmware starts
    board = tmp_path / "rp2040"
    assert main(["flash", "--out", str(board), "--chip", "rp2040"]) == 0
    capsys.readouterr()
    assert main(["fly", "--scenario", "hover", "--firmware", "micropython", "--bundle", str(board)]) == 2
    err = capsys.readouterr().err
    assert "--chip unix-x64" in err and "Traceback" not in err and err.count("\n") == 1


@needs_mp
def test_cli_flies_with_the_micropython_firmware(capsys):
    code = main(["fly", "--scenario", "hover", "--duration", "3", "--firmware", "micropython",
                 "--micropython", MICROPYTHON, "--json"])
    assert code == 0
    r = json.loads(capsys.readouterr().out)
    assert r["firmware"]["runtime"] == "micropython"
    assert any(e["event"] == "armed" for e in r["events"])


def test_bridge_also_runs_a_cpython_firmware_process():
    r = fly("hover", duration_s=3, firmware="cpython-process")
    assert r["firmware"]["steps"] == 3000
    assert any(e["event"] == "armed" for e in r["events"])


def test_missing_micropython_is_one_line_error(capsys):
    code = main(["fly", "--scenario", "hover", "--firmware", "micropython", "--micropython", "/nonexistent/mp"])
    assert code == 2
    err = capsys.readouterr().err
    assert "no such program" in err and "Traceback" not in err


def test_firmware_that_dies_is_a_user_error(capsys):
    code = main(["fly", "--scenario", "hover", "--firmware", "micropython", "--micropython", "false"])
    assert code == 2
    assert "firmware bridge" in capsys.readouterr().err


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="needs Linux and two CPUs")
def test_the_simulator_and_its_firmware_process_share_one_cpu_while_the_bridge_is_open():
    # the two take turns: on one CPU a turn is a switch, on two a wake-up across CPUs (docs/sweep-and-tune.md)
    from hoverfly.sim.bridge import PipeTransport, firmware_command

    before = os.sched_getaffinity(0)
    t = PipeTransport(*firmware_command("cpython-process"), same_cpu=True)
    t.open()
    try:
        assert os.sched_getaffinity(0) == {t.cpu} == os.sched_getaffinity(t._proc.pid)
    finally:
        t.close()
    assert os.sched_getaffinity(0) == before
    # same_cpu=False (HOVERFLY_BRIDGE_SAME_CPU=0) leaves both to the scheduler
    free = PipeTransport(*firmware_command("cpython-process"), same_cpu=False)
    free.open()
    try:
        assert free.cpu is None and os.sched_getaffinity(free._proc.pid) == before
    finally:
        free.close()
