"""Seed 001's control law options in the RC stage (issue 25): the channel map (Betaflight's `map`, rc_map),
the angle limit down to 5 deg, an alpha-beta pair per stick and the yaw heading hold; and the CLI's `map`.

Portable: the same functions run under MicroPython (tests/portable/mprun.py), where the fixed-point stage
and its viper twin read the sticks.
"""

import math
from array import array

from configfakes import make_flight
from fastpathkit import params as _params

from hoverfly.core.config.params import rc_map_error
from hoverfly.core.links.cliserver import CliServer
from hoverfly.core.signals import Setpoint
from hoverfly.core.stages.rc import MAP_LETTERS, RcInput, map_channels, map_text, map_value

_DEG = math.pi / 180.0


def _rc(**kw):
    rc = RcInput()
    rc.configure(_params(**kw), 1000)
    return rc


def _each_permutation(letters, fn):
    """fn(text) for every ordering of `letters` (Heap's algorithm, in place: no list of 40 320 strings on a
    small heap, no itertools on MicroPython); returns how many."""
    a = list(letters)
    n = len(a)
    c = [0] * n
    fn("".join(a))
    count = 1
    i = 0
    while i < n:
        if c[i] < i:
            j = 0 if i % 2 == 0 else c[i]
            a[j], a[i] = a[i], a[j]
            fn("".join(a))
            count += 1
            c[i] += 1
            i = 0
        else:
            c[i] = 0
            i += 1
    return count


def _frame_for(text, roll_us, pitch_us, yaw_us, throttle_us, aux_us=(1000, 1000, 1000, 1000)):
    """The receiver frame a transmitter mapped as `text` (Betaflight map letters) sends."""
    ch = array("H", [1500] * 16)
    by_letter = {"A": roll_us, "E": pitch_us, "R": yaw_us, "T": throttle_us,
                 "1": aux_us[0], "2": aux_us[1], "3": aux_us[2], "4": aux_us[3]}
    for i in range(8):
        ch[i] = by_letter[text[i]]
    return ch


# ----------------------------------------------------------------------------- the map
def test_every_permutation_of_aetr1234_round_trips_through_rc_map():
    texts = {}

    def check(text):
        value, err = map_value(text)
        assert err is None, (text, err)
        assert rc_map_error(value) is None, text
        # back to the same letters: so no two maps share a value
        assert map_text(value) == text, (text, value)
        if len(texts) < 100:
            texts[text] = True

    assert _each_permutation("AETR1234", check) == 40320
    assert len(texts) == 100  # distinct orderings, not one repeated


def test_betaflight_map_letters_name_the_function_of_each_receiver_channel():
    assert map_value("AETR1234") == (12435678, None)  # the default: rc_map's digits per roll pitch yaw thr
    assert map_value("taer1234") == (23415678, None)  # any case
    assert map_value("AERT1234") == (12345678, None)  # seed 001's FlySky: yaw on 3, throttle on 4
    assert map_channels(23415678) == [1, 2, 3, 0, 4, 5, 6, 7]
    assert MAP_LETTERS == "AERT1234"  # rcmap's order: roll, pitch, yaw, throttle, AUX1..4


def test_a_map_that_is_no_permutation_is_refused_with_a_one_line_reason():
    for text, words in (("AETR123", "8 letters"), ("AETR12345", "8 letters"), ("AETX1234", "'X'"),
                        ("AATR1234", "twice"), ("", "8 letters")):
        value, err = map_value(text)
        assert value is None and words in err and "\n" not in err, (text, err)
    p = _params()
    for bad in (12345677, 11345678, 12345688, 92345678, 12345670):
        err = p.set("rc_map", bad)
        assert err is not None and "\n" not in err, bad
        assert p.get("rc_map") == 12435678  # nothing changed
    assert "rc_map = 12345688 must name each channel 1..8 once" in rc_map_error(12345688)


def test_sticks_are_read_from_the_channels_the_map_names():
    for text in ("AETR1234", "TAER1234", "AERT1234", "1234AETR", "R4T3E2A1", "4321TREA"):
        value, _ = map_value(text)
        for math_kind in ("float", "fixed"):
            rc = _rc(rc_map=value, pid_math=math_kind)
            # full right roll, full back pitch (nose up: + in FRD), yaw right of centre, throttle 30 %
            rc.new_frame(_frame_for(text, 2000, 1000, 1750, 1300))
            assert abs(rc.stick_raw[0] - 1.0) < 1e-5, (text, math_kind, rc.stick_raw)
            assert abs(rc.stick_raw[1] - 1.0) < 1e-5, (text, math_kind)
            assert abs(rc.stick_raw[2] - 245 / 495) < 1e-5, (text, math_kind)
            assert rc.throttle_us == 1300 and abs(rc.throttle_raw - 0.3) < 1e-6, (text, math_kind)


def test_aux_switches_are_read_where_the_map_puts_their_letter():
    # AUX1 on receiver channel 8, AUX2 on channel 5: arm_ch = 5 (AUX1), angle_ch = 6 (AUX2) follow them
    text = "AETR2341"
    value, _ = map_value(text)
    rc = _rc(rc_map=value, arm_ch=5, angle_ch=6, horizon_ch=0)
    rc.new_frame(_frame_for(text, 1500, 1500, 1500, 1000, aux_us=(2000, 2000, 1000, 1000)))
    assert rc.arm_switch and rc.mode == 1  # MODE_ANGLE
    frame = _frame_for(text, 1500, 1500, 1500, 1000, aux_us=(1000, 1000, 1000, 1000))
    frame[4] = 2000  # receiver channel 5 (AUX2 in this map) high: not the arm switch
    rc.new_frame(frame)
    assert not rc.arm_switch and rc.mode == 1
    rc.set_arm_range(5, 1501, 0x10000)  # seed 001's arm rule keeps the map too
    rc.new_frame(_frame_for(text, 1500, 1500, 1500, 1000, aux_us=(1600, 1000, 1000, 1000)))
    assert rc.arm_switch


# ------------------------------------------------------------------------- angle limit
def test_an_angle_limit_of_5_deg_gives_5_deg_at_full_stick():
    assert _params().set("angle_limit", 5) is None
    assert "out of range" in _params().set("angle_limit", 4)
    for math_kind in ("float", "fixed"):
        rc = _rc(angle_limit=5, pid_math=math_kind)
        sp = Setpoint()
        rc.new_frame(_frame_for("AETR1234", 2000, 1000, 1500, 1000))
        for _ in range(300):
            rc.update(sp)
        assert abs(sp.roll_angle_rad - 5 * _DEG) < 1e-4, (math_kind, sp.roll_angle_rad / _DEG)
        assert abs(sp.pitch_angle_rad - 5 * _DEG) < 1e-4, (math_kind, sp.pitch_angle_rad / _DEG)
        rc.new_frame(_frame_for("AETR1234", 1750, 1500, 1500, 1000))
        for _ in range(300):
            rc.update(sp)
        assert abs(sp.roll_angle_rad - 2.5 * 245 / 247.5 * _DEG) < 1e-4, math_kind  # half stick, past the deadband


# ---------------------------------------------------------------------- alpha-beta per stick
def test_each_stick_has_its_own_alpha_beta_pair():
    rc = _rc(rc_smooth_type="alphabeta", ab_roll_alpha=1.0, ab_roll_beta=0.0, ab_pitch_alpha=0.05,
             ab_pitch_beta=0.0, ab_yaw_alpha=0.2, ab_yaw_beta=0.0, ab_thr_alpha=0.5, ab_thr_beta=0.0)
    assert not rc.fixed  # the fixed-point stage is the PT2's only: alpha-beta runs the float stage
    sp = Setpoint()
    rc.new_frame(_frame_for("AETR1234", 2000, 1000, 2000, 2000))
    rc.update(sp)
    assert abs(sp.stick_norm[0] - 1.0) < 1e-6  # alpha 1, beta 0: passes straight through
    assert abs(sp.stick_norm[1] - 0.05) < 1e-6  # each pass takes alpha of the residual
    assert abs(sp.stick_norm[2] - 0.2) < 1e-6
    assert abs(sp.throttle_norm - 0.5) < 1e-6
    rc = _rc(rc_smooth_type="alphabeta", ab_roll_alpha=0.1, ab_roll_beta=0.01)
    rc.new_frame(_frame_for("AETR1234", 2000, 1500, 1500, 1000))
    for _ in range(2000):
        rc.update(sp)
    assert abs(sp.stick_norm[0] - 1.0) < 1e-3  # a velocity term too, and it settles on the stick


# -------------------------------------------------------------------------- heading hold
def test_heading_hold_steers_back_to_the_heading_held_since_arming():
    for math_kind in ("float", "fixed"):
        rc = _rc(yaw_hold=1, yaw_hold_p=2.0, pid_math=math_kind)
        sp = Setpoint()
        rc.new_frame(_frame_for("AETR1234", 1500, 1500, 1500, 1400))
        rc.hold_heading(False, 0.7)  # disarmed: the heading to hold follows the craft
        rc.update(sp)
        assert not rc.holding and sp.rate_rad_s[2] == 0.0
        rc.hold_heading(True, 0.7)  # armed at 0.7 rad
        rc.hold_heading(True, 0.8)  # pushed 0.1 rad right: steer left at 2 rad/s per rad
        rc.update(sp)
        assert rc.holding and abs(sp.rate_rad_s[2] + 0.2) < 1e-6, (math_kind, sp.rate_rad_s[2])
        # the pilot yaws: the stick's rate, and the heading follows; centred again, the new heading holds
        rc.new_frame(_frame_for("AETR1234", 1500, 1500, 1800, 1400))
        rc.hold_heading(True, 1.5)
        rc.update(sp)
        assert not rc.holding and sp.rate_rad_s[2] > 0.0
        rc.new_frame(_frame_for("AETR1234", 1500, 1500, 1500, 1400))
        rc.hold_heading(True, 2.0)
        rc.hold_heading(True, 1.9)
        rc.update(sp)
        assert abs(sp.rate_rad_s[2] - 0.2) < 1e-6, math_kind


def test_heading_hold_turns_the_short_way_across_180_deg_and_is_capped():
    rc = _rc(yaw_hold=1, yaw_hold_p=2.0)
    rc.new_frame(_frame_for("AETR1234", 1500, 1500, 1500, 1400))
    rc.hold_heading(True, 3.1)
    rc.hold_heading(True, -3.1)  # 0.083 rad past 180 deg: back left, not 6.2 rad right
    assert abs(rc.hold_rate_rad_s + 2.0 * (2 * math.pi - 6.2)) < 1e-6
    rc = _rc(yaw_hold=1, yaw_hold_p=20.0, yaw_srate=20)
    rc.new_frame(_frame_for("AETR1234", 1500, 1500, 1500, 1400))
    rc.hold_heading(True, 0.0)
    rc.hold_heading(True, 3.0)
    assert abs(rc.hold_rate_rad_s + rc.rates[2].rate_rad_s(1.0)) < 1e-6  # no faster than full yaw stick


def test_with_the_hold_off_the_yaw_rate_is_the_sticks():
    rc = _rc(yaw_hold=1)
    rc.configure(_params(yaw_hold=0), 1000)  # on, then off: the plain update() again
    sp = Setpoint()
    rc.new_frame(_frame_for("AETR1234", 1500, 1500, 1500, 1400))
    rc.holding = True
    rc.hold_rate_rad_s = 1.0
    rc.update(sp)
    assert sp.rate_rad_s[2] == 0.0


# ------------------------------------------------------------------------------ CLI map
def _cli():
    flight, _ = make_flight()
    cli = CliServer(flight)
    cli.enter(lambda b: None)
    return cli, flight


def _type(cli, text):
    out = []
    data = text.encode()
    cli.feed(data, len(data), out.append)
    return b"".join(out).decode()


def test_cli_map_prints_and_sets_the_map_as_betaflight_does():
    cli, f = _cli()
    assert "map AETR1234" in _type(cli, "map\r")
    text = _type(cli, "map AERT1234\r")
    assert "map AERT1234" in text and f.params.get("rc_map") == 12345678
    assert "map TAER1234" in _type(cli, "map taer1234\r")
    assert f.params.get("rc_map") == 23415678
    for bad in ("map AETR12\r", "map AETR1233\r", "map QWERTYUI\r"):
        text = _type(cli, bad)
        assert "###ERROR: map" in text and f.params.get("rc_map") == 23415678, (bad, text)
    f.arming.armed = True
    assert "refused while armed" in _type(cli, "map AETR1234\r")
    assert f.params.get("rc_map") == 23415678


# -------------------------------------------------------------------------------- MSP
def _msp():
    from hoverfly.core.links.mspserver import MspServer

    flight, _ = make_flight()
    return MspServer(flight), flight


def _msp_ask(server, cmd, payload=b""):
    from hoverfly.protocols import msp

    out = []
    frame = msp.encode_request(cmd, payload)
    server.feed(frame, len(frame), out.append)
    p = msp.MspParser()
    for chunk in out:
        p.feed(chunk)
    assert p.pop(), "no reply"
    return p.direction, p.message()


def test_msp_rx_map_reads_and_writes_the_map_as_betaflight_does():
    from hoverfly.core.links.mspserver import MSP_RX_MAP, MSP_SET_RX_MAP
    from hoverfly.protocols import msp

    s, f = _msp()
    assert _msp_ask(s, MSP_RX_MAP) == (msp.DIR_REPLY, bytes([0, 1, 3, 2, 4, 5, 6, 7]))  # AETR1234
    assert _msp_ask(s, MSP_SET_RX_MAP, bytes([0, 1, 2, 3, 4, 5, 6, 7]))[0] == msp.DIR_REPLY  # AERT1234
    assert f.params.get("rc_map") == 12345678
    for bad in (bytes([0, 1, 2, 3, 4, 5, 6, 6]), bytes([0, 1, 2, 3, 4, 5, 6, 8]), bytes([0, 1, 2])):
        assert _msp_ask(s, MSP_SET_RX_MAP, bad)[0] == msp.DIR_ERROR, bad
        assert f.params.get("rc_map") == 12345678
    f.arming.armed = True
    assert _msp_ask(s, MSP_SET_RX_MAP, bytes([1, 2, 3, 0, 4, 5, 6, 7]))[0] == msp.DIR_ERROR
    assert f.params.get("rc_map") == 12345678


def test_msp_rc_reports_sticks_and_aux_in_betaflight_order_whatever_the_map():
    from hoverfly.protocols import msp

    s, f = _msp()
    text = "1234AETR"  # the sticks on receiver channels 5..8, AUX1..4 on 1..4
    f.params.set("rc_map", map_value(text)[0])
    f.rc.configure(f.params, 1000)
    ch = _frame_for(text, 1100, 1200, 1300, 1400, aux_us=(1501, 1502, 1503, 1504))
    for i in range(16):
        f.signals.rc_channels_us[i] = ch[i]
    got = msp.unpack_rc(_msp_ask(s, msp.MSP_RC)[1])
    assert list(got[:8]) == [1100, 1200, 1300, 1400, 1501, 1502, 1503, 1504]
