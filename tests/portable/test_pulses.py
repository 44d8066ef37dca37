"""PWM and PPM capture from edge timestamps, round-tripped through the edge generators.

Plain asserts: runs under pytest and under MicroPython (tests/portable/mprun.py).
Times start just below the tick wrap so every width is measured across it.
"""

from hoverfly.compat import TICKS_MAX, ticks_add
from hoverfly.protocols.pulses import PpmCapture, PwmCapture, ppm_edges, pwm_edges

NEAR_WRAP_US = ticks_add(TICKS_MAX, -3000)  # 3 ms before the tick counter wraps
FS_IA6 = [1000, 2000, 1500, 1234, 1800, 1100]  # six PWM outputs (seed 001's FS-IA6)


def _pwm(capture, events):
    done = 0
    for ch, level, t in events:
        done += capture.edge(ch, level, t)
    return done


def _ppm(capture, events):
    done = 0
    for level, t in events:
        done += capture.edge(level, t)
    return done


def test_pwm_frame_counts_when_every_channel_has_a_fresh_width():
    cap = PwmCapture(6)
    events = pwm_edges(FS_IA6, NEAR_WRAP_US)
    assert _pwm(cap, events[:-1]) == 0  # last channel not finished yet
    assert _pwm(cap, events[-1:]) == 1
    assert list(cap.channels_us[:6]) == FS_IA6
    assert list(cap.channels_us[6:]) == [1500] * 10
    assert cap.frames == 1 and cap.errors == 0


def test_pwm_dead_channel_stops_frames_but_updates_the_rest():
    cap = PwmCapture(4)
    t = NEAR_WRAP_US
    _pwm(cap, pwm_edges([1500, 1500, 1500, 1500], t))
    events = [e for e in pwm_edges([1600, 1700, 1800, 1900], ticks_add(t, 20000)) if e[0] != 2]
    assert _pwm(cap, events) == 0
    assert cap.frames == 1 and list(cap.channels_us[:4]) == [1600, 1700, 1500, 1900]


def test_pwm_widths_outside_800_2200_are_refused_and_counted():
    cap = PwmCapture(2)
    assert _pwm(cap, pwm_edges([700, 2300], NEAR_WRAP_US)) == 0
    assert cap.errors == 2 and cap.frames == 0
    assert _pwm(cap, pwm_edges([800, 2200], NEAR_WRAP_US)) == 1


def test_pwm_falling_edge_without_rising_and_bad_channel_index_never_raise():
    cap = PwmCapture(2)
    assert cap.edge(0, 0, 100) == 0 and cap.errors == 0
    assert cap.edge(7, 1, 100) == 0 and cap.edge(-1, 0, 100) == 0
    assert cap.errors == 2


def test_ppm_frame_completes_at_the_next_sync():
    cap = PpmCapture()
    chans = [1000, 2000, 1500, 1234, 1100, 1900, 1500, 1500]
    events = ppm_edges(chans, NEAR_WRAP_US, frames=4)
    done = _ppm(cap, events)
    # frame 1 only finds the first sync; 2 and 3 complete at the next syncs; 4 waits for its own
    assert done == 2
    assert list(cap.channels_us) == chans + [1500] * 8
    assert cap.channel_count == 8 and cap.errors == 0


def test_ppm_twelve_channels_fit_a_22_5_ms_frame():
    cap = PpmCapture()
    chans = [1400 + 10 * k for k in range(12)]
    assert _ppm(cap, ppm_edges(chans, NEAR_WRAP_US, frame_us=22500, frames=3)) == 1
    assert cap.channel_count == 12 and list(cap.channels_us[:12]) == chans


def test_ppm_bad_interval_drops_the_frame_and_counts_once():
    cap = PpmCapture()
    chans = [1500, 2500, 1500, 1500]  # 2500 µs: too long for a channel, too short for a sync
    assert _ppm(cap, ppm_edges(chans, NEAR_WRAP_US, frames=2)) == 0  # frame 2 is the first after a sync
    assert cap.errors == 1 and cap.frames == 0
    assert _ppm(cap, ppm_edges([1500] * 4, ticks_add(NEAR_WRAP_US, 45000), frames=2)) == 1


def test_ppm_too_few_and_too_many_channels_are_errors():
    few = PpmCapture(min_channels=4)
    assert _ppm(few, ppm_edges([1500] * 3, NEAR_WRAP_US, frames=3)) == 0
    assert few.errors == 1
    many = PpmCapture()
    chans = [1000] * 17
    assert _ppm(many, ppm_edges(chans, NEAR_WRAP_US, frame_us=30000, frames=2)) == 0
    assert many.errors == 1


def test_ppm_ignores_falling_edges_and_starts_at_the_first_sync():
    cap = PpmCapture()
    events = ppm_edges([1500] * 6, NEAR_WRAP_US, frames=3)
    done = _ppm(cap, events[5:])  # join mid-frame
    assert done >= 1 and cap.errors == 0 and cap.channel_count == 6
