"""Tasks at divided rates: one row per slow job, run after the flight pass.

Each task has a rate in Hz and is due when the tick clock passes its next time; a
task that fell behind runs once and is rescheduled from now (no bursts of catch-up).
The fastest task (the receiver's, 500 Hz: every other pass at 1 kHz) is checked on its own;
the others are looked at only once the soonest of them is due, so a pass that runs just the
receiver does not walk the whole table (on MicroPython each look is calls and attribute look-ups).
The others keep off a pass that ran the fastest (or another of them) until they have waited one
loop period: at 1 kHz the receiver's frame and the 100 Hz arming and failsafe task, the two heaviest
jobs, never share a pass, so the longest pass is one of them and the gyro/PID loop, not both (as
Betaflight's scheduler runs a task only where it fits). A loop slower than the receiver's rate still
runs everything, a pass late. Tasks run in the order they were added, the fastest first.
Each task call is guarded: a task that raises (a link's request handler, a telemetry encoder, a
slow check) is counted against its task with the exception it raised, and the pass and the other
tasks go on (no link can stop the flight loop). The guard is at the task's dispatch, not in the pass,
and in a function of its own (`_call`): a `try` takes 3 words of a frame and an `except ... as` 6, so
Scheduler.run's or _run's frame would leave the C stack (bench/frame_sizes.py; tests/test_perf_rules.py
holds the pass's functions within 11 words) at every task call. The
guard's frame is at 11 words with a bare `except`: the exception object comes from sys.exc_info where
the port has it (CPython, the unix VM), else from a wrapper put around a task once it has raised, until
it raises again (`_Capture`: only a failing task pays for its frame).
The scheduler also keeps the pass statistics: cycle time, jitter against the nominal
period, and overruns. `HeapWatch` tells a board's loop when to collect garbage in its slack.
"""

import sys
from array import array

from hoverfly.compat import IS_MICROPYTHON, TICKS_HALF, const, ticks_add, ticks_diff

# How far ahead the slow tasks' time lies when there are none: within ticks_diff's range.
_FAR_US = TICKS_HALF - 1

# Scheduler.stats, the pass statistics in one array: the pass's own bookkeeping is then one call of
# pass_stats (on MicroPython its viper twin, accel/sched.py generated from it by hoverfly.fastgen: no bytecode
# frame, no attribute look-ups).
PS_PASSES = const(0)  # passes, all told (wraps at COUNT_MASK)
PS_CYCLE = const(1)  # the last pass's cycle time, µs
PS_CYCLE_MAX = const(2)
PS_JITTER_MAX = const(3)  # |cycle - period|, µs
PS_JITTER_SUM = const(4)  # (wraps at COUNT_MASK)
PS_PERIOD = const(5)  # the nominal period, µs
PS_SIZE = const(6)
COUNT_MASK = const(0x3FFFFFFF)  # small ints on a 32-bit port; a cycle time is clamped to it


# fastpass: pass_stats ps:i
def pass_stats(ps, cycle_us):
    """Record one pass, cycle_us after the last one, into ps (Scheduler.stats)."""
    if cycle_us > COUNT_MASK:
        cycle_us = COUNT_MASK
    ps[PS_PASSES] = (ps[PS_PASSES] + 1) & COUNT_MASK
    ps[PS_CYCLE] = cycle_us
    if cycle_us > ps[PS_CYCLE_MAX]:
        ps[PS_CYCLE_MAX] = cycle_us
    j = cycle_us - ps[PS_PERIOD]
    if j < 0:
        j = -j
    ps[PS_JITTER_SUM] = (ps[PS_JITTER_SUM] + j) & COUNT_MASK
    if j > ps[PS_JITTER_MAX]:
        ps[PS_JITTER_MAX] = j


_viper = None
if IS_MICROPYTHON:
    try:  # generated from pass_stats above by hoverfly.fastgen; absent, or a port without viper: the Python runs
        from hoverfly.accel import sched as _viper
    except (ImportError, SyntaxError, NameError, ValueError, TypeError):  # TypeError: ViperTypeError
        pass
fast_pass_stats = _viper.pass_stats if _viper is not None else pass_stats

_exc_info = getattr(sys, "exc_info", None)  # MicroPython ports without it: _Capture


def _call(t, now_us):
    """Task t's call behind the guard: False if it raised (counted on t by Task.failed). SAFETY: whatever a
    task raises stops here. (A bare except: this frame stays on the C stack, 11 words.)"""
    try:
        t.fn(now_us)
    except Exception:  # noqa: BLE001 - any bug in a task, a link or an encoder: not the loop's end
        t.failed()
        return False
    return True


class _Capture:
    """A failed task's next call on a port without sys.exc_info: puts the task's own function back, calls it,
    and keeps what it raises on the task before passing it on to the guard (which wraps it again). Its frame
    is on the heap: paid only by a task that raised on its last call."""

    def __init__(self, t, fn):
        self.t = t
        self.fn = fn

    def __call__(self, now_us):
        t = self.t
        t.fn = self.fn
        try:
            self.fn(now_us)
        except Exception as exc:
            t.last_error = exc
            raise


class Task:
    def __init__(self, name, rate_hz, fn):
        self.name = name
        self.rate_hz = rate_hz
        self.period_us = 1000000 // rate_hz
        self.fn = fn
        self.next_us = 0
        self.runs = 0
        self.errors = 0  # calls that raised (_call caught them)
        self.last_error = None  # the last exception it raised (formatted only when asked: error_text)

    def failed(self):
        """In _call's except: counted, and the exception kept (not formatted: a task raising at every run
        allocates no text)."""
        self.errors += 1
        if _exc_info is not None:
            self.last_error = _exc_info()[1]
        elif not isinstance(self.fn, _Capture):
            self.fn = _Capture(self, self.fn)  # the next failure keeps its exception

    def error_text(self):
        """The last exception this task raised, one line."""
        e = self.last_error
        if e is None:
            return "not kept yet (raised once)" if self.errors else ""
        return "%s: %s" % (type(e).__name__, e)


class Scheduler:
    def __init__(self):
        self.tasks = []
        self.period_us = 1000
        # PS_*: passes, cycle time, jitter. Read as stats[PS_...]: not properties, which would make every
        # attribute store on a Scheduler look in its class first (tests/test_portable_classes.py).
        self.stats = array("i", [0] * PS_SIZE)
        self.stats[PS_PERIOD] = 1000
        self.overruns = 0
        self.errors = 0  # calls the loop's boundaries caught: the tasks', caught()'s, the log's (Logger._failed)
        self.failed = None  # the task that raised last
        self.on_error = None  # called with (task, exception) after a task raised (Flight: arming's own rule)
        self.boundaries = []  # the records of the loop's other guarded calls (caught), as Tasks never run
        self._last_us = 0
        self.next_due_us = 0  # the earliest task's next time: run() has nothing to do before it
        self._fast = None  # the task of the highest rate, checked on its own every run()
        self._slow = []  # the others, the last added first
        self._slow_due_us = 0  # the soonest of their next times
        self._started = False

    def add(self, name, rate_hz, fn):
        """A task at rate_hz. Added after start(), it is due at once (at the last pass's time)."""
        t = Task(name, rate_hz, fn)
        self.tasks.append(t)
        fast = self.tasks[0]
        for task in self.tasks:
            if task.rate_hz > fast.rate_hz:
                fast = task
        self._fast = fast
        self._slow = [task for task in self.tasks if task is not fast]
        self._slow.reverse()  # _run_slow walks it from the end
        if self._started:
            t.next_us = self._last_us
            self._slow_due_us = self._last_us
            self.next_due_us = self._last_us
        return t

    def start(self, now_us, loop_hz):
        self.period_us = 1000000 // loop_hz
        self.stats[PS_PERIOD] = self.period_us
        self._last_us = now_us
        for t in self.tasks:
            t.next_us = now_us
        self._slow_due_us = now_us
        self.next_due_us = now_us
        self._started = True

    def pass_took(self, duration_us):
        if duration_us > self.period_us:
            self.overruns += 1

    def run(self, now_us):
        """Run the tasks that are due: the fastest on its own check, the others when the soonest is due.
        A call before next_due_us runs nothing (each task has its own check)."""
        # Most passes run no task: the caller compares the time with next_due_us first (Flight.step), so
        # this does not again. The slow tasks' loop is a method of its own, so that this frame and
        # that one stay within 11 words (a bigger one comes from the heap at every call on MicroPython).
        self._last_us = now_us  # a task added from now on is due at once (add)
        fast = self._fast
        if fast is None:
            self.next_due_us = ticks_add(now_us, _FAR_US)
            return
        wait_us = 0  # how late a slow task must be to run in this pass: a loop period once a task ran
        late = ticks_diff(now_us, fast.next_us)
        if late >= 0:
            # _run(fast, now_us) inline, on the lateness already taken: the receiver's task, every other
            # pass at 1 kHz (a period on; from now if it fell a whole period behind)
            fast.runs += 1
            if not _call(fast, now_us):
                self._failed(fast)
            nxt = fast.period_us
            fast.next_us = ticks_add(fast.next_us if late < nxt else now_us, nxt)
            wait_us = self.period_us
        if ticks_diff(now_us, self._slow_due_us) >= wait_us:  # none may run yet: not even the walk
            self._run_slow(now_us, wait_us)
        nxt = fast.next_us
        if ticks_diff(self._slow_due_us, nxt) < 0:
            nxt = self._slow_due_us
        self.next_due_us = nxt

    def _run_slow(self, now_us, wait_us):
        """The tasks other than the fastest that are due, then the soonest of their next times. A due task
        runs once it is wait_us late: 0 on a pass no task has taken yet; a loop period on one another task
        took, so it waits for the next pass unless it has waited that long already. (Indexed from the end,
        not `for t in ...` or a range: a list iterator takes 4 words of the frame, a range loop one, and
        this frame is at 11 words.)"""
        soonest = ticks_add(now_us, _FAR_US)
        i = len(self._slow)
        while i > 0:  # _slow is held last-added first: from its end, in the order added
            i -= 1
            t = self._slow[i]
            if ticks_diff(now_us, t.next_us) >= wait_us:
                self._run(t, now_us)
                wait_us = self.period_us
            if ticks_diff(t.next_us, soonest) < 0:
                soonest = t.next_us
        self._slow_due_us = soonest

    def _run(self, t, now_us):
        """Run task t, then its next time: a period on, or a period from now if it fell behind.
        SAFETY: whatever the task raises stops in _call, counted against it: the pass and the other tasks
        go on, and the task is due again a period on as if it had returned."""
        t.runs += 1
        if not _call(t, now_us):
            self._failed(t)
        nxt = ticks_add(t.next_us, t.period_us)
        if ticks_diff(now_us, nxt) >= 0:
            nxt = ticks_add(now_us, t.period_us)
        t.next_us = nxt

    def _failed(self, t):
        """Task t raised (counted on it by _call): the scheduler's count, and on_error."""
        self.errors += 1
        self.failed = t
        cb = self.on_error
        if cb is not None:
            try:
                cb(t, t.last_error)
            except Exception:  # noqa: BLE001, S110 - the handler's own bug must not end the loop either
                pass

    def caught(self, name, exc):
        """A guarded call outside the task table (the receiver telemetry's) raised exc: counted under name."""
        for b in self.boundaries:
            if b.name == name:
                break
        else:
            b = Task(name, 1, None)
            self.boundaries.append(b)
        b.errors += 1
        b.last_error = exc
        self.errors += 1

    def boundary_errors(self):
        n = 0
        for b in self.boundaries:
            n += b.errors
        return n

    def error_line(self):
        """The tasks and other guarded calls that raised, with their counts and last errors ("" if none)."""
        parts = []
        for t in self.tasks + self.boundaries:
            if t.errors:
                parts.append("%s %d (last %s)" % (t.name, t.errors, t.error_text()))
        return ", ".join(parts)

    def stats_reset(self):
        ps = self.stats
        ps[PS_CYCLE_MAX] = 0
        ps[PS_JITTER_MAX] = 0
        ps[PS_JITTER_SUM] = 0


# Passes between two looks at the free heap: until an allocation rate has been measured, and at most.
GC_CHECK_FIRST = 8
GC_CHECK_MAX = 1000


class HeapWatch:
    """When a board's loop should collect garbage, in its slack: once `1/fraction` of what the last
    collection left free is still free (half used up, by default).

    `mem_free()` (gc.mem_free) walks the heap's whole allocation table: 16-26 µs for a 192 KB heap on
    the MicroPython unix VM here (bench/heap_look.py), so milliseconds on an RP2040, more than a pass.
    So the watch does not ask every pass: it estimates the bytes a pass allocates and looks again halfway
    to the threshold (every GC_CHECK_FIRST passes until it knows the rate, at most every GC_CHECK_MAX).
    The loop calls `due()` every pass; when it is due and the slack allows, `need()` (one walk) says
    whether to collect now, and after collecting, `collected()`.

    The estimate must not run low: the passes do not allocate evenly (a slow task's pass allocates
    far more than a loop-only pass), so a short stretch between two looks can show a fraction of the
    real rate, and a look planned on it comes too late: the heap runs out mid-pass (on a board an
    automatic collection mid-pass, in bench/core_loop.py a MemoryError with the collector off). So the
    rate is the average over all the passes since the last collection, and never below the average of
    the whole previous collection cycle; and the next look is never further ahead than the passes seen
    since the last collection (an extrapolation at most doubles what was measured)."""

    def __init__(self, mem_free, fraction=2):
        self.mem_free = mem_free
        self.fraction = fraction
        self.free_min = 0
        self.looks = 0
        self._free_after = 0  # what the last collection left free
        self._free_last = 0  # what the last look found free
        self._passes = 0  # passes since the last collection
        self._since = 0  # passes since the last look
        self._check_in = GC_CHECK_FIRST
        self._rate = 0  # bytes a pass since the last collection (0: none measured, or none used)
        self._cycle_rate = 0  # bytes a pass over the last whole collection cycle (0: none yet)

    def collected(self):
        """After a collection: the new threshold, from what it left free."""
        if self._passes > 0:  # the cycle that ended: what it used by its last look, over its passes
            used = self._free_after - self._free_last
            self._cycle_rate = used // self._passes if used > 0 else 0
        free = self.mem_free()
        self.free_min = free // self.fraction
        self._free_after = free
        self._free_last = free
        self._passes = 0
        self._rate = 0
        self._seen(free)

    def due(self):
        """Every pass: True when it is time to look at the heap (need(), in the slack)."""
        self._since += 1
        return self._since >= self._check_in

    def need(self):
        """Look at the heap (one walk): True when a collection is due now."""
        free = self.mem_free()
        self.looks += 1
        self._passes += self._since
        self._free_last = free
        if self._passes > 0:
            used = self._free_after - free
            self._rate = used // self._passes if used > 0 else 0
        if free < self.free_min:
            return True
        self._seen(free)
        return False

    def _seen(self, free):
        self._since = 0
        rate = self._rate
        if rate < self._cycle_rate:
            rate = self._cycle_rate
        # halfway to the threshold at that rate; a pass that allocates nothing, GC_CHECK_MAX
        n = (free - self.free_min) // (2 * rate) if rate > 0 else GC_CHECK_MAX
        horizon = self._passes if self._passes > GC_CHECK_FIRST else GC_CHECK_FIRST
        if n > horizon:
            n = horizon
        self._check_in = 1 if n < 1 else (GC_CHECK_MAX if n > GC_CHECK_MAX else n)
