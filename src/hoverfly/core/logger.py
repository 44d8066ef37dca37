"""The flight logger: the core's signals in, a PX4 ULog stream out to whatever sink the board gives.

Takes the Flight it logs (signals, PID terms, events, parameters, scheduler and link
statistics) and a sink (`open(sink)`: a RingSink the board drains in its slack, or a file).
Gives a ULog that pyulog, PlotJuggler and Flight Review read, with PX4 topic names where
one applies. Flight.step calls `update(now_us)` last in the pass while a sink is open (not a
task-table row: dispatching a task due every pass cost more than the logging it ran), so it
sees exactly what the pass consumed and produced; below the loop rate it logs every n-th pass.

Topics at the logging rate, one frame per run: vehicle_attitude, vehicle_angular_velocity
(the filtered gyro the PID used), vehicle_rates_setpoint, actuator_outputs (motor_out:
0 = stop, idle..1), sensor_combined (the aligned IMU sample the pass read; gyro_integral_dt
0 = no new sample that pass) and hoverfly_pid (P, I, D, F and sum per axis). input_rc is
written for every new receiver frame; battery_status, vehicle_status, hoverfly_loop and
hoverfly_link about ten times a second. Events (arming, failsafe, modes) become log strings,
parameter changes become `P` messages after that run's samples, and a sync marker goes out
about once a second.

Cost: on CPython the arrays the fast topics record live in the signals' pass record (core/
logframe.py), laid out as the frame: a run stores the timestamps and scalars through views and
copies the record into a preallocated staging buffer. Where there is no record (MicroPython) the
frame is one struct.pack_into with each array as one bytes argument. input_rc is staged behind,
and the sink gets one write per batch (STAGE_BYTES; flush() or close() hand over the rest); the
other topics run only when something changed. With no sink the pass skips the logger.
Figures: docs/logs.md "Logging cost", bench/log_loop.py.
"""

import struct
from array import array

from hoverfly.compat import IS_MICROPYTHON, ticks_diff
from hoverfly.core.arming import REASONS
from hoverfly.core.control import MODE_NAMES
from hoverfly.core.events import (
    DISARM_REASONS,
    EV_ARMING_BLOCKED,
    EV_CRASH,
    EV_DISARMED,
    EV_FAILSAFE_END,
    EV_FAILSAFE_STAGE1,
    EV_FAILSAFE_STAGE2,
    EV_IMU_FAULT,
    EV_MODE,
    EV_OUTPUT_FAILSAFE,
    EV_RX_LOST,
    EVENT_NAMES,
)
from hoverfly.core.logframe import (
    ARRAY_FIELDS,
    FAST_PACK,
    array_table,
    field_offsets,
    frame_format,
    header_offsets,
)
from hoverfly.core.params import PARAMS
from hoverfly.protocols.ulog import UlogWriter

_SLOW_HZ = 10  # battery, status, loop and link topics
_RC_CHANNELS = 18  # PX4 input_rc.values[18]
_U32_MAX = 0xFFFFFFFF
# The frames of several passes are packed straight into one staging buffer and handed to the sink
# in one write when the next pass's frame might not fit: the sink's per-write cost (~2.4 µs into a
# RingSink on CPython) is paid once per batch. 2 KiB (five passes) on the Pico, where RAM is
# short; 8 KiB (about 22 passes) elsewhere. Anything else the log holds (slow topics, strings,
# parameter changes, syncs) goes out after the staged frames, so the file stays in time order.
STAGE_BYTES = 2048 if IS_MICROPYTHON else 8192

# PX4 message definitions (PX4-Autopilot msg/*.msg), trimmed to what hoverfly has; the
# padding fields are left out (readers go by name). Every format starts with its timestamp.
VEHICLE_ATTITUDE = (
    ("uint64_t", "timestamp"),
    ("float[4]", "q"),
    ("float[4]", "delta_q_reset"),
    ("uint8_t", "quat_reset_counter"),
)
VEHICLE_ANGULAR_VELOCITY = (
    ("uint64_t", "timestamp"),
    ("uint64_t", "timestamp_sample"),
    ("float[3]", "xyz"),
    ("float[3]", "xyz_derivative"),
)
VEHICLE_RATES_SETPOINT = (
    ("uint64_t", "timestamp"),
    ("float", "roll"),
    ("float", "pitch"),
    ("float", "yaw"),
    ("float[3]", "thrust_body"),
    ("bool", "reset_integral"),
)
ACTUATOR_OUTPUTS = (
    ("uint64_t", "timestamp"),
    ("uint32_t", "noutputs"),
    ("float[16]", "output"),
)
SENSOR_COMBINED = (
    ("uint64_t", "timestamp"),
    ("float[3]", "gyro_rad"),
    ("uint32_t", "gyro_integral_dt"),
    ("int32_t", "accelerometer_timestamp_relative"),
    ("float[3]", "accelerometer_m_s2"),
    ("uint32_t", "accelerometer_integral_dt"),
    ("uint8_t", "accelerometer_clipping"),
    ("uint8_t", "gyro_clipping"),
    ("uint8_t", "accel_calibration_count"),
    ("uint8_t", "gyro_calibration_count"),
)
HOVERFLY_PID = (
    ("uint64_t", "timestamp"),
    ("float[3]", "sum"),
    ("float[3]", "p"),
    ("float[3]", "i"),
    ("float[3]", "d"),
    ("float[3]", "f"),
    ("float", "tpa"),
    ("bool", "i_active"),
    ("bool", "airmode_active"),
    ("bool", "saturated"),
)
INPUT_RC = (
    ("uint64_t", "timestamp"),
    ("uint64_t", "timestamp_last_signal"),
    ("int32_t", "rssi"),
    ("uint16_t", "rc_lost_frame_count"),
    ("uint16_t", "rc_total_frame_count"),
    ("uint16_t[18]", "values"),
    ("uint8_t", "channel_count"),
    ("bool", "rc_failsafe"),
    ("bool", "rc_lost"),
    ("uint8_t", "input_source"),
    ("int8_t", "link_quality"),
    ("float", "rssi_dbm"),
)
BATTERY_STATUS = (
    ("uint64_t", "timestamp"),
    ("float", "voltage_v"),
    ("float", "current_a"),
    ("float", "discharged_mah"),
    ("float", "remaining"),
    ("bool", "connected"),
)
VEHICLE_STATUS = (
    ("uint64_t", "timestamp"),
    ("uint64_t", "armed_time"),
    ("uint8_t", "arming_state"),
    ("uint8_t", "nav_state"),
    ("bool", "failsafe"),
    ("bool", "rc_signal_lost"),
    ("uint8_t", "hoverfly_mode"),
    ("uint8_t", "failsafe_state"),
    ("bool", "imu_ok"),
    ("bool", "gyro_calibrated"),
)
HOVERFLY_LOOP = (
    ("uint64_t", "timestamp"),
    ("uint32_t", "passes"),
    ("uint32_t", "cycle_us"),
    ("uint32_t", "cycle_max_us"),
    ("uint32_t", "jitter_max_us"),
    ("uint32_t", "overruns"),
    ("uint32_t", "log_frames"),
    ("uint32_t", "log_dropped"),
)
HOVERFLY_LINK = (
    ("uint64_t", "timestamp"),
    ("uint32_t", "frames"),
    ("uint32_t", "errors"),
    ("float", "frame_rate_hz"),
    ("uint8_t", "link_quality_pct"),
    ("float", "rssi_dbm"),
    ("bool", "rx_failsafe"),
    ("bool", "rx_ok"),
)

# Order of the formats in the file, and of the fast topics in the frame.
FORMATS = (
    ("vehicle_attitude", VEHICLE_ATTITUDE),
    ("vehicle_angular_velocity", VEHICLE_ANGULAR_VELOCITY),
    ("vehicle_rates_setpoint", VEHICLE_RATES_SETPOINT),
    ("actuator_outputs", ACTUATOR_OUTPUTS),
    ("sensor_combined", SENSOR_COMBINED),
    ("hoverfly_pid", HOVERFLY_PID),
    ("input_rc", INPUT_RC),
    ("battery_status", BATTERY_STATUS),
    ("vehicle_status", VEHICLE_STATUS),
    ("hoverfly_loop", HOVERFLY_LOOP),
    ("hoverfly_link", HOVERFLY_LINK),
)
FAST_TOPICS = ("vehicle_attitude", "vehicle_angular_velocity", "vehicle_rates_setpoint", "actuator_outputs",
               "sensor_combined", "hoverfly_pid")
SLOW_TOPICS = ("battery_status", "vehicle_status", "hoverfly_loop", "hoverfly_link")

# The fast frame's layout (FAST_PACK, one struct format per topic after its header) lives in
# core/logframe.py, with the pass record the signals' logged arrays live in where they can.
_RC_PACK = "<5sQQiHH36sBBBBbf"  # values[18] as the raw bytes of an array('H') of 18
_RC_PACK_VALUES = "<5sQQiHH18HBBBBbf"  # the same from 18 separate ints (any other channel source)

# array -> its raw bytes: array.tobytes on CPython (one C call); MicroPython's array has no
# tobytes, bytes(a) copies the same buffer there.
_raw = getattr(array, "tobytes", bytes)


def _raw_view(a):
    """Raw bytes of an array or a memoryview (the signals' record views on CPython)."""
    return a.tobytes()


def copy_arrays_py(dst, base, table, srcs):
    """Each array of `srcs` as raw bytes into `dst` at base + table[2k] (table[2k + 1] bytes).
    The plain twin of logger_viper.copy_arrays."""
    for k in range(len(srcs)):
        off = base + table[2 * k]
        n = table[2 * k + 1]
        dst[off : off + n] = bytes(srcs[k])[:n]


# On MicroPython the arrays are copied by a viper loop (no bytes object, no float boxed) after a
# pack of the scalars alone; on CPython one pack_into with the arrays' bytes is faster.
try:
    from hoverfly.core.logger_viper import copy_arrays as _copy_fast
except (SyntaxError, ImportError, NameError):
    _copy_fast = None

# PX4 vehicle_status constants: arming_state 1 standby / 2 armed; nav_state 10 acro, 15 stabilized.
_ARMING_STANDBY = 1
_ARMING_ARMED = 2
_NAV_STATES = (10, 15, 15)

_LEVEL_INFO = 6
_LEVEL_NOTICE = 5
_LEVEL_WARNING = 4
_LEVEL_ERROR = 3


def format_size(fields):
    """Payload bytes of a format given as (type, name) pairs of base types."""
    sizes = {"int8_t": 1, "uint8_t": 1, "bool": 1, "char": 1, "int16_t": 2, "uint16_t": 2,
             "int32_t": 4, "uint32_t": 4, "float": 4, "int64_t": 8, "uint64_t": 8, "double": 8}
    n = 0
    for type_str, _ in fields:
        i = type_str.find("[")
        if i < 0:
            n += sizes[type_str]
        else:
            n += sizes[type_str[:i]] * int(type_str[i + 1 : -1])
    return n


def event_text(event, detail):
    """Words for one event record, as the log strings and the simulator print them."""
    name = EVENT_NAMES[event] if 0 <= event < len(EVENT_NAMES) else "event%d" % event
    if event == EV_MODE:
        return "%s %s" % (name, MODE_NAMES[detail] if 0 <= detail < len(MODE_NAMES) else detail)
    if event == EV_ARMING_BLOCKED:
        return "%s %s" % (name, REASONS[detail][0] if detail in REASONS else detail)
    if event == EV_DISARMED:
        return "%s %s" % (name, DISARM_REASONS[detail] if 0 <= detail < len(DISARM_REASONS) else detail)
    return "%s %d" % (name, detail)


def _event_level(event):
    if event == EV_IMU_FAULT or event == EV_CRASH:
        return _LEVEL_ERROR
    if (event == EV_RX_LOST or event == EV_FAILSAFE_STAGE1 or event == EV_FAILSAFE_STAGE2
            or event == EV_FAILSAFE_END or event == EV_OUTPUT_FAILSAFE):
        return _LEVEL_WARNING
    if event == EV_ARMING_BLOCKED:
        return _LEVEL_NOTICE
    return _LEVEL_INFO


def param_to_ulog(row, value):
    """A parameter value as ULog can hold it: int -> int32, float -> float, a choice -> its index."""
    default = row[1]
    if isinstance(default, str):
        choices = row[4]
        for i in range(len(choices)):
            if choices[i] == value:
                return i
        return -1
    if isinstance(default, float):
        return float(value)
    return int(value)


class Logger:
    """Flight logger. `open(sink)` starts a log (definitions at the next pass), `close()` ends it;
    `active` is True while one is open (and blackbox_rate_hz > 0): Flight.step then calls
    `update(now_us)` every pass. `start(now_us)` is Flight.start's time (log time counts from it).

    Counters: frames (fast frames the sink took), dropped (fast and input_rc frames it refused),
    rc_frames, events, param_changes, bytes (of the fast frames and input_rc). Frames are staged
    and handed over in batches: flush() hands over the staged ones now.
    """

    def __init__(self, flight):
        self.flight = flight
        self.sink = None
        self.writer = None
        self.rate_hz = 0  # configured logging rate, 0 = off
        self.frames = 0
        self.dropped = 0
        self.rc_frames = 0
        self.events = 0
        self.param_changes = 0
        self.bytes = 0
        self.sys_name = "hoverfly"
        self._fmt = frame_format()
        self._fmt_gaps = frame_format(True)
        self._table = array_table()
        self._srcs = ()
        # How the arrays reach the frame: None = as bytes arguments of the one pack_into, else
        # copy_arrays(stage, frame offset, table, arrays) after a pack of the scalars.
        self.copy_arrays = _copy_fast
        self._copy = None  # copy_arrays for this log, None if an array's size does not match
        self._rawf = _raw
        self.record_path = True  # use the signals' pass record where it is backed (tests turn it off)
        self._rv = None
        self._fast_n = struct.calcsize(self._fmt)
        self._rc_n = struct.calcsize(_RC_PACK)
        self._stage = bytearray(STAGE_BYTES)
        self._stage_mv = memoryview(self._stage)
        self._stage_last = STAGE_BYTES - self._fast_n - self._rc_n  # flush once past this offset
        self._off = 0  # staged bytes
        self._staged = 0  # staged fast frames
        self._staged_rc = 0  # staged input_rc samples
        self._staged_t64 = 0  # time of the first staged frame
        self._rc_header = b"\0" * 5
        self._ids = {}
        self._sink_free = None
        self._t64 = 0
        self._slow_every = 100
        self._slow_left = 0
        self._ev_seen = 0
        self._rc_seen = 0
        self._par_seen = -1
        self._par_last = {}
        self._dropping = False
        self._drop_t64 = 0
        self._armed_t64 = 0
        self._h = []
        self._receiver = None
        self._dt_us = 1000
        self.active = False  # a sink is open and the rate is above 0: Flight.step calls update()
        self._start_us = 0  # Flight.start's tick time
        self._started = False
        self._from_start = False  # opened before Flight.start: log time counts from the start
        self._every_pass = True  # blackbox_rate_hz == loop_hz
        self._period_us = 1000  # 1 / blackbox_rate_hz
        self._pass_us = 1000  # 1 / loop_hz
        self._left_us = 0  # until the next logged pass, counted down by pass_us
        self._headers = None
        self._ctx = None
        self._rc_whole = False

    # ---------------------------------------------------------------- set-up
    def configure(self, params):
        """Read blackbox_rate_hz (capped at the loop rate) and the loop rate it divides."""
        rate = params.get("blackbox_rate_hz")
        loop_hz = params.get("loop_hz")
        if rate > loop_hz:
            rate = loop_hz
        self.rate_hz = rate
        self._dt_us = 1000000 // loop_hz  # gyro_integral_dt of a pass with a new IMU sample
        self._pass_us = self._dt_us
        self._apply_rate()

    def _apply_rate(self):
        rate = self.rate_hz
        self.active = self.sink is not None and rate > 0
        if rate <= 0:
            return
        every = rate // _SLOW_HZ
        self._slow_every = every if every > 0 else 1
        self._period_us = 1000000 // rate
        self._every_pass = self._period_us <= self._pass_us
        if self._left_us > self._period_us:
            self._left_us = self._period_us

    def start(self, now_us):
        """Flight.start: the time log timestamps count from (a log opened before it)."""
        self._start_us = now_us
        self._started = True

    def open(self, sink):
        """Start a log into `sink` (anything with write(bytes)); definitions go out at the next pass."""
        self.sink = sink
        self._off = 0
        self._staged = 0
        self._staged_rc = 0
        self._sink_free = getattr(sink, "free", None)
        self.writer = None
        self._from_start = not self._started
        self._left_us = 0  # the next pass logs
        self._apply_rate()

    def close(self):
        """End the log: the staged frames and a last sync; the sink's owner flushes and closes it."""
        if self.writer is not None:
            self.flush()
            self.writer.sync()
        self.sink = None
        self.writer = None
        self._apply_rate()

    def _begin(self, now_us):
        f = self.flight
        w = UlogWriter(self.sink, 0)
        self.writer = w
        for name, fields in FORMATS:
            w.add_format(name, fields)
        w.add_info("char[%d] sys_name" % len(self.sys_name), self.sys_name)
        board_name = getattr(f.board, "name", "board")
        w.add_info("char[%d] ver_hw" % len(board_name), board_name)
        try:
            from hoverfly import __version__ as version
        except ImportError:
            version = "0"
        w.add_info("char[%d] ver_sw" % len(version), version)
        w.add_info("int32_t hoverfly_motor_count", f.motor_count)
        values = f.params.values
        for row in PARAMS:
            v = param_to_ulog(row, values[row[0]])
            w.add_param(row[0], v)
            self._par_last[row[0]] = v
        self._par_seen = f.params.changed
        ids = {}
        for name, _ in FORMATS:
            ids[name] = w.subscribe(name)
        self._ids = ids
        rec = getattr(f, "receiver", None)
        self._receiver = rec if (rec is not None and hasattr(rec, "link_quality_pct")) else None
        headers = []
        for i in range(len(FAST_TOPICS)):
            size = struct.calcsize("<" + FAST_PACK[i])
            headers.append(struct.pack("<HBH", size + 2, 0x44, ids[FAST_TOPICS[i]]))
        self._rc_header = struct.pack("<HBH", struct.calcsize(_RC_PACK) - 3, 0x44, ids["input_rc"])
        # What the task reads every run, bound once: the stages fill these same objects in place.
        sig = f.signals
        c = f.controller
        self._headers = tuple(headers)
        self._ctx = (sig.setpoint, c, f.mixer, f.rc, f.events, f.params)
        self._srcs = (sig.attitude.q, sig.gyro_rad_s, sig.setpoint.rate_rad_s, sig.motor_out,
                      sig.gyro_raw_rad_s, sig.accel_raw_m_s2, sig.torque_norm, c.terms)
        copy = self.copy_arrays
        for k in range(len(self._srcs)):
            if len(bytes(self._srcs[k])) != self._table[2 * k + 1]:
                copy = None  # the copy would read past a short array: pack its bytes instead
        self._copy = copy
        self._rv = self._record_views(getattr(sig, "record", None), headers)
        self._rawf = _raw if isinstance(sig.gyro_rad_s, array) else _raw_view
        ch = sig.rc_channels_us
        self._rc_whole = len(ch) == _RC_CHANNELS and len(bytes(ch)) == 2 * _RC_CHANNELS
        # Log time is µs since Flight.start when the log was opened before it (from boot), else
        # it starts at 0 here (a tick difference over a long flight could wrap).
        t0 = 0
        if self._from_start and self._started:
            t0 = ticks_diff(now_us, self._start_us)
            if t0 < 0:
                t0 = 0
        self._t64 = t0
        # Events and the receiver frame from before this first run (the boot pass) go in too.
        self._ev_seen = 0
        self._rc_seen = 0
        self._slow_left = 0
        self._dropping = False
        w.maybe_sync(t0)

    def _record_views(self, record, headers):
        """The pass record path: when the signals' logged arrays are views into one frame-shaped
        block (core/logframe.py), the headers go in once and every pass stores the scalars
        through views and copies the block. None when they are not (MicroPython, or an array
        replaced since): the frame is packed instead."""
        if record is None or not record.backed or not self.record_path:
            return None
        for k in range(len(ARRAY_FIELDS)):
            if not record.holds(ARRAY_FIELDS[k][0], self._srcs[k]):
                return None
        buf = record.buf
        hs = header_offsets()
        for k in range(len(hs)):
            buf[hs[k] : hs[k] + len(headers[k])] = headers[k]
        ts = [record.view(off, "Q") for off, n in field_offsets("Q")]
        ints = [record.view(off, "I") for off, n in field_offsets("I")]
        floats = field_offsets("f")  # thrust_body[2], tpa
        flags = field_offsets("B")  # reset_integral, then i_active, airmode_active, saturated
        return (self._stage, buf, ts[0], ts[1], ts[2], ts[3], ts[4], ts[5], ts[6], record.view(floats[0][0], "f"),
                record.view(flags[0][0], "B"), ints[0], ints[1], ints[2], record.view(floats[1][0], "f"),
                record.view(flags[1][0], "B", 3))

    # ------------------------------------------------------------------ the pass
    def update(self, now_us):
        """One logged pass: Flight.step calls it last in the pass while `active`. Below the loop
        rate it counts passes down (in µs of the nominal period) and logs the due ones."""
        f = self.flight
        # Log time: the passes' own tick differences (Flight.step's pass_dt_us), summed in a plain
        # int: one add here instead of another ticks_diff (a Python function on CPython).
        t = self._t64 + f.pass_dt_us
        self._t64 = t
        if not self._every_pass:
            left = self._left_us - self._pass_us
            if left > 0:
                self._left_us = left
                return
            self._left_us = left + self._period_us
        if self.writer is None:
            self._begin(now_us)
            t = self._t64
        sp, c, mixer, rc, events, params = self._ctx
        dt_us = self._dt_us if f.imu_us == now_us else 0
        i_active = f.i_active
        off = self._off
        if off == 0:
            self._staged_t64 = t
        rv = self._rv
        if rv is not None:
            # The arrays are already in the record (the stages wrote them there): the scalars go in
            # through views, then the record is the frame.
            stage_copy, buf, v0, v1, v2, v3, v4, v5, v6, thrust_z, reset, nout, gdt, adt, tpa, flags = rv
            v0[0] = t
            v1[0] = t
            v2[0] = t
            v3[0] = t
            v4[0] = t
            v5[0] = t
            v6[0] = t
            thrust_z[0] = -sp.throttle_norm
            reset[0] = 0 if i_active else 1
            nout[0] = f.motor_count
            gdt[0] = dt_us
            adt[0] = dt_us
            tpa[0] = c.tpa
            flags[0] = 1 if i_active else 0
            flags[1] = 1 if f.airmode_active else 0
            flags[2] = 1 if mixer.saturated else 0
            stage_copy[off : off + self._fast_n] = buf
        else:
            self._pack(off, t, dt_us, i_active, sp, c, mixer)
        off += self._fast_n
        self._staged += 1
        if rc.frames != self._rc_seen:
            self._rc_seen = rc.frames
            off = self._stage_rc(off, t)
        self._off = off
        if off > self._stage_last:
            self._flush()
        if events.count != self._ev_seen:
            self._log_events(now_us, t)
        if params.changed != self._par_seen:
            self._log_param_changes(t)
        left = self._slow_left - 1
        if left > 0:
            self._slow_left = left
        else:
            self._slow_left = self._slow_every
            self._log_slow(t)

    def _pack(self, off, t, dt_us, i_active, sp, c, mixer):
        """The frame packed into the staging buffer at `off` (no pass record: MicroPython)."""
        f = self.flight
        h0, h1, h2, h3, h4, h5 = self._headers
        q, g, rs, mo, gr, ar, tq, pt = self._srcs
        copy = self._copy
        if copy is None:
            # One C call packs the whole frame (headers, the seven copies of the timestamp, the
            # scalars); each array signal goes in as one bytes object.
            raw = self._rawf
            struct.pack_into(
                self._fmt, self._stage, off,
                h0, t, raw(q),
                h1, t, t, raw(g),
                h2, t, raw(rs), -sp.throttle_norm, 0 if i_active else 1,
                h3, t, f.motor_count, raw(mo),
                h4, t, raw(gr), dt_us, raw(ar), dt_us,
                h5, t, raw(tq), raw(pt), c.tpa,
                1 if i_active else 0, 1 if f.airmode_active else 0, 1 if mixer.saturated else 0,
            )
        else:
            struct.pack_into(
                self._fmt_gaps, self._stage, off,
                h0, t,
                h1, t, t,
                h2, t, -sp.throttle_norm, 0 if i_active else 1,
                h3, t, f.motor_count,
                h4, t, dt_us, dt_us,
                h5, t, c.tpa,
                1 if i_active else 0, 1 if f.airmode_active else 0, 1 if mixer.saturated else 0,
            )
            copy(self._stage, off, self._table, self._srcs)

    def flush(self):
        """Hand the staged frames to the sink now (close() and every other log write do this first)."""
        if self._off > 0 and self.sink is not None:
            self._flush()

    def _flush(self):
        n = self._off
        if n == 0:
            return
        frames = self._staged
        rc = self._staged_rc
        self._off = 0
        self._staged = 0
        self._staged_rc = 0
        if self._write(self.sink, self._stage_mv[:n], self._staged_t64):
            self.frames += frames
            self.rc_frames += rc
            self.bytes += n
        else:
            self.dropped += frames + rc

    def _write(self, sink, buf, t):
        """One batch to the sink, whole or not at all; a refused batch opens a dropout (from `t`, its
        first frame's time) that the next batch to fit closes."""
        n = len(buf)
        if self._dropping:
            free = self._sink_free
            if free is not None and free() < n + 5:
                return False
            ms = (t - self._drop_t64) // 1000
            self.writer.dropout(ms)
            self._dropping = False
        try:
            got = sink.write(buf)
        except OSError:
            got = 0
        if got is not None and got < n:
            if not self._dropping:
                self._dropping = True
                self._drop_t64 = t
            return False
        return True

    def _stage_rc(self, off, t):
        """input_rc for the new receiver frame, staged after this run's frame; returns the new offset."""
        f = self.flight
        ch = f.signals.rc_channels_us
        rec = self._receiver
        if rec is not None:
            lq = rec.link_quality_pct
            lq = 0 if lq < 0 else (100 if lq > 100 else lq)
            fs = 1 if rec.rx_failsafe else 0
            total = rec.frames & 0xFFFF
            errors = rec.errors & 0xFFFF
            rssi_dbm = rec.rssi_dbm
        else:
            lq = 100 if f.rx_ok else 0
            fs = 0
            total = f.rc.frames & 0xFFFF
            errors = 0
            rssi_dbm = 0
        if self._rc_whole:
            struct.pack_into(_RC_PACK, self._stage, off, self._rc_header, t, t, lq, errors, total, _raw(ch),
                             _RC_CHANNELS, fs, 0 if f.rx_ok else 1, 0, lq, rssi_dbm)
        else:  # another board's channel source: pad or cut to PX4's 18
            v = [0] * _RC_CHANNELS
            for i in range(len(ch) if len(ch) < _RC_CHANNELS else _RC_CHANNELS):
                v[i] = ch[i]
            struct.pack_into(_RC_PACK_VALUES, self._stage, off, self._rc_header, t, t, lq, errors, total, *v,
                             len(ch), fs, 0 if f.rx_ok else 1, 0, lq, rssi_dbm)
        self._staged_rc += 1
        return off + self._rc_n

    def _log_events(self, now_us, t):
        self._flush()
        self._h = []
        self._ev_seen = self.flight.events.drain(self._ev_seen, self._collect_event)
        w = self.writer
        for et, event, detail in self._h:
            # Back-date by the event's age in ticks (it may come from an earlier pass).
            age = ticks_diff(now_us, et)
            te = t - age if 0 <= age <= t else t
            w.log_message(_event_level(event), te, event_text(event, detail))
            self.events += 1
        self._h = []

    def _collect_event(self, t_us, event, detail):
        self._h.append((t_us, event, detail))

    def _log_param_changes(self, t):
        self._flush()
        f = self.flight
        self._par_seen = f.params.changed
        values = f.params.values
        last = self._par_last
        w = self.writer
        for row in PARAMS:
            name = row[0]
            v = param_to_ulog(row, values[name])
            if last.get(name) != v:
                last[name] = v
                w.param_change(name, v, t)
                self.param_changes += 1

    def _log_slow(self, t):
        self._flush()
        f = self.flight
        w = self.writer
        ids = self._ids
        s = f.signals
        armed = f.arming.armed
        if armed and self._armed_t64 == 0:
            self._armed_t64 = t if t > 0 else 1
        elif not armed:
            self._armed_t64 = 0
        mah = getattr(s, "mah_drawn", 0.0)
        w.write_data(ids["battery_status"], t, (s.battery_v, s.current_a, mah, -1.0, s.battery_v > 0.5))
        mode = f.signals.setpoint.mode
        fs_state = f.failsafe.state
        w.write_data(ids["vehicle_status"], t, (
            self._armed_t64, _ARMING_ARMED if armed else _ARMING_STANDBY,
            _NAV_STATES[mode] if 0 <= mode < 3 else 0, fs_state != 0, not f.rx_ok,
            _clamp_int(mode, 0, 255), _clamp_int(fs_state, 0, 255), f.imu_ok, f.calibration.calibrated))
        sc = f.scheduler
        w.write_data(ids["hoverfly_loop"], t, (
            _clamp_int(sc.passes, 0, _U32_MAX), _clamp_int(sc.cycle_us, 0, _U32_MAX),
            _clamp_int(sc.cycle_max_us, 0, _U32_MAX), _clamp_int(sc.jitter_max_us, 0, _U32_MAX),
            _clamp_int(sc.overruns, 0, _U32_MAX), _clamp_int(self.frames, 0, _U32_MAX),
            _clamp_int(self.dropped, 0, _U32_MAX)))
        rec = getattr(f, "receiver", None)
        if rec is not None:
            link = (_clamp_int(getattr(rec, "frames", 0), 0, _U32_MAX),
                    _clamp_int(getattr(rec, "errors", 0), 0, _U32_MAX),
                    float(getattr(rec, "frame_rate_hz", 0.0)),
                    _clamp_int(getattr(rec, "link_quality_pct", 0), 0, 100),
                    float(getattr(rec, "rssi_dbm", 0.0)), bool(getattr(rec, "rx_failsafe", False)), f.rx_ok)
        else:
            link = (_clamp_int(f.rc.frames, 0, _U32_MAX), 0, 0.0, 100 if f.rx_ok else 0, 0.0, False, f.rx_ok)
        w.write_data(ids["hoverfly_link"], t, link)
        w.maybe_sync(t)


def _clamp_int(v, lo, hi):
    try:
        v = int(v)
    except (TypeError, ValueError):
        return lo
    if v < lo:
        return lo
    if v > hi:
        return hi
    return v

