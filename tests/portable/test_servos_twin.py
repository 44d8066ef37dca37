"""The servo mixer's kernel (core/stages/servos.py `servo_mix`) against its viper twin (accel/servos.py).

Portable: under MicroPython (tests/portable/mprun.py, the 64- and 32-bit VMs) the viper twin must be the one
the mixer runs and must give the Python kernel's widths and state word for word, over random commands and
throttle, odd floats (NaN, infinities, denormals, values past the range), receiver channels anywhere in
0..65535, odd pass lengths, speed limits and every input kind; and an armed pass must allocate nothing.
"""

from array import array

from fastpathkit import heap_bytes
from test_fixedrate import Lcg  # the same deterministic numbers on every port

from hoverfly.compat import IS_MICROPYTHON
from hoverfly.core.config.params import Params
from hoverfly.core.stages import servos as servos_mod
from hoverfly.core.stages.servos import ServoMixer, servo_mix

_ODD = (float("nan"), float("inf"), -float("inf"), 1e30, -1e30, -0.0, 0.0, 1e-40, -1e-40, 1.0, 1.0000001,
        -1.0000001, 0.9999999, 2.0 ** -20, -(2.0 ** -19), 0.5, -0.75, 3.0)

# every input kind, two rules on a servo, reversed and scaled servos, speed limits from 1 to 255
_TABLES = (
    (("mixer_type", "airplane"),),
    (("mixer_type", "flying_wing"), ("servo0_rate", -100), ("servo1_rate", 37)),
    (("mixer_type", "vtail"), ("servo1_min_us", 1200), ("servo2_max_us", 1700), ("servo0_mid_us", 1520)),
    (("smix0_servo", 0), ("smix0_input", 0), ("smix0_rate", 125), ("smix0_speed", 1),
     ("smix1_servo", 0), ("smix1_input", 24), ("smix1_rate", -73), ("smix1_speed", 255),
     ("smix2_servo", 1), ("smix2_input", 5), ("smix2_rate", 100),
     ("smix3_servo", 1), ("smix3_input", 22), ("smix3_rate", -125), ("smix3_speed", 40),
     ("smix4_servo", 2), ("smix4_input", 27), ("smix4_rate", 33),
     ("smix5_servo", 3), ("smix5_input", 3), ("smix5_rate", 100), ("smix5_speed", 7),
     ("smix6_servo", 3), ("smix6_input", 26), ("smix6_rate", 99), ("servo3_rate", -125),
     ("smix7_servo", 3), ("smix7_input", 8), ("smix7_rate", 125)),
)


def _mixer(sets):
    p = Params()
    for name, value in sets:
        assert p.set(name, value) is None, name
    m = ServoMixer()
    m.configure(p)
    return m


def _commands(rnd, n, tq, ch):
    for k in range(3):
        v = rnd.span(1.3)
        if n % 4 == 3 and rnd.unit() < 0.5:
            v = _ODD[int(rnd.unit() * len(_ODD))]
        tq[k] = v
    for k in range(18):
        ch[k] = 1500 + int(rnd.span(700.0)) if rnd.unit() < 0.95 else int(rnd.unit() * 65535)


def test_the_viper_twin_gives_the_python_kernels_widths_and_state():
    if not IS_MICROPYTHON:
        assert servos_mod._servo_mix is servo_mix  # no viper: the Python kernel runs
        return
    from hoverfly.accel import servos as servos_viper

    assert servos_mod._servo_mix is servos_viper.servo_mix
    for sets in _TABLES:
        m = _mixer(sets)
        plan = m._plan
        sa = array("i", m._st)
        sb = array("i", m._st)
        tq = array("f", [0.0] * 3)
        thr = array("f", [0.0])
        ch = array("H", [1500] * 18)
        oa = array("H", [7] * 8)
        ob = array("H", [7] * 8)
        rnd = Lcg(29)
        for n in range(1500):
            _commands(rnd, n, tq, ch)
            dt = 1000 if n % 9 else (0, 250, 20000, -5, 4000)[n % 5]
            sa[0] = sb[0] = dt
            thr[0] = rnd.unit() * 1.2 - 0.1 if n % 7 else _ODD[n % len(_ODD)]
            servo_mix(tq, thr, ch, plan, sa, oa)
            servos_viper.servo_mix(tq, thr, ch, plan, sb, ob)
            assert list(oa) == list(ob), (sets, n, list(tq), list(oa), list(ob))
            assert list(sa) == list(sb), (sets, n)


def test_an_armed_pass_allocates_nothing_on_micropython():
    if not IS_MICROPYTHON:
        return
    m = _mixer(_TABLES[1])
    tq = array("f", [0.3, -0.2, 0.1])
    m.bind(tq, array("H", [1500] * 18), array("H", [0] * 8))
    m.update(1000, True, 0.5)
    used = heap_bytes(lambda: m.update(1000, True, 0.5), 50)
    assert used == 0, used
