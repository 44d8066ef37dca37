"""hoverfly: a flight controller in Python (MicroPython on the Pico, CPython on Linux and the simulator)."""

import sys

VERSION = (0, 1, 0)
__version__ = "0.1.0"

if sys.implementation.name == "cpython":
    # the simulated flight runs on its compiled twins where built, unless HOVERFLY_NATIVE=0 (hoverfly/nativeenv.py)
    from hoverfly import nativeenv  # noqa: F401
