"""Stick to rate setpoint: Betaflight's "actual" rates curve.

centre sensitivity (deg/s per unit stick at centre), max rate (deg/s at full stick)
and expo shape the curve. Parameters are in Betaflight's units (rc_rate and srate in
10 deg/s, expo in percent); the curve returns rad/s.
"""

import math

_DEG = math.pi / 180.0


class ActualRates:
    def __init__(self):
        self.centre_rad_s = 70.0 * _DEG
        self.travel_rad_s = 600.0 * _DEG
        self.expo = 0.0
        self._one_minus_expo = 1.0

    def configure(self, rc_rate, srate, expo_pct):
        centre = rc_rate * 10.0
        max_rate = srate * 10.0
        travel = max_rate - centre
        if travel < 0:
            travel = 0.0
        self.centre_rad_s = centre * _DEG
        self.travel_rad_s = travel * _DEG
        self.expo = expo_pct * 0.01
        self._one_minus_expo = 1.0 - self.expo

    def max_rate_rad_s(self):
        return self.centre_rad_s + self.travel_rad_s

    def rate_rad_s(self, stick_norm):
        a = stick_norm if stick_norm >= 0 else -stick_norm
        if a > 1.0:
            a = 1.0
        e = self.expo
        if e == 0.0:
            curve = a * a  # a * (0 + a * 1): exactly the general form's value
        else:
            a2 = a * a
            curve = a * (a2 * a2 * a * e + a * self._one_minus_expo)
        r = a * self.centre_rad_s + curve * self.travel_rad_s
        return r if stick_norm >= 0 else -r

    def stick_for_rate(self, rate_rad_s):
        """Inverse of the curve (bisection): the stick that asks for `rate_rad_s`."""
        target = rate_rad_s if rate_rad_s >= 0 else -rate_rad_s
        lo = 0.0
        hi = 1.0
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if self.rate_rad_s(mid) < target:
                lo = mid
            else:
                hi = mid
        s = 0.5 * (lo + hi)
        return s if rate_rad_s >= 0 else -s
