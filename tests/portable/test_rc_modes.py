"""AUX mode ranges of the RC input stage: ARM, ANGLE, HORIZON, AIRMODE and the FAILSAFE box.

Given a parameter set and one receiver frame (µs per channel), the boxes read as Betaflight's
mode ranges: channel (1-based, 0 = none) and min_us <= µs < max_us.
"""

from array import array

from hoverfly.core.config.params import Params
from hoverfly.core.stages.control import MODE_ACRO, MODE_ANGLE, MODE_HORIZON
from hoverfly.core.stages.rc import RcInput


def _rc(**values):
    p = Params()
    for name in values:
        err = p.set(name, values[name])
        assert err is None, err
    rc = RcInput()
    rc.configure(p, 1000)
    return rc


def _frame(**aux):
    """Sticks centred, throttle low; aux: ch5=..., ch6=... in µs."""
    ch = [1500, 1500, 1000, 1500] + [1000] * 12
    for key in aux:
        ch[int(key[2:]) - 1] = aux[key]
    return array("H", ch)  # as the Flight's rc_channels_us


def test_airmode_box_with_no_channel_leaves_the_parameter_to_decide():
    rc = _rc()
    rc.new_frame(_frame(ch7=2000, ch8=2000))
    assert not rc.airmode_box
    assert not rc.airmode_switch


def test_airmode_switch_in_range_is_on_and_out_of_range_off():
    rc = _rc(airmode_ch=8, airmode_min_us=1700, airmode_max_us=2100)
    assert rc.airmode_box
    rc.new_frame(_frame(ch8=2000))
    assert rc.airmode_switch
    rc.new_frame(_frame(ch8=1500))
    assert not rc.airmode_switch
    rc.new_frame(_frame(ch8=1700))  # the range includes its start ...
    assert rc.airmode_switch
    rc.new_frame(_frame(ch8=2100))  # ... but not its end
    assert not rc.airmode_switch


def test_airmode_switch_on_a_channel_the_frame_does_not_carry_reads_off():
    rc = _rc(airmode_ch=18)
    rc.new_frame(_frame())  # 16 channels
    assert rc.airmode_box and not rc.airmode_switch


def test_failsafe_switch_reads_the_raw_frame_in_and_out_of_range():
    rc = _rc(fs_switch_ch=9, fs_switch_min_us=1800, fs_switch_max_us=2100)
    assert rc.fs_switch_in(_frame(ch9=2000))
    assert not rc.fs_switch_in(_frame(ch9=1790))
    assert not rc.fs_switch_in(_frame(ch9=1000))
    assert rc.frames == 0  # reading the switch does not take the frame


def test_failsafe_switch_with_no_channel_never_reads_on():
    rc = _rc()
    for us in (900, 1000, 1500, 2000, 2100):
        assert not rc.fs_switch_in(_frame(ch5=us, ch6=us, ch7=us, ch8=us, ch9=us))


def test_arm_angle_horizon_ranges_and_channel_zero_is_none():
    rc = _rc()
    rc.new_frame(_frame(ch5=2000, ch6=2000))
    assert rc.arm_switch and rc.mode == MODE_ANGLE
    rc.new_frame(_frame(ch5=1000, ch6=1500))
    assert not rc.arm_switch and rc.mode == MODE_HORIZON
    rc.new_frame(_frame(ch6=1000))
    assert rc.mode == MODE_ACRO
    rc = _rc(arm_ch=0, angle_ch=0, horizon_ch=0)
    rc.new_frame(_frame(ch5=2000, ch6=1500))
    assert not rc.arm_switch and rc.mode == MODE_ACRO


def test_set_arm_range_replaces_the_configured_range():
    rc = _rc()
    rc.set_arm_range(5, 1501, 0x10000)  # seed 001: above 1500 µs arms
    rc.new_frame(_frame(ch5=1600))
    assert rc.arm_switch
    rc.new_frame(_frame(ch5=1500))
    assert not rc.arm_switch
    rc.set_arm_range(0, 900, 2100)
    rc.new_frame(_frame(ch5=2000))
    assert not rc.arm_switch


def test_reconfigure_takes_new_ranges():
    p = Params()
    rc = RcInput()
    rc.configure(p, 1000)
    assert not rc.airmode_box
    assert p.set("airmode_ch", 7) is None
    assert p.set("fs_switch_ch", 8) is None
    rc.configure(p, 1000)
    rc.new_frame(_frame(ch7=2000))
    assert rc.airmode_box and rc.airmode_switch
    assert rc.fs_switch_in(_frame(ch8=2000))


def test_autopilot_switch_range_reads_as_the_autopilot_reads_it():
    # the Flight hands RcInput's reading of the autopilot switch to Autopilot.on_pilot_frame: it must be
    # the autopilot's own switch_on() on the same frame, for the default AUX3 range and a moved one
    from hoverfly.core.command.autopilot import Autopilot
    from hoverfly.core.events import EventLog

    for ch, lo, hi in ((7, 1700, 2100), (8, 1300, 1600), (0, 1000, 2100)):
        p = Params()
        assert p.set("ap_ch", ch) is None
        assert p.set("ap_min_us", lo) is None
        assert p.set("ap_max_us", hi) is None
        rc = RcInput()
        rc.configure(p, 1000)
        ap = Autopilot(EventLog())
        ap.configure(p)
        for us in (900, 1299, 1300, 1599, 1600, 1699, 1700, 2099, 2100):
            frame = _frame(ch7=us, ch8=us)
            rc.new_frame(frame)
            ap.pilot_channels = frame
            assert rc.ap_switch == ap.switch_on(), (ch, lo, hi, us)


def test_fs_switch_box_says_whether_a_failsafe_channel_is_set():
    # Flight._rx_frame reads the FAILSAFE box only where a channel is set for it
    assert not _rc().fs_switch_box
    rc = _rc(fs_switch_ch=8)
    assert rc.fs_switch_box and rc.fs_switch_in(_frame(ch8=2000))
