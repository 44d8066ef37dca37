"""Seed 004 over MSP bytes: the autopilot's privilege (MSP2_HOVERFLY_AUTOPILOT), MSP_SET_MODE_RANGE, and
the scripted companion driving the flight through the links task, not a direct call (issue 25).

The scenario tests fly `autopilot` in lockstep with the companion wired to the CLI/MSP port; a ground
poller adds its own MSP2_HOVERFLY_AUTOPILOT request every 100 ms and reads what the companion would.
The bench tests feed bytes into core.links.task.ConfigLinks over the same port and read the reply bytes.
"""

import pytest

from hoverfly.core.command.autopilot import (
    AP_ENABLED,
    AP_OFF,
    AP_SILENT,
    AP_WAIT,
    LATCH_HARD,
    LATCH_TIMEOUT,
    PRIV_ARM,
    PRIV_IN_CONTROL,
    PRIV_RC,
    PRIV_SOFT_OVERRIDE,
    PRIV_THROTTLE_LATCH,
    R_SWITCH_OFF,
    R_WAIT,
    RES_SWITCH_OFF,
    RES_TAKEN,
    RES_WAIT,
)
from hoverfly.core.links.task import ConfigLinks, attach
from hoverfly.protocols import msp
from hoverfly.sim.companion import CompanionPort
from hoverfly.sim.runner import SimRun

NOBODY, PILOT, AUTOPILOT, FAILSAFE, MOTOR_TEST = range(5)
NO_OVERRIDE, SOFT, HARD = range(3)
POLL = msp.encode_request(msp.MSP2_HOVERFLY_AUTOPILOT, b"", 2)


# ------------------------------------------------------------------------- the autopilot scenario
@pytest.fixture(scope="module")
def flown():
    run = SimRun("5inch", "autopilot", seed=7)
    seen = {"polls": 0, "statuses": [], "mode_range_armed": None, "arm_min_us_after": None}

    def hook(r):
        t = r.board.sim_us * 1e-6
        c = r.companion
        if c is None:
            return
        k = round(t * 1000)
        if c.status is not None:
            seen["statuses"].append((t, dict(c.status), r.flight.arming.armed))
        if k % 100 == 0:  # a ground station's poll, through the same port
            c.port.to_fc += POLL
            seen["polls"] += 1
        if k == 5000:  # armed by the autopilot and flying: a mode range sent now must change nothing
            c.port.to_fc += msp.encode_request(msp.MSP_SET_MODE_RANGE, msp.pack_set_mode_range(0, 0, 0, 8, 20))
        if k == 5100:
            seen["mode_range_armed"] = list(c.other_replies)
            seen["arm_min_us_after"] = r.flight.params.get("arm_min_us")

    run.on_step = hook
    result = run.run()
    return run, result, seen


def _status_at(seen, t):
    """The newest status the companion had read by time t."""
    rows = [s for s in seen["statuses"] if s[0] <= t]
    return rows[-1][1]


def test_privilege_reads_off_and_refusals_before_the_procedure(flown):
    _, _, seen = flown
    st = _status_at(seen, 1.15)
    assert (st["state"], st["privilege"], st["flier"], st["override"], st["latch"]) == (AP_OFF, 0, NOBODY, 0, 0)
    assert st["last_result"] == RES_SWITCH_OFF and st["frames"] == 0 and st["rejected"] >= 60
    st = _status_at(seen, 1.35)  # its arm request at 1.2 s met the switch off: no arming reason involved
    assert st["last_result"] == RES_SWITCH_OFF and st["last_arm_reason"] == 255
    st = _status_at(seen, 2.15)  # autopilot switch on, the arm switch not yet
    assert (st["state"], st["privilege"], st["last_result"]) == (AP_WAIT, 0, RES_WAIT)


def test_privilege_reads_enabled_then_the_autopilot_flying(flown):
    _, _, seen = flown
    st = _status_at(seen, 2.45)  # enabled at 2.2 s, its frames taken, not armed yet
    assert st["state"] == AP_ENABLED and st["privilege"] == PRIV_RC | PRIV_ARM | PRIV_IN_CONTROL
    assert st["flier"] == NOBODY and st["last_result"] == RES_TAKEN and st["frames"] > 0
    st = _status_at(seen, 4.0)  # armed by MSP at 2.5 s, holding 3 m
    assert (st["flier"], st["override"], st["latch"]) == (AUTOPILOT, NO_OVERRIDE, 0)
    assert 1200 < st["throttle_us"] < 1800 and st["last_frame_age_ms"] <= 20


def test_privilege_reads_the_soft_overrides(flown):
    _, _, seen = flown
    st = _status_at(seen, 7.3)  # the pilot's roll beyond ap_override_pct
    assert st["override"] == SOFT and st["soft_axes"] == 1 and st["privilege"] & PRIV_SOFT_OVERRIDE
    assert st["flier"] == AUTOPILOT
    st = _status_at(seen, 8.9)  # the pilot's throttle stick caps the autopilot's
    assert st["override"] == SOFT and st["soft_axes"] == 4
    st = _status_at(seen, 10.0)
    assert st["override"] == NO_OVERRIDE and st["soft_axes"] == 0


def test_privilege_reads_the_hard_override_latch_and_its_release(flown):
    _, _, seen = flown
    before = _status_at(seen, 11.95)
    st = _status_at(seen, 12.3)  # autopilot switch off while it flew
    assert (st["state"], st["flier"], st["override"], st["latch"]) == (AP_OFF, PILOT, HARD, LATCH_HARD)
    assert st["privilege"] == PRIV_THROTTLE_LATCH
    assert abs(st["latch_throttle_us"] - before["throttle_us"]) <= 30  # held at the autopilot's last
    st = _status_at(seen, 13.8)  # the pilot's stick came down through it
    assert (st["override"], st["latch"], st["latch_throttle_us"], st["flier"]) == (NO_OVERRIDE, 0, 0, PILOT)
    assert _status_at(seen, 18.5)["flier"] == NOBODY  # landed and disarmed


def test_privilege_reads_the_timeout_latch_of_a_silent_autopilot(flown):
    _, _, seen = flown
    assert _status_at(seen, 23.9)["flier"] == AUTOPILOT
    st = _status_at(seen, 24.6)  # silent since 24 s: the pilot flies, throttle latched at its last
    assert (st["state"], st["flier"], st["latch"], st["override"]) == (AP_SILENT, PILOT, LATCH_TIMEOUT, NO_OVERRIDE)
    assert st["privilege"] == PRIV_THROTTLE_LATCH and st["last_frame_age_ms"] >= 500
    st = _status_at(seen, 29.9)  # the arm switch off in autopilot mode: disarmed, privilege withdrawn
    assert (st["state"], st["flier"], st["privilege"]) == (AP_WAIT, NOBODY, 0)


def test_companion_frames_travel_as_bytes_through_the_links_task(flown):
    run, result, seen = flown
    c = run.companion
    server = c.port.links.config.msp
    rep = result["autopilot"]
    # every frame it sent was answered but at most the last, still on the wire when the flight ended
    assert rep["unanswered"] <= 1 and c.answered == rep["sent"] - rep["unanswered"]
    assert rep["taken"] + sum(rep["refused"].values()) == c.answered
    # the refusals came back as `!` replies, worded from the poll after them
    assert set(rep["refused"]) == {R_SWITCH_OFF, R_WAIT} and rep["refused"][R_SWITCH_OFF] >= 100
    # the server counted each frame, the companion's poll after it and the ground polls
    assert server.requests >= 2 * c.answered + seen["polls"] - 3
    assert server.parser.crc_errors == 0 and server.errors == sum(rep["refused"].values()) + 1
    assert run.flight.autopilot.frames == rep["taken"]


def test_set_mode_range_is_refused_while_the_autopilot_flies(flown):
    run, result, seen = flown
    replies = seen["mode_range_armed"]
    assert [(d, cmd) for d, cmd, _ in replies] == [(msp.DIR_ERROR, msp.MSP_SET_MODE_RANGE)]
    assert seen["arm_min_us_after"] == 1700 and run.params.get("arm_min_us") == 1700
    assert not result["crashed"] and [e for e in result["events"] if e["event"] == "disarmed"][0]["t_s"] > 17


# ------------------------------------------------------------------------ bench: links over the port
class Bench:
    """The flight controller's CLI/MSP port with ConfigLinks behind it; requests in, replies out as bytes."""

    def __init__(self):
        self.run = SimRun("5inch", "autopilot", seed=7)
        self.flight = self.run.flight
        self.board = self.run.board
        self.flight.start(self.board.now_us())
        self.port = CompanionPort()
        self.board.serial = self.port
        self.links = ConfigLinks(self.flight)
        self.parser = msp.MspParser(max_payload=512, queue_depth=16)

    def send(self, data):
        """Bytes onto the wire, one links task run, the replies as (direction, cmd, payload)."""
        self.port.to_fc += data
        self.links.task(self.board.now_us())
        self.parser.feed(self.port.from_fc)
        self.port.from_fc = bytearray()
        out = []
        while self.parser.pop():
            out.append((self.parser.direction, self.parser.cmd, self.parser.message()))
        return out

    def ask(self, cmd, payload=b"", version=1):
        return self.send(msp.encode_request(cmd, payload, version))

    def status(self):
        (d, cmd, payload), = self.ask(msp.MSP2_HOVERFLY_AUTOPILOT, version=2)
        assert (d, cmd) == (msp.DIR_REPLY, msp.MSP2_HOVERFLY_AUTOPILOT)
        return msp.unpack_autopilot(payload)

    def enable_autopilot(self):
        """The pilot's procedure, as the autopilot sees the receiver's frames: arm switch off, autopilot
        switch on, then the arm switch on."""
        ap = self.flight.autopilot
        for k in range(6):
            ap.on_pilot_frame(k, False, False, True)
        ap.on_pilot_frame(10, True, False, True)
        assert ap.state == AP_ENABLED


def _rc(throttle_us=1100):
    return msp.pack_set_raw_rc([1500, 1500, throttle_us, 1500, 1000, 1500, 1500, 1500])


def test_a_corrupted_set_raw_rc_is_not_taken_and_gets_no_reply():
    b = Bench()
    b.enable_autopilot()
    good = msp.encode_request(msp.MSP_SET_RAW_RC, _rc(1300))
    assert b.send(good) == [(msp.DIR_REPLY, msp.MSP_SET_RAW_RC, b"")]
    assert b.status()["frames"] == 1 and b.status()["throttle_us"] == 1300
    bad = bytearray(msp.encode_request(msp.MSP_SET_RAW_RC, _rc(1900)))
    bad[7] ^= 0x04  # one bit of a channel flipped on the wire: the checksum no longer matches
    assert b.send(bytes(bad)) == []
    st = b.status()
    assert st["frames"] == 1 and st["rejected"] == 0 and st["throttle_us"] == 1300
    assert b.links.config.msp.parser.crc_errors == 1
    # the next good frame after the bad one is found and taken
    assert b.send(good)[0][0] == msp.DIR_REPLY and b.status()["frames"] == 2


def test_pipelined_frames_and_polls_are_each_answered_in_order():
    b = Bench()
    b.enable_autopilot()
    data = b""
    for us in (1200, 1250):  # as the companion writes them: each frame with its poll, two ticks' worth
        data += msp.encode_request(msp.MSP_SET_RAW_RC, _rc(us)) + POLL
    replies = b.send(data)
    assert [cmd for _, cmd, _ in replies] == [msp.MSP_SET_RAW_RC, msp.MSP2_HOVERFLY_AUTOPILOT] * 2
    assert [msp.unpack_autopilot(p)["throttle_us"] for _, cmd, p in replies if cmd != msp.MSP_SET_RAW_RC] == \
        [1200, 1250]
    assert b.links.config.msp.requests == 4


def test_refused_set_raw_rc_is_an_error_reply_and_the_poll_says_why():
    b = Bench()  # the autopilot switch off: no privilege
    replies = b.send(msp.encode_request(msp.MSP_SET_RAW_RC, _rc()) + POLL)
    assert [(d, cmd) for d, cmd, _ in replies] == [(msp.DIR_ERROR, msp.MSP_SET_RAW_RC),
                                                  (msp.DIR_REPLY, msp.MSP2_HOVERFLY_AUTOPILOT)]
    st = msp.unpack_autopilot(replies[1][2])
    assert (st["state"], st["last_result"], st["rejected"], st["frames"]) == (AP_OFF, RES_SWITCH_OFF, 1, 0)


def _mode_ranges(b):
    (d, _, payload), = b.ask(msp.MSP_MODE_RANGES)
    return msp.unpack_mode_ranges(payload)


def test_set_mode_range_sets_the_box_range_and_mode_ranges_reads_it_back():
    b = Bench()
    p = b.flight.params
    # ANGLE (box 1) on AUX2 (aux index 1) from 1500 to 2100 us, in its own slot (1)
    assert b.ask(msp.MSP_SET_MODE_RANGE, msp.pack_set_mode_range(1, 1, 1, 24, 48)) == \
        [(msp.DIR_REPLY, msp.MSP_SET_MODE_RANGE, b"")]
    assert (p.get("angle_ch"), p.get("angle_min_us"), p.get("angle_max_us")) == (6, 1500, 2100)
    ranges = _mode_ranges(b)
    assert len(ranges) == 20 and ranges[1] == (1, 1, 24, 48)
    assert ranges[0] == (0, 0, msp.step_of_us(1700), msp.step_of_us(2100))  # ARM untouched, slot 0
    # ARM moved to AUX4, 7-byte form of Betaflight 3.4+ (logic OR, not linked), named in another slot
    assert b.ask(msp.MSP_SET_MODE_RANGE, msp.pack_set_mode_range(6, 0, 3, 36, 48, 0, 0))[0][0] == msp.DIR_REPLY
    assert (p.get("arm_ch"), p.get("arm_min_us"), p.get("arm_max_us")) == (8, 1800, 2100)
    assert _mode_ranges(b)[0] == (0, 3, 36, 48)
    # the configurator's unused slots (box 0, empty range) change nothing; an empty range in the box's
    # own slot clears the box
    assert b.ask(msp.MSP_SET_MODE_RANGE, msp.pack_set_mode_range(7, 0, 0, 0, 0))[0][0] == msp.DIR_REPLY
    assert p.get("arm_ch") == 8
    assert b.ask(msp.MSP_SET_MODE_RANGE, msp.pack_set_mode_range(2, 2, 0, 0, 0))[0][0] == msp.DIR_REPLY
    assert p.get("horizon_ch") == 0 and _mode_ranges(b)[2] == (0, 0, 0, 0)


@pytest.mark.parametrize("payload, why", [
    (msp.pack_set_mode_range(0, 13, 0, 10, 20), "box 13"),  # a Betaflight box hoverfly does not have
    (msp.pack_set_mode_range(20, 0, 0, 10, 20), "slot 20"),
    (msp.pack_set_mode_range(0, 0, 0, 10, 49), "steps must be 0..48"),
    (msp.pack_set_mode_range(0, 0, 14, 10, 20), "arm_ch"),  # AUX15 = channel 19: past the 18
    (msp.pack_set_mode_range(0, 0, 0, 10, 20, 1, 1), "linked"),
    (bytes([0, 0, 0, 10]), "5 bytes"),
])
def test_set_mode_range_refuses_a_bad_payload_box_or_range_and_changes_nothing(payload, why):
    b = Bench()
    before = dict(b.flight.params.values)
    assert b.ask(msp.MSP_SET_MODE_RANGE, payload) == [(msp.DIR_ERROR, msp.MSP_SET_MODE_RANGE, b"")]
    assert why in b.links.config.msp.last_error
    assert b.flight.params.values == before


class BenchSerial:
    """A pyserial-like port (in_waiting, read, write, flush) whose far end is the bench's links task."""

    def __init__(self, bench):
        self.bench = bench
        self.port = "bench"

    @property
    def in_waiting(self):
        return len(self.bench.port.from_fc)

    def read(self, n):
        data = bytes(self.bench.port.from_fc[:n])
        del self.bench.port.from_fc[:n]
        return data

    def write(self, data):
        self.bench.port.to_fc += data
        self.bench.links.task(self.bench.board.now_us())  # the controller's links task runs

    def flush(self):
        pass


def test_host_msp_client_reads_the_privilege_with_names():
    pytest.importorskip("serial")
    from hoverfly.gcs.link import MspClient

    b = Bench()
    client = MspClient(BenchSerial(b))
    st = client.autopilot()
    assert (st["state_name"], st["flier_name"], st["override_name"], st["privilege_names"]) == \
        ("off", "nobody", "none", [])
    b.ask(msp.MSP_SET_RAW_RC, _rc())  # refused: the autopilot switch is off
    st = client.autopilot()
    assert st["last_reason"] == R_SWITCH_OFF and st["rejected"] == 1
    b.enable_autopilot()
    b.ask(msp.MSP_SET_RAW_RC, _rc(1400))
    st = client.autopilot()
    assert st["state_name"] == "enabled" and st["privilege_names"] == ["rc", "arm", "in_control"]
    assert st["last_reason"] is None and st["throttle_us"] == 1400


def test_set_mode_range_moved_under_an_on_arm_switch_does_not_arm_until_it_is_toggled():
    # given a disarmed craft whose arm switch sits at 1500 us, below the ARM range (1700..2100)
    sc = {"name": "mode-range", "duration_s": 5.5, "mode": "angle", "params": {},
          "events": [{"t": 0.5, "channel": {"ch": 5, "us": 1500}}, {"t": 4.0, "channel": {"ch": 5, "us": 1000}},
                     {"t": 4.5, "channel": {"ch": 5, "us": 1500}}]}
    run = SimRun("5inch", sc, seed=1)
    port = CompanionPort()
    run.board.serial = port
    armed = {}

    def hook(r):
        k = round(r.board.sim_us / 1000)
        if k == 100:
            port.links = attach(r.flight)
        if k == 2000:  # when a configurator moves the ARM range down over the switch (1300..2100)
            port.to_fc += msp.encode_request(msp.MSP_SET_MODE_RANGE,
                                             msp.pack_set_mode_range(0, 0, 0, msp.step_of_us(1300), 48))
        armed[k] = r.flight.arming.armed

    run.on_step = hook
    result = run.run()
    # then the range is taken, but the switch that became "on" by it does not arm
    assert run.params.get("arm_min_us") == 1300
    assert not any(armed[k] for k in range(2000, 4000))
    # until the pilot switches it off and on again
    arms = [e["t_s"] for e in result["events"] if e["event"] == "armed"]
    assert len(arms) == 1 and arms[0] >= 4.5 and armed[5500]
