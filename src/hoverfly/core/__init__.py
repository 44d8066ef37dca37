"""The portable flight core: stages of the pass, tasks, parameters (MicroPython-safe)."""
