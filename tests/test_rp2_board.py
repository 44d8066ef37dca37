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
import shutil
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
from usbport import UsbPort

world = World(%(airframe)s, judge_from_s=%(judge)r)
board = fw.make_board(%(imu)r, "crsf", "dshot600", clock=world, usb=%(usb)s, storage_path=%(storage)r)
world.board = board
led = []
hooks = []


def extra(flight):
    return {}


def on_pass(flight):
    p = machine.pin(25)
    if p is not None and (not led or led[-1] != p.value()):
        led.append(p.value())
    for h in hooks:
        h(flight)

"""

EPILOGUE = """
flight, stats = fw.main(board=board, passes=int(%(seconds)r * 500), on_pass=on_pass,
                        overrides=(("loop_hz", 500),%(overrides)s))
r = world.stats()
r["faults"] = board.faults
r["status"] = board.status_line()
r["armed"] = flight.arming.armed
r["led_changes"] = len(led)
r["gc_runs"] = stats.gc_runs
r["passes"] = stats.passes
r["imu_errors"] = board.imu_read_errors
r["failsafe_trips"] = board.output.failsafe_trips
r["timer_ticks"] = board.timer_ticks
r.update(extra(flight))
print("RESULT " + json.dumps(r))
"""


def run_board(tmp_path, body, seconds, imu="mpu6050", judge=5.0, heap="2m", usb="False", hook="", lib=None,
              overrides=""):
    """The board's main loop under MicroPython for `seconds`, from the sources (or from `lib`, a flash
    bundle's lib/); the RESULT it printed. (2 MB: compiling the core from source on the 64-bit VM leaves a
    fragmented 1 MB heap without room for the storage's 10 kB image; a board loads precompiled .mpy.)"""
    values = {"airframe": repr(load_airframe("5inch")), "judge": judge, "imu": imu, "usb": usb,
              "storage": str(tmp_path / "params.bin"), "seconds": seconds, "overrides": overrides}
    script = tmp_path / "run.py"
    script.write_text(PRELUDE % values + body + EPILOGUE % values)
    env = dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (FAKES, lib or ROOT / "src"))
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
def test_rp2_main_loop_hovers_with_the_receiver_parsed_on_core_1(tmp_path):
    # given rx_core1 (the receiver UART and CRSF codec on a second thread, core 1 on a Pico), when the
    # board's own loop flies the hover, then it holds it as well as with the receiver parsed in the loop's
    # task, every frame reaching the loop through the handover and the loop's telemetry going back out
    body = ("world.at(2.0, arm)\nworld.at(2.5, hold(2.0))\n"
            "from hoverfly.core.stages.rxcore import W_POLLS, W_RUNNING\n"
            "def extra(flight):\n"
            "    w = board._rx_link.words\n"
            "    return {'rx_frames': flight.receiver.frames, 'polls': w[W_POLLS], 'running': w[W_RUNNING],\n"
            "            'torn': flight.receiver.decoder.torn, 'tlm': flight.receiver.telemetry_frames,\n"
            "            'tx': len(machine.uart(1).tx), 'fault': repr(board._rx_link.fault)}\n")
    r = run_board(tmp_path, body, seconds=7.0, judge=4.5, overrides=' ("rx_core1", 1),')
    assert r["faults"] == 0, r["status"]
    assert "parsed on core 1" in r["status"]
    assert r["armed"] and r["spun"] and not r["crashed"]
    assert r["tilt_rms_deg"] <= 1.5
    assert 1.5 <= r["alt_m"] <= 2.5
    assert r["polls"] > 0 and r["fault"] == "None"
    assert r["rx_frames"] >= 6.5 * 250  # the world's 250 Hz frames from boot to the end, through core 1
    assert r["tlm"] > 100 and r["tx"] > 100 * 10  # telemetry frames written by core 1
    assert r["running"] == 0  # main() stopped core 1's loop on its way out


@needs_mp
def test_core_1_stopping_on_an_error_is_a_fault_and_the_link_watch_fails_safe(tmp_path):
    # given a hover with rx_core1, when the receiver UART starts raising on core 1 at 3 s, then core 1's
    # loop stops, the board names the fault and the error, and the flight's link watch runs the failsafe
    body = ("world.at(2.0, arm)\nworld.at(2.5, hold(2.0))\n"
            "def broken(buf, n=-1):\n"
            "    raise OSError(5)\n"
            "def brk(w):\n"
            "    machine.uart(1).readinto = broken\n"
            "world.at(3.0, brk)\n"
            "def extra(flight):\n"
            "    return {'fs_state': flight.failsafe.state, 'rx_ok': flight.rx_ok}\n")
    r = run_board(tmp_path, body, seconds=4.0, judge=10.0, overrides=' ("rx_core1", 1),')
    assert r["faults"] == 32, r["status"]
    assert "core 1 stopped: OSError" in r["status"] and "rx_core1_stopped" in r["status"]
    assert not r["rx_ok"] and r["fs_state"] != 0  # the failsafe flies (or has landed) the craft


@needs_mp
def test_rp2_main_loop_hovers_from_the_flash_bundle_as_from_the_sources(tmp_path, unix_bundle):
    # the board code and the core as `hoverfly flash` ships them (precompiled, flight.py as machine code;
    # built for the unix VM): the board's own loop, its collections in the slack included, flies the same
    body = "world.at(2.0, arm)\nworld.at(2.5, hold(2.0))\n"
    src = run_board(tmp_path, body, seconds=5.0, judge=4.0)
    # the fake world's physics is the simulator's (hoverfly.sim, not in a bundle): its sources go beside the bundle's
    lib = tmp_path / "lib"
    shutil.copytree(unix_bundle / "lib", lib)
    shutil.copytree(ROOT / "src" / "hoverfly" / "sim", lib / "hoverfly" / "sim")
    flashed = run_board(tmp_path, body, seconds=5.0, judge=4.0, lib=lib)
    assert flashed["faults"] == 0 and flashed["armed"] and flashed["spun"] and not flashed["crashed"]
    assert flashed["gc_runs"] >= 1
    for key in ("tilt_rms_deg", "tilt_max_deg", "alt_m", "alt_max_m"):
        assert flashed[key] == src[key], key


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


@needs_mp
def test_output_timer_disarms_every_motor_when_the_loop_stalls(tmp_path):
    # given a steady hover, when the board's loop hangs for 300 ms at 3.5 s (no pass, no write),
    # then the output timer puts stop words on every line within output_fs_ms (100 ms) + one
    # timer period (10 ms), and the motors run again once passes resume
    body = ("world.at(2.0, arm)\nworld.at(2.5, hold(2.0))\n"
            "stalled = []\n"
            "def stall(flight):\n"
            "    if not stalled and world.t_us >= 3500000:\n"
            "        stalled.append(1)\n"
            "        world.stall(0.3)\n"
            "hooks.append(stall)\n")
    r = run_board(tmp_path, body, seconds=4.2, judge=10.0)
    assert r["faults"] == 0, r["status"]
    assert 0.100 <= r["stall_stop_s"] <= 0.112
    assert r["failsafe_trips"] == 1
    assert r["timer_ticks"] >= 400  # 100 Hz from boot, whatever the loop did
    assert r["last_spin_s"] >= 3.9  # fresh commands after the stall spin the motors again


@needs_mp
def test_msp_request_over_usb_gets_a_reply_and_ctrl_c_is_off_meanwhile(tmp_path):
    # given the board on a fake USB port, when a configurator sends MSP_API_VERSION and
    # MSP_FC_VERSION (whose frame holds 0x03 bytes) at 1 s, then both are answered on USB,
    # Ctrl-C is off from the first byte and back on after USB_IDLE_MS of quiet, disarmed
    body = ("kbd = []\nboard._kbd_intr = kbd.append\nseen = []\n"
            "world.at(1.0, lambda w: board._usb.inject(b'$M<\\x00\\x01\\x01$M<\\x00\\x03\\x03'))\n"
            "world.at(1.5, lambda w: seen.append(board.ctrl_c_enabled))\n"
            "world.at(3.9, lambda w: seen.append(board.ctrl_c_enabled))\n"
            "def extra(flight):\n"
            "    return {'tx': bytes(board._usb.tx).hex(), 'kbd': kbd, 'seen': seen,\n"
            "            'ctrl_c': board.ctrl_c_enabled}\n")
    r = run_board(tmp_path, body, seconds=4.5, usb="UsbPort()")
    tx = bytes.fromhex(r["tx"])
    frames = {}
    i = tx.find(b"$M>")
    while i >= 0:
        size, cmd = tx[i + 3], tx[i + 4]
        payload = tx[i + 5:i + 5 + size]
        check = size ^ cmd
        for b in payload:
            check ^= b
        assert tx[i + 5 + size] == check
        frames[cmd] = payload
        i = tx.find(b"$M>", i + 6 + size)
    assert set(frames) == {1, 3}
    assert len(frames[3]) == 3  # major, minor, patch
    assert r["seen"] == [False, False]
    assert r["kbd"] == [-1, 3]
    assert r["ctrl_c"]


@needs_mp
def test_parameters_round_trip_through_the_flash_file_under_micropython(tmp_path):
    # given parameters saved through the two-slot store into the board's file before boot,
    # when main boots, then the flight flies them; and a save from the running flight (as the
    # CLI's `save`) lands in the file and loads back, with no temporary file left behind
    body = ("from hoverfly.core.config.params import Params\nfrom hoverfly.core.config.storage import Storage\n"
            "p = Params()\np.set('p_roll', 55)\nassert Storage(board).save(p) is None\n"
            "def extra(flight):\n"
            "    flight.params.set('p_pitch', 66)\n"
            "    err = flight.storage.save(flight.params)\n"
            "    q = Params()\n"
            "    st = Storage(board).load(q)\n"
            "    return {'p_roll': flight.params.get('p_roll'), 'err': err, 'status': st,\n"
            "            'loaded': (q.get('p_roll'), q.get('p_pitch')), 'bit': flight.bit.storage_ok}\n")
    r = run_board(tmp_path, body, seconds=0.2)
    assert r["p_roll"] == 55
    assert r["err"] is None
    assert r["status"] == 1  # LOADED
    assert r["loaded"] == [55, 66]
    assert r["bit"]
    assert "parameters loaded" in r["stdout"]
    assert (tmp_path / "params.bin").exists() and not (tmp_path / "params.bin.tmp").exists()


@needs_mp
def test_lost_parameters_fail_the_built_in_test(tmp_path):
    # given a parameter file whose slots are both damaged, when main boots, then the defaults fly
    # and the built-in test's storage check fails (it blocks arming)
    (tmp_path / "params.bin").write_bytes(b"HVFP" + b"\x00" * 60)
    body = "def extra(flight):\n    return {'bit': flight.bit.storage_ok, 'names': flight.bit.names()}\n"
    r = run_board(tmp_path, body, seconds=0.3)
    assert not r["bit"]
    assert "storage" in r["names"]
    assert "parameters lost" in r["stdout"]


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
    from hoverfly.core.config.params import Params
    from hoverfly.core.stages.receiver import Receiver

    params = Params()
    params.set("rx_provider", "pwm")
    rx = Receiver()
    rx.configure(params)
    rx.start(0)
    assert rx.update(t, b) >= 1
    assert tuple(rx.channels_us[:6]) == widths


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


def _params(**values):
    from hoverfly.core.config.params import Params

    p = Params()
    for k, v in values.items():
        assert p.set(k, v) is None
    return p


def _imu_board(fakes, **params):
    b = _board()
    fakes.attach_i2c(0, __import__("regmodels").MPU6050Model())
    b.setup(_params(**params))
    return b


def test_dshot_words_reach_the_fifos_through_the_output_encoder_in_motor_order(fakes):
    # given motor_order 2143 (motor 1 on output 2 ...) and DShot300, when the core writes four
    # different throttles, then each state machine's newest word is the encoder's word for its
    # line, and motor 1's (the lowest) is on line 2
    from array import array

    from hoverfly.protocols.dshot import frame_value

    b = _imu_board(fakes, motor_protocol="dshot300", motor_order=2143)
    sms = b._dshot.sms
    assert [sm.freq for sm in sms] == [2400000] * 4
    first = [sm.take() for sm in sms]
    assert all(f and frame_value(f[-1] >> 16) == 0 for f in first)  # boot: disarmed values
    for _ in range(3):
        b.write_motors(array("f", [0.2, 0.4, 0.6, 0.8]), 4)
    words = [sm.take()[-1] >> 16 for sm in sms]
    assert words == list(b.output.words[:4])
    values = [frame_value(w) for w in words]
    assert values[1] < values[0] < values[3] < values[2]
    assert b.output.line_of_motor == bytes([1, 0, 3, 2])


def test_output_timer_sends_stop_words_once_commands_stop(fakes):
    # given motors spinning on DShot600 and output_fs_ms 100, when no write comes for 150 ms,
    # then between 100 and 110 ms the output timer puts DShot 0 on every line, each tick after
    from array import array

    from hoverfly.protocols.dshot import frame_value

    b = _imu_board(fakes)
    sms = b._dshot.sms
    t0_ms = b.clock.t // 1000  # the IMU's start-up delays ran the clock
    fakes.run_timers(t0_ms)
    b.write_motors(array("f", [0.5] * 4), 4)
    for sm in sms:
        sm.take()
    stopped_at = -1
    for t_ms in range(1, 151):
        b.clock.t = (t0_ms + t_ms) * 1000
        fakes.run_timers(t0_ms + t_ms)
        got = [sm.take() for sm in sms]
        if stopped_at < 0 and all(g and frame_value(g[-1] >> 16) == 0 for g in got):
            stopped_at = t_ms
    assert 100 < stopped_at <= 110
    assert b.output.failsafe and b.output.failsafe_trips == 1
    b.write_motors(array("f", [0.5] * 4), 4)  # commands resume: the failsafe lets go
    assert not b.output.failsafe
    assert all(frame_value(sm.take()[-1] >> 16) > 48 for sm in sms)


def test_analog_output_failsafe_holds_the_minimum_pulse(fakes):
    from array import array

    b = _imu_board(fakes, motor_protocol="oneshot125", motor_pwm_rate=2000)
    assert fakes.pwm(10).freq() == 2000
    t0_ms = b.clock.t // 1000
    fakes.run_timers(t0_ms)
    b.write_motors(array("f", [1.0] * 4), 4)
    assert fakes.pwm(12).duty_ns() == 250000
    for t_ms in range(1, 121):
        b.clock.t = (t0_ms + t_ms) * 1000
        fakes.run_timers(t0_ms + t_ms)
    assert [fakes.pwm(p).duty_ns() for p in (10, 11, 12, 13)] == [125000] * 4


def test_bidirectional_dshot_runs_the_receiving_program_without_a_fault(fakes):
    # dshot_bidir=1 builds the bidirectional PIO program (tests/test_rp2_dshot_bidir.py tests
    # it on the line): no output fault, and every word carries the inverted CRC
    from array import array

    from hoverfly.protocols.dshot import frame_crc_ok

    b = _imu_board(fakes, dshot_bidir=1)
    assert not b.faults & 16, b.status_line()
    assert b._dshot.bidir
    b.write_motors(array("f", [0.5] * 4), 4)
    assert all(frame_crc_ok(sm.take()[-1] >> 16, True) for sm in b._dshot.sms)
    assert b.configure_outputs(_params(), 4, 0)  # reconfigured without it: the transmit-only program
    assert not b._dshot.bidir and not b.faults & 16


def test_motor_telemetry_comes_back_in_motor_order(fakes):
    from array import array

    b = _imu_board(fakes, motor_order=2143)
    codes = array("i", [0] * 4)
    assert not b.read_motor_telemetry(codes, 4)
    d = b._dshot
    for line in range(4):
        d.replies[line] = 100 + line
    d.fresh = True
    assert b.read_motor_telemetry(codes, 4)
    assert list(codes) == [101, 100, 103, 102]
    assert not b.read_motor_telemetry(codes, 4)


def test_usb_bytes_turn_ctrl_c_off_until_disarmed_quiet_and_no_session(fakes):
    from usbport import UsbPort

    calls = []
    b = _board()
    b._kbd_intr = calls.append
    b.use_usb = UsbPort()
    b.setup()

    class Arming:
        armed = False

    class Flight:
        arming = Arming()
        config_session = 0
        receiver = None

    b.flight = Flight()
    buf = bytearray(64)
    b._usb.inject(b"$M<\x00\x03\x03")
    assert b.serial_read(0, buf) == 6
    assert not b.ctrl_c_enabled and calls == [-1]
    b.clock.t += 2000000
    b.set_led(False)
    assert not b.ctrl_c_enabled  # quiet for only 2 s
    b.clock.t += 2000000
    Flight.config_session = 1  # the CLI is open
    b.set_led(False)
    assert not b.ctrl_c_enabled
    Flight.config_session = 0
    Arming.armed = True
    b.set_led(False)
    assert not b.ctrl_c_enabled
    Arming.armed = False
    b.set_led(False)
    assert b.ctrl_c_enabled and calls == [-1, 3]
    assert b.serial_write(0, b"abc", 2) == 2 and bytes(b._usb.tx) == b"ab"


def test_maintenance_port_is_uart0(fakes):
    b = _board()
    b.setup()
    u = fakes.uart(0)
    assert u.baudrate == 115200
    u.inject(b"\x01\x02")
    buf = bytearray(8)
    assert b.serial_read(1, buf) == 2 and buf[:2] == b"\x01\x02"
    assert b.serial_write(1, b"xyz") == 3 and bytes(u.tx) == b"xyz"


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
