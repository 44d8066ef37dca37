"""Scheduler: tasks at their rates, the fastest first, the slow ones only looked at when due and kept off the
fastest task's passes."""

from hoverfly.compat import IS_MICROPYTHON, TICKS_MAX, ticks_add, ticks_diff
from hoverfly.core.scheduler import Scheduler, fast_pass_stats


class Log:
    """Task functions that note (name, time) of each run."""

    def __init__(self):
        self.runs = []

    def task(self, name):
        def fn(now_us):
            self.runs.append((name, now_us))

        return fn

    def names(self, now_us):
        return [n for n, t in self.runs if t == now_us]

    def count(self, name):
        return len([n for n, t in self.runs if n == name])


def _flight_like(log, start_us=0):
    s = Scheduler()
    s.add("rx", 500, log.task("rx"))
    s.add("arming", 100, log.task("arming"))
    s.add("battery", 50, log.task("battery"))
    s.add("led", 10, log.task("led"))
    s.start(start_us, 1000)
    return s


def _passes(s, start_us, n, period_us=1000):
    """n passes, the first at start_us; returns the time of the next one."""
    t = start_us
    for _ in range(n):
        fast_pass_stats(s.stats, period_us)  # as Flight.step records the pass
        s.run(t)
        t = ticks_add(t, period_us)
    return t


def test_each_task_runs_at_its_rate():
    log = Log()
    s = _flight_like(log)
    _passes(s, 0, 1000)  # one second at 1 kHz
    assert log.count("rx") == 500
    assert log.count("arming") == 100
    assert log.count("battery") == 50
    assert log.count("led") == 10
    assert [t.runs for t in s.tasks] == [500, 100, 50, 10]


def test_the_fastest_runs_first_then_the_others_on_the_next_pass_in_order():
    log = Log()
    s = _flight_like(log)
    _passes(s, 0, 102)
    assert log.names(0) == ["rx"]  # all due at start: the receiver, and the others a pass later
    assert log.names(1000) == ["arming", "battery", "led"]
    assert log.names(100000) == ["rx"]
    assert log.names(101000) == ["arming", "battery", "led"]
    assert log.names(10000) == ["rx"]
    assert log.names(11000) == ["arming"]
    assert log.names(2000) == ["rx"]
    assert log.names(3000) == []


def test_receiver_and_arming_never_share_a_pass_at_1khz():
    # The two heaviest jobs (a receiver frame, the 100 Hz arming and failsafe task) in passes of their own:
    # the longest pass is the loop and one of them.
    log = Log()
    s = _flight_like(log)
    _passes(s, 0, 2000)
    rx = set(t for n, t in log.runs if n == "rx")
    arming = set(t for n, t in log.runs if n == "arming")
    assert len(rx) == 1000 and len(arming) == 200
    assert not (rx & arming)
    assert all(t % 10000 == 1000 for t in arming)  # one pass after its time, every 10 ms: no drift


def test_a_loop_as_slow_as_the_receiver_still_runs_everything():
    # At 500 Hz the receiver runs every pass: the others run a pass late with it, not never.
    log = Log()
    s = Scheduler()
    s.add("rx", 500, log.task("rx"))
    s.add("arming", 100, log.task("arming"))
    s.add("led", 10, log.task("led"))
    s.start(0, 500)
    _passes(s, 0, 500, 2000)  # one second
    assert (log.count("rx"), log.count("arming"), log.count("led")) == (500, 100, 10)
    assert log.names(0) == ["rx"]
    assert log.names(2000) == ["rx", "arming", "led"]


def test_fastest_is_found_whatever_the_order_added():
    log = Log()
    s = Scheduler()
    s.add("slow", 10, log.task("slow"))
    s.add("fast", 250, log.task("fast"))
    s.start(0, 1000)
    _passes(s, 0, 100)
    assert log.count("fast") == 25
    assert log.count("slow") == 1
    assert log.names(0) == ["fast"]
    assert log.names(1000) == ["slow"]


def test_next_due_is_the_soonest_task():
    log = Log()
    s = _flight_like(log)
    s.run(0)
    assert s.next_due_us == 0  # arming, battery and LED wait for the next pass
    s.run(1000)
    assert s.next_due_us == 2000  # rx
    s2 = Scheduler()
    s2.add("a", 100, log.task("a"))
    s2.add("b", 50, log.task("b"))
    s2.start(0, 1000)
    s2.run(0)
    s2.run(1000)
    assert s2.next_due_us == 10000
    s2.run(10000)
    assert s2.next_due_us == 20000
    s2.run(20000)
    assert s2.next_due_us == 20000  # b is due, kept off a's pass: the next pass runs it
    s2.run(21000)
    assert s2.next_due_us == 30000


def test_run_before_due_does_nothing():
    log = Log()
    s = _flight_like(log)
    s.run(0)
    s.run(1000)
    n = len(log.runs)
    s.run(1500)
    assert len(log.runs) == n


def test_task_behind_runs_once_and_is_rescheduled_from_now():
    log = Log()
    s = _flight_like(log)
    s.run(0)
    s.run(250000)  # a 250 ms stall: each task once, no burst of catch-up (all late: none waits a pass)
    assert log.names(250000) == ["rx", "arming", "battery", "led"]
    assert [t.next_us for t in s.tasks] == [252000, 260000, 270000, 350000]
    assert s.next_due_us == 252000


def test_task_added_after_start_is_due_at_once():
    log = Log()
    s = _flight_like(log)
    t = _passes(s, 0, 6)  # the last pass at 5000
    s.add("links", 100, log.task("links"))
    assert s.next_due_us == 5000
    s.run(5500)
    assert log.names(5500) == ["links"]
    _passes(s, t, 100)  # 6000 .. 105000
    assert log.count("links") == 11  # 5500, then every 10 ms from 15000 to 105000 (a period on from 5000)


def test_task_faster_than_the_others_added_after_start():
    log = Log()
    s = _flight_like(log)
    t = _passes(s, 0, 10)
    s.add("fast", 1000, log.task("fast"))
    _passes(s, t, 100)  # 10 .. 109 ms
    assert log.count("fast") == 100
    assert log.count("rx") == 55  # every 2 ms: 0 to 8, then a pass late (fast takes every pass) 11 to 109
    assert log.count("arming") == 11  # 1 .. 101 ms
    assert log.names(10000) == ["fast"]
    assert log.names(11000) == ["fast", "rx", "arming"]  # the fastest first, then in the order added


def test_no_tasks():
    s = Scheduler()
    s.start(0, 1000)
    s.run(0)
    s.run(1000)
    assert s.tasks == []
    assert ticks_diff(s.next_due_us, 1000) > 1000000  # nothing due: the pass does not call run() again


def test_rates_across_the_tick_wrap():
    log = Log()
    start = TICKS_MAX - 500000 + 1  # half a second before the tick counter wraps
    s = _flight_like(log, start)
    _passes(s, start, 1000)
    assert log.count("rx") == 500
    assert log.count("arming") == 100
    assert log.count("led") == 10


def test_pass_statistics():
    s = Scheduler()
    s.start(0, 1000)
    for cycle in (1000, 1200, 900, 1000):  # as Flight.step records each pass
        fast_pass_stats(s.stats, cycle)
    from hoverfly.core.scheduler import PS_CYCLE, PS_CYCLE_MAX, PS_JITTER_MAX, PS_JITTER_SUM, PS_PASSES

    ps = s.stats
    assert ps[PS_PASSES] == 4
    assert ps[PS_CYCLE] == 1000 and ps[PS_CYCLE_MAX] == 1200
    assert ps[PS_JITTER_MAX] == 200 and ps[PS_JITTER_SUM] == 300


def test_pass_stats_twins_agree_and_wrap_and_clamp():
    # Flight.step's pass_stats (accel/sched.py's viper twin on MicroPython): the same words as the Python
    # twin, the counts wrapping at COUNT_MASK, a stall longer than that clamped, negative cycles kept
    from array import array

    from hoverfly.core import scheduler as sm

    if not IS_MICROPYTHON:
        assert sm.fast_pass_stats is sm.pass_stats
    a = array("i", [0] * 6)
    b = array("i", [0] * 6)
    a[sm.PS_PERIOD] = b[sm.PS_PERIOD] = 1000
    a[sm.PS_PASSES] = b[sm.PS_PASSES] = sm.COUNT_MASK - 2
    a[sm.PS_JITTER_SUM] = b[sm.PS_JITTER_SUM] = sm.COUNT_MASK - 500
    cycles = [1000, 1250, 990, -40, 0, 7000, sm.COUNT_MASK + 12345, 1000, 999, 1001]
    cycles += [1000 + (k * 37) % 400 for k in range(50)]
    for c in cycles:
        sm.pass_stats(a, c)
        sm.fast_pass_stats(b, c)
        assert list(a) == list(b), c
    assert a[sm.PS_PASSES] == len(cycles) - 3  # wrapped
    assert a[sm.PS_CYCLE_MAX] == sm.COUNT_MASK  # the stall, clamped
    assert 0 <= a[sm.PS_JITTER_SUM] < sm.COUNT_MASK
