"""The pass's glue stages (RC smoothing, output stage, DShot encoder, MPU-6050 decode) equal the
plain formulas they replace, bit for bit.

The speed work there saves calls, lookups and float results on MicroPython: an RC filter sitting
still on an unchanged input is not run, DShot's per-motor value is computed inline, the output
span is kept from configure(). Each stage is driven with varied inputs (steps, holds long enough
for the filters to settle, both signs of zero, NaN, out-of-range) beside a reference written the
plain way (the shapes the stages had before), and the outputs must be the same bits
(struct-packed, so -0.0 and 0.0 differ). Portable: runs under pytest and tests/portable/mprun.py.
"""

import struct
from array import array

from fastpathkit import Rand as _Rand
from fastpathkit import params as _params

from hoverfly.core.signals import Setpoint
from hoverfly.core.stages.output import OutputEncoder, OutputStage
from hoverfly.core.stages.rc import RcInput
from hoverfly.drivers.imu import signed16
from hoverfly.drivers.mpu6050 import MPU6050, WHO_AM_I_VALUE
from hoverfly.drivers.orientation import Orientation
from hoverfly.protocols.dshot import VALUE_MAX, DshotEncoder, dshot_frame


def _bits_f(a, n):
    """The float32 bits of a[0..n-1] (array('f'))."""
    return [struct.pack("<f", a[i]) for i in range(n)]


def _bits(x):
    return struct.pack("<d", x)


# ------------------------------------------------------------------------------------- RC input
class _RcRef:
    """RcInput.update as it was: every filter run every pass, fill_setpoint's curve on the stored sticks."""

    def __init__(self, rc, params):
        # Its own filters, configured from the same parameters (filters.py's plain classes); a PT2's
        # state is copied from rc's, so the two can start mid-flight.
        twin = RcInput()
        twin.configure(params, 1000)
        self.filters = twin.filters
        if params.get("rc_smooth_type") == "pt2":
            for i in range(4):
                self.filters[i].s1 = rc.filters[i].s1
                self.filters[i].y = rc.filters[i].y
        self.rates = twin.rates
        self.angle_limit_rad = twin.angle_limit_rad

    def update(self, stick_raw, throttle_raw, sp):
        f = self.filters
        s = sp.stick_norm
        s[0] = f[0].update(stick_raw[0])
        s[1] = f[1].update(stick_raw[1])
        s[2] = f[2].update(stick_raw[2])
        sp.throttle_norm = f[3].update(throttle_raw)
        r = sp.rate_rad_s
        r[0] = self.rates[0].rate_rad_s(s[0])
        r[1] = self.rates[1].rate_rad_s(s[1])
        r[2] = self.rates[2].rate_rad_s(s[2])
        sp.roll_angle_rad = s[0] * self.angle_limit_rad
        sp.pitch_angle_rad = s[1] * self.angle_limit_rad


def _same_setpoint(a, b):
    return (_bits_f(a.stick_norm, 3) == _bits_f(b.stick_norm, 3)
            and _bits_f(a.rate_rad_s, 3) == _bits_f(b.rate_rad_s, 3)
            and _bits(a.throttle_norm) == _bits(b.throttle_norm) and _bits(a.roll_angle_rad) == _bits(b.roll_angle_rad)
            and _bits(a.pitch_angle_rad) == _bits(b.pitch_angle_rad))


def _rc_inputs():
    """(roll, pitch, yaw, throttle, passes) holds: steps, long holds (the filters settle), signed zeros, NaN."""
    nan = float("nan")
    return (
        (0.0, -0.0, 0.0, 0.0, 300),
        (0.3, -0.0, 0.0, 0.4, 700),  # settles
        (0.3, 0.0, -0.0, 0.4, 50),  # zero changes sign under a settled filter
        (0.3, -0.25, 1.0, 0.4, 5),
        (0.31, -0.25, 1.0, 0.4, 3),
        (0.3, -0.25, 1.0, 0.4, 1),
        (0.31, -0.25, 1.0, 0.4, 700),
        (-1.0, 1.0, -1.0, 1.0, 400),
        (-0.0, -0.0, -0.0, 0.0, 2000),  # decays to zero (and through the subnormals)
        (0.0, 0.0, 0.0, 0.0, 30),
        (nan, 0.5, 0.0, 0.5, 4),
        (0.2, 0.5, 0.0, 0.5, 40),
    )


def test_rc_update_equals_running_every_filter_every_pass():
    for kw in ({}, {"rc_smoothing_hz": 0}, {"rc_smoothing_hz": 150, "roll_expo": 40, "angle_limit": 45}):
        rc = RcInput()
        p = _params(pid_math="float", **kw)  # the float stage (test_rc_fixed.py: the fixed one)
        rc.configure(p, 1000)
        ref = _RcRef(rc, p)
        sp = Setpoint()
        sp_ref = Setpoint()
        k = 0
        for roll, pitch, yaw, thr, passes in _rc_inputs():
            for _ in range(passes):
                rc.stick_raw[0] = roll
                rc.stick_raw[1] = pitch
                rc.stick_raw[2] = yaw
                rc.throttle_raw = thr
                rc.update(sp)
                ref.update(rc.stick_raw, thr, sp_ref)
                assert _same_setpoint(sp, sp_ref), (kw, k, roll, pitch, yaw, thr)
                # another stage (failsafe, autopilot) may overwrite the setpoint after rc.update
                sp.stick_norm[0] = 0.5
                sp.rate_rad_s[1] = 0.5
                sp.throttle_norm = 0.5
                sp.roll_angle_rad = 0.5
                k += 1


def test_rc_update_follows_a_new_configuration_and_a_reset():
    rc = RcInput()
    rc.configure(_params(pid_math="float"), 1000)
    sp = Setpoint()
    sp_ref = Setpoint()
    for _ in range(800):  # settle on a held stick
        rc.stick_raw[0] = 0.4
        rc.update(sp)
    p = _params(angle_limit=30, roll_srate=90, rc_smoothing_hz=80, pid_math="float")
    rc.configure(p, 1000)
    ref = _RcRef(rc, p)
    for _ in range(50):
        rc.update(sp)
        ref.update(rc.stick_raw, rc.throttle_raw, sp_ref)
        assert _same_setpoint(sp, sp_ref)
    rc.stick_raw[1] = -0.2
    rc.reset_smoothing()
    ref = _RcRef(rc, p)
    for _ in range(50):
        rc.update(sp)
        ref.update(rc.stick_raw, rc.throttle_raw, sp_ref)
        assert _same_setpoint(sp, sp_ref)


def test_rc_update_with_other_smoothing_is_the_plain_chain():
    for kind in ("pt1", "alphabeta"):
        rc = RcInput()
        p = _params(rc_smooth_type=kind)
        rc.configure(p, 1000)
        ref = _RcRef(rc, p)
        sp = Setpoint()
        sp_ref = Setpoint()
        rnd = _Rand(5)
        for k in range(300):
            rc.stick_raw[0] = rnd() if k % 7 else 0.0
            rc.throttle_raw = 0.5
            rc.update(sp)
            ref.update(rc.stick_raw, 0.5, sp_ref)
            assert _same_setpoint(sp, sp_ref), (kind, k)


# --------------------------------------------------------------------------------- output stage
def _demands():
    nan = float("nan")
    rnd = _Rand(11)
    out = [[0.0, 1.0, -0.0, 0.5], [1.5, -0.2, nan, float("inf")], [1e-9, 0.999999, 2.0, -1e30]]
    for _ in range(200):
        out.append([rnd() * 0.6 + 0.5, rnd() * 0.6 + 0.5, rnd() * 0.6 + 0.5, rnd() * 0.6 + 0.5])
    return out


def test_output_stage_equals_idle_plus_span_times_demand():
    for idle_pct, max_pct in ((5.5, 100), (0, 100), (10, 80), (15, 50)):
        stage = OutputStage()
        p = _params(motor_idle_pct=idle_pct, motor_max_pct=max_pct)
        stage.configure(p, 4)
        idle = p.get("motor_idle_pct") * 0.01
        top = p.get("motor_max_pct") * 0.01
        if top < idle:
            top = idle
        norm = array("f", [0.0] * 4)
        out = array("f", [0.0] * 4)
        ref = array("f", [0.0] * 4)
        clamped = 0
        for d in _demands():
            for i in range(4):
                norm[i] = d[i]
            stage.update(norm, True, out)
            for i in range(4):
                m = norm[i]
                if m > 1.0:
                    m = 1.0
                    clamped += 1
                elif not (m >= 0.0):
                    m = 0.0
                    clamped += 1
                ref[i] = idle + (top - idle) * m
            assert _bits_f(out, 4) == _bits_f(ref, 4), (idle_pct, max_pct, d)
        assert stage.clamped == clamped
        stage.update(norm, False, out)
        assert list(out) == [0.0] * 4


# ---------------------------------------------------------------------------------- DShot words
def _ref_word(enc, t, i):
    """DshotEncoder._value and the frame, the plain way (one call per motor)."""
    v = enc._value(t, enc._low_fp, enc._span_fp)
    return dshot_frame(v, 1 if i == enc.telemetry_motor else 0, enc.bidir)


def test_dshot_encode_motors_equals_value_per_motor():
    for bidir, idle_pct, stop_at_zero, tm in ((False, 0.0, True, -1), (True, 5.5, False, 2), (False, 100.0, False, 0),
                                              (True, 0.0, True, 3)):
        enc = DshotEncoder(4, bidir, idle_pct, stop_at_zero)
        enc.telemetry_motor = tm
        ref = DshotEncoder(4, bidir, idle_pct, stop_at_zero)
        ref.telemetry_motor = tm
        words = array("H", [0] * 4)
        for d in _demands():
            norm = array("f", d)
            moving = enc.encode_motors(norm, True, words)
            want = [_ref_word(ref, norm[i], i) for i in range(4)]
            assert list(words) == want, (bidir, idle_pct, stop_at_zero, d)
            assert moving == len([w for w in want if w != dshot_frame(0, 0, bidir)])
            assert enc.clamped == ref.clamped
        assert enc.encode_motors(norm, False, words) == 0
        assert list(words) == [dshot_frame(0, 0, bidir)] * 4
        assert max(frame >> 5 for frame in want) <= VALUE_MAX


def test_output_encoder_words_follow_motor_order_and_queue_commands_only_while_stopped():
    for order in (0, 2143, 4321):
        codec = OutputEncoder()
        codec.configure(_params(motor_order=order, motor_protocol="dshot300"), 4, 0, 0)
        enc = DshotEncoder(4, False, 0.0, True)
        lines = codec.line_of_motor
        t = 0
        for d in _demands()[:40]:
            norm = array("f", d)
            t += 1000
            codec.write(norm, 4, t)
            for m in range(4):
                assert codec.words[lines[m]] == dshot_frame(enc._value(norm[m], enc._low_fp, enc._span_fp), 0, False)
        # boot commands (3D off) go out once every motor is stopped
        stopped = array("f", [0.0] * 4)
        codec.configure(_params(motor_order=order, motor_protocol="dshot300"), 4, 0, t)
        codec.write(stopped, 4, t + 1000)
        assert codec.commands.sent == 1 and codec.words[0] != 0


# ------------------------------------------------------------------------------ MPU-6050 decode
class _BurstBus:
    """One MPU-6050: WHO_AM_I answers, every burst read gets `burst`."""

    def __init__(self):
        self.burst = bytearray(14)

    def readfrom_mem_into(self, address, register, buf):
        if len(buf) == 1:
            buf[0] = WHO_AM_I_VALUE
        else:
            for i in range(len(buf)):
                buf[i] = self.burst[i]

    def writeto_mem(self, address, register, data):
        pass


def _ref_read(drv, o, burst, gyro, accel):
    """MPU6050.read the plain way: signed16 per register, Orientation.rotate_scaled into FRD."""
    v = [signed16(burst[2 * i], burst[2 * i + 1]) for i in range(7)]
    o.rotate_scaled(v[4] * 16 - drv._bias16_x, v[5] * 16 - drv._bias16_y, v[6] * 16 - drv._bias16_z,
                    drv._gyro_k16, gyro)
    o.rotate_scaled(v[0], v[1], v[2], drv._accel_k, accel)
    return v[3]


def test_mpu6050_read_equals_signed16_and_rotate_scaled_for_every_mount():
    rnd = _Rand(21)
    rails = (0, 1, -1, 32767, -32768, -32767, 32766, 16, -16)
    for mount in range(8):
        for angles in ((0.0, 0.0, 0.0), (0.0, 0.1, -0.05)):
            o = Orientation(mount, angles[0], angles[1], angles[2])
            bus = _BurstBus()
            drv = MPU6050(bus, o, delay_us=lambda us: None)
            assert drv.configure(gyro_range_dps=1000, accel_range_g=8)
            drv.set_gyro_bias16(37, -250, 0)
            gyro = array("f", [0.0] * 3)
            accel = array("f", [0.0] * 3)
            gyro_ref = array("f", [0.0] * 3)
            accel_ref = array("f", [0.0] * 3)
            frozen = 0
            same = 0
            last = None
            for k in range(120):
                if 0 < k % 40 < 12:
                    pass  # the same burst again: the frozen watch counts
                else:
                    for i in range(7):
                        v = rails[(k + i) % len(rails)] if k % 4 == 0 else int(rnd() * 32767)
                        bus.burst[2 * i] = (v >> 8) & 0xFF
                        bus.burst[2 * i + 1] = v & 0xFF
                assert drv.read(gyro, accel)
                t = _ref_read(drv, o, bus.burst, gyro_ref, accel_ref)
                assert _bits_f(gyro, 3) == _bits_f(gyro_ref, 3), (mount, angles, k)
                assert _bits_f(accel, 3) == _bits_f(accel_ref, 3), (mount, angles, k)
                assert drv.temp_raw == t
                raw = [signed16(bus.burst[2 * i], bus.burst[2 * i + 1]) for i in (0, 1, 2, 4, 5, 6)]
                assert drv.saturated == (max(raw) >= 32767 or min(raw) <= -32767)
                same = same + 1 if raw == last else 0
                last = raw
                if same >= 8:
                    frozen += 1
                assert drv.frozen == (same >= 8)
            assert drv.frozen_count == frozen > 0 and drv.samples == 120


def test_rc_new_frame_mode_ranges_equal_in_range():
    # new_frame's mode ranges and fs_switch_in are _in_range() inline: the same answers
    from hoverfly.core.stages.control import MODE_ACRO, MODE_ANGLE, MODE_HORIZON
    from hoverfly.core.stages.rc import _in_range

    rnd = _Rand(9)
    rc = RcInput()
    rc.configure(_params(), 1000)
    channels = array("H", [1500] * 16)
    for k in range(400):
        for i in range(16):
            channels[i] = 1000 + int((rnd() + 1.0) * 500)
        rc._arm = (k % 18, 1400 + k % 300, 1900)
        rc._horizon = ((k * 7) % 18, 1300, 1700)
        rc._angle = ((k * 5) % 17, 1200, 2100)
        rc._airmode = ((k * 3) % 19, 1500, 1500 + k)
        rc._fs_switch = ((k * 11) % 18, 1100 + k, 1800)
        rc.frame_table()
        rc.new_frame(channels)
        a, h, g, m, fs = rc._arm, rc._horizon, rc._angle, rc._airmode, rc._fs_switch
        assert rc.fs_switch_in(channels) is _in_range(channels, fs[0], fs[1], fs[2])
        assert rc.arm_switch is _in_range(channels, a[0], a[1], a[2])
        if _in_range(channels, h[0], h[1], h[2]):
            mode = MODE_HORIZON
        elif _in_range(channels, g[0], g[1], g[2]):
            mode = MODE_ANGLE
        else:
            mode = MODE_ACRO
        assert rc.mode == mode
        assert rc.airmode_switch is _in_range(channels, m[0], m[1], m[2])
