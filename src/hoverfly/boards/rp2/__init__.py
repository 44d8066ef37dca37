"""The Raspberry Pi Pico board (MicroPython-only device code): pins, board, DShot PIO, main loop."""
