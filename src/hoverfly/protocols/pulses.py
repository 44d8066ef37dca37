"""PWM and PPM receiver decoding from edge timestamps, and edge generators for the simulator.

Takes pin edges as (level, time) pairs: the board captures them (rp2: a hard `Pin.irq` on
both edges storing `ticks_us()`, or a PIO pulse counter; reference/micropython.md §3.4)
and calls `edge(...)`, which allocates nothing and may run inside the interrupt. Times are
`compat` ticks in µs, compared only with `ticks_diff`, so they work across the 2**30 wrap.
Gives `channels_us` (array('H') of 16), `frames` and `errors` like the serial decoders;
it sits at the start of the receiver task, in place of a serial codec.

`PwmCapture(channels)`: one pin per channel (e.g. the FlySky FS-IA6's outputs, seed 001).
Width = falling minus rising edge of the same channel. Widths outside 800..2200 µs are
refused and counted in `errors`. A good width is written to `channels_us` at once; a
frame counts (`frames`, `edge` returns 1) when EVERY captured channel has a fresh width
since the last frame, so one dead or unplugged channel stops frames and the link-loss
watch trips instead of flying on a stale value. Channels past `channels` read 1500 µs.

`PpmCapture()`: the PPM sum signal on one pin, rising edges only (an inverted PPM signal:
pass its falling edges as level 1). Channel width = time between consecutive rising edges.
A gap longer than 2700 µs (`SYNC_MIN_US`, Betaflight's minimum PPM sync) is the sync; the
channels collected since the previous sync form a frame, complete at this sync. Errors
(each counted once in `errors`; the frame is then dropped whole): an interval outside
800..2200 µs (including 2200..2700), more than 16 channels, fewer than `min_channels`
(default 4). Channels past the frame's `channel_count` read 1500 µs.

`pwm_edges` / `ppm_edges` build the edge lists a receiver would produce (simulator, tests);
they allocate, they are not for the hot path.
"""

from array import array

from hoverfly.compat import const, ticks_add, ticks_diff
from hoverfly.protocols.rxcodec import CENTRE_US, CHANNELS, MAX_PULSE_US, MIN_PULSE_US, new_channels

SYNC_MIN_US = const(2700)


class PwmCapture:
    """Parallel PWM: one input per channel, `edge(channel_index, level, t_us)` per edge."""

    def __init__(self, channels=8):
        if channels < 1:
            channels = 1
        if channels > CHANNELS:
            channels = CHANNELS
        self.channel_count = channels
        self.channels_us = new_channels()
        for c in range(channels, CHANNELS):
            self.channels_us[c] = CENTRE_US
        self.frames = 0
        self.errors = 0
        self.edges = 0
        self.last_frame_us = 0
        self._rise_us = [0] * channels
        self._high = bytearray(channels)
        self._fresh = 0  # bit c set: channel c has a new width since the last frame
        self._all = (1 << channels) - 1

    def edge(self, channel_index, level, t_us):
        """One edge; returns 1 when it completed a frame, else 0. Never raises on bad input."""
        self.edges += 1
        if channel_index < 0 or channel_index >= self.channel_count:
            self.errors += 1
            return 0
        if level:
            self._rise_us[channel_index] = t_us
            self._high[channel_index] = 1
            return 0
        if not self._high[channel_index]:
            return 0  # falling edge with no rising edge seen (capture started mid-pulse)
        self._high[channel_index] = 0
        width_us = ticks_diff(t_us, self._rise_us[channel_index])
        if width_us < MIN_PULSE_US or width_us > MAX_PULSE_US:
            self.errors += 1
            return 0
        self.channels_us[channel_index] = width_us
        fresh = self._fresh | (1 << channel_index)
        if fresh == self._all:
            self._fresh = 0
            self.frames += 1
            self.last_frame_us = t_us
            return 1
        self._fresh = fresh
        return 0


class PpmCapture:
    """PPM sum signal: `edge(level, t_us)` per edge (only rising edges count)."""

    def __init__(self, min_channels=4):
        self.min_channels = min_channels
        self.channels_us = new_channels()
        self.channel_count = 0
        self.frames = 0
        self.errors = 0
        self.edges = 0
        self.last_frame_us = 0
        self._pending = array("H", [0] * CHANNELS)
        self._count = 0
        self._synced = False  # a sync gap has been seen: intervals are channels
        self._bad = False  # this frame already had an error
        self._have_last = False
        self._last_us = 0

    def edge(self, level, t_us):
        """One edge; returns 1 when a sync gap completed a good frame, else 0."""
        self.edges += 1
        if not level:
            return 0
        if not self._have_last:
            self._have_last = True
            self._last_us = t_us
            return 0
        interval_us = ticks_diff(t_us, self._last_us)
        self._last_us = t_us
        if interval_us > SYNC_MIN_US:
            done = 0
            if self._synced and not self._bad:
                n = self._count
                if n < self.min_channels:
                    self.errors += 1
                else:
                    us = self.channels_us
                    p = self._pending
                    for c in range(CHANNELS):
                        us[c] = p[c] if c < n else CENTRE_US
                    self.channel_count = n
                    self.frames += 1
                    self.last_frame_us = t_us
                    done = 1
            self._synced = True
            self._count = 0
            self._bad = False
            return done
        if not self._synced or self._bad:
            return 0
        if interval_us < MIN_PULSE_US or interval_us > MAX_PULSE_US or self._count >= CHANNELS:
            self.errors += 1
            self._bad = True
            return 0
        self._pending[self._count] = interval_us
        self._count += 1
        return 0


def pwm_edges(channels_us, t0_us):
    """Edges of one PWM frame as [(channel_index, level, t_us), ...] in time order.

    Channels pulse one after the other (as most PWM receivers do): channel c rises when
    channel c-1 falls, the first at t0_us.
    """
    events = []
    t = t0_us
    for c in range(len(channels_us)):
        w = int(channels_us[c])
        events.append((c, 1, t))
        t = ticks_add(t, w)
        events.append((c, 0, t))
    return events


def ppm_edges(channels_us, t0_us, frame_us=22500, pulse_us=300, frames=1):
    """Edges of `frames` PPM frames, one every frame_us from t0_us, as [(level, t_us), ...].

    A frame period holds len(channels_us) + 1 pulses of pulse_us: channel c is the time from
    pulse c to pulse c + 1, and the last pulse starts the sync gap that lasts until the next
    period (it must exceed 2700 µs for a decoder to see it: keep sum(channels_us) below
    frame_us - 2700). A decoder completes a frame at the next frame's first rising edge, and
    one joining the signal needs a sync first: it decodes frame 2 at the start of frame 3.
    """
    events = []
    n = len(channels_us)
    start = t0_us
    for _ in range(frames):
        t = start
        for c in range(n + 1):
            events.append((1, t))
            events.append((0, ticks_add(t, pulse_us)))
            if c < n:
                t = ticks_add(t, int(channels_us[c]))
        start = ticks_add(start, frame_us)
    return events
