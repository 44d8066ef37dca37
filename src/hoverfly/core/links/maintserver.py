"""Seed-001 maintenance protocol server: telemetry by header bitmask, commands 0-25, radio override.

Takes request bytes of the maintenance port (`MaintServer.feed(data, n, write)`, any chunking) and
the Flight; gives one reply frame per good request through `write(bytes)`: the request's header
echoed and the requested values in header order (protocols/maintenance.py is the codec; the
units and mapping are in docs/configuration.md). Frames with a bad checksum, a wrong length or an
unknown command id cannot be answered (their length is unknown): the codec counts and drops them.
A request that is framed but refused (out-of-range value, a write while armed, a command hoverfly
cannot carry out) is answered with the command id replaced by ERROR_CMD (127) and nothing
changes; `last_error` says why. Runs from the links task, never in the flight pass, and never
raises: a board or stage that does is a refusal ("internal error"), a field it cannot read or fit
to its wire type is sent as 0 (counted in `field_errors`).

What each command does in hoverfly, the parameters it writes and the capping rules are in
docs/maintenance-protocol.md ("Commands in hoverfly").

REMOTE_CONTROL_TAG with override = 1 is the seed's "fly from maintenance". With `maint_override` = 1
(on in `hoverfly sim`, off by default on a board) it replaces the radio: `RadioOverride` stands in for
flight.receiver and its frames are the pilot's, so arming, modes and the failsafe treat it as a
receiver, and when the frames stop the flight's own link watch (rx_timeout_ms) starts the failsafe.
With 0 the frame goes to flight.on_msp_rc (seed 004's autopilot rules).
Command 6 (control motors) = 1 is the props-off acknowledgement: motor commands 1-5 then drive
flight.motor_test, and flight.config_session bit 4 blocks arming until 6 = 0 or the client goes away.
"""

from array import array

from hoverfly import VERSION
from hoverfly.compat import ticks_diff
from hoverfly.core.links.mspserver import CONFIG_MAINT, ParsedRequests
from hoverfly.core.stages.rc import aux_channel
from hoverfly.protocols import maintenance as mp

ERROR_CMD = 127
_DEG = 57.29577951308232
_TWO_PI = 6.283185307179586

# Refused while armed: every parameter write, the motor commands and both I2C transactions (22, 23).
_REFUSED_ARMED = (1, 2, 3, 4, 5, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25)
_AXES = ("roll", "pitch", "yaw")
_JS_NAMES = ("thr", "roll", "pitch")  # commands 12-14 and js_params: ab_<stick>_alpha / _beta
_IMU_PARAM = ("lsm9ds1", "mpu6050", "bno055")  # the seed's IMU enum -> the imu_type parameter
_IMU_OTHER = 255  # imu_type for an IMU the seed's enum has no id for

_SPEC = {}  # field name -> (struct code, count): what field() fits each value to
for _f in mp.FIELDS:
    _SPEC[_f[0]] = (_f[1], _f[2])
_SPEC["pt1f_params"] = _SPEC["ptf1_params"]


def _tau_of_hz(hz):
    return 1.0 / (_TWO_PI * hz) if hz > 0 else 0.0


def _hz_of_tau(tau):
    return int(1.0 / (_TWO_PI * tau) + 0.5) if tau > 0 else 0


class MaintServer(ParsedRequests):
    def __init__(self, flight, storage=None, layout=mp.LAYOUT_SEED):
        self.flight = flight
        self.storage = storage
        # Each maintenance server holds its own config_session bit: one releasing motor control must not
        # clear the arming lock another (UART beside USB) still holds.
        self.session_bit = CONFIG_MAINT
        self.layout = layout
        self.parser = mp.MaintenanceParser(layout=layout, queue_depth=2)
        self.buf = bytearray(1 + mp.HEADER_LEN + mp.MAX_REPLY_PAYLOAD + 1)
        self.header = bytearray(mp.HEADER_LEN)
        self.motor_control = False
        self.i2c_value = 0
        self.requests = 0
        self.refused = 0
        self.overrides = 0
        self.capped = 0  # motor commands run at a cap or floor other than the pulse sent (last_capped: why)
        self.last_capped = ""
        self.field_errors = 0  # telemetry values that could not be read or did not fit their wire type
        self.last_field_error = ""
        self.last_error = None
        self.served = 0  # requests answered by the last serve()

    def close(self):
        """The client went away: its session ends before another is served. Motor control (the
        props-off acknowledgement), the motor test it drove, its arming lock and any partial or
        queued frame go with it."""
        # SAFETY: the next client must not inherit motor control or spinning motors.
        if self.motor_control:
            self._motor_control(False)
        self.parser.reset()

    def _motor_control(self, on):
        f = self.flight
        if not on:
            mt = getattr(f, "motor_test", None)
            if self.motor_control and mt is not None and getattr(mt, "active", False):
                mt.stop(0)
        self.motor_control = on
        s = getattr(f, "config_session", 0)
        bit = self.session_bit
        f.config_session = (s | bit) if on else (s & ~bit)

    def feed(self, data, n, write):
        """Answer every request in data[:n], in order."""
        i = 0
        while True:
            i = self.serve(data, i, n, write, 64)
            if i >= n and not self.pending():
                return

    def serve(self, data, start, n, write, budget):
        """Answer the requests in data[start:n] in order, at most `budget` of them; return where it
        stopped (n once every byte was taken). The parser is fed only as many bytes as its queue
        holds, so no request is overwritten; `served` says how many were answered."""
        p = self.parser
        i = start
        done = 0
        while done < budget:
            if not p.pending():
                if i >= n and not p.carrying():
                    break
                i = p.feed_some(data, i, n)
                if not p.pending():
                    break
            p.pop()
            done += 1
            self.requests += 1
            err = self._request(p)
            h = self.header
            for k in range(mp.HEADER_LEN):
                h[k] = p.header[k]
            if err is not None:
                self.refused += 1
                self.last_error = err
                if self.layout == mp.LAYOUT_FIRMWARE:
                    h[7] = (h[7] & 0x01) | (ERROR_CMD << 1)
                else:
                    h[7] = (h[7] & 0x80) | ERROR_CMD
            values = {}
            for k in range(mp.FIELD_COUNT):
                if p.wants(k):
                    name = mp.FIELDS[k][0]
                    values[name] = self.field(name)
            n_out = mp.encode_reply_into(self.buf, h, values, self.layout)
            write(bytes(self.buf[:n_out]))
        self.served = done
        return i

    # ----------------------------------------------------------------- requests
    def _request(self, p):
        """Carry out one request; None, or the one-line reason it was refused (nothing changed)."""
        try:
            return self._carry_out(p)
        except Exception as exc:  # a board or stage that raises must not end the links task or the pass
            return "internal error: %s" % (exc,)

    def _carry_out(self, p):
        err = mp.validate_remote_control(p.rc_override, p.rc_armed_us, p.rc_roll_us, p.rc_pitch_us,
                                         p.rc_throttle_us)
        if err is not None:
            return err
        cmd = p.cmd_id
        args = p.args
        err = mp.validate_command(cmd, args)
        if err is not None:
            return err
        f = self.flight
        # SAFETY: configuration writes, motor commands and I2C transactions (the IMU's own bus) never
        # while armed.
        if cmd in _REFUSED_ARMED and f.arming.armed:
            return "refused while armed: disarm first"
        if p.rc_override:
            err = self._override(p)
            if err is not None:
                return err
        if cmd == mp.CMD_NONE:
            return None
        if cmd <= mp.CMD_SET_ALL_MOTORS:
            return self._motor(cmd, args[0])
        if cmd == mp.CMD_CONTROL_MOTORS:
            self._motor_control(args[0] == 1)
            return None
        if cmd == mp.CMD_FLASH_WRITE:
            if self.storage is None:
                return "no storage on this board"
            return self.storage.save(f.params)
        if cmd <= mp.CMD_SET_MOTOR4_PARAMS:
            k = cmd - mp.CMD_SET_MOTOR1_PARAMS
            if k >= f.motor_count:
                return "no motor %d on this frame" % (k + 1)
            enable = f.params.get("motor_enable")
            enable = (enable | (1 << k)) if args[0] else (enable & ~(1 << k))
            n = "motor%d_" % (k + 1)
            return f.params.update((("motor_enable", enable), (n + "min_us", args[1]), (n + "max_us", args[2])))
        if cmd <= mp.CMD_SET_JS_PITCH:
            n = _JS_NAMES[cmd - mp.CMD_SET_JS_THROTTLE]
            return f.params.update((("ab_%s_alpha" % n, args[0]), ("ab_%s_beta" % n, args[1])))
        if cmd <= mp.CMD_SET_YAW_PID:
            axis = _AXES[cmd - mp.CMD_SET_ROLL_PID]
            # KP, KI, BD are Betaflight-scale P, I, D (whole numbers); SAT is iterm_limit, one for every
            # axis; KT and AD are kept (pid_kt_*, pid_ad_*) and reported back, the controller does not use them.
            return f.params.update((("p_" + axis, args[mp.PID_KP]), ("i_" + axis, args[mp.PID_KI]),
                                    ("pid_kt_" + axis, args[mp.PID_KT]), ("iterm_limit", args[mp.PID_SAT]),
                                    ("pid_ad_" + axis, args[mp.PID_AD]), ("d_" + axis, args[mp.PID_BD])))
        if cmd <= mp.CMD_SET_PT1_MAGN:
            if not (args[0] == args[1] == args[2]):
                return "hoverfly filters all three axes alike: x, y and z time constants must be equal"
            if cmd == mp.CMD_SET_PT1_MAGN:
                return None if args[0] == 0 else "no magnetometer filter on hoverfly: send 0"
            name = "acc_lpf_hz" if cmd == mp.CMD_SET_PT1_ACCEL else "gyro_lpf1_hz"
            return f.params.set(name, _hz_of_tau(args[0]))
        if cmd == mp.CMD_SET_IMU_TYPE:
            # a REBOOT parameter: the IMU starts at the next boot (after a flash write)
            return f.params.set("imu_type", _IMU_PARAM[args[0]])
        if cmd == mp.CMD_I2C_READ or cmd == mp.CMD_I2C_WRITE:
            return self._i2c(cmd, args)
        if cmd == mp.CMD_RESET_IMU_OFFSET:
            att = f.signals.attitude
            return f.params.update((("acc_trim_roll", att.roll_rad * _DEG), ("acc_trim_pitch", att.pitch_rad * _DEG)))
        return f.params.update((("thr_descend_us", args[0]), ("thr_hover_us", args[1]), ("thr_climb_us", args[2])))

    def _i2c(self, cmd, args):
        """Commands 22-23 through the board: `i2c_read(bus, address, register)` gives the byte or a reason
        (str), `i2c_write(bus, address, register, value)` None or a reason."""
        read = cmd == mp.CMD_I2C_READ
        fn = getattr(self.flight.board, "i2c_read" if read else "i2c_write", None)
        if fn is None:
            return "no I2C access on this board"
        what = "I2C%d 0x%02x register 0x%02x" % (args[0], args[1], args[2])
        try:
            r = fn(args[0], args[1], args[2]) if read else fn(args[0], args[1], args[2], args[3])
        except Exception as exc:  # a board without its own reasons: the bus error is the reason
            return "%s: %s failed (%s)" % (what, "read" if read else "write", exc)
        if read:
            if isinstance(r, int) and not isinstance(r, bool) and 0 <= r <= 255:
                self.i2c_value = r
                return None
            return str(r) if isinstance(r, str) else "%s: read failed" % what
        return None if r is None else str(r)

    def _override(self, p):
        f = self.flight
        if f.params.get("maint_override"):
            return self._radio_override(p)
        fn = getattr(f, "on_msp_rc", None)
        if fn is None:
            return "this firmware takes no remote-control override"
        rc = f.rc
        ch = [1500] * 8
        ch[rc.roll_ch] = p.rc_roll_us
        ch[rc.pitch_ch] = p.rc_pitch_us
        ch[rc.throttle_ch] = p.rc_throttle_us
        arm = aux_channel(rc.map_ch, f.params.get("arm_ch"))  # AUX1..4 where rc_map puts them
        if 1 <= arm <= 8:
            ch[arm - 1] = p.rc_armed_us
        self.overrides += 1
        reason = fn(f.board.now_us(), ch, 8)
        return None if not reason else str(reason)

    def _radio_override(self, p):
        """The request's sticks and arm switch as a receiver frame (maint_override = 1)."""
        f = self.flight
        ovr = f.receiver
        if not isinstance(ovr, RadioOverride):
            ovr = RadioOverride(f, f.receiver)
            f.receiver = ovr
        rc = f.rc
        ch = ovr.frame_us
        for k in range(len(ch)):
            ch[k] = 1500
        ch[rc.roll_ch] = p.rc_roll_us
        ch[rc.pitch_ch] = p.rc_pitch_us
        ch[rc.throttle_ch] = p.rc_throttle_us
        params = f.params
        arm = aux_channel(rc.map_ch, params.get("arm_ch"))  # AUX1..4 where rc_map puts them
        if 1 <= arm <= len(ch):
            ch[arm - 1] = p.rc_armed_us
        # Seed 001 flies self-levelled: the angle switch on, in its range and out of horizon's.
        angle = aux_channel(rc.map_ch, params.get("angle_ch"))
        if 1 <= angle <= len(ch) and angle != arm:
            ch[angle - 1] = params.get("angle_max_us") - 1
        self.overrides += 1
        ovr.take(f.board.now_us())
        return None

    def _motor(self, cmd, pulse_us):
        """Commands 1-5: the props-off motor test (core/command/motortest.py) on enabled motors. A pulse above
        the test's cap (motor_test_pct) or the motor's motorN_max_us runs at that cap, one between 1000 us
        and the motor's floor (motorN_min_us, the idle output) at the floor: the command is carried out
        and motorN_signal reads the value the motor runs at from this reply on; `capped` counts it and
        `last_capped` says why."""
        if not self.motor_control:
            return "send control_motors 1 first (props removed)"
        f = self.flight
        mt = getattr(f, "motor_test", None)
        if mt is None:
            return "this firmware has no motor test"
        index = -1 if cmd == mp.CMD_SET_ALL_MOTORS else cmd - mp.CMD_SET_MOTOR1
        n = f.motor_count
        if index >= n:
            return "no motor %d on this frame" % (index + 1)
        p = f.params
        enable = p.get("motor_enable")
        if index >= 0 and not enable & (1 << index):
            return "motor %d is disabled (motor_enable): enable it with command %d first" % (
                index + 1, mp.CMD_SET_MOTOR1_PARAMS + index)
        now = f.board.now_us()
        test_cap_us = 1000 + int(p.get("motor_test_pct") * 10.0 + 0.5)
        notes = []
        for k in (range(n) if index < 0 else (index,)):
            if not enable & (1 << k):
                continue  # "all motors": the enabled ones; a disabled motor stays stopped
            run_us, why = self._test_pulse(k, pulse_us, test_cap_us)
            if why:
                notes.append("motor %d runs at %d us, not %d: %s" % (k + 1, run_us, pulse_us, why))
            reason = mt.request(now, k, (run_us - 1000) * 0.001, True)
            if reason:
                return str(reason)
        if notes:
            self.capped += 1
            self.last_capped = "; ".join(notes)
        return None

    def _test_pulse(self, k, pulse_us, test_cap_us):
        """The pulse motor k's test runs at for `pulse_us`, and why it differs ('' when it does not)."""
        if pulse_us <= 1000:
            return 1000, ""
        p = self.flight.params
        idle_us = 1000 + int(p.get("motor_idle_pct") * 10.0 + 0.5)
        lo_us, hi_us = idle_us, 2000
        if k < 4:
            n = "motor%d_" % (k + 1)
            if p.get(n + "min_us") > lo_us:
                lo_us = p.get(n + "min_us")
            hi_us = p.get(n + "max_us")
        if test_cap_us < hi_us:
            if pulse_us > test_cap_us:
                return test_cap_us, "capped by motor_test_pct %g %% (props-off test limit)" % p.get("motor_test_pct")
        elif pulse_us > hi_us:
            return hi_us, "capped by motor%d_max_us" % (k + 1)
        if pulse_us < lo_us:
            return lo_us, "raised to the motor's floor (motor_idle_pct, motor%d_min_us)" % (k + 1)
        return pulse_us, ""

    # ----------------------------------------------------------------- telemetry
    def imu_type(self):
        """The seed's IMU id (0 LSM9DS1, 1 MPU6050, 2 BNO055, 255 another) of the IMU the board runs: its
        driver's name, else the board's `imu_type`, else the `imu_type` parameter. Total: any value the
        board holds (a name, an id, anything else) gives an id, never an exception."""
        board = self.flight.board
        v = None
        try:
            imu = getattr(board, "imu", None)
            v = getattr(imu, "name", None) if imu is not None else None
            if v is None or v == "imu":
                v = getattr(board, "imu_type", None)
            if v is None:
                v = self.flight.params.stored("imu_type")  # a reboot row: what is stored reads back
        except Exception:
            return _IMU_OTHER
        return imu_id(v)

    def field(self, name):
        """The value of one header field, in the seed's units (docs/maintenance-protocol.md), fitted to
        the field's wire type: whatever a stage or the board holds, this never raises (a value that
        cannot be read or does not fit counts in `field_errors` and is sent as 0 or clamped)."""
        spec = _SPEC.get(name)
        try:
            v = self._field(name)
        except Exception as exc:
            self.field_errors += 1
            self.last_field_error = "%s: %s" % (name, exc)
            v = 0
        if spec is None:
            return 0
        code, count = spec
        if count == 1:
            return self._fit(code, v)
        out = [0] * count
        try:
            m = len(v)
        except Exception:
            m = 0
        for j in range(count if m > count else m):
            out[j] = self._fit(code, v[j])
        if m != count:
            self.field_errors += 1
        return out

    def _fit(self, code, v):
        try:
            if code == "f":
                x = float(v)
                return x if x - x == 0 else 0.0  # no nan or inf on the wire
            x = int(v)
        except Exception:
            self.field_errors += 1
            return 0.0 if code == "f" else 0
        hi = 0xFF if code == "B" else (0xFFFF if code == "H" else 0xFFFFFFFF)
        if x < 0 or x > hi:
            self.field_errors += 1
            return 0 if x < 0 else hi
        return x

    def _field(self, name):
        f = self.flight
        s = f.signals
        if name.startswith("raw_") or name.startswith("filtered_"):
            raw = name[0] == "r"
            sensor = name[4:-2] if raw else name[9:-2]
            axis = "xyz".index(name[-1])
            if sensor == "accel":
                return (s.accel_raw_m_s2 if raw else s.accel_m_s2)[axis]
            if sensor == "gyro":
                return (s.gyro_raw_rad_s if raw else s.gyro_rad_s)[axis] * _DEG
            return 0.0
        rc = f.rc
        ch = s.rc_channels_us
        if name == "throttle_signal":
            return ch[rc.throttle_ch]
        if name == "roll_signal":
            return ch[rc.roll_ch]
        if name == "pitch_signal":
            return ch[rc.pitch_ch]
        if name == "throttle_set_point":
            return 1000 + int(s.setpoint.throttle_norm * 1000.0 + 0.5)
        if name == "roll_set_point":
            return s.setpoint.roll_angle_rad * _DEG
        if name == "pitch_set_point":
            return s.setpoint.pitch_angle_rad * _DEG
        if name.startswith("body_"):
            att = s.attitude
            return (att.roll_rad, att.pitch_rad, att.yaw_rad)[_AXES.index(name[5:])] * _DEG
        if "_PID_" in name:
            # From the pass's signals, which the float and the fixed-point controller both write.
            k = _AXES.index(name[:name.index("_")])
            term = name[-1]
            if term == "r":
                return (s.setpoint.rate_rad_s[k] - s.gyro_rad_s[k]) * _DEG
            # PID terms in Betaflight PID-sum units (1000 = the mixer's full range)
            t = s.pid_terms
            return {"p": t[k], "i": t[k + 3], "d": t[k + 6], "u": s.torque_norm[k]}[term] * 1000.0
        if name.startswith("motor") and name.endswith("_signal"):
            k = int(name[5]) - 1
            if k >= f.motor_count:
                return 0
            v = s.motor_out[k]
            mt = getattr(f, "motor_test", None)
            if mt is not None and (mt.active or self.motor_control) and not f.arming.armed and hasattr(mt, "values"):
                v = mt.values[k]  # what the test drives from the next pass on (a capped value reads capped)
            return 1000 + int((v if v > 0.0 else 0.0) * 1000.0 + 0.5)
        if name == "motors_armed":
            return 1 if f.arming.armed else 0
        if name == "builtin_test_status":
            bit = getattr(f, "bit", None)
            return getattr(bit, "flags", 0) if bit is not None else 0
        p = f.params
        if name == "motor_params":
            out = []
            enable = p.get("motor_enable")
            for k in range(4):
                on = k < f.motor_count and enable & (1 << k)
                out.append(1 if on else 0)
                out.append(p.get("motor%d_min_us" % (k + 1)))
                out.append(p.get("motor%d_max_us" % (k + 1)))
            return out
        if name == "js_params":
            out = []
            for n in _JS_NAMES:
                out.append(p.get("ab_%s_alpha" % n))
                out.append(p.get("ab_%s_beta" % n))
            return out
        if name == "PID_params":
            out = []
            for axis in _AXES:
                out.extend((p.get("p_" + axis), p.get("i_" + axis), p.get("pid_kt_" + axis), p.get("iterm_limit"),
                            p.get("pid_ad_" + axis), p.get("d_" + axis)))
            return out
        if name in ("ptf1_params", "pt1f_params"):
            ta = _tau_of_hz(p.get("acc_lpf_hz"))
            tg = _tau_of_hz(p.get("gyro_lpf1_hz"))
            return (ta, ta, ta, tg, tg, tg, 0.0, 0.0, 0.0)
        if name == "imu_type":
            return self.imu_type()
        if name == "i2c_read":
            return self.i2c_value
        if name == "sw_ver":
            return (VERSION[0], VERSION[1], VERSION[2], mp.RELEASE_BETA if VERSION[0] == 0 else mp.RELEASE_RELEASE)
        if name == "imu_offset":
            return (p.get("acc_trim_roll"), p.get("acc_trim_pitch"), 0.0)
        if name == "throttle_params":
            return (p.get("thr_descend_us"), p.get("thr_hover_us"), p.get("thr_climb_us"))
        return 0


class RadioOverride:
    """Stands in for flight.receiver while the maintenance link flies (maint_override = 1).

    The board's receiver is still read every poll (its bytes drained, its counts and link quality
    kept, mirrored here for CLI status, MSP and the log), but while the override holds the radio
    only the maintenance frames reach the flight: two sources taking turns would toggle the arm
    switch. When they stop, update() reports no frames, so the flight's link watch times out into
    the failsafe as for a lost receiver. The radio is handed back only once the override has been
    silent past rx_timeout_ms with the craft disarmed (the failsafe landed it, or the pilot
    disarmed first), or when maint_override is set to 0 while disarmed."""

    def __init__(self, flight, inner):
        self.flight = flight
        self.inner = inner
        n = len(inner.channels_us)
        self.channels_us = array("H", [1500] * n)
        self.frame_us = array("H", [1500] * n)  # the latest override frame, copied in by take()
        self.holding = False
        self.fresh = False
        self.last_us = 0
        self.frames_taken = 0
        self.released = 0
        self._copy_stats()

    def _copy_stats(self):
        r = self.inner
        self.provider = getattr(r, "provider", "")
        self.frames = r.frames
        self.errors = r.errors
        self.link_quality_pct = r.link_quality_pct
        self.rssi_dbm = r.rssi_dbm
        self.rx_failsafe = r.rx_failsafe
        self.frame_rate_hz = getattr(r, "frame_rate_hz", 0)
        self.telemetry = getattr(r, "telemetry", None)

    def take(self, now_us):
        self.holding = True
        self.fresh = True
        self.last_us = now_us

    # the Receiver interface Flight uses
    def configure(self, params):
        self.inner.configure(params)

    def start(self, now_us):
        self.inner.start(now_us)

    def use_core1(self, link):
        return None  # the override runs in the links task; the second core keeps to its own receiver

    def update(self, now_us, board):
        new = self.inner.update(now_us, board)
        self._copy_stats()
        if not self.holding:
            if new:
                src = self.inner.channels_us
                dst = self.channels_us
                for k in range(len(dst) if len(dst) < len(src) else len(src)):
                    dst[k] = src[k]
            return new
        f = self.flight
        if self.fresh:
            self.fresh = False
            src = self.frame_us
            dst = self.channels_us
            for k in range(len(dst)):
                dst[k] = src[k]
            self.frames_taken += 1
            return 1
        # SAFETY: a silent override keeps the radio silent while armed, so the failsafe (not the
        # radio's sticks and arm switch) decides what happens next.
        if not f.arming.armed and (not f.params.get("maint_override") or ticks_diff(
                now_us, self.last_us) > f.params.get("rx_timeout_ms") * 1000):
            self.holding = False
            self.released += 1
        return 0

    def frame_age_us(self, now_us):
        if self.holding:
            return ticks_diff(now_us, self.last_us)
        return self.inner.frame_age_us(now_us)

    def telemetry_due(self, now_us):
        return False if self.holding else self.inner.telemetry_due(now_us)

    def send_telemetry(self, now_us, board, signals, mode, airmode, failsafe, armed, arming_flags):
        self.inner.send_telemetry(now_us, board, signals, mode, airmode, failsafe, armed, arming_flags)


def imu_id(v):
    """The seed's IMU enum for an IMU named `v` ('mpu6050', 'MPU-6050', 'BNO055', ...) or an id already;
    255 for anything else (another chip, 'auto' before detection, a value of another type)."""
    if isinstance(v, bool):
        return _IMU_OTHER
    if isinstance(v, int):
        return v if 0 <= v <= 2 else _IMU_OTHER
    if isinstance(v, (str, bytes)):
        if isinstance(v, bytes):
            try:
                v = v.decode()
            except Exception:
                return _IMU_OTHER
        key = v.replace("-", "").replace("_", "").upper()
        for i in range(len(mp.IMU_TYPE_NAMES)):
            if mp.IMU_TYPE_NAMES[i] == key:
                return i
    return _IMU_OTHER
