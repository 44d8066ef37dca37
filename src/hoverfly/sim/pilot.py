"""The scenario pilot: sticks and switches on a transmitter, moved as a pilot would.

It sees what a pilot sees (the craft's altitude, speed and attitude, from the physics)
and writes channel pulse widths where the transmitter's channel map puts them (`map`, the
flight's rc_map: AETR1234 by default): sticks, the arm switch on AUX1, the mode switch on
AUX2 (low acro, middle horizon, high angle). Beyond plain stick
positions it can hold an altitude with the throttle (the core has no altitude hold),
fly to a point in angle mode, land, and fly a flip in acro.
"""

import math

ARM_CH = 4  # function index in the map: AUX1 (channel 5 in AETR1234)
MODE_CH = 5  # AUX2 (channel 6)
MODE_US = {"acro": 1000, "horizon": 1500, "angle": 2000}


def _clamp(x, lo, hi):
    return lo if x < lo else (hi if x > hi else x)


class Pilot:
    def __init__(self, channels_us, mode="angle"):
        self.ch = channels_us
        self.roll = 0.0
        self.pitch = 0.0  # forward positive (nose down), as on the transmitter
        self.yaw = 0.0
        self.throttle = 0.0
        self.arm = False
        self.mode = mode
        self.hold_alt_m = None
        self._alt_target_m = 0.0
        self._alt_i = 0.0
        self.climb_rate_m_s = 1.5
        self.fly_to = None
        self.landing = False
        self._landed_s = None
        self.flip_axis = None
        self._flip_phase = 0
        self._flip_t0 = 0.0
        self._flip_turned_rad = 0.0
        self.hover_guess = 0.35
        self.overrides_us = {}
        # receiver channel (0-based) per function: roll, pitch, yaw, throttle, AUX1..4 (rc.map_channels)
        self.map = [0, 1, 3, 2, 4, 5, 6, 7]

    # ------------------------------------------------------------------ commands
    def set_hold(self, alt_m, v):
        if alt_m is False or alt_m is None:
            self.hold_alt_m = None
            return
        if self.hold_alt_m is None:
            self._alt_target_m = v.altitude_m()
        self.hold_alt_m = float(alt_m)

    def start_land(self, v):
        self.landing = True
        self.fly_to = None
        if self.hold_alt_m is None:
            self._alt_target_m = v.altitude_m()
        self.hold_alt_m = 0.0

    def start_flip(self, axis, t):
        self.flip_axis = axis
        self._flip_phase = 1
        self._flip_t0 = t
        self._flip_turned_rad = 0.0

    # --------------------------------------------------------------------- update
    def update(self, t, dt, v, euler=None):
        roll_stick = self.roll
        pitch_stick = self.pitch
        throttle = self.throttle
        roll, pitch, yaw = euler if euler is not None else v.euler_rad()
        cos_tilt = math.cos(roll) * math.cos(pitch)

        if self.hold_alt_m is not None:
            # Move the target toward the wanted altitude at a comfortable climb rate.
            # (The `: float` locals are C doubles on the compiled twin, as in sim/physics.py's Vehicle.step.)
            step: float = self.climb_rate_m_s * dt
            lo: float = -step * (0.5 if self.landing else 1.0)
            d: float = self.hold_alt_m - self._alt_target_m
            target: float = self._alt_target_m + (lo if d < lo else (step if d > step else d))
            self._alt_target_m = target
            err: float = target - -v.pd  # the altitude
            alt_i: float = self._alt_i
            if not v.on_ground:
                alt_i += err * dt * 0.15
                alt_i = -0.3 if alt_i < -0.3 else (0.3 if alt_i > 0.3 else alt_i)
                self._alt_i = alt_i
            thr: float = self.hover_guess + alt_i + 0.12 * err - 0.10 * -v.vd  # -vd: the climb rate
            if cos_tilt > 0.5:
                thr /= cos_tilt
            throttle = 0.0 if thr < 0.0 else (0.9 if thr > 0.9 else thr)
            if self.landing and v.on_ground and self._alt_target_m <= 0.05:
                if self._landed_s is None:
                    self._landed_s = t
                throttle = 0.0
                if t - self._landed_s > 0.5:
                    self.arm = False
                    self.landing = False
                    self.hold_alt_m = None
                    self.throttle = 0.0

        if self.fly_to is not None:
            # Angle mode: want a speed toward the point, tilt the sticks to get it.
            tn, te = self.fly_to
            vn_want = _clamp(0.8 * (tn - v.pn), -4.0, 4.0)
            ve_want = _clamp(0.8 * (te - v.pe), -4.0, 4.0)
            cy = math.cos(yaw)
            sy = math.sin(yaw)
            dvn = vn_want - v.vn
            dve = ve_want - v.ve
            fwd = cy * dvn + sy * dve
            right = -sy * dvn + cy * dve
            pitch_stick = _clamp(0.12 * fwd, -0.5, 0.5)
            roll_stick = _clamp(0.12 * right, -0.5, 0.5)

        if self._flip_phase:
            roll_stick, pitch_stick, throttle = self._flip(t, dt, v, roll, pitch, throttle)

        self.write(roll_stick, pitch_stick, self.yaw, throttle)

    def _flip(self, t, dt, v, roll, pitch, throttle):
        axis_rate = v.p if self.flip_axis == "roll" else v.q
        angle = roll if self.flip_axis == "roll" else pitch
        phase = self._flip_phase
        stick = 0.0
        if phase == 1:  # punch up for a moment to buy height
            throttle = 0.5 + 0.5 * self.hover_guess
            if t - self._flip_t0 > 0.25:
                self._flip_phase = 2
        elif phase == 2:  # full stick, throttle low while inverted
            self._flip_turned_rad += axis_rate * dt
            stick = 1.0
            throttle = 0.15
            # Let go early enough for the rate to come down: the pilot's lead.
            if self._flip_turned_rad > 2 * math.pi - abs(axis_rate) * 0.06:
                self._flip_phase = 3
                self._flip_t0 = t
        elif phase == 3:  # level out by hand in acro and recover height
            stick = _clamp(-2.0 * angle - 0.1 * axis_rate, -0.3, 0.3)
            if t - self._flip_t0 > 0.6:
                self._flip_phase = 0
                stick = 0.0
        if self.flip_axis == "roll":
            return stick, self.pitch, throttle
        # the pitch stick is forward-positive: a back flip (nose up) wants it pulled back
        return self.roll, -stick, throttle

    def write(self, roll: float, pitch: float, yaw: float, throttle: float):
        # Every step: the clamps are written out (a call each would be most of the cost); the stick positions
        # are C doubles on the compiled twin.
        ch = self.ch
        m = self.map
        ch[m[0]] = int(1500 + 500 * (-1.0 if roll < -1.0 else (1.0 if roll > 1.0 else roll)))
        ch[m[1]] = int(1500 + 500 * (-1.0 if pitch < -1.0 else (1.0 if pitch > 1.0 else pitch)))
        ch[m[3]] = int(1000 + 1000 * (0.0 if throttle < 0.0 else (1.0 if throttle > 1.0 else throttle)))
        ch[m[2]] = int(1500 + 500 * (-1.0 if yaw < -1.0 else (1.0 if yaw > 1.0 else yaw)))
        ch[m[ARM_CH]] = 2000 if self.arm else 1000
        ch[m[MODE_CH]] = MODE_US[self.mode]
        if self.overrides_us:
            for idx, us in self.overrides_us.items():
                ch[idx] = int(us)
