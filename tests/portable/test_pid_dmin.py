"""D-min, anti-gravity and the stick deadband (issue 28): what a Betaflight pilot expects of each, in the
float stages and the fixed-point pass, and the fixed pass's viper twin bit for bit.

Portable: mprun.py runs it under MicroPython (64-bit, and 32-bit with HOVERFLY_MP32), pytest on CPython.
"""

from test_fixedrate import Lcg, _agree, _stages

from hoverfly.compat import IS_MICROPYTHON
from hoverfly.core.config.params import Params
from hoverfly.core.fastpass import fixedrate
from hoverfly.core.signals import Signals
from hoverfly.core.stages import rc as rcmod
from hoverfly.core.stages.control import Controller

_DMIN = (("d_roll", 60), ("d_min_roll", 30), ("d_pitch", 66), ("d_min_pitch", 33), ("d_yaw", 20), ("d_min_yaw", 8),
         ("d_min_gain", 45), ("d_min_advance", 60))
_AG = (("ag_gain", 80), ("ag_cutoff_hz", 5), ("ag_p_gain", 100))


def _controller(sets):
    p = Params()
    for name, value in sets:
        assert p.set(name, value) is None, name
    s = Signals()
    c = Controller(s.pid_terms)
    c.configure(p, 1000)
    return s, c


def _fly(c, s, passes, rate_sp=0.0, gyro=0.0, throttle=0.5):
    sp = s.setpoint
    sp.mode = 0
    sp.throttle_norm = throttle
    for k in range(3):
        sp.rate_rad_s[k] = rate_sp
        s.gyro_rad_s[k] = gyro
    for _ in range(passes):
        c.update(sp, s.attitude, s.gyro_rad_s, 0.001, True, False, s.torque_norm)


def test_d_min_holds_d_at_d_min_at_rest():
    s, c = _controller(_DMIN)
    _fly(c, s, 300)
    assert abs(c.roll.dmin_factor - 0.5) < 1e-3, c.roll.dmin_factor  # 30 of 60
    assert abs(c.yaw.dmin_factor - 0.4) < 1e-3, c.yaw.dmin_factor


def test_d_min_raises_d_towards_d_max_on_a_fast_stick_move_before_the_gyro_moves():
    s, c = _controller(_DMIN)
    _fly(c, s, 300)
    sp = s.setpoint
    peak = 0.0
    # the stick swept to 600 deg/s over 50 ms: the setpoint accelerates at 200 rad/s², the gyro not yet
    for n in range(50):
        sp.rate_rad_s[0] = 10.47 * (n + 1) / 50
        c.update(sp, s.attitude, s.gyro_rad_s, 0.001, True, False, s.torque_norm)
        peak = max(peak, c.roll.dmin_factor)
    assert peak > 0.8, peak  # D most of the way to D max while the stick moves
    _fly(c, s, 400, rate_sp=10.47)  # held: D falls back to rest
    assert abs(c.roll.dmin_factor - 0.5) < 0.02, c.roll.dmin_factor


def test_d_min_raises_d_on_gyro_shake_alone():
    s, c = _controller(_DMIN)
    _fly(c, s, 300)
    peak = 0.0
    for n in range(100):  # propwash: the gyro shaking at 50 Hz, +-60 deg/s, sticks still
        s.gyro_rad_s[0] = 1.05 if (n // 10) % 2 else -1.05
        c.update(s.setpoint, s.attitude, s.gyro_rad_s, 0.001, True, False, s.torque_norm)
        peak = max(peak, c.roll.dmin_factor)
    assert peak > 0.9, peak


def test_d_min_off_keeps_d_at_d_max():
    for d_min in (0, 40, 50):  # 0, or not below D max (d_roll 40): off
        sets = (("d_roll", 40), ("d_min_roll", d_min))
        s, c = _controller(sets)
        assert not c.roll.dmin_on, sets
        s.gyro_rad_s[0] = 0.3
        c.update(s.setpoint, s.attitude, s.gyro_rad_s, 0.001, True, False, s.torque_norm)
        assert c.roll.dmin_factor == 1.0


def test_anti_gravity_boosts_i_on_a_fast_throttle_move_and_lets_go_after():
    s, c = _controller(_AG)
    sp = s.setpoint
    sp.mode = 0
    sp.rate_rad_s[0] = 0.2  # a steady error for I to integrate
    sp.throttle_norm = 0.6
    for _ in range(500):
        c.update(sp, s.attitude, s.gyro_rad_s, 0.001, True, False, s.torque_norm)
    assert c.ag_boost < 1e-6
    i0 = c.roll.i
    for _ in range(50):
        c.update(sp, s.attitude, s.gyro_rad_s, 0.001, True, False, s.torque_norm)
    calm = c.roll.i - i0
    # a chop from 60 % to 10 % throttle in 40 ms
    peak = 0.0
    i0 = c.roll.i
    for n in range(50):
        sp.throttle_norm = max(0.1, 0.6 - 0.5 * (n + 1) / 40)
        c.update(sp, s.attitude, s.gyro_rad_s, 0.001, True, False, s.torque_norm)
        peak = max(peak, c.ag_boost)
    boosted = c.roll.i - i0
    assert peak > 2.0, peak
    assert boosted > 1.5 * calm, (boosted, calm)
    assert c.roll.p_boost > 1.0 and c.yaw.p_boost == 1.0  # P on roll and pitch only (Betaflight 4.3)
    for _ in range(2000):
        c.update(sp, s.attitude, s.gyro_rad_s, 0.001, True, False, s.torque_norm)
    assert c.ag_boost < 0.01 and c.roll.i_boost < 1.01


def test_anti_gravity_off_changes_nothing():
    s, c = _controller((("ag_gain", 0),))
    sp = s.setpoint
    for n in range(100):
        sp.throttle_norm = (n % 20) * 0.05
        c.update(sp, s.attitude, s.gyro_rad_s, 0.001, True, False, s.torque_norm)
    assert c.ag_boost == 0.0 and c.roll.i_boost == 1.0 and c.roll.p_boost == 1.0


def test_the_fixed_pass_agrees_with_the_float_stages_with_d_min_and_anti_gravity():
    for sets, mode in ((_DMIN, 0), (_AG, 1), (_DMIN + _AG, 0), (_DMIN + _AG + (("dterm_lpf1_type", "pt2"),), 2)):
        worst, flags = _agree(sets, mode, passes=400)
        assert worst[0] < 4e-4, (sets, mode, worst)
        assert worst[1] < 2e-6, (sets, mode, worst)
        assert worst[2] < 6e-4, (sets, mode, worst)
        assert flags > 0


def test_the_fixed_pass_hands_d_min_and_anti_gravity_state_back():
    s, c, m, fx, on = _stages(_DMIN + _AG)
    sp = s.setpoint
    rnd = Lcg(9)
    for _ in range(200):
        sp.throttle_norm = 0.3 + 0.3 * rnd.unit()
        for k in range(3):
            s.gyro_rad_s[k] = rnd.span(3.0)
            sp.rate_rad_s[k] = rnd.span(3.0)
        fx.update(sp, 1000, True, True)
    fx.give_state()
    st = fx.st
    assert abs(c.roll.dmin_lowpass.y - st[fixedrate.S_DM + 3] / 32768.0) < 1e-6
    assert c.roll.dmin_lowpass.y > 0.5
    assert abs(c.ag_filter.y - st[fixedrate.S_AG2] / 4096.0) < 1e-6
    assert c.ag_filter.y > 0.0


def test_the_viper_twin_gives_the_python_twins_bits_with_d_min_and_anti_gravity():
    if not IS_MICROPYTHON:
        return
    for sets in (_DMIN + _AG, _DMIN + _AG + (("dterm_lpf1_type", "pt2"), ("tpa_mode", "pd"), ("ag_gain", 250),
                                             ("d_min_gain", 100), ("d_min_advance", 200))):
        sa, ca, ma, fa, on = _stages(sets)
        sb, cb, mb, fb, on = _stages(sets)
        rnd = Lcg(21)
        for n in range(1200):
            thr = rnd.unit() * 1.1 if n % 3 else (0.0 if n % 2 else 1.0)  # throttle jumps: the boost at its cap
            for s in (sa, sb):
                s.setpoint.throttle_norm = thr
            for arr in range(2):
                for k in range(3):
                    v = rnd.span(40.0 if n % 7 == 0 else 3.0)
                    for s in (sa, sb):
                        (s.gyro_rad_s, s.setpoint.rate_rad_s)[arr][k] = v
            i_active = rnd.unit() > 0.1
            airmode = rnd.unit() > 0.5
            dt_us = (1000, 999, 64, 20000, 125)[n % 5]
            sa.setpoint.mode = sb.setpoint.mode = 0
            fixedrate.update_python(fa, sa.setpoint, dt_us, i_active, airmode)
            fb.update(sb.setpoint, dt_us, i_active, airmode)
            for k in range(fixedrate.ST_SIZE):
                assert fa.st[k] == fb.st[k], (n, "st", k, fa.st[k], fb.st[k])
            for name in ("pid_terms", "torque_norm", "motor_norm"):
                a = getattr(sa, name)
                b = getattr(sb, name)
                for k in range(len(a)):
                    assert a[k] == b[k], (n, name, k, a[k], b[k])


def test_the_deadband_is_taken_out_and_the_rest_rescaled_so_full_stick_is_full_rate():
    # Betaflight's: (us - 1500 - deadband) / (500 - deadband). A held stick reads exactly that on both paths:
    # no step at the deadband's edge, full stick is 1.0
    rc = rcmod.RcInput()
    for db in (0, 5, 32):
        for us in range(1000, 2001):
            d = us - 1500
            if d > db:
                want = (d - db) / (500.0 - db)
            elif d < -db:
                want = (d + db) / (500.0 - db)
            else:
                want = 0.0
            got = rc._stick(us, db)
            assert abs(got - want) < 1e-9, (db, us, got, want)
            q = rcmod._stick_q(us, db)
            assert abs(q / 1048576.0 - want) <= 0.5 / 1048576.0 + 1e-12, (db, us, q, want)
        assert rc._stick(2000, db) == 1.0 and rc._stick(1000, db) == -1.0
        assert rcmod._stick_q(2000, db) == 1048576
    # a stick held at 1881 us with the 5 us deadband: 376 of 495
    assert abs(rc._stick(1881, 5) - 376.0 / 495.0) < 1e-12


def test_anti_gravity_counts_no_take_off_punch_while_i_is_held_off():
    # below airmode_thr_pct I is off (i_active False): the throttle's jump to flight must not boost it
    s, c = _controller(_AG)
    sp = s.setpoint
    sp.mode = 0
    for n in range(40):
        sp.throttle_norm = min(0.3, n * 0.02)
        c.update(sp, s.attitude, s.gyro_rad_s, 0.001, False, False, s.torque_norm)
        assert c.ag_boost == 0.0 and c.roll.i_boost == 1.0
    c.update(sp, s.attitude, s.gyro_rad_s, 0.001, True, False, s.torque_norm)  # I starts at a steady throttle
    assert c.ag_boost < 1e-6
