"""What one attribute store costs on an instance of a plain class, of a class with a property, and of
a subclass of that (the reason the portable packages have no properties: tests/test_portable_classes.py).

Runs under MicroPython and CPython; prints one JSON object {runtime, stores, us_per_store: {plain,
with_property, subclass}}, the best of five rounds each, in turn.

    MICROPYPATH=src .venv/bin/micropython bench/attr_store.py
    .venv/bin/python bench/attr_store.py
"""

import sys

from hoverfly.compat import ticks_diff, ticks_us

STORES = 20000
ROUNDS = 5


class Plain:
    def __init__(self):
        self.x = 0


class WithProperty:
    def __init__(self):
        self.x = 0

    @property
    def p(self):
        return 1


class Subclass(WithProperty):
    pass


def _round(obj):
    t0 = ticks_us()
    for i in range(STORES):
        obj.x = i
    return ticks_diff(ticks_us(), t0)


def main():
    objs = (("plain", Plain()), ("with_property", WithProperty()), ("subclass", Subclass()))
    best = {}
    for _ in range(ROUNDS):
        for name, obj in objs:
            us = _round(obj)
            if name not in best or us < best[name]:
                best[name] = us
    print('{"runtime": "%s", "stores": %d, "us_per_store": {"plain": %.3f, "with_property": %.3f, '
          '"subclass": %.3f}}' % (sys.implementation.name, STORES, best["plain"] / STORES,
                                  best["with_property"] / STORES, best["subclass"] / STORES))


if __name__ == "__main__":
    main()
