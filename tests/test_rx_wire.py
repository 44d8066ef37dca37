"""The receiver wire in flight: the scenario pilot's sticks go out as real CRSF / SBUS / iBUS frames
or PPM / PWM edges (sim/rxlink.py), with each protocol's frame rate and byte timing, and the
flight core flies on what its receiver stage decodes. Judged as a pilot would, per protocol."""

import pytest

pytest.importorskip("crsf_parser")
from crsf_parser import CRSFParser, PacketValidationStatus  # noqa: E402

from hoverfly.cli import main  # noqa: E402
from hoverfly.protocols import crsf  # noqa: E402
from hoverfly.sim.runner import SimRun  # noqa: E402
from hoverfly.sim.rxlink import RxLink  # noqa: E402
from hoverfly.sim.scenario import parse_scenario  # noqa: E402

PROTOCOLS = ("crsf", "sbus", "ibus", "ppm", "pwm")
# Frames per second each simulated receiver sends (sim/rxlink.py).
FRAME_RATE_HZ = {"crsf": 250, "sbus": 1e6 / 9000, "ibus": 1e6 / 7000, "ppm": 1e6 / 22500, "pwm": 50}
# Worst-case age of the sticks when a frame completes: one frame period of waiting for the next
# frame plus its time on the wire; PPM completes a frame only at the next frame's sync edge.
WIRE_LATENCY_MS = {"crsf": 4 + 1, "sbus": 9 + 3, "ibus": 7 + 3, "ppm": 2 * 22.5, "pwm": 20 + 12}


def _fly(scenario, rx, duration_s=None, airframe="5inch", overrides=()):
    run = SimRun(airframe, scenario, seed=7, overrides=overrides, duration_s=duration_s, rx=rx)
    return run, run.run()


def _events(result, name):
    return [e["t_s"] for e in result["events"] if e["event"] == name]


@pytest.mark.parametrize("rx", PROTOCOLS)
def test_hover_through_each_receiver_holds_level_and_height(rx):
    run, r = _fly("hover", rx, duration_s=8.0)  # judged from 5 s on
    assert not r["crashed"]
    assert r["armed"]
    assert r["tilt_rms_deg"] <= 1.0
    assert abs(r["altitude_m"]["final"] - 2.0) < 0.5
    # the link watch saw the receiver's own frame rate, no errors, a clean link
    rv = run.flight.receiver
    assert rv.provider == rx
    assert abs(rv.frame_rate_hz - FRAME_RATE_HZ[rx]) <= 0.03 * FRAME_RATE_HZ[rx]
    assert rv.frames >= 0.95 * 8.0 * FRAME_RATE_HZ[rx] - 3
    assert rv.errors == 0 and rv.failsafe_frames == 0 and not rv.rx_failsafe
    assert rv.link_quality_pct == 100
    assert rv.rssi_dbm == (-50 if rx == "crsf" else 0)
    assert not [e for e in r["events"] if e["event"] in ("rx_lost", "failsafe_stage1")]


@pytest.mark.parametrize("rx", PROTOCOLS)
def test_angle_steps_through_each_receiver_are_quick_and_accurate(rx):
    _, r = _fly("angle-steps", rx)
    assert not r["crashed"]
    steps = [s for s in r["steps"] if s["mode"] == "angle"]
    assert len(steps) == 4
    for s in steps:
        # the flight test's 200 ms, plus what the wire itself adds
        assert s["t90_ms"] is not None and s["t90_ms"] <= 200.0 + WIRE_LATENCY_MS[rx], s
        assert s["overshoot_pct"] <= 10.0, s
        assert abs(s["steady_error"]) <= 1.0, s


LOSS = """
duration_s = 7
mode = "angle"
[[at]]
t = 2.0
arm = true
[[at]]
t = 2.5
hold_altitude_m = 2.0
[[at]]
t = 5.0
rx_lost = true
"""


@pytest.mark.parametrize("rx", PROTOCOLS)
def test_radio_loss_is_noticed_within_the_timeout_on_every_wire(rx):
    run, r = _fly(parse_scenario(LOSS), rx)
    period_s = 1.0 / FRAME_RATE_HZ[rx]
    lost = _events(r, "rx_lost")
    assert len(lost) == 1
    # stamped at the last good frame: one frame period (+ the 2 ms receiver task) before the loss at most;
    # PPM's last frame completes at the first edge of the next, so its last one is older still
    assert 5.0 - 2 * period_s - 0.003 <= lost[0] <= 5.0 + 0.003
    stage1 = _events(r, "failsafe_stage1")
    # rx_timeout_ms = 100, seen by the 100 Hz failsafe task: up to 10 ms on, and a pass (1 ms) more when its
    # time falls on a pass the receiver task took (core/scheduler.py keeps the two apart)
    assert stage1 and 0.09 <= stage1[0] - lost[0] <= 0.1115
    rv = run.flight.receiver
    assert rv.frame_rate_hz == 0  # a second later nothing valid arrives
    if rx == "sbus":
        # SBUS keeps talking: failsafe-flagged frames, never taken as the pilot's sticks
        assert rv.rx_failsafe and rv.failsafe_frames >= 0.9 * 2.0 * FRAME_RATE_HZ[rx]
        assert run.board.rx_link.failsafe_frames_sent == rv.failsafe_frames
        assert rv.link_quality_pct == 0
    else:
        assert rv.failsafe_frames == 0
        assert rv.link_quality_pct == 0


def test_radio_back_before_the_timeout_is_no_loss_and_back_after_it_is_restored():
    sc = parse_scenario(LOSS.replace("duration_s = 7", "duration_s = 5.5") + """
[[at]]
t = 5.05
rx_lost = false
""")
    _, r = _fly(sc, "sbus")
    assert not _events(r, "rx_lost")
    sc = parse_scenario(LOSS + """
[[at]]
t = 5.3
rx_lost = false
""")
    _, r = _fly(sc, "crsf")
    assert len(_events(r, "rx_lost")) == 1
    restored = [t for t in _events(r, "rx_restored") if t > 5.0]
    assert restored and 5.3 <= restored[0] <= 5.31


def _split(stream):
    """CRSF frames of a clean stream: [sync, len, type, payload..., crc] each."""
    frames = []
    i = 0
    while i + 2 <= len(stream):
        n = stream[i + 1] + 2
        frames.append(stream[i:i + n])
        i += n
    return frames


def _their_parse(frame):
    got = []
    CRSFParser(lambda content, status: got.append((content, status))).parse_stream(bytearray(frame))
    return got


def test_crsf_telemetry_goes_back_on_the_same_wire_and_decodes():
    run, r = _fly("hover", "crsf", duration_s=6.0)
    out = bytes(run.board.telemetry_out)
    # our own decoder: every frame valid, none an RC frame
    d = crsf.CrsfDecoder()
    d.feed(out)
    assert d.crc_errors == 0 and d.length_errors == 0 and d.resyncs == 0 and d.frames == 0
    assert d.other_frames == run.flight.receiver.telemetry_frames
    # ~10 Hz per kind, three kinds, never more than one frame per 25 ms
    assert 30 * 6.0 <= d.other_frames <= 40 * 6.0
    frames = _split(out)
    assert len(frames) == d.other_frames
    last = {}
    for f in frames:
        last[f[2]] = f
    assert set(last) == {crsf.TYPE_BATTERY, crsf.TYPE_ATTITUDE, crsf.TYPE_FLIGHT_MODE}
    # battery through the independent parser (crsf-parser 0.3.2 decodes battery, not attitude/mode)
    (content, status), = _their_parse(last[crsf.TYPE_BATTERY])
    assert status == PacketValidationStatus.VALID
    v = run.vehicle.battery.voltage_v
    assert abs(content.payload.voltage * 0.1 - v) <= 0.15
    assert 0 < content.payload.remaining <= 100
    att = last[crsf.TYPE_ATTITUDE]
    pitch, roll = (int.from_bytes(att[i:i + 2], "big", signed=True) * 1e-4 for i in (3, 5))
    assert abs(pitch) < 0.05 and abs(roll) < 0.05  # hovering level
    assert last[crsf.TYPE_FLIGHT_MODE][3:-1] == b"ANGL\x00"  # armed, angle mode


def test_crsf_telemetry_says_ready_or_blocked_while_disarmed():
    run, _ = _fly("hover", "crsf", duration_s=1.9)  # arms at 2.0 s; boot grace and calibration block first
    texts = [f[3:-1] for f in _split(bytes(run.board.telemetry_out)) if f[2] == crsf.TYPE_FLIGHT_MODE]
    assert texts[0] == b"ANGL!\x00"  # still booting: arming blocked
    assert texts[-1] == b"ANGL*\x00"  # ready to arm


def test_crsf_telemetry_can_be_switched_off():
    run, _ = _fly("hover", "crsf", duration_s=3.0, overrides=[("crsf_telemetry", "0")])
    assert run.board.telemetry_bytes == 0 and run.flight.receiver.telemetry_frames == 0


def test_bytes_arrive_at_the_line_rate():
    ch = [1500] * 18
    for protocol, bits, baud, size in (("crsf", 10, 420000, 26), ("sbus", 12, 100000, 25), ("ibus", 10, 115200, 32)):
        link = RxLink(protocol, ch)
        link.advance(0)
        assert len(link.rx_bytes) == 0  # the first frame has only just started
        t_us = 2000
        link.advance(t_us)
        assert len(link.rx_bytes) == min(size, t_us * baud // (bits * 1_000_000))


def test_sbus_frames_straddle_the_receiver_task_and_still_decode():
    # 25 bytes at 120 µs take 3 ms: every SBUS frame arrives in two or more 2 ms reads.
    run, r = _fly("hover", "sbus", duration_s=3.0)
    dec = run.flight.receiver.decoder
    assert dec.frames > 300 and dec.crc_errors == 0 and dec.length_errors == 0 and dec.resyncs == 0


def test_pwm_frames_need_every_channel():
    # The receiver sends 6 channels; a controller that captures 8 never sees a whole frame.
    run = SimRun("5inch", "hover", seed=7, overrides=[("rx_pwm_channels", "8")], duration_s=3.0, rx="pwm")
    run.board.rx_link.pwm_channels = 6
    r = run.run()
    assert run.flight.receiver.frames == 0 and not r["armed"] and not r["altitude_m"]["max"]


def test_fly_cli_takes_the_receiver_protocol(capsys):
    import json

    assert main(["fly", "--scenario", "hover", "--duration", "3", "--rx", "ibus", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert not r["crashed"]
    assert main(["fly", "--rx", "dsm"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("hoverfly: error:") and "invalid choice: 'dsm'" in err and "\n" not in err
