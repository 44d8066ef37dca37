"""Wire codecs: bytes in through feed(), values out; they never raise on bad input (MicroPython-safe)."""
