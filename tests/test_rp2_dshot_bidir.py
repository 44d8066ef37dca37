"""Bidirectional DShot on the rp2 board: the PIO program, the board's telemetry read, a hover.

The fake rp2 state machine clocks the board's bidirectional PIO program cycle by cycle
against a fake ESC on the motor pin (tests/rp2fakes/world.py `EscLine`): the ESC reads the
frame off the driven line (idle high, inverted CRC, timing tolerance) and answers with the
GCR line code of its eRPM 30 µs after the frame, at 5/4 the bit rate, on its own clock; the
program's samples are what the RX FIFO yields. So a bit timing off in the program, or an
ESC clock too far off, shows as wrong codes. The last test flies the board's own main loop
with dshot_bidir=1 under MicroPython and reads the motors' RPM back from the replies.
"""

import json
import os
import pathlib
import subprocess
import sys
from array import array

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
FAKES = ROOT / "tests" / "rp2fakes"
sys.path.insert(0, str(FAKES))

from hoverfly.protocols.dshot import (  # noqa: E402
    dshot_frame,
    erpm_reply_word,
    frame_crc_ok,
    frame_value,
    gcr_encode,
)
from hoverfly.sim.airframes import load_airframe  # noqa: E402
from test_micropython import MICROPYTHON  # noqa: E402

MOTOR_PINS = (10, 11, 12, 13)
FAULT_OUTPUT = 16


@pytest.fixture
def fakes():
    import machine
    import rp2

    machine.reset()
    rp2.reset()
    yield rp2
    machine.reset()
    rp2.reset()


def _escs(rp2, **kw):
    from world import EscLine

    escs = []
    for pin in MOTOR_PINS:
        esc = EscLine(**kw)
        rp2.attach_line(pin, esc)
        escs.append(esc)
    return escs


def _pio(speed_kbit=600, lines=1):
    from hoverfly.boards.rp2.dshot_pio import DshotPio

    return DshotPio(MOTOR_PINS[:lines], speed_kbit, bidir=True)


def _cells(pulses):
    """[level, cycles] runs after the leading idle -> [(low, high)] per bit."""
    runs = pulses[1:]
    return [(runs[i][1], runs[i + 1][1]) for i in range(0, len(runs) - 1, 2)]


def test_frame_goes_out_inverted_and_the_esc_accepts_its_inverted_crc(fakes):
    # given a bidirectional line on DShot600, when the board's word for 1046 goes out, then
    # the line idles high, each bit is a low pulse (15 of 20 cycles for a 1, 7 for a 0) and
    # the ESC decodes 1046 with the inverted CRC (0x82C9, protocols.md §4.1)
    esc = _escs(fakes)[0]
    d = _pio()
    sm = d.sms[0]
    assert sm.freq == 12000000  # 20 cycles per bit at 600 kbit/s
    assert fakes.PIO.OUT_HIGH == sm.prog.kw["sideset_init"]
    d.put(array("H", [dshot_frame(1046, 0, True)]), 1)
    assert esc.word == 0x82C9 and esc.value == 1046
    assert (esc.frames, esc.errors, esc.crc_errors, esc.idle_low) == (1, 0, 0, 0)
    assert sm.pulses[0][0] == 1  # idle high before the first falling edge
    assert sm.pulses[1][0] == 0
    cells = _cells(sm.pulses)
    bits = [(0x82C9 >> (15 - i)) & 1 for i in range(16)]
    for i in range(15):  # the last bit's high runs into the release
        assert cells[i][0] == (15 if bits[i] else 7), (i, cells[i])
        assert cells[i][0] + cells[i][1] == 20, (i, cells[i])


def test_the_esc_refuses_a_normal_crc_and_an_idle_low_line(fakes):
    # given the fake ESC, when a word with the normal CRC comes on the inverted line, then it
    # is a CRC error and no reply; and the transmit-only program's line (idle low) gets none
    from world import EscLine

    esc = _escs(fakes)[0]
    d = _pio()
    d.put(array("H", [dshot_frame(1046, 0, False)]), 1)
    assert esc.crc_errors == 1 and esc.frames == 0
    assert not d.poll()
    quiet = EscLine()
    quiet.receive([[0, 40], [1, 6], [0, 2]], 4800000)
    assert quiet.idle_low == 1 and quiet.replies == 0


@pytest.mark.parametrize("speed_kbit", [150, 300, 600, 1200])
def test_the_reply_is_sampled_into_the_esc_line_code_at_every_speed(fakes, speed_kbit):
    # given an ESC answering 30 µs after each frame, when frames go out, then poll() gives
    # exactly the ESC's 21-bit line code for its eRPM, reply after reply
    esc = _escs(fakes)[0]
    d = _pio(speed_kbit)
    for i, erpm in enumerate((1000, 12345, 30000, 99999, 250000, 0)):
        esc.erpm = erpm
        d.put(array("H", [dshot_frame(48 + 300 * i, 0, True)]), 1)
        assert d.poll()
        d.fresh = False
        assert d.replies[0] == gcr_encode(erpm_reply_word(erpm)), (speed_kbit, erpm)
    assert d.missed == 0 and d.sms[0].contention == 0


@pytest.mark.parametrize("clock_error, delay_us", [(-0.015, 30.0), (0.015, 30.0), (0.0, 10.0), (0.0, 70.0)])
def test_replies_read_through_esc_clock_error_and_reply_delay(fakes, clock_error, delay_us):
    # an ESC whose clock runs 1.5 % off, or that answers after 10 or 70 µs instead of 30
    esc = _escs(fakes, clock_error=clock_error, delay_us=delay_us)[0]
    d = _pio()
    esc.erpm = 45678
    d.put(array("H", [dshot_frame(500, 0, True)]), 1)
    assert d.poll() and d.replies[0] == gcr_encode(erpm_reply_word(45678))


def test_a_mistimed_sampling_loop_reads_wrong_codes(fakes):
    # given the program with its sampling loop one cycle short (15-cycle reply bits), the
    # samples drift out of the ESC's bits: the codes are wrong. (The fake checks the timing.)
    esc = _escs(fakes)[0]
    d = _pio()
    for rec in d.program.instr:
        if rec[0] == "in_":
            rec[3] -= 1
    wrong = 0
    for erpm in (1000, 12345, 30000, 99999):
        esc.erpm = erpm
        d.put(array("H", [dshot_frame(500, 0, True)]), 1)
        d.poll()
        wrong += d.replies[0] != gcr_encode(erpm_reply_word(erpm))
    assert wrong == 4


def test_a_silent_esc_never_stalls_the_frames_and_its_replies_count_as_missed(fakes):
    # given ESCs that never answer, when frames keep going, then each one still reaches the
    # ESC (the program's wait times out), nothing reads fresh, and each owed reply is counted
    escs = _escs(fakes, reply=False)
    d = _pio(lines=4)
    words = array("H", [dshot_frame(600 + i, 0, True) for i in range(4)])
    for _ in range(10):
        d.put(words, 4)
        assert not d.poll()
    assert [e.frames for e in escs] == [10] * 4
    assert [e.value for e in escs] == [600, 601, 602, 603]
    assert d.missed == 9 * 4 and list(d.missed_line) == [9] * 4
    assert not any(sm.stalled for sm in d.sms)
    assert all(sm.runs == 10 for sm in d.sms)


def test_a_program_waiting_without_a_timeout_hangs_in_the_fake(fakes):
    # the fake's own check: a `wait` for the reply's edge with nobody answering hangs the
    # state machine, and the put onto its full TX FIFO fails as the real one would block
    import rp2

    @rp2.asm_pio(sideset_init=rp2.PIO.OUT_HIGH, set_init=rp2.PIO.OUT_HIGH)
    def no_timeout():
        pull(block).side(1)  # noqa: F821
        set(pindirs, 0).side(1)  # noqa: F821
        wait(0, pin, 0).side(1)  # noqa: F821
        set(pindirs, 1).side(1)  # noqa: F821

    _escs(fakes, reply=False)
    from machine import Pin

    p = Pin(10, Pin.IN, Pin.PULL_UP)
    sm = rp2.StateMachine(0, no_timeout, freq=12000000, sideset_base=p, set_base=p, in_base=p, jmp_pin=p)
    sm.active(1)
    sm.put(1, 16)
    assert sm.stalled
    for _ in range(4):
        sm.put(1, 16)
    with pytest.raises(RuntimeError):
        sm.put(1, 16)


# ------------------------------------------------------------------ the board


def _board(rp2, **values):
    import regmodels
    from machine import attach_i2c

    from hoverfly.boards.rp2.board import Rp2Board
    from hoverfly.core.config.params import Params

    class Clock:
        t = 0

        def ticks_us(self):
            return self.t

        def sleep_us(self, us):
            self.t += us

    params = Params()
    for k, v in values.items():
        assert params.set(k, v) is None
    b = Rp2Board(clock=Clock(), usb=False)
    b.print_status = False
    attach_i2c(0, regmodels.MPU6050Model())
    b.setup(params)
    return b, params


def _board_params(**values):
    from hoverfly.core.config.params import Params

    p = Params()
    for k, v in values.items():
        p.set(k, v)
    return p


def test_board_builds_the_bidirectional_program_without_a_fault(fakes):
    b, _ = _board(fakes, dshot_bidir=1)
    assert not b.faults & FAULT_OUTPUT, b.status_line()
    assert b._dshot.bidir and len(b._dshot.sms) == 4
    assert b.configure_outputs(_board_params(), 4, 0)  # bidir off: back to the transmit-only program
    assert not b._dshot.bidir
    assert fakes.PIO.removed  # the bidirectional program's PIO memory was freed


def test_board_telemetry_gives_each_motor_its_rpm_within_1pct(fakes):
    # given motor_order 2143, 14-pole motors and ESCs on lines 1..4 spinning at known eRPM,
    # when the core writes motors and reads telemetry, then the OutputStage decodes each
    # motor's own RPM (eRPM / 7) within 1 %, and a second read without new frames is not fresh
    from hoverfly.core.stages.output import OutputStage

    escs = _escs(fakes)
    b, params = _board(fakes, dshot_bidir=1, motor_order=2143, motor_poles=14)
    line_erpm = (21000, 35000, 70000, 140000)
    for line in range(4):
        escs[line].erpm = line_erpm[line]
    stage = OutputStage()
    stage.configure(params, 4)
    erpm_out = array("i", [0] * 8)
    rpm_out = array("i", [0] * 8)
    b.write_motors(array("f", [0.3, 0.4, 0.5, 0.6]), 4)
    assert b.read_motor_telemetry(stage.reply_codes, 4)
    stage.decode_replies(4, erpm_out, rpm_out)
    assert stage.reply_errors == 0
    for m in range(4):
        want = line_erpm[b.output.line_of_motor[m]] / 7.0
        assert abs(rpm_out[m] - want) <= 0.01 * want, (m, rpm_out[m], want)
    assert [e.value for e in escs] == [frame_value(w) for w in b.output.words[:4]]
    assert all(frame_crc_ok(w, True) for w in b.output.words[:4])
    assert not b.read_motor_telemetry(stage.reply_codes, 4)


def test_board_telemetry_with_one_silent_esc_counts_it_and_never_crashes(fakes):
    # given one ESC that stopped answering, when passes go on, then the others' replies are
    # fresh, the silent one's code is 0 (a decoder error, counted) and the board counts it;
    # with every ESC silent nothing reads fresh
    from hoverfly.core.stages.output import OutputStage

    escs = _escs(fakes)
    b, params = _board(fakes, dshot_bidir=1)
    for e in escs:
        e.erpm = 50000
    escs[2].reply = False
    stage = OutputStage()
    stage.configure(params, 4)
    erpm_out = array("i", [0] * 8)
    rpm_out = array("i", [0] * 8)
    for _ in range(3):
        b.write_motors(array("f", [0.5] * 4), 4)
        assert b.read_motor_telemetry(stage.reply_codes, 4)
        stage.decode_replies(4, erpm_out, rpm_out)
    m = list(b.output.motor_of_line).index(2)
    assert b._dshot.missed_line[2] >= 2 and b._dshot.missed >= 2
    assert stage.reply_codes[m] == 0
    assert stage.reply_errors >= 2
    assert escs[2].frames == escs[0].frames  # its frames still went out
    for e in escs:
        e.reply = False
    b.write_motors(array("f", [0.5] * 4), 4)
    b.read_motor_telemetry(stage.reply_codes, 4)  # the last replies (before they all went quiet)
    b.write_motors(array("f", [0.5] * 4), 4)
    assert not b.read_motor_telemetry(stage.reply_codes, 4)


# ------------------------------------------------------------- the hover under MicroPython

SCRIPT = """
import json
from world import World, arm, hold
from hoverfly.boards.rp2 import main as fw

world = World(%(airframe)s, judge_from_s=4.5)
board = fw.make_board("mpu6050", "crsf", "dshot600", clock=world, usb=False, storage_path=%(storage)r)
world.board = board
seen = {"passes": 0, "err_max_pct": 0.0}


def on_pass(flight):
    s = flight.signals
    if flight.arming.armed and world.t_us > 4500000:
        seen["passes"] += 1
        # the rotor a frame ago (the reply answers the previous frame): within a few percent
        for i in range(4):
            want = world.vehicle.omega[i] * 9.549296585513721
            got = s.motor_rpm[i]  # default motor_order: motor i on line i
            if want > 1000.0:
                e = abs(got - want) * 100.0 / want
                if e > seen["err_max_pct"]:
                    seen["err_max_pct"] = e


world.at(2.0, arm)
world.at(2.5, hold(2.0))
flight, stats = fw.main(board=board, passes=int(7.0 * 500), on_pass=on_pass,
                        overrides=(("loop_hz", 500), ("dshot_bidir", 1)))
r = world.stats()
r.update(seen)
r["faults"] = board.faults
r["status"] = board.status_line()
r["armed"] = flight.arming.armed
r["replies"] = flight.output.replies
r["reply_errors"] = flight.output.reply_errors
r["missed"] = board._dshot.missed
r["bidir"] = board._dshot.bidir
r["rpm"] = [flight.signals.motor_rpm[i] for i in range(4)]
r["esc_frames"] = [e.frames for e in world.escs]
r["esc_errors"] = [e.errors + e.crc_errors + e.idle_low for e in world.escs]
r["contention"] = [sm.contention for sm in board._dshot.sms]
print("RESULT " + json.dumps(r))
"""


@pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")
def test_rp2_main_loop_hovers_on_bidirectional_dshot_and_reports_rpm(tmp_path):
    # given the hover scenario with dshot_bidir=1, when the board's own loop flies it under
    # MicroPython, then the ESCs read every frame off the inverted line, it hovers, and the
    # motors' RPM comes back through the replies within 3 % of the rotors'
    script = tmp_path / "run.py"
    script.write_text(SCRIPT % {"airframe": repr(load_airframe("5inch")), "storage": str(tmp_path / "p.bin")})
    env = dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (FAKES, ROOT / "src"))
    # 2 MB, as tests/test_rp2_board.py: compiling the core from source on the 64-bit VM; a board loads .mpy
    res = subprocess.run([MICROPYTHON, "-X", "heapsize=2m", str(script)], capture_output=True, text=True,
                         timeout=120, env=env, cwd=str(ROOT))
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    lines = [ln for ln in res.stdout.splitlines() if ln.startswith("RESULT ")]
    assert lines, res.stdout[-3000:]
    r = json.loads(lines[-1][len("RESULT "):])
    assert r["faults"] == 0, r["status"]
    assert r["bidir"] and r["armed"] and not r["crashed"] and r["spun"]
    assert r["tilt_rms_deg"] <= 1.5
    assert 1.5 <= r["alt_m"] <= 2.5
    assert min(r["esc_frames"]) >= 3000 and r["esc_errors"] == [0, 0, 0, 0]
    assert r["replies"] >= 4 * 3000 and r["reply_errors"] == 0 and r["missed"] == 0
    assert r["contention"] == [0, 0, 0, 0]
    assert all(rpm > 5000 for rpm in r["rpm"]), r["rpm"]
    assert r["passes"] > 1000 and r["err_max_pct"] < 3.0, r
