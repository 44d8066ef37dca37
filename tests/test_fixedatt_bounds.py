"""The fixed-point attitude estimator stays inside 32-bit words, whatever it is fed.

On the RP2040/RP2350 the viper twin (accel/att.py) computes in 32-bit machine words that wrap
silently; the unix VM's are 64-bit, so an overflow would not show in the twin test. Here the Python
twin (core/fastpass/fixedatt.py's `att_pass`, which the viper twin equals bit for bit) runs on extreme inputs
and the largest gains with every product replaced by the viper twin's split product, checked, and
every integer it computes from the inputs checked: any intermediate at 2**31 or beyond raises.
"""

import math
import random

import pytest
from test_fixedatt import _io, _stages  # tests/portable (conftest puts it on the path)

from hoverfly.core.fastpass import fixedatt
from test_fixedrate_bounds import I32, _checked_mul

_LIMIT = 1 << 31
_B_WIDE = (1 << 29) - (1 << 15)


def _checked_mulw(a, b):
    """The viper twin's product of two wide words on 15-bit halves, every partial result checked."""
    a = int(a)
    b = int(b)
    assert -(1 << 30) < a < (1 << 30), a  # the module docstring's bounds
    assert -_B_WIDE < b < _B_WIDE, b
    ah = I32(a >> 15)
    al = I32(a & 0x7FFF)
    bh = I32(b >> 15)
    bl = I32(b & 0x7FFF)
    return ((ah * bh) << 2) + ((ah * bl + al * bh + ((al * bl + 0x8000000) >> 15)) >> 13)


@pytest.fixture
def checked(monkeypatch):
    plain_dec = fixedatt._dec

    def dec(x, scale, lim):
        return I32(plain_dec(x, scale, lim))

    monkeypatch.setattr(fixedatt, "_mul", _checked_mul)
    monkeypatch.setattr(fixedatt, "_mulw", _checked_mulw)
    monkeypatch.setattr(fixedatt, "_dec", dec)


_WILD = (float("nan"), float("inf"), -float("inf"), 1e30, -1e30, 63.99, -64.0, 255.9, -256.0, 0.0, 1.0, -1.0,
         0.7071, 9.80665, -9.80665 * 1.07)

# The largest gains the parameters allow (kp 5/s, x10 disarmed; ki 5/s^2), the smallest, and the most
# passes averaged with the longest step.
_EXTREME = (
    ((("imu_dcm_kp", 50000), ("imu_dcm_ki", 50000)), 1),
    ((("imu_dcm_kp", 1), ("imu_dcm_ki", 1)), 4),
    ((("imu_dcm_kp", 50000), ("imu_dcm_ki", 50000)), 255),
)


@pytest.mark.parametrize("sets,every", _EXTREME)
def test_no_intermediate_reaches_2_to_the_31_on_extreme_inputs(checked, sets, every):
    m, att, s, fx, on = _stages(sets, every)
    assert on
    io = _io()
    rnd = random.Random(6)
    updates = 0
    worst_b = 0
    for n in range(6000):
        wild = n % 3 == 0
        for k in range(3):
            io[0][k] = rnd.choice(_WILD) if wild else rnd.uniform(-70.0, 70.0)
            io[1][k] = rnd.choice(_WILD) if wild else rnd.uniform(-300.0, 300.0)
        if n % 7 == 0:  # the state as written from outside: anything at all
            for k in range(4):
                io[2][k] = rnd.choice(_WILD) if wild else rnd.uniform(-1.2, 1.2)
            for k in range(3):
                io[4][k] = rnd.choice(_WILD) if wild else rnd.uniform(-0.6, 0.6)
        if n % 5 == 0 or (n % every == every - 1 and n % 2):
            # gravity alone, turned any way: the trusted path, with its largest error
            v = [rnd.uniform(-1.0, 1.0) for _ in range(3)]
            k = 9.80665 * rnd.choice((1.0, 1.07)) / math.sqrt(sum(c * c for c in v) or 1.0)
            for i in range(3):
                io[1][i] = v[i] * k
        dt_us = rnd.choice((0, -3, 1, 1000, 4000, 20000, 24999, 25000, 10 ** 6, -(10 ** 6)))
        r = fixedatt.att_pass(fx.co, fx.st, io, rnd.choice((0, fixedatt.F_ARMED)), dt_us)
        for v in fx.st:
            assert -_LIMIT <= v < _LIMIT
        if r:
            updates += 1
            assert abs(sum(io[2][i] * io[2][i] for i in range(4)) - 1.0) < 1e-5
            if r & fixedatt.R_BIAS:  # written: within its clamp
                b = max(abs(io[4][i]) for i in range(3))
                assert b <= 0.5
                worst_b = max(worst_b, b)
    assert updates == 6000 // every
    assert worst_b > 0.0  # the bias integral ran (checked)


def test_the_checked_wide_product_is_the_plain_one_up_to_its_bounds():
    rnd = random.Random(3)
    pairs = [(((1 << 30) - 1) * sa, (_B_WIDE - 1) * sb) for sa in (1, -1) for sb in (1, -1)]
    pairs += [(rnd.randrange(-(1 << 30) + 1, 1 << 30), rnd.randrange(-_B_WIDE + 1, _B_WIDE)) for _ in range(20000)]
    seen = 0
    for a, b in pairs:
        want = (a * b + 0x8000000) >> 28
        if -(1 << 30) <= want < (1 << 30):  # (a result near 2**31 would overflow the sum: the bounds)
            assert int(_checked_mulw(a, b)) == want
            seen += 1
    assert seen > 10000


def test_a_wide_product_past_its_bounds_is_caught():
    with pytest.raises(AssertionError):
        _checked_mulw(1 << 29, 1 << 29)
    with pytest.raises(OverflowError):  # what the bound on b keeps away: -2**15 * -2**14 * 4
        (I32(-(1 << 15)) * I32(-(1 << 14))) << 2
