"""hoverfly: a flight controller in Python (MicroPython on the Pico, CPython on Linux and the simulator)."""

import sys

VERSION = (0, 1, 0)
__version__ = "0.1.0"

if sys.implementation.name == "cpython":
    import os

    if os.environ.get("HOVERFLY_NATIVE", "0") not in ("", "0"):
        # The simulated flight's modules from their compiled twins, where built (hoverfly/native.py).
        from hoverfly import native

        native.install()
