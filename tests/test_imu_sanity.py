"""Sensor sanity (issue 30): a NaN or infinite IMU value, or a sample stuck on one value, is a fault.

On the ground the gyro calibration does not complete on NaN and arming is refused with a named reason
(NOGYRO); in flight the fault is found at the next 100 Hz check and handled as the existing IMU fault
(imu-freeze): disarmed, no flyaway. Nothing non-finite stays in the filters, the estimator or the
controller: once the values are good again they start cleanly and the craft flies as usual.
"""

from array import array

import pytest

from hoverfly.core.config.params import Params
from hoverfly.core.safety.arming import NO_GYRO
from hoverfly.core.safety.failsafe import FAULT_IMU_FROZEN, FAULT_IMU_NONFINITE, FAULT_NONE, FaultWatch
from hoverfly.core.stages.estimator import GyroCalibration
from hoverfly.sim.runner import SimRun
from hoverfly.sim.scenario import parse_scenario

NAN = float("nan")
INF = float("inf")


def _events(r, name):
    return [e for e in r["events"] if e["event"] == name]


def _finite(values):
    return all(v - v == 0.0 for v in values)


# ------------------------------------------------------------------ the stages
def test_gyro_calibration_never_completes_on_nan_or_inf():
    cal = GyroCalibration()
    cal.configure(Params(), 1000)
    for sample in ([NAN, NAN, NAN], [0.01, NAN, 0.0], [INF, 0.0, 0.0]):
        cal.reset()
        for _ in range(5000):
            assert not cal.update(array("f", sample))
        assert not cal.calibrated
    # and still completes on good samples after them, with a finite bias
    g = array("f", [0.01, -0.02, 0.005])
    done = [cal.update(g) for _ in range(2000)]
    assert any(done) and cal.calibrated and _finite(cal.bias_rad_s)


@pytest.mark.parametrize("gyro, accel", [
    ([NAN, 0.0, 0.0], [0.0, 0.0, -9.8]),
    ([0.0, 0.0, 0.0], [0.0, INF, -9.8]),
    ([0.0, -INF, 0.0], [0.0, 0.0, -9.8]),
    ([0.0, 0.0, 0.0], [NAN, NAN, NAN]),
])
def test_a_non_finite_sample_is_a_fault_at_the_first_check(gyro, accel):
    fw = FaultWatch()
    assert fw.check_imu(array("f", [0.01, 0.0, 0.0]), array("f", [0.0, 0.0, -9.8])) == FAULT_NONE
    assert fw.check_imu(array("f", gyro), array("f", accel)) == FAULT_IMU_NONFINITE
    # and a good one ends it
    assert fw.check_imu(array("f", [0.02, 0.0, 0.0]), array("f", [0.0, 0.1, -9.8])) == FAULT_NONE


def test_a_stuck_sample_is_frozen_after_ten_checks():
    fw = FaultWatch()
    g = array("f", [0.01, 0.02, 0.03])
    a = array("f", [0.1, 0.2, -9.7])
    got = [fw.check_imu(g, a) for _ in range(11)]
    assert got[:10] == [FAULT_NONE] * 10 and got[10] == FAULT_IMU_FROZEN


# ------------------------------------------------------------------ on the ground
class BadImu:
    """Wraps the sim board's read_imu: from start_s to end_s the sample is changed by `spoil`."""

    def __init__(self, run, spoil, start_s=0.0, end_s=1e9):
        self.run = run
        self.read = run.board.read_imu
        self.spoil = spoil
        self.start_us = start_s * 1e6
        self.end_us = end_s * 1e6
        run.board.read_imu = self

    def __call__(self, gyro, accel):
        ok = self.read(gyro, accel)
        if ok and self.start_us <= self.run.board.sim_us < self.end_us:
            self.spoil(gyro, accel)
        return ok


def nan_gyro(g, a):
    g[0] = g[1] = g[2] = NAN


def inf_accel(g, a):
    a[2] = -INF


class Stuck:
    def __init__(self):
        self.kept = None

    def __call__(self, g, a):
        if self.kept is None:
            self.kept = (list(g), list(a))
        for i in range(3):
            g[i] = self.kept[0][i]
            a[i] = self.kept[1][i]


@pytest.mark.parametrize("name, spoil", [("nan_gyro", nan_gyro), ("inf_accel", inf_accel), ("stuck", Stuck())])
def test_on_the_ground_a_bad_imu_refuses_arming_with_nogyro_and_motors_stay_still(name, spoil):
    # given the hover scenario's pilot (arms at 2.0 s), when the IMU gives bad values from boot (NaN gyro,
    # inf accelerometer) or from 1 s (stuck on one sample), then arming is refused, NOGYRO first
    run = SimRun("5inch", "hover", seed=3, duration_s=3.0)
    BadImu(run, spoil, start_s=1.0 if name == "stuck" else 0.0)
    spun = []
    run.on_step = lambda r: spun.append(max(r.flight.signals.motor_out[:4]))
    r = run.run()
    f = run.flight
    assert not r["armed"] and not _events(r, "armed")
    blocked = _events(r, "arming_blocked")
    assert blocked and blocked[0]["detail"].startswith("NOGYRO:"), r["events"]
    assert f.arming.flags & (1 << NO_GYRO) and not f.supervisor.imu_ok
    assert "imu" in f.bit.names()
    assert max(spun) == 0.0 and r["altitude_m"]["max"] < 0.01
    if name == "nan_gyro":
        assert not f.calibration.calibrated  # no bias from NaN: CALIB stays too


# ------------------------------------------------------------------ in flight
IMU_FAULT_AT_6 = """
duration_s = 8
mode = "angle"
[[at]]
t = 2.0
arm = true
[[at]]
t = 2.5
hold_altitude_m = 1.0
"""


@pytest.mark.parametrize("name, spoil, end_s", [
    ("nan_gyro", nan_gyro, 1e9),
    ("inf_accel", inf_accel, 1e9),
    ("one_nan_sample", nan_gyro, 6.0005),  # one pass's sample at 1 kHz, between two 100 Hz checks
    ("stuck", Stuck(), 1e9),
])
def test_in_flight_a_bad_imu_disarms_as_the_imu_freeze_scenario_judges(name, spoil, end_s):
    # as tests/test_safety_scenarios.py judges imu-freeze: the fault within 35 ms (stuck: its 10 checks,
    # 100 ms, + 35 ms), disarmed for it, no climb, on the ground at the end
    run = SimRun("5inch", parse_scenario(IMU_FAULT_AT_6), seed=7)
    BadImu(run, spoil, start_s=6.0, end_s=end_s)
    r = run.run()
    fault = _events(r, "imu_fault")
    limit = 6.0 + (0.135 if name == "stuck" else 0.035)
    assert fault and fault[0]["t_s"] <= limit, r["events"]
    assert fault[0]["detail"] == ("imu_frozen" if name == "stuck" else "imu_nonfinite")
    assert _events(r, "disarmed")[0]["detail"] == "imu_fault"
    assert r["altitude_m"]["max"] < 2.0 and r["altitude_m"]["final"] < 0.05
    assert not r["armed"]


def test_after_a_nan_spell_on_the_ground_the_stages_start_clean_and_the_hover_flies():
    # given NaN gyro samples from 0.3 s to 1.0 s (during the calibration), when they end, then nothing
    # non-finite is left in the filters, the attitude or the PID state, the calibration completes on good
    # samples, and the pilot's arm at 2.0 s takes off to a hover as usual
    run = SimRun("5inch", "hover", seed=7)
    BadImu(run, nan_gyro, start_s=0.3, end_s=1.0)
    seen = {"fault": False, "clean_at": None}

    def hook(r):
        f = r.flight
        if not f.supervisor.imu_ok:
            seen["fault"] = True
        elif seen["fault"] and seen["clean_at"] is None:
            seen["clean_at"] = r.board.sim_us * 1e-6
            s = f.signals
            c = f.controller
            seen["state"] = (list(s.gyro_rad_s) + list(s.attitude.q) + [c.roll.i, c.pitch.i, c.yaw.i])
    run.on_step = hook
    r = run.run()
    f = run.flight
    assert seen["fault"] and seen["clean_at"] is not None and seen["clean_at"] <= 1.05
    assert _finite(seen["state"])
    assert f.calibration.calibrated and _finite(f.calibration.bias_rad_s)
    armed = _events(r, "armed")
    assert armed and armed[0]["t_s"] <= 2.05
    assert r["armed"] and not r["crashed"]
    assert r["tilt_rms_deg"] <= 1.5 and abs(r["altitude_m"]["final"] - 2.0) <= 0.15
    assert _finite(f.signals.attitude.q) and _finite(f.signals.gyro_rad_s)
