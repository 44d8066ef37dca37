"""DShot through a PIO state machine: one SM per motor, words pushed with `sm.put(word, 16)`.

Takes 16-bit DShot words (protocols/dshot.py builds them) and drives the motor pin.
Each bit is 8 SM cycles (reference/micropython.md §3.1): high 6 cycles for a 1 (75 %),
3 cycles for a 0 (37.5 %), low for the rest, so the SM clock is 8 × the bit rate
(DShot600: 4.8 MHz). The word goes MSB first (out_shiftdir left) with autopull at 16
bits; `put(word, 16)` puts it in the top half of the OSR and the port does the shift in
C (`word << 16` would be a heap int on the rp2 for words >= 0x4000). Between frames the
SM stalls on `out` with side-set 0: the line idles low. No auto-repeat: if Python stops
sending, the ESC sees no frames and disarms (its own failsafe).
MicroPython-only (rp2).
"""

import rp2

from hoverfly.protocols.dshot import PIO_CYCLES_PER_BIT


@rp2.asm_pio(sideset_init=rp2.PIO.OUT_LOW, out_shiftdir=rp2.PIO.SHIFT_LEFT, autopull=True, pull_thresh=16)
def dshot_program():
    wrap_target()  # noqa: F821 - names injected by rp2.asm_pio
    label("bit")  # noqa: F821
    out(x, 1).side(0)  # noqa: F821 - 1 cycle low (a 1's tail, or the idle stall)
    jmp(not_x, "zero").side(1)[2]  # noqa: F821 - 3 cycles high
    nop().side(1)[2]  # noqa: F821 - a 1: 3 more high (6)
    jmp("bit").side(0)  # noqa: F821 - 1 low, + the next out's 1 = 2 low
    label("zero")  # noqa: F821
    nop().side(0)[3]  # noqa: F821 - a 0: 4 low, + the next out's 1 = 5 low
    wrap()  # noqa: F821


class DshotPio:
    """Motor lines as PIO state machines (state machines 0.. in order of `pins`).

    `put(words, count)` sends words[line] on line `line`. `replies` (21-bit GCR line codes per
    line) and `fresh` are the bidirectional side's slots for board.read_motor_telemetry; this
    transmit-only program never fills them (the board refuses dshot_bidir)."""

    def __init__(self, pins, speed_kbit, first_sm=0):
        from array import array

        from machine import Pin

        self.speed_kbit = speed_kbit
        self.replies = array("i", [0] * len(pins))
        self.fresh = False
        freq = speed_kbit * 1000 * PIO_CYCLES_PER_BIT
        self.sms = []
        for i in range(len(pins)):
            sm = rp2.StateMachine(first_sm + i, dshot_program, freq=freq, sideset_base=Pin(pins[i]))
            sm.active(1)
            self.sms.append(sm)
        self.puts = 0

    def put(self, words, count):
        """One frame per line: words[i] to state machine i."""
        sms = self.sms
        n = count if count < len(sms) else len(sms)
        for i in range(n):
            sms[i].put(words[i], 16)
        self.puts += 1

    def stop(self):
        """Stop every state machine (a protocol change rebuilds them); the pins idle low."""
        for sm in self.sms:
            sm.active(0)
