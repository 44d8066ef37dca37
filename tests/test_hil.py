"""`hoverfly fly --hil PORT`: the firmware on a device behind a serial port (hardware in the loop).

The device here is the real MicroPython VM running the Pico's HIL entry point
(boards/rp2/hil.py) on one end of a pseudo-terminal pair, raw mode; the host opens the
other end's /dev/pts/N path with pyserial, exactly as it opens /dev/ttyACM0 for a Pico.
(The VM sits on the pair's master side: the /dev/pts/N path is the slave side, and the
two ends of the pair are what a USB cable's two ends are.) A device that never answers,
freezes mid-flight or speaks something else is a one-line error, never a hang.
"""

import json
import os
import signal
import subprocess
import threading
import time
import tty
from contextlib import contextmanager

import pytest

from hoverfly.cli import main
from hoverfly.errors import UserError
from hoverfly.protocols import bridge as B
from hoverfly.sim.bridge import DEFAULT_HEAP
from hoverfly.sim.runner import SimRun, fly
from test_micropython import MICROPYTHON, ROOT

needs_mp = pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")
DEVICE_CODE = "from hoverfly.boards.rp2.hil import main; main(sessions=1)"


@contextmanager
def pty_port():
    """(path the host opens, the far end's fd); both closed afterwards."""
    far, near = os.openpty()
    tty.setraw(near)
    try:
        yield os.ttyname(near), far
    finally:
        os.close(far)
        os.close(near)


@contextmanager
def micropython_device():
    """The HIL firmware under the MicroPython VM on the far end of a pty; yields (path, process)."""
    with pty_port() as (path, far):
        env = dict(os.environ, MICROPYPATH="%s:.frozen" % (ROOT / "src"))
        # the bridge's heap: compiled from source at import, as `hoverfly fly --firmware micropython` runs it
        proc = subprocess.Popen([MICROPYTHON, "-X", "heapsize=" + DEFAULT_HEAP, "-c", DEVICE_CODE], stdin=far,
                                stdout=far, stderr=subprocess.PIPE, env=env)
        try:
            yield path, proc
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.wait()
            proc.stderr.close()


@contextmanager
def fake_device(answer):
    """A device on the far end of a pty that answers every read with answer(bytes_read)."""
    with pty_port() as (path, far):
        def run():
            while True:
                try:
                    data = os.read(far, 4096)
                    if not data:
                        return
                    os.write(far, answer(data))
                except OSError:
                    return

        threading.Thread(target=run, daemon=True).start()
        yield path


def events(r):
    return [(e["event"], e["t_s"], e["detail"]) for e in r["events"]]


@needs_mp
def test_hover_over_a_serial_port_holds_and_matches_the_micropython_bridge(capsys):
    # given the Pico's HIL entry point on the far end of a serial line
    with micropython_device() as (path, proc):
        # when the host flies the hover through it
        code = main(["fly", "--hil", path, "--scenario", "hover", "--seed", "3", "--duration", "8", "--json"])
        assert code == 0, capsys.readouterr().err
        hil = json.loads(capsys.readouterr().out)
        # then the session ends cleanly on the device (QUIT, ACK, its one session served)
        assert proc.wait(timeout=10) == 0
    assert hil["tilt_rms_deg"] <= 1.5
    assert not hil["crashed"] and hil["armed"]
    fw = hil["firmware"]
    assert fw["runtime"] == "hil" and fw["command"] == path and fw["steps"] == 8000
    assert fw["crc_errors"] == 0 and fw["pass_mean_us"] > 0
    # and it flies as the same VM over pipes does: same core, same inputs, same seed
    mp = fly("hover", seed=3, duration_s=8, firmware="micropython", micropython=MICROPYTHON)
    assert abs(hil["tilt_rms_deg"] - mp["tilt_rms_deg"]) <= 0.05
    assert abs(hil["altitude_m"]["final"] - mp["altitude_m"]["final"]) <= 0.05
    assert abs(hil["horizontal_drift_m"] - mp["horizontal_drift_m"]) <= 0.05
    assert events(hil) == events(mp)


def test_a_device_that_never_answers_is_a_one_line_error_within_seconds(capsys):
    with pty_port() as (path, _far):
        t0 = time.monotonic()
        code = main(["fly", "--hil", path, "--scenario", "hover", "--json"])
        took_s = time.monotonic() - t0
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert path in err and "no answer to HELLO" in err
    assert took_s < 8.0


@needs_mp
def test_a_device_that_freezes_mid_flight_names_the_step():
    with micropython_device() as (path, proc):
        run = SimRun("5inch", "hover", seed=1, duration_s=3, hil=path)

        def freeze(r):
            if r.flight.steps == 400:
                os.kill(proc.pid, signal.SIGSTOP)

        run.on_step = freeze
        t0 = time.monotonic()
        with pytest.raises(UserError) as exc:
            run.run()
        assert time.monotonic() - t0 < 15.0
    msg = str(exc.value)
    assert path in msg and "no answer to step 401" in msg and "\n" not in msg


def test_a_device_that_speaks_something_else_is_a_clear_error(capsys):
    # a MicroPython REPL where the bridge should be: text, never a frame
    repl = b"MicroPython v1.24.0 on 2024-10-25; Raspberry Pi Pico with RP2040\r\n>>> " * 80
    with fake_device(lambda data: repl) as path:
        t0 = time.monotonic()
        code = main(["fly", "--hil", path, "--scenario", "hover"])
        took_s = time.monotonic() - t0
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and path in err
    assert "no bridge frame" in err and "not the hoverfly bridge firmware" in err
    assert took_s < 8.0


def test_frames_that_fail_their_crc_are_a_clear_error(capsys):
    bad = bytearray(B.frame(B.HELLO, B.VERSION.encode()))
    bad[-1] ^= 0x5A
    with fake_device(lambda data: bytes(bad)) as path:
        code = main(["fly", "--hil", path, "--scenario", "hover"])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "no bridge frame" in err and "CRC errors" in err


def test_a_device_with_another_protocol_version_is_told_to_update(capsys):
    old = B.frame(B.HELLO, b"hoverfly-bridge 1")
    with fake_device(lambda data: old if bytes([B.SYNC, B.HELLO]) in data else b"") as path:
        code = main(["fly", "--hil", path, "--scenario", "hover"])
    assert code == 2
    err = capsys.readouterr().err
    assert "hoverfly-bridge 1" in err and "hoverfly flash" in err


def test_a_port_that_cannot_be_opened_is_a_one_line_error(capsys):
    code = main(["fly", "--hil", "/dev/nonexistent-hoverfly-port", "--scenario", "hover"])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert "cannot open the port" in err
    assert "/dev/nonexistent-hoverfly-port" in err and len(err.splitlines()) == 1


def test_hil_and_a_firmware_process_are_one_or_the_other(capsys):
    code = main(["fly", "--hil", "/dev/null", "--firmware", "micropython", "--scenario", "hover"])
    assert code == 2
    assert "--hil" in capsys.readouterr().err
