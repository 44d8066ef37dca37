"""The MSP server's seed-004 commands on the real Flight, here and under MicroPython: MSP2_HOVERFLY_AUTOPILOT
follows the enabling procedure and the companion's frames; MSP_SET_MODE_RANGE writes a box's range or refuses.
(The flown versions, through the links task and the simulator: tests/test_msp_autopilot.py.)"""

from configfakes import make_flight

from hoverfly.core.command.autopilot import AP_ENABLED, AP_OFF, AP_SILENT, AP_WAIT, RES_SWITCH_OFF, RES_TAKEN, RES_WAIT
from hoverfly.core.links.mspserver import MspServer
from hoverfly.protocols import msp


def _server():
    flight, board = make_flight(False)  # the Flight's own on_msp_rc: its Autopilot takes or refuses
    return MspServer(flight, None), flight, board


def _ask(server, cmd, payload=b"", version=1):
    out = []
    frame = msp.encode_request(cmd, payload, version)
    server.feed(frame, len(frame), out.append)
    p = msp.MspParser()
    for chunk in out:
        p.feed(chunk)
    assert p.pop(), "no reply"
    return p.direction, p.message()


def _status(server):
    d, payload = _ask(server, msp.MSP2_HOVERFLY_AUTOPILOT, b"", 2)
    assert d == msp.DIR_REPLY and len(payload) == msp.AUTOPILOT_SIZE
    return msp.unpack_autopilot(payload)


def _rc(throttle_us):
    return msp.pack_set_raw_rc([1500, 1500, throttle_us, 1500, 1000, 1500, 1500, 1500])


def test_privilege_reply_follows_the_procedure_and_the_frames():
    s, f, board = _server()
    ap = f.autopilot
    now = board.now_us()
    assert _ask(s, msp.MSP_SET_RAW_RC, _rc(1200))[0] == msp.DIR_ERROR  # switch off: refused
    st = _status(s)
    assert (st["state"], st["privilege"], st["last_result"], st["rejected"]) == (AP_OFF, 0, RES_SWITCH_OFF, 1)
    for k in range(6):  # the autopilot switch on with the arm switch off
        ap.on_pilot_frame(now + k, False, False, True)
    assert _ask(s, msp.MSP_SET_RAW_RC, _rc(1200))[0] == msp.DIR_ERROR
    assert (_status(s)["state"], _status(s)["last_result"]) == (AP_WAIT, RES_WAIT)
    ap.on_pilot_frame(now + 10, True, False, True)  # then the arm switch on: enabled
    assert _ask(s, msp.MSP_SET_RAW_RC, _rc(1200)) == (msp.DIR_REPLY, b"")
    st = _status(s)
    assert (st["state"], st["privilege"], st["last_result"], st["frames"]) == (AP_ENABLED, 7, RES_TAKEN, 1)
    assert st["throttle_us"] == 1200 and st["flier"] == 0 and st["last_frame_age_ms"] < 1000
    ap.update(ap.last_msp_us + ap.timeout_us + 1, False)  # silent past ap_timeout_ms, disarmed: no latch
    st = _status(s)
    assert (st["state"], st["privilege"], st["latch"], st["latch_throttle_us"]) == (AP_SILENT, 0, 0, 0)


def test_set_mode_range_writes_the_box_and_mode_ranges_reads_it_back():
    s, f, _ = _server()
    assert _ask(s, msp.MSP_SET_MODE_RANGE, msp.pack_set_mode_range(2, 2, 3, 12, 24)) == (msp.DIR_REPLY, b"")
    assert (f.params.get("horizon_ch"), f.params.get("horizon_min_us"), f.params.get("horizon_max_us")) == \
        (8, 1200, 1500)
    assert msp.unpack_mode_ranges(_ask(s, msp.MSP_MODE_RANGES)[1])[2] == (2, 3, 12, 24)


def test_set_mode_range_refusals_change_nothing():
    s, f, _ = _server()
    before = f.params.get("arm_ch"), f.params.get("arm_min_us"), f.params.get("arm_max_us")
    for payload in (msp.pack_set_mode_range(0, 13, 0, 10, 20), msp.pack_set_mode_range(20, 0, 0, 10, 20),
                    msp.pack_set_mode_range(0, 0, 0, 10, 60), msp.pack_set_mode_range(0, 0, 14, 10, 20),
                    bytes([0, 0, 0])):
        assert _ask(s, msp.MSP_SET_MODE_RANGE, payload) == (msp.DIR_ERROR, b"")
    assert (f.params.get("arm_ch"), f.params.get("arm_min_us"), f.params.get("arm_max_us")) == before
