"""The arming-disable reasons on a whole Flight: worked out by the 100 Hz task only while disarmed (as
Betaflight does), and at once on a disarm, so an arm request on the very next frame meets the reasons of
now, not those of before the arming. Receiver frames go through the real CRSF receiver and the Flight's
receiver task. Portable."""

from configfakes import FakeBoard

from hoverfly.core.events import EV_ARMED, EV_ARMING_BLOCKED, EV_DISARMED
from hoverfly.core.flight import Flight
from hoverfly.core.safety.arming import THROTTLE
from hoverfly.protocols.crsf import encode_rc_frame


class RxBoard(FakeBoard):
    """configfakes' board with a receiver UART (queued CRSF bytes come out of read_rx) and a live IMU."""

    def __init__(self):
        super().__init__()
        self.wire = bytearray()
        self.k = 0

    def read_imu(self, gyro_rad_s, accel_m_s2):
        self.k += 1  # a little noise: never the same sample twice in a row (a frozen IMU blocks arming)
        gyro_rad_s[0] = 0.001 * (self.k % 3)
        gyro_rad_s[1] = 0.0
        gyro_rad_s[2] = 0.0
        accel_m_s2[0] = 0.0
        accel_m_s2[1] = 0.0
        accel_m_s2[2] = -9.80665
        return True

    def read_rx(self, buf):
        n = len(self.wire)
        if n > len(buf):
            n = len(buf)
        for i in range(n):
            buf[i] = self.wire[i]
        self.wire = self.wire[n:]
        return n


def _channels(arm_us, throttle_us):
    ch = [1500] * 16
    ch[2] = throttle_us  # AETR: throttle on channel 3
    ch[4] = arm_us  # AUX1: the arm switch
    return ch


def _events(f):
    out = []
    f.events.drain(0, lambda t, e, d: out.append((e, d)))
    return out


def _flight():
    board = RxBoard()
    f = Flight(board)
    f.params.set("gyro_cal_ms", 100)
    f.params.set("boot_grace_ms", 0)
    f.start(1000)
    return board, f


def _fly(board, f, t, passes, arm_us, throttle_us):
    for k in range(passes):
        if k % 4 == 0:
            board.wire.extend(encode_rc_frame(_channels(arm_us, throttle_us)))
        t += 1000
        board.t_us = t
        f.step(t)
    return t


def test_a_rearm_on_the_frame_after_a_disarm_meets_the_reasons_of_now():
    board, f = _flight()
    t = _fly(board, f, 1000, 400, 1000, 1000)  # calibrated, switch off, throttle low
    t = _fly(board, f, t, 40, 2000, 1000)
    assert f.arming.armed
    t = _fly(board, f, t, 200, 2000, 1600)  # flying: throttle up
    assert f.arming.armed
    # the switch off for the disarm frames: disarmed on the last of them, inside the receiver task
    for _ in range(10):
        board.wire.extend(encode_rc_frame(_channels(1000, 1600)))
        t += 4000
        f.task_rx(t)
        if not f.arming.armed:
            break
    assert not f.arming.armed
    # the very next frame: the switch on again, the throttle still up, before any 100 Hz task has run
    board.wire.extend(encode_rc_frame(_channels(2000, 1600)))
    f.task_rx(t + 4000)
    assert not f.arming.armed
    ev = _events(f)
    assert ev[-1] == (EV_ARMING_BLOCKED, THROTTLE), ev[-3:]
    assert ev[-2][0] == EV_DISARMED


def test_armed_the_reasons_are_left_as_they_were_and_come_back_on_the_disarm():
    board, f = _flight()
    t = _fly(board, f, 1000, 400, 1000, 1000)
    t = _fly(board, f, t, 40, 2000, 1000)
    assert f.arming.armed and f.arming.flags & (1 << THROTTLE) == 0
    t = _fly(board, f, t, 100, 2000, 1600)
    assert f.arming.flags & (1 << THROTTLE) == 0  # armed: not worked out (nothing reads them to decide)
    t = _fly(board, f, t, 40, 1000, 1600)
    assert not f.arming.armed
    assert f.arming.flags & (1 << THROTTLE)
    assert (EV_ARMED, 0) in _events(f)
