"""FaultWatch.check_imu's twins (core/safety/failsafe.py `check_imu_python` on `imu_faults`, and on MicroPython
accel/faults.py `check_imu`, generated from it): the same faults from the same samples, frozen and saturated
runs, recoveries, limits, signed zeros and NaNs included. Portable: on CPython the Python twin is the method
and the test checks that.
"""

from array import array

from test_fixedrate import Lcg  # the same deterministic numbers on every port

from hoverfly.compat import IS_MICROPYTHON
from hoverfly.core.safety import failsafe
from hoverfly.core.safety.failsafe import (
    FAULT_IMU_FROZEN,
    FAULT_IMU_NONFINITE,
    FAULT_IMU_SATURATED,
    FAULT_NONE,
    FaultWatch,
)


def _samples():
    """(gyro, accel) rad/s and m/s² samples: noise, frozen stretches, saturation at and past the limits."""
    rnd = Lcg(7)
    out = []
    frozen = ([0.01, -0.02, 0.03], [0.1, 0.2, -9.8])
    for k in range(400):
        phase = (k // 25) % 8
        if phase == 1:
            g, a = frozen  # 25 identical samples: frozen after 10
        elif phase == 3:
            g = [34.0, -34.0, 0.0]  # at the limit: not saturated
            a = [150.0, -150.0, -9.8]
        elif phase == 4:
            g = [34.01 if k % 2 else -35.0, 0.0, 0.0]  # past it
            a = [0.0, 0.0, -9.8]
        elif phase == 5:
            g = [0.0, 0.0, 0.0]
            a = [0.0, -151.0 if k % 3 else float("inf"), -9.8]  # an infinity: not finite at once
            if k % 7 == 0:
                g[k % 3] = float("nan")  # a NaN: not finite at once
        elif phase == 6:
            g = [rnd.span(40.0) for _ in range(3)]  # now and then past the limit
            a = [rnd.span(160.0) for _ in range(3)]
        else:
            g = [rnd.span(1.0) for _ in range(3)]
            a = [rnd.span(1.0), rnd.span(1.0), -9.8 + rnd.span(0.5)]
        out.append((g, a))
    return out


def test_the_twins_give_the_same_faults():
    chosen = FaultWatch()
    python = FaultWatch()
    g = array("f", [0.0] * 3)
    a = array("f", [0.0] * 3)
    seen = set()
    for k, (gv, av) in enumerate(_samples()):
        for i in range(3):
            g[i] = gv[i]
            a[i] = av[i]
        f1 = chosen.check_imu(g, a)
        f2 = failsafe.check_imu_python(python, g, a)
        assert f1 == f2, (k, gv, av, f1, f2)
        assert chosen.imu_fault == f1
        seen.add(f1)
        if k == 310:
            chosen.reset_imu()
            python.reset_imu()
    assert seen == {FAULT_NONE, FAULT_IMU_FROZEN, FAULT_IMU_SATURATED, FAULT_IMU_NONFINITE}


def test_frozen_compares_values_as_python_does_signed_zeros_alike_and_a_nan_never_equal():
    # the generated twin reads the floats as their bits: -0.0 and 0.0 must still be the same value, and a NaN
    # (a fault of its own) must not count as a repeat, so the frozen count after it starts again
    chosen = FaultWatch()
    python = FaultWatch()
    g = array("f", [0.0, 0.01, 0.02])
    a = array("f", [0.1, 0.2, -9.8])
    got = []
    for k in range(40):
        g[0] = -0.0 if k % 2 else 0.0  # the same value, other bits
        a[1] = float("nan") if 12 <= k < 15 else 0.2
        f1 = chosen.check_imu(g, a)
        f2 = failsafe.check_imu_python(python, g, a)
        assert f1 == f2, (k, f1, f2)
        got.append(f1)
    assert got[9] == FAULT_NONE and got[10] == FAULT_IMU_FROZEN  # the first sample new, then ten repeats
    assert got[12:15] == [FAULT_IMU_NONFINITE] * 3
    assert got[15:25] == [FAULT_NONE] * 10 and got[25] == FAULT_IMU_FROZEN  # counted again after the NaN


def test_micropython_picks_the_viper_twin_and_cpython_the_python_one():
    if IS_MICROPYTHON:
        assert FaultWatch.check_imu is not failsafe.check_imu_python
    else:
        assert FaultWatch.check_imu is failsafe.check_imu_python
