"""Hand launch for a plane, as INAV's NAV LAUNCH: armed on the ground, a throw, the motor, a climb.

Takes the armed state, the filtered accelerometer (body FRD, m/s²), the tilt and the pilot's throttle
and sticks once per slow pass (the commander's 100 Hz task); gives the launch's state, which the
commander turns into the set point while it runs: ANGLE, wings level at `launch_climb_deg` of pitch, the
throttle at `launch_idle_us` until the motor starts and at `launch_thr_us` after.

- WAIT: armed with the launch on (`fw_autolaunch`, INAV's FW_AUTOLAUNCH: every arm of a plane). The
  motor stays at idle; detection runs once the pilot has raised the throttle (INAV waits for it too).
- A throw (INAV's bungee/hand-launch test, swing launches aside): forward specific force above
  `launch_acc_m_s2` for `launch_detect_ms` with the tilt within `launch_max_deg`, and the speed that push
  gave (the forward acceleration integrated while it lasts) above `launch_vel_m_s`. A knock or a bump of
  the table is short: it fails the time or the speed, and the push starts again from zero.
- THROWN: `launch_delay_ms` at idle (the propeller clear of the hand), then CLIMB at the launch throttle.
- The launch ends, and the pilot's sticks and throttle fly, when the pilot moves the roll or pitch stick
  after the throw, or `launch_time_ms` after the throw; disarming ends it too. The integrator is held at
  zero until the motor starts (the commander's `i_active`), as INAV freezes it.
"""

from hoverfly.compat import const, ticks_diff
from hoverfly.core.events import EV_LAUNCH

LAUNCH_OFF = const(0)  # not launching: the pilot flies
LAUNCH_WAIT = const(1)  # armed on the ground: waiting for the throttle and the throw
LAUNCH_THROWN = const(2)  # the throw detected: the motor delay
LAUNCH_CLIMB = const(3)  # the motor runs: climbing at the launch pitch
LAUNCH_STATES = ("off", "wait", "thrown", "climb")

# EV_LAUNCH details: what happened
LAUNCH_EV_WAIT = const(0)
LAUNCH_EV_THROWN = const(1)
LAUNCH_EV_MOTOR = const(2)
LAUNCH_EV_STICKS = const(3)  # ended by the pilot's sticks
LAUNCH_EV_TIMEOUT = const(4)  # ended by launch_time_ms
LAUNCH_EV_DISARMED = const(5)
LAUNCH_EVENTS = ("wait", "thrown", "motor", "sticks", "timeout", "disarmed")

_DEG = 0.017453292519943295
# A stick this far from centre (after the deadband) is the pilot taking over.
_STICK_TAKEOVER = 0.1


class Launch:
    def __init__(self, events):
        self.events = events
        self.state = LAUNCH_OFF
        self.enabled = False  # fw_autolaunch on a plane
        self.acc_m_s2 = 18.63
        self.vel_m_s = 3.0
        self.detect_us = 40000
        self.cos_max = 0.7071
        self.delay_us = 500000
        self.time_us = 5000000
        self.idle_norm = 0.0
        self.thr_norm = 0.7
        self.climb_rad = 18.0 * _DEG
        self.push_m_s = 0.0  # the speed the current push has given
        self.push_us = 0  # how long the forward acceleration has been above launch_acc_m_s2
        self.since_us = 0  # when the state began
        self._last_us = 0
        self._counting = False

    def configure(self, params, plane):
        self.enabled = plane and params.get("fw_autolaunch") == 1
        self.acc_m_s2 = params.get("launch_acc_m_s2")
        self.vel_m_s = params.get("launch_vel_m_s")
        self.detect_us = params.get("launch_detect_ms") * 1000
        d = params.get("launch_max_deg") * _DEG
        # cos by its series to the 8th power: within 3e-5 up to 90 degrees, and no math import here
        d2 = d * d
        self.cos_max = 1.0 - d2 / 2.0 + d2 * d2 / 24.0 - d2 * d2 * d2 / 720.0 + d2 * d2 * d2 * d2 / 40320.0
        self.delay_us = params.get("launch_delay_ms") * 1000
        self.time_us = params.get("launch_time_ms") * 1000
        self.idle_norm = (params.get("launch_idle_us") - 1000) * 0.001
        self.thr_norm = (params.get("launch_thr_us") - 1000) * 0.001
        self.climb_rad = params.get("launch_climb_deg") * _DEG
        if not self.enabled:
            self.state = LAUNCH_OFF

    def active(self):
        return self.state != LAUNCH_OFF

    def motor_on(self):
        return self.state == LAUNCH_CLIMB

    def throttle_norm(self):
        """The throttle the launch asks for while it runs."""
        return self.thr_norm if self.state == LAUNCH_CLIMB else self.idle_norm

    def arm(self, now_us):
        """The plane armed: a launch starts when it is on."""
        if self.enabled:
            self._set(now_us, LAUNCH_WAIT, LAUNCH_EV_WAIT)
            self._restart_push(now_us)

    def update(self, now_us, armed, accel_m_s2, cos_tilt, throttle_low, stick_raw):
        """Slow pass: advance the launch (stick_raw: the pilot's roll, pitch, yaw sticks, -1..1). Returns True
        when its state changed (the commander's set point)."""
        st = self.state
        if st == LAUNCH_OFF:
            return False
        if not armed:
            self._set(now_us, LAUNCH_OFF, LAUNCH_EV_DISARMED)
            return True
        if st == LAUNCH_WAIT:
            if throttle_low:
                self._restart_push(now_us)
                return False
            if self._thrown(now_us, accel_m_s2[0], cos_tilt):
                self._set(now_us, LAUNCH_THROWN, LAUNCH_EV_THROWN)
                return True
            return False
        if sticks_moved(stick_raw):
            self._set(now_us, LAUNCH_OFF, LAUNCH_EV_STICKS)
            return True
        since = ticks_diff(now_us, self.since_us)
        if st == LAUNCH_THROWN:
            if since >= self.delay_us:
                self.state = LAUNCH_CLIMB  # the launch's time still counts from the throw
                self.events.record(now_us, EV_LAUNCH, LAUNCH_EV_MOTOR)
                return True
            return False
        if since >= self.time_us:
            self._set(now_us, LAUNCH_OFF, LAUNCH_EV_TIMEOUT)
            return True
        return False

    def _thrown(self, now_us, forward_m_s2, cos_tilt):
        """The throw test on this sample: a forward push strong, long and fast enough, nearly level."""
        dt_us = ticks_diff(now_us, self._last_us)
        self._last_us = now_us
        if dt_us < 0 or dt_us > 100000:
            dt_us = 0
        if forward_m_s2 < 0.5 * self.acc_m_s2 or cos_tilt < self.cos_max:
            self._restart_push(now_us)
            return False
        self.push_m_s += forward_m_s2 * dt_us * 1e-6
        if forward_m_s2 >= self.acc_m_s2:
            if self._counting:
                self.push_us += dt_us
            self._counting = True
        else:
            self.push_us = 0
            self._counting = False
        return self.push_us >= self.detect_us and self.push_m_s >= self.vel_m_s

    def _restart_push(self, now_us):
        self.push_m_s = 0.0
        self.push_us = 0
        self._counting = False
        self._last_us = now_us

    def _set(self, now_us, state, detail):
        self.state = state
        self.since_us = now_us
        self.events.record(now_us, EV_LAUNCH, detail)


def sticks_moved(stick_raw):
    """The pilot's roll or pitch stick out of centre: a launch ends (and the failsafe hands back)."""
    a = stick_raw[0]
    b = stick_raw[1]
    return a > _STICK_TAKEOVER or a < -_STICK_TAKEOVER or b > _STICK_TAKEOVER or b < -_STICK_TAKEOVER
