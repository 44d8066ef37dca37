"""`hoverfly sim` over TCP: an independent MSP client (yamspy) reads the simulated controller and
drives it; maintenance-protocol parameter writes persist across a restart with the same storage."""

import logging
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from hoverfly.core.board import SERIAL_CONFIG, SERIAL_MAINT
from hoverfly.protocols import maintenance as mp
from hoverfly.protocols import msp
from hoverfly.sim.server import SimServer

yamspy = pytest.importorskip("yamspy")
serial = pytest.importorskip("serial")

HOVERFLY = str(Path(sys.executable).parent / "hoverfly")


@pytest.fixture
def sim(tmp_path):
    server = SimServer("5inch", 0, 0, str(tmp_path / "params.bin"), duration_s=60)
    calls = []
    original = getattr(server.flight, "on_msp_rc", None)

    def recording(now_us, channels_us, count):
        calls.append(list(channels_us[:count]))
        return original(now_us, channels_us, count) if original is not None else None

    server.flight.on_msp_rc = recording
    server.rc_calls = calls
    t = threading.Thread(target=server.serve, daemon=True)
    t.start()
    yield server
    server.stop()
    t.join(5)
    assert not t.is_alive()


def _yamspy(port):
    level = logging.getLogger().level
    board = yamspy.MSPy("/dev/null", logfilename=None, loglevel="WARNING")
    logging.getLogger().setLevel(level)
    board.conn = serial.serial_for_url("socket://127.0.0.1:%d" % port, timeout=2)
    return board


def _ask(board, name, data=()):
    assert board.send_RAW_msg(board.MSPCodes[name], data=list(data))
    handler = board.receive_msg()
    assert board.process_recv_data(handler) >= 0
    return handler


def test_yamspy_reads_identity_status_attitude_imu_and_rc(sim, capsys):
    board = _yamspy(sim.ports.address(SERIAL_CONFIG)[1])
    board.basic_info()
    capsys.readouterr()  # basic_info prints its CONFIG
    c = board.CONFIG
    assert c["apiVersion"] == "1.46.0" and c["flightControllerIdentifier"] == "HVFL"
    assert c["flightControllerVersion"] == "0.1.0" and c["name"] == "hoverfly" and c["boardIdentifier"] == "HVFL"
    _ask(board, "MSP_STATUS_EX")
    assert board.CONFIG["armingDisableCount"] == 31
    time.sleep(0.3)
    _ask(board, "MSP_RAW_IMU")
    acc = board.SENSOR_DATA["accelerometer"]
    assert acc[2] == pytest.approx(2048, abs=100)  # resting on the ground: 1 g up, acc_1G = 2048
    _ask(board, "MSP_ATTITUDE")
    assert abs(board.SENSOR_DATA["kinematics"][0]) < 5 and abs(board.SENSOR_DATA["kinematics"][1]) < 5
    _ask(board, "MSP_RC")
    assert len(board.RC["channels"]) == 18 and board.RC["channels"][3] < 1100  # throttle low
    board.conn.close()


def test_yamspy_set_raw_rc_reaches_the_controller(sim):
    board = _yamspy(sim.ports.address(SERIAL_CONFIG)[1])
    channels = [1500, 1600, 1000, 1500, 1000, 1000, 1500, 1500]
    for _ in range(3):
        board.send_RAW_RC(channels)
        handler = board.receive_msg()
        board.process_recv_data(handler)
    deadline = time.time() + 3
    while not sim.rc_calls and time.time() < deadline:
        time.sleep(0.02)
    assert sim.rc_calls and sim.rc_calls[0] == channels
    board.conn.close()


def test_a_misbehaving_client_does_not_stall_the_loop(sim):
    port = sim.ports.address(SERIAL_CONFIG)[1]
    junk = socket.create_connection(("127.0.0.1", port))
    junk.sendall(bytes(range(256)) * 64 + b"#" + b"dump\r" * 50)  # then never reads its replies
    passes = sim.flight.scheduler.stats[0]  # PS_PASSES
    time.sleep(1.0)
    done = sim.flight.scheduler.stats[0] - passes
    assert done > 800  # ~1000 passes a second in real time
    junk.close()
    time.sleep(0.2)
    assert sim.flight.config_session & 1 == 0  # the CLI session ended with the connection


def _maint(port, frame, want_header):
    with socket.create_connection(("127.0.0.1", port), timeout=3) as s:
        s.sendall(frame)
        p = mp.MaintenanceParser(replies=True, expected_header=want_header)
        deadline = time.time() + 3
        while time.time() < deadline:
            p.feed(s.recv(4096))
            if p.pop():
                return p
    raise AssertionError("no maintenance reply")


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(storage):
    msp_port, maint_port = _free_port(), _free_port()
    proc = subprocess.Popen([HOVERFLY, "sim", "--msp-port", str(msp_port), "--maint-port", str(maint_port),
                             "--storage", storage, "--duration", "30"], stdout=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    assert "hoverfly sim" in line, line
    return proc, msp_port, maint_port


def test_maintenance_parameter_writes_persist_across_a_restart(tmp_path):
    storage = str(tmp_path / "params.bin")
    proc, _, maint_port = _start(storage)
    try:
        frame = mp.encode_request([], mp.CMD_SET_ROLL_PID, (60.0, 70.0, 0.0, 350.0, 0.0, 35.0))
        assert _maint(maint_port, frame, None).cmd_id == mp.CMD_SET_ROLL_PID
        frame = mp.encode_request([], mp.CMD_FLASH_WRITE)
        assert _maint(maint_port, frame, None).cmd_id == mp.CMD_FLASH_WRITE
    finally:
        proc.terminate()
        proc.wait(10)
    proc, msp_port, maint_port = _start(storage)
    try:
        header = mp.encode_header(["PID_params"], 0)
        p = _maint(maint_port, mp.encode_request(["PID_params"]), header)
        pid = dict(p.values)["PID_params"]
        assert pid[0] == 60 and pid[1] == 70 and pid[3] == 350 and pid[5] == 35
        with socket.create_connection(("127.0.0.1", msp_port), timeout=3) as s:
            s.sendall(msp.encode_request(msp.MSP_PID))
            parser = msp.MspParser()
            while not parser.pop():
                parser.feed(s.recv(256))
            assert msp.unpack_pid(parser.message())[0] == (60, 70, 35)
    finally:
        proc.terminate()
        proc.wait(10)


def test_sim_refuses_a_busy_port_with_one_line():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        busy = s.getsockname()[1]
        r = subprocess.run([HOVERFLY, "sim", "--msp-port", str(busy), "--duration", "1"], capture_output=True,
                           text=True, timeout=20)
    assert r.returncode == 2 and "cannot serve on 127.0.0.1:%d" % busy in r.stderr
    assert "Traceback" not in r.stderr
    assert SERIAL_MAINT == 1
