"""The configuration links (core/links/task.py): a session ends with its link, no request is dropped, the
config port tells MSP, CLI and maintenance frames apart, and MSP_REBOOT restarts `hoverfly sim`.

Over real sockets on 127.0.0.1 to an in-process `hoverfly sim` (ports chosen by the OS), and on the
in-memory board of the portable tests where time has to be injected (the inter-byte timeout)."""

import socket
import sys
import threading
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).parent / "portable"))
from configfakes import make_flight  # noqa: E402

from hoverfly.core.board import SERIAL_CONFIG, SERIAL_MAINT  # noqa: E402
from hoverfly.core.links.mspserver import CONFIG_MSP  # noqa: E402
from hoverfly.core.links.task import PARTIAL_FRAME_US, REQUESTS_PER_RUN, ConfigLinks, ConfigPort  # noqa: E402
from hoverfly.core.safety.arming import MAINTENANCE, session_flags  # noqa: E402
from hoverfly.protocols import maintenance as mp  # noqa: E402
from hoverfly.protocols import msp  # noqa: E402
from hoverfly.sim.server import SimServer  # noqa: E402

MOTOR_1100 = msp.pack_set_motor([1100] * 4)


@pytest.fixture
def sim(tmp_path):
    server = SimServer("5inch", 0, 0, str(tmp_path / "params.bin"), duration_s=120)
    t = threading.Thread(target=server.serve, daemon=True)
    t.start()
    yield server
    server.stop()
    t.join(5)
    assert not t.is_alive()


def _connect(server, pid=SERIAL_CONFIG):
    s = socket.create_connection(server.ports.address(pid), timeout=5)
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return s


def _msp_replies(sock, count, timeout_s=5.0, parser=None):
    """(direction, cmd, payload) of the next `count` MSP replies (fewer if the time runs out)."""
    p = parser if parser is not None else msp.MspParser(queue_depth=64)
    out = []
    end = time.monotonic() + timeout_s
    sock.settimeout(0.05)
    while len(out) < count and time.monotonic() < end:
        try:
            data = sock.recv(65536)
        except TimeoutError:
            continue
        if not data:
            break
        p.feed(data)
        while p.pop():
            out.append((p.direction, p.cmd, p.message()))
    return out


def _ask(sock, cmd, payload=b""):
    sock.sendall(msp.encode_request(cmd, payload))
    got = _msp_replies(sock, 1)
    assert got, "no reply to MSP %d" % cmd
    return got[0]


def _wait(cond, timeout_s=3.0):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.01)
    return cond()


# ------------------------------------------------------------------------------------ sessions
def test_a_replaced_client_cannot_drive_the_motors_with_the_first_ones_acknowledgement(sim):
    a = _connect(sim)
    assert _ask(a, msp.MSP_SET_ARMING_DISABLED, msp.pack_set_arming_disabled(1))[0] == msp.DIR_REPLY
    assert _ask(a, msp.MSP_SET_MOTOR, MOTOR_1100)[0] == msp.DIR_REPLY
    assert sim.flight.motor_test.active and sim.flight.config_session & CONFIG_MSP
    # B takes the port while A is still connected: A's session ends before B's first byte is read.
    b = _connect(sim)
    direction, cmd, _ = _ask(b, msp.MSP_SET_MOTOR, MOTOR_1100)
    assert (direction, cmd) == (msp.DIR_ERROR, msp.MSP_SET_MOTOR)
    assert "props-off" in sim.links.config.msp.last_error
    assert not sim.flight.motor_test.active  # A's motor test stopped with its session
    assert sim.flight.config_session == 0
    assert not sim.flight.arming.armed
    assert sim.links.sessions_closed >= 1
    a.close()
    b.close()


def test_a_replaced_clients_open_cli_and_half_frame_do_not_swallow_the_next_clients_msp(sim):
    a = _connect(sim)
    a.sendall(b"#")
    assert _wait(lambda: sim.links.config.cli.active)
    a.sendall(msp.encode_request(msp.MSP_API_VERSION)[:3])  # typed into A's CLI: no matter
    b = _connect(sim)
    assert _ask(b, msp.MSP_API_VERSION)[:2] == (msp.DIR_REPLY, msp.MSP_API_VERSION)  # MSP, not CLI echo
    assert not sim.links.config.cli.active and sim.flight.config_session == 0
    c = _connect(sim)
    c.sendall(msp.encode_request(msp.MSP_STATUS)[:4])  # half a frame, then the client is replaced
    time.sleep(0.05)
    d = _connect(sim)
    assert _ask(d, msp.MSP_FC_VARIANT)[:2] == (msp.DIR_REPLY, msp.MSP_FC_VARIANT)
    for s in (a, b, c, d):
        s.close()


def test_a_disconnected_maintenance_client_releases_motor_control(sim):
    a = _connect(sim, SERIAL_MAINT)
    a.sendall(mp.encode_request([], mp.CMD_CONTROL_MOTORS, (1,))
              + mp.encode_request([], mp.CMD_SET_ALL_MOTORS, (1100,)))
    assert _wait(lambda: sim.flight.motor_test.active)
    a.close()
    assert _wait(lambda: not sim.flight.motor_test.active and sim.flight.config_session == 0)
    b = _connect(sim, SERIAL_MAINT)
    b.sendall(mp.encode_request([], mp.CMD_SET_ALL_MOTORS, (1100,)))
    assert _wait(lambda: sim.links.maint.requests >= 3)
    assert not sim.flight.motor_test.active and "control_motors" in sim.links.maint.last_error
    b.close()


# ------------------------------------------------------------------------------------ no silent drops
def test_a_hundred_pipelined_msp_requests_get_a_hundred_answers_in_order(sim):
    s = _connect(sim)
    cmds = [(msp.MSP_STATUS, msp.MSP_ATTITUDE, msp.MSP_RAW_IMU, msp.MSP_API_VERSION)[k % 4] for k in range(100)]
    s.sendall(b"".join(msp.encode_request(c) for c in cmds))
    got = _msp_replies(s, 100)
    assert [c for _, c, _ in got] == cmds
    assert all(d == msp.DIR_REPLY for d, _, _ in got)
    assert sim.links.config.dropped() == 0
    s.close()


def test_a_motor_stop_among_pipelined_maintenance_requests_is_carried_out_and_all_are_answered(sim):
    s = _connect(sim, SERIAL_MAINT)
    reqs = [mp.encode_request([], mp.CMD_CONTROL_MOTORS, (1,)), mp.encode_request([], mp.CMD_SET_ALL_MOTORS, (1100,))]
    reqs += [mp.encode_request(["body_roll"])] * 5 + [mp.encode_request([], mp.CMD_SET_ALL_MOTORS, (1000,))]
    reqs += [mp.encode_request(["body_roll", "body_pitch"])] * 12
    s.sendall(b"".join(reqs))
    p = mp.MaintenanceParser(replies=True, queue_depth=64)
    cmds = []
    end = time.monotonic() + 5
    s.settimeout(0.05)
    while len(cmds) < len(reqs) and time.monotonic() < end:
        try:
            data = s.recv(65536)
        except TimeoutError:
            continue
        p.feed(data)
        while p.pop():
            cmds.append(p.cmd_id)
    assert cmds == [mp.header_cmd(r[1:9]) for r in reqs]  # every one answered, none refused, in order
    assert not sim.flight.motor_test.active  # the stop was not the one lost
    s.close()


def test_half_a_frame_then_silence_does_not_swallow_the_next_request(sim):
    s = _connect(sim)
    s.sendall(msp.encode_request(msp.MSP_STATUS)[:4])
    time.sleep(PARTIAL_FRAME_US * 2e-6)
    got = _ask(s, msp.MSP_API_VERSION)
    assert got[:2] == (msp.DIR_REPLY, msp.MSP_API_VERSION)
    assert sim.links.partial_timeouts == 1
    s.close()


def test_a_flooding_client_does_not_stall_the_other_ports_replies(sim):
    flood = _connect(sim)
    poll = _connect(sim, SERIAL_MAINT)
    stop = threading.Event()
    burst = msp.encode_request(msp.MSP_RAW_IMU) * 200

    def flooder():
        flood.settimeout(0.01)
        while not stop.is_set():
            try:
                flood.sendall(burst)
                flood.recv(1 << 20)  # read some replies so the server keeps answering
            except (TimeoutError, BlockingIOError):
                pass
            except OSError:
                return

    t = threading.Thread(target=flooder, daemon=True)
    t.start()
    time.sleep(0.3)
    lat = []
    p = mp.MaintenanceParser(replies=True)
    poll.settimeout(2)
    for _ in range(20):
        t0 = time.monotonic()
        poll.sendall(mp.encode_request(["body_roll"]))
        got = False
        while not got:
            p.feed(poll.recv(4096))
            got = p.pop()
        lat.append(time.monotonic() - t0)
    stop.set()
    t.join(2)
    assert sim.links.held_back > 0  # the flood did exceed its share
    lat.sort()
    # 100 Hz links task: a reply waits at most about a run (10 ms) plus the machine's scheduling.
    assert lat[len(lat) // 2] < 0.05 and lat[-1] < 0.25, lat
    flood.close()
    poll.close()


# ------------------------------------------------------------------------------------ in memory, time injected
def _links():
    flight, board = make_flight()
    return ConfigLinks(flight), flight, board


def _replies(data):
    p = msp.MspParser(queue_depth=256)
    p.feed(data)
    out = []
    while p.pop():
        out.append(p.cmd)
    return out


def test_a_port_gets_its_share_a_run_and_the_rest_waits_unread_for_the_next():
    links, flight, board = _links()
    board.rx[SERIAL_CONFIG] += msp.encode_request(msp.MSP_API_VERSION) * 40
    links.task(board.now_us())
    assert len(_replies(board.take(SERIAL_CONFIG))) == REQUESTS_PER_RUN and links.held_back == 1
    board.t_us += 10000
    links.task(board.now_us())
    links.task(board.now_us())
    assert len(_replies(board.take(SERIAL_CONFIG))) == 40 - REQUESTS_PER_RUN
    assert links.config.dropped() == 0


def test_a_half_frame_is_dropped_after_the_inter_byte_timeout_by_the_board_clock():
    links, flight, board = _links()
    board.rx[SERIAL_CONFIG] += msp.encode_request(msp.MSP_STATUS)[:5]
    links.task(board.now_us())
    board.t_us += PARTIAL_FRAME_US // 2
    links.task(board.now_us())
    assert links.config.in_frame() and links.partial_timeouts == 0  # not yet: the rest may come
    board.t_us += PARTIAL_FRAME_US
    links.task(board.now_us())
    assert not links.config.in_frame() and links.partial_timeouts == 1
    board.rx[SERIAL_CONFIG] += msp.encode_request(msp.MSP_API_VERSION)
    links.task(board.now_us())
    assert _replies(board.take(SERIAL_CONFIG)) == [msp.MSP_API_VERSION]


def test_a_closed_link_ends_its_session_and_its_half_frame_is_not_glued_to_the_next_clients_bytes():
    links, flight, board = _links()
    rc = msp.encode_request(msp.MSP_SET_RAW_RC, msp.pack_set_raw_rc([1500] * 8))
    board.rx[SERIAL_CONFIG] += rc * 23 + rc[:10]  # a 512-byte read: 23 frames and a half
    links.task(board.now_us())
    assert len(flight.rc_calls) == REQUESTS_PER_RUN  # the rest waits for the next run
    board.gone[SERIAL_CONFIG] = True  # the client goes; the port forgets what it had not yet read
    board.rx[SERIAL_CONFIG] = bytearray()
    links.task(board.now_us())  # what it sent before it left is answered, then its session closes
    assert len(flight.rc_calls) == 23 and links.sessions_closed == 1 and not links.config.in_frame()
    board.take(SERIAL_CONFIG)
    board.rx[SERIAL_CONFIG] += msp.encode_request(msp.MSP_API_VERSION)  # the next client
    links.task(board.now_us())
    assert _replies(board.take(SERIAL_CONFIG)) == [msp.MSP_API_VERSION] and len(flight.rc_calls) == 23


def test_status_shows_the_links_counters():
    links, flight, board = _links()
    out = links.config.cli.cmd_status()
    assert any(line.startswith("Links: MSP 0 requests") and "frames dropped 0" in line for line in out)


# ------------------------------------------------------------------------------------ one port, three protocols
def test_the_config_port_tells_msp_cli_and_maintenance_apart_by_their_first_bytes():
    flight, board = make_flight()
    port = ConfigPort(flight)
    out = []
    rc = msp.encode_request(msp.MSP_SET_RAW_RC, msp.pack_set_raw_rc([1535, 1500, 1023 + 512, 0x5FF] + [1500] * 4))
    maint = mp.encode_request(["body_roll"], mp.CMD_NONE)
    assert 0xFF in rc and 0x23 not in maint  # an MSP payload holding 0xFF stays MSP
    data = (msp.encode_request(msp.MSP_API_VERSION) + maint + rc + maint
            + msp.encode_request(msp.MSP_FC_VARIANT) + b"#")
    for cut in (len(data), 1, 3):  # in one write, a byte at a time, three at a time
        port.close()
        out = []
        for k in range(0, len(data), cut):
            port.feed(data[k:k + cut], len(data[k:k + cut]), out.append)
        replies = [r[:3] for r in out]
        assert replies[:5] == [b"$M>", b"\xff" + maint[1:3], b"$M>", b"\xff" + maint[1:3], b"$M>"], replies
        assert port.cli.active and flight.config_session & 1
        assert port.maint.requests > 0
    assert len(flight.rc_calls) == 3 and flight.rc_calls[0][0] == 1535


# ------------------------------------------------------------------------------------ reboot
def test_msp_reboot_restarts_the_sim_with_the_stored_reboot_parameter(sim):
    s = _connect(sim)
    before = [t.rate_hz for t in sim.flight.scheduler.tasks if t.name == "links"]
    assert before == [100]
    s.sendall(b"#")
    assert _wait(lambda: sim.links.config.cli.active)
    s.sendall(b"set serial_update_rate_hz = 400\r\nsave\r\n")
    assert _wait(lambda: not sim.links.config.cli.active)
    time.sleep(0.1)
    s.recv(65536)
    # not in effect before the reboot: a reboot parameter
    assert [t.rate_hz for t in sim.flight.scheduler.tasks if t.name == "links"] == [100]
    old = sim.flight
    direction, cmd, _ = _ask(s, msp.MSP_REBOOT)
    assert (direction, cmd) == (msp.DIR_REPLY, msp.MSP_REBOOT)
    assert _wait(lambda: sim.reboots == 1 and sim.flight is not old)
    assert [t.rate_hz for t in sim.flight.scheduler.tasks if t.name == "links"] == [400]
    assert sim.flight.params.get("serial_update_hz") == 400
    assert _ask(s, msp.MSP_API_VERSION)[:2] == (msp.DIR_REPLY, msp.MSP_API_VERSION)  # same port, new flight
    s.close()


def test_msp_reboot_is_refused_while_armed_and_where_the_board_cannot():
    flight, board = make_flight()
    port = ConfigPort(flight)
    out = []
    frame = msp.encode_request(msp.MSP_REBOOT)
    port.feed(frame, len(frame), out.append)
    assert out[0][2] == msp.DIR_ERROR and "cannot reboot" in port.msp.last_error
    port.msp.on_reboot = lambda: out.append(b"rebooted")
    flight.arming.armed = True
    port.feed(frame, len(frame), out.append)
    assert out[-1][2] == msp.DIR_ERROR and b"rebooted" not in out


# ------------------------------------------------------------------------------------ the rp2 board's USB
@pytest.mark.skipif(not Path(__file__).with_name("rp2fakes").is_dir(), reason="rp2 fakes missing")
def test_rp2_usb_answers_msp_and_maintenance_and_msp_reboot_resets_after_the_reply(tmp_path):
    from test_rp2_board import MICROPYTHON, run_board

    if MICROPYTHON is None:
        pytest.skip("micropython not installed")
    maint = mp.encode_request(["body_roll", "imu_type"])
    api = msp.encode_request(msp.MSP_API_VERSION)
    reboot = msp.encode_request(msp.MSP_REBOOT)
    # the board's loop under MicroPython on the fake USB port; machine.reset recorded with the bytes sent so far
    body = ("resets = []\n"
            "machine.reset = lambda: resets.append(len(board._usb.tx))\n"
            "world.at(1.0, lambda w: board._usb.inject(%r))\n"
            "world.at(1.5, lambda w: board._usb.inject(%r))\n"
            "def extra(flight):\n"
            "    return {'tx': bytes(board._usb.tx).hex(), 'resets': resets}\n") % (api + maint + api, reboot)
    r = run_board(tmp_path, body, seconds=2.0, usb="UsbPort()")
    tx = bytes.fromhex(r["tx"])
    p = msp.MspParser()
    p.feed(tx)
    cmds = []
    while p.pop():
        cmds.append((p.direction, p.cmd))
    assert cmds == [(msp.DIR_REPLY, msp.MSP_API_VERSION)] * 2 + [(msp.DIR_REPLY, msp.MSP_REBOOT)]
    q = mp.MaintenanceParser(replies=True, expected_header=maint[1:9])
    q.feed(tx)
    assert q.pop() and dict(q.values)["imu_type"] == mp.IMU_MPU6050
    assert r["resets"] == [len(tx)]  # one reset, after the reply was written


# ------------------------------------------------------------------------------------ property
_READS = (msp.MSP_API_VERSION, msp.MSP_STATUS, msp.MSP_ATTITUDE, msp.MSP_RAW_IMU, msp.MSP_RC, msp.MSP_MOTOR)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.one_of(st.sampled_from(_READS), st.just("maint")), min_size=1, max_size=80),
       st.lists(st.integers(1, 700), min_size=1, max_size=20))
def test_any_pipelined_mix_in_any_chunking_gets_every_answer_in_order(items, cuts):
    links, flight, board = _links()
    maint = mp.encode_request(["body_roll"])
    data = b"".join(maint if it == "maint" else msp.encode_request(it) for it in items)
    k = 0
    c = 0
    while k < len(data):  # the bytes arrive in pieces between runs
        n = cuts[c % len(cuts)]
        board.rx[SERIAL_CONFIG] += data[k:k + n]
        k += n
        c += 1
        links.task(board.now_us())
        board.t_us += 1000
    for _ in range(len(items) // REQUESTS_PER_RUN + 2):
        links.task(board.now_us())
    out = board.take(SERIAL_CONFIG)
    got = []
    i = 0
    while i < len(out):  # the replies, MSP and maintenance, in the order they were written
        if out[i] == 0xFF:
            got.append("maint")
            i += 1 + 8 + 4 + 1  # header, body_roll (f32), checksum
        else:
            size = out[i + 3]
            got.append(out[i + 4])
            assert out[i + 2] == msp.DIR_REPLY
            i += 6 + size
    assert got == items
    assert links.config.dropped() == 0 and links.partial_timeouts == 0


def test_requests_a_false_frame_start_swallowed_are_all_answered_when_it_fails():
    # given '$M<' and a size of 200 in front of 40 real requests: the candidate takes them in, then its
    # checksum fails; a plain feed's rescan finds 40 frames for a 4-deep queue and overwrites 36
    links, flight, board = _links()
    data = b"$M<" + bytes([200, 1]) + msp.encode_request(msp.MSP_API_VERSION) * 40
    plain = msp.MspParser(queue_depth=4)
    plain.feed(data)
    assert plain.dropped == 36
    board.rx[SERIAL_CONFIG] += data
    for _ in range(6):
        links.task(board.now_us())
        board.t_us += 1000
    assert _replies(board.take(SERIAL_CONFIG)) == [msp.MSP_API_VERSION] * 40
    assert links.config.dropped() == 0


_FRAME = st.builds(lambda cmd, payload: msp.encode_request(cmd, payload), st.integers(0, 254),
                   st.binary(max_size=40))


@settings(max_examples=150, deadline=None)
@given(st.lists(st.one_of(_FRAME, st.binary(max_size=30), st.just(b"$M<\xc8\x01"), st.just(b"$X<")), max_size=40),
       st.lists(st.integers(1, 300), min_size=1, max_size=10), st.integers(1, 4))
def test_feed_some_delivers_what_an_unbounded_queue_would_however_small_its_queue(parts, cuts, depth):
    data = b"".join(parts)
    whole = msp.MspParser(queue_depth=4096)
    whole.feed(data)
    expected = []
    while whole.pop():
        expected.append((whole.cmd, whole.message()))
    p = msp.MspParser(queue_depth=depth)
    got = []
    k = 0
    c = 0
    while k < len(data) or p.pending() or p.carrying():
        n = min(len(data), k + cuts[c % len(cuts)])
        c += 1
        i = k
        while True:  # a server's serve(): feed as the queue allows, pop, answer
            i = p.feed_some(data, i, n)
            while p.pop():
                got.append((p.cmd, p.message()))
            if i >= n and not p.carrying():
                break
        k = n
    assert got == expected and p.dropped == 0


def test_a_server_that_raises_closes_only_its_own_session_and_the_other_port_is_still_served():
    links, flight, board = _links()
    broken = links.config.msp

    def boom(cmd, payload, length):
        raise RuntimeError("injected")

    real_handle = broken.handle
    broken.handle = boom
    board.rx[SERIAL_CONFIG] += msp.encode_request(msp.MSP_API_VERSION) * 3
    links.task(board.now_us())
    assert links.server_errors == 1 and "injected" in links.status_line()
    broken.handle = real_handle
    board.take(SERIAL_CONFIG)
    board.rx[SERIAL_CONFIG] += msp.encode_request(msp.MSP_API_VERSION)  # the port is not wedged
    links.task(board.now_us())
    assert _replies(board.take(SERIAL_CONFIG)) == [msp.MSP_API_VERSION] and links.server_errors == 1


def test_one_maintenance_session_letting_go_of_the_motors_keeps_the_others_arming_lock():
    links, flight, board = _links()
    take_motors = mp.encode_request([], mp.CMD_CONTROL_MOTORS, (1,))
    board.rx[SERIAL_CONFIG] += take_motors  # maintenance on the USB (config) port
    board.rx[SERIAL_MAINT] += take_motors  # and on the UART
    links.task(board.now_us())
    assert links.config.maint.motor_control and links.maint.motor_control
    board.rx[SERIAL_MAINT] += mp.encode_request([], mp.CMD_CONTROL_MOTORS, (0,))  # the UART client lets go
    board.t_us += 10000
    links.task(board.now_us())
    assert not links.maint.motor_control
    assert session_flags(flight.config_session) & (1 << MAINTENANCE)  # the USB client still holds it
