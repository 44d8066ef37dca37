"""MSP v1/v2 server: answers Betaflight-style requests from the live flight state.

Takes request bytes of the CLI/MSP port (`MspServer.feed(data, n, write)`, any chunking) and the
Flight; gives reply frames through `write(bytes)`, in the version (v1, v2, v2-over-v1) each
request came in, error frames (`!`) for unknown commands, bad payloads and refused writes.
Payloads are msp.py's packers in Betaflight's layouts; this module chooses the values and
converts SI to wire units once. Runs from the configuration-links task (core/links/task.py, 100 Hz),
never in the flight pass. `# ` on an idle port is the CLI's business (links.ConfigPort).

Writes: SET_RAW_RC goes to flight.on_msp_rc (the autopilot source, any time); SET_PID,
SET_MOTOR, ACC_CALIBRATION, EEPROM_WRITE and REBOOT are refused while armed; SET_MOTOR goes to
flight.motor_test.request with props_off = this session's SET_ARMING_DISABLED(1) (the
configurator's "I understand the risks" switch), which also holds config_session bit 2.
SET_MODE_RANGE (refused while armed) writes a box's range parameters through params.update;
SERVO, SERVO_CONFIGURATIONS and MSP2_INAV_SERVO_MIXER show the servo mixer in INAV's layouts, MSP2_INAV_AIR_SPEED
a plane's pitot airspeed (cm/s, 0 without one), and
SET_SERVO_CONFIGURATION / MSP2_INAV_SET_SERVO_MIXER (refused while armed) write it through the same
checks as the CLI's `servo` and `smix` (core/stages/servos.py);
MSP2_HOVERFLY_AUTOPILOT (0x3F00) reports seed 004's autopilot privilege state (docs/msp.md).
"""

from struct import pack

from hoverfly import VERSION
from hoverfly.compat import const, ticks_diff
from hoverfly.core.command.autopilot import AP_ENABLED, LATCH_HARD
from hoverfly.core.command.motortest import STOP_LINK
from hoverfly.core.safety.arming import REASONS
from hoverfly.core.safety.failsafe import IDLE
from hoverfly.core.scheduler import PS_CYCLE
from hoverfly.core.stages.control import MODE_ANGLE, MODE_HORIZON, MODE_MANUAL
from hoverfly.core.stages.mixer import is_plane
from hoverfly.core.stages.output import MAX_SERVOS as SERVO_LINES
from hoverfly.core.stages.rc import map_channels
from hoverfly.core.stages.servos import MAX_RULES, SERVO_ROWS, rule_pairs, rules_of, servo_pairs, servo_rows
from hoverfly.protocols import msp

CONFIG_CLI = 1  # flight.config_session bits (core/safety/arming.py blocks arming while any is set)
CONFIG_MSP = 2
CONFIG_MAINT = 4
CONFIG_MAINT_USB = 8  # the maintenance protocol on the config (USB) port: a session of its own

_DEG = 57.29577951308232
_ACC_1G = 2048  # MSP_RAW_IMU accelerometer LSB per g (Betaflight's acc_1G on modern parts)
_GYRO_LSB_PER_DPS = 16.4  # MSP_RAW_IMU gyro LSB per deg/s (+-2000 deg/s part, reference 6.3)
_G = 9.80665
MSP_ACC_TRIM = 240  # Betaflight msp_protocol.h; yamspy's basic_info asks for it
MSP_RX_MAP = 64  # Betaflight msp_protocol.h: u8 x 8, the receiver channel (0-based) of each function, AERT1234
MSP_SET_RX_MAP = 65

# The modes hoverfly reports (MSP_BOXIDS / BOXNAMES order; STATUS mode_flags bit = index here).
# MANUAL (INAV's permanent id 12) last, and only for a plane, as INAV lists it: a quad's boxes are the others.
BOXES = ((0, "ARM"), (1, "ANGLE"), (2, "HORIZON"), (28, "AIR MODE"), (27, "FAILSAFE"), (12, "MANUAL"))
_RANGE_PARAMS = ("arm", "angle", "horizon", "airmode", "fs_switch", "manual")  # each box's <key>_ch/_min_us/_max_us
_QUAD_BOXES = const(5)
ARMING_FLAG_COUNT = 31  # hoverfly's reasons run to bit 30 (arming.py)

IDENTITY = {
    "variant": "HVFL",
    "board_id": "HVFL",
    "target_name": "HOVERFLY",
    "board_name": "hoverfly",
    "manufacturer_id": "",
    "build_date": "Jan  1 2026",
    "build_time": "00:00:00",
    "git_hash": "0000000",
    "craft_name": "hoverfly",
}


def _set_session(flight, bit, on):
    s = getattr(flight, "config_session", 0)
    flight.config_session = (s | bit) if on else (s & ~bit)


def arming_flags(flight):
    """The arming-disable mask as MSP reports it (arming.py uses Betaflight's bit numbers)."""
    return flight.arming.flags


class ParsedRequests:
    """What the links task asks of a server over a streaming parser (MSP, maintenance): its `parser`'s state."""

    def in_frame(self):
        """True while a frame is half received (on the config port a '#' then belongs to it, not to the CLI)."""
        return self.parser.in_frame()

    def idle(self):
        """The line has been quiet past the inter-byte timeout: a half frame will never complete."""
        self.parser.idle()

    def pending(self):
        """Requests parsed and not yet answered (serve() stopped at its budget), or taken bytes not yet
        scanned (the parser's carry): either way serve() has work without a new byte."""
        return self.parser.pending() or self.parser.carrying()


class MspServer(ParsedRequests):
    def __init__(self, flight, storage=None, identity=None):
        self.flight = flight
        self.storage = storage
        self.identity = identity if identity is not None else IDENTITY
        self.parser = msp.MspParser(max_payload=512, queue_depth=4)
        self.requests = 0
        self.errors = 0  # error replies sent
        self.unknown = 0  # unknown command ids
        self.last_error = None
        self.arming_disabled = False  # SET_ARMING_DISABLED(1) from this session
        self.reboot_requested = False
        self.on_reboot = None  # the board's reboot, called once the REBOOT reply has been written
        self.served = 0  # requests answered by the last serve()
        self._rc = [1500] * 18

    # ----------------------------------------------------------------- session
    def close(self):
        """The client went away: its session ends before another is served. The props-off
        acknowledgement, the motor test it drove, its arming lock, a pending reboot and any partial
        or queued frame all go with it."""
        # SAFETY: the next client must not inherit the props-off acknowledgement or spinning motors.
        if self.arming_disabled:
            self.arming_disabled = False
            mt = getattr(self.flight, "motor_test", None)
            if mt is not None and getattr(mt, "active", False):
                mt.stop(STOP_LINK)
        _set_session(self.flight, CONFIG_MSP, False)
        self.reboot_requested = False
        self.parser.reset()

    def feed(self, data, n, write):
        """Answer every request in data[:n], in order."""
        i = 0
        while True:
            i = self.serve(data, i, n, write, 64)
            if i >= n and not self.pending():
                return

    def serve(self, data, start, n, write, budget):
        """Answer the requests in data[start:n] in order, at most `budget` of them (the links task's
        share for this port in this run); return where it stopped: n once every byte was taken. The
        parser is fed only as many bytes as its queue holds, so no request is ever overwritten: what
        is left waits, unread, for the next run. `served` says how many were answered."""
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
            if p.direction != msp.DIR_REQUEST:
                continue  # replies and errors from the other side are not ours to answer
            done += 1
            self.requests += 1
            reply = self.handle(p.cmd, p.payload, p.length)
            if reply is None:
                self.errors += 1
                write(msp.encode_reply(p.version, p.cmd, b"", True, p.encapsulated))
            else:
                write(msp.encode_reply(p.version, p.cmd, reply, False, p.encapsulated))
            if self.reboot_requested and self.on_reboot is not None:
                # The reply is written: now the board may restart (the sim rebuilds its flight, the
                # Pico resets). Nothing after a reboot belongs to this flight.
                self.reboot_requested = False
                self.on_reboot()
                self.served = done
                return n
        self.served = done
        return i

    def _refuse(self, reason):
        self.last_error = reason
        return None

    # ----------------------------------------------------------------- commands
    def handle(self, cmd, payload, length):
        """Reply payload (bytes) for one request, or None for an error reply."""
        f = self.flight
        s = f.signals
        ident = self.identity
        if cmd == msp.MSP_API_VERSION:
            return msp.pack_api_version()
        if cmd == msp.MSP_FC_VARIANT:
            return msp.pack_fc_variant(ident["variant"])
        if cmd == msp.MSP_FC_VERSION:
            return msp.pack_fc_version(VERSION[0], VERSION[1], VERSION[2])
        if cmd == msp.MSP_BOARD_INFO:
            return msp.pack_board_info(ident["board_id"], target_name=ident["target_name"],
                                       board_name=ident["board_name"], manufacturer_id=ident["manufacturer_id"],
                                       gyro_rate_hz=f.loop_hz)
        if cmd == msp.MSP_BUILD_INFO:
            return msp.pack_build_info(ident["build_date"], ident["build_time"], ident["git_hash"])
        if cmd == msp.MSP_NAME:
            return msp.pack_name(ident["craft_name"])
        if cmd == msp.MSP_STATUS or cmd == msp.MSP_STATUS_EX:
            return self._status(cmd == msp.MSP_STATUS_EX)
        if cmd == msp.MSP_RAW_IMU:
            a = s.accel_raw_m_s2
            g = s.gyro_rad_s
            k = _ACC_1G / _G
            kg = _GYRO_LSB_PER_DPS * _DEG
            # FRD body axes; accelerometer z sign as Betaflight's (level at rest reads +1 g).
            return msp.pack_raw_imu((a[0] * k, a[1] * k, -a[2] * k), (g[0] * kg, g[1] * kg, g[2] * kg))
        if cmd == msp.MSP_MOTOR:
            out = s.motor_out
            return msp.pack_motor([1000 + int(out[i] * 1000.0 + 0.5) for i in range(f.motor_count)])
        if cmd == msp.MSP_RC:
            return msp.pack_rc(self._rc_order())
        if cmd == msp.MSP_SERVO:
            return msp.pack_servo(s.servo_us)
        if cmd == msp.MSP_SERVO_CONFIGURATIONS:
            return self._servo_configurations()
        if cmd == msp.MSP2_INAV_AIR_SPEED:
            # As INAV: 0 when there is no pitot, so a configurator or OSD shows no airspeed rather than an error.
            return msp.pack_air_speed(s.airspeed_m_s * 100.0 + 0.5 if s.airspeed_valid else 0)
        if cmd == msp.MSP2_INAV_SERVO_MIXER:
            return self._servo_mixer()
        if cmd == msp.MSP_SET_SERVO_CONFIGURATION or cmd == msp.MSP2_INAV_SET_SERVO_MIXER:
            # SAFETY: a surface reversed or re-mixed in flight is a crash: not while armed.
            if f.arming.armed:
                return self._refuse("refused while armed")
            if cmd == msp.MSP_SET_SERVO_CONFIGURATION:
                return self._set_servo_configuration(payload, length)
            return self._set_servo_mixer(payload, length)
        if cmd == msp.MSP_ATTITUDE:
            att = s.attitude
            return msp.pack_attitude(att.roll_rad * _DEG * 10.0, att.pitch_rad * _DEG * 10.0,
                                     (att.yaw_rad * _DEG) % 360.0)
        if cmd == msp.MSP_ALTITUDE:
            return msp.pack_altitude(getattr(s, "altitude_m", 0.0) * 100.0, getattr(s, "vario_m_s", 0.0) * 100.0)
        if cmd == msp.MSP_ANALOG:
            rssi = 0
            rx = getattr(f, "receiver", None)
            if rx is not None:
                rssi = int(getattr(rx, "link_quality_pct", 0) * 1023 // 100)
            return msp.pack_analog(s.battery_v * 100.0, s.mah_drawn, rssi, s.current_a * 100.0)
        if cmd == msp.MSP_RC_TUNING:
            return self._rc_tuning()
        if cmd == msp.MSP_PID:
            p = f.params
            return msp.pack_pid([(p.get("p_" + a), p.get("i_" + a), p.get("d_" + a)) for a in ("roll", "pitch", "yaw")])
        if cmd == msp.MSP_BOXNAMES:
            return msp.pack_boxnames([b[1] for b in BOXES[:self._box_count()]])
        if cmd == msp.MSP_BOXIDS:
            return msp.pack_boxids([b[0] for b in BOXES[:self._box_count()]])
        if cmd == msp.MSP_MODE_RANGES:
            return self._mode_ranges()
        if cmd == msp.MSP_UID:
            uid = getattr(f.board, "uid", (0x48564600, 0x4C590000, 1))
            return msp.pack_uid(uid[0], uid[1], uid[2])
        if cmd == MSP_ACC_TRIM:
            # i16 pitch, i16 roll; hoverfly sends its trims in 0.1 deg (Betaflight: accelerometer counts)
            p = f.params
            return pack("<hh", int(p.get("acc_trim_pitch") * 10.0), int(p.get("acc_trim_roll") * 10.0))
        if cmd == MSP_RX_MAP:
            return bytes(map_channels(f.params.get("rc_map")))
        if cmd == MSP_SET_RX_MAP:
            # SAFETY: a stick or switch moved to another channel in flight: not while armed.
            if f.arming.armed:
                return self._refuse("refused while armed")
            return self._set_rx_map(payload, length)
        if cmd == msp.MSP_SET_RAW_RC:
            return self._set_raw_rc(payload, length)
        if cmd == msp.MSP2_HOVERFLY_AUTOPILOT:
            return self._autopilot()
        if cmd == msp.MSP_SET_MODE_RANGE:
            # SAFETY: a mode range moved under a switch can arm or change mode in flight: not while armed.
            if f.arming.armed:
                return self._refuse("refused while armed")
            return self._set_mode_range(payload, length)
        if cmd == msp.MSP_SET_ARMING_DISABLED:
            disable, _ = msp.unpack_set_arming_disabled(payload, length)
            self.arming_disabled = disable != 0
            _set_session(f, CONFIG_MSP, self.arming_disabled)
            if not self.arming_disabled:
                mt = getattr(f, "motor_test", None)
                if mt is not None and getattr(mt, "active", False):
                    mt.stop(0)  # Betaflight: turning the switch off stops the motors
            return b""
        # -- writes refused while armed
        if cmd in (msp.MSP_SET_PID, msp.MSP_SET_MOTOR, msp.MSP_ACC_CALIBRATION, msp.MSP_EEPROM_WRITE,
                   msp.MSP_REBOOT):
            if f.arming.armed:
                return self._refuse("refused while armed")
            if cmd == msp.MSP_SET_PID:
                return self._set_pid(payload, length)
            if cmd == msp.MSP_SET_MOTOR:
                return self._set_motor(payload, length)
            if cmd == msp.MSP_ACC_CALIBRATION:
                att = s.attitude
                err = f.params.update((("acc_trim_roll", att.roll_rad * _DEG),
                                       ("acc_trim_pitch", att.pitch_rad * _DEG)))
                return b"" if err is None else self._refuse(err)
            if cmd == msp.MSP_EEPROM_WRITE:
                if self.storage is None:
                    return self._refuse("no storage on this board")
                err = self.storage.save(f.params)
                return b"" if err is None else self._refuse(err)
            mode = msp.unpack_reboot(payload, length)
            if mode != 0:
                return self._refuse("only a firmware reboot (mode 0) is supported")
            if self.on_reboot is None:
                return self._refuse("this board cannot reboot from MSP: power-cycle it")
            self.reboot_requested = True
            return msp.pack_reboot(0)
        self.unknown += 1
        return self._refuse("unknown MSP command %d" % cmd)

    def _servo_configurations(self):
        p = self.flight.params
        servos = []
        for i in range(SERVO_ROWS):
            n = servo_rows(i)
            servos.append((p.stored(n[0]), p.stored(n[2]), p.stored(n[1]), p.stored(n[3])))
        return msp.pack_servo_configurations(servos)

    def _servo_mixer(self):
        """The rules the mixer runs (the mixer_type's preset when none is stored), padded to MAX_RULES."""
        rules = [(0, 0, 0, 0)] * MAX_RULES
        for i, servo, source, rate, speed in rules_of(self.flight.params):
            rules[i] = (servo, source, rate, speed)
        return msp.pack_servo_mixer(rules)

    def _set_servo_configuration(self, payload, length):
        got = msp.unpack_set_servo_configuration(payload, length)
        if got is None:
            return self._refuse("SET_SERVO_CONFIGURATION needs 15 bytes: index, min, max, middle, rate and 7 unused")
        index, lo, hi, mid, rate = got
        pairs, err = servo_pairs(index, lo, hi, mid, rate)
        if err is None:
            err = self.flight.params.update(pairs)
        return b"" if err is None else self._refuse(err)

    def _set_servo_mixer(self, payload, length):
        got = msp.unpack_set_servo_mixer(payload, length)
        if got is None:
            return self._refuse("INAV_SET_SERVO_MIXER needs 7 bytes: rule, servo, input, rate, speed, condition")
        index, servo, source, rate, speed, condition = got
        if condition != 255:
            return self._refuse("smix: logic conditions are not supported (condition must be 255, always)")
        pairs, err = rule_pairs(self.flight.params, index, servo, source, rate, speed, SERVO_LINES)
        if err is None:
            err = self.flight.params.update(pairs)
        return b"" if err is None else self._refuse(err)

    def _rc_order(self):
        # Betaflight's MSP_RC order: roll, pitch, yaw, throttle, then AUX1.. (receiver channels 5..)
        ch = self.flight.signals.rc_channels_us
        rc = self.flight.rc
        out = self._rc
        out[0] = ch[rc.roll_ch]
        out[1] = ch[rc.pitch_ch]
        out[2] = ch[rc.yaw_ch]
        out[3] = ch[rc.throttle_ch]
        m = rc.map_ch
        for i in range(4, len(ch)):
            out[i] = ch[m[i]] if i < 8 else ch[i]  # AUX1..4 where rc_map puts them, as Betaflight's rcData
        return out

    def _status(self, ex):
        f = self.flight
        modes = 0
        if f.arming.armed:
            modes |= 1
        m = f.signals.setpoint.mode
        if m == MODE_ANGLE:
            modes |= 2
        elif m == MODE_HORIZON:
            modes |= 4
        elif m == MODE_MANUAL:
            modes |= 32
        if f.commander.airmode_enabled:  # the AIRMODE box: the switch when one is set, else the parameter
            modes |= 8
        if f.failsafe.state != IDLE:
            modes |= 16
        sch = f.scheduler
        period = sch.period_us if sch.period_us > 0 else 1000
        load = f.pass_us * 100 // period if f.pass_us > 0 else 0
        flags = arming_flags(f)
        pack = msp.pack_status_ex if ex else msp.pack_status
        cycle_us = sch.stats[PS_CYCLE]
        return pack(cycle_us if cycle_us > 0 else period, 0, 1 | 32, modes, 0, load,
                    flags, ARMING_FLAG_COUNT)

    def _rc_tuning(self):
        p = self.flight.params
        v = {}
        # hoverfly keeps Betaflight "actual" rates: rc_rate in 10 deg/s, srate in 10 deg/s, expo %.
        for axis in ("roll", "pitch", "yaw"):
            v[axis + "_rc_rate"] = p.get(axis + "_rc_rate")
            v[axis + "_rate"] = p.get(axis + "_srate")
            v[axis + "_expo"] = p.get(axis + "_expo")
        v["roll_rc_expo"] = v.pop("roll_expo")
        v["throttle_mid"] = 50
        v["throttle_limit_pct"] = 100
        v["rates_type"] = 4  # Betaflight RATES_TYPE_ACTUAL
        return msp.pack_rc_tuning(v)

    def _box_count(self):
        """How many of BOXES this craft has: MANUAL is a plane's."""
        return len(BOXES) if is_plane(self.flight.params.get("mixer_type")) else _QUAD_BOXES

    def _mode_ranges(self):
        """One fixed slot per box, in BOXES order (slot 0 ARM ...), so what SET_MODE_RANGE wrote reads
        back in the slot it names; a box without an AUX channel (ch < 5) is an unused slot (all zero)."""
        p = self.flight.params
        ranges = []
        for k in range(self._box_count()):
            key = _RANGE_PARAMS[k]
            ch = p.get(key + "_ch")
            if ch >= 5:
                ranges.append((BOXES[k][0], ch - 5, msp.step_of_us(p.get(key + "_min_us")),
                               msp.step_of_us(p.get(key + "_max_us"))))
            else:
                ranges.append((0, 0, 0, 0))
        return msp.pack_mode_ranges(ranges)

    def _set_rx_map(self, payload, length):
        """MSP_SET_RX_MAP: Betaflight's rcmap (a 0-based receiver channel per roll, pitch, yaw, throttle,
        AUX1..4) into rc_map through params.set, which refuses anything but a permutation."""
        if length < 8:
            return self._refuse("SET_RX_MAP needs 8 bytes, a channel 0..7 per function (AERT1234)")
        v = 0
        for i in range(8):
            c = payload[i]
            if c > 7:
                return self._refuse("SET_RX_MAP channel %d: hoverfly maps channels 0..7" % c)
            v = v * 10 + c + 1
        err = self.flight.params.set("rc_map", v)
        return b"" if err is None else self._refuse(err)

    def _set_mode_range(self, payload, length):
        """MSP_SET_MODE_RANGE: a box's AUX channel and range into its parameters (<key>_ch, _min_us,
        _max_us) through params.update, the one checked entry point. hoverfly keeps one range per box:
        a non-empty range sets the box's range whatever slot it names; an empty one (start >= end)
        clears the box (ch 0) in the box's own slot and is an unused slot anywhere else (Betaflight's
        configurator writes every slot, unused ones as box 0 with an empty range)."""
        r = msp.unpack_set_mode_range(payload, length)
        if r is None:
            return self._refuse("SET_MODE_RANGE needs slot, box, aux channel, start and end (5 bytes)")
        slot, box_id, aux, start, end, logic, linked = r
        if slot >= msp.MODE_RANGE_SLOTS:
            return self._refuse("SET_MODE_RANGE slot %d: there are %d" % (slot, msp.MODE_RANGE_SLOTS))
        k = -1
        n = self._box_count()
        for i in range(n):
            if BOXES[i][0] == box_id:
                k = i
        if k < 0:
            return self._refuse("SET_MODE_RANGE box %d: this craft's boxes are %s" % (
                box_id, ", ".join("%d %s" % b for b in BOXES[:n])))
        if start > msp.MODE_RANGE_MAX_STEP or end > msp.MODE_RANGE_MAX_STEP:
            return self._refuse("SET_MODE_RANGE steps must be 0..48 (900..2100 us)")
        if logic > 1 or linked != 0:
            return self._refuse("SET_MODE_RANGE: linked modes are not supported")
        key = _RANGE_PARAMS[k]
        if start >= end:
            if slot != k:
                return b""  # an unused slot
            err = self.flight.params.update(((key + "_ch", 0),))
        else:
            err = self.flight.params.update(((key + "_ch", aux + 5), (key + "_min_us", msp.us_of_step(start)),
                                             (key + "_max_us", msp.us_of_step(end))))
        return b"" if err is None else self._refuse(err)

    def _autopilot(self):
        """MSP2_HOVERFLY_AUTOPILOT: seed 004's privilege state, for the companion computer."""
        f = self.flight
        ap = getattr(f, "autopilot", None)
        if ap is None:
            return self._refuse("this firmware has no autopilot link")
        flier = f.commander.flier(f.motor_test.active)  # who flies (FLIER_NAMES)
        latched = ap.latch_norm >= 0.0
        latch = ap.latch_cause if latched else 0
        soft = ap.soft if ap.state == AP_ENABLED else 0
        override = 2 if latch == LATCH_HARD else (1 if soft else 0)
        age_ms = 0xFFFF
        if ap.frames > 0:
            age_ms = ticks_diff(f.board.now_us(), ap.last_msp_us) // 1000
        return msp.pack_autopilot(ap.state, ap.privilege(), flier, override, soft, latch,
                                  1000 + int(ap.latch_norm * 1000.0 + 0.5) if latched else 0,
                                  1000 + int(ap.throttle_norm * 1000.0 + 0.5) if ap.has_frame else 0,
                                  ap.last_result, ap.last_arm_reason if ap.last_arm_reason >= 0 else 255,
                                  age_ms, ap.frames, ap.rejected)

    def _set_raw_rc(self, payload, length):
        f = self.flight
        fn = getattr(f, "on_msp_rc", None)
        if fn is None:
            return self._refuse("this firmware takes no MSP RC")
        if length < 8 or length & 1:
            return self._refuse("SET_RAW_RC needs 4..18 channels of 2 bytes")
        channels = msp.unpack_set_raw_rc(payload, length)
        for us in channels:
            if us < 750 or us > 2250:
                return self._refuse("SET_RAW_RC channel out of range 750..2250 us")
        reason = fn(f.board.now_us(), channels, len(channels))
        if reason:
            return self._refuse(str(reason))
        return b""

    def _set_pid(self, payload, length):
        if length < 9:
            return self._refuse("SET_PID needs roll, pitch and yaw (9 bytes)")
        rows = msp.unpack_pid(payload[:length])
        pairs = []
        for k, axis in ((0, "roll"), (1, "pitch"), (2, "yaw")):
            pairs.append(("p_" + axis, rows[k][0]))
            pairs.append(("i_" + axis, rows[k][1]))
            pairs.append(("d_" + axis, rows[k][2]))
        err = self.flight.params.update(pairs)
        return b"" if err is None else self._refuse(err)

    def _set_motor(self, payload, length):
        f = self.flight
        mt = getattr(f, "motor_test", None)
        if mt is None:
            return self._refuse("this firmware has no motor test")
        values = msp.unpack_set_motor(payload, length)
        n = f.motor_count
        if len(values) < n:
            return self._refuse("SET_MOTOR needs a value per motor")
        for k in range(n):
            if values[k] < 1000 or values[k] > 2000:
                return self._refuse("SET_MOTOR values must be 1000..2000")
        now = f.board.now_us()
        same = True
        for k in range(1, n):
            if values[k] != values[0]:
                same = False
        if same:
            reason = mt.request(now, -1, (values[0] - 1000) * 0.001, self.arming_disabled)
        else:
            reason = None
            for k in range(n):
                reason = reason or mt.request(now, k, (values[k] - 1000) * 0.001, self.arming_disabled)
        if reason:
            return self._refuse(str(reason))
        return b""


def reason_words(flags):
    """'NAME: sentence' for each set arming-disable bit (CLI status, reports)."""
    out = []
    for bit in range(32):
        if flags & (1 << bit):
            r = REASONS.get(bit)
            out.append("%s: %s" % r if r is not None else "BIT%d" % bit)
    return out
