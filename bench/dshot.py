"""DShot output codec cost: µs to build four frames (float and integer paths, and the board's whole
output codec `OutputEncoder.write`: motor order, command queue, failsafe stamp), bytes allocated, eRPM decode.

Run: `.venv/bin/python bench/dshot.py` and
`MICROPYPATH=src:.frozen .venv/bin/micropython -X heapsize=384k bench/dshot.py` (the parameter table and
output stage compiled from source need more than 192 KB).
Prints one JSON object; times are the best of several runs; allocation is measured with
the GC disabled (MicroPython only; null on CPython).
"""

import sys
from array import array

from hoverfly.compat import (
    IS_MICROPYTHON,
    collect_garbage,
    disable_gc,
    enable_gc,
    mem_alloc,
    ticks_diff,
    ticks_us,
)
from hoverfly.core.config.params import Params
from hoverfly.core.stages.output import OutputEncoder
from hoverfly.protocols.dshot import DshotEncoder, ErpmDecoder, dshot_frame, gcr_encode

RUNS = 5
N = 2000 if IS_MICROPYTHON else 20000

ENC = DshotEncoder(4, bidir=True, idle_pct=5.5, stop_at_zero=False)
MOTORS = array("f", [0.1, 0.42, 0.77, 1.0])
VALUES = array("H", [158, 900, 1600, 2047])
OUT = array("H", [0] * 4)
CODE = gcr_encode(0x5F41)
DEC = ErpmDecoder(14)
_P = Params()
_P.set("dshot_bidir", 1)
_P.set("motor_order", 2143)
BOARD_OUT = OutputEncoder()
BOARD_OUT.configure(_P, 4, 0, ticks_us())
BOARD_OUT.commands.clear()  # the boot commands would otherwise be dropped by the first spinning write


def op_encode_motors():
    ENC.encode_motors(MOTORS, True, OUT)


def op_encode_values():
    ENC.encode_values(VALUES, OUT)


def op_four_frames():
    f = dshot_frame
    OUT[0] = f(158, 0, True)
    OUT[1] = f(900, 0, True)
    OUT[2] = f(1600, 0, True)
    OUT[3] = f(2047, 0, True)


def op_output_encoder_write():
    BOARD_OUT.write(MOTORS, 4, 0)


def op_decode_reply():
    DEC.decode_code(CODE)


def best_us(op):
    best = None
    for _ in range(RUNS):
        t0 = ticks_us()
        for _ in range(N):
            op()
        us = ticks_diff(ticks_us(), t0) / N
        best = us if best is None or us < best else best
    return best


def alloc_bytes(op):
    if not IS_MICROPYTHON:
        return None
    op()
    collect_garbage()
    disable_gc()
    try:
        before = mem_alloc()
        for _ in range(100):
            op()
        grown = mem_alloc() - before
    finally:
        enable_gc()
    return grown / 100


def _num(x):
    return "null" if x is None else "%.3f" % x


def main():
    ops = (
        ("encode_motors_4_float", op_encode_motors),
        ("encode_values_4_int", op_encode_values),
        ("dshot_frame_x4", op_four_frames),
        ("output_encoder_write_4", op_output_encoder_write),
        ("erpm_decode_code", op_decode_reply),
    )
    parts = ['"implementation": "%s"' % sys.implementation.name]
    for name, op in ops:
        parts.append('"%s_us": %s' % (name, _num(best_us(op))))
        parts.append('"%s_alloc_bytes": %s' % (name, _num(alloc_bytes(op))))
    print("{" + ", ".join(parts) + "}")


main()
