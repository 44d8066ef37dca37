"""The companion-computer autopilot link (seed 004): MSP RC as a second command source.

Takes the pilot's receiver frames (autopilot switch on AUX `ap_ch`, the arm switch, the
sticks) and the companion's MSP SET_RAW_RC frames (`on_msp_rc`); gives the commander the
sticks and throttle to fly (`apply`, stage 3 of the pass), arms and disarms for the
autopilot through Arming, and reports its privilege (`privilege()`, `state`) for MSP.

Seed 004's rules, as implemented:
1. Enabling procedure: autopilot switch on, THEN the arm switch on. Only then may the
   autopilot send RC (its frames are used) and arm/disarm (its arm channel, AUX1 in its
   frame, rising edge; seen off first). In autopilot mode the pilot's arm switch never arms.
2. The pilot's arm switch off while the autopilot switch is on: privilege withdrawn and the
   motors disarmed (crash landing); Arming disarms after `disarm_frames`, as for any switch.
3. Soft override while enabled: the pilot's throttle stick caps the autopilot's throttle;
   a pilot roll or pitch stick beyond `ap_override_pct` replaces the autopilot's on that axis.
4. Hard override: autopilot switch off -> the pilot's sticks at once; the craft stays armed;
   the throttle is held at the autopilot's last throttle until the pilot's throttle stick
   comes down to it, then the pilot's throttle is used.
5. Privilege status: `privilege()` bits, readable over MSP. Frames sent without privilege are
   counted (`rejected`) and change nothing.
6. Not in seed 004, required by issue 5: a silent autopilot (no MSP RC for `ap_timeout_ms`)
   loses its privilege; the pilot flies (with the same throttle latch), or the receiver
   failsafe if the pilot's link is gone too. It never holds its last command. Re-enabling
   takes the procedure again.
The receiver failsafe outranks the autopilot: with the pilot's link lost nobody can override.
"""

from array import array

from hoverfly.compat import const, ticks_diff
from hoverfly.core.events import (
    DISARM_COMMAND,
    EV_AUTOPILOT_DISABLED,
    EV_AUTOPILOT_ENABLED,
    EV_AUTOPILOT_OVERRIDE,
)
from hoverfly.core.safety.arming import AUTOPILOT, REASONS, SOURCE_AUTOPILOT, first_reason
from hoverfly.core.stages.rc import aux_channel, map_channels

AP_OFF = const(0)  # autopilot switch off: the pilot flies and arms
AP_WAIT = const(1)  # switch on, waiting for the arm switch to come on after it
AP_ENABLED = const(2)  # privileged: its RC flies, it may arm
AP_SILENT = const(3)  # was enabled, went silent: the pilot flies until the switch goes off
STATE_NAMES = ("off", "wait_arm_switch", "enabled", "silent")

# privilege() bits
PRIV_RC = const(1)  # MSP RC is accepted
PRIV_ARM = const(2)  # may arm and disarm
PRIV_IN_CONTROL = const(4)  # its commands fly the craft now
PRIV_SOFT_OVERRIDE = const(8)  # the pilot overrides an axis or caps the throttle
PRIV_THROTTLE_LATCH = const(16)  # the pilot flies with the throttle held at the autopilot's last
PRIV_NAMES = ("rc", "arm", "in_control", "soft_override", "throttle_latch")

# detail of `autopilot_override`
OVR_ROLL = const(1)  # soft: pilot roll replaces the autopilot's
OVR_PITCH = const(2)  # soft: pilot pitch replaces the autopilot's
OVR_THROTTLE_CAP = const(3)  # soft: pilot throttle caps the autopilot's
OVR_HARD = const(4)  # hard: autopilot switch off, throttle latched
OVR_LATCH_RELEASED = const(5)  # the pilot's throttle came down to the latch
OVR_END = const(6)  # soft override over: the autopilot has every axis again
OVERRIDE_NAMES = ("", "roll", "pitch", "throttle_cap", "hard", "latch_released", "end")

# detail of `autopilot_disabled`
DIS_SWITCH_OFF = const(0)
DIS_ARM_SWITCH = const(1)
DIS_TIMEOUT = const(2)
DISABLED_NAMES = ("autopilot_switch_off", "arm_switch_off", "timeout")

# on_msp_rc refusals (constant strings: nothing allocated per rejected frame)
R_NO_AUTOPILOT = "no autopilot switch configured (ap_ch = 0)"
R_SWITCH_OFF = "autopilot switch is off"
R_WAIT = "autopilot not enabled: switch the arm switch on after the autopilot switch"
R_SILENT = "autopilot timed out: switch the autopilot switch off and run the procedure again"
R_SHORT = "MSP RC needs at least 4 channels"
R_RANGE = "MSP RC channel out of range 800..2200 us"

# What became of the companion's last MSP RC frame (`last_result`, readable over MSP as
# MSP2_HOVERFLY_AUTOPILOT): 0 taken, else why it was refused. RESULT_TEXTS holds on_msp_rc's
# reason for each, so a companion reading the code over the wire words it as the flight did.
RES_TAKEN = const(0)
RES_NO_AUTOPILOT = const(1)
RES_SWITCH_OFF = const(2)
RES_WAIT = const(3)
RES_SILENT = const(4)
RES_SHORT = const(5)
RES_RANGE = const(6)
RES_ARM_REFUSED = const(7)  # the frame was taken, but its arm request was refused (`last_arm_reason`)
RESULT_TEXTS = (None, R_NO_AUTOPILOT, R_SWITCH_OFF, R_WAIT, R_SILENT, R_SHORT, R_RANGE, "arming refused")

# Why the throttle is latched (`latch_cause`, while latch_norm >= 0)
LATCH_NONE = const(0)
LATCH_HARD = const(1)  # hard override: the autopilot switch went off while it flew
LATCH_TIMEOUT = const(2)  # the autopilot fell silent while armed

_SOFT_ROLL = const(1)
_SOFT_PITCH = const(2)
_SOFT_THROTTLE = const(4)


def arm_refusal_text(bit):
    """on_msp_rc's reason when the autopilot's arm request meets arming reason `bit`."""
    r = REASONS.get(bit)
    return "arming refused: " + (r[1] if r else "reason %d" % bit)


def _stick(us):
    v = (us - 1500) * 0.002
    return 1.0 if v > 1.0 else (-1.0 if v < -1.0 else v)


class Autopilot:
    def __init__(self, events):
        self.events = events
        self.state = AP_OFF
        self.pilot_channels = None  # the pilot's latest frame (Flight hands signals.rc_channels_us)
        self.stick_norm = array("f", [0.0, 0.0, 0.0])  # the autopilot's last roll, pitch, yaw
        self.throttle_norm = 0.0  # the autopilot's last throttle
        self.has_frame = False  # a frame arrived since it was enabled
        self.last_msp_us = 0
        self.enabled_us = 0
        self.frames = 0  # accepted MSP RC frames
        self.rejected = 0  # frames refused (no privilege, malformed)
        self.latch_norm = -1.0  # >= 0: the pilot's throttle is held at this
        self.latch_cause = LATCH_NONE  # why it is held (LATCH_*)
        self.last_result = RES_TAKEN  # RES_*: what became of the last MSP RC frame
        self.last_arm_reason = -1  # with RES_ARM_REFUSED: the arming reason bit that refused it
        self.soft = 0
        # configuration
        self.ch = 7
        self.lo_us = 1700
        self.hi_us = 2100
        self.timeout_us = 200000
        self.override_norm = 0.1
        self.map = (0, 1, 3, 2)
        self.arm_ch = 5
        self.arm_lo_us = 1700
        self.arm_hi_us = 2100
        self.min_check_norm = 0.05
        self.disarm_frames_needed = 5
        self._arm_off_frames = 0
        self._arm_seen_off = False
        self._msp_arm_was_on = True
        self._msp_disarm_frames = 0

    def configure(self, params):
        chmap = map_channels(params.get("rc_map"))  # the frames come in the receiver's order (rc_map)
        self.ch = aux_channel(chmap, params.get("ap_ch"))
        self.lo_us = params.get("ap_min_us")
        self.hi_us = params.get("ap_max_us")
        self.timeout_us = params.get("ap_timeout_ms") * 1000
        self.override_norm = params.get("ap_override_pct") * 0.01
        self.map = (chmap[0], chmap[1], chmap[2], chmap[3])  # roll, pitch, yaw, throttle
        self.arm_ch = aux_channel(chmap, params.get("arm_ch"))
        if params.get("arm_source") == "seed001":
            self.arm_lo_us = 1501
            self.arm_hi_us = 0x10000
        else:
            self.arm_lo_us = params.get("arm_min_us")
            self.arm_hi_us = params.get("arm_max_us")
        self.min_check_norm = (params.get("min_check") - 1000) * 0.001
        self.disarm_frames_needed = params.get("disarm_frames")

    # ------------------------------------------------------------ the pilot's side
    def switch_on(self):
        """The autopilot switch in the pilot's latest frame."""
        ch = self.ch
        chans = self.pilot_channels
        if ch <= 0 or chans is None or ch > len(chans):
            return False
        v = chans[ch - 1]
        return self.lo_us <= v < self.hi_us

    def pilot_may_arm(self):
        """Arming asks: may the pilot's arm switch arm? Not in autopilot mode (seed 004)."""
        return not self.switch_on()

    def on_pilot_frame(self, now_us, arm_switch, armed, ap_on=None):
        """One new frame from the pilot's receiver: run the enabling procedure. ap_on: the autopilot switch
        in the frame where the caller has read it (Flight: RcInput's mode ranges), else switch_on(). False
        when the state and the latch cannot have changed (the switch off, the autopilot off already: the
        usual frame)."""
        if ap_on is None:
            ap_on = self.switch_on()
        st = self.state
        if arm_switch:
            self._arm_off_frames = 0
        else:
            self._arm_off_frames += 1
        if not ap_on:
            if st == AP_OFF:
                return False
            if st == AP_ENABLED or st == AP_SILENT:
                if st == AP_ENABLED and armed and self.has_frame:
                    # Hard override: the pilot's sticks now, the throttle held at the autopilot's last.
                    self.latch_norm = self.throttle_norm
                    self.latch_cause = LATCH_HARD
                    self.events.record(now_us, EV_AUTOPILOT_OVERRIDE, OVR_HARD)
                self.events.record(now_us, EV_AUTOPILOT_DISABLED, DIS_SWITCH_OFF)
            self.state = AP_OFF
            self.has_frame = False
            self.soft = 0
            return True
        # An arm switch counts as off after disarm_frames frames, as for a disarm (seed 000).
        arm_off = self._arm_off_frames >= self.disarm_frames_needed
        if st == AP_OFF:
            self.state = AP_WAIT
            # The order matters: an arm switch already on must be seen off first.
            self._arm_seen_off = False
            return True
        if st == AP_WAIT:
            if arm_off:
                self._arm_seen_off = True
            elif arm_switch and self._arm_seen_off:
                self.state = AP_ENABLED
                self.enabled_us = now_us
                self.has_frame = False
                self.soft = 0
                self._msp_arm_was_on = True  # its arm channel must be seen off first
                self._msp_disarm_frames = 0
                self.latch_norm = -1.0
                self.events.record(now_us, EV_AUTOPILOT_ENABLED, 0)
            return True
        # enabled or silent: the arm switch off withdraws the privilege (Arming disarms)
        if arm_off:
            self.state = AP_WAIT
            self._arm_seen_off = True
            self.has_frame = False
            self.soft = 0
            self.events.record(now_us, EV_AUTOPILOT_DISABLED, DIS_ARM_SWITCH)
        return True

    # -------------------------------------------------------- the companion's side
    def on_msp_rc(self, now_us, channels_us, count, arming):
        """MSP SET_RAW_RC from the companion. None when taken, else why it was refused."""
        st = self.state
        if st != AP_ENABLED:
            if self.ch <= 0:
                return self._refused(RES_NO_AUTOPILOT)
            if st == AP_OFF:
                return self._refused(RES_SWITCH_OFF)
            if st == AP_WAIT:
                return self._refused(RES_WAIT)
            return self._refused(RES_SILENT)
        if count < 4:
            return self._refused(RES_SHORT)
        n = count if count < len(channels_us) else len(channels_us)
        for i in range(n):
            v = channels_us[i]
            if v < 800 or v > 2200:
                return self._refused(RES_RANGE)
        self.last_result = RES_TAKEN
        m = self.map
        s = self.stick_norm
        s[0] = _stick(channels_us[m[0]])
        # Pitch forward (more µs) is nose down: negative pitch in FRD, as the pilot's.
        s[1] = -_stick(channels_us[m[1]])
        s[2] = _stick(channels_us[m[2]])
        t = (channels_us[m[3]] - 1000) * 0.001
        self.throttle_norm = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
        self.has_frame = True
        self.last_msp_us = now_us
        self.frames += 1
        a = self.arm_ch
        arm_on = 0 < a <= n and self.arm_lo_us <= channels_us[a - 1] < self.arm_hi_us
        if arm_on:
            self._msp_disarm_frames = 0
            if not self._msp_arm_was_on:
                self._msp_arm_was_on = True
                if not arming.armed:
                    blocked = arming.try_arm(now_us, SOURCE_AUTOPILOT, 1 << AUTOPILOT)
                    if blocked:
                        self.last_result = RES_ARM_REFUSED
                        self.last_arm_reason = first_reason(blocked)
                        return arm_refusal_text(self.last_arm_reason)
        else:
            self._msp_arm_was_on = False
            if arming.armed:
                self._msp_disarm_frames += 1
                if self._msp_disarm_frames >= self.disarm_frames_needed:
                    arming.disarm(now_us, DISARM_COMMAND)
        return None

    def _refused(self, result):
        self.rejected += 1
        self.last_result = result
        return RESULT_TEXTS[result]

    # ----------------------------------------------------------------- each pass
    def update(self, now_us, armed):
        """Slow task: a silent autopilot loses its privilege (never holds its last command)."""
        if self.state != AP_ENABLED:
            return
        if self.has_frame:
            silent = ticks_diff(now_us, self.last_msp_us) > self.timeout_us
        else:
            silent = False  # nothing sent yet: it has not armed, nothing to hold
        if silent:
            self.state = AP_SILENT
            if armed:
                self.latch_norm = self.throttle_norm
                self.latch_cause = LATCH_TIMEOUT
            self.has_frame = False
            self.soft = 0
            self.events.record(now_us, EV_AUTOPILOT_DISABLED, DIS_TIMEOUT)

    def in_control(self):
        return self.state == AP_ENABLED and self.has_frame

    def throttle_low(self):
        """The autopilot's own throttle, for its arming check."""
        return (not self.has_frame) or self.throttle_norm < self.min_check_norm

    def apply(self, now_us, sp, pilot_stick_raw, pilot_throttle_raw):
        """Stage 3: sp holds the pilot's smoothed sticks; make it the autopilot's where it flies.
        Returns True when sp was changed (the caller refills rates and angles)."""
        # Every pass: the common case (no autopilot flying, no latch) returns from here. The work is in
        # methods of their own so this one's frame stays on the C stack on MicroPython (no heap frame).
        if self.state == AP_ENABLED and self.has_frame:
            self._fly(now_us, sp, pilot_stick_raw)
            return True
        if self.latch_norm >= 0.0:
            self._hold_latch(now_us, sp, pilot_throttle_raw)
        return False

    def _fly(self, now_us, sp, pilot_stick_raw):
        """The autopilot's sticks and throttle into sp, less what the pilot overrides (soft override)."""
        s = sp.stick_norm
        a = self.stick_norm
        soft = 0
        lim = self.override_norm
        p = pilot_stick_raw[0]
        if p > lim or p < -lim:
            soft |= _SOFT_ROLL  # the pilot's roll stays in sp
        else:
            s[0] = a[0]
        p = pilot_stick_raw[1]
        if p > lim or p < -lim:
            soft |= _SOFT_PITCH
        else:
            s[1] = a[1]
        s[2] = a[2]
        thr = self.throttle_norm
        if sp.throttle_norm < thr:
            thr = sp.throttle_norm  # the pilot's throttle stick is a ceiling
            soft |= _SOFT_THROTTLE
        sp.throttle_norm = thr
        if soft != self.soft:
            self._soft_events(now_us, soft)

    def _hold_latch(self, now_us, sp, pilot_throttle_raw):
        """After a hard override: the throttle held at the autopilot's last until the pilot's stick comes down to it."""
        latch = self.latch_norm
        if pilot_throttle_raw <= latch:
            self.latch_norm = -1.0
            self.events.record(now_us, EV_AUTOPILOT_OVERRIDE, OVR_LATCH_RELEASED)
        elif sp.throttle_norm > latch:
            sp.throttle_norm = latch

    def _soft_events(self, now_us, soft):
        new = soft & ~self.soft
        if new & _SOFT_ROLL:
            self.events.record(now_us, EV_AUTOPILOT_OVERRIDE, OVR_ROLL)
        if new & _SOFT_PITCH:
            self.events.record(now_us, EV_AUTOPILOT_OVERRIDE, OVR_PITCH)
        if new & _SOFT_THROTTLE:
            self.events.record(now_us, EV_AUTOPILOT_OVERRIDE, OVR_THROTTLE_CAP)
        if soft == 0:
            self.events.record(now_us, EV_AUTOPILOT_OVERRIDE, OVR_END)
        self.soft = soft

    def privilege(self):
        """Bits: 1 RC accepted, 2 may arm, 4 in control, 8 soft override, 16 throttle latched."""
        p = 0
        if self.state == AP_ENABLED:
            p = PRIV_RC | PRIV_ARM
            if self.has_frame:
                p |= PRIV_IN_CONTROL
            if self.soft:
                p |= PRIV_SOFT_OVERRIDE
        if self.latch_norm >= 0.0:
            p |= PRIV_THROTTLE_LATCH
        return p

    def state_name(self):
        return STATE_NAMES[self.state]
