"""HeapWatch: when a board's loop collects garbage, looking at the free heap (a whole-heap walk) seldom."""

from hoverfly.core.scheduler import GC_CHECK_FIRST, GC_CHECK_MAX, HeapWatch


class FakeHeap:
    """A heap of `size` bytes whose passes allocate `per_pass` bytes each; counts its walks (mem_free)."""

    def __init__(self, size, per_pass):
        self.size = size
        self.free = size
        self.per_pass = per_pass
        self.walks = 0

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
        heap.free -= heap.per_pass  # the pass
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
    collections, _ = _loop(heap, watch, 3 * GC_CHECK_MAX + GC_CHECK_FIRST)
    assert collections == 0
    # the first look after GC_CHECK_FIRST passes measures no allocation; then one every GC_CHECK_MAX
    assert heap.walks == 1 + 1 + 3


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
