"""The receiver parsed on a second core (core/stages/rxcore.py, Receiver.use_core1): the same frames, counts and
telemetry as parsing in the receiver task; no torn frame through the lock-free handover under a real
thread; core 1's failure silences the link. Portable: pytest on CPython, mprun.py under MicroPython
(both have `_thread`: a pthread on the unix port, core 1 on the rp2 port).
"""

import _thread
from array import array

from fastpathkit import heap_bytes
from test_receiver import CH, T0, FakeBoard, _receiver

from hoverfly.compat import IS_MICROPYTHON, sleep_us, ticks_add
from hoverfly.core.config.params import Params
from hoverfly.core.signals import Signals
from hoverfly.core.stages.control import MODE_ANGLE
from hoverfly.core.stages.receiver import Receiver
from hoverfly.core.stages.rxcore import MASK, W_FRAMES, W_POLLS, W_RUNNING, W_SEQ, W_TX_LEN, RxCore, RxLink
from hoverfly.protocols import crsf, sbus


def _pair(provider="crsf", **values):
    """(receiver parsing here, receiver fed by core 1, core 1's RxCore), configured alike."""
    here = _receiver(provider, **values)
    there = _receiver(provider, **values)
    return here, there, there.use_core1(RxLink())


def _state(rx):
    return (list(rx.channels_us), rx.frames, rx.failsafe_frames, rx.lost_frames, rx.rx_failsafe, rx.errors,
            rx.link_quality_pct, rx.rssi_dbm, rx.snr_db, rx.frame_rate_hz, rx.last_frame_us, rx.new_frames)


def _wire(provider):
    """A byte stream with good frames, a corrupt one, garbage, receiver failsafe and repeat flags."""
    chunks = []
    for k in range(60):
        ch = list(CH)
        ch[0] = 1000 + 10 * k
        if provider == "crsf":
            f = bytearray(crsf.encode_rc_frame(ch))
            if k % 13 == 5:
                f[9] ^= 0x10  # a CRC error
            chunks.append(bytes(f))
            if k % 20 == 0:
                chunks.append(crsf.encode_link_statistics(rssi1_dbm=-60 - k, link_quality_pct=99 - k, snr_db=k % 7))
        else:
            f = bytearray(sbus.encode_rc_frame(ch, frame_lost=(k % 9 == 0), failsafe=(20 <= k < 24)))
            if k % 13 == 5:
                f[-1] = 0x55  # a bad footer
            chunks.append(bytes(f))
        if k % 17 == 3:
            chunks.append(b"\x00\xff junk")
    return chunks


def test_core1_gives_the_frames_and_counts_of_parsing_in_the_task():
    for provider in ("crsf", "sbus"):
        here, there, core = _pair(provider)
        b_here = FakeBoard()
        b_there = FakeBoard()
        t = T0
        for chunk in _wire(provider):
            b_here.queue(chunk)
            b_there.queue(chunk)
            t = ticks_add(t, 4000)
            here.update(t, b_here)
            while core.poll(b_there) > 0:  # core 1 reads everything waiting before the task looks
                pass
            there.update(t, b_there)
            assert _state(there) == _state(here), provider
        assert here.frames > 40 and here.errors > 0, provider
        assert there.decoder.torn == 0


def test_a_copy_in_progress_is_not_taken_until_core_1_has_finished_it():
    _, rx, core = _pair()
    b = FakeBoard()
    b.queue(crsf.encode_rc_frame(CH))
    core.poll(b)
    w = core.link.words
    seq = w[W_SEQ]
    w[W_SEQ] = seq + 1  # core 1 is writing
    assert rx.update(T0, b) == 0 and rx.frames == 0
    w[W_SEQ] = seq
    t = ticks_add(T0, 2000)
    assert rx.update(t, b) == 1 and list(rx.channels_us) == CH and rx.last_frame_us == t
    assert rx.update(ticks_add(t, 2000), b) == 0  # nothing new published


def test_counters_wrap_without_losing_a_frame():
    _, rx, core = _pair()
    b = FakeBoard()
    core.link.words[W_FRAMES] = MASK  # one frame before the wrap
    rx.decoder.frames = MASK
    for k in range(3):
        b.queue(crsf.encode_rc_frame(CH))
        core.poll(b)
        assert rx.update(ticks_add(T0, 4000 * k), b) == 1
    assert core.link.words[W_FRAMES] == 2 and rx.frames == 3


def test_telemetry_goes_out_through_core_1():
    here, there, core = _pair()
    b_here = FakeBoard()
    b_there = FakeBoard()
    s = Signals()
    s.battery_v = 16.0
    s.attitude.pitch_rad = 0.1
    t = T0
    for k in range(100):
        if k % 2 == 0:
            b_here.queue(crsf.encode_rc_frame(CH))
            b_there.queue(crsf.encode_rc_frame(CH))
        t = ticks_add(t, 2000)
        core.poll(b_there)
        for rx, b in ((here, b_here), (there, b_there)):
            rx.update(t, b)
            if rx.telemetry_due(t):
                rx.send_telemetry(t, b, s, MODE_ANGLE, True, False, True, 0)
        core.poll(b_there)  # core 1 writes what the task left in the link
    assert there.telemetry_frames == here.telemetry_frames >= 7
    assert bytes(b_there.sent) == bytes(b_here.sent)


def test_a_frame_waits_while_core_1_has_not_sent_the_last_one():
    _, rx, core = _pair()
    b = FakeBoard()
    s = Signals()
    s.battery_v = 16.0
    b.queue(crsf.encode_rc_frame(CH))
    core.poll(b)
    rx.update(T0, b)
    assert rx.send_telemetry(T0, b, s, MODE_ANGLE, False, False, False, 0) > 0
    w = core.link.words
    waiting = w[W_TX_LEN]
    assert waiting > 0 and len(b.sent) == 0
    t = ticks_add(T0, 30000)
    b.queue(crsf.encode_rc_frame(CH))
    assert rx.send_telemetry(t, b, s, MODE_ANGLE, False, False, False, 0) == 0  # core 1 is behind
    assert rx.telemetry_frames == 1
    core.poll(b)
    assert len(b.sent) == waiting and w[W_TX_LEN] == 0


def test_pin_receivers_stay_in_the_task():
    p = Params()
    p.set("rx_provider", "ppm")
    rx = Receiver()
    rx.configure(p)
    assert rx.use_core1(RxLink()) is None
    assert rx.decoder.__class__.__name__ != "LinkView"


class _CountingDecoder:
    """A codec whose every read completes one frame: all 16 channels carry the frame's number."""

    def __init__(self):
        self.channels_us = array("H", [1000] * 16)
        self.crc_errors = 0
        self.length_errors = 0
        self.failsafe = False
        self.frame_lost = False
        self.n = 0

    def feed(self, data, n):
        self.n += 1
        v = 1000 + self.n % 1000
        self.channels_us = array("H", [v] * 16)
        return 1


class _ByteBoard:
    def __init__(self, reads, taken=None):
        self.reads = reads
        self.sent = 0
        self.taken = taken  # [frames core 0 took so far]: core 1 waits on it every 1000 reads
        self._seen = 0

    def read_rx(self, buf):
        if self.reads == 0:
            raise OSError(5)  # the UART failed: core 1's loop stops
        self.reads -= 1
        if self.taken is not None and self.reads % 1000 == 0:
            # On a loaded host core 1 can run all its reads before core 0 is scheduled once, and the test would
            # then check no handover at all: wait (at most 1 s) until core 0 has taken a frame since the last wait.
            for _ in range(10000):
                if self.taken[0] > self._seen:
                    break
                sleep_us(100)
            self._seen = self.taken[0]
        return 1

    def write_rx(self, data, n):
        self.sent += n


def test_a_thread_publishing_as_fast_as_it_can_never_hands_over_a_torn_frame():
    # given core 1 (a real thread) publishing frames back to back, when core 0 takes them as often as it
    # can, then every frame it takes has all 16 channels from the frame its count says (a copy that core 1
    # overwrote meanwhile is dropped, not taken)
    try:
        import sys

        sys.setswitchinterval(1e-6)  # CPython: switch threads as often as it can
    except AttributeError:
        pass
    link = RxLink()
    core = RxCore(link, _CountingDecoder())
    rx = Receiver()
    p = Params()
    p.set("rx_provider", "crsf")
    rx.configure(p)
    rx.start(T0)
    rx.use_core1(link)  # its own RxCore is not started: the counting one publishes on the link
    taken = [0]
    board = _ByteBoard(20000, taken)
    _thread.start_new_thread(core.run, (board,))
    took = 0
    t = T0
    spins = 0
    while spins < 2000000:
        spins += 1
        t = ticks_add(t, 100)
        if rx.update(t, board):
            took += 1
            taken[0] = took
            v = rx.channels_us[0]
            assert v == 1000 + rx.decoder.frames % 1000, (v, rx.decoder.frames)
            for c in rx.channels_us:
                assert c == v
        if not link.words[W_RUNNING] and link.words[W_POLLS] > 0:
            break
        if took and spins % 64 == 0:
            sleep_us(1)
    while link.words[W_RUNNING]:
        sleep_us(100)
    assert link.fault is not None  # the fake UART failed after its 20000 reads: the loop stopped on it
    assert link.words[W_POLLS] == 20000
    rx.update(ticks_add(t, 100), board)
    assert rx.decoder.frames == 20000
    assert took > 10
    try:
        import sys

        sys.setswitchinterval(0.005)
    except AttributeError:
        pass


def test_core_1_stops_when_asked():
    link = RxLink()
    core = RxCore(link, _CountingDecoder())
    board = _ByteBoard(10 ** 9)
    _thread.start_new_thread(core.run, (board,))
    for _ in range(10000):
        if link.words[W_POLLS] > 10:
            break
        sleep_us(100)
    from hoverfly.core.stages.rxcore import LinkView

    LinkView(link).stop()
    for _ in range(10000):
        if not link.words[W_RUNNING]:
            break
        sleep_us(100)
    assert not link.words[W_RUNNING] and link.fault is None


def test_taking_a_frame_from_core_1_allocates_nothing_on_either_side():
    _, rx, core = _pair()
    b = FakeBoard()
    frame = crsf.encode_rc_frame(CH)
    b.queue(frame)
    core.poll(b)
    rx.update(T0, b)
    t = [T0]

    def one_frame():  # the frame's bytes queued before the count: the test board's own work is not the cores'
        core.poll(b)
        t[0] = ticks_add(t[0], 4000)
        rx.update(t[0], b)

    for _ in range(20):
        b.queue(frame)
        grown = heap_bytes(one_frame, 1)
        if IS_MICROPYTHON:
            assert grown == 0, grown
    assert rx.frames == 21
