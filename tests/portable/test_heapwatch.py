"""HeapWatch: when a board's loop collects garbage, looking at the free heap (a whole-heap walk) seldom."""

from hoverfly.core.scheduler import GC_CHECK_FIRST, GC_CHECK_MAX, HeapWatch


class FakeHeap:
    """A heap of `size` bytes whose passes allocate `per_pass` bytes each; counts its walks (mem_free)."""

    def __init__(self, size, per_pass, pattern=None):
        self.size = size
        self.free = size
        self.per_pass = per_pass
        self.pattern = pattern  # bytes of each pass in turn, instead of per_pass
        self.k = 0
        self.walks = 0

    def run_pass(self):
        if self.pattern is None:
            self.free -= self.per_pass
        else:
            self.free -= self.pattern[self.k % len(self.pattern)]
            self.k += 1

    def mem_free(self):
        self.walks += 1
        return self.free

    def collect(self):
        self.free = self.size


def _loop(heap, watch, passes):
    """The board's loop (boards/rp2/main.run) with endless slack: (collections, lowest free seen)."""
    heap.collect()
    watch.collected()
    collections = 0
    lowest = heap.free
    for _ in range(passes):
        heap.run_pass()
        if heap.free < lowest:
            lowest = heap.free
        if watch.due() and watch.need():
            heap.collect()
            watch.collected()
            collections += 1
    return collections, lowest


def test_collects_once_half_the_heap_is_used_and_never_lets_it_run_out():
    heap = FakeHeap(200000, 2000)
    watch = HeapWatch(heap.mem_free)
    collections, lowest = _loop(heap, watch, 5000)
    # half of 200 kB in 2 kB passes: a collection every 50 passes or so, never below a quarter free
    assert 5000 // 60 <= collections <= 5000 // 45
    assert lowest >= 200000 // 2 - 3 * 2000


def test_looks_at_the_heap_a_few_times_a_collection_not_every_pass():
    heap = FakeHeap(200000, 2000)
    watch = HeapWatch(heap.mem_free)
    collections, _ = _loop(heap, watch, 5000)
    # each look halves the distance to the threshold: a handful of walks a collection
    assert heap.walks <= collections * 12 + 20
    assert heap.walks < 5000 // 4


def test_a_pass_that_allocates_nothing_is_looked_at_every_check_max_passes():
    heap = FakeHeap(200000, 0)
    watch = HeapWatch(heap.mem_free)
    passes = 3 * GC_CHECK_MAX + GC_CHECK_FIRST
    collections, _ = _loop(heap, watch, passes)
    assert collections == 0
    # after the collection's walk: a look once GC_CHECK_FIRST passes have gone, then each look at most as
    # far ahead as the passes seen so far (8, 16, 32 ... since the collection), then every GC_CHECK_MAX
    looks = 0
    seen = 0
    step = GC_CHECK_FIRST
    while seen + step <= passes:
        seen += step
        looks += 1
        step = seen if seen < GC_CHECK_MAX else GC_CHECK_MAX
    assert heap.walks == 1 + looks


def test_a_look_the_slack_had_no_room_for_comes_again_the_next_pass():
    heap = FakeHeap(100000, 1000)
    watch = HeapWatch(heap.mem_free)
    heap.collect()
    watch.collected()
    due = 0
    for _ in range(200):
        heap.free -= heap.per_pass
        if watch.due():
            due += 1  # no slack: the loop skips the look; the watch stays due
        if heap.free < 50000:
            break
    assert due > 1
    assert watch.due()
    assert watch.need()  # under half of 100 kB free: past the threshold at the look


def test_uneven_passes_never_run_the_heap_out():
    # given passes that allocate unevenly, as the flight's do (most a few floats, a slow task's pass a
    # lot more), when the watch plans its looks from what it measured, then the heap never runs out,
    # whichever pass the looks fall on: a short stretch of light passes must not read as the rate
    # (bench/core_loop.py's flight once ran a 512 KB heap out this way with the collector off)
    for light, heavy, every in ((32, 1600, 10), (0, 4000, 20), (16, 900, 4)):
        for phase in range(every):
            pattern = [light] * every
            pattern[phase] = heavy
            heap = FakeHeap(140000, 0, pattern)
            watch = HeapWatch(heap.mem_free)
            collections, lowest = _loop(heap, watch, 20000)
            assert collections > 10
            assert lowest >= 140000 // 4, (light, heavy, every, phase, lowest)


def test_a_rate_that_jumps_is_caught_before_the_heap_runs_out():
    # given a watch that has measured a light rate for a while, when the passes start allocating four
    # times as much in the middle of a collection cycle, then a look still comes before the heap runs out
    for switch in range(3000, 3400, 7):
        heap = FakeHeap(200000, 100)
        watch = HeapWatch(heap.mem_free)
        heap.collect()
        watch.collected()
        lowest = heap.free
        for k in range(6000):
            if k == switch:
                heap.per_pass = 400
            heap.run_pass()
            lowest = min(lowest, heap.free)
            if watch.due() and watch.need():
                heap.collect()
                watch.collected()
        assert lowest > 0, switch
