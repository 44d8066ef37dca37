"""Native-code twins (`@micropython.viper`) of the flight pass's stages, MicroPython only.

Not portable code: viper compiles to the target's machine code, so mpy-cross needs its `-march`
(`hoverfly flash` passes the chip's) and CPython cannot import these modules. The portable module that
uses one imports it on MicroPython only, inside try/except, and keeps its own Python code as the
reference and the fallback; the twin tests check both give the same bits.

imufilter, rate, att, output, sched, rc, faults, rxcodec, crc and mpu6050 are generated from their Python by
hoverfly.fastgen (docs/fastpass.md) and are not in git (.gitignore); dshot is written by hand
(docs/fastpass.md says why). addr.py holds what the generated ones share:
`bind` and the encode's `LOG2` table.
"""
