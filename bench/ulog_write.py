"""ULog writer cost: µs per write_data, bytes allocated per sample, and a PX4 topic set at 1 kHz.

Run: `.venv/bin/python bench/ulog_write.py` and
`MICROPYPATH=src:.frozen .venv/bin/micropython -X heapsize=192k bench/ulog_write.py`.
Prints one JSON object; times are the best of several runs.
"""

import sys

from hoverfly.compat import (
    IS_MICROPYTHON,
    collect_garbage,
    disable_gc,
    enable_gc,
    mem_alloc,
    ticks_diff,
    ticks_us,
)
from hoverfly.protocols.ulog import RingSink, UlogWriter

RUNS = 5
N = 2000 if IS_MICROPYTHON else 20000


class NullSink:
    def write(self, data):
        return None


def _null(mv):
    return None


# PX4 message definitions (msg/*.msg), trimmed to the fields hoverfly has.
VEHICLE_ATTITUDE = (
    ("uint64_t", "timestamp"),
    ("float[4]", "q"),
    ("float[4]", "delta_q_reset"),
    ("uint8_t", "quat_reset_counter"),
    ("uint8_t[7]", "_padding0"),
)
PX4_SET = (
    # (name, fields, every n-th loop at 1 kHz, values)
    ("vehicle_attitude", VEHICLE_ATTITUDE, 1, (1.0, 0.01, -0.02, 0.3, 0.0, 0.0, 0.0, 0.0, 0)),
    (
        "vehicle_angular_velocity",
        (
            ("uint64_t", "timestamp"),
            ("uint64_t", "timestamp_sample"),
            ("float[3]", "xyz"),
            ("float[3]", "xyz_derivative"),
        ),
        1,
        (5, 0.1, -0.2, 0.3, 1.0, 2.0, 3.0),
    ),
    (
        "vehicle_rates_setpoint",
        (
            ("uint64_t", "timestamp"),
            ("float", "roll"),
            ("float", "pitch"),
            ("float", "yaw"),
            ("float[3]", "thrust_body"),
            ("bool", "reset_integral"),
            ("uint8_t[7]", "_padding0"),
        ),
        1,
        (0.1, 0.2, 0.3, 0.0, 0.0, -0.5, False),
    ),
    (
        "actuator_outputs",
        (("uint64_t", "timestamp"), ("uint32_t", "noutputs"), ("float[16]", "output")),
        1,
        (4,) + (1500.0,) * 4 + (0.0,) * 12,
    ),
    (
        "sensor_combined",
        (
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
        ),
        1,
        (0.1, 0.2, 0.3, 1000, 0, 0.0, 0.0, -9.81, 1000, 0, 0, 1, 1),
    ),
    (
        "input_rc",
        (
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
        ),
        20,  # 50 Hz, a CRSF frame rate
        (5, 100, 0, 1000) + (1500,) * 18 + (16, False, False, 1),
    ),
    (
        "battery_status",
        (
            ("uint64_t", "timestamp"),
            ("float", "voltage_v"),
            ("float", "current_a"),
            ("float", "discharged_mah"),
            ("float", "remaining"),
            ("bool", "connected"),
            ("uint8_t[3]", "_padding0"),
        ),
        100,  # 10 Hz
        (16.4, 12.0, 350.0, 0.8, True),
    ),
)


def _attitude_writer(sink):
    w = UlogWriter(sink, 0)
    w.add_format("vehicle_attitude", VEHICLE_ATTITUDE)
    return w, w.subscribe("vehicle_attitude")


def bench_write_data(sink, drain_every=0):
    w, m = _attitude_writer(sink)
    values = PX4_SET[0][3]
    write = w.write_data
    best = None
    t = 1
    for _ in range(RUNS):
        t0 = ticks_us()
        for _ in range(N):
            write(m, t, values)
            t += 1
            if drain_every and t % drain_every == 0:
                sink.drain(_null)
        us = ticks_diff(ticks_us(), t0) / N
        best = us if best is None or us < best else best
    return best


def bench_alloc_per_sample():
    w, m = _attitude_writer(NullSink())
    values = PX4_SET[0][3]
    w.write_data(m, 1, values)
    collect_garbage()
    disable_gc()
    try:
        before = mem_alloc()
        for t in range(2, 1002):
            w.write_data(m, t, values)
        grown = mem_alloc() - before
    finally:
        enable_gc()
    return grown / 1000


def bench_px4_set():
    sink = RingSink(32768)
    w = UlogWriter(sink, 0)
    for name, fields, _, _ in PX4_SET:
        w.add_format(name, fields)
    w.add_info("char[8] sys_name", "hoverfly")
    ids = [w.subscribe(name) for name, _, _, _ in PX4_SET]
    table = [(ids[i], PX4_SET[i][2], PX4_SET[i][3]) for i in range(len(PX4_SET))]
    sink.drain(_null)
    loops = N // 4
    best = None
    t = 1000
    bytes_before = w.bytes_written
    for _ in range(RUNS):
        t0 = ticks_us()
        for i in range(loops):
            for msg_id, every, values in table:
                if every == 1 or i % every == 0:
                    w.write_data(msg_id, t, values)
            w.maybe_sync(t)
            sink.drain(_null)
            t += 1000
        us = ticks_diff(ticks_us(), t0) / loops
        best = us if best is None or us < best else best
    per_loop_bytes = (w.bytes_written - bytes_before) / (loops * RUNS)
    return best, per_loop_bytes * 1000, sink.dropped_bytes


def main():
    null_us = bench_write_data(NullSink())
    ring_us = bench_write_data(RingSink(16384), drain_every=64)
    alloc = bench_alloc_per_sample() if IS_MICROPYTHON else None
    loop_us, bytes_per_s, dropped = bench_px4_set()
    impl = sys.implementation.name
    print(
        '{"implementation": "%s", "sample_bytes": 46, "write_data_us_null_sink": %.3f, '
        '"write_data_us_ring_sink_incl_drain": %.3f, "alloc_bytes_per_sample": %s, '
        '"px4_set_1khz_us_per_loop": %.3f, "px4_set_bytes_per_s": %d, "px4_set_topics": %d, '
        '"ring_dropped_bytes": %d}'
        % (
            impl,
            null_us,
            ring_us,
            "null" if alloc is None else "%.1f" % alloc,
            loop_us,
            int(bytes_per_s),
            len(PX4_SET),
            dropped,
        )
    )


main()
