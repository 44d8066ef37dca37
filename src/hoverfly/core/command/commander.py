"""The commander: who flies, and with what set point. Stage 3 of the pass, after the pilot's input.

Takes the set point RcInput made from the pilot's sticks and passes it on as it is, or as the failsafe or
the autopilot (seed 004's MSP companion) make it; gives the flight mode the controller runs and whether
its I-term and air mode may act (`i_active`, `airmode_active`).

Who flies is one word, `source`: 0 while the pilot's sticks are all there is (the usual pass), else a bit
for each source that has taken the set point over. Each bit is written by the code that starts and ends
that source's say, at that moment, so the pass reads one int and no caller has to remember to bring a
summary up to date:
- SOURCE_FAILSAFE: Failsafe.update, at each change of stage (`failsafe_flies`);
- SOURCE_AUTOPILOT: this commander, after each autopilot call that can enable or silence it, or hold or
  release its throttle latch (`pilot_frame`, `task`, `update`): in a flight nothing else drives the
  autopilot's procedure (`Flight.on_msp_rc` takes its frames, which never change either).
- SOURCE_LAUNCH: a plane's hand launch (core/command/launch.py), from the arming to the pilot's sticks or
  its timeout; the commander's `task` follows it.
The failsafe outranks the launch and the autopilot. One more source, the bench motor test, owns the motor
outputs rather than the set point (disarmed only): Flight._outputs gives it its word after the mixer, and
`flier()` names it for the MSP status.

A plane (`is_plane(mixer_type)`) has a MANUAL mode besides ANGLE, HORIZON and ACRO: its switch
(`manual_ch` range) outranks the others, read once per frame (`pilot_frame`). While the failsafe glides
or a launch climbs, the plane's controller holds a pitch of their choosing (`FwController.pitch_offset_rad`,
set here at each change of who flies, never in the pass).
"""

from hoverfly.compat import const
from hoverfly.core.command.autopilot import AP_ENABLED
from hoverfly.core.events import EV_AIRMODE, EV_MODE
from hoverfly.core.safety.failsafe import PROC_DROP, PROC_GLIDE, PROC_LAND, STAGE2
from hoverfly.core.stages.control import MODE_ANGLE, MODE_MANUAL
from hoverfly.core.stages.mixer import is_plane
from hoverfly.core.stages.rc import aux_channel

SOURCE_FAILSAFE = const(1)  # the failsafe flies (stage 1 or 2)
SOURCE_AUTOPILOT = const(2)  # the autopilot is enabled, or holds the pilot's throttle at its latch
SOURCE_LAUNCH = const(4)  # a plane's hand launch: from arming until the pilot's sticks or its timeout

# flier(): who flies, as MSP2_HOVERFLY_AUTOPILOT reports it (protocols/msp.py FLIER_NAMES)
FLIER_NOBODY = const(0)
FLIER_PILOT = const(1)
FLIER_AUTOPILOT = const(2)
FLIER_FAILSAFE = const(3)
FLIER_MOTOR_TEST = const(4)


class Commander:
    def __init__(self, events, rc, arming, failsafe, autopilot, controller, accel_raw_m_s2):
        self.events = events
        self.rc = rc
        self.arming = arming
        self.failsafe = failsafe
        self.autopilot = autopilot
        self.controller = controller  # its I-terms are held at zero on the ground (_i_airmode)
        self._accel_raw_m_s2 = accel_raw_m_s2  # the failsafe's touchdown watch reads it while landing
        self.source = 0
        self.mode = -1  # the flight mode of the last pass (-1: none yet, so the first pass records it)
        self.i_active = False
        self.airmode_active = False
        self.airmode_enabled = True  # the airmode parameter, or the AIRMODE switch when airmode_ch is set
        self.throttle_was_up = False  # the throttle has been raised past airmode_thr_pct since arming
        self._airmode_thr = 0.25
        # a plane's parts (Flight.plane_parts): its controller, the launch, and what the launch reads
        self.plane = False
        self.fw = None
        self.launch = None
        self._attitude = None
        self._accel_m_s2 = None
        self._channels_us = None
        self._manual = (0, 1700, 2100)  # the MANUAL switch: channel (1-based, 0 = none), range
        self._glide_pitch_rad = 0.0
        self._was_armed = False

    def plane_parts(self, fw, launch, attitude, accel_m_s2, channels_us):
        """A plane's controller (its pitch target) and hand launch, the attitude and filtered accelerometer
        the launch reads, and the pilot's frame the MANUAL switch is read from (Flight wires them once)."""
        self._channels_us = channels_us
        self.fw = fw
        self.launch = launch
        self._attitude = attitude
        self._accel_m_s2 = accel_m_s2

    def configure(self, params, airmode_param):
        """airmode_param: the mixer's airmode setting, what air mode follows with no AIRMODE channel set."""
        self.autopilot.configure(params)
        self._airmode_thr = params.get("airmode_thr_pct") * 0.01
        rc = self.rc
        # With no AIRMODE channel only this changes airmode_enabled; with one, each frame does (pilot_frame).
        self.airmode_enabled = rc.airmode_switch if rc.airmode_box else airmode_param
        self.plane = is_plane(params.get("mixer_type"))
        self._glide_pitch_rad = params.get("fs_glide_pitch") * 0.017453292519943295
        ch = aux_channel(rc.map_ch, params.get("manual_ch"))  # AUX1..4 where rc_map puts them
        on = self.plane and self._channels_us is not None
        self._manual = (ch if on else 0, params.get("manual_min_us"), params.get("manual_max_us"))
        if self.launch is not None:
            self.launch.configure(params, self.plane)
            if not self.launch.active():
                self.source &= ~SOURCE_LAUNCH
        self._fw_pitch()

    # ------------------------------------------------------------------ the pass
    def update(self, sp, now_us):
        """Stage 3: sp arrives holding the pilot's smoothed sticks and leaves holding the set point of
        whoever flies, with its mode."""
        if self.source:
            mode = self._other(sp, now_us)
        else:
            mode = self.rc.mode
        if mode != self.mode:
            self.mode = mode
            self.events.record(now_us, EV_MODE, mode)
        sp.mode = mode
        if not (self.i_active and self.arming.armed and self.airmode_active == self.airmode_enabled):
            self._i_airmode(sp, now_us)  # in flight (armed, I-term on, air mode as set) nothing changes

    def _other(self, sp, now_us):
        """update() when the pilot's sticks are not all: the failsafe's set point, or the autopilot's."""
        if self.source & SOURCE_FAILSAFE:
            # SAFETY: the failsafe outranks the pilot's stale sticks, a launch and the autopilot.
            return self._failsafe_setpoint(sp)
        if self.source & SOURCE_LAUNCH:
            return self._launch_setpoint(sp)
        rc = self.rc
        if self.autopilot.apply(now_us, sp, rc.stick_raw, rc.throttle_raw):
            rc.fill_setpoint(sp)
        self._autopilot_claim()  # the pilot's stick may have released the latch
        return rc.mode

    def _failsafe_setpoint(self, sp):
        """The failsafe's set point: level (angle mode, sticks centred) and its throttle in stage 2."""
        fs = self.failsafe
        sp.stick_norm[0] = 0.0
        sp.stick_norm[1] = 0.0
        sp.stick_norm[2] = 0.0
        if fs.state == STAGE2:
            if fs.procedure == PROC_GLIDE or fs.procedure == PROC_DROP:
                sp.throttle_norm = 0.0
            else:
                sp.throttle_norm = fs.land_throttle_norm
                if fs.procedure == PROC_LAND:
                    fs.note_accel(self._accel_raw_m_s2)  # every pass: a 1 ms spike counts
        self.rc.fill_setpoint(sp)
        return MODE_ANGLE

    def _launch_setpoint(self, sp):
        """A hand launch's set point: wings level at the climb pitch (the controller's pitch target), the
        launch's throttle: idle until the motor starts."""
        sp.stick_norm[0] = 0.0
        sp.stick_norm[1] = 0.0
        sp.stick_norm[2] = 0.0
        sp.throttle_norm = self.launch.throttle_norm()
        self.rc.fill_setpoint(sp)
        return MODE_ANGLE

    def _i_airmode(self, sp, now_us):
        """Whether I-term and air mode may act."""
        # Until the throttle has been raised once after arming the craft sits on the ground:
        # no I-term wind-up against the ground, no air-mode spin-up (Betaflight's airmode start).
        armed = self.arming.armed
        if not armed:
            self.throttle_was_up = False
        elif not self.throttle_was_up and sp.throttle_norm > self._airmode_thr:
            self.throttle_was_up = True
        self.i_active = self.throttle_was_up
        # Air mode: the airmode parameter, or with an AIRMODE channel set only its switch (in range = on).
        active = self.i_active and self.airmode_enabled
        if active != self.airmode_active:
            self.airmode_active = active
            if armed:  # air mode starts (1) or the switch turns it off in flight (0)
                self.events.record(now_us, EV_AIRMODE, 1 if active else 0)
        if not self.i_active:
            self.controller.roll.i = 0.0
            self.controller.pitch.i = 0.0
            self.controller.yaw.i = 0.0

    # --------------------------------------------------------- the slow tasks
    def pilot_frame(self, now_us, armed):
        """A new frame from the pilot, after arming has seen it (receiver task): the autopilot's enabling
        procedure, and the AIRMODE switch (here, not in every pass)."""
        rc = self.rc
        if self.autopilot.on_pilot_frame(now_us, rc.arm_switch, armed, rc.ap_switch):
            self._autopilot_claim()
        if rc.airmode_box:
            self.airmode_enabled = rc.airmode_switch
        if self._manual[0]:
            self._manual_switch(rc)

    def _manual_switch(self, rc):
        """A plane's MANUAL switch in range outranks ANGLE and HORIZON (INAV's priority): the mode of this frame."""
        ch, lo, hi = self._manual
        channels = self._channels_us
        if ch <= len(channels) and lo <= channels[ch - 1] < hi:
            rc.mode = MODE_MANUAL

    def task(self, now_us, armed, yaw_rad):
        """100 Hz, after the supervisor's checks: a silent autopilot loses its privilege; the heading hold's
        yaw rate (here rather than in every pass)."""
        ap = self.autopilot
        if ap.state == AP_ENABLED:  # only an enabled autopilot can go silent
            ap.update(now_us, armed)
            self._autopilot_claim()
        rc = self.rc
        if rc.yaw_hold:
            rc.hold_heading(armed, yaw_rad)
        launch = self.launch
        if launch is not None and (armed != self._was_armed or launch.active()):
            self._launch_task(now_us, armed)

    def _launch_task(self, now_us, armed):
        """A plane's hand launch at 100 Hz: it starts at arming (fw_autolaunch), follows the throw, and hands the
        set point back to the pilot at its end."""
        launch = self.launch
        if armed and not self._was_armed:
            launch.arm(now_us)
        self._was_armed = armed
        if launch.active():
            rc = self.rc
            launch.update(now_us, armed, self._accel_m_s2, self._attitude.cos_tilt, rc.throttle_low(), rc.stick_raw)
        if launch.active():
            self.source |= SOURCE_LAUNCH
        else:
            self.source &= ~SOURCE_LAUNCH
        self._fw_pitch()

    def _fw_pitch(self):
        """The plane controller's pitch target in ANGLE: the glide's in failsafe stage 2, the climb's while a
        launch runs, else none (level)."""
        fw = self.fw
        if fw is None:
            return
        fs = self.failsafe
        if self.source & SOURCE_FAILSAFE:
            glide = fs.state == STAGE2 and fs.procedure == PROC_GLIDE
            fw.pitch_offset_rad = self._glide_pitch_rad if glide else 0.0
        elif self.source & SOURCE_LAUNCH:
            fw.pitch_offset_rad = self.launch.climb_rad
        else:
            fw.pitch_offset_rad = 0.0

    # ------------------------------------------------------------- who flies
    def failsafe_flies(self, flying):
        """Failsafe.update, at each change of stage: the failsafe takes the set point (stage 1 or 2) or
        hands it back."""
        if flying:
            self.source |= SOURCE_FAILSAFE
        else:
            self.source &= ~SOURCE_FAILSAFE
        self._fw_pitch()

    def _autopilot_claim(self):
        """The autopilot's bit of `source`, from its state after a call that can change it."""
        ap = self.autopilot
        if ap.state == AP_ENABLED or ap.latch_norm >= 0.0:
            self.source |= SOURCE_AUTOPILOT
        else:
            self.source &= ~SOURCE_AUTOPILOT

    def flier(self, motor_test_active):
        """Who flies, as the MSP status names it (FLIER_*): the failsafe outranks a motor test, which
        outranks the rest; disarmed otherwise, nobody; the autopilot only while its frames steer."""
        if self.source & SOURCE_FAILSAFE:
            return FLIER_FAILSAFE
        if motor_test_active:
            return FLIER_MOTOR_TEST
        if not self.arming.armed:
            return FLIER_NOBODY
        if self.autopilot.in_control():
            return FLIER_AUTOPILOT
        return FLIER_PILOT
