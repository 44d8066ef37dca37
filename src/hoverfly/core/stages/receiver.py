"""The receiver stage: wire bytes or pin edges in, channels and a link watch out, telemetry back.

Takes what the board's receiver input delivered since the last call (UART bytes through
`board.read_rx`, or pin edges through `board.read_rx_edges` for PPM/PWM) and feeds
the protocol codec chosen by the `rx_provider` parameter (crsf | sbus | ibus | ppm | pwm,
built by `rxfactory.make_decoder`). Gives `channels_us` (16 channels, µs) whenever a new
valid frame arrived, and the link watch: `last_frame_us`, `frames`, `errors`,
`frame_rate_hz`, `link_quality_pct`, `rssi_dbm`, `rx_failsafe`. On CRSF it also sends
telemetry back on the same UART (`board.write_rx`): battery, attitude and flight
mode, one frame right after an RC frame at most every 25 ms (CrsfTelemetryScheduler).
It runs in the receiver task (500 Hz), never in the flight pass; Flight.task_rx hands
the channels to the RC input stage and decides link lost / restored from `last_frame_us`.
With `rx_core1` (rp2 board, `use_core1`) the UART and the codec are the second core's
(core/stages/rxcore.py): update() takes the frames it published instead of reading, and the
telemetry frames go back out through it; everything else here is unchanged.

What counts as a valid frame: a frame the codec accepted (CRC, checksum, footer, pulse
widths) that does not carry the receiver's own failsafe flag (SBUS flag bit 3). A
receiver in failsafe sends its failsafe channel values, not the pilot's: such a frame is
counted as a lost frame (`failsafe_frames`, `rx_failsafe` True) and does not refresh
`last_frame_us`, so the link watch trips exactly as if the receiver had gone quiet.

Link quality: CRSF reports it (LINK_STATISTICS 0x14: uplink LQ and the active antenna's
RSSI); like Betaflight both read 0 once no 0x14 came for 250 ms. The other protocols
carry none, so it is measured over 1 s windows as good frames / (good + bad) in percent,
bad being the frames the receiver flagged (SBUS frame lost, failsafe) plus the codec's
errors; a window without any frame reads 0. Their `rssi_dbm` is 0 (unknown).
"""

from array import array

from hoverfly.compat import const, ticks_add, ticks_diff
from hoverfly.core.safety.arming import ARM_SWITCH
from hoverfly.protocols.rxcodec import CHANNELS
from hoverfly.protocols.rxfactory import make_decoder

_READ_BYTES = const(64)  # one read: two CRSF RC frames and a link-statistics frame fit
_READS_MAX = const(4)  # bounded: a chattering UART cannot hold the task
_EDGES_MAX = const(32)  # pairs (code, t_us) per read; a 20 ms PWM frame of 8 channels is 16 edges
_WINDOW_US = const(1000000)  # frame-rate and link-quality window
_LQ_STALE_US = const(250000)  # Betaflight: no CRSF 0x14 this long => RSSI and LQ read 0
TELEMETRY_INTERVAL_US = const(25000)  # 40 frames/s: ~10 Hz per kind with three kinds (Betaflight)
# crsf.KIND_BATTERY, KIND_ATTITUDE, KIND_FLIGHT_MODE (protocols/crsf.py is imported only with CRSF telemetry)
_KIND_BATTERY = const(0)
_KIND_ATTITUDE = const(1)
_KIND_FLIGHT_MODE = const(2)
_KIND_AIRSPEED = const(4)  # crsf.KIND_AIRSPEED

# CRSF flight-mode strings as Betaflight master sends them (reference/protocols.md §1.5):
# armed plain, disarmed and ready to arm '*', disarmed with arming blocked '!'.
# Indexed [mode][state]; mode 0 acro, 1 angle, 2 horizon (control.MODE_*), 3 acro with air
# mode, 4 failsafe, 5 a plane's MANUAL (INAV's "MANU"). Preallocated bytes: choosing one allocates nothing.
_MODE_TEXT = (
    (b"ACRO", b"ACRO*", b"ACRO!"),
    (b"ANGL", b"ANGL*", b"ANGL!"),
    (b"HOR", b"HOR*", b"HOR!"),
    (b"AIR", b"AIR*", b"AIR!"),
    (b"!FS!", b"!FS!*", b"!FS!!"),
    (b"MANU", b"MANU*", b"MANU!"),
)
_TEXT_AIR = const(3)
_TEXT_FAILSAFE = const(4)
_TEXT_MANUAL = const(5)


def flight_mode_text(mode, airmode, failsafe, armed, arming_flags):
    """The CRSF flight-mode string (bytes constant) for this state."""
    if failsafe:
        row = _MODE_TEXT[_TEXT_FAILSAFE]
    elif mode == 0 and airmode:
        row = _MODE_TEXT[_TEXT_AIR]
    elif 0 <= mode <= 2:
        row = _MODE_TEXT[mode]
    elif mode == 3:  # control.MODE_MANUAL
        row = _MODE_TEXT[_TEXT_MANUAL]
    else:
        row = _MODE_TEXT[0]
    if armed:
        return row[0]
    # The arm switch having to be toggled is not a block: the pilot's next flick arms.
    if arming_flags & ~(1 << ARM_SWITCH):
        return row[2]
    return row[1]


def cell_count(voltage_v):
    """LiPo cells of a pack, from its voltage when plugged in (Betaflight: 4.3 V max per cell)."""
    return int(voltage_v / 4.3) + 1


def battery_remaining_pct(voltage_v, cells):
    """Rough charge left: 3.3 V empty .. 4.2 V full per cell, linear; 0 when unknown."""
    if cells <= 0 or voltage_v <= 0.5:
        return 0
    pct = int((voltage_v / cells - 3.3) * 111.11 + 0.5)
    if pct < 0:
        return 0
    if pct > 100:
        return 100
    return pct


class Receiver:
    def __init__(self):
        self.provider = ""
        self.decoder = None
        self.serial = True  # a serial codec fed in this task (not pin edges, not core 1's frames)
        self._link = None  # rxcore.LinkView once the codec runs on core 1 (use_core1)
        self._crsf = False
        self._flags = False  # the codec reads the receiver's failsafe and frame-lost flags (SBUS)
        self._pwm = False
        self.pwm_channels = 6
        self.channels_us = array("H", [1500] * CHANNELS)
        # link watch
        self.last_frame_us = 0
        self.frames = 0  # valid frames (receiver failsafe frames excluded)
        self.errors = 0  # codec errors: CRC/checksum, impossible lengths/footers, bad pulses
        self.failsafe_frames = 0  # frames carrying the receiver's failsafe flag
        self.lost_frames = 0  # frames the receiver flagged as repeats (SBUS frame lost)
        self.rx_failsafe = False  # the last frame carried the receiver's failsafe flag
        self.frame_rate_hz = 0
        self.link_quality_pct = 0
        self.rssi_dbm = 0
        self.snr_db = 0
        self.new_frames = 0  # valid frames in the last update()
        self._win_start_us = 0
        self._win_valid = 0
        self._win_repeat = 0
        self._win_failsafe = 0
        self._win_errors = 0
        self._stats_frames = 0
        self._stats_us = 0
        self._check_us = 0  # when update() next looks at the clock: the window's end, stale link statistics
        # telemetry (CRSF only)
        self.telemetry = None  # CrsfTelemetryScheduler while CRSF telemetry is on
        self.telemetry_frames = 0
        self._cells = 0
        self._tlm_next_us = 0
        self._tlm_buf = bytearray(64)
        # read buffers
        self._buf = bytearray(_READ_BYTES)
        self._edges = array("i", [0] * (2 * _EDGES_MAX))

    def configure(self, params):
        provider = params.get("rx_provider")
        pwm_channels = params.get("rx_pwm_channels")
        wire = provider != self.provider or (provider == "pwm" and pwm_channels != self.pwm_channels)
        if wire and self._link is None:
            # A new codec only when the wire changes: counters survive other parameter writes. (Not once
            # core 1 runs the codec: a new wire takes a reboot, as rx_provider says.)
            self.provider = provider
            self.pwm_channels = pwm_channels
            self.decoder = make_decoder(provider, pwm_channels)
            self.serial = provider in ("crsf", "sbus", "ibus")
            self._crsf = provider == "crsf"
            self._flags = provider == "sbus"
            self._pwm = provider == "pwm"
            self.channels_us = self.decoder.channels_us
            self._win_errors = 0
            self._stats_frames = 0
        if provider == "crsf" and params.get("crsf_telemetry"):
            if self.telemetry is None:
                from hoverfly.protocols.crsf import CrsfTelemetryScheduler

                self.telemetry = CrsfTelemetryScheduler(TELEMETRY_INTERVAL_US)
        else:
            self.telemetry = None

    def use_core1(self, link):
        """Hand the serial codec to the second core: returns the rxcore.RxCore to run there (its `run`);
        from now on update() takes the frames it publishes on `link` (an rxcore.RxLink) and the telemetry
        frames go out through it. None for pin-edge receivers (PPM/PWM), which stay here."""
        if not self.serial or self._link is not None:
            return None
        from hoverfly.core.stages.rxcore import LinkView, RxCore

        core = RxCore(link, self.decoder)
        view = LinkView(link)
        self._link = view
        self.decoder = view
        self.channels_us = view.channels_us
        self.serial = False  # update() reads the link, not the UART
        return core

    def start(self, now_us):
        self.last_frame_us = now_us
        self._win_start_us = now_us
        self._stats_us = now_us
        self._tlm_next_us = now_us
        self._plan_check()

    # ------------------------------------------------------------------ input
    def update(self, now_us, board):
        """Take what the board received; returns the number of new valid frames (0 if none)."""
        # Few locals here: a bytecode function whose frame (locals and value stack) passes 11 machine
        # words takes it from the heap on every call on MicroPython (docs/pico.md); the rarer paths are
        # methods of their own. A frame's own bookkeeping is here, not a method: it runs at every frame.
        if self.serial:
            n = board.read_rx(self._buf)
            new = 0
            if n > 0:  # many polls find nothing, and then the codec's counts cannot have moved either
                dec = self.decoder
                new = dec.feed(self._buf, n)
                if n >= _READ_BYTES:  # a full read: more may be waiting
                    new += self._read_more(board)
                self.errors = dec.crc_errors + dec.length_errors
                if self._crsf and dec.link_stats_frames != self._stats_frames:
                    self._link_statistics(now_us)
        else:
            new = self._read_other(board, now_us)
        if new:
            if self._flags:  # a codec whose receiver flags its own failsafe and repeated frames (SBUS)
                new = self._flagged(new)
            if new:  # the pilot's sticks
                self.rx_failsafe = False
                self.frames += new
                self._win_valid += new
                self.last_frame_us = now_us
        self.new_frames = new
        if ticks_diff(now_us, self._check_us) >= 0:  # one look at the clock a call, for both timed checks
            self._housekeeping(now_us)
        return new

    def _housekeeping(self, now_us):
        """The link watch's timed parts, when _check_us comes: CRSF link statistics gone stale, the 1 s window."""
        if self._crsf and self.link_quality_pct and ticks_diff(now_us, self._stats_us) > _LQ_STALE_US:
            self.link_quality_pct = 0  # Betaflight: no 0x14 for 250 ms reads as no link
            self.rssi_dbm = 0
            self.snr_db = 0
        if ticks_diff(now_us, self._win_start_us) >= _WINDOW_US:
            self._close_window(now_us)
        self._plan_check()

    def _plan_check(self):
        """_check_us: the window's end, or sooner while CRSF link statistics read a link (their going stale)."""
        due = ticks_add(self._win_start_us, _WINDOW_US)
        if self._crsf and self.link_quality_pct:
            stale = ticks_add(self._stats_us, _LQ_STALE_US + 1)
            if ticks_diff(stale, due) < 0:
                due = stale
        self._check_us = due

    def _read_more(self, board):
        """Reads after a full one, _READS_MAX in all (bounded: a chattering UART cannot hold the task)."""
        buf = self._buf
        dec = self.decoder
        new = 0
        for _ in range(_READS_MAX - 1):
            n = board.read_rx(buf)
            if n <= 0:
                break
            new += dec.feed(buf, n)
            if n < _READ_BYTES:
                break
        return new

    def _read_other(self, board, now_us):
        """Pin edges (PPM/PWM), or the frames the second core published (rx_core1)."""
        view = self._link
        if view is None:
            return self._read_edges(board)
        new = view.take()
        if new < 0:  # nothing new published (most polls)
            return 0
        self.errors = view.crc_errors + view.length_errors
        if self._crsf and view.link_stats_frames != self._stats_frames:
            self._link_statistics(now_us)
        return new

    def _read_edges(self, board):
        """PPM/PWM: the pin edges since the last call through the pulse decoder; new frames."""
        dec = self.decoder
        edges = self._edges
        pwm = self._pwm
        new = 0
        for _ in range(_READS_MAX):
            n = board.read_rx_edges(edges)
            if n <= 0:
                break
            k = 0
            end = 2 * n
            while k < end:
                code = edges[k]
                if pwm:
                    new += dec.edge(code >> 1, code & 1, edges[k + 1])
                else:
                    new += dec.edge(code & 1, edges[k + 1])
                k += 2
            if n < _EDGES_MAX:
                break
        self.errors = dec.errors
        return new

    def _flagged(self, new):
        """The flags of `new` decoded frames from a receiver that sets them (SBUS): returns how many carry the
        pilot's sticks (0 for the receiver's failsafe values; repeats still carry the last ones)."""
        dec = self.decoder
        if dec.failsafe:
            # The receiver's failsafe values are not the pilot's sticks: a lost frame.
            self.failsafe_frames += new
            self._win_failsafe += new
            self.rx_failsafe = True
            return 0
        if dec.frame_lost:
            self.lost_frames += new  # a repeat: still the pilot's last sticks
            self._win_repeat += new
        return new

    def _close_window(self, now_us):
        dt_us = ticks_diff(now_us, self._win_start_us)
        valid = self._win_valid
        self.frame_rate_hz = (valid * 1000000 + (dt_us >> 1)) // dt_us
        if not self._crsf:
            good = valid - self._win_repeat
            bad = self._win_repeat + self._win_failsafe + self.errors - self._win_errors
            self.link_quality_pct = (100 * good) // (good + bad) if good + bad > 0 else 0
        self._win_errors = self.errors
        self._win_valid = 0
        self._win_repeat = 0
        self._win_failsafe = 0
        self._win_start_us = now_us

    def _link_statistics(self, now_us):
        dec = self.decoder
        self._stats_frames = dec.link_stats_frames
        self._stats_us = now_us
        self.link_quality_pct = dec.link_quality_pct
        self.rssi_dbm = dec.rssi_dbm
        self.snr_db = dec.snr_db
        self._plan_check()

    def frame_age_us(self, now_us):
        """Time since the last valid frame."""
        return ticks_diff(now_us, self.last_frame_us)

    # -------------------------------------------------------------- telemetry
    def telemetry_due(self, now_us):
        """True right after an RC frame arrived, when the next telemetry frame may go out."""
        return (self.telemetry is not None and self.new_frames > 0
                and ticks_diff(now_us, self._tlm_next_us) >= 0)

    def send_telemetry(self, now_us, board, signals, mode, airmode, failsafe, armed, arming_flags):
        """Refresh the telemetry values and send the scheduler's next frame on the receiver UART."""
        t = self.telemetry
        v = signals.battery_v
        if self._cells == 0 and v > 0.5:
            self._cells = cell_count(v)  # counted once, as the pack is plugged in: sag must not change it
        # Only the kind the frame will carry is refreshed (all of them until each has data): the same
        # frame, a third of the work.
        kind = t.upcoming()
        if kind < 0 or kind == _KIND_BATTERY:
            t.set_battery(v, signals.current_a, signals.mah_drawn, battery_remaining_pct(v, self._cells))
        if kind < 0 or kind == _KIND_ATTITUDE:
            a = signals.attitude
            t.set_attitude(a.pitch_rad, a.roll_rad, a.yaw_rad)
        if kind < 0 or kind == _KIND_FLIGHT_MODE:
            t.set_flight_mode(flight_mode_text(mode, airmode, failsafe, armed, arming_flags))
        # A plane's pitot joins the rotation while it reads (set every time: until it has data it is never upcoming).
        if signals.airspeed_valid:
            t.set_airspeed(signals.airspeed_m_s)
        else:
            t.clear(_KIND_AIRSPEED)
        view = self._link
        buf = self._tlm_buf if view is None else view.tx_buffer()
        if buf is None:  # core 1 has not written the last frame yet: this one waits for the next slot
            return 0
        n = t.poll(now_us, self.new_frames, buf)
        self._tlm_next_us = ticks_add(now_us, TELEMETRY_INTERVAL_US)
        if n:
            if view is None:
                board.write_rx(buf, n)
            else:
                view.send(n)
            self.telemetry_frames += 1
        return n
