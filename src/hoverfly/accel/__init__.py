"""Native-code twins (`@micropython.viper`) of the flight pass's byte-level stages, MicroPython only.

Not portable code: viper compiles to the target's machine code, so mpy-cross needs its `-march`
(`hoverfly flash` passes the chip's) and CPython cannot import these modules. The portable modules
that use them (protocols/crsf.py, protocols/dshot.py, drivers/mpu6050.py) import them on MicroPython
only, inside try/except, and keep their own Python code as the twin and the fallback;
tests/portable/test_viper_twins.py checks both give the same results. docs/micropython-accel.md.
"""
