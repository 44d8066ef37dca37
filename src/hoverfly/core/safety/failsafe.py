"""Receiver failsafe, staged (seed 002: hold at 100 ms, act at 500 ms), and the fault watch.

`Failsafe` takes the link state (`rx_ok`, `last_frame_us`) and the armed state once per
slow-task pass and gives the stage the commander obeys. The link counts as lost
`rx_timeout_ms` after its last valid frame (default 100 ms). Stage 1 holds the last throttle
with the sticks centred in angle mode (levelled) until `rx_timeout_ms + fs_delay_ms` after
the last valid frame (default 500 ms, seed 002's RC failsafe); stage 2 runs `fs_procedure`:
- drop: disarm;
- land: level, descend at `fs_land_m_s` (a vertical-speed loop on the accelerometer around
  the hover throttle learnt while flying; `fs_throttle` until one is known), disarm on
  touchdown (an acceleration spike, latched every pass so a 1 ms spike is not missed) or
  after `fs_land_max_ms`;
- glide (a plane, seed 002's stabilised glide): wings level at `fs_glide_pitch` (a few degrees nose
  down: the trainer and the wing glide near their best glide speed there, well above the stall), motor
  off, in ANGLE with the integrator on, to the ground and on it: the plane stays armed until the pilot
  disarms (INAV's glide). Only a plane glides: a multirotor with `fs_procedure` glide lands instead (the
  parameter check refuses glide on a multirotor; an old stored value still lands it), and a plane set to
  land glides (it cannot hover down).
A link that comes back ends stage 1 at once but not stage 2: the pilot must disarm, or move
the sticks out of centre, to take over (as Betaflight).
The failsafe switch (Betaflight's FAILSAFE box, `fs_switch_mode`) runs the same stages:
Flight drops frames taken with it on, so stage1 mode is a lost receiver to the letter;
stage2 mode also passes `skip_stage1`; kill mode disarms in Flight and never gets here.
The cause (no frames, or the switch) is the detail of the rx_lost and stage-1 events.

`FaultWatch` looks at the IMU and the loop every slow pass and names what is wrong: a frozen
IMU (new samples that repeat bit for bit), a saturated one, a crash on the ground (armed,
tipped over, still, throttle low), a loop-rate collapse (overrun storm). Flight disarms on
each of them.
"""

from array import array

from hoverfly.compat import IS_MICROPYTHON, const, ticks_diff
from hoverfly.core.events import (
    DISARM_FAILSAFE,
    DISARM_LANDED,
    EV_FAILSAFE_END,
    EV_FAILSAFE_STAGE1,
    EV_FAILSAFE_STAGE2,
    EV_LANDED,
)
from hoverfly.core.stages.mixer import is_plane

IDLE = const(0)
STAGE1 = const(1)
STAGE2 = const(2)
STAGE_NAMES = ("idle", "stage1", "stage2")

PROC_DROP = const(0)
PROC_LAND = const(1)
PROC_GLIDE = const(2)
PROCEDURES = ("drop", "land", "glide")

# Why the link counts as lost: detail of EV_RX_LOST and EV_FAILSAFE_STAGE1.
CAUSE_NO_FRAMES = const(0)
CAUSE_SWITCH = const(1)
CAUSES = ("no_frames", "fs_switch")

# fs_switch_mode (params.FS_SWITCH_MODES order)
SWITCH_STAGE1 = const(0)
SWITCH_STAGE2 = const(1)
SWITCH_KILL = const(2)

_G_M_S2 = 9.80665
# Landed: the landing throttle well below the hover throttle (so in the air the craft would be accelerating
# down at a metre per second squared or more), yet it neither accelerates down nor descends: the ground holds it.
# Held for _GROUND_S, or _IMPACT_GROUND_S after an impact (an acceleration spike above 2.5 g). A spike alone is
# no landing: rotor vibration reaches it in the air (11 of 200 rx-loss flights disarmed metres up on it).
# An impact also sets the descent estimate to 0: the accelerometer clips the touchdown's deceleration (100 g for a
# millisecond), so the estimate would go on saying 1 m/s and ask for the hover throttle on the ground. If the
# craft then accelerates down, it was in the air: the estimate gets back what it had.
_GROUND_THR = 0.9  # landing throttle below this share of the hover throttle
_GROUND_A_M_S2 = 0.7  # |vertical acceleration| below this (low-passed, _GROUND_TAU_S)
_GROUND_TAU_S = 0.1
_GROUND_SPEED_M_S = 0.5  # estimated descent below this
_GROUND_S = 0.5
_IMPACT_GROUND_S = 0.25
_TOUCHDOWN_M_S2 = 24.5
_TOUCHDOWN_SQ = _TOUCHDOWN_M_S2 * _TOUCHDOWN_M_S2
# No touchdown in the first 200 ms of stage 2: the throttle cut itself jolts the frame.
_TOUCHDOWN_ARM_US = 200000
# The hover throttle is learnt with this time constant while flying.
_LEARN_TAU_S = 2.0
# Landing speed loop: throttle per m/s of speed error, and the throttle window around the
# hover throttle it may use (it never asks for more than 1.3 x hover: a landing never climbs).
_LAND_KV = 0.08
# Leak of the vertical speed estimate while the pilot flies (s).
_SPEED_LEAK_S = 3.0
_LAND_MIN = 0.5
_LAND_MAX = 1.3


class Failsafe:
    def __init__(self, events):
        self.events = events
        self.state = IDLE
        self.stage_since_us = 0
        self.procedure = PROC_LAND
        self.rx_timeout_us = 100000
        self.delay_us = 400000
        self.land_max_us = 20000000
        self.throttle_norm = 0.3  # fs_throttle: the landing throttle until a hover throttle is known
        self.land_m_s = 1.0
        # learnt while flying (observe), used while landing
        self.hover_norm = 0.0  # 0 = not known yet
        self.speed_down_m_s = 0.0
        self.land_throttle_norm = 0.3
        self._peak_sq = 0.0
        self._impact = False  # a spike above _TOUCHDOWN_M_S2 seen in stage 2
        self._speed_before_impact_m_s = 0.0
        # note_accel's sum and count of the passes since the last observe: observe integrates their mean, since a
        # touchdown's deceleration lasts a few milliseconds and one sample in ten would miss it
        self._acc_sum = array("f", (0.0, 0.0, 0.0))
        self._acc_n = 0
        self._a_down_f = 0.0  # the vertical acceleration, low-passed, while the failsafe runs
        self._ground_s = 0.0  # how long the ground has held the craft (see _GROUND_THR)
        self._learn_dt_s = -1.0  # observe: the dt of a call whose learning waits for the next (-1.0: none)
        self.commander = None  # told at each change of stage who flies (Commander.failsafe_flies), when wired

    def configure(self, params):
        self.procedure = PROCEDURES.index(params.get("fs_procedure"))
        plane = is_plane(params.get("mixer_type"))
        if self.procedure == PROC_GLIDE and not plane:
            self.procedure = PROC_LAND  # SAFETY: a multirotor cannot glide: a level drop would crash it
        elif self.procedure == PROC_LAND and plane:
            self.procedure = PROC_GLIDE  # SAFETY: a plane cannot hover down: its landing is the glide
        self.rx_timeout_us = params.get("rx_timeout_ms") * 1000
        self.delay_us = params.get("fs_delay_ms") * 1000
        self.land_max_us = params.get("fs_land_max_ms") * 1000
        self.throttle_norm = (params.get("fs_throttle") - 1000) * 0.001
        self.land_m_s = params.get("fs_land_m_s")

    def active(self):
        return self.state != IDLE

    def note_accel(self, accel_m_s2):
        """Every pass while landing: keep the largest acceleration since the last slow pass."""
        a0 = accel_m_s2[0]
        a1 = accel_m_s2[1]
        a2 = accel_m_s2[2]
        sq = a0 * a0 + a1 * a1 + a2 * a2
        if sq > self._peak_sq:
            self._peak_sq = sq
        s = self._acc_sum
        s[0] += a0
        s[1] += a1
        s[2] += a2
        self._acc_n += 1

    def observe(self, dt_s, q, accel_m_s2, throttle_norm, cos_tilt, flying):
        """Slow task: learn the hover throttle while the pilot flies; while the failsafe runs,
        integrate the vertical speed from the accelerometer and set the landing throttle.

        The learning while the pilot flies runs on every other call (50 Hz from the 100 Hz task), over
        both calls' time: its time constants are seconds (_LEARN_TAU_S, _SPEED_LEAK_S), and each update
        makes some thirty float objects on MicroPython. While the failsafe runs, every call counts."""
        if self.state == IDLE:
            if not flying:
                self.speed_down_m_s = 0.0
                self._learn_dt_s = -1.0
                return
            held = self._learn_dt_s
            if held < 0.0:
                self._learn_dt_s = dt_s
                return
            self._learn_dt_s = -1.0
            dt_s += held
        # specific force to NED down: third row of the body->NED rotation, plus gravity. The row's
        # last term, 1 - 2 (x² + y²), is cos_tilt (Attitude keeps it): six float objects a call fewer
        # on MicroPython.
        w = q[0]
        x = q[1]
        y = q[2]
        z = q[3]
        n = self._acc_n
        if n:  # landing: the mean over every pass since the last call
            s = self._acc_sum
            a0 = s[0] / n
            a1 = s[1] / n
            a2 = s[2] / n
            s[0] = 0.0
            s[1] = 0.0
            s[2] = 0.0
            self._acc_n = 0
        else:
            a0 = accel_m_s2[0]
            a1 = accel_m_s2[1]
            a2 = accel_m_s2[2]
        a_down = 2.0 * ((x * z - w * y) * a0 + (y * z + w * x) * a1) + cos_tilt * a2 + _G_M_S2
        if self.state == IDLE:  # flying (see above)
            # While the pilot flies the speed estimate leaks back to zero (a craft flown by hand
            # does not keep one vertical speed for long), so stage 1 starts from the speed the
            # craft really had, not from zero, and accelerometer bias cannot pile up.
            v = self.speed_down_m_s + a_down * dt_s
            self.speed_down_m_s = v - v * dt_s / _SPEED_LEAK_S
            if cos_tilt > 0.5:
                k = dt_s / _LEARN_TAU_S
                if k > 1.0:
                    k = 1.0
                thr = throttle_norm * cos_tilt
                if self.hover_norm <= 0.0:
                    self.hover_norm = thr
                else:
                    self.hover_norm += k * (thr - self.hover_norm)
            return
        # No bias correction: a calibrated accelerometer's ~0.03 m/s² is 0.3 m/s after 10 s, and a
        # bias learnt in flight would learn the pilot's climbs and descents too.
        self.speed_down_m_s += a_down * dt_s
        f = self._a_down_f + (a_down - self._a_down_f) * (dt_s / (_GROUND_TAU_S + dt_s))
        self._a_down_f = f
        hover = self.hover_norm
        c = cos_tilt if cos_tilt > 0.7 else 0.7
        if hover <= 0.0:
            self.land_throttle_norm = self.throttle_norm
        else:
            thr = hover / c + _LAND_KV * (self.speed_down_m_s - self.land_m_s)
            lo = _LAND_MIN * hover
            hi = _LAND_MAX * hover
            self.land_throttle_norm = lo if thr < lo else (hi if thr > hi else thr)
        if self._impact and f > _GROUND_A_M_S2:  # accelerating down after the "impact": still in the air
            self._impact = False
            self.speed_down_m_s += self._speed_before_impact_m_s
        # (with no hover throttle learnt, the thrust test is skipped and update wants an impact as well)
        if (self.state == STAGE2 and (hover <= 0.0 or self.land_throttle_norm < _GROUND_THR * hover / c)
                and -_GROUND_A_M_S2 < f < _GROUND_A_M_S2 and self.speed_down_m_s < _GROUND_SPEED_M_S):
            self._ground_s += dt_s
        else:
            self._ground_s = 0.0

    def update(self, now_us, link_lost, last_frame_us, armed, sticks_moved, arming, cause=CAUSE_NO_FRAMES,
               skip_stage1=False):
        """Slow task: advance the stages. Stage times count from the last valid frame. `cause`
        names why the link is lost (stage-1 event detail); `skip_stage1` goes straight on to
        stage 2 (the failsafe switch in stage2 mode)."""
        if not armed:
            if self.state != IDLE:
                self._stage(now_us, IDLE, EV_FAILSAFE_END, 0)
            self._peak_sq = 0.0
            return
        if self.state == IDLE:
            if link_lost:
                self.stage_since_us = last_frame_us
                self._stage(now_us, STAGE1, EV_FAILSAFE_STAGE1, cause)
        if self.state == STAGE1:
            if not link_lost:
                self._stage(now_us, IDLE, EV_FAILSAFE_END, 0)
            elif skip_stage1 or ticks_diff(now_us, self.stage_since_us) >= self.rx_timeout_us + self.delay_us:
                self.stage_since_us = now_us
                self._peak_sq = 0.0
                self._impact = False
                self._ground_s = 0.0
                self._a_down_f = 0.0
                self._acc_n = 0
                self._acc_sum[0] = 0.0
                self._acc_sum[1] = 0.0
                self._acc_sum[2] = 0.0
                self._stage(now_us, STAGE2, EV_FAILSAFE_STAGE2, self.procedure)
                if self.procedure == PROC_DROP:
                    arming.disarm(now_us, DISARM_FAILSAFE)
                    return
        if self.state == STAGE2:
            if not link_lost and sticks_moved:
                self._stage(now_us, IDLE, EV_FAILSAFE_END, 1)
                return
            if self.procedure == PROC_LAND:
                since = ticks_diff(now_us, self.stage_since_us)
                if self._peak_sq > _TOUCHDOWN_SQ and since > _TOUCHDOWN_ARM_US and not self._impact:
                    self._impact = True
                    self._speed_before_impact_m_s = self.speed_down_m_s
                    self.speed_down_m_s = 0.0
                    self._ground_s = 0.0
                self._peak_sq = 0.0
                held = self._ground_s
                if self._impact:
                    landed = held >= _IMPACT_GROUND_S
                else:
                    landed = held >= _GROUND_S and self.hover_norm > 0.0
                landed = landed and since > _TOUCHDOWN_ARM_US
                if landed:
                    self.events.record(now_us, EV_LANDED, 0)
                if landed or since >= self.land_max_us:
                    arming.disarm(now_us, DISARM_LANDED if landed else DISARM_FAILSAFE)

    def _stage(self, now_us, state, event, detail):
        """A change of stage: its event, and who flies (SAFETY: the commander flies the failsafe's set
        point from the next pass, exactly while a stage runs)."""
        self.state = state
        self.events.record(now_us, event, detail)
        if self.commander is not None:
            self.commander.failsafe_flies(state != IDLE)


# FaultWatch verdicts (what Flight disarms for).
FAULT_NONE = const(0)
FAULT_IMU_FROZEN = const(1)
FAULT_IMU_SATURATED = const(2)
FAULT_CRASH = const(3)
FAULT_LOAD = const(4)
FAULT_IMU_NONFINITE = const(5)  # a NaN or an infinity: never a measurement, a fault from the first check
FAULT_NAMES = ("none", "imu_frozen", "imu_saturated", "crash", "load", "imu_nonfinite")

# A gyro reading this close to full scale counts as saturated (2000 °/s parts, the common range).
_GYRO_SAT_RAD_S = 34.0
# Accelerometer: 16 g parts clip at 157 m/s².
_ACCEL_SAT_M_S2 = 150.0
# The negative bounds as constants of their own: `g < -_GYRO_SAT_RAD_S` makes a float object at every
# comparison on MicroPython (check_imu's six a call were most of what the 100 Hz task allocated).
_GYRO_SAT_NEG = -_GYRO_SAT_RAD_S
_ACCEL_SAT_NEG = -_ACCEL_SAT_M_S2
_INF = float("inf")
_NEG_INF = float("-inf")
# Consecutive slow passes (100 Hz: 100 ms) of identical or saturated samples before a fault.
_IMU_BAD_CHECKS = const(10)
# imu_faults' counts (FaultWatch._imu_st) stop here: a small int on every port, far past _IMU_BAD_CHECKS.
_IMU_COUNT_MAX = const(0x100000)
IMU_SAME = const(0)  # checks in a row with six values equal to the last check's
IMU_SAT = const(1)  # checks in a row with a value past its limit
# Crash: tipped beyond 60°, turning slower than 30 °/s, reading 1 g ± 3 m/s² (resting, not falling).
_CRASH_COS = 0.5
_CRASH_RATE_SQ = 0.5236 * 0.5236
_CRASH_G_LO_SQ = (_G_M_S2 - 3.0) * (_G_M_S2 - 3.0)
_CRASH_G_HI_SQ = (_G_M_S2 + 3.0) * (_G_M_S2 + 3.0)
# Loop: below this share of loop_hz over a 100 ms window counts as overloaded; a storm is
# 500 ms of it while armed.
_LOAD_RATE_PCT = 80
_STORM_US = 500000


# fastpass: FaultWatch.check_imu st:i@ last:f@ graw:f@ araw:f@
def imu_faults(st, last, graw, araw):
    """check_imu's verdict on one sample (graw rad/s, araw m/s², float32 arrays of three) against the last
    one (last: six float32): not finite (a NaN or an infinity, at once), frozen (six values equal to the
    last check's for _IMU_BAD_CHECKS checks) or saturated (a value past its limit as long; an infinity is
    past it). st[IMU_SAME], st[IMU_SAT]: the counts, stopping at _IMU_COUNT_MAX. The viper twin
    (accel/faults.py) is generated from it: on MicroPython it reads the floats as their bits, no float
    object made."""
    same = 1
    sat = 0
    bad = 0
    for i in range(3):
        g = graw[i]
        a = araw[i]
        g_last = last[i]
        a_last = last[3 + i]
        if g != g_last or a != a_last:
            same = 0
        last[i] = g
        last[3 + i] = a
        if g > _GYRO_SAT_RAD_S or g < _GYRO_SAT_NEG or a > _ACCEL_SAT_M_S2 or a < _ACCEL_SAT_NEG:
            sat = 1
        if not (_NEG_INF < g < _INF and _NEG_INF < a < _INF):
            bad = 1
    n_same = st[IMU_SAME] + 1 if same else 0
    if n_same > _IMU_COUNT_MAX:
        n_same = _IMU_COUNT_MAX
    st[IMU_SAME] = n_same
    n_sat = st[IMU_SAT] + 1 if sat else 0
    if n_sat > _IMU_COUNT_MAX:
        n_sat = _IMU_COUNT_MAX
    st[IMU_SAT] = n_sat
    if bad:
        return FAULT_IMU_NONFINITE
    if n_same >= _IMU_BAD_CHECKS:
        return FAULT_IMU_FROZEN
    if n_sat >= _IMU_BAD_CHECKS:
        return FAULT_IMU_SATURATED
    return FAULT_NONE


class FaultWatch:
    def __init__(self):
        self.crash_us = 1000000  # crash_time_ms; 0 = off
        self._imu_last = array("f", [0.0] * 6)  # the last check's six values
        self._imu_st = array("i", [0, 0])  # imu_faults' counts: IMU_SAME, IMU_SAT
        self.imu_fault = FAULT_NONE
        self.fault_before = FAULT_NONE  # the flight's IMU verdict at its last check (Supervisor.task)
        self.crash_since_us = None
        self.overloaded = False
        self.storm_since_us = None
        self._win_started = False
        self._win_us = 0
        self._win_passes = 0
        self._win_overruns = 0
        self._period_us = 1000

    def configure(self, params):
        self.crash_us = params.get("crash_time_ms") * 1000
        self._period_us = 1000000 // params.get("loop_hz")

    def reset_imu(self):
        self._imu_st[IMU_SAME] = 0
        self._imu_st[IMU_SAT] = 0
        self.imu_fault = FAULT_NONE

    def check_imu(self, gyro_raw_rad_s, accel_raw_m_s2):
        """Slow pass with a fresh sample (float32 arrays): imu_faults' verdict, kept in imu_fault. On
        MicroPython the viper twin generated from imu_faults (accel/faults.py `check_imu`) stands in for this
        method; `check_imu_python` keeps it."""
        fault = imu_faults(self._imu_st, self._imu_last, gyro_raw_rad_s, accel_raw_m_s2)
        self.imu_fault = fault
        return fault

    def _lying_still(self, gyro_rad_s, accel_m_s2):
        """Not turning, and about 1 g: what a craft lying where it fell reads."""
        g0 = gyro_rad_s[0]
        g1 = gyro_rad_s[1]
        g2 = gyro_rad_s[2]
        a0 = accel_m_s2[0]
        a1 = accel_m_s2[1]
        a2 = accel_m_s2[2]
        a_sq = a0 * a0 + a1 * a1 + a2 * a2
        return g0 * g0 + g1 * g1 + g2 * g2 <= _CRASH_RATE_SQ and _CRASH_G_LO_SQ <= a_sq <= _CRASH_G_HI_SQ

    def check_crash(self, now_us, armed, throttle_low, cos_tilt, gyro_rad_s, accel_m_s2):
        """True once the craft has lain tipped over, still, armed with the throttle low for crash_time_ms."""
        # (The stillness test is a method of its own: this frame stays within 11 words, on the C stack on
        # MicroPython, at every call.)
        if (not armed or self.crash_us <= 0 or not throttle_low or cos_tilt > _CRASH_COS
                or not self._lying_still(gyro_rad_s, accel_m_s2)):
            self.crash_since_us = None
            return False
        if self.crash_since_us is None:
            self.crash_since_us = now_us
            return False
        return ticks_diff(now_us, self.crash_since_us) >= self.crash_us

    def _load_window(self, now_us, passes, overruns):
        """check_load's ~100 ms window closed: the loop's rate and overruns over it. (A method of its own:
        check_load's frame stays within 11 words, on the C stack on MicroPython, at every call.)"""
        done = (passes - self._win_passes) & 0x3FFFFFFF  # the scheduler's count wraps there
        expected = ticks_diff(now_us, self._win_us) // self._period_us
        over = overruns - self._win_overruns
        self.overloaded = done * 100 < expected * _LOAD_RATE_PCT or over * 2 > done
        self._win_us = now_us
        self._win_passes = passes
        self._win_overruns = overruns

    def check_load(self, now_us, passes, overruns, armed):
        """Loop rate over ~100 ms windows; returns True on an overrun storm while armed."""
        if not self._win_started:
            self._win_started = True
            self._win_us = now_us
            self._win_passes = passes
            self._win_overruns = overruns
            return False
        if ticks_diff(now_us, self._win_us) >= 100000:
            self._load_window(now_us, passes, overruns)
        if not (armed and self.overloaded):
            self.storm_since_us = None
            return False
        if self.storm_since_us is None:
            self.storm_since_us = now_us
            return False
        return ticks_diff(now_us, self.storm_since_us) >= _STORM_US


check_imu_python = FaultWatch.check_imu
_viper = None
if IS_MICROPYTHON:
    try:  # generated from imu_faults above by hoverfly.fastgen; absent, or a port without viper: the Python runs
        from hoverfly.accel import faults as _viper
    except (ImportError, SyntaxError, NameError, ValueError, TypeError):  # TypeError: ViperTypeError
        pass
if _viper is not None:
    FaultWatch.check_imu = _viper.check_imu
