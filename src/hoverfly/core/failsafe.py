"""Receiver failsafe, staged (seed 002: hold at 100 ms, act at 500 ms).

The link counts as lost `rx_timeout_ms` after its last valid frame. Stage 1 holds the
last sticks, levelled when the craft flies in angle mode, for `fs_delay_ms`;
stage 2 runs `fs_procedure`: drop (disarm), land (level, descend at
`fs_throttle`, disarm on touchdown or after `fs_land_max_ms`) or glide (level,
throttle off: fixed wing). A link that comes back ends stage 1 at once but not stage 2:
the pilot must disarm, or move the sticks out of centre, to take over (as Betaflight).
"""

from hoverfly.compat import const, ticks_diff
from hoverfly.core.events import (
    DISARM_FAILSAFE,
    DISARM_LANDED,
    EV_FAILSAFE_END,
    EV_FAILSAFE_STAGE1,
    EV_FAILSAFE_STAGE2,
    EV_LANDED,
)

IDLE = const(0)
STAGE1 = const(1)
STAGE2 = const(2)

PROC_DROP = const(0)
PROC_LAND = const(1)
PROC_GLIDE = const(2)
PROCEDURES = ("drop", "land", "glide")

# Touchdown: an acceleration spike above this while landing (m/s²; 2.5 g).
_TOUCHDOWN_M_S2 = 24.5


class Failsafe:
    def __init__(self, events):
        self.events = events
        self.state = IDLE
        self.stage_since_us = 0
        self.procedure = PROC_LAND
        self.delay_us = 400000
        self.land_max_us = 20000000
        self.throttle_norm = 0.3

    def configure(self, params):
        self.procedure = PROCEDURES.index(params.get("fs_procedure"))
        self.delay_us = params.get("fs_delay_ms") * 1000
        self.land_max_us = params.get("fs_land_max_ms") * 1000
        self.throttle_norm = (params.get("fs_throttle") - 1000) * 0.001

    @property
    def active(self):
        return self.state != IDLE

    def update(self, now_us, link_lost, last_frame_us, armed, sticks_moved, accel_norm_m_s2, arming):
        """Slow task: advance the stages. Stage times count from the last valid frame."""
        if not armed:
            if self.state != IDLE:
                self.state = IDLE
                self.events.record(now_us, EV_FAILSAFE_END, 0)
            return
        if self.state == IDLE:
            if link_lost:
                self.state = STAGE1
                self.stage_since_us = last_frame_us
                self.events.record(now_us, EV_FAILSAFE_STAGE1, 0)
        if self.state == STAGE1:
            if not link_lost:
                self.state = IDLE
                self.events.record(now_us, EV_FAILSAFE_END, 0)
            elif ticks_diff(now_us, self.stage_since_us) >= self.delay_us:
                self.state = STAGE2
                self.stage_since_us = now_us
                self.events.record(now_us, EV_FAILSAFE_STAGE2, self.procedure)
                if self.procedure == PROC_DROP:
                    arming.disarm(now_us, DISARM_FAILSAFE)
                    return
        if self.state == STAGE2:
            if not link_lost and sticks_moved:
                self.state = IDLE
                self.events.record(now_us, EV_FAILSAFE_END, 1)
                return
            if self.procedure == PROC_LAND:
                landed = accel_norm_m_s2 > _TOUCHDOWN_M_S2 and ticks_diff(now_us, self.stage_since_us) > 200000
                if landed:
                    self.events.record(now_us, EV_LANDED, 0)
                if landed or ticks_diff(now_us, self.stage_since_us) >= self.land_max_us:
                    arming.disarm(now_us, DISARM_LANDED if landed else DISARM_FAILSAFE)
