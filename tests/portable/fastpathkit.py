"""What the fast-path tests (test_fast_paths, test_glue_fast_paths) share: deterministic inputs
and a parameter set with overrides. Portable: imported under pytest and tests/portable/mprun.py."""

from hoverfly.core.config.params import Params


class Rand:
    """Deterministic -1..1 numbers (LCG): the same sequence on CPython and MicroPython."""

    def __init__(self, seed):
        self.s = seed

    def __call__(self):
        self.s = (self.s * 1103515245 + 12345) & 0x7FFFFFFF
        return self.s / 0x7FFFFFFF * 2.0 - 1.0


def params(**kw):
    """Params with the defaults, then each keyword set."""
    p = Params()
    for k, v in kw.items():
        p.set(k, v)
    return p


def heap_bytes(fn, times):
    """Heap bytes `times` calls of fn() allocate, the collector off (MicroPython's gc.mem_alloc;
    0 on CPython, which has no such count)."""
    from hoverfly.compat import collect_garbage, disable_gc, enable_gc, mem_alloc

    collect_garbage()
    disable_gc()
    try:
        a0 = mem_alloc()
        for _ in range(times):
            fn()
        return mem_alloc() - a0
    finally:
        enable_gc()
