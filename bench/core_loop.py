"""Cost of one full flight-core pass (IMU -> filters -> Mahony -> commander -> PID -> mixer -> outputs).

Runs under CPython and MicroPython; prints one JSON object:
{runtime, us_per_pass, bytes_per_pass, passes}. Armed, angle mode: an MPU-6050 burst decoded
by hand, filters, Mahony, commander, PIDs, mixer, DShot words (core.output.OutputEncoder), a
CRSF frame parsed every 4th pass, the scheduler's slow tasks included. bytes_per_pass from gc.mem_alloc() deltas
with the GC disabled (0 on CPython).

    python3 bench/core_loop.py
    MICROPYPATH=src:.frozen micropython -X heapsize=192k bench/core_loop.py
"""

import sys

if sys.implementation.name == "micropython":
    # Compiling the whole core from source at once fragments a 192 KB heap: compile the modules
    # one at a time, leaves first, collecting in between (the device loads precompiled .mpy).
    import gc

    for _name in ("params", "events", "filters", "control", "estimator", "mixer", "arming", "failsafe",
                  "rc", "scheduler", "signals", "output", "receiver", "flight"):
        gc.collect()
        try:
            __import__("hoverfly.core." + _name)
        except ImportError:
            pass
    gc.collect()

from hoverfly.compat import (
    IS_MICROPYTHON,
    collect_garbage,
    disable_gc,
    enable_gc,
    mem_alloc,
    ticks_diff,
    ticks_us,
)
from hoverfly.core.board import Board
from hoverfly.core.flight import Flight

try:
    from hoverfly.protocols.crsf import encode_rc_frame
except ImportError:  # pragma: no cover - older trees
    encode_rc_frame = None
try:
    from hoverfly.core.output import OutputEncoder
except ImportError:  # pragma: no cover - older trees
    OutputEncoder = None

_GYRO_RAD_S = 3.141592653589793 / 180.0 / 16.4  # MPU-6050 at +-2000 deg/s: 16.4 LSB per deg/s
_ACCEL_M_S2 = 9.80665 / 2048.0  # at +-16 g: 2048 LSB per g


def _burst(gx, gy, gz):
    """An MPU-6050 burst (ACCEL_XOUT_H..GYRO_ZOUT_L, big-endian int16): level, slightly tilted."""
    b = bytearray(14)
    for k, v in ((0, 20), (1, -20), (2, -2008), (3, 0), (4, gx), (5, gy), (6, gz)):
        v &= 0xFFFF
        b[2 * k] = v >> 8
        b[2 * k + 1] = v & 0xFF
    return b


class BenchBoard(Board):
    """The pass's I/O as the device does it: an IMU burst decoded by hand, a CRSF frame from the
    receiver UART every 4th pass (the receiver task runs every 2nd), DShot words encoded per pass."""

    def __init__(self):
        self.t = 0
        self.k = 0
        self.polls = 0
        # about +-0.01 rad/s of noise, three samples in turn: never the same value at the 100 Hz IMU check
        self.bursts = (_burst(10, 20, -5), _burst(-10, 21, -5), _burst(3, 20, -6))
        self.frames = []
        for arm_us, roll_us in ((1000, 1500), (2000, 1500), (2000, 1507)):
            ch = [roll_us, 1500, 1400, 1500, arm_us, 2000] + [1500] * 10
            self.frames.append(bytes(encode_rc_frame(ch)) if encode_rc_frame else b"")
        self.encoder = OutputEncoder() if OutputEncoder else None

    def now_us(self):
        return self.t

    def read_imu(self, gyro, accel):
        self.k += 1
        b = self.bursts[self.k % 3]
        v = (b[0] << 8) | b[1]
        if v > 32767:
            v -= 65536
        accel[0] = v * _ACCEL_M_S2
        v = (b[2] << 8) | b[3]
        if v > 32767:
            v -= 65536
        accel[1] = v * _ACCEL_M_S2
        v = (b[4] << 8) | b[5]
        if v > 32767:
            v -= 65536
        accel[2] = v * _ACCEL_M_S2
        v = (b[8] << 8) | b[9]
        if v > 32767:
            v -= 65536
        gyro[0] = v * _GYRO_RAD_S
        v = (b[10] << 8) | b[11]
        if v > 32767:
            v -= 65536
        gyro[1] = v * _GYRO_RAD_S
        v = (b[12] << 8) | b[13]
        if v > 32767:
            v -= 65536
        gyro[2] = v * _GYRO_RAD_S
        return True

    def read_rx(self, buf):
        self.polls += 1
        if self.polls & 1:
            return 0
        # arm switch low until calibration is done, then high; the roll stick moves a little
        f = self.frames[0] if self.polls < 800 else self.frames[1 + ((self.polls >> 1) & 1)]
        n = len(f)
        buf[0:n] = f
        return n

    def configure_outputs(self, params, motor_count, servo_count):
        if self.encoder is not None:
            self.encoder.configure(params, motor_count, servo_count, self.t)

    def write_motors(self, out, n):
        if self.encoder is not None:
            self.encoder.write(out, n, self.t)


def run(passes):
    board = BenchBoard()
    f = Flight(board)
    f.params.set("gyro_cal_ms", 100)
    f.params.set("boot_grace_ms", 0)
    f.params.set("min_check", 1500)
    f.start(0)
    t = 0
    # warm up: calibrate, arm
    for _ in range(3000):
        t += 1000
        board.t = t
        f.step(t)
    assert f.arming.armed, "bench flight did not arm"
    # One pass at a time with the GC off, collecting between passes (untimed): the pass itself
    # is measured, as on the device where the collection runs in the loop's slack. (One pass:
    # the core loaded from source leaves little of a 192 KB heap on the 64-bit VM.)
    total_us = 0
    total_bytes = 0
    done = 0
    while done < passes:
        collect_garbage()
        disable_gc()
        a0 = mem_alloc()
        t0 = ticks_us()
        t += 1000
        board.t = t
        f.step(t)
        t1 = ticks_us()
        a1 = mem_alloc()
        enable_gc()
        total_us += ticks_diff(t1, t0)
        total_bytes += a1 - a0
        done += 1
    return total_us / done, total_bytes / done


def main():
    passes = 2000 if IS_MICROPYTHON else 20000
    best = None
    alloc = 0
    for _ in range(3):
        us, b = run(passes)
        if best is None or us < best:
            best = us
            alloc = b
    runtime = "micropython" if IS_MICROPYTHON else "cpython"
    print('{"runtime": "%s", "us_per_pass": %.2f, "bytes_per_pass": %.1f, "passes": %d}'
          % (runtime, best, alloc, passes))


main()
sys.stdout.flush()
