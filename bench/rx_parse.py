"""Receiver parse cost: µs to feed one whole RC frame and have channels_us, per protocol.

Runs unchanged on CPython and MicroPython:
    .venv/bin/python bench/rx_parse.py
    MICROPYPATH=src:.frozen .venv/bin/micropython -X heapsize=384k bench/rx_parse.py
    .venv/bin/python bench/rx_parse.py --frames 200   # a quick run (FRAMES: 500 on MicroPython, else 20000)
(384 KB: the parameter table compiled from source needs more than 192 KB.)
Prints one JSON object: runtime, µs per frame for CRSF (26 bytes), SBUS (25), iBUS (32),
CRSF with the frame split in two reads (the framer's assembly path), the whole receiver
stage per CRSF frame (core/stages/receiver.py: board read + decode + link watch, as the 500 Hz
receiver task runs it), and bytes the heap grew per CRSF/SBUS/iBUS frame and per receiver
stage frame with the GC disabled (MicroPython; CPython reports 0).
Best of several runs. The goal is CRSF <= 5 µs on CPython.
"""

import sys

from hoverfly.compat import collect_garbage, disable_gc, enable_gc, mem_alloc, ticks_diff, ticks_us
from hoverfly.core.config.params import Params
from hoverfly.core.stages.receiver import Receiver
from hoverfly.protocols import crsf, ibus, sbus

RUNS = 7
MICROPYTHON = sys.implementation.name == "micropython"
FRAMES = 500 if MICROPYTHON else 20000
if "--frames" in sys.argv:  # a short run checks that the bench still runs; figures need the default
    FRAMES = int(sys.argv[sys.argv.index("--frames") + 1])

_CHANNELS_US = (988, 2011, 1500, 1000, 2000, 1193, 1505, 1817, 1200, 1800, 988, 1500, 2011, 1500, 988, 1500)


def _best_us(decoder, frame, frames):
    best = 1e9
    feed = decoder.feed
    for _ in range(RUNS):
        t0 = ticks_us()
        for _ in range(frames):
            feed(frame)
        dt = ticks_diff(ticks_us(), t0)
        if dt < best:
            best = dt
    return best / frames


def _best_split_us(decoder, frame, frames):
    mv = memoryview(frame)
    head = bytes(mv[:10])
    tail = bytes(mv[10:])
    best = 1e9
    feed = decoder.feed
    for _ in range(RUNS):
        t0 = ticks_us()
        for _ in range(frames):
            feed(head)
            feed(tail)
        dt = ticks_diff(ticks_us(), t0)
        if dt < best:
            best = dt
    return best / frames


class _OneFrameBoard:
    """Hands the receiver stage the same whole CRSF frame on every read (a UART DMA buffer)."""

    def __init__(self, frame):
        self.frame = frame
        self.ready = False

    def read_rx(self, buf):
        if not self.ready:
            return 0
        self.ready = False
        f = self.frame
        for i in range(26):
            buf[i] = f[i]
        return 26


def _receiver_us(frame, frames):
    rx = Receiver()
    rx.configure(Params())
    rx.start(0)
    board = _OneFrameBoard(frame)
    update = rx.update
    best = 1e9
    t_us = 0
    for _ in range(RUNS):
        t0 = ticks_us()
        for _ in range(frames):
            board.ready = True
            t_us += 4000
            update(t_us, board)
        dt = ticks_diff(ticks_us(), t0)
        if dt < best:
            best = dt
    collect_garbage()
    disable_gc()
    try:
        a0 = mem_alloc()
        for _ in range(200):
            board.ready = True
            t_us += 4000
            update(t_us, board)
        grown = mem_alloc() - a0
    finally:
        enable_gc()
    return best / frames, grown / 200, rx.frames == RUNS * frames + 200


def _bytes_per_frame(decoder, frame, frames):
    feed = decoder.feed
    feed(frame)
    collect_garbage()
    disable_gc()
    try:
        a0 = mem_alloc()
        for _ in range(frames):
            feed(frame)
        grown = mem_alloc() - a0
    finally:
        enable_gc()
    return grown / frames


def main():
    crsf_frame = bytes(crsf.encode_rc_frame(_CHANNELS_US))
    sbus_frame = bytes(sbus.encode_rc_frame(_CHANNELS_US))
    ibus_frame = bytes(ibus.encode_rc_frame(_CHANNELS_US))
    dc = crsf.CrsfDecoder()
    ds = sbus.SbusDecoder()
    di = ibus.IbusDecoder()
    crsf_us = _best_us(dc, crsf_frame, FRAMES)
    sbus_us = _best_us(ds, sbus_frame, FRAMES)
    ibus_us = _best_us(di, ibus_frame, FRAMES)
    split_us = _best_split_us(crsf.CrsfDecoder(), crsf_frame, FRAMES)
    stage_us, stage_bpf, stage_ok = _receiver_us(crsf_frame, FRAMES)
    ok = (list(dc.channels_us) == list(_CHANNELS_US) and dc.crc_errors == 0 and ds.frames > 0 and di.frames > 0
          and stage_ok)
    bpf_crsf = _bytes_per_frame(dc, crsf_frame, 200)
    bpf_sbus = _bytes_per_frame(ds, sbus_frame, 200)
    bpf_ibus = _bytes_per_frame(di, ibus_frame, 200)
    print(
        '{"runtime": "%s", "crsf_us_per_frame": %.2f, "sbus_us_per_frame": %.2f, "ibus_us_per_frame": %.2f, '
        '"crsf_split_us_per_frame": %.2f, "receiver_stage_us_per_frame": %.2f, "bytes_per_frame": %.1f, '
        '"sbus_bytes_per_frame": %.1f, "ibus_bytes_per_frame": %.1f, "receiver_stage_bytes_per_frame": %.1f, '
        '"frames": %d, "decoded_ok": %s}'
        % (
            "micropython" if MICROPYTHON else "cpython",
            crsf_us, sbus_us, ibus_us, split_us, stage_us, bpf_crsf, bpf_sbus, bpf_ibus, stage_bpf, FRAMES,
            "true" if ok else "false",
        )
    )


main()
