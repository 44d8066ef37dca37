"""A scripted companion computer: sends MSP SET_RAW_RC at a rate, as seed 004's autopilot does.

The scenario sets what it sends (`msp_rc = {roll, pitch, yaw, throttle, arm, rate_hz,
hold_altitude_m}`, or `msp_rc = false` to fall silent); with `hold_altitude_m` it flies the
throttle itself from the craft's altitude, as a companion with its own height sensor would.
Each frame goes through the MSP codec (a SET_RAW_RC request, parsed back as the flight
controller's MSP server parses it) and into `flight.on_msp_rc`, the seam the MSP server uses.
It counts what was taken and why the rest was refused.
"""

from hoverfly.protocols import msp

_MAPS = {"AETR": (0, 1, 3, 2), "TAER": (1, 2, 3, 0), "RETA": (3, 2, 1, 0)}  # roll, pitch, yaw, throttle


def _clamp(x, lo, hi):
    return lo if x < lo else (hi if x > hi else x)


class Companion:
    def __init__(self, flight, params, hover_guess=0.35):
        self.flight = flight
        self.hover_guess = hover_guess
        self.hold_altitude_m = None
        self._alt_i = 0.0
        self._last_t = 0.0
        self.map = _MAPS[params.get("map_aetr")]
        self.arm_ch = params.get("arm_ch")
        self.sending = False
        self.rate_hz = 100.0
        self.roll = 0.0
        self.pitch = 0.0  # forward positive, as a transmitter
        self.yaw = 0.0
        self.throttle = 0.0
        self.arm = False
        self.channels = 8
        self._next_s = 0.0
        self.sent = 0
        self.taken = 0
        self.refusals = {}

    def set(self, spec, t):
        if spec is False:
            self.sending = False
            return
        if "throttle" in spec:
            self.hold_altitude_m = None
        for key in ("roll", "pitch", "yaw", "throttle", "arm", "rate_hz", "channels", "hold_altitude_m"):
            if key in spec:
                setattr(self, key, spec[key])
        if not self.sending:
            self._next_s = t
        self.sending = True

    def frame_us(self):
        ch = [1500] * int(self.channels)
        m = self.map
        ch[m[0]] = int(1500 + 500 * _clamp(self.roll, -1.0, 1.0))
        ch[m[1]] = int(1500 + 500 * _clamp(self.pitch, -1.0, 1.0))
        ch[m[2]] = int(1500 + 500 * _clamp(self.yaw, -1.0, 1.0))
        ch[m[3]] = int(1000 + 1000 * _clamp(self.throttle, 0.0, 1.0))
        if 0 < self.arm_ch <= len(ch):
            ch[self.arm_ch - 1] = 2000 if self.arm else 1000
        return ch

    def tick(self, t, now_us, vehicle=None):
        """Send the frames due by time t (s)."""
        if not self.sending or t + 1e-9 < self._next_s:
            return
        if self.hold_altitude_m is not None and vehicle is not None:
            dt = t - self._last_t if self._last_t > 0.0 else 0.01
            err = self.hold_altitude_m - vehicle.altitude_m()
            if not vehicle.on_ground:
                self._alt_i = _clamp(self._alt_i + err * dt * 0.15, -0.3, 0.3)
            self.throttle = _clamp(self.hover_guess + self._alt_i + 0.12 * err + 0.10 * vehicle.vd, 0.0, 0.9)
        self._last_t = t
        self._next_s += 1.0 / self.rate_hz
        if self._next_s <= t:
            self._next_s = t + 1.0 / self.rate_hz
        # over the wire format and back, as the MSP server would see it
        payload = msp.pack_set_raw_rc(self.frame_us())
        channels = msp.unpack_set_raw_rc(payload, len(payload))
        self.sent += 1
        fn = getattr(self.flight, "on_msp_rc", None)
        reason = "no MSP RC in this firmware" if fn is None else fn(now_us, channels, len(channels))
        if reason is None:
            self.taken += 1
        else:
            self.refusals[reason] = self.refusals.get(reason, 0) + 1

    def report(self):
        ap = getattr(self.flight, "autopilot", None)
        r = {"sent": self.sent, "taken": self.taken, "refused": dict(self.refusals)}
        if ap is not None:
            r["state"] = ap.state_name()
            r["privilege"] = ap.privilege()
        return r
