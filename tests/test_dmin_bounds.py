"""D-min and anti-gravity in the fixed-point rate loop stay inside 32-bit words, whatever they are fed.

The same check as tests/test_fixedrate_bounds.py (every product the viper twin's split one, every integer
checked against 2**31), with D-min and anti-gravity at the largest gains the parameters allow: throttle
jumps end to end at the shortest pass hold the anti-gravity boost at its cap, gyro and setpoint jumps the
D-min boost at its.
"""

import math
import random

import pytest
from test_fixedrate import _stages, set_attitude  # tests/portable (conftest puts it on the path)

from hoverfly.core.fastpass import fixedrate
from test_fixedrate_bounds import _LIMIT, _WILD, checked  # noqa: F401 (checked: the fixture)

_EXTREME = (
    (("p_roll", 250), ("i_roll", 250), ("d_roll", 250), ("d_min_roll", 1), ("f_roll", 1000),
     ("p_pitch", 250), ("i_pitch", 250), ("d_pitch", 250), ("d_min_pitch", 249), ("d_yaw", 250), ("d_min_yaw", 100),
     ("d_min_gain", 100), ("d_min_advance", 200), ("ag_gain", 250), ("ag_cutoff_hz", 50), ("ag_p_gain", 250),
     ("iterm_limit", 500), ("pidsum_limit", 1000), ("tpa_mode", "pd"), ("iterm_relax", "off"),
     ("dterm_lpf1_type", "pt2"), ("dterm_lpf1_hz", 0), ("angle_p_gain", 300), ("angle_ff", 200)),
    (("d_min_roll", 20), ("ag_gain", 80), ("ag_cutoff_hz", 2), ("iterm_relax", "rpy"), ("dterm_lpf1_hz", 500)),
)


@pytest.mark.parametrize("sets", _EXTREME)
def test_d_min_and_anti_gravity_stay_within_32_bits_on_extreme_inputs(checked, sets):  # noqa: F811
    s, c, m, fx, on = _stages(sets)
    assert on
    sp = s.setpoint
    rnd = random.Random(5)
    peak_ag = 0
    peak_dm = 0
    for n in range(4000):
        wild = n % 3 == 0
        pick = (lambda: rnd.choice(_WILD)) if wild else (lambda: rnd.uniform(-130.0, 130.0))
        sp.throttle_norm = rnd.choice((0.0, 1.0, 0.0, 1.0, 1e30, float("nan"), rnd.random()))
        sp.roll_angle_rad = pick()
        set_attitude(s.attitude, pick(), s.attitude.pitch_rad)
        for k in range(3):
            s.gyro_rad_s[k] = pick()
            sp.rate_rad_s[k] = pick()
        sp.mode = n % 3
        dt_us = rnd.choice((0, 1, 64, 1000, 20000, 10 ** 6))
        fx.update(sp, dt_us, rnd.random() < 0.9, rnd.random() < 0.5)
        for v in fx.st:
            assert -_LIMIT <= v < _LIMIT
        for v in s.torque_norm:
            assert math.isfinite(v) and abs(v) <= 1.0
        peak_ag = max(peak_ag, fx.st[fixedrate.S_AG2])
        peak_dm = max(peak_dm, fx.st[fixedrate.S_DM + 3])
    assert peak_ag > 0 and peak_dm > 0  # both paths ran, checked
