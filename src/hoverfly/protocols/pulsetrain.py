"""Line-level model of the ESC outputs: frames and widths in, (level, duration_ns) pulse lists out, and back.

A test and simulation model, not a hot-path codec: it allocates lists. It renders what the
pin does for a DShot frame (normal: idle low, each bit a high pulse; bidirectional: idle
high, each bit a low pulse), for a bidirectional reply (21 GCR line levels at 5/4 of the
bit rate) and for one analog period, and decodes such lists back with a timing tolerance,
as an ESC does: a pulse too far from T0H/T1H, a bit period off, or a width outside the
protocol's range gives None and is counted in `rejected`. The encoders in dshot.py and
analog.py are checked end to end through it; the simulated ESC can read frames with it.
Timings: reference/protocols.md §4.1, §4.3, §5.
"""

from hoverfly.protocols.analog import pulse_range_us
from hoverfly.protocols.dshot import code_to_levels, dshot_timing, gcr_encode, levels_to_code

# (t0h, t1h, per) of a bit: nominal / PIO 8-cycle (3/8, 6/8) and what other senders use
# (reference/protocols.md §8.7); an ESC accepts them all.
DUTY_NOMINAL = (3, 6, 8)
DUTY_BETAFLIGHT_DMA = (35, 70, 100)
DUTY_BITBANG = (1, 2, 3)
DUTY_BETAFLIGHT_PIO = (13, 27, 40)


def _edge_ns(i, num, den, speed_kbit):
    # ns from the frame start to i + num/den bits, rounded; bit = 1e6 / speed_kbit ns
    return (1000000 * (i * den + num) * 2 + speed_kbit * den) // (2 * speed_kbit * den)


def render_dshot(frame, speed_kbit, bidir=False, duty=DUTY_NOMINAL, trailing_idle_bits=0):
    """16-bit frame -> [(level, duration_ns), ...], MSB first; bidirectional inverts the levels."""
    active = 0 if bidir else 1
    idle = 1 - active
    t0, t1, per = duty
    out = []
    for i in range(16):
        bit = (frame >> (15 - i)) & 1
        start = _edge_ns(i, 0, per, speed_kbit)
        mid = _edge_ns(i, t1 if bit else t0, per, speed_kbit)
        end = _edge_ns(i + 1, 0, per, speed_kbit)
        out.append((active, mid - start))
        out.append((idle, end - mid))
    if trailing_idle_bits:
        level, d = out[-1]
        out[-1] = (level, d + _edge_ns(trailing_idle_bits, 0, 1, speed_kbit))
    return out


def _merge(pulses):
    merged = []
    for level, d in pulses:
        if d <= 0:
            continue
        if merged and merged[-1][0] == level:
            merged[-1] = (level, merged[-1][1] + d)
        else:
            merged.append((level, d))
    return merged


class DshotPulseDecoder:
    """What an ESC does with the line: pulse list -> 16-bit word, or None (counted in `rejected`).

    tolerance_pct: how far (percent of a bit period) a high time may sit from T0H/T1H and a
    bit period from nominal. The default 12 % accepts every sender in the DUTY_* table and
    keeps the two classes apart (T0H 37.5 % and T1H 75 % are 37.5 % apart).
    """

    def __init__(self, speed_kbit, bidir=False, tolerance_pct=12):
        bit_ns, t0h_ns, t1h_ns = dshot_timing(speed_kbit)[:3]
        self.speed_kbit = speed_kbit
        self.bidir = bidir
        self.bit_ns = bit_ns
        self.t0h_ns = t0h_ns
        self.t1h_ns = t1h_ns
        self.tol_ns = bit_ns * tolerance_pct // 100
        self.frames = 0
        self.rejected = 0
        self.last_error = ""

    def _reject(self, why):
        self.rejected += 1
        self.last_error = why
        return None

    def decode(self, pulses):
        active = 0 if self.bidir else 1
        p = _merge(pulses)
        i = 0
        while i < len(p) and p[i][0] != active:  # leading idle
            i += 1
        word = 0
        tol = self.tol_ns
        for bit in range(16):
            if i >= len(p):
                return self._reject("frame ends after %d bits" % bit)
            high = p[i][1]
            if abs(high - self.t0h_ns) <= tol:
                b = 0
            elif abs(high - self.t1h_ns) <= tol:
                b = 1
            else:
                return self._reject("bit %d: %d ns is neither T0H nor T1H" % (bit, high))
            low = p[i + 1][1] if i + 1 < len(p) else None
            if bit < 15:
                if low is None or abs(high + low - self.bit_ns) > tol:
                    return self._reject("bit %d: period off" % bit)
            elif low is not None and high + low < self.bit_ns - tol:
                return self._reject("bit 15: period short")
            word = (word << 1) | b
            i += 2
        if i < len(p):
            return self._reject("pulses after the 16th bit")
        self.frames += 1
        return word


def render_reply(word, speed_kbit):
    """Bidirectional reply word -> the ESC's line: 21 GCR levels at 5/4 of the DShot rate, idle high after."""
    reply_bit_ns = dshot_timing(speed_kbit)[5]
    levels = code_to_levels(gcr_encode(word))
    out = []
    for i in range(20, -1, -1):
        out.append(((levels >> i) & 1, reply_bit_ns))
    out.append((1, reply_bit_ns))
    return _merge(out)


class ReplyPulseDecoder:
    """Reply line (starting at the falling start edge) -> 21-bit line code by sampling each bit's centre,
    as Betaflight's edge decoder does; None (counted) when the line is not 21 bits long."""

    def __init__(self, speed_kbit):
        self.bit_ns = dshot_timing(speed_kbit)[5]
        self.rejected = 0

    def decode_code(self, pulses):
        p = _merge(pulses)
        while p and p[0][0] == 1:
            p = p[1:]
        levels = 0
        n = 0
        half = self.bit_ns // 2
        t = 0
        for level, d in p:
            # samples whose centre falls in [t, t + d)
            while n < 21 and n * self.bit_ns + half < t + d:
                levels = (levels << 1) | level
                n += 1
            t += d
        if n < 21:
            self.rejected += 1
            return None
        return levels_to_code(levels)


def render_analog(width_ns, period_ns):
    """One period of an analog output: high for the width, low for the rest."""
    if width_ns > period_ns:
        width_ns = period_ns
    out = [(1, width_ns)]
    if period_ns > width_ns:
        out.append((0, period_ns - width_ns))
    return out


class AnalogPulseDecoder:
    """One period -> pulse width in ns, or None (counted) when the width is outside the protocol's
    range by more than tolerance_us or the list is not one high pulse then low."""

    def __init__(self, protocol, tolerance_us=0.5):
        lo_us, hi_us = pulse_range_us(protocol)
        self.min_ns = int((lo_us - tolerance_us) * 1000)
        self.max_ns = int((hi_us + tolerance_us) * 1000 + 0.5)
        self.frames = 0
        self.rejected = 0

    def decode(self, pulses):
        p = _merge(pulses)
        while p and p[0][0] == 0:
            p = p[1:]
        if not p or len(p) > 2:
            self.rejected += 1
            return None
        w = p[0][1]
        if w < self.min_ns or w > self.max_ns:
            self.rejected += 1
            return None
        self.frames += 1
        return w
