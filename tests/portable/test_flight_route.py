"""Flight._route(): the pass's paths (IMU preparation, estimator) follow the calibration, the first sample
and configure(), including a start() after the calibration had finished."""

from configfakes import FakeBoard

from hoverfly.core.flight import Flight


def _fly(f, t, passes):
    for _ in range(passes):
        t += 1000
        f.step(t)
    return t


def test_the_gyro_calibration_runs_again_after_a_second_start():
    f = Flight(FakeBoard())
    f.params.set("gyro_cal_ms", 100)
    f.start(1000)
    assert f._imu_prepare and not f._att_fixed_now  # calibrating; the first sample levels the estimator
    t = _fly(f, 1000, 200)
    assert f.calibration.calibrated and not f._imu_prepare
    assert f._att_fixed_now == (f._fixed_att_on and not f._use_external)
    f.start(t)  # a board that starts the flight again (the calibration with it)
    assert not f.calibration.calibrated and f._imu_prepare
    _fly(f, t, 200)
    assert f.calibration.calibrated and not f._imu_prepare


def test_a_board_mounted_at_an_angle_keeps_the_rotation_after_calibration():
    f = Flight(FakeBoard())
    f.params.set("gyro_cal_ms", 100)
    f.params.set("board_roll_deg", 90.0)
    f.start(1000)
    _fly(f, 1000, 200)
    assert f.calibration.calibrated and not f.alignment.identity and f._imu_prepare
