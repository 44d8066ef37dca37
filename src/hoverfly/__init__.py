"""hoverfly: a flight controller in Python (MicroPython on the Pico, CPython on Linux and the simulator)."""

import sys

VERSION = (0, 1, 0)
__version__ = "0.1.0"

if sys.implementation.name == "cpython":
    # HOVERFLY_NATIVE=1: the simulated flight's modules from their compiled twins, where built (hoverfly/native.py)
    from hoverfly import nativeenv  # noqa: F401
