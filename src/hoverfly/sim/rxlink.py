"""The simulated radio link: the pilot's transmitter and the receiver on the craft, as a wire.

Takes the channels the scenario pilot writes (`channels_us`, µs, AETR + AUX) and turns them
into what a real receiver puts on the flight controller's input, with its timing: frames of
the chosen protocol encoded by the same codecs the Pico decodes (`protocols/`), each byte
arriving when its stop bit would, or pin edges at their µs. The sim board pulls what has
arrived by `sim_us` (`advance`, then `take_bytes` / `take_edges`); the flight core parses it
through its receiver stage exactly as on hardware. CPython only (it allocates freely).

| protocol | frame period | line (per byte) | on link loss |
| --- | --- | --- | --- |
| crsf | 4 ms (ExpressLRS 250 Hz); LINK_STATISTICS after every 25th | 420000 8N1: 23.8 µs | silence |
| sbus | 9 ms (FrSky X8R; `sbus_period_us=14000`: Futaba) | 100000 8E2: 120 µs | failsafe frames |
| ibus | 7 ms | 115200 8N1: 86.8 µs | silence |
| ppm | 22.5 ms, 8 channels, 300 µs pulses | edges on one pin | no pulses |
| pwm | 20 ms (50 Hz), `pwm_channels` pins pulsing one after another | edges per pin | no pulses |

Frames start at their period from sim time 0; the sticks are sampled when a frame is
built, which is at most one receiver-task period (2 ms) after its start time.

SBUS on link loss: an SBUS receiver does not go quiet, it keeps its frame rate and says so
in the flags. The choice here, fixed (no parameter): from the first frame after the loss,
every frame repeats the last good channels with both `frame lost` and `failsafe` set (a
receiver set to "hold" whose own failsafe acts at once; real ones wait a few missed
packets first, which would only delay the controller's reaction by that much). The
controller must not fly on them: its receiver stage counts them as lost frames, so link
loss is declared after `rx_timeout_ms` as with the silent protocols. When the link comes
back the flags clear and the pilot's sticks flow again.
"""

from collections import deque

from hoverfly.compat import ticks_add
from hoverfly.protocols import crsf, ibus, sbus
from hoverfly.protocols.pulses import ppm_edges, pwm_edges

CRSF_PERIOD_US = 4000  # ExpressLRS packet rate 250 Hz
CRSF_LINK_STATS_EVERY = 25  # RC frames per LINK_STATISTICS frame: 10 Hz (Betaflight zeroes LQ after 250 ms)
SBUS_PERIOD_US = 9000  # FrSky X8R (reference/protocols.md §2); Futaba 14 ms
IBUS_PERIOD_US = 7000
PPM_PERIOD_US = 22500
PPM_CHANNELS = 8
PPM_PULSE_US = 300
PWM_PERIOD_US = 20000  # 50 Hz servo frame

# bits per byte on the wire (start + data + parity + stop) and baud
_LINE = {"crsf": (10, 420000), "sbus": (12, 100000), "ibus": (10, 115200)}


class RxLink:
    def __init__(self, protocol, channels_us, pwm_channels=6, sbus_period_us=SBUS_PERIOD_US):
        if protocol not in ("crsf", "sbus", "ibus", "ppm", "pwm"):
            raise ValueError("unknown receiver protocol %r" % (protocol,))
        self.protocol = protocol
        self.channels_us = channels_us
        self.pwm_channels = pwm_channels
        self.serial = protocol in _LINE
        self.period_us = {"crsf": CRSF_PERIOD_US, "sbus": sbus_period_us, "ibus": IBUS_PERIOD_US,
                          "ppm": PPM_PERIOD_US, "pwm": PWM_PERIOD_US}[protocol]
        if self.serial:
            bits, baud = _LINE[protocol]
            self._bit_ns = bits * 1_000_000_000 // baud  # ns per byte
        self.link_quality_pct = 100  # what the CRSF receiver reports in LINK_STATISTICS
        self.rssi_dbm = -50
        self.snr_db = 9
        self.frames_sent = 0
        self.failsafe_frames_sent = 0
        self.link_stats_sent = 0
        self.bytes_sent = 0
        self.edges_sent = 0
        self._next_us = 0
        self._rc_frames = 0
        self._held = [1500] * 16  # SBUS: the last channels sent while the link was up
        # The last RC frame and the channels it carries: a transmitter's sticks rarely move between
        # two 4 ms frames (94.5 % of CRSF frames in a hover repeat the last), so the bytes are reused.
        self._frame_channels = None
        self._frame_bytes = b""
        self._frames = deque()  # [start_us, bytes, delivered] of serial frames still on the wire
        self._edges = deque()  # (code, t_sim_us) of pulse edges not yet due
        self.rx_bytes = bytearray()  # arrived, not yet read by the board
        self.rx_edges = deque()  # arrived (code, t_sim_us), not yet read

    # ---------------------------------------------------------------- sending
    def advance(self, sim_us, alive=True):
        """Build every frame due by sim_us and move what has arrived by then to rx_bytes/rx_edges."""
        while self._next_us <= sim_us:
            t = self._next_us
            self._next_us += self.period_us
            self._send(t, alive)
        if self.serial:
            self._arrive_bytes(sim_us)
        else:
            edges = self._edges
            out = self.rx_edges
            while edges and edges[0][1] <= sim_us:
                out.append(edges.popleft())

    def _send(self, t_us, alive):
        p = self.protocol
        ch = self.channels_us
        if p == "sbus":
            if alive:
                held = self._held
                for i in range(16):
                    held[i] = ch[i]
                frame = sbus.encode_rc_frame(held)
            else:
                frame = sbus.encode_rc_frame(self._held, frame_lost=True, failsafe=True)
                self.failsafe_frames_sent += 1
            self._queue(t_us, bytes(frame))
            return
        if not alive:
            return
        if p == "crsf":
            frame = self._rc_frame(ch[:16], crsf.encode_rc_frame)
            self._rc_frames += 1
            if self._rc_frames % CRSF_LINK_STATS_EVERY == 0:
                frame += bytes(crsf.encode_link_statistics(
                    rssi1_dbm=self.rssi_dbm, rssi2_dbm=self.rssi_dbm - 3, link_quality_pct=self.link_quality_pct,
                    snr_db=self.snr_db, downlink_rssi_dbm=self.rssi_dbm, downlink_link_quality_pct=100))
                self.link_stats_sent += 1
            self._queue(t_us, frame)
        elif p == "ibus":
            self._queue(t_us, self._rc_frame(ch[:14], ibus.encode_rc_frame))
        elif p == "ppm":
            for level, t in ppm_edges(ch[:PPM_CHANNELS], t_us, PPM_PERIOD_US, PPM_PULSE_US, 1):
                self._edges.append((level, t))
            self.frames_sent += 1
        else:
            for c, level, t in pwm_edges(ch[:self.pwm_channels], t_us):
                self._edges.append((c * 2 + level, t))
            self.frames_sent += 1

    def _rc_frame(self, channels, encode):
        """The encoded frame for these channels: the last one again while they have not changed."""
        if channels != self._frame_channels:
            self._frame_bytes = bytes(encode(channels))
            self._frame_channels = channels
        return self._frame_bytes

    def _queue(self, t_us, frame):
        self._frames.append([t_us, frame, 0])
        self.frames_sent += 1

    def _arrive_bytes(self, sim_us):
        frames = self._frames
        out = self.rx_bytes
        bit_ns = self._bit_ns
        while frames:
            f = frames[0]
            start, data, done = f
            # byte i has arrived once its last (stop) bit has: start + (i + 1) byte times
            arrived = (sim_us - start) * 1000 // bit_ns
            if arrived <= done:
                return
            if arrived >= len(data):
                out += data[done:]
                self.bytes_sent += len(data) - done
                frames.popleft()
                continue
            out += data[done:arrived]
            self.bytes_sent += arrived - done
            f[2] = arrived
            return

    # -------------------------------------------------------------- receiving
    def take_bytes(self, buf):
        """Move up to len(buf) arrived bytes into buf; returns how many."""
        src = self.rx_bytes
        n = min(len(buf), len(src))
        if n:
            buf[:n] = src[:n]
            del src[:n]
        return n

    def take_edges(self, edges, origin_ticks_us):
        """Move up to len(edges) // 2 arrived edges into edges as (code, ticks) pairs; returns how many.

        Sim time becomes the board's tick clock (origin_ticks_us + t, wrapping as ticks do)."""
        src = self.rx_edges
        n = 0
        cap = len(edges) // 2
        k = 0
        while src and n < cap:
            code, t = src.popleft()
            edges[k] = code
            edges[k + 1] = ticks_add(origin_ticks_us, t)
            k += 2
            n += 1
        self.edges_sent += n
        return n
