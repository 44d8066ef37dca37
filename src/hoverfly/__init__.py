"""hoverfly: a flight controller in Python (MicroPython on the Pico, CPython on Linux and the simulator)."""

VERSION = (0, 1, 0)
__version__ = "0.1.0"
