"""DShot through PIO state machines: one SM per motor; transmit-only, or bidirectional with eRPM replies.

Takes 16-bit DShot words (protocols/dshot.py builds them; inverted CRC for bidirectional)
and drives the motor pins; with `bidir` it also gives each line's reply as a 21-bit GCR
line code (`replies`, `fresh`) for board.read_motor_telemetry, where the core's
OutputStage decodes it into eRPM / RPM. MicroPython-only (rp2).

Transmit-only (`dshot_program`): each bit is 8 SM cycles (reference/micropython.md §3.1):
high 6 cycles for a 1 (75 %), 3 cycles for a 0 (37.5 %), low for the rest, so the SM clock
is 8 × the bit rate (DShot600: 4.8 MHz). The word goes MSB first (out_shiftdir left) with
autopull at 16 bits; `put(word, 16)` puts it in the top half of the OSR and the port does
the shift in C (`word << 16` would be a heap int on the rp2 for words >= 0x4000). Between
frames the SM stalls on `out` with side-set 0: the line idles low.

Bidirectional (`bidir_program`, reference/protocols.md §4.1, §4.3): the line is inverted
(idle high, each bit a low pulse), and after the frame the SM lets go of the pin (the pad's
pull-up holds it high), waits for the ESC's reply — ~30 µs after the frame, 21 GCR bits at
5/4 of the bit rate, starting with a falling edge — samples each reply bit once in its
centre, pushes the 21 levels to the RX FIFO and drives the line high again. The SM clock is
20 × the bit rate (DShot600: 12 MHz) so that both bit times are whole cycles: a command bit
is 20 cycles, a reply bit 16 (20 × 4/5). If no falling edge comes within REPLY_WAIT_US the
SM goes back to waiting for the next word: an ESC that does not answer never stalls the
frames. `poll()` (board.read_motor_telemetry, and every `put`) drains the RX FIFOs without
blocking into `replies[line]` (the line code, levels_to_code of the samples) and counts a
frame whose reply never came (`missed`; its code becomes 0, which no decoder accepts).
The replies read in `poll` answer the frames before the newest `put` (the reply to the
newest one is still ~60 µs away). One sample per bit, timed from the start edge, reads an
ESC whose reply clock is within about ±2 % of nominal (bit 20's sample may drift 7 of 16
cycles); Betaflight's edge-timestamp decoder tolerates more.

No auto-repeat in either program: if Python stops sending, the ESC sees no frames and
disarms (its own failsafe).
"""

from array import array

import rp2

from hoverfly.protocols.dshot import PIO_CYCLES_PER_BIT, levels_to_code


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


# Bidirectional timing, in SM cycles (the program below spells them out as delays).
BIDIR_CYCLES_PER_BIT = 20  # SM clock = 20 × bit rate: command bit 20 cycles, reply bit 16 (5/4 the rate)
BIDIR_LOW_1 = 15  # a 1: low 15/20 = 75 %, the nominal T1H (protocols.md §4.1)
BIDIR_LOW_0 = 7  # a 0: low 7/20 = 35 %, Betaflight's DMA T0H (nominal 37.5 % is 7.5 cycles)
REPLY_CYCLES_PER_BIT = 16  # 20 × 4/5
REPLY_BITS = 21
# The ESC answers ~30 µs after the frame (Betaflight allows 30 µs + 5 µs turnaround, §4.3):
# wait up to 80 µs for the reply's first falling edge, then give up and take the next frame.
REPLY_WAIT_US = 80
WAIT_LOOP_CYCLES = 66  # one outer pass of the wait: set y (1) + 32 × (jmp pin + jmp y--) + jmp x-- (1)


def reply_wait_loops(speed_kbit):
    """Outer passes of the reply wait (the program's `set x` + 1) for REPLY_WAIT_US at this speed, 1..32."""
    cycles = REPLY_WAIT_US * speed_kbit * BIDIR_CYCLES_PER_BIT // 1000
    loops = (cycles + WAIT_LOOP_CYCLES - 1) // WAIT_LOOP_CYCLES
    if loops < 1:
        return 1
    if loops > 32:
        return 32  # `set` takes 0..31
    return loops


def bidir_program(wait_loops):
    """The bidirectional DShot program with a reply wait of `wait_loops` × WAIT_LOOP_CYCLES cycles.

    Pins: side-set, set, in and jmp pin are all the motor pin. 21 instructions (a PIO block
    has 32; the transmit-only program's 4 fit beside it). Side-set is 1 on every instruction
    outside the frame's low pulses: while the pin is an input it sets the output latch only,
    so the line is high the moment the SM drives it again.
    """
    last = wait_loops - 1

    @rp2.asm_pio(sideset_init=rp2.PIO.OUT_HIGH, set_init=rp2.PIO.OUT_HIGH, out_shiftdir=rp2.PIO.SHIFT_LEFT,
                 in_shiftdir=rp2.PIO.SHIFT_LEFT, autopull=False, autopush=False)
    def dshot_bidir_program():
        wrap_target()  # noqa: F821 - names injected by rp2.asm_pio
        label("frame")  # noqa: F821
        set(pindirs, 1).side(1)  # noqa: F821 - drive the line again: high, the idle level
        pull(block).side(1)  # noqa: F821 - idle high until the next word
        set(y, 15).side(1)  # noqa: F821 - 16 bits
        label("bit")  # noqa: F821
        out(x, 1).side(0)  # noqa: F821 - the falling edge opens every bit: 1 low
        jmp(not_x, "zero").side(0)[5]  # noqa: F821 - 6 more low (7 = BIDIR_LOW_0)
        nop().side(0)[7]  # noqa: F821 - a 1: 8 more low (15 = BIDIR_LOW_1)
        jmp(y_dec, "bit").side(1)[4]  # noqa: F821 - a 1: 5 high (20)
        jmp("reply").side(1)  # noqa: F821
        label("zero")  # noqa: F821
        jmp(y_dec, "bit").side(1)[12]  # noqa: F821 - a 0: 13 high (20)
        label("reply")  # noqa: F821
        set(pindirs, 0).side(1)  # noqa: F821 - let go: the pull-up holds the line high, the ESC takes it
        set(x, last).side(1)  # noqa: F821
        label("wait")  # noqa: F821
        set(y, 31).side(1)  # noqa: F821
        label("poll")  # noqa: F821 - the line is read every 2 cycles (1/8 of a reply bit)
        jmp(pin, "high").side(1)  # noqa: F821
        jmp("edge").side(1)  # noqa: F821
        label("high")  # noqa: F821
        jmp(y_dec, "poll").side(1)  # noqa: F821
        jmp(x_dec, "wait").side(1)  # noqa: F821
        jmp("frame").side(1)  # noqa: F821 - no reply: back to the frames
        label("edge")  # noqa: F821
        # The edge fell 0..2 cycles before the read that saw it low (1 on average); that read,
        # the jmp and these 5 cycles put the first sample 7..9 cycles after it: the centre of
        # a 16-cycle bit. (The GPIO input synchroniser adds 2 system clocks: < 1 SM cycle.)
        set(y, 20).side(1)[4]  # noqa: F821
        label("sample")  # noqa: F821
        in_(pins, 1).side(1)[14]  # noqa: F821 - one sample per reply bit: 15 + the jmp's 1 = 16
        jmp(y_dec, "sample").side(1)  # noqa: F821
        # The last sample sits in bit 20's centre: 8 cycles of it remain. Wait a reply bit before
        # driving the line again, so the SM never fights the ESC's last level. noblock: with the
        # RX FIFO full (Python not reading), the reply is dropped, never the next frame.
        push(noblock).side(1)[15]  # noqa: F821
        wrap()  # noqa: F821

    return dshot_bidir_program


class DshotPio:
    """Motor lines as PIO state machines (state machines first_sm.. in order of `pins`).

    `put(words, count)` sends words[line] on line `line`. With `bidir`, `replies[line]` holds
    the newest 21-bit GCR line code from that line's ESC and `fresh` says new ones came since
    the board last read them; `poll()` updates both. Counters: `puts`, `received` (replies
    read), `missed` (frames whose reply never came), `missed_line[line]`."""

    def __init__(self, pins, speed_kbit, first_sm=0, bidir=False):
        from machine import Pin

        n = len(pins)
        self.speed_kbit = speed_kbit
        self.bidir = bool(bidir)
        self.replies = array("i", [0] * n)
        self.fresh = False
        self.received = 0
        self.missed = 0
        self.missed_line = array("i", [0] * n)
        self._sent = bytearray(n)  # a frame went out on the line and its reply is still owed
        self._pio = first_sm // 4
        self.sms = []
        self.puts = 0
        if self.bidir:
            self.program = bidir_program(reply_wait_loops(speed_kbit))
            freq = speed_kbit * 1000 * BIDIR_CYCLES_PER_BIT
            for i in range(n):
                # The pull-up holds the line high (idle) while neither side drives it.
                pin = Pin(pins[i], Pin.IN, Pin.PULL_UP)
                sm = rp2.StateMachine(first_sm + i, self.program, freq=freq, sideset_base=pin, set_base=pin,
                                      in_base=pin, jmp_pin=pin)
                sm.active(1)
                self.sms.append(sm)
        else:
            self.program = dshot_program
            freq = speed_kbit * 1000 * PIO_CYCLES_PER_BIT
            for i in range(n):
                sm = rp2.StateMachine(first_sm + i, dshot_program, freq=freq, sideset_base=Pin(pins[i]))
                sm.active(1)
                self.sms.append(sm)

    def put(self, words, count):
        """One frame per line: words[i] to state machine i. Bidirectional: first the replies to
        the last frames (poll), and a line whose reply never came gets code 0, counted."""
        sms = self.sms
        n = count if count < len(sms) else len(sms)
        if self.bidir:
            self.poll()
            sent = self._sent
            replies = self.replies
            for i in range(n):
                if sent[i]:
                    replies[i] = 0
                    self.missed += 1
                    self.missed_line[i] += 1
                sent[i] = 1
        for i in range(n):
            sms[i].put(words[i], 16)
        self.puts += 1

    def poll(self):
        """Drain every RX FIFO without blocking (the newest reply per line wins); returns `fresh`.

        Allocates nothing: `rx_fifo()` and `get()` give small ints (21 bits)."""
        if not self.bidir:
            return self.fresh
        sms = self.sms
        replies = self.replies
        sent = self._sent
        for i in range(len(sms)):
            sm = sms[i]
            k = sm.rx_fifo()
            if k:
                levels = 0
                while k > 0:
                    levels = sm.get()
                    k -= 1
                    self.received += 1
                replies[i] = levels_to_code(levels)
                sent[i] = 0
                self.fresh = True
        return self.fresh

    def stop(self):
        """Stop every state machine (a protocol change rebuilds them) and free the bidirectional
        program's PIO memory. The lines idle low (transmit-only) or high (bidirectional: pull-up)."""
        for sm in self.sms:
            sm.active(0)
        if self.bidir:
            remove = getattr(rp2.PIO(self._pio), "remove_program", None)
            if remove is not None:
                remove(self.program)
