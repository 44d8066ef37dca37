"""Register-level sensor drivers over a bus object (MicroPython-safe)."""
