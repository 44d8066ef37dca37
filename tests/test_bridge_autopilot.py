"""The companion computer's MSP RC over the firmware bridge (MSP_RC / RC_ANSWER frames).

Under `--firmware micropython` the scripted companion (sim/companion.py) calls
`BridgedFlight.on_msp_rc`; the frame crosses at once, the firmware's own autopilot takes or
refuses it, and the answer and the autopilot's state come back. The autopilot scenario must
fly as it does in-process (where the companion's MSP bytes go through the links task): the
same refusals, the same events, the same report within a links period.
"""

import json
from struct import unpack_from

import pytest

from hoverfly.boards.bridge_fw import Firmware
from hoverfly.cli import main
from hoverfly.core.command.autopilot import R_NO_AUTOPILOT, R_SWITCH_OFF
from hoverfly.protocols import bridge as B
from hoverfly.sim.runner import SimRun, fly
from test_micropython import MICROPYTHON

needs_mp = pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")


def events(r):
    return [(e["event"], e["t_s"], e["detail"]) for e in r["events"]]


def flown(capsys, *args):
    code = main(["fly", "--json"] + list(args))
    assert code == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


@needs_mp
def test_autopilot_scenario_under_micropython_matches_the_cpython_flight(capsys):
    # through the hard override at 12 s: refused, enabled, armed by MSP, soft and hard overrides
    cp = fly("autopilot", duration_s=12.5)
    mp = flown(capsys, "--scenario", "autopilot", "--duration", "12.5", "--firmware", "micropython",
               "--micropython", MICROPYTHON)
    # In process the companion's frames are MSP bytes answered by the links task (within its 10 ms
    # period); across the bridge each crosses at once as an MSP_RC frame. The same frames sent, the
    # same refusals and outcome; a frame meeting a state change in that period may fall either side.
    ap, cap = mp["autopilot"], cp["autopilot"]
    assert (ap["sent"], sorted(ap["refused"]), ap["state"], ap["privilege"]) == \
        (cap["sent"], sorted(cap["refused"]), cap["state"], cap["privilege"])
    assert abs(ap["taken"] - cap["taken"]) <= 2 and cap["unanswered"] <= 1
    assert ap["taken"] > 0 and ap["refused"] and ap["sent"] == mp["firmware"]["msp_rc"]
    assert ap["state"] == "off" and ap["privilege"] == 16  # switched off, the throttle latched
    names = [e[0] for e in events(mp)]
    assert "autopilot_enabled" in names and "armed" in names
    assert [(e[0], e[2]) for e in events(mp)] == [(e[0], e[2]) for e in events(cp)]
    assert all(abs(m[1] - c[1]) <= 0.015 for m, c in zip(events(mp), events(cp), strict=True))
    assert abs(mp["tilt_rms_deg"] - cp["tilt_rms_deg"]) <= 0.05
    assert abs(mp["altitude_m"]["max"] - cp["altitude_m"]["max"]) <= 0.05


@needs_mp
def test_autopilot_in_control_is_reported_from_the_firmware():
    # given the companion in control at 3 s (enabled, armed by MSP at 2.5 s, holding altitude)
    r = fly("autopilot", duration_s=3, firmware="micropython", micropython=MICROPYTHON)
    # then the privilege bits say so: RC, arm, in control
    assert r["autopilot"]["state"] == "enabled" and r["autopilot"]["privilege"] == 7
    assert r["armed"] and not r["crashed"]
    assert [e["event"] for e in r["events"] if e["event"] in ("autopilot_enabled", "armed")] == \
        ["autopilot_enabled", "armed"]


@needs_mp
def test_configuration_sessions_block_arming_in_the_firmware_too():
    # the CLI, MSP and maintenance sessions open and close between 2.5 and 4.1 s
    cp = fly("arming-refusals", duration_s=4.5)
    mp = fly("arming-refusals", duration_s=4.5, firmware="micropython", micropython=MICROPYTHON)
    assert events(mp) == events(cp)
    assert sum("session" in e[2] for e in events(mp)) == 3


def test_msp_rc_before_the_flight_starts_is_refused():
    run = SimRun("5inch", "hover", firmware="cpython-process")
    assert run.flight.on_msp_rc(0, [1500] * 8, 8) == "the firmware bridge is not running"


# ------------------------------------------------------ the firmware's end, in-process
def answer(fw, kind, payload=b""):
    n = fw.handle(kind, bytearray(payload) + bytearray(B.MAX_PAYLOAD), len(payload))
    d = B.BridgeDecoder()
    assert d.feed(fw.out, n) == 1
    return d.pop(), d


def booted(params=""):
    fw = Firmware()
    kind, d = answer(fw, B.HELLO, B.VERSION.encode())
    assert kind == B.HELLO and d.text() == B.VERSION
    if params:
        assert answer(fw, B.PARAMS, params.encode())[0] == B.ACK
    assert answer(fw, B.BOOT, bytes(4))[0] == B.ACK
    return fw


def msp_rc(fw, channels, sim_us=1000):
    buf = bytearray(B.MAX_PAYLOAD + B.OVERHEAD)
    n = B.put_msp_rc(buf, sim_us, channels, len(channels))
    return answer(fw, B.MSP_RC, bytes(buf[B.HEADER:n - 1]))


def test_firmware_answers_msp_rc_with_its_autopilots_refusal():
    fw = booted("ap_ch=0")
    kind, d = msp_rc(fw, [1500, 1500, 1000, 1500, 1000, 1000, 1000, 1000])
    assert kind == B.RC_ANSWER
    flags, state, privilege = unpack_from(B.RC_ANSWER_FMT, d.payload, 0)
    assert state == 0 and privilege == 0 and not flags & B.OUT_ARMED
    assert bytes(d.payload[B.RC_ANSWER_SIZE:d.length]).decode() == R_NO_AUTOPILOT
    fw = booted("ap_ch=7")
    kind, d = msp_rc(fw, [1500] * 8)
    assert bytes(d.payload[B.RC_ANSWER_SIZE:d.length]).decode() == R_SWITCH_OFF
    assert fw.flight.autopilot.rejected == 1


def test_firmware_refuses_malformed_or_early_msp_rc_frames_with_an_error():
    fw = Firmware()
    kind, d = msp_rc(fw, [1500] * 8)
    assert kind == B.ERROR and "before BOOT" in d.text()
    fw = booted()
    kind, d = answer(fw, B.MSP_RC, b"\x00\x00\x00\x00\x08\xdc\x05")  # claims 8 channels, holds 1
    assert kind == B.ERROR and "malformed" in d.text()


def test_hello_starts_a_fresh_session_on_a_device_that_stayed_up():
    fw = booted("p_roll=80")
    assert fw.params.get("p_roll") == 80
    kind, d = answer(fw, B.HELLO, B.VERSION.encode())
    assert kind == B.HELLO and fw.flight is None
    assert fw.params.get("p_roll") != 80
