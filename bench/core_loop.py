"""Cost of one full flight-core pass (IMU -> filters -> Mahony -> commander -> PID -> mixer -> outputs).

Runs under CPython and MicroPython; prints one JSON object:
{runtime, us_per_pass, bytes_per_pass, passes, passes_per_gc, us_per_pass_after_gc, tasks_us_per_pass,
loop_us_per_pass, rpm_harmonics} (with "rx_core1": true or "plane": true for those runs). Armed, angle mode: an
MPU-6050 burst decoded by the MPU-6050 driver, filters, estimator, commander, PIDs, mixer, DShot words
(core.stages.output.OutputEncoder), a CRSF frame parsed every 4th pass, the scheduler's slow tasks included.
bytes_per_pass from gc.mem_alloc() deltas with the GC disabled (0 on CPython). Garbage is collected between
passes, untimed, as the rp2 main loop collects it (timed_passes below); us_per_pass_after_gc is the passes
right after a collection, which run with the host's caches emptied by it. tasks_us_per_pass is the part of a
pass spent in the scheduler's slow tasks (the receiver task at 500 Hz with the frame every 4th pass, arming and
failsafe at 100 Hz, battery, LED), timed on a flight of its own; loop_us_per_pass is the rest: IMU to DShot
words, commander included (Betaflight's gyro/PID loop, its tasks apart).

    python3 bench/core_loop.py
    python3 -m hoverfly.fastgen   # first: the generated viper stages the VM imports (docs/fastpass.md)
    MICROPYPATH=src:.frozen micropython -X heapsize=640k bench/core_loop.py
    MICROPYPATH=src:.frozen micropython -X heapsize=640k bench/core_loop.py --rx-core1
    MICROPYPATH=src:.frozen micropython -X heapsize=640k bench/core_loop.py --rpm 1   # RPM filter, 1 harmonic
    MICROPYPATH=src:.frozen micropython -X heapsize=640k bench/core_loop.py --plane   # mixer_type airplane

With --plane the flight is an airplane (mixer_type airplane: the fixed-wing controller, core/stages/fwcontrol.py
and its fixed-point twin, the servo mix of aileron, elevator and rudder, one motor), in ANGLE as the quad.

With --rx-core1 the receiver's UART reads and CRSF parsing are core 1's (`rx_core1`, core/stages/rxcore.py): the
codec's RxCore polls the bench board before every other pass, outside the timing (on a Pico it runs on the
other core meanwhile): the board answers every other poll, so a frame still comes every 4th pass, and the
pass takes it from the handover. The JSON says "rx_core1": true.

(640 KB: compiling the core from source on the 64-bit VM, one module at a time, needs about 560 KB since the
fixed-wing and RPM-filter stages came in (512 KB runs out while compiling the generated accel/fw.py); a board
loads precompiled .mpy, as bench/bundle_loop.py does. The heap sets passes_per_gc, not what a pass costs.)
"""

import sys

if sys.implementation.name == "micropython":
    # Compiling the whole core from source at once fragments a small heap: compile the modules
    # one at a time, leaves first, collecting in between (the device loads precompiled .mpy).
    import gc

    for _name in ("accel.mpu6050", "drivers.orientation", "drivers.imu", "drivers.mpu6050", "core.config.params",
                  "core.events", "core.stages.filters", "accel.imufilter", "core.fastpass.fixedimu",
                  "core.stages.control", "core.stages.estimator", "accel.att", "core.fastpass.fixedatt",
                  "core.stages.mixer", "core.stages.pid", "accel.rate", "core.fastpass.fixedrate",
                  "core.safety.arming", "accel.faults", "core.safety.failsafe", "accel.rc", "core.stages.rc",
                  "accel.sched", "core.scheduler", "core.signals", "accel.output", "accel.dshot",
                  "core.stages.output", "accel.crc", "accel.rxcodec", "protocols.rxcodec", "protocols.crsf",
                  "core.stages.receiver", "core.log.logger", "core.command.commander", "core.command.autopilot",
                  "core.command.launch", "core.command.motortest", "core.safety.bit", "accel.rpmfilter",
                  "core.stages.rpmfilter", "core.fastpass.fixedrpm", "accel.servos", "core.stages.servos",
                  "accel.fw", "core.fastpass.fixedfw", "core.stages.fwcontrol", "core.safety.supervisor",
                  "core.flight"):
        gc.collect()
        try:
            __import__("hoverfly." + _name)
        except (SyntaxError, ImportError):  # an accel module on a port without viper (its module falls back),
            pass  # or a module an older tree does not have (the bench compares trees)
        if _name == "core.stages.output" and "--plane" in sys.argv:  # a plane's stages, which Flight imports then
            for _fw in ("core.stages.fwcontrol", "accel.fw", "core.fastpass.fixedfw", "core.command.launch"):
                gc.collect()
                try:
                    __import__("hoverfly." + _fw)
                except (SyntaxError, ImportError):
                    pass
        if _name == "core.stages.output" and ("--rpm" in sys.argv or "--dyn" in sys.argv):  # Flight imports them then
            for _rpm in ("core.stages.rpmfilter", "accel.rpmfilter", "core.fastpass.fixedrpm", "core.stages.dynnotch",
                         "accel.dynnotch", "core.fastpass.fixeddyn"):
                gc.collect()
                try:
                    __import__("hoverfly." + _rpm)
                except (SyntaxError, ImportError):
                    pass
    gc.collect()

from hoverfly.compat import (
    IS_MICROPYTHON,
    collect_garbage,
    disable_gc,
    enable_gc,
    mem_alloc,
    mem_free,
    ticks_diff,
    ticks_us,
)
from hoverfly.core.board import Board
from hoverfly.core.flight import Flight
from hoverfly.core.scheduler import HeapWatch
from hoverfly.core.stages.output import OutputEncoder
from hoverfly.drivers.mpu6050 import MPU6050, WHO_AM_I_VALUE
from hoverfly.drivers.orientation import Orientation
from hoverfly.protocols.crsf import encode_rc_frame
from hoverfly.protocols.dshot import erpm_reply_word, gcr_encode

# --rpm N: bidirectional DShot with the RPM filter at N harmonics, the ESCs answering every frame with eRPM
RPM_HARMONICS = int(sys.argv[sys.argv.index("--rpm") + 1]) if "--rpm" in sys.argv else 0
# --dyn N: the dynamic notch with N notches an axis (its fixed-point form, with the fixed IMU filter)
DYN_NOTCHES = int(sys.argv[sys.argv.index("--dyn") + 1]) if "--dyn" in sys.argv else 0
# --plane: an airplane's flight (the fixed-wing controller and the servo mix) instead of the quad's
PLANE = "--plane" in sys.argv


class BurstBus:
    """An I2C bus with one MPU-6050 on it: WHO_AM_I answers, every other read gets `burst`."""

    def __init__(self):
        self.burst = bytes(14)

    def readfrom_mem_into(self, address, register, buf):
        if len(buf) == 1:
            buf[0] = WHO_AM_I_VALUE
        else:
            buf[:] = self.burst

    def writeto_mem(self, address, register, data):
        pass


def _burst(gx, gy, gz):
    """An MPU-6050 burst (ACCEL_XOUT_H..GYRO_ZOUT_L, big-endian int16, chip axes: z up reads +1 g):
    level, slightly tilted; the driver turns it into FRD (x, -y, -z)."""
    b = bytearray(14)
    for k, v in ((0, 20), (1, 20), (2, 2008), (3, 0), (4, gx), (5, -gy), (6, -gz)):
        v &= 0xFFFF
        b[2 * k] = v >> 8
        b[2 * k + 1] = v & 0xFF
    return b


class BenchBoard(Board):
    """The pass's I/O as the device does it: an IMU burst through the MPU-6050 driver, a CRSF frame from the
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
            self.frames.append(bytes(encode_rc_frame(ch)))
        self.encoder = OutputEncoder()
        self.bus = BurstBus()
        # The device's own driver decodes the burst (2000 deg/s, 16 g, as the rp2 board sets it).
        self.imu = MPU6050(self.bus, Orientation(), delay_us=lambda us: None)
        self.imu.configure()
        # the ESCs' replies (--rpm): four motors near a 5-inch's hover, 10 000 RPM on 14 poles, as GCR line codes
        self.replies = [gcr_encode(erpm_reply_word(70000 + 700 * m)) for m in range(4)]

    def now_us(self):
        return self.t

    def read_imu(self, gyro, accel):
        self.k += 1
        self.bus.burst = self.bursts[self.k % 3]
        return self.imu.read(gyro, accel)

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
        self.encoder.configure(params, motor_count, servo_count, self.t)

    def write_motors(self, out, n):
        self.encoder.write(out, n, self.t)

    def read_motor_telemetry(self, codes, count):
        if not RPM_HARMONICS:
            return False
        r = self.replies
        for m in range(count):
            codes[m] = r[m & 3]
        return True


def armed_flight():
    """The bench flight, calibrated and armed: (board, flight, time of its last pass in µs).
    bench/core_stages.py times the same flight stage by stage."""
    collect_garbage()  # the last run's flight first: two do not fit its heap on the 64-bit VM
    board = BenchBoard()
    f = Flight(board)
    f.params.set("gyro_cal_ms", 100)
    f.params.set("boot_grace_ms", 0)
    f.params.set("min_check", 1500)
    if PLANE:
        f.params.set("mixer_type", "airplane")
    if RPM_HARMONICS:
        f.params.set("dshot_bidir", 1)
        f.params.set("rpm_harmonics", RPM_HARMONICS)
    if DYN_NOTCHES:
        f.params.set("dyn_notch_count", DYN_NOTCHES)
    f.start(0)
    t = 0
    for _ in range(3000):
        t += 1000
        board.t = t
        f.step(t)
    assert f.arming.armed, "bench flight did not arm"
    assert f._rpm_on == (RPM_HARMONICS > 0), "the RPM filter is not as asked"
    return board, f, t


GC_FREE_FRACTION = 2  # as boards/rp2/main.py


def timed_passes(board, f, t, passes, after_gc=None, core1=None):
    """Step the flight `passes` times as the rp2 main loop does (boards/rp2/main.run): each pass with
    the GC off, and a collection between passes (untimed, in the loop's slack) once half of what the last
    collection freed is used up, the free heap looked at when core/scheduler.py's HeapWatch says (the same
    watch main.run keeps). Returns (µs, bytes, collections, t): totals over the passes.
    after_gc, a two-slot list, gets the µs and the count of the passes that came straight after a
    collection: those run with the host's caches emptied by the collection's heap walk (an RP2040 has
    no data cache; on this host they are the slowest passes).
    On CPython nothing is collected and no bytes are counted (compat's GC hooks do nothing).
    core1, an rxcore.RxCore: polled before every other pass, untimed and uncounted (core 1's share; the
    bench board answers every other poll, so a frame every 4th pass, as the receiver task reads it)."""
    us = 0
    nbytes = 0
    gcs = 0
    watch = HeapWatch(mem_free, GC_FREE_FRACTION)
    collect_garbage()
    watch.collected()
    fresh = True
    for k in range(passes):
        if watch.due() and watch.need():
            enable_gc()
            collect_garbage()
            watch.collected()
            gcs += 1
            fresh = True
        if core1 is not None and k & 1:
            core1.poll(board)
        disable_gc()
        a0 = mem_alloc()
        t0 = ticks_us()
        t += 1000
        board.t = t
        f.step(t)
        t1 = ticks_us()
        a1 = mem_alloc()
        d = ticks_diff(t1, t0)
        us += d
        nbytes += a1 - a0
        if fresh:
            if after_gc is not None:
                after_gc[0] += d
                after_gc[1] += 1
            fresh = False
    enable_gc()
    return us, nbytes, gcs, t


def rx_core1(f):
    """The flight's receiver codec handed to an RxCore (rx_core1), for timed_passes to poll as core 1 would."""
    from hoverfly.core.stages.rxcore import RxLink

    return f.receiver.use_core1(RxLink())


def run(passes, core1=False):
    """(µs a pass, bytes a pass, passes a collection, µs a pass right after a collection)."""
    board, f, t = armed_flight()
    after_gc = [0, 0]
    us, nbytes, gcs, t = timed_passes(board, f, t, passes, after_gc, rx_core1(f) if core1 else None)
    cold = after_gc[0] / after_gc[1] if after_gc[1] else 0.0
    return us / passes, nbytes / passes, passes / gcs if gcs else 0.0, cold


def tasks_us(passes, core1=False):
    """µs a pass spent in the scheduler's slow tasks (Scheduler.run: receiver, arming and failsafe, battery,
    LED), timed around each run() call on a flight of its own (the timing wrapper is not in us_per_pass)."""
    board, f, t = armed_flight()
    sched = f.scheduler
    real_run = sched.run
    spent = [0]

    def timed_run(now_us):
        t0 = ticks_us()
        real_run(now_us)
        spent[0] += ticks_diff(ticks_us(), t0)

    sched.run = timed_run
    timed_passes(board, f, t, passes, None, rx_core1(f) if core1 else None)
    return spent[0] / passes


def main():
    core1 = "--rx-core1" in sys.argv
    passes = 2000 if IS_MICROPYTHON else 20000
    best = None
    tasks = None
    for _ in range(3):
        r = run(passes, core1)
        if best is None or r[0] < best[0]:
            best = r
        u = tasks_us(passes, core1)
        if tasks is None or u < tasks:
            tasks = u
    runtime = "micropython" if IS_MICROPYTHON else "cpython"
    # loop_us_per_pass: the pass less its slow tasks, what Betaflight calls the gyro/PID loop (its `tasks`
    # command lists the receiver and the other tasks apart); the board runs both in the same period.
    print('{"runtime": "%s", "us_per_pass": %.2f, "bytes_per_pass": %.1f, "passes": %d, "passes_per_gc": %.1f, '
          '"us_per_pass_after_gc": %.2f, "tasks_us_per_pass": %.2f, "loop_us_per_pass": %.2f, "rpm_harmonics": %d%s%s}'
          % (runtime, best[0], best[1], passes, best[2], best[3], tasks, best[0] - tasks, RPM_HARMONICS,
             ', "rx_core1": true' if core1 else "", ', "plane": true' if PLANE else ""))


if __name__ == "__main__":
    main()
    sys.stdout.flush()
