"""Motor test: spin chosen motors on the bench, disarmed, with the props off.

MSP SET_MOTOR and the maintenance protocol call `request(now_us, index, value_norm, props_off)`;
the pass calls `update(now_us, armed, arm_switch, link_ok, motor_out)` in step 6, which writes
the test values over the disarmed motor_out while the test is active. Rules (issue 4):
- only while disarmed, and only with the user's props-off acknowledgement (`props_off`);
- each motor's command expires unless refreshed within `EXPIRE_US` (1 s);
- the value is capped by `motor_test_pct` (capped values are counted, not refused);
- any arming attempt (the arm switch turned on, or `stop(STOP_ARMING)` from the arming
  check), being armed, or the receiver link being lost ends it, as does `stop()`.
`active` is True while any motor has a test value; the arming check refuses to arm then.

value_norm is the ESC command on motor_out's scale (0 = stop; above 0 it is raised to the
idle output, so a test never asks an ESC for less than flight does).
"""

from array import array

from hoverfly.compat import const, ticks_diff
from hoverfly.core.stages.mixer import MAX_MOTORS

EXPIRE_US = const(1000000)

STOP_NONE = const(0)
STOP_USER = const(1)  # stop(), or every value set to 0
STOP_EXPIRED = const(2)  # not refreshed within EXPIRE_US
STOP_ARMING = const(3)  # arm switch on / an arming attempt
STOP_LINK = const(4)  # receiver link lost, or the configuration link that drove the test closed
STOP_ARMED = const(5)  # found armed: never test an armed craft
STOP_NAMES = ("none", "stopped", "expired", "arming attempt", "link lost", "armed")


class MotorTest:
    def __init__(self, arming):
        self._arming = arming  # read-only: `armed` decides whether a request may start
        self.active = False
        self.motor_count = 4
        self.values = array("f", [0.0] * MAX_MOTORS)  # motor_out per motor while the test runs
        self._refreshed_us = [0] * MAX_MOTORS
        self.max_norm = 0.3
        self.idle = 0.055
        self.requests = 0
        self.refused = 0
        self.capped = 0
        self.stop_reason = STOP_NONE
        self.last_error = ""
        self._arm_switch = False
        self._link_was_ok = False

    def configure(self, params, motor_count):
        self.motor_count = motor_count
        self.max_norm = params.get("motor_test_pct") * 0.01
        self.idle = params.get("motor_idle_pct") * 0.01

    def _refuse(self, why):
        self.refused += 1
        self.last_error = why
        return why

    def request(self, now_us, index, value_norm, props_off):
        """Set motor `index` (-1 = all) to value_norm 0..1; None, or the reason it was refused."""
        if self._arming.armed:
            return self._refuse("motor test refused: armed")
        if props_off is not True:
            return self._refuse("motor test needs the props-off acknowledgement")
        if self._arm_switch:
            return self._refuse("motor test refused: the arm switch is on")
        n = self.motor_count
        if not isinstance(index, int) or index < -1 or index >= n:
            return self._refuse("motor %r outside -1..%d (-1 = all)" % (index, n - 1))
        if isinstance(value_norm, bool) or not isinstance(value_norm, (int, float)) \
                or not (0.0 <= value_norm <= 1.0):
            return self._refuse("motor test value %r outside 0..1" % (value_norm,))
        v = float(value_norm)
        if v > self.max_norm:
            v = self.max_norm
            self.capped += 1
        if 0.0 < v < self.idle:
            v = self.idle
        self.requests += 1
        lo = 0 if index < 0 else index
        hi = n if index < 0 else index + 1
        for i in range(lo, hi):
            self.values[i] = v
            self._refreshed_us[i] = now_us
        self._recount(STOP_USER)
        return None

    def stop(self, reason_code=STOP_USER):
        """End the test: every motor back to stop."""
        for i in range(MAX_MOTORS):
            self.values[i] = 0.0
        if self.active:
            self.stop_reason = reason_code
        self.active = False

    def _recount(self, reason_if_idle):
        on = False
        for i in range(self.motor_count):
            if self.values[i] > 0.0:
                on = True
        if self.active and not on:
            self.stop_reason = reason_if_idle
        elif on:
            self.stop_reason = STOP_NONE
        self.active = on

    def update(self, now_us, armed, arm_switch, link_ok, motor_out):
        """Each pass: end the test on arming, link loss or expiry; else write its values to motor_out."""
        # The flight's every pass (no test) only notes the two inputs. Few locals and a shallow stack:
        # a MicroPython function needing more than 11 slots gets its frame from the heap on every call.
        if not self.active:
            self._link_was_ok = link_ok
            self._arm_switch = arm_switch
            return False
        link_lost = self._link_was_ok and not link_ok
        self._link_was_ok = link_ok
        self._arm_switch = arm_switch
        # SAFETY: a motor test never runs armed, and gives way to any arming attempt or lost link.
        if armed:
            self.stop(STOP_ARMED)
            return False
        if arm_switch:
            self.stop(STOP_ARMING)
            return False
        if link_lost:
            self.stop(STOP_LINK)
            return False
        return self._write(now_us, motor_out)

    def _write(self, now_us, motor_out):
        """Expire motors not refreshed in time; the rest's test values to motor_out."""
        values = self.values
        refreshed = self._refreshed_us
        expired = False
        for i in range(self.motor_count):
            if values[i] > 0.0 and ticks_diff(now_us, refreshed[i]) > EXPIRE_US:
                values[i] = 0.0
                expired = True
        if expired:
            self._recount(STOP_EXPIRED)
            if not self.active:
                return False
        for i in range(self.motor_count):
            motor_out[i] = values[i]
        return True
