"""Tasks at divided rates: one row per slow job, run after the flight pass.

Each task has a rate in Hz and is due when the tick clock passes its next time; a
task that fell behind runs once and is rescheduled from now (no bursts of catch-up).
The scheduler also keeps the pass statistics: cycle time, jitter against the nominal
period, and overruns.
"""

from hoverfly.compat import ticks_add, ticks_diff


class Task:
    def __init__(self, name, rate_hz, fn):
        self.name = name
        self.rate_hz = rate_hz
        self.period_us = 1000000 // rate_hz
        self.fn = fn
        self.next_us = 0
        self.runs = 0


class Scheduler:
    def __init__(self):
        self.tasks = []
        self.period_us = 1000
        self.passes = 0
        self.cycle_us = 0
        self.cycle_max_us = 0
        self.jitter_max_us = 0
        self.jitter_sum_us = 0
        self.overruns = 0
        self._last_us = 0
        self.next_due_us = 0  # the earliest task's next time: run() has nothing to do before it

    def add(self, name, rate_hz, fn):
        self.tasks.append(Task(name, rate_hz, fn))

    def start(self, now_us, loop_hz):
        self.period_us = 1000000 // loop_hz
        self._last_us = now_us
        for t in self.tasks:
            t.next_us = now_us
        self.next_due_us = now_us

    def pass_started(self, now_us):
        """Record the cycle time of the pass starting now."""
        c = ticks_diff(now_us, self._last_us)
        self._last_us = now_us
        self.passes += 1
        self.cycle_us = c
        if c > self.cycle_max_us:
            self.cycle_max_us = c
        j = c - self.period_us
        if j < 0:
            j = -j
        self.jitter_sum_us += j
        if j > self.jitter_max_us:
            self.jitter_max_us = j

    def pass_took(self, duration_us):
        if duration_us > self.period_us:
            self.overruns += 1

    def run(self, now_us):
        # Most passes run no task: one comparison against the earliest due time.
        if ticks_diff(now_us, self.next_due_us) < 0:
            return
        first = None
        for t in self.tasks:
            if ticks_diff(now_us, t.next_us) >= 0:
                t.runs += 1
                t.fn(now_us)
                nxt = ticks_add(t.next_us, t.period_us)
                if ticks_diff(now_us, nxt) >= 0:
                    nxt = ticks_add(now_us, t.period_us)
                t.next_us = nxt
            if first is None or ticks_diff(t.next_us, first) < 0:
                first = t.next_us
        self.next_due_us = first

    def stats_reset(self):
        self.cycle_max_us = 0
        self.jitter_max_us = 0
        self.jitter_sum_us = 0
