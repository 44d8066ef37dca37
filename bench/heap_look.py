"""What a look at the free heap costs on MicroPython: gc.mem_free() and gc.mem_alloc() walk the heap's
whole allocation table, so their cost grows with the heap (why boards/rp2/main.run asks only when
core/scheduler.py's HeapWatch says a collection may be near, not after every pass).

Prints one JSON object: {runtime, heap_bytes, mem_free_us, mem_alloc_us} (best of three batches of 200
calls, with 2000 small objects live). MicroPython only (CPython has no gc.mem_free).

    .venv/bin/micropython -X heapsize=192k bench/heap_look.py
    .venv/bin/micropython -X heapsize=384k bench/heap_look.py
"""

import gc
import sys

try:
    from time import ticks_diff, ticks_us
except ImportError:  # CPython
    ticks_us = None


def _per_call(fn, calls=200):
    best = None
    for _ in range(3):
        t0 = ticks_us()
        for _ in range(calls):
            fn()
        us = ticks_diff(ticks_us(), t0) / calls
        if best is None or us < best:
            best = us
    return best


def main():
    if ticks_us is None or not hasattr(gc, "mem_free"):
        print('{"runtime": "%s", "error": "MicroPython only"}' % sys.implementation.name)
        return
    live = [bytearray(20) for _ in range(2000)]  # a heap with objects on it, as a flight's is
    gc.collect()
    heap = gc.mem_free() + gc.mem_alloc()
    print('{"runtime": "micropython", "heap_bytes": %d, "mem_free_us": %.2f, "mem_alloc_us": %.2f}'
          % (heap, _per_call(gc.mem_free), _per_call(gc.mem_alloc)))
    return live


if __name__ == "__main__":
    main()
