"""The supervisor on a whole Flight: the failsafe's stages timed from the last frame and handed to the commander,
the failsafe switch's kill, the battery's cell count and limit, a configuration change and a raising task as
arming reasons. Receiver frames go through the real CRSF receiver and the Flight's receiver task; time is
injected. Portable."""

from configfakes import FakeBoard

from hoverfly.core.command.commander import SOURCE_FAILSAFE
from hoverfly.core.events import (
    DISARM_FS_SWITCH,
    EV_ARMING_BLOCKED,
    EV_DISARMED,
    EV_FAILSAFE_STAGE1,
    EV_FAILSAFE_STAGE2,
)
from hoverfly.core.flight import Flight
from hoverfly.core.safety.arming import BATTERY_CRITICAL, BIT_FAILED, BOXFAILSAFE, CLI
from hoverfly.core.safety.failsafe import IDLE, STAGE1, STAGE2
from hoverfly.core.stages.control import MODE_ANGLE
from hoverfly.protocols.crsf import encode_rc_frame


class RxBoard(FakeBoard):
    """configfakes' board with a receiver UART (queued CRSF bytes), a live IMU and a battery."""

    def __init__(self):
        super().__init__()
        self.wire = bytearray()
        self.k = 0
        self.battery_v = 0.0

    def read_imu(self, gyro_rad_s, accel_m_s2):
        self.k += 1  # never the same sample twice in a row (a frozen IMU blocks arming)
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

    def read_battery(self, signals):
        signals.battery_v = self.battery_v


def _channels(arm_us, throttle_us, fs_us=1000):
    ch = [1500] * 16
    ch[2] = throttle_us  # AETR: throttle on channel 3
    ch[4] = arm_us  # AUX1: the arm switch
    ch[7] = fs_us  # AUX4: the failsafe switch, where fs_switch_ch = 8
    return ch


def _flight(**params):
    board = RxBoard()
    f = Flight(board)
    f.params.set("gyro_cal_ms", 100)
    f.params.set("boot_grace_ms", 0)
    for name in params:
        f.params.set(name, params[name])
    f.start(1000)
    return board, f


def _fly(board, f, t, passes, arm_us, throttle_us, fs_us=1000, frames=True):
    for k in range(passes):
        if frames and k % 4 == 0:
            board.wire.extend(encode_rc_frame(_channels(arm_us, throttle_us, fs_us)))
        t += 1000
        board.t_us = t
        f.step(t)
    return t


def _armed_in_flight(**params):
    board, f = _flight(**params)
    t = _fly(board, f, 1000, 400, 1000, 1000)  # calibrated, switch off, throttle low
    t = _fly(board, f, t, 40, 2000, 1000)
    assert f.arming.armed
    t = _fly(board, f, t, 100, 2000, 1500)  # throttle up: flying
    return board, f, t


def _events(f, kind):
    out = []
    f.events.drain(0, lambda t, e, d: out.append(t) if e == kind else None)
    return out


def test_a_lost_link_runs_the_failsafe_stages_from_the_last_frame_and_the_commander_flies_them():
    board, f, t = _armed_in_flight(rx_timeout_ms=100, fs_delay_ms=400, fs_procedure="land")
    last = f.last_frame_us
    t = _fly(board, f, t, 250, 2000, 1500, frames=False)  # 250 ms with no frame
    assert f.failsafe.state == STAGE1 and f.commander.source == SOURCE_FAILSAFE
    assert f.signals.setpoint.mode == MODE_ANGLE and f.signals.setpoint.stick_norm[0] == 0.0
    stage1 = _events(f, EV_FAILSAFE_STAGE1)
    assert len(stage1) == 1 and 100000 < stage1[0] - last <= 110000  # rx_timeout_ms, seen by the 100 Hz task
    t = _fly(board, f, t, 400, 2000, 1500, frames=False)
    stage2 = _events(f, EV_FAILSAFE_STAGE2)
    assert f.failsafe.state == STAGE2 and len(stage2) == 1
    assert 500000 <= stage2[0] - last <= 510000  # rx_timeout_ms + fs_delay_ms after the last frame
    # the link back and the sticks moved: the pilot has it again
    t = _fly(board, f, t, 40, 2000, 1500)
    board.wire.extend(encode_rc_frame([1900] + _channels(2000, 1500)[1:]))
    t = _fly(board, f, t, 20, 2000, 1500, frames=False)
    assert f.failsafe.state == IDLE and f.commander.source == 0


def test_the_failsafe_switch_in_kill_mode_disarms_on_its_frame_and_blocks_arming_while_on():
    board, f, t = _armed_in_flight(fs_switch_ch=8, fs_switch_mode="kill")
    board.wire.extend(encode_rc_frame(_channels(2000, 1500, 2000)))
    for _ in range(4):  # no 100 Hz task in between: the receiver task disarms on this frame
        t += 1000
        f.task_rx(t)
    assert not f.arming.armed and f.arming.flags & (1 << BOXFAILSAFE)
    seen = []
    f.events.drain(0, lambda tt, e, d: seen.append(d) if e == EV_DISARMED else None)
    assert seen == [DISARM_FS_SWITCH]
    t = _fly(board, f, t, 100, 1000, 1000, 2000)  # switch still on, arm switch off and on again
    t = _fly(board, f, t, 40, 2000, 1000, 2000)
    assert not f.arming.armed and f.arming.flags & (1 << BOXFAILSAFE)


def test_the_battery_is_counted_in_cells_at_its_first_reading_and_blocks_arming_below_vbat_min_cell():
    board, f = _flight(vbat_min_cell=3.5)
    board.battery_v = 16.6  # a full 4S
    t = _fly(board, f, 1000, 400, 1000, 1000)
    assert f.supervisor.battery_cells == 4 and f.arming.flags & (1 << BATTERY_CRITICAL) == 0
    board.battery_v = 13.6  # 3.4 V a cell
    t = _fly(board, f, t, 100, 1000, 1000)
    assert f.supervisor.battery_cells == 4 and f.arming.flags & (1 << BATTERY_CRITICAL)
    t = _fly(board, f, t, 40, 2000, 1000)
    assert not f.arming.armed


def test_an_arm_switch_raised_during_a_configuration_session_must_be_toggled_after_it_closes():
    board, f = _flight()
    t = _fly(board, f, 1000, 400, 1000, 1000)  # ready, the switch off
    f.config_session = 1  # a CLI session
    t = _fly(board, f, t, 40, 2000, 1000)  # the switch on meanwhile
    assert not f.arming.armed and f.arming.flags & (1 << CLI)
    f.config_session = 0
    t = _fly(board, f, t, 40, 2000, 1000)  # closed, the switch still on: not armed
    assert not f.arming.armed
    t = _fly(board, f, t, 40, 1000, 1000)
    t = _fly(board, f, t, 40, 2000, 1000)
    assert f.arming.armed  # seen off and on again


def _blocked(f):
    out = []
    f.events.drain(0, lambda t, e, d: out.append(d) if e == EV_ARMING_BLOCKED else None)
    return out


def test_an_arming_task_that_raised_blocks_arming_with_bit_until_it_runs_through():
    board, f = _flight()
    t = _fly(board, f, 1000, 400, 1000, 1000)
    task = [k for k in f.scheduler.tasks if k.name == "arming"][0]
    f.supervisor.task_failed(task, ValueError("injected"))
    assert f.arming.flags & (1 << BIT_FAILED)
    board.wire.extend(encode_rc_frame(_channels(2000, 1000)))
    t += 4000
    f.task_rx(t)  # the switch's rising edge, before the task has run again
    assert not f.arming.armed and _blocked(f) == [BIT_FAILED]
    t = _fly(board, f, t, 40, 1000, 1000)  # the task runs through; the switch seen off
    t = _fly(board, f, t, 40, 2000, 1000)
    assert f.arming.armed
