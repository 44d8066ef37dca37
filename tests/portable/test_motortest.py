"""Motor test: disarmed only, props-off acknowledged, capped, expiring, ended by arming or link loss."""

from array import array

from hoverfly.compat import ticks_add
from hoverfly.core.command.motortest import (
    STOP_ARMED,
    STOP_ARMING,
    STOP_EXPIRED,
    STOP_LINK,
    STOP_USER,
    MotorTest,
)
from hoverfly.core.config.params import Params

T0 = ticks_add(0, -500000)  # the test crosses the tick wrap


class _Arming:
    def __init__(self):
        self.armed = False


def _test(**values):
    p = Params()
    for name in values:
        assert p.set(name, values[name]) is None
    arming = _Arming()
    mt = MotorTest(arming)
    mt.configure(p, 4)
    return mt, arming


def _out():
    return array("f", [0.0] * 8)


def test_motor_test_spins_the_chosen_motor_while_disarmed():
    mt, _ = _test()
    assert mt.request(T0, 2, 0.2, True) is None
    assert mt.active
    out = _out()
    assert mt.update(ticks_add(T0, 1000), False, False, True, out)
    assert list(out[:4]) == [0.0, 0.0, out[2], 0.0] and abs(out[2] - 0.2) < 1e-6


def test_index_minus_one_sets_every_motor():
    mt, _ = _test()
    assert mt.request(T0, -1, 0.1, True) is None
    out = _out()
    mt.update(T0, False, False, True, out)
    assert all(abs(out[i] - 0.1) < 1e-6 for i in range(4))


def test_refused_while_armed():
    mt, arming = _test()
    arming.armed = True
    why = mt.request(T0, 0, 0.2, True)
    assert isinstance(why, str) and "armed" in why
    assert not mt.active and mt.refused == 1


def test_refused_without_the_props_off_acknowledgement():
    mt, _ = _test()
    for ack in (False, None, 1, "yes"):
        why = mt.request(T0, 0, 0.2, ack)
        assert isinstance(why, str) and "props" in why
    assert not mt.active and mt.refused == 4


def test_refused_while_the_arm_switch_is_on():
    mt, _ = _test()
    mt.update(T0, False, True, True, _out())
    assert "arm switch" in mt.request(T0, 0, 0.2, True)


def test_bad_index_or_value_is_refused_not_wrapped():
    mt, _ = _test()
    for index, value in ((4, 0.1), (-2, 0.1), (0, -0.1), (0, 1.5), (0, float("nan")), (0, True), (0, "0.5")):
        assert isinstance(mt.request(T0, index, value, True), str), (index, value)
    assert not mt.active


def test_value_is_capped_by_the_parameter_and_counted():
    mt, _ = _test(motor_test_pct=25.0)
    assert mt.request(T0, 0, 0.9, True) is None
    out = _out()
    mt.update(T0, False, False, True, out)
    assert abs(out[0] - 0.25) < 1e-6 and mt.capped == 1


def test_small_values_are_raised_to_idle():
    mt, _ = _test(motor_idle_pct=5.5)
    mt.request(T0, 1, 0.01, True)
    out = _out()
    mt.update(T0, False, False, True, out)
    assert abs(out[1] - 0.055) < 1e-6


def test_command_expires_unless_refreshed_within_one_second():
    mt, _ = _test()
    mt.request(T0, 0, 0.2, True)
    mt.request(ticks_add(T0, 600000), 1, 0.2, True)
    out = _out()
    assert mt.update(ticks_add(T0, 1000000), False, False, True, out)  # 1 s exactly: still on
    assert out[0] > 0.0
    out = _out()
    assert mt.update(ticks_add(T0, 1000001), False, False, True, out)  # motor 0 expired, motor 1 not
    assert out[0] == 0.0 and out[1] > 0.0
    mt.request(ticks_add(T0, 1500000), 1, 0.2, True)  # refreshed
    assert mt.update(ticks_add(T0, 2400000), False, False, True, _out())
    assert not mt.update(ticks_add(T0, 2500001), False, False, True, _out())
    assert not mt.active and mt.stop_reason == STOP_EXPIRED


def test_arming_attempt_ends_the_test():
    mt, _ = _test()
    mt.request(T0, -1, 0.2, True)
    out = _out()
    assert not mt.update(T0, False, True, True, out)  # arm switch turned on
    assert not mt.active and mt.stop_reason == STOP_ARMING
    assert list(out[:4]) == [0.0] * 4


def test_being_armed_ends_the_test():
    mt, _ = _test()
    mt.request(T0, -1, 0.2, True)
    assert not mt.update(T0, True, False, True, _out())
    assert mt.stop_reason == STOP_ARMED


def test_receiver_link_loss_ends_the_test_but_no_receiver_at_all_does_not():
    mt, _ = _test()
    mt.update(T0, False, False, False, _out())  # bench, no receiver
    mt.request(T0, 0, 0.2, True)
    assert mt.update(T0, False, False, False, _out())
    mt.update(T0, False, False, True, _out())  # link comes up
    assert not mt.update(T0, False, False, False, _out())  # and is lost
    assert mt.stop_reason == STOP_LINK


def test_stop_and_zero_values_end_the_test():
    mt, _ = _test()
    mt.request(T0, -1, 0.2, True)
    mt.stop(STOP_LINK)
    assert not mt.active and mt.stop_reason == STOP_LINK
    mt.request(T0, 0, 0.2, True)
    mt.request(T0, 0, 0.0, True)
    assert not mt.active and mt.stop_reason == STOP_USER
