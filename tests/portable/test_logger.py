"""Flight logger (core/log/logger.py): what a Flight writes into a ULog sink, checked with a tiny reader.

Runs under pytest and MicroPython (tests/portable/mprun.py test_logger).
"""

import struct

from hoverfly.core.board import Board
from hoverfly.core.flight import Flight
from hoverfly.core.log.logger import FAST_TOPICS, FORMATS, STAGE_FRAMES, format_size
from hoverfly.protocols.ulog import RingSink

try:
    from hoverfly.protocols.crsf import encode_rc_frame
except ImportError:  # pragma: no cover
    encode_rc_frame = None

_PERIOD_US = 1000


class _Board(Board):
    name = "test"

    def __init__(self):
        self.k = 0
        self.frame_every = 4
        self.arm = False
        self.imu = True
        self.rx_frame = None  # CRSF bytes served on every other receiver poll
        self.polls = 0

    def now_us(self):
        return 0

    def read_imu(self, gyro, accel):
        if not self.imu:
            return False
        gyro[0] = 0.01 * (self.k % 7)
        gyro[1] = -0.02
        gyro[2] = 0.003
        accel[0] = 0.1
        accel[1] = -0.1
        accel[2] = -9.8
        return True

    def read_rx(self, buf):
        self.polls += 1
        if self.rx_frame is None or self.polls & 1:
            return 0
        n = len(self.rx_frame)
        buf[0:n] = self.rx_frame
        return n

    def write_motors(self, out, n):
        pass


class _Sink:
    def __init__(self):
        self.data = bytearray()

    def write(self, b):
        self.data.extend(b)
        return len(b)


def _parse(data):
    """formats {name: fields}, subs {msg_id: name}, samples {name: [payload]}, strings, params,
    syncs, dropouts [duration_ms]."""
    assert bytes(data[0:7]) == b"ULog\x01\x12\x35"
    formats = {}
    subs = {}
    samples = {}
    strings = []
    params = []
    syncs = 0
    dropouts = []
    off = 16
    n = len(data)
    while off + 3 <= n:
        size = data[off] | (data[off + 1] << 8)
        kind = data[off + 2]
        body = bytes(data[off + 3 : off + 3 + size])
        off += 3 + size
        if kind == 0x46:
            text = body.decode()
            name, fields = text.split(":", 1)
            formats[name] = fields
        elif kind == 0x41:
            msg_id = body[1] | (body[2] << 8)
            subs[msg_id] = body[3:].decode()
            samples[subs[msg_id]] = []
        elif kind == 0x44:
            msg_id = body[0] | (body[1] << 8)
            samples[subs[msg_id]].append(body[2:])
        elif kind == 0x4C:
            strings.append(body[9:].decode())
        elif kind == 0x50:
            klen = body[0]
            params.append(body[1 : 1 + klen].decode())
        elif kind == 0x53:
            syncs += 1
        elif kind == 0x4F:
            dropouts.append(body[0] | (body[1] << 8))
    assert off == n
    return formats, subs, samples, strings, params, syncs, dropouts


def _fly(passes, rate_hz=1000, sink=None, start_log=True, setup=None, flush=True):
    board = _Board()
    f = Flight(board, None)
    f.params.set("blackbox_rate_hz", rate_hz)
    f.params.set("gyro_cal_ms", 100)
    if setup is not None:
        setup(f)
    sink = _Sink() if sink is None else sink
    if start_log:
        f.logger.open(sink)
    t = 100000
    f.start(t)
    for k in range(passes):
        board.k = k
        t += _PERIOD_US
        f.step(t)
    if flush:
        f.logger.flush()
    return f, sink


def test_every_fast_topic_gets_one_sample_per_pass_at_the_loop_rate():
    f, sink = _fly(50)
    formats, subs, samples, strings, params, syncs, dropouts = _parse(sink.data)
    for name in FAST_TOPICS:
        assert len(samples[name]) == 50, (name, len(samples[name]))
    assert f.logger.frames == 50 and f.logger.dropped == 0


def test_samples_are_exactly_the_size_of_their_format():
    f, sink = _fly(5)
    formats, subs, samples, strings, params, syncs, dropouts = _parse(sink.data)
    for name, fields in FORMATS:
        assert name in formats
        for payload in samples[name]:
            assert len(payload) == format_size(fields), name


def test_timestamps_count_microseconds_since_the_start():
    f, sink = _fly(5)
    samples = _parse(sink.data)[2]
    ts = [struct.unpack_from("<Q", p, 0)[0] for p in samples["vehicle_attitude"]]
    assert ts == [1000, 2000, 3000, 4000, 5000]


def test_angular_velocity_and_sensor_samples_hold_what_the_pass_used():
    f, sink = _fly(3)
    samples = _parse(sink.data)[2]
    s = f.signals
    last = samples["vehicle_angular_velocity"][-1]
    xyz = struct.unpack_from("<3f", last, 16)
    for i in range(3):
        assert xyz[i] == s.gyro_rad_s[i]
    sc = samples["sensor_combined"][-1]
    gyro = struct.unpack_from("<3f", sc, 8)
    dt = struct.unpack_from("<I", sc, 20)[0]
    accel = struct.unpack_from("<3f", sc, 28)
    for i in range(3):
        assert gyro[i] == s.gyro_raw_rad_s[i]
        assert accel[i] == s.accel_raw_m_s2[i]
    assert dt == _PERIOD_US


def test_a_pass_without_a_new_imu_sample_logs_integral_dt_zero():
    board_ref = []

    def setup(f):
        board_ref.append(f.board)

    f, sink = _fly(3, setup=setup)
    board_ref[0].imu = False
    f.step(100000 + 4 * _PERIOD_US)
    f.logger.flush()
    sc = _parse(sink.data)[2]["sensor_combined"]
    assert struct.unpack_from("<I", sc[-1], 20)[0] == 0
    assert struct.unpack_from("<I", sc[-2], 20)[0] == _PERIOD_US
    # and the next pass with a sample logs its interval again (on the record path, from the
    # every-pass update it went back to)
    board_ref[0].imu = True
    for k in (5, 6):
        f.step(100000 + k * _PERIOD_US)
    assert f.logger._fast == (f.logger._rec is not None)
    f.logger.flush()
    sc = _parse(sink.data)[2]["sensor_combined"]
    assert [struct.unpack_from("<I", p, 20)[0] for p in sc[-3:]] == [0, _PERIOD_US, _PERIOD_US]


def test_a_flush_mid_flight_hands_each_frame_over_once():
    f, sink = _fly(30)  # flushed at the end
    for k in range(31, 61):
        f.step(100000 + k * _PERIOD_US)
    f.logger.flush()
    ts = [struct.unpack_from("<Q", p, 0)[0] for p in _parse(sink.data)[2]["vehicle_attitude"]]
    assert ts == [k * _PERIOD_US for k in range(1, 61)]
    assert f.logger.frames == 60


def test_the_pass_reaches_the_logger_through_one_flight_attribute():
    # Flight.step calls flight.log_pass: the logger's update while a log is open, else nothing.
    f, sink = _fly(5, start_log=False)
    assert f.log_pass is None and f.log_rc is None
    f.logger.open(sink)
    t = 100000 + 6 * _PERIOD_US
    f.step(t)
    assert f.log_pass is not None and f.log_pass == f.logger.update
    f.logger.close()
    assert f.log_pass is None and f.log_rc is None
    n = len(sink.data)
    f.step(t + _PERIOD_US)
    assert len(sink.data) == n


def test_input_rc_is_stamped_with_the_time_of_the_pass_its_frame_came_in():
    # While every pass is logged on the record path, Flight.task_rx hands each new frame to the
    # logger (flight.log_rc); a pass without an IMU sample and a parameter write take the full
    # update for a pass, which looks for frames itself. Every frame is logged once either way.
    if encode_rc_frame is None:
        return
    board = _Board()
    board.rx_frame = bytes(encode_rc_frame([1500] * 16))
    f = Flight(board, None)
    f.params.set("blackbox_rate_hz", 1000)
    f.params.set("gyro_cal_ms", 100)
    sink = _Sink()
    f.logger.open(sink)
    t = 100000
    f.start(t)
    expected = []
    hooked = 0
    for k in range(400):
        board.k = k
        board.imu = k % 97 != 50
        if k == 230:
            f.params.set("p_roll", 61)
        hooked += f.log_rc is not None
        frames = f.rc.frames
        t += _PERIOD_US
        f.step(t)
        if f.rc.frames != frames:
            expected.append(t - 100000)
    f.logger.flush()
    rc = _parse(sink.data)[2]["input_rc"]
    assert [struct.unpack_from("<Q", p, 0)[0] for p in rc] == expected
    assert len(expected) > 50
    if f.logger._rec is not None:  # CPython: most frames came through the hook
        assert hooked > 300


def test_logging_rate_set_to_zero_mid_flight_stops_the_log_receiver_frames_and_all():
    if encode_rc_frame is None:
        return

    def setup(f):
        f.board.rx_frame = bytes(encode_rc_frame([1500] * 16))

    f, sink = _fly(20, setup=setup)
    f.params.set("blackbox_rate_hz", 0)  # applied by the next arming task (disarmed)
    t = 100000 + 21 * _PERIOD_US
    for k in range(20):
        f.step(t + k * _PERIOD_US)
    f.logger.flush()  # what was staged before the stop
    n = len(sink.data)
    assert not f.logger.active and f.log_pass is None and f.log_rc is None
    for k in range(20, 600):  # far more receiver frames than a batch holds
        f.step(t + k * _PERIOD_US)
    f.logger.flush()
    assert len(sink.data) == n


def test_logging_rate_is_a_parameter():
    f, sink = _fly(100, rate_hz=250)
    samples = _parse(sink.data)[2]
    assert 24 <= len(samples["vehicle_attitude"]) <= 26


def test_slow_topics_come_about_ten_times_a_second():
    f, sink = _fly(1000)
    samples = _parse(sink.data)[2]
    for name in ("battery_status", "vehicle_status", "hoverfly_loop", "hoverfly_link"):
        assert 9 <= len(samples[name]) <= 11, (name, len(samples[name]))


def test_parameters_are_logged_and_a_change_comes_after_the_samples_of_its_pass():
    f, sink = _fly(10)
    f.params.set("p_roll", 60)
    f.step(100000 + 11 * _PERIOD_US)
    data = sink.data
    params = _parse(data)[4]
    assert "int32_t p_roll" in params and "int32_t blackbox_rate_hz" in params
    assert params.count("int32_t p_roll") == 2
    # the change's 'P' follows this pass's attitude sample
    i_change = bytes(data).rfind(b"int32_t p_roll")
    i_last_sample = bytes(data).rfind(struct.pack("<Q", 11000))
    assert i_last_sample < i_change


def test_events_become_log_strings():
    f, sink = _fly(300)
    strings = _parse(sink.data)[3]
    assert "gyro_calibrated 0" in strings
    assert any(s.startswith("mode ") for s in strings)


class _SyncCounter:
    """Keeps nothing but the count of sync messages (each write is one whole message)."""

    def __init__(self):
        self.syncs = 0

    def write(self, b):
        if len(b) == 11 and b[2] == 0x53:
            self.syncs += 1
        return len(b)


def test_a_sync_marker_goes_out_about_once_a_second():
    f, sink = _fly(2500, sink=_SyncCounter())
    assert 2 <= sink.syncs <= 4


def test_without_a_sink_nothing_is_written_and_the_pass_skips_the_logger():
    f, sink = _fly(20, start_log=False)
    assert len(sink.data) == 0
    assert not f.logger.active
    for t in f.scheduler.tasks:
        assert t.name != "log"  # called by Flight.step, not dispatched as a task


def test_a_closed_log_stops_the_logger_and_a_reopened_one_logs_again():
    f, sink = _fly(10)
    f.logger.close()
    assert not f.logger.active
    t = 100000 + 11 * _PERIOD_US
    f.step(t)
    n = len(sink.data)
    f.step(t + _PERIOD_US)
    assert len(sink.data) == n
    sink2 = _Sink()
    f.logger.open(sink2)
    assert f.logger.active
    f.step(t + 2 * _PERIOD_US)
    f.logger.flush()
    samples = _parse(sink2.data)[2]
    assert len(samples["vehicle_attitude"]) == 1
    assert struct.unpack_from("<Q", samples["vehicle_attitude"][0], 0)[0] == 0  # opened mid-flight: from 0


def test_a_rate_that_does_not_divide_the_loop_rate_keeps_its_average():
    f, sink = _fly(1000, rate_hz=300)
    samples = _parse(sink.data)[2]["vehicle_attitude"]
    assert 299 <= len(samples) <= 301
    ts = [struct.unpack_from("<Q", p, 0)[0] for p in samples]
    gaps = [ts[i + 1] - ts[i] for i in range(len(ts) - 1)]
    assert min(gaps) == 3000 and max(gaps) == 4000


def test_a_full_ring_drops_whole_frames_and_marks_the_gap():
    ring = RingSink(12000)
    f, _ = _fly(1, sink=ring)
    out = bytearray()

    def take(mv):
        out.extend(mv)

    ring.drain(take)
    t = 100000 + _PERIOD_US
    for _ in range(200):  # no draining: the ring fills, frames drop
        t += _PERIOD_US
        f.step(t)
    assert f.logger.dropped > 0
    ring.drain(take)
    for _ in range(5):
        t += _PERIOD_US
        f.step(t)
    f.logger.flush()  # the staged batch, which fits again
    ring.drain(take)
    samples = _parse(out)[2]
    assert len(samples["vehicle_attitude"]) == f.logger.frames
    # a dropout 'O' marks the gap: from the first lost frame's time to the first kept one's
    ts = [struct.unpack_from("<Q", p, 0)[0] for p in samples["vehicle_attitude"]]
    gaps = [(ts[k], ts[k + 1]) for k in range(len(ts) - 1) if ts[k + 1] - ts[k] > _PERIOD_US]
    assert len(gaps) == 1
    before, after = gaps[0]
    assert (after - (before + _PERIOD_US)) // 1000 in _parse(out)[6]


class _Writes:
    """Keeps every write's length and bytes."""

    def __init__(self):
        self.sizes = []
        self.data = bytearray()

    def write(self, b):
        self.sizes.append(len(b))
        self.data.extend(b)
        return len(b)


def _frame_bytes():
    n = 0
    for name in FAST_TOPICS:
        for fields in FORMATS:
            if fields[0] == name:
                n += 5 + format_size(fields[1])
    return n


def test_frames_go_out_in_batches_and_all_of_them_by_close():
    sink = _Writes()
    frame = _frame_bytes()
    passes = 3 * STAGE_FRAMES + 2  # three full batches and a few staged frames
    f, _ = _fly(passes, sink=sink, flush=False)
    lg = f.logger
    assert 0 < lg.frames < passes  # the last passes' frames are still staged
    lg.close()
    assert lg.frames == passes and lg.dropped == 0
    assert len(_parse(sink.data)[2]["vehicle_attitude"]) == passes
    # several passes' frames per write, never more than the staging buffer
    batches = [n for n in sink.sizes if n % frame == 0 and n >= 2 * frame]
    assert len(batches) >= 3
    assert max(sink.sizes) <= len(lg._stage)


def test_input_rc_sample_holds_the_channels_of_each_new_frame():
    if encode_rc_frame is None:
        return
    ch = [1000 + 37 * i for i in range(16)]

    def setup(f):
        f.board.rx_frame = bytes(encode_rc_frame(ch))

    f, sink = _fly(40, setup=setup)
    samples = _parse(sink.data)[2]["input_rc"]
    assert len(samples) == f.rc.frames == f.logger.rc_frames > 5
    # after timestamp, timestamp_last_signal, rssi, lost and total frame counts: values[18]
    values = struct.unpack_from("<18H", samples[-1], 8 + 8 + 4 + 2 + 2)
    for i in range(18):
        assert values[i] == f.signals.rc_channels_us[i]
    assert abs(values[0] - ch[0]) <= 1 and abs(values[15] - ch[15]) <= 1


def test_pass_record_and_one_pack_write_the_same_log():
    # The pass record (CPython: the signals live in the frame, the timestamps go in per batch) and
    # one pack of everything (the MicroPython path): byte-identical logs.
    logs = []
    for record in (True, False):

        def setup(f, record=record):
            f.logger.record_path = record

        f, sink = _fly(30, setup=setup)
        assert (f.logger._rec is not None) == (record and f.signals.record.backed)
        logs.append(bytes(sink.data))
    assert logs[1] == logs[0]


def test_signals_logged_arrays_live_in_the_frame_where_the_runtime_can_view_bytes_as_floats():
    from hoverfly.core.log.logframe import ARRAY_FIELDS, CAN_VIEW, FRAME_BYTES, array_table, frame_format
    from hoverfly.core.signals import Signals

    assert FRAME_BYTES == struct.calcsize(frame_format())
    s = Signals()
    rec = s.record
    assert rec.backed == CAN_VIEW
    assert s.accel_raw_m_s2[2] == struct.unpack("<f", struct.pack("<f", -9.80665))[0]
    assert s.attitude.q[0] == 1.0
    arrays = (s.attitude.q, s.gyro_rad_s, s.motor_out, s.gyro_raw_rad_s, s.accel_raw_m_s2,
              s.setpoint.rate_rad_s, s.torque_norm)
    table = array_table()
    for k in range(len(arrays)):
        assert len(arrays[k]) == ARRAY_FIELDS[k][1]
        arrays[k][len(arrays[k]) - 1] = 0.5 + k
        if rec.backed:  # the stage's write is the frame's bytes
            off = table[2 * k] + table[2 * k + 1] - 4
            assert struct.unpack_from("<f", rec.buf, off)[0] == 0.5 + k


def test_the_fixed_controller_writes_its_pid_terms_every_pass_while_a_log_runs():
    # Flight.logging_changed: every pass while the logger's every-pass calls are installed (the log
    # records the terms at every pass), every TERMS_IDLE_PASSES passes otherwise
    from hoverfly.core.fastpass.fixedrate import TERMS_EVERY
    from hoverfly.core.flight import TERMS_IDLE_PASSES

    f = Flight(_Board(), None)
    f.params.set("pid_math", "fixed")
    f.start(100000)
    assert f.log_pass is None and f.fixed.co[TERMS_EVERY] == TERMS_IDLE_PASSES
    f.logger.open(_Sink())
    assert f.log_pass is not None and f.fixed.co[TERMS_EVERY] == 1
    f.logger.close()
    assert f.log_pass is None and f.fixed.co[TERMS_EVERY] == TERMS_IDLE_PASSES
