"""The rp2 board drives a plane's outputs off-hardware: four servos on GP22, GP20, GP21, GP28 and the motor on
GP10, each through the fake machine.PWM (tests/rp2fakes), whose duty values the checks read. The same script
runs under MicroPython (the board's own runtime) and CPython."""

import json
import os
import pathlib
import subprocess
import sys

import pytest

from test_micropython import MICROPYTHON

ROOT = pathlib.Path(__file__).resolve().parent.parent
FAKES = ROOT / "tests" / "rp2fakes"

SCRIPT = """
import json
from array import array

import machine
from hoverfly.boards.rp2.board import Rp2Board
from hoverfly.core.config.params import Params


class Clock:
    t = 0

    def ticks_us(self):
        return self.t

    def sleep_us(self, us):
        self.t += us


machine.reset()
clock = Clock()
board = Rp2Board(clock=clock, usb=False, motor_count=1)
board.print_status = False
p = Params()
for name, value in (("mixer_type", "airplane"), ("motor_protocol", "pwm"), ("motor_pwm_rate", 400),
                    ("servo_pwm_rate", 200), ("servo2_mid_us", 1480), ("servo3_mid_us", 1520)):
    assert p.set(name, value) is None, name
board.setup(p)
board.configure_outputs(p, 1, 4)
board.faults = 0  # no IMU on the fake bus: the board would hold the motor at stop
pins = (22, 20, 21, 28)
r = {"boot_us": [machine.pwm(n).duty_ns() // 1000 for n in pins],
     "servo_hz": [machine.pwm(n).freq() for n in pins], "motor_hz": machine.pwm(10).freq(),
     "status": board.output_status}
clock.t = 1000
board.write_motors(array("f", [0.5]), 1)
board.write_servos(array("H", [1100, 1300, 1700, 1900]), 4)
r["servo_us"] = [machine.pwm(n).duty_ns() // 1000 for n in pins]
r["motor_us"] = machine.pwm(10).duty_ns() // 1000
clock.t = 1000 + 101000  # no command for 101 ms: the output timer's failsafe
board._output_tick(None)
r["failsafe_servo_us"] = [machine.pwm(n).duty_ns() // 1000 for n in pins]
r["failsafe_motor_us"] = machine.pwm(10).duty_ns() // 1000
r["trips"] = board.output.failsafe_trips
print("RESULT " + json.dumps(r))
"""


def _check(r):
    assert r["boot_us"] == [1500, 1500, 1480, 1520]  # each servo starts at its own mid
    assert r["servo_hz"] == [200] * 4 and r["motor_hz"] == 400
    assert "servos GP22,GP20,GP21,GP28" in r["status"]
    assert r["servo_us"] == [1100, 1300, 1700, 1900]
    assert r["motor_us"] == 1500
    assert r["failsafe_servo_us"] == [1500, 1500, 1480, 1520] and r["failsafe_motor_us"] == 1000
    assert r["trips"] == 1


def _result(stdout):
    for line in stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    raise AssertionError("no RESULT in: " + stdout[-2000:])


@pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")
def test_rp2_board_drives_four_servos_and_the_motor_under_micropython(tmp_path):
    script = tmp_path / "servos.py"
    script.write_text(SCRIPT)
    env = dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (FAKES, ROOT / "src"))
    res = subprocess.run([MICROPYTHON, "-X", "heapsize=2m", str(script)], capture_output=True, text=True,
                         timeout=120, env=env, cwd=str(ROOT))
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    _check(_result(res.stdout))


def test_rp2_board_drives_four_servos_and_the_motor_under_cpython(tmp_path):
    script = tmp_path / "servos.py"
    script.write_text(SCRIPT)
    env = dict(os.environ, PYTHONPATH="%s:%s" % (FAKES, ROOT / "src"))
    res = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, env=env,
                         cwd=str(ROOT))
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    _check(_result(res.stdout))
