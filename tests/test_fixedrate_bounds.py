"""The fixed-point rate loop stays inside 32-bit words, whatever it is fed.

On the RP2040/RP2350 the viper twin (accel/rate.py) computes in 32-bit machine words that wrap
silently; the unix VM's are 64-bit, so an overflow would not show in the twin test. Here the Python
twin (core/fastpass/fixedrate.py's `rate_pass`, which the viper twin equals bit for bit) runs on extreme
inputs with every product replaced by the viper twin's split product, checked, and every integer it
computes with checked: any intermediate at 2**31 or beyond raises.
"""

import math
import random

import pytest
from test_fixedrate import _stages, set_attitude  # tests/portable (conftest puts it on the path)

from hoverfly.core.fastpass import fixedrate

_LIMIT = 1 << 31


class I32(int):
    """An int that raises once a result leaves the signed 32-bit range."""

    def _chk(self, v):
        if v is NotImplemented:  # with a float: the float's own operator runs (the encode to float32)
            return v
        if not -_LIMIT <= v < _LIMIT:
            raise OverflowError("32-bit overflow: %d" % v)
        return I32(v)


for _name in ("add", "sub", "mul", "lshift", "rshift", "and", "or", "floordiv"):
    def _make(op):
        def fwd(self, other):
            return self._chk(getattr(int, "__%s__" % op)(self, other))

        def rev(self, other):
            return self._chk(getattr(int, "__r%s__" % op)(self, other))
        return fwd, rev

    _f, _r = _make(_name)
    setattr(I32, "__%s__" % _name, _f)
    setattr(I32, "__r%s__" % _name, _r)
I32.__neg__ = lambda self: self._chk(-int(self))


def _checked_mul(c, x, s):
    """The viper twin's product, step by step, every partial result checked."""
    c = int(c)
    x = int(x)
    assert -(1 << 15) < c < (1 << 15), c
    assert -_LIMIT < x < _LIMIT, x
    xh = I32(x >> 16)
    xl = I32(x & 0xFFFF)
    c = I32(c)
    if s <= 16:
        if s:
            return ((c * xh) << (16 - s)) + ((c * xl + (1 << (s - 1))) >> s)
        return ((c * xh) << 16) + c * xl
    return (c * xh + ((c * xl) >> 16) + (1 << (s - 17))) >> (s - 16)


@pytest.fixture
def checked(monkeypatch):
    plain_dec = fixedrate._dec

    def dec(x, scale, lim):
        return I32(plain_dec(x, scale, lim))

    monkeypatch.setattr(fixedrate, "_mul", _checked_mul)
    monkeypatch.setattr(fixedrate, "_dec", dec)


# The largest gains and limits the parameters allow, and the settings that open each path.
_EXTREME = (
    (("p_roll", 250), ("i_roll", 250), ("d_roll", 250), ("f_roll", 1000), ("p_pitch", 250), ("i_pitch", 250),
     ("d_pitch", 250), ("f_pitch", 1000), ("p_yaw", 250), ("i_yaw", 250), ("d_yaw", 250), ("f_yaw", 1000),
     ("ff_static_pct", 100.0), ("iterm_limit", 500), ("pidsum_limit", 1000), ("pidsum_limit_yaw", 1000),
     ("angle_p_gain", 300), ("angle_ff", 200), ("angle_rate_limit", 2000), ("horizon_level", 100),
     ("tpa_mode", "pd"), ("tpa_rate", 100), ("tpa_breakpoint", 1999), ("iterm_relax", "off"),
     ("dterm_lpf1_type", "pt2"), ("dterm_lpf1_hz", 0), ("mixer_type", "hexx")),
    (("tpa_breakpoint", 750), ("iterm_relax", "rpy"), ("iterm_relax_hz", 50), ("dterm_lpf1_hz", 500)),
)

_WILD = (float("nan"), float("inf"), -float("inf"), 1e30, -1e30, 127.9, -127.9, 5.0, -5.0, 0.0)


@pytest.mark.parametrize("sets", _EXTREME)
def test_no_intermediate_reaches_2_to_the_31_on_extreme_inputs(checked, sets):
    s, c, m, fx, on = _stages(sets)
    assert on
    sp = s.setpoint
    rnd = random.Random(4)
    worst_i = 0
    for n in range(4000):
        wild = n % 3 == 0
        pick = (lambda: rnd.choice(_WILD)) if wild else (lambda: rnd.uniform(-130.0, 130.0))
        sp.throttle_norm = rnd.choice((0.0, 1.0, 1e30, -1e30, float("nan"), rnd.random()))
        sp.roll_angle_rad = pick()
        sp.pitch_angle_rad = pick()
        set_attitude(s.attitude, pick(), pick())
        for k in range(3):
            s.gyro_rad_s[k] = pick()
            sp.rate_rad_s[k] = pick()
            sp.stick_norm[k] = rnd.choice((1.0, -1.0, 0.0, 1e30, float("nan")))
        sp.mode = n % 3
        dt_us = rnd.choice((0, -3, 1, 64, 65, 1000, 19999, 20000, 10 ** 6))
        fx.update(sp, dt_us, rnd.random() < 0.9, rnd.random() < 0.5)
        for v in fx.st:
            assert -_LIMIT <= v < _LIMIT
        for v in s.motor_norm:
            assert 0.0 <= v <= 1.0
        for v in s.torque_norm:
            assert math.isfinite(v) and abs(v) <= 1.0
        worst_i = max(worst_i, abs(fx.st[fixedrate.S_I]))
    assert worst_i > 0  # the I-term did integrate (the I path ran checked)


def test_the_checked_product_is_the_plain_one():
    rnd = random.Random(9)
    for _ in range(20000):
        c = rnd.randrange(-(1 << 15) + 1, 1 << 15)
        x = rnd.randrange(-(1 << 24), 1 << 24)
        s = rnd.randrange(0, 30)
        want = fixedrate._mul(c, x, s)
        if -(1 << 30) <= want < (1 << 30):  # (a result near 2**31 would overflow a partial: the test's bounds)
            assert int(_checked_mul(c, x, s)) == want


def test_a_product_past_32_bits_is_caught(checked):
    with pytest.raises(OverflowError):
        _checked_mul(32767, (1 << 30) - 1, 0)
