"""Where the flight pass goes: µs and bytes per call of each stage of bench/core_loop.py's armed flight.

Takes bench/core_loop.py's armed flight (`armed_flight()`: an MPU-6050 burst through the driver,
a CRSF frame every 4th pass, DShot words), then times every stage call separately: each stage
method is replaced on its instance by a wrapper that reads ticks_us() and gc.mem_alloc() around
the real call (GC disabled for the pass, collected between passes as bench/core_loop.py does, untimed).
A wrapper has the stage's arity and calls the class's function with the instance first, as the pass's own
method call does (a bound method called with many arguments copies them to the heap on MicroPython). The
wrapper's own cost (a wrapped no-op of the same arity, measured the same way) is subtracted from every
per-call figure; probe_us and probe_bytes are the three-argument one's. The slow tasks
are probed on a second flight and the calls inside them on a third (gc.mem_alloc() walks the heap: a
probe inside a probed call would add its walk to the outer call's time).

Prints one JSON object:
{runtime, passes, step_us, step_bytes, probe_us, probe_bytes, stages: {name: [us_per_call, bytes_per_call,
calls_per_pass, us_per_pass]}, nested: {...}, step_self_us}. `stages` are called from Flight.step (they add
up to the pass with step_self_us, the pass's own glue); `nested` run inside a stage (task_rx, task_arming) and
are already counted in it. Per-call figures are the best (lowest) of three runs.

    python3 bench/core_stages.py
    MICROPYPATH=src .venv/bin/micropython -X heapsize=1m bench/core_stages.py
    MICROPYPATH=src .venv/bin/micropython -X heapsize=1m bench/core_stages.py --passes 100   # a quick run

(`--passes N`: N passes a run instead of 20000 on CPython, 2000 on MicroPython.)

(1 MB heap: the probes and more flights do not fit the 512 KB bench/core_loop.py runs in.)
"""

import sys

# The flight bench/core_loop.py times whole (importing it also compiles the core leaves first on
# MicroPython, collecting in between; both runtimes put the script's folder on sys.path).
from core_loop import armed_flight, timed_passes
from hoverfly.compat import (
    IS_MICROPYTHON,
    collect_garbage,
    disable_gc,
    enable_gc,
    mem_alloc,
    ticks_diff,
    ticks_us,
)

# ------------------------------------------------------------------------------------ the probes
# One slot per probe: total µs, bytes and calls. Small ints only, so the bookkeeping allocates nothing.
US = [0] * 64
BYTES = [0] * 64
CALLS = [0] * 64
NAMES = []
NESTED = []
ARITY = []


_WRAPPER = """
def w(%(params)s):
    m0 = mem_alloc()
    t0 = ticks_us()
    r = fn(%(args)s)
    t1 = ticks_us()
    m1 = mem_alloc()
    US[slot] += ticks_diff(t1, t0)
    BYTES[slot] += m1 - m0
    CALLS[slot] += 1
    return r
"""


def _wrap(slot, fn, nargs, obj):
    """A wrapper of the stage's own arity (a *args call allocates on MicroPython, inside the timed window).
    With obj, fn is the class's function and gets obj first: calling a bound method with many arguments
    copies them to the heap on MicroPython, which the stage's own call (LOAD_METHOD) never does."""
    params = ", ".join("a%d" % i for i in range(nargs))
    args = ", ".join((["obj"] if obj is not None else []) + ["a%d" % i for i in range(nargs)])
    space = {"fn": fn, "obj": obj, "slot": slot, "US": US, "BYTES": BYTES, "CALLS": CALLS,
             "mem_alloc": mem_alloc, "ticks_us": ticks_us, "ticks_diff": ticks_diff}
    exec(_WRAPPER % {"params": params, "args": args}, space)
    return space["w"]


def probe(obj, attr, name, nargs, nested=False):
    slot = len(NAMES)
    NAMES.append(name)
    NESTED.append(nested)
    ARITY.append(nargs)
    fn = getattr(type(obj), attr, None)
    if type(fn) is not _FUNCTION or attr in getattr(obj, "__dict__", {}):
        # an instance attribute (a callable stored on it), or a viper/native method: the bound method
        setattr(obj, attr, _wrap(slot, getattr(obj, attr), nargs, None))
    else:
        setattr(obj, attr, _wrap(slot, fn, nargs, obj))


class _Noop:
    """Methods of each arity the stages have: what a probe costs around a call that does nothing."""

    def f0(self):
        return None

    def f1(self, a):
        return None

    def f2(self, a, b):
        return None

    def f3(self, a, b, c):
        return None

    def f4(self, a, b, c, d):
        return None

    def f5(self, a, b, c, d, e):
        return None

    def f6(self, a, b, c, d, e, g):
        return None

    def f7(self, a, b, c, d, e, g, h):
        return None

    def f8(self, a, b, c, d, e, g, h, k):
        return None


_FUNCTION = type(_Noop.f0)


def _probe_costs(passes, runs):
    """The probe's own cost by arity: ([µs a call], [bytes a call]), best of runs."""
    noop = _Noop()
    us = [0.0] * 9
    nbytes = [0.0] * 9
    for n in range(9):
        slot = len(NAMES)
        probe(noop, "f%d" % n, "noop", n)
        call = getattr(noop, "f%d" % n)
        args = tuple(range(n))
        best = None
        for _ in range(runs):
            US[slot] = BYTES[slot] = CALLS[slot] = 0
            for k in range(passes):
                if k % 16 == 0:
                    collect_garbage()
                disable_gc()
                call(*args)
                enable_gc()
            if best is None or US[slot] < best:
                best = US[slot]
                nbytes[n] = BYTES[slot] / passes
        us[n] = best / passes
        NAMES.pop()
        NESTED.pop()
        ARITY.pop()
    return us, nbytes


def _clear():
    for i in range(len(US)):
        US[i] = 0
        BYTES[i] = 0
        CALLS[i] = 0


def install_stages(board, f):
    """Probes on what Flight.step calls (the slow tasks as whole calls)."""
    probe(board, "read_imu", "read_imu", 2)
    probe(f.alignment, "apply", "alignment (math)", 1)
    if f._fixed_imu_on:  # with pid_math's fixed rate loop: both IMU filters as one fixed-point pass
        probe(f.fixed_imu, "update", "fixed: gyro + accel filters", 0)
    else:
        probe(f.gyro_filter, "update", "gyro_filter (math)", 3)
        probe(f.accel_filter, "update", "accel_filter (math)", 2)
    if f._fixed_att_on:  # with the fixed rate loop: the estimator's gyro average and update in fixed point
        probe(f.fixed_att, "step", "fixed: estimator", 2)
    else:
        probe(f.mahony, "update", "mahony (math)", 5)
    probe(f.rc, "update", "rc.update", 1)
    probe(f.commander, "update", "commander.update", 2)
    if f._fixed_on:  # pid_math: the controller and mixer as one fixed-point pass (MicroPython)
        probe(f.fixed, "update", "fixed: controller + mixer", 4)
    else:
        probe(f.controller, "update", "controller (math)", 7)
        probe(f.mixer, "update", "mixer", 4)
    if f._fixed_out_on:  # with the fixed rate loop: the motor commands in fixed point
        probe(f.output, "update_fixed", "fixed: motor commands", 3)
    else:
        probe(f.output, "update", "output.update", 3)
    probe(f.motor_test, "update", "motor_test", 5)
    probe(board, "write_motors", "write_motors", 2)
    probe(f.scheduler, "run", "scheduler.run (+tasks)", 1)


def install_tasks(board, f):
    """Probes on the slow tasks as whole calls."""
    for task in f.scheduler.tasks:
        probe(task, "fn", "task_" + task.name, 1, True)


def install_nested(board, f):
    """Probes inside the slow tasks, on a flight of their own: gc.mem_alloc() walks the heap, so a probe
    inside a probed call would add its walk to the outer figure."""
    probe(f.receiver, "update", "receiver.update", 2, True)
    probe(f.rc, "fs_switch_in", "rc.fs_switch_in", 1, True)
    probe(f.rc, "new_frame", "rc.new_frame", 2, True)  # the pilot's frame, and the receiver's copied into it
    probe(f.arming, "on_switch", "arming.on_switch", 2, True)
    probe(f.receiver, "telemetry_due", "receiver.telemetry_due", 1, True)
    probe(f.faults, "check_imu", "faults.check_imu", 2, True)
    probe(f.faults, "check_load", "faults.check_load", 4, True)
    probe(f.faults, "check_crash", "faults.check_crash", 6, True)
    probe(f.rc, "throttle_low", "rc.throttle_low", 0, True)
    probe(f.bit, "update", "bit.update", 5, True)
    probe(f.arming, "check", "arming.check", 8, True)
    probe(f.autopilot, "update", "autopilot.update", 2, True)
    probe(f.failsafe, "observe", "failsafe.observe", 6, True)
    probe(f.failsafe, "update", "failsafe.update", 8, True)


def _measure(board, f, t, passes, runs, probe_us, probe_b, best):
    for _ in range(runs):
        _clear()
        _, _, _, t = timed_passes(board, f, t, passes)
        for i in range(len(NAMES)):
            if CALLS[i]:
                per_us = US[i] / CALLS[i] - probe_us[ARITY[i]]
                per_b = BYTES[i] / CALLS[i] - probe_b[ARITY[i]]
                if best[i] is None or per_us < best[i][0]:
                    best[i] = (per_us, per_b, CALLS[i] / passes)
    return t


def main():
    passes = 2000 if IS_MICROPYTHON else 20000
    if "--passes" in sys.argv:  # a short run checks that every probe still fits its stage; figures need the default
        passes = int(sys.argv[sys.argv.index("--passes") + 1])
    runs = 3
    board, f, t = armed_flight()
    step_us = None
    step_bytes = 0
    for _ in range(runs):
        us, nbytes, _, t = timed_passes(board, f, t, passes)
        if step_us is None or us < step_us:
            step_us = us
            step_bytes = nbytes
    # the probe's own cost: a wrapped no-op of each arity, called as the stages are
    probe_us, probe_b = _probe_costs(passes, runs)
    install_stages(board, f)
    best = [None] * 64
    _measure(board, f, t, passes, runs, probe_us, probe_b, best)
    board, f, t = armed_flight()
    install_tasks(board, f)
    _measure(board, f, t, passes, runs, probe_us, probe_b, best)
    board, f, t = armed_flight()
    install_nested(board, f)
    _measure(board, f, t, passes, runs, probe_us, probe_b, best)
    self_us = step_us / passes
    parts = []
    for nested in (False, True):
        items = []
        for i in range(len(NAMES)):
            if NESTED[i] != nested or best[i] is None:
                continue
            per_us, per_b, per_pass = best[i]
            if not nested:
                self_us -= per_us * per_pass
            items.append('"%s": [%.2f, %.1f, %.2f, %.2f]' % (NAMES[i], per_us, per_b, per_pass, per_us * per_pass))
        parts.append("{" + ", ".join(items) + "}")
    runtime = "micropython" if IS_MICROPYTHON else "cpython"
    print('{"runtime": "%s", "passes": %d, "step_us": %.2f, "step_bytes": %.1f, "probe_us": %.2f, '
          '"probe_bytes": %.1f, "step_self_us": %.2f, "stages": %s, "nested": %s}'
          % (runtime, passes, step_us / passes, step_bytes / passes, probe_us[3], probe_b[3], self_us, parts[0],
             parts[1]))


if __name__ == "__main__":
    main()
sys.stdout.flush()
