"""Fakes of the rp2 hardware for off-hardware runs (portable: CPython and MicroPython).

regmodels: register models of the IMU chips behind a fake I2C bus / SPI device, fed with
body-frame motion so drivers (and later the simulator's rp2 board) can be exercised
without a chip.
"""
