"""Fake `rp2` module for off-hardware runs (tests only; MicroPython and CPython).

`asm_pio(**kw)` assembles the decorated program the way the port does — it runs the
function with the PIO instruction names injected into its globals — and records each
instruction as (op, args, side, delay) plus labels and wrap points, so a test can read
the program back and even clock it (`run_bits`). `StateMachine(id, prog, freq=...,
sideset_base=...)` keeps its TX FIFO as a list: `put(value, shift)` appends
`value << shift` (the port shifts in C) and `take()` hands the words to the test.
"""


class PIO:
    OUT_LOW = 0
    OUT_HIGH = 1
    IN_LOW = 0
    IN_HIGH = 1
    SHIFT_LEFT = 0
    SHIFT_RIGHT = 1
    JOIN_NONE = 0
    JOIN_TX = 1
    JOIN_RX = 2

    def __init__(self, n):
        self.id = n


class Program:
    def __init__(self, kw):
        self.kw = kw
        self.instr = []  # [op, args, side, delay]
        self.labels = {}
        self.wrap_target = 0
        self.wrap = -1

    def __len__(self):
        return len(self.instr)


class _Instr:
    def __init__(self, prog, op, args):
        self.rec = [op, args, None, 0]
        prog.instr.append(self.rec)

    def side(self, v):
        self.rec[2] = v
        return self

    def __getitem__(self, delay):
        self.rec[3] = delay
        return self


def asm_pio(**kw):
    def dec(fn):
        prog = Program(kw)

        def op(name):
            return lambda *args: _Instr(prog, name, args)

        def label(name):
            prog.labels[name] = len(prog.instr)

        def wrap_target():
            prog.wrap_target = len(prog.instr)

        def wrap():
            prog.wrap = len(prog.instr) - 1

        names = {"label": label, "wrap_target": wrap_target, "wrap": wrap}
        for name in ("out", "jmp", "nop", "set", "mov", "in_", "push", "pull", "wait", "irq"):
            names[name] = op(name)
        for name in ("x", "y", "not_x", "not_y", "x_dec", "y_dec", "pins", "pindirs", "null", "isr", "osr",
                     "block", "noblock", "x_not_y", "pin", "not_osre"):
            names[name] = name
        g = fn.__globals__
        saved = {}
        for k in names:
            if k in g:
                saved[k] = g[k]
            g[k] = names[k]
        try:
            fn()
        finally:
            for k in names:
                if k in saved:
                    g[k] = saved[k]
                else:
                    del g[k]
        if prog.wrap < 0:
            prog.wrap = len(prog.instr) - 1
        return prog

    return dec


def run_bits(prog, word, bits=16):
    """Clock a side-set-only serial program over the top `bits` of a 32-bit OSR word.

    Supports the instructions a DShot program needs (out x 1, jmp label / not_x, nop) and
    returns the line level per SM cycle, starting at the first `out`.
    """
    levels = []
    osr = word
    left = bits
    x = 0
    pc = prog.wrap_target
    guard = 0
    while guard < 64 * bits:
        guard += 1
        op, args, side, delay = prog.instr[pc]
        if op == "out" and left == 0:
            break  # autopull stall: the FIFO is empty
        level = side if side is not None else (levels[-1] if levels else 0)
        nxt = pc + 1
        if op == "out":
            x = (osr >> 31) & 1
            osr = (osr << 1) & 0xFFFFFFFF
            left -= 1
        elif op == "jmp":
            if len(args) == 1:
                nxt = prog.labels[args[0]]
            elif args[0] == "not_x" and x == 0:
                nxt = prog.labels[args[1]]
        for _ in range(1 + delay):
            levels.append(level)
        if pc == prog.wrap:
            nxt = prog.wrap_target
        pc = nxt
    return levels


class StateMachine:
    def __init__(self, sm_id, prog=None, freq=-1, sideset_base=None, out_base=None, set_base=None,
                 in_base=None, jmp_pin=None):
        self.id = sm_id
        self.prog = prog
        self.freq = freq
        self.sideset_base = sideset_base
        self.running = False
        self.fifo = []
        self.puts = 0

    def init(self, prog, freq=-1, sideset_base=None, **kw):
        self.prog = prog
        self.freq = freq
        self.sideset_base = sideset_base

    def active(self, v=None):
        if v is None:
            return self.running
        self.running = bool(v)

    def put(self, value, shift=0):
        self.puts += 1
        self.fifo.append((value << shift) & 0xFFFFFFFF)
        if len(self.fifo) > 64:
            del self.fifo[0]

    def take(self):
        out = self.fifo
        self.fifo = []
        return out

    def tx_fifo(self):
        return len(self.fifo)
