"""Seed-001 maintenance protocol server: telemetry by header bitmask, commands 0-25, radio override.

Takes request bytes of the maintenance port (`MaintServer.feed(data, n, write)`, any chunking) and
the Flight; gives one reply frame per good request through `write(bytes)`: the request's header
echoed and the requested values in header order (protocols/maintenance.py is the codec; the
units and mapping are in docs/configuration.md). Frames with a bad checksum, a wrong length or an
unknown command id cannot be answered (their length is unknown): the codec counts and drops them.
A request that is framed but refused (out-of-range value, a write while armed, a command hoverfly
cannot carry out) is answered with the command id replaced by ERROR_CMD (127) and nothing
changes; `last_error` says why. Runs from the links task, never in the flight pass.

REMOTE_CONTROL_TAG with override = 1 becomes an RC frame for flight.on_msp_rc (the seed's
"fly from maintenance"). Command 6 (control motors) = 1 is the props-off acknowledgement: motor
commands 1-5 then drive flight.motor_test, and flight.config_session bit 4 blocks arming until
6 = 0 or the client goes away.
"""

from hoverfly import VERSION
from hoverfly.core.mspserver import CONFIG_MAINT
from hoverfly.protocols import maintenance as mp

ERROR_CMD = 127
_DEG = 57.29577951308232
_TWO_PI = 6.283185307179586

_WRITES = (1, 2, 3, 4, 5, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 23, 24, 25)
_AXES = ("roll", "pitch", "yaw")


def _tau_of_hz(hz):
    return 1.0 / (_TWO_PI * hz) if hz > 0 else 0.0


def _hz_of_tau(tau):
    return int(1.0 / (_TWO_PI * tau) + 0.5) if tau > 0 else 0


class MaintServer:
    def __init__(self, flight, storage=None, layout=mp.LAYOUT_SEED):
        self.flight = flight
        self.storage = storage
        self.layout = layout
        self.parser = mp.MaintenanceParser(layout=layout, queue_depth=2)
        self.buf = bytearray(1 + mp.HEADER_LEN + mp.MAX_REPLY_PAYLOAD + 1)
        self.header = bytearray(mp.HEADER_LEN)
        self.motor_control = False
        self.i2c_value = 0
        self.requests = 0
        self.refused = 0
        self.overrides = 0
        self.last_error = None

    def close(self):
        """The client went away: release motor control and the arming lock."""
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
        f.config_session = (s | CONFIG_MAINT) if on else (s & ~CONFIG_MAINT)

    def feed(self, data, n, write):
        self.parser.feed(data, n)
        p = self.parser
        while p.pop():
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

    # ----------------------------------------------------------------- requests
    def _request(self, p):
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
        if cmd in _WRITES and f.arming.armed:
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
            return "per-motor pulse ranges are not hoverfly parameters (see motor protocol settings)"
        if cmd <= mp.CMD_SET_JS_PITCH:
            return "joystick alpha/beta filters are not hoverfly parameters (see rc_smoothing_hz)"
        if cmd <= mp.CMD_SET_YAW_PID:
            axis = _AXES[cmd - mp.CMD_SET_ROLL_PID]
            # KP, KI, BD carry Betaflight-scale P, I, D; SAT the I-term limit; KT and AD are ignored.
            return f.params.update((("p_" + axis, args[mp.PID_KP]), ("i_" + axis, args[mp.PID_KI]),
                                    ("d_" + axis, args[mp.PID_BD]), ("iterm_limit", args[mp.PID_SAT])))
        if cmd <= mp.CMD_SET_PT1_MAGN:
            if not (args[0] == args[1] == args[2]):
                return "hoverfly filters all three axes alike: x, y and z time constants must be equal"
            if cmd == mp.CMD_SET_PT1_MAGN:
                return None if args[0] == 0 else "no magnetometer filter on hoverfly: send 0"
            name = "acc_lpf_hz" if cmd == mp.CMD_SET_PT1_ACCEL else "gyro_lpf1_hz"
            return f.params.set(name, _hz_of_tau(args[0]))
        if cmd == mp.CMD_SET_IMU_TYPE:
            if args[0] == self.imu_type():
                return None
            return "the IMU type is fixed by the board"
        if cmd == mp.CMD_I2C_READ or cmd == mp.CMD_I2C_WRITE:
            fn = getattr(f.board, "i2c_read" if cmd == mp.CMD_I2C_READ else "i2c_write", None)
            if fn is None:
                return "no I2C access on this board"
            if cmd == mp.CMD_I2C_READ:
                v = fn(args[0], args[1], args[2])
                if v is None or v < 0:
                    return "I2C read failed"
                self.i2c_value = v & 0xFF
                return None
            return None if fn(args[0], args[1], args[2], args[3]) else "I2C write failed"
        if cmd == mp.CMD_RESET_IMU_OFFSET:
            att = f.signals.attitude
            return f.params.update((("acc_trim_roll", att.roll_rad * _DEG), ("acc_trim_pitch", att.pitch_rad * _DEG)))
        return "seed throttle presets are not hoverfly parameters (the throttle stick is proportional)"

    def _override(self, p):
        f = self.flight
        fn = getattr(f, "on_msp_rc", None)
        if fn is None:
            return "this firmware takes no remote-control override"
        rc = f.rc
        ch = [1500] * 8
        ch[rc.roll_ch] = p.rc_roll_us
        ch[rc.pitch_ch] = p.rc_pitch_us
        ch[rc.throttle_ch] = p.rc_throttle_us
        arm = f.params.get("arm_ch")
        if 1 <= arm <= 8:
            ch[arm - 1] = p.rc_armed_us
        self.overrides += 1
        reason = fn(f.board.now_us(), ch, 8)
        return None if not reason else str(reason)

    def _motor(self, cmd, pulse_us):
        if not self.motor_control:
            return "send control_motors 1 first (props removed)"
        mt = getattr(self.flight, "motor_test", None)
        if mt is None:
            return "this firmware has no motor test"
        index = -1 if cmd == mp.CMD_SET_ALL_MOTORS else cmd - mp.CMD_SET_MOTOR1
        if index >= self.flight.motor_count:
            return "no motor %d on this frame" % (index + 1)
        reason = mt.request(self.flight.board.now_us(), index, (pulse_us - 1000) * 0.001, True)
        return None if not reason else str(reason)

    # ----------------------------------------------------------------- telemetry
    def imu_type(self):
        return getattr(self.flight.board, "imu_type", mp.IMU_MPU6050)

    def field(self, name):
        """The value of one header field, in the seed's units (docs/configuration.md)."""
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
            return 1000 + int((v if v > 0.0 else 0.0) * 1000.0 + 0.5)
        if name == "motors_armed":
            return 1 if f.arming.armed else 0
        if name == "builtin_test_status":
            bit = getattr(f, "bit", None)
            return getattr(bit, "flags", 0) if bit is not None else 0
        if name == "motor_params":
            out = []
            for k in range(4):
                out.append(1 if k < f.motor_count else 0)
                out.append(1000)
                out.append(2000)
            return out
        if name == "js_params":
            return (0.0,) * 6
        if name == "PID_params":
            p = f.params
            out = []
            for axis in _AXES:
                out.extend((float(p.get("p_" + axis)), float(p.get("i_" + axis)), 0.0,
                            float(p.get("iterm_limit")), 0.0, float(p.get("d_" + axis))))
            return out
        if name in ("ptf1_params", "pt1f_params"):
            ta = _tau_of_hz(f.params.get("acc_lpf_hz"))
            tg = _tau_of_hz(f.params.get("gyro_lpf1_hz"))
            return (ta, ta, ta, tg, tg, tg, 0.0, 0.0, 0.0)
        if name == "imu_type":
            return self.imu_type()
        if name == "i2c_read":
            return self.i2c_value
        if name == "sw_ver":
            return (VERSION[0], VERSION[1], VERSION[2], mp.RELEASE_BETA if VERSION[0] == 0 else mp.RELEASE_RELEASE)
        if name == "imu_offset":
            return (float(f.params.get("acc_trim_roll")), float(f.params.get("acc_trim_pitch")), 0.0)
        if name == "throttle_params":
            return (0, 0, 0)
        return 0
