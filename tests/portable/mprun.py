"""Run the portable tests under MicroPython (or CPython): `micropython tests/portable/mprun.py [module ...]`.

Each module in tests/portable named test_*.py holds plain `test_*` functions with bare
asserts (no pytest), so pytest collects the very same functions on CPython. Prints one
line per failure and closes with 'N passed, N failed'. Exit status 1 on any failure.
"""

import sys

try:
    import os

    _listdir = os.listdir
except ImportError:  # pragma: no cover - minimal ports
    _listdir = None

HERE = __file__.rsplit("/", 1)[0] if "/" in __file__ else "."


def _modules(argv):
    if argv:
        return argv
    names = [n[:-3] for n in _listdir(HERE) if n.startswith("test_") and n.endswith(".py")]
    names.sort()
    return names


def main(argv):
    sys.path.insert(0, HERE)
    passed = 0
    failed = 0
    for modname in _modules(argv):
        mod = __import__(modname)
        names = [n for n in dir(mod) if n.startswith("test_")]
        names.sort()
        for name in names:
            fn = getattr(mod, name)
            try:
                fn()
                passed += 1
            except Exception as exc:  # report and keep going
                failed += 1
                print("FAIL %s.%s: %r" % (modname, name, exc))
                try:
                    sys.print_exception(exc)
                except AttributeError:
                    import traceback

                    traceback.print_exc()
    print("%d passed, %d failed" % (passed, failed))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
