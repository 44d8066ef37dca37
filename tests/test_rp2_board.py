"""The rp2 board off-hardware: its own main loop under MicroPython against fake machine/rp2.

The fakes (tests/rp2fakes): an MPU-6050 register model on the fake I2C bus fed by the
simulator's physics, CRSF frames on the fake receiver UART, DShot words collected from
the PIO state machines' FIFOs and fed back to the motors (world.py). The hover flies on
the board's own loop; the bad-input cases check the status (fault bits, status line, LED
blink code) and that no motor ever got a non-stop word. A few fast checks of the board's
wiring run on CPython with the same fakes.
"""

import json
import os
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
FAKES = ROOT / "tests" / "rp2fakes"
sys.path.insert(0, str(FAKES))

from hoverfly.sim.airframes import load_airframe  # noqa: E402
from test_micropython import MICROPYTHON  # noqa: E402

FAULT_IMU_ABSENT = 1
FAULT_IMU_BUS = 2
FAULT_RX_SILENT = 4

PRELUDE = """
import json
import machine
from world import World, arm, hold
from hoverfly.boards.rp2 import main as fw

world = World(%(airframe)s, judge_from_s=%(judge)r)
board = fw.make_board(%(imu)r, "crsf", "dshot600", clock=world, usb=False, storage_path=%(storage)r)
_setup = board.setup


def setup(params=None):
    f = _setup(params)
    world.sms = board._dshot.sms if board._dshot is not None else []
    return f


board.setup = setup
led = []


def on_pass(flight):
    p = machine.pin(25)
    if p is not None and (not led or led[-1] != p.value()):
        led.append(p.value())

"""

EPILOGUE = """
flight, stats = fw.main(board=board, passes=int(%(seconds)r * 500), on_pass=on_pass,
                        overrides=(("loop_hz", 500),))
r = world.stats()
r["faults"] = board.faults
r["status"] = board.status_line()
r["armed"] = flight.arming.armed
r["led_changes"] = len(led)
r["gc_runs"] = stats.gc_runs
r["passes"] = stats.passes
r["imu_errors"] = board.imu_read_errors
print("RESULT " + json.dumps(r))
"""


def run_board(tmp_path, body, seconds, imu="mpu6050", judge=5.0, heap="1m"):
    values = {"airframe": repr(load_airframe("5inch")), "judge": judge, "imu": imu,
              "storage": str(tmp_path / "params.bin"), "seconds": seconds}
    script = tmp_path / "run.py"
    script.write_text(PRELUDE % values + body + EPILOGUE % values)
    env = dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (FAKES, ROOT / "src"))
    res = subprocess.run([MICROPYTHON, "-X", "heapsize=" + heap, str(script)], capture_output=True, text=True,
                         timeout=120, env=env, cwd=str(ROOT))
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    lines = [ln for ln in res.stdout.splitlines() if ln.startswith("RESULT ")]
    assert lines, res.stdout[-3000:]
    r = json.loads(lines[-1][len("RESULT "):])
    r["stdout"] = res.stdout
    return r


needs_mp = pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")


@needs_mp
def test_rp2_main_loop_hovers_under_micropython(tmp_path):
    # given the hover scenario's pilot (arm at 2 s, hold 2 m from 2.5 s), when the board's own
    # loop flies it at 500 Hz on register reads and PIO words, then it holds a steady hover
    r = run_board(tmp_path, "world.at(2.0, arm)\nworld.at(2.5, hold(2.0))\n", seconds=7.0, judge=4.5)
    assert r["faults"] == 0, r["status"]
    assert r["armed"]
    assert not r["crashed"]
    assert r["spun"]
    assert r["tilt_rms_deg"] <= 1.5
    assert 1.5 <= r["alt_m"] <= 2.5
    assert r["gc_runs"] >= 1  # collections happened, in the slack


@needs_mp
def test_missing_imu_at_boot_sets_status_and_motors_never_spin(tmp_path):
    body = "world.mpu.absent = True\nworld.at(1.5, arm)\nworld.at(1.6, hold(2.0))\n"
    r = run_board(tmp_path, body, seconds=3.0)
    assert r["faults"] & FAULT_IMU_ABSENT
    assert "imu_absent" in r["status"] and "mpu6050 absent" in r["status"]
    assert "imu_absent" in r["stdout"]  # printed at boot
    assert not r["armed"]
    assert not r["spun"]
    assert r["led_changes"] >= 4  # the blink code runs


@needs_mp
def test_unsupported_imu_type_is_a_fault_not_a_crash(tmp_path):
    r = run_board(tmp_path, "world.at(1.5, arm)\n", seconds=2.0, imu="bmi270")
    assert r["faults"] & FAULT_IMU_ABSENT
    assert "unsupported IMU 'bmi270'" in r["status"]
    assert not r["spun"]


@needs_mp
def test_imu_bus_error_mid_flight_disarms_and_stops_the_motors(tmp_path):
    body = ("world.at(2.0, arm)\nworld.at(2.5, hold(2.0))\n"
            "world.at(4.0, lambda w: machine.i2c_fail(0, 10 ** 9))\n")
    r = run_board(tmp_path, body, seconds=4.5, judge=10.0)
    assert r["faults"] & FAULT_IMU_BUS
    assert "imu_bus_error" in r["status"]
    assert not r["armed"]
    assert r["imu_errors"] > 0
    # motors flew until the fault and got nothing but stop words from the 5th failed read on
    assert 3.9 <= r["last_spin_s"] <= 4.0 + 0.012


@needs_mp
def test_silent_receiver_sets_status_and_motors_never_spin(tmp_path):
    body = "world.rx_alive = False\nworld.at(1.5, arm)\nworld.at(1.6, hold(2.0))\n"
    r = run_board(tmp_path, body, seconds=2.5)
    assert r["faults"] & FAULT_RX_SILENT
    assert "rx_silent" in r["status"] and "uart1 rx GP9" in r["status"]
    assert not r["armed"]
    assert not r["spun"]


# ----------------------------------------------------------------- CPython, same fakes


@pytest.fixture
def fakes():
    import machine

    machine.reset()
    yield machine
    machine.reset()


def _board(**kw):
    from hoverfly.boards.rp2.board import Rp2Board

    class Clock:
        t = 0

        def ticks_us(self):
            return self.t

        def sleep_us(self, us):
            self.t += us

    b = Rp2Board(clock=Clock(), usb=False, **kw)
    b.print_status = False
    return b


def test_sbus_receiver_opens_uart1_at_100k_8e2_inverted(fakes):
    b = _board(rx="sbus")
    b.setup()
    u = fakes.uart(1)
    assert (u.baudrate, u.bits, u.parity, u.stop) == (100000, 8, 0, 2)
    assert u.invert == fakes.UART.INV_RX


def test_crsf_and_ibus_baud_rates(fakes):
    for rx, baud in (("crsf", 420000), ("ibus", 115200)):
        fakes.reset()
        _board(rx=rx).setup()
        assert fakes.uart(1).baudrate == baud
        assert fakes.uart(1).invert == 0


def test_pwm_receiver_captures_pulses_by_pin_irq(fakes):
    from array import array

    b = _board(rx="pwm")
    b.setup()
    widths = (1000, 1500, 2000, 1200, 1800, 1600)
    t = 0
    for ch, w in enumerate(widths):
        p = fakes.pin((2, 3, 6, 7, 14, 15)[ch])
        assert p.hard
        b.clock.t = t
        p.fire(1)
        b.clock.t = t + w
        p.fire(0)
        t += 2500
    from hoverfly.core.params import Params
    from hoverfly.core.receiver import Receiver

    params = Params()
    params.set("rx_provider", "pwm")
    rx = Receiver()
    rx.configure(params)
    rx.start(0)
    assert rx.update(t, b) >= 1
    out = array("H", [0] * 18)
    rx.copy_channels(out)
    assert tuple(out[:6]) == widths


def test_dshot_pio_program_keeps_the_bit_timing():
    import rp2

    from hoverfly.boards.rp2.dshot_pio import dshot_program

    # 0b1010... : each bit 8 cycles, high 6 for a one and 3 for a zero
    levels = rp2.run_bits(dshot_program, 0xA000 << 16)
    assert len(levels) == 16 * 8
    for bit in range(16):
        cell = levels[bit * 8:(bit + 1) * 8]
        one = (0xA000 >> (15 - bit)) & 1
        # the cell starts at the out instruction (low); rotate so it starts at the rising edge
        high = sum(cell)
        assert high == (6 if one else 3), (bit, cell)


def test_dshot_words_go_to_the_state_machines_and_stop_when_blind(fakes):
    from array import array

    b = _board(motors="dshot600")
    fakes.attach_i2c(0, __import__("regmodels").MPU6050Model())
    b.setup()
    sms = b._dshot.sms
    assert [sm.freq for sm in sms] == [4800000] * 4
    for sm in sms:
        sm.take()
    b.write_motors(array("f", [0.5, 0.5, 0.5, 0.5]), 4)
    assert all((sm.take()[-1] >> 16) >> 5 > 48 for sm in sms)
    b.faults |= FAULT_IMU_BUS
    b.write_motors(array("f", [0.5, 0.5, 0.5, 0.5]), 4)
    assert all((sm.take()[-1] >> 16) >> 5 == 0 for sm in sms)


def test_oneshot_outputs_use_machine_pwm(fakes):
    from array import array

    b = _board(motors="oneshot125")
    b.setup()
    b.faults = 0
    b.write_motors(array("f", [0.0, 1.0, 0.5, 0.5]), 4)
    assert [fakes.pwm(p).duty_ns() for p in (10, 11)] == [125000, 250000]


def test_storage_is_replaced_whole_through_a_temporary_file(tmp_path, fakes):
    b = _board(storage_path=str(tmp_path / "p.bin"))
    assert b.load_storage() is None
    assert b.save_storage(b"one")
    assert b.save_storage(b"two")
    assert b.load_storage() == b"two"
    assert not (tmp_path / "p.bin.tmp").exists()


def test_led_blink_code_counts_the_lowest_fault():
    from hoverfly.boards.rp2.board import led_pattern

    def flashes(faults):
        on = [led_pattern(faults, t) for t in range(0, 30000, 100)]
        period = 3 * (faults & -faults).bit_length() + 12
        return sum(on[:period])

    assert flashes(1) == 1
    assert flashes(2) == 2
    assert flashes(4) == 3
    assert flashes(4 | 8) == 3
