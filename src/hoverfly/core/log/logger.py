"""The flight logger: the core's signals in, a PX4 ULog stream out to whatever sink the board gives.

Takes the Flight it logs (signals, PID terms, events, parameters, scheduler and link
statistics) and a sink (`open(sink)`: a RingSink the board drains in its slack, or a file).
Gives a ULog that pyulog, PlotJuggler and Flight Review read, with PX4 topic names where
one applies. Flight.step calls `update(now_us)` last in the pass while a sink is open, through
`Flight.log_pass`, which the logger keeps set to its `update` (None with no sink; not a task-table
row: dispatching a task due every pass cost more than the logging it ran), so it sees exactly what
the pass consumed and produced; below the loop rate it logs every n-th pass.

Topics at the logging rate, one frame per run: vehicle_attitude, vehicle_angular_velocity
(the filtered gyro the PID used), vehicle_rates_setpoint, actuator_outputs (motor_out:
0 = stop, idle..1), sensor_combined (the aligned IMU sample the pass read; gyro_integral_dt
0 = no new sample that pass) and hoverfly_pid (P, I, D, F and sum per axis, the mode). input_rc is
written for every new receiver frame; actuator_servos (PX4's: a plane's or a tricopter's servo
widths as control -1..1 = 1000..2000 µs) at most every SERVO_LOG_US, looked at once a batch;
airspeed (PX4's: a plane's pitot, indicated and true m/s) at most every AIRSPEED_LOG_US while the board has one;
battery_status, vehicle_status, hoverfly_loop and hoverfly_link about ten times a second. Events
(arming, failsafe, modes) become log strings, parameter changes become `P` messages after that
run's samples, and a sync marker goes out about once a second.

Cost: on CPython the arrays the fast topics record live in the signals' pass record (core/
logframe.py), laid out as the frame: a logged pass is one pack of the changing scalars (with the
log time, as hoverfly_pid's timestamp) and one copy of the record into the staging buffer
(`_fast_update`, a closure installed as `update` while every pass is logged); the flush copies
that timestamp over the batch's six other timestamp fields with one strided store each. Where
there is no record (MicroPython) the frame is one struct.pack_into with each array as one bytes
argument. input_rc waits in its own buffer and goes behind the batch's frames; while the closure
is installed Flight.task_rx hands each new receiver frame to it (`Flight.log_rc`), else each
logged pass looks for one. The sink gets one write per batch (STAGE_FRAMES passes; flush() or
close() hand over the rest); events and the slow topics (one pack of all four) are looked at once
a batch. With no sink the pass skips the logger.
Figures: docs/logs.md "Logging cost", bench/log_loop.py.
"""

import struct
from array import array

from hoverfly.compat import IS_MICROPYTHON, ticks_diff
from hoverfly.core.config.params import PARAMS
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
from hoverfly.core.log.logframe import (
    ARRAY_FIELDS,
    FAST_PACK,
    HEADER_BYTES,
    field_offsets,
    frame_format,
    header_offsets,
)
from hoverfly.core.safety.arming import REASONS
from hoverfly.core.scheduler import PS_CYCLE, PS_CYCLE_MAX, PS_JITTER_MAX, PS_PASSES
from hoverfly.core.stages.control import MODE_NAMES
from hoverfly.protocols.ulog import UlogWriter

_SLOW_HZ = 10  # battery, status, loop and link topics
# A batch of staged frames goes to the sink at least 20 times a second on CPython, 50 on MicroPython
# (fewer frames a batch at low logging rates); events and the slow topics are looked at when a batch goes (an event
# carries its own time: it is back-dated to when it happened). Parameter changes are looked for
# every logged pass: replay applies each after the pass it was logged with.
_BATCH_HZ = 50 if IS_MICROPYTHON else 20
_RC_CHANNELS = 18  # PX4 input_rc.values[18]
_U32_MAX = 0xFFFFFFFF
# The frames of several passes are staged in one buffer and handed to the sink in one write when
# a batch is full: the sink's per-write cost (~2.4 µs into a RingSink on CPython) is paid once
# per batch. The fast frames sit back to back at a fixed stride, the batch's input_rc samples go
# after them at the flush. Up to 5 passes (about 2 KiB) on the Pico, where RAM is short; 50
# (about 20 KiB) elsewhere. Anything else the log holds (slow topics, strings, parameter
# changes, syncs) goes out after the staged frames.
STAGE_FRAMES = 5 if IS_MICROPYTHON else 50

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
    ("float", "tpa"),
    ("bool", "i_active"),
    ("bool", "airmode_active"),
    ("bool", "saturated"),
    ("uint8_t", "mode"),  # the controller's mode this pass: 0 acro, 1 angle, 2 horizon
    ("float[3]", "sum"),
    ("float[3]", "p"),
    ("float[3]", "i"),
    ("float[3]", "d"),
    ("float[3]", "f"),
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
ACTUATOR_SERVOS = (  # PX4's actuator_servos: control[i] = (servo_us[i] - 1500) / 500
    ("uint64_t", "timestamp"),
    ("uint64_t", "timestamp_sample"),
    ("float[8]", "control"),
)
SERVO_LOG_US = 20000  # actuator_servos every 20 ms at most: the 50 Hz frame of an analog servo
AIRSPEED = (  # PX4's airspeed; hoverfly has no static pressure or air temperature, so true = indicated
    ("uint64_t", "timestamp"),
    ("uint64_t", "timestamp_sample"),
    ("float", "indicated_airspeed_m_s"),
    ("float", "true_airspeed_m_s"),
    ("float", "confidence"),
)
AIRSPEED_LOG_US = 50000  # airspeed every 50 ms at most: enough for a pilot's trace of a 50 Hz pitot
HOVERFLY_NOTCH = (  # with the slow topics, for a craft with ESC telemetry or a dynamic notch (`hoverfly log report`)
    ("uint64_t", "timestamp"),
    ("float[8]", "motor_hz"),  # each motor's rotation frequency from its eRPM, 0 without a valid reply
    ("float[9]", "dyn_notch_hz"),  # the dynamic notches' centres, axis by axis (3 each), 0 = off
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
    ("actuator_servos", ACTUATOR_SERVOS),
    ("hoverfly_notch", HOVERFLY_NOTCH),
    ("airspeed", AIRSPEED),
)
FAST_TOPICS = ("vehicle_attitude", "vehicle_angular_velocity", "actuator_outputs", "sensor_combined",
               "vehicle_rates_setpoint", "hoverfly_pid")
SLOW_TOPICS = ("battery_status", "vehicle_status", "hoverfly_loop", "hoverfly_link")

# The fast frame's layout (FAST_PACK, one struct format per topic after its header) lives in
# core/log/logframe.py, with the pass record the signals' logged arrays live in where they can.
# The record path's changing scalars, one run of the frame (core/log/logframe.py): rates setpoint
# thrust_body[2], reset_integral; hoverfly_pid header, timestamp, tpa, i_active, airmode_active,
# saturated, mode. ('?' is CPython's: the record path is CPython's.)
_SCALARS = "<f?5sQf???B"
_RC_PACK = "<5sQQiHH36sBBBBbf"  # values[18] as the raw bytes of an array('H') of 18
_RC_PACK_VALUES = "<5sQQiHH18HBBBBbf"  # the same from 18 separate ints (any other channel source)

# array -> its raw bytes: array.tobytes on CPython (one C call); MicroPython's array has no
# tobytes, bytes(a) copies the same buffer there.
_raw = getattr(array, "tobytes", bytes)
_pack_into = struct.pack_into  # the closures' one global look-up (a free variable costs a copy per call)


def _raw_view(a):
    """Raw bytes of an array or a memoryview (the signals' record views on CPython)."""
    return a.tobytes()

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
        self.errors = 0  # logger calls from the pass that raised: each one stopped the log (_failed)
        self.error = None  # the last exception they raised
        self.sys_name = "hoverfly"
        self._fmt = frame_format()
        self._srcs = ()
        self._rawf = _raw
        self.record_path = True  # use the signals' pass record where it is backed (tests turn it off)
        # The pass record path (_record_views): the record's bytes (None: the frame is packed), where
        # its run of changing scalars starts, and views of its constant fields.
        self._rec = None
        self._fast = False  # _fast_update installed as update
        self._fast_sync = None  # writes its time, staged count and last receiver frame back (_fast_update)
        self._at_thrust = 0  # the run of changing scalars (_SCALARS) from thrust_body[2]
        self._pid_header = b""  # hoverfly_pid's header, inside that run
        self._nout = None  # actuator_outputs.noutputs
        self._integral_dt = ()  # sensor_combined gyro_integral_dt, accelerometer_integral_dt
        self._fast_n = struct.calcsize(self._fmt)  # a whole number of 8-byte words (core/log/logframe.py)
        self._rc_n = struct.calcsize(_RC_PACK)
        # The stage: up to `_batch` fast frames at a stride of _fast_n bytes, and room after them for
        # as many input_rc samples (at most one per logged pass), which wait in _rc_stage until the
        # flush puts them behind the batch's frames.
        self._batch = STAGE_FRAMES
        self._stage = bytearray(self._batch * (self._fast_n + self._rc_n))
        self._stage_mv = memoryview(self._stage)
        self._rc_stage = bytearray(self._batch * self._rc_n)
        self._t_views = ()  # each fast timestamp field but hoverfly_pid's of the staged frames as a 'Q' view
        self._t_pid = None  # hoverfly_pid's timestamp of the staged frames (packed with each pass's scalars)
        self._staged = 0  # staged fast frames
        self._rc_off = 0  # staged input_rc bytes (_rc_n a sample)
        self._rc_ch = None  # the signals' rc_channels_us (bound at _begin)
        self._imu_fresh = True  # the record's integral_dt fields hold _dt_us (else 0: no new sample)
        self._rc_header = b"\0" * 5
        self._ids = {}
        self._sink_free = None
        self._t64 = 0
        self._batch_n = self._batch  # frames a batch at this logging rate
        self._slow_every = 5  # batches between slow topics
        self._servo_t = -SERVO_LOG_US  # log time of the last actuator_servos
        self._airspeed_t = -AIRSPEED_LOG_US  # log time of the last airspeed
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
        self._slow_fmt = ""  # battery_status, vehicle_status, hoverfly_loop, hoverfly_link: one pack
        self._slow_heads = ()
        self._slow_buf = None
        self._dt_us = 1000
        self.active = False  # a sink is open and the rate is above 0: Flight.step calls update()
        # The two calls the flight makes into the logger, kept on the Flight so a pass pays one
        # attribute look-up for each: Flight.step calls log_pass(now_us) last in a pass (`update`
        # while active, else None); Flight.task_rx calls log_rc() on each new receiver frame while
        # the every-pass closure is installed (it stages input_rc; else None and update() looks).
        flight.log_pass = None
        flight.log_rc = None
        self._fast_rc = None  # the closure's input_rc stager (_fast_update)
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
        if self._rec is not None:
            self._record_constants()
        self._apply_rate()

    def _apply_rate(self):
        rate = self.rate_hz
        self.active = self.sink is not None and rate > 0
        if rate <= 0:
            self._hand_over()
            return
        n = rate // _BATCH_HZ
        self._batch_n = self._batch if n > self._batch else (n if n > 0 else 1)
        every = rate // self._batch_n // _SLOW_HZ
        self._slow_every = every if every > 0 else 1
        self._period_us = 1000000 // rate
        self._every_pass = self._period_us <= self._pass_us
        if self._left_us > self._period_us:
            self._left_us = self._period_us
        self._use_fast_update(False)  # the next logged pass picks the path again

    def start(self, now_us):
        """Flight.start: the time log timestamps count from (a log opened before it)."""
        self._start_us = now_us
        self._started = True

    def open(self, sink):
        """Start a log into `sink` (anything with write(bytes)); definitions go out at the next pass."""
        if self._fast:
            self._use_fast_update(False)
        self.sink = sink
        self._staged = 0
        self._rc_off = 0
        self._sink_free = getattr(sink, "free", None)
        self.writer = None
        self._from_start = not self._started
        self._left_us = 0  # the next pass logs
        self._apply_rate()

    def close(self):
        """End the log: the staged frames and a last sync; the sink's owner flushes and closes it."""
        if self._fast:
            self._use_fast_update(False)
        if self.writer is not None:
            self._check(None, self._t64)  # events since the last look
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
        self._ctx = (sig.setpoint, c, f.mixer, f.rc, f.params)
        self._srcs = (sig.attitude.q, sig.gyro_rad_s, sig.motor_out, sig.gyro_raw_rad_s, sig.accel_raw_m_s2,
                      sig.setpoint.rate_rad_s, sig.torque_norm, c.terms)
        self._rec = self._record_views(getattr(sig, "record", None), headers)
        self._rawf = _raw if isinstance(sig.gyro_rad_s, array) else _raw_view
        ch = sig.rc_channels_us
        self._rc_ch = ch
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
        self._slow_left = self._slow_every
        self._servo_t = t0 - SERVO_LOG_US
        self._airspeed_t = t0 - AIRSPEED_LOG_US
        self._dropping = False
        # The slow topics go out as one run of their four D messages, packed in one go (_log_slow).
        fmt = "<"
        heads = []
        for name in SLOW_TOPICS:
            head, payload = w.data_layout(ids[name])
            heads.append(head)
            fmt += "5s" + payload
        self._slow_fmt = fmt
        self._slow_heads = tuple(heads)
        self._slow_buf = bytearray(struct.calcsize(fmt))
        w.maybe_sync(t0)
        self._check(now_us, t0)
        self._log_slow(t0)

    def _record_views(self, record, headers):
        """The pass record path: when the signals' logged arrays are views into one frame-shaped
        block (core/log/logframe.py), the headers and constant fields go in once, every pass packs
        the changing scalars into it and copies the block; returns the block's bytes. None when
        they are not (MicroPython, or an array replaced since): the frame is packed instead."""
        if record is None or not record.backed or not self.record_path:
            return None
        for k in range(len(ARRAY_FIELDS)):
            if not record.holds(ARRAY_FIELDS[k][0], self._srcs[k]):
                return None
        buf = record.buf
        hs = header_offsets()
        for k in range(len(hs)):
            buf[hs[k] : hs[k] + len(headers[k])] = headers[k]
        # The timestamps go in once per batch (_flush), a strided store per field into the stage.
        n = self._fast_n
        words = (self._batch - 1) * (n // 8) + 1  # from the field in frame 0 to it in the last frame
        views = [self._stage_mv[off : off + 8 * words].cast("Q") for off, _ in field_offsets("Q")]
        self._t_pid = views.pop()  # hoverfly_pid's, the frame's last
        self._t_views = tuple(views)
        ints = [record.view(off, "I") for off, _ in field_offsets("I")]
        self._nout = ints[0]
        self._integral_dt = (ints[1], ints[2])
        self._imu_fresh = True
        self._record_constants()
        # The scalars that change pass to pass are one run, one pack (_SCALARS): thrust_body[2] and
        # reset_integral, then hoverfly_pid's header and timestamp (the flush fills that in), tpa,
        # i_active, airmode_active, saturated and mode.
        floats = field_offsets("f")
        if floats[1][0] - floats[0][0] != struct.calcsize(_SCALARS) - struct.calcsize("<f???B"):
            return None  # a layout without the run (core/log/logframe.py): pack the frame
        self._at_thrust = floats[0][0]
        self._pid_header = headers[len(headers) - 1]
        return buf

    def _record_constants(self):
        """The record's fields that change only on configure, or when a pass has no new IMU sample
        (integral_dt 0, until the samples come again)."""
        self._nout[0] = self.flight.motor_count
        dt = self._dt_us if self._imu_fresh else 0
        self._integral_dt[0][0] = dt
        self._integral_dt[1][0] = dt

    # ------------------------------------------------------------------ the pass
    def update(self, now_us):
        """One logged pass: Flight.step calls it last in the pass while `active`. Below the loop
        rate it counts passes down (in µs of the nominal period) and logs the due ones. Logging
        every pass into the pass record (CPython), the first pass installs `_fast_update` in its
        place."""
        # SAFETY: whatever the logging raises ends the log (_failed), never the pass that called it. (This frame
        # is on the heap already, so the try costs no frame of its own.)
        try:
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
            sp, c, mixer, rc, params = self._ctx
            i = self._staged
            rec = self._rec
            if rec is not None:
                i_active = f.commander.i_active
                struct.pack_into(_SCALARS, rec, self._at_thrust, -sp.throttle_norm, not i_active, self._pid_header, t,
                                 c.tpa, i_active, f.commander.airmode_active, mixer.saturated, sp.mode)
                if (f.imu_us == now_us) is not self._imu_fresh:
                    self._imu_fresh = not self._imu_fresh
                    self._record_constants()
                n = self._fast_n
                self._stage[i * n : i * n + n] = rec
            else:
                self._pack(i * self._fast_n, t, now_us, sp, c, mixer)
            i += 1
            self._staged = i
            if rc.frames != self._rc_seen:
                self._rc_seen = rc.frames
                self._stage_rc(t)
            if i >= self._batch_n:
                self._batch_full(now_us, t)
            if params.changed != self._par_seen:
                self._log_param_changes(t)
            if rec is not None and self._every_pass and self._imu_fresh:
                self._use_fast_update(True)  # last: the closure starts from this pass's state
        except Exception as exc:  # noqa: BLE001
            self._failed(exc)

    def _use_fast_update(self, on):
        """Install (on) or remove the every-pass record-path update as this logger's `update`. While
        it is installed a parameter write removes it (Params.on_change), so the pass that brought
        the change takes update() and logs it."""
        params = self.flight.params
        if self._fast:
            self._fast_sync()
        self._fast = on
        if on:
            self.update = self._fast_update()
            params.on_change = self.full_pass_next
        else:
            params.on_change = None
            try:
                del self.update
            except (AttributeError, KeyError, TypeError):
                pass
        self._hand_over()

    def _hand_over(self):
        """The flight's calls into the logger follow `active` and the closure (log_pass, log_rc)."""
        f = self.flight
        f.log_pass = self.update if self.active else None
        f.log_rc = self._fast_rc if self._fast and self.active else None
        f.logging_changed()

    def _failed(self, exc):
        """A logger call from the pass raised exc: counted and kept, and the log stops here (its sink is dropped
        without a last write, which could raise again; the sink's owner still closes it). SAFETY: the flight's
        calls into the logger are taken away first, so the pass that raised is the last one to log."""
        self.errors += 1
        self.error = exc
        f = self.flight
        try:
            f.scheduler.errors += 1  # the loop's count of what its boundaries caught (the built-in test's)
        except Exception:  # noqa: BLE001, S110 - a flight without one
            pass
        f.log_pass = None
        f.log_rc = None
        self.sink = None
        self.writer = None
        self.active = False
        try:
            if self._fast:
                self._fast = False
                self.flight.params.on_change = None
                del self.update
        except Exception:  # noqa: BLE001, S110 - already stopping: nothing more to undo
            pass
        try:
            f.logging_changed()
        except Exception:  # noqa: BLE001, S110
            pass

    def error_text(self):
        """The last exception a logger call raised, one line ("" if none)."""
        e = self.error
        return "" if e is None else "%s: %s" % (type(e).__name__, e)

    def full_pass_next(self):
        """The next logged pass takes update()'s full path, which looks at the parameters and the
        IMU sample (Params.on_change; Flight.step on a pass with no new sample)."""
        if self._fast:
            self._use_fast_update(False)

    def _fast_update(self):
        """`update` for the common case, logging every pass into the pass record (CPython): the
        same steps as update()'s record path with everything it reads bound once, as a closure
        (the every-pass path's attribute look-ups and branches cost more than the logging). The
        stages wrote the arrays into the record; the constant fields were set once; one pack stores
        the changing scalars and the log time (hoverfly_pid's timestamp: the batch's flush copies
        it to the other six); the record is copied into the stage. The log time and the staged
        count live in the closure while it is installed (cells cost less than the logger's
        attributes); `_fast_sync` writes them back, and everything else that reads them (flush,
        close, removing the closure) calls it first. It does not look for receiver frames: with it
        comes `_fast_rc`, which Flight.task_rx calls on each (Flight.log_rc), stamped with the time
        of the pass it came in. Nor does it look at the parameters or the IMU sample: a parameter
        write or a pass without a new sample removes it (full_pass_next) and update() does, until
        the sample is fresh again."""
        lg = self
        f = self.flight
        cm = f.commander  # i_active, airmode_active
        sp, c, mixer, rc, _ = self._ctx
        stage = self._stage
        buf = self._rec
        at_thrust = self._at_thrust
        pid_header = self._pid_header
        n = self._fast_n
        batch_n = self._batch_n
        slots = tuple(slice(k * n, k * n + n) for k in range(batch_n))  # each staged frame's bytes
        t = self._t64
        i = self._staged

        def update(now_us):
            nonlocal t, i
            try:  # SAFETY: as update()'s: the log ends, the pass goes on
                t += f.pass_dt_us
                i_active = cm.i_active
                _pack_into(_SCALARS, buf, at_thrust, -sp.throttle_norm, not i_active, pid_header, t, c.tpa,
                           i_active, cm.airmode_active, mixer.saturated, sp.mode)
                stage[slots[i]] = buf
                i += 1
                if i >= batch_n:
                    lg._t64 = t
                    lg._staged = i
                    lg._batch_full(now_us, t)
                    i = lg._staged
            except Exception as exc:  # noqa: BLE001
                lg._failed(exc)

        # input_rc for a new receiver frame (Flight.task_rx, earlier in the pass: this pass's time is
        # t + pass_dt_us). From a receiver that reports its link the same pack as _stage_rc's.
        receiver = self._receiver
        if receiver is not None and self._rc_whole:
            rc_stage = self._rc_stage
            rc_n = self._rc_n
            rc_header = self._rc_header
            ch = self._rc_ch

            def rc_frame():
                try:  # SAFETY: as update()'s: the log ends, the receiver task goes on
                    tt = t + f.pass_dt_us
                    lq = receiver.link_quality_pct
                    if lq > 100:
                        lq = 100
                    elif lq < 0:
                        lq = 0
                    off = lg._rc_off
                    _pack_into(_RC_PACK, rc_stage, off, rc_header, tt, tt, lq, receiver.errors & 0xFFFF,
                               receiver.frames & 0xFFFF, _raw(ch), _RC_CHANNELS, receiver.rx_failsafe, not f.rx_ok,
                               0, lq, receiver.rssi_dbm)
                    lg._rc_off = off + rc_n
                except Exception as exc:  # noqa: BLE001
                    lg._failed(exc)
        else:

            def rc_frame():
                try:
                    lg._stage_rc(t + f.pass_dt_us)
                except Exception as exc:  # noqa: BLE001
                    lg._failed(exc)

        def sync():
            lg._t64 = t
            lg._staged = i
            lg._rc_seen = rc.frames  # every frame so far went through rc_frame

        self._fast_sync = sync
        self._fast_rc = rc_frame
        return update

    def _batch_full(self, now_us, t):
        """A full batch to the sink, then the events since the last batch and, every
        `_slow_every` batches (about ten times a second), the slow topics."""
        self._flush()
        self._check(now_us, t)
        if t - self._servo_t >= SERVO_LOG_US:
            self._log_servos(t)
        if self.flight.signals.airspeed_valid and t - self._airspeed_t >= AIRSPEED_LOG_US:
            self._log_airspeed(t)
        left = self._slow_left - 1
        if left > 0:
            self._slow_left = left
        else:
            self._slow_left = self._slow_every
            self._log_slow(t)
            self._log_notch(t)

    def _check(self, now_us, t):
        """Events since the last look (each batch, and at close with now_us None: stamped `t`)."""
        if self.flight.events.count != self._ev_seen:
            self._log_events(now_us, t)

    def _pack(self, off, t, now_us, sp, c, mixer):
        """The frame packed into the staging buffer at `off` (no pass record: MicroPython): one C
        call packs the whole frame (headers, the seven copies of the timestamp, the scalars); each
        array signal goes in as one bytes object."""
        f = self.flight
        h0, h1, h2, h3, h4, h5 = self._headers
        q, g, mo, gr, ar, rs, tq, pt = self._srcs
        raw = self._rawf
        dt_us = self._dt_us if f.imu_us == now_us else 0
        i_active = f.commander.i_active
        struct.pack_into(
            self._fmt, self._stage, off,
            h0, t, raw(q),
            h1, t, t, raw(g),
            h2, t, f.motor_count, raw(mo),
            h3, t, raw(gr), dt_us, raw(ar), dt_us,
            h4, t, raw(rs), -sp.throttle_norm, 0 if i_active else 1,
            h5, t, c.tpa, 1 if i_active else 0, 1 if f.commander.airmode_active else 0, 1 if mixer.saturated else 0,
            sp.mode, raw(tq), raw(pt),
        )

    def flush(self):
        """Hand the staged frames to the sink now (close() and every other log write do this first).
        The every-pass closure goes too: its count of staged frames would still hold the ones
        handed over here; the next pass takes update(), which puts it back."""
        if self._fast:
            self._use_fast_update(False)
        if self._staged > 0 and self.sink is not None:
            self._flush()

    def _flush(self):
        frames = self._staged
        if frames == 0:
            return
        n = frames * self._fast_n
        if self._rec is not None:
            # hoverfly_pid's timestamp went in with each pass's scalars: every other timestamp field
            # of the staged frames is one strided store from it (the views' stride is the frame's
            # size in 8-byte words).
            step = self._fast_n // 8
            last = (frames - 1) * step + 1
            col = self._t_pid[0:last:step]
            for v in self._t_views:
                v[0:last:step] = col
        rc = self._rc_off // self._rc_n
        if rc:
            m = self._rc_off
            self._stage[n : n + m] = self._rc_stage[:m]
            n += m
        self._staged = 0
        self._rc_off = 0
        if self._write(self.sink, self._stage_mv[:n]):
            self.frames += frames
            self.rc_frames += rc
            self.bytes += n
        else:
            self.dropped += frames + rc

    def _write(self, sink, buf):
        """One batch to the sink, whole or not at all; a refused batch opens a dropout (from its first
        frame's time) that the next batch to fit closes."""
        n = len(buf)
        if self._dropping:
            free = self._sink_free
            if free is not None and free() < n + 5:
                return False
            ms = (_first_time(buf) - self._drop_t64) // 1000
            self.writer.dropout(ms)
            self._dropping = False
        try:
            got = sink.write(buf)
        except OSError:
            got = 0
        if got is not None and got < n:
            if not self._dropping:
                self._dropping = True
                self._drop_t64 = _first_time(buf)
            return False
        return True

    def _stage_rc(self, t):
        """input_rc for the new receiver frame, staged until this batch's flush."""
        rec = self._receiver
        off = self._rc_off
        if rec is None or not self._rc_whole:
            self._stage_rc_any(off, t)
            self._rc_off = off + self._rc_n
            return
        lq = rec.link_quality_pct
        if lq > 100:
            lq = 100
        elif lq < 0:
            lq = 0
        struct.pack_into(_RC_PACK, self._rc_stage, off, self._rc_header, t, t, lq, rec.errors & 0xFFFF,
                         rec.frames & 0xFFFF, _raw(self._rc_ch), _RC_CHANNELS, rec.rx_failsafe,
                         not self.flight.rx_ok, 0, lq, rec.rssi_dbm)
        self._rc_off = off + self._rc_n

    def _stage_rc_any(self, off, t):
        """_stage_rc without a receiver that reports its link (the flight's own counts), or from
        another board's channel source (padded or cut to PX4's 18)."""
        rec = self._receiver
        if rec is not None:
            lq = _clamp_int(rec.link_quality_pct, 0, 100)
            fs = rec.rx_failsafe
            total = rec.frames & 0xFFFF
            errors = rec.errors & 0xFFFF
            rssi_dbm = rec.rssi_dbm
        else:
            f = self.flight
            lq = 100 if f.rx_ok else 0
            fs = False
            total = f.rc.frames & 0xFFFF
            errors = 0
            rssi_dbm = 0
        ch = self._rc_ch
        lost = not self.flight.rx_ok
        if self._rc_whole:
            struct.pack_into(_RC_PACK, self._rc_stage, off, self._rc_header, t, t, lq, errors, total, _raw(ch),
                             _RC_CHANNELS, fs, lost, 0, lq, rssi_dbm)
        else:
            v = [0] * _RC_CHANNELS
            for i in range(len(ch) if len(ch) < _RC_CHANNELS else _RC_CHANNELS):
                v[i] = ch[i]
            struct.pack_into(_RC_PACK_VALUES, self._rc_stage, off, self._rc_header, t, t, lq, errors, total, *v,
                             len(ch), fs, lost, 0, lq, rssi_dbm)

    def _log_events(self, now_us, t):
        self._flush()
        self._h = []
        self._ev_seen = self.flight.events.drain(self._ev_seen, self._collect_event)
        w = self.writer
        for et, event, detail in self._h:
            # Back-date by the event's age in ticks (it may come from an earlier pass).
            age = ticks_diff(now_us, et) if now_us is not None else -1
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

    def _log_notch(self, t):
        """hoverfly_notch for a craft whose ESCs answer (bidirectional DShot) or with a dynamic notch: what the
        RPM filter and the dynamic notch sit on, for the log report's spectrum."""
        f = self.flight
        dyn = getattr(f, "fixed_dyn", None)  # the stage that runs: the fixed one where it does
        if dyn is None or not dyn.active:
            dyn = getattr(f, "dyn_notch", None)
            dyn = dyn if dyn is not None and dyn.active else None
        if not f.output.bidir and dyn is None:
            return
        rpm = f.signals.motor_rpm
        rf = getattr(f, "rpm_filter", None)
        lost = rf.lost if rf is not None else 0
        values = []
        for m in range(8):
            values.append(rpm[m] / 60.0 if m < f.motor_count and not lost & (1 << m) else 0.0)
        out = [0.0, 0.0, 0.0]
        for axis in range(3):
            if dyn is not None:
                dyn.centres_hz(axis, out)
            values.extend(out)
        self.writer.write_data(self._ids["hoverfly_notch"], t, values)

    def _log_servos(self, t):
        """actuator_servos for a craft with servos (a plane's smix, a tricopter's tail): each width as
        PX4's control -1..1 (1000..2000 µs), servos past the ones in use 0."""
        f = self.flight
        sv = getattr(f, "servos", None)
        n = sv.count if sv is not None else 0
        if n == 0 and f.mixer.servo_yaw:
            n = 1
        if n == 0:
            return
        self._servo_t = t
        us = f.signals.servo_us
        values = [t]
        for i in range(8):
            values.append((us[i] - 1500) * 0.002 if i < n else 0.0)
        self.writer.write_data(self._ids["actuator_servos"], t, values)

    def _log_airspeed(self, t):
        """airspeed for a plane with a pitot (the board's, read in the 50 Hz task): the latest reading."""
        self._airspeed_t = t
        v = self.flight.signals.airspeed_m_s
        self.writer.write_data(self._ids["airspeed"], t, [t, v, v, 1.0])

    def _log_slow(self, t):
        """The slow topics (SLOW_TOPICS, about ten times a second): one pack of their four messages
        into a buffer built at _begin, one write."""
        self._flush()
        f = self.flight
        s = f.signals
        armed = f.arming.armed
        if armed and self._armed_t64 == 0:
            self._armed_t64 = t if t > 0 else 1
        elif not armed:
            self._armed_t64 = 0
        mode = s.setpoint.mode
        fs_state = f.failsafe.state
        sc = f.scheduler
        rec = getattr(f, "receiver", None)
        if rec is not None:
            link = (_clamp_int(getattr(rec, "frames", 0), 0, _U32_MAX),
                    _clamp_int(getattr(rec, "errors", 0), 0, _U32_MAX),
                    float(getattr(rec, "frame_rate_hz", 0.0)),
                    _clamp_int(getattr(rec, "link_quality_pct", 0), 0, 100),
                    float(getattr(rec, "rssi_dbm", 0.0)), bool(getattr(rec, "rx_failsafe", False)), f.rx_ok)
        else:
            link = (_clamp_int(f.rc.frames, 0, _U32_MAX), 0, 0.0, 100 if f.rx_ok else 0, 0.0, False, f.rx_ok)
        h0, h1, h2, h3 = self._slow_heads
        # Every integer is clamped to its field's type here (write_packed does not check).
        self.writer.write_packed(self._slow_buf, self._slow_fmt, (
            h0, t, s.battery_v, s.current_a, getattr(s, "mah_drawn", 0.0), -1.0, s.battery_v > 0.5,
            h1, t, self._armed_t64, _ARMING_ARMED if armed else _ARMING_STANDBY,
            _NAV_STATES[mode] if 0 <= mode < 3 else 0, fs_state != 0, not f.rx_ok,
            _clamp_int(mode, 0, 255), _clamp_int(fs_state, 0, 255), f.supervisor.imu_ok, f.calibration.calibrated,
            h2, t, _clamp_int(sc.stats[PS_PASSES], 0, _U32_MAX), _clamp_int(sc.stats[PS_CYCLE], 0, _U32_MAX),
            _clamp_int(sc.stats[PS_CYCLE_MAX], 0, _U32_MAX), _clamp_int(sc.stats[PS_JITTER_MAX], 0, _U32_MAX),
            _clamp_int(sc.overruns, 0, _U32_MAX), _clamp_int(self.frames, 0, _U32_MAX),
            _clamp_int(self.dropped, 0, _U32_MAX),
            h3, t) + link, 4, t)
        self.writer.maybe_sync(t)


def _first_time(buf):
    """The time of a batch's first frame: its vehicle_attitude timestamp, after the header."""
    return struct.unpack_from("<Q", buf, HEADER_BYTES)[0]


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

