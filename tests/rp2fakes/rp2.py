"""Fake `rp2` module for off-hardware runs (tests only; MicroPython and CPython).

`asm_pio(**kw)` assembles the decorated program the way the port does — it runs the
function with the PIO instruction names injected into its globals — and records each
instruction as (op, args, side, delay) plus labels and wrap points, so a test can read
the program back and even clock it (`run_bits`). `StateMachine(id, prog, freq=...,
sideset_base=...)` keeps its TX FIFO as a list: `put(value, shift)` appends
`value << shift` (the port shifts in C) and `take()` hands the words to the test.

Programs that pull and push by hand (the bidirectional DShot program) also run: each
`put` clocks the program, cycle by cycle, from where it stalled until it stalls again on
an empty TX FIFO, against a line model attached to its pin with `attach_line(pin_id,
line)`. While the state machine drives the pin the line is its output; once it lets go
(`set(pindirs, 0)`) the line model gets what was driven, `line.receive(pulses, freq_hz)`
with pulses as [level, cycles] runs from the run's start, and the pin reads
`line.level(t_cycles)` (same time base) — an ESC answering, say. Without a line model a
released pin reads its pull: 1 with Pin.PULL_UP, else 0 (floating, read as low). Words
the program pushes land in the RX FIFO (4 deep: `rx_fifo()`, `get()`); `push(noblock)` on a
full FIFO drops them (`rx_dropped`). A `wait` that never ends, or a run that never stalls,
hangs the state machine (`stalled`); a `put` onto 4 queued words then raises, as the real
put would block forever. Re-driving the pin while the line model holds it low counts in
`contention`.
"""

_lines = {}


def attach_line(pin_id, line):
    """A line model on pin `pin_id`: `receive(pulses, freq_hz)` and `level(t_cycles)`."""
    _lines[pin_id] = line


def reset():
    """Forget every line model and removed program (between test runs)."""
    _lines.clear()
    del PIO.removed[:]



class PIO:
    removed = []  # programs handed to remove_program, newest last

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

    def remove_program(self, prog=None):
        PIO.removed.append(prog)


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


_MASK32 = 0xFFFFFFFF
_FIFO_DEPTH = 4
_MAX_STEPS = 200000  # instructions per run before the state machine counts as hung


class StateMachine:
    def __init__(self, sm_id, prog=None, freq=-1, sideset_base=None, out_base=None, set_base=None,
                 in_base=None, jmp_pin=None):
        self.id = sm_id
        self.running = False
        self.fifo = []  # every word put, for the test (take())
        self.puts = 0
        self.rx = []
        self.rx_dropped = 0
        self.runs = 0
        self.stalled = False
        self.contention = 0
        self.pulses = []  # the last run's line while driven: [level, cycles] runs from the run's start
        self.init(prog, freq, sideset_base, set_base=set_base, in_base=in_base, jmp_pin=jmp_pin)

    def init(self, prog, freq=-1, sideset_base=None, out_base=None, set_base=None, in_base=None, jmp_pin=None,
             **kw):
        self.prog = prog
        self.freq = freq
        self.sideset_base = sideset_base
        self.set_base = set_base
        self.in_base = in_base
        self.jmp_pin = jmp_pin
        self._tx = []
        self.rx = []
        self.stalled = False
        self._pc = prog.wrap_target if prog is not None else 0
        self._x = 0
        self._y = 0
        self._osr = 0
        self._osr_used = 32
        self._isr = 0
        kw0 = prog.kw if prog is not None else {}
        self._level = kw0.get("sideset_init", kw0.get("set_init", 0)) & 1
        self._drive = 1 if ("sideset_init" in kw0 or "set_init" in kw0) else 0
        # Programs that pull by hand are clocked on each put; autopull ones only queue words.
        self._clocked = prog is not None and any(rec[0] == "pull" for rec in prog.instr)

    def active(self, v=None):
        if v is None:
            return self.running
        self.running = bool(v)

    def put(self, value, shift=0):
        self.puts += 1
        word = (value << shift) & _MASK32
        self.fifo.append(word)
        if len(self.fifo) > 64:
            del self.fifo[0]
        if not self._clocked:
            return
        if self.stalled and len(self._tx) >= _FIFO_DEPTH:
            raise RuntimeError("state machine %d hung: put blocks on a full TX FIFO" % self.id)
        self._tx.append(word)
        if self.running and not self.stalled:
            self._run()

    def take(self):
        out = self.fifo
        self.fifo = []
        return out

    def tx_fifo(self):
        return len(self._tx) if self._clocked else len(self.fifo)

    def rx_fifo(self):
        return len(self.rx)

    def get(self, buf=None, shift=0):
        if not self.rx:
            raise RuntimeError("get() on an empty RX FIFO blocks forever")
        return self.rx.pop(0) >> shift

    # ------------------------------------------------------------ the clocked program
    def _pin_id(self):
        for p in (self.sideset_base, self.set_base, self.in_base, self.jmp_pin):
            if p is not None:
                return getattr(p, "id", p)
        return -1

    def _run(self):
        """Clock the program from its stall point until it stalls on `pull` with an empty TX FIFO."""
        self.runs += 1
        prog = self.prog
        ins = prog.instr
        labels = prog.labels
        wrap_at = prog.wrap
        wrap_target = prog.wrap_target
        pin = self.in_base if self.in_base is not None else self.jmp_pin
        line = _lines.get(self._pin_id())
        line_level = line.level if line is not None else None
        pull = getattr(pin, "pull", -1) if pin is not None else -1
        float_level = 1 if pull == 1 else 0  # machine.Pin.PULL_UP
        pc = self._pc
        x = self._x
        y = self._y
        osr = self._osr
        osr_used = self._osr_used
        isr = self._isr
        level = self._level
        drive = self._drive
        t = 0
        pulses = []
        steps = 0
        while True:
            steps += 1
            if steps > _MAX_STEPS:
                self.stalled = True
                break
            op, args, side, delay = ins[pc]
            if side is not None:
                level = side & 1
            nxt = pc + 1
            if pc == wrap_at:
                nxt = wrap_target
            if op == "jmp":
                if len(args) == 1:
                    nxt = labels[args[0]]
                else:
                    cond = args[0]
                    if cond == "y_dec":
                        take = y != 0
                        y = (y - 1) & _MASK32
                    elif cond == "pin":
                        take = (level if drive else (line_level(t) if line is not None else float_level)) == 1
                    elif cond == "not_x":
                        take = x == 0
                    elif cond == "not_y":
                        take = y == 0
                    elif cond == "x_dec":
                        take = x != 0
                        x = (x - 1) & _MASK32
                    elif cond == "x_not_y":
                        take = x != y
                    elif cond == "not_osre":
                        take = osr_used < 32
                    else:
                        raise NotImplementedError("jmp %s" % cond)
                    if take:
                        nxt = labels[args[1]]
            elif op == "pull":
                if self._tx:
                    osr = self._tx.pop(0)
                    osr_used = 0
                elif args and args[0] == "noblock":
                    osr = x
                    osr_used = 0
                else:
                    break  # stalls here until the next put
            elif op == "out":
                dest, n = args
                v = osr >> (32 - n)
                osr = (osr << n) & _MASK32
                osr_used += n
                if dest == "x":
                    x = v
                elif dest == "y":
                    y = v
                elif dest != "null":
                    raise NotImplementedError("out to %s" % dest)
            elif op == "set":
                dest, v = args
                if dest == "x":
                    x = v
                elif dest == "y":
                    y = v
                elif dest == "pins":
                    level = v & 1
                elif dest == "pindirs":
                    if v & 1 and not drive and line is not None and line.level(t) == 0:
                        self.contention += 1
                    if drive and not v & 1:
                        if line is not None:
                            line.receive(pulses, self.freq)
                    drive = v & 1
                else:
                    raise NotImplementedError("set %s" % dest)
            elif op == "in_":
                src, n = args
                if src == "pins":
                    v = level if drive else (line_level(t) if line is not None else float_level)
                elif src == "x":
                    v = x
                elif src == "y":
                    v = y
                else:
                    v = 0
                isr = ((isr << n) | (v & ((1 << n) - 1))) & _MASK32
            elif op == "push":
                if len(self.rx) < _FIFO_DEPTH:
                    self.rx.append(isr)
                elif args and args[0] == "noblock":
                    self.rx_dropped += 1
                else:
                    self.stalled = True  # push(block) on a full FIFO: waits for Python, which never reads here
                    break
                isr = 0
            elif op == "wait":
                polarity = args[0]
                waited = 0
                while (level if drive else (line.level(t) if line is not None else float_level)) != polarity:
                    t += 1
                    waited += 1
                    if waited > _MAX_STEPS:
                        break
                if waited > _MAX_STEPS:
                    self.stalled = True
                    break
            elif op != "nop":
                raise NotImplementedError(op)
            cycles = 1 + delay
            if drive:
                if pulses and pulses[-1][0] == level:
                    pulses[-1][1] += cycles
                else:
                    pulses.append([level, cycles])
            t += cycles
            pc = nxt
        self._pc = pc
        self._x = x
        self._y = y
        self._osr = osr
        self._osr_used = osr_used
        self._isr = isr
        self._level = level
        self._drive = drive
        self.pulses = pulses
