"""The output stage's motor commands in fixed point (core/stages/output.py `motors_fixed`, with the fixed rate
loop) against the float stage, and their viper twin (accel/output.py).

Portable: under MicroPython (tests/portable/mprun.py) the viper twin must be the one chosen and must
give the Python twin's bits and clamp counts; on both runtimes the fixed commands must be within
2**-14 of `OutputStage.update`'s and count the same clamps.
"""

from array import array

from fastpathkit import heap_bytes
from test_fixedrate import Lcg  # the same deterministic numbers on every port

from hoverfly.compat import IS_MICROPYTHON
from hoverfly.core.config.params import Params
from hoverfly.core.stages import output as output_mod
from hoverfly.core.stages.output import OutputStage

if IS_MICROPYTHON:
    from hoverfly.accel import output as output_viper
else:
    output_viper = None

_ODD = (float("nan"), float("inf"), -float("inf"), 1e30, -1e30, -0.0, 0.0, 1e-40, -1e-40, 1.0, 1.0000001,
        0.9999999, 2.0 ** -17, -(2.0 ** -16), 0.5, 1.5)

# seed 001's motor parameters (commands 8-11): motor 3 and 6 disabled, motor 1's floor and motor 2's ceiling
# moved, motor 4's range empty (max below min: held at its min)
_PER_MOTOR = (("motor_enable", 0xDB), ("motor1_min_us", 1200), ("motor2_max_us", 1600), ("motor4_min_us", 1500),
              ("motor4_max_us", 1400))


def _stage(sets=()):
    p = Params()
    for name, value in sets:
        p.set(name, value)
    st = OutputStage()
    st.configure(p, 8)
    return st


def _demands(rnd, n, a, b=None):
    for k in range(8):
        v = rnd.unit() * 1.2 - 0.1
        if n % 3 == 2 and rnd.unit() < 0.5:
            v = _ODD[int(rnd.unit() * len(_ODD))]
        a[k] = v
        if b is not None:
            b[k] = v


def test_the_fixed_commands_agree_with_the_float_stage():
    for sets in ((), (("motor_idle_pct", 0.0), ("motor_max_pct", 50.0)), (("motor_idle_pct", 20.0),), _PER_MOTOR):
        a = _stage(sets)
        b = _stage(sets)
        norm = array("f", [0.0] * 8)
        want = array("f", [0.0] * 8)
        got = array("f", [0.0] * 8)
        rnd = Lcg(17)
        worst = 0.0
        for n in range(400):
            _demands(rnd, n, norm)
            a.update(norm, True, want)
            b.update_fixed(norm, True, got)
            for k in range(8):
                worst = max(worst, abs(want[k] - got[k]))
        assert worst < 2.0 ** -14, (sets, worst)  # the Q14 span, the Q16 demand and idle; a DShot step is 5e-4
        assert a.clamped == b.clamped and a.clamped > 100, (a.clamped, b.clamped)
        b.update_fixed(norm, False, got)  # disarmed: stop, whatever the demand
        assert list(got) == [0.0] * 8


def test_the_viper_twin_gives_the_python_twins_bits():
    if not IS_MICROPYTHON:
        assert OutputStage.update_fixed is OutputStage.update_fixed_python  # no viper: the Python twin runs
        return
    assert OutputStage.update_fixed is output_viper.update_fixed
    for sets in ((), (("motor_idle_pct", 0.0), ("motor_max_pct", 50.0)), (("motor_idle_pct", 20.0),), _PER_MOTOR):
        sa = _stage(sets)
        sb = _stage(sets)
        na, nb = array("f", [0.0] * 8), array("f", [0.0] * 8)
        oa, ob = array("f", [7.0] * 8), array("f", [7.0] * 8)
        rnd = Lcg(23)
        for n in range(1500):
            _demands(rnd, n, na, nb)
            armed = n % 50 != 7
            sa.update_fixed_python(na, armed, oa)
            sb.update_fixed(nb, armed, ob)
            assert sa.clamped == sb.clamped, (sets, n, sa.clamped, sb.clamped)
            for k in range(8):
                assert oa[k] == ob[k], (sets, n, k, na[k], oa[k], ob[k])
        assert sa.clamped > 100
    # every Q16 command's float32 bits (each exponent of the encode): demand c / 65536 with idle 0, span 1
    sa = _stage((("motor_idle_pct", 0.0), ("motor_max_pct", 100.0)))
    sb = _stage((("motor_idle_pct", 0.0), ("motor_max_pct", 100.0)))
    na = array("f", [0.0] * 8)
    oa, ob = array("f", [0.0] * 8), array("f", [0.0] * 8)
    for c in range(0, 65537, 8):
        for k in range(8):
            na[k] = (c + k) / 65536.0
        sa.update_fixed_python(na, True, oa)
        sb.update_fixed(na, True, ob)
        assert list(oa) == list(ob), (c, list(oa), list(ob))


def test_the_clamp_count_saturates_below_2_to_the_31_on_both_twins():
    for st in (_stage(), _stage()):
        st.clamped = 0x3FFFFFFF - 3
        norm = array("f", [2.0] * 8)
        out = array("f", [0.0] * 8)
        st.update_fixed(norm, True, out)
        assert st.clamped == 0x3FFFFFFF + 5
        st.update_fixed(norm, True, out)
        assert st.clamped == 0x3FFFFFFF + 5 and out[0] == 1.0
        st.update_fixed_python(norm, True, out)
        assert st.clamped == 0x3FFFFFFF + 5


def test_fixed_commands_allocate_nothing_on_micropython():
    if not IS_MICROPYTHON:
        return
    st = _stage()
    norm = array("f", [0.3, 0.5, 0.7, 1.2, -0.1, 0.0, 1.0, 0.25])
    out = array("f", [0.0] * 8)
    st.update_fixed(norm, True, out)
    used = heap_bytes(lambda: st.update_fixed(norm, True, out), 50)
    assert used == 0, used


def test_a_flight_takes_the_fixed_commands_with_the_fixed_rate_loop():
    from configfakes import FakeBoard

    from hoverfly.core.flight import Flight

    f = Flight(FakeBoard())
    f.params.set("pid_math", "fixed")
    f.start(1000)
    assert f._fixed_out_on
    f.params.set("pid_math", "float")
    f.configure()
    assert not f._fixed_out_on
    assert output_mod.HAS_ACCEL == IS_MICROPYTHON


def test_per_motor_ranges_bound_the_armed_commands_and_a_disabled_motor_stays_stopped():
    from hoverfly.core.stages.output import OutputEncoder

    p = Params()
    for name, value in _PER_MOTOR + (("motor_protocol", "pwm"), ("motor_pwm_rate", 400)):
        assert p.set(name, value) is None
    enc = OutputEncoder()
    enc.configure(p, 8, 0, 0)
    for update in ("update", "update_fixed", "update_fixed_python"):
        st = OutputStage()
        st.configure(p, 8)
        out = array("f", [0.0] * 8)
        for demand in (0.0, 0.5, 1.0):
            norm = array("f", [demand] * 8)
            getattr(st, update)(norm, True, out)
            enc.write(out, 8, 1000)
            us = enc.pulse_us
            # the PWM pulse of each motor: its own range while armed, the idle floor (5.5 %) elsewhere
            assert abs(us[0] - (1200 + 800 * demand)) < 0.2, (update, demand, list(us))
            assert abs(us[1] - (1055 + 545 * demand)) < 0.2, (update, demand, list(us))
            assert us[2] == 1000.0 and us[5] == 1000.0, (update, demand, list(us))  # disabled: the stop pulse
            assert abs(us[3] - 1500) < 0.2, (update, demand, list(us))
            assert abs(us[4] - (1055 + 945 * demand)) < 0.2, (update, demand, list(us))
        getattr(st, update)(norm, False, out)  # disarmed: every motor its disarmed value, whatever its range
        enc.write(out, 8, 2000)
        assert list(enc.pulse_us) == [1000.0] * 8, (update, list(enc.pulse_us))
