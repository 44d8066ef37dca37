"""The mixer: collective throttle and per-axis torque to motor commands, table driven.

Each frame is a table of rows (throttle, roll, pitch, yaw) per motor in the body
frame FRD: positive roll torque rolls right, positive pitch raises the nose, positive
yaw turns the nose right. A motor on the right gets a negative roll weight, a front
motor a positive pitch weight, a motor whose prop turns counter-clockwise seen from
above a positive yaw weight (its reaction torque turns the frame clockwise).

Presets: `quadx` is Betaflight's motor order (1 rear right, 2 front right, 3 rear left,
4 front left; Betaflight's pitch column has the opposite sign because Betaflight counts
nose-down as positive). `quadx_seed000` is the PicoFlight table of seed 000 taken
literally in this frame, which puts M1 front right, M2 rear right, M3 front left, M4 rear
left. `quadp`, `hexx` (Betaflight order) and `tri` (three motors, yaw by a tail servo). The
planes (`airplane`, `flying_wing`, `vtail`: `is_plane`) have one motor on the throttle; their
surfaces are mixed by the servo mixer (core/stages/servos.py) from the same torque commands.

Desaturation keeps attitude authority: when the torque mix spans more than the motor
range it is scaled down as a whole (ratios kept); otherwise throttle is shifted so no
motor clips (air mode) — Betaflight's approach. Step 5 of the pass.
"""

from array import array

_H = 0.8660254037844386

MIXER_TABLES = {
    # throttle, roll, pitch, yaw
    "quadx": (
        (1.0, -1.0, -1.0, -1.0),  # 1 rear right, CW
        (1.0, -1.0, 1.0, 1.0),  # 2 front right, CCW
        (1.0, 1.0, -1.0, 1.0),  # 3 rear left, CCW
        (1.0, 1.0, 1.0, -1.0),  # 4 front left, CW
    ),
    "quadx_seed000": (
        (1.0, -1.0, 1.0, -1.0),  # M1 front right, CW
        (1.0, -1.0, -1.0, 1.0),  # M2 rear right, CCW
        (1.0, 1.0, 1.0, 1.0),  # M3 front left, CCW
        (1.0, 1.0, -1.0, -1.0),  # M4 rear left, CW
    ),
    "quadp": (
        (1.0, 0.0, -1.0, -1.0),  # 1 rear
        (1.0, -1.0, 0.0, 1.0),  # 2 right
        (1.0, 1.0, 0.0, 1.0),  # 3 left
        (1.0, 0.0, 1.0, -1.0),  # 4 front
    ),
    "hexx": (
        (1.0, -0.5, -_H, 1.0),  # 1 rear right
        (1.0, -0.5, _H, 1.0),  # 2 front right
        (1.0, 0.5, -_H, -1.0),  # 3 rear left
        (1.0, 0.5, _H, -1.0),  # 4 front left
        (1.0, -1.0, 0.0, -1.0),  # 5 right
        (1.0, 1.0, 0.0, 1.0),  # 6 left
    ),
    "tri": (
        (1.0, 0.0, -1.333333, 0.0),  # 1 rear (on the yaw servo)
        (1.0, -1.0, 0.666667, 0.0),  # 2 front right
        (1.0, 1.0, 0.666667, 0.0),  # 3 front left
    ),
    # Planes: one motor on the throttle alone; the surfaces are the servo mixer's (core/stages/servos.py).
    "airplane": ((1.0, 0.0, 0.0, 0.0),),
    "flying_wing": ((1.0, 0.0, 0.0, 0.0),),
    "vtail": ((1.0, 0.0, 0.0, 0.0),),
}

# INAV's fixed-wing platforms: surfaces on servos, one motor.
PLANE_TYPES = ("airplane", "flying_wing", "vtail")


def is_plane(mixer_type):
    """True for a fixed-wing mixer_type: the one test the controller, commander and failsafe pick by."""
    return mixer_type in PLANE_TYPES

# Frames whose yaw comes from a servo rather than from prop torque: (servo index, sign).
SERVO_YAW = {"tri": (0, 1.0)}

MAX_MOTORS = 8


def motor_count(frame):
    return len(MIXER_TABLES[frame])


class Mixer:
    def __init__(self):
        self.n = 4
        self.roll_w = array("f", [0.0] * MAX_MOTORS)
        self.pitch_w = array("f", [0.0] * MAX_MOTORS)
        self.yaw_w = array("f", [0.0] * MAX_MOTORS)
        self._mix = array("f", [0.0] * MAX_MOTORS)
        # The weights as one tuple of floats per motor (float32 values, as the arrays hold them):
        # reading an array element boxes a new float on MicroPython, a tuple item does not.
        self._rows = ((0.0, 0.0, 0.0),) * MAX_MOTORS
        self.saturated = False
        self.airmode = True
        self.servo_yaw = False
        self.servo_norm = array("f", [0.0])

    def configure(self, params):
        frame = params.get("mixer_type")
        table = MIXER_TABLES[frame]
        self.n = len(table)
        yaw_sign = -1.0 if params.get("yaw_motors_rev") else 1.0
        for i in range(MAX_MOTORS):
            if i < self.n:
                self.roll_w[i] = table[i][1]
                self.pitch_w[i] = table[i][2]
                self.yaw_w[i] = table[i][3] * yaw_sign
            else:
                self.roll_w[i] = 0.0
                self.pitch_w[i] = 0.0
                self.yaw_w[i] = 0.0
        rows = []
        for i in range(self.n):
            rows.append((self.roll_w[i], self.pitch_w[i], self.yaw_w[i]))
        self._rows = tuple(rows)
        self.servo_yaw = frame in SERVO_YAW
        self.airmode = bool(params.get("airmode"))

    def update(self, throttle_norm, torque_norm, airmode_active, motor_norm):
        """Fill motor_norm[0..n-1] in 0..1 from throttle 0..1 and torques; sets `saturated`."""
        r = torque_norm[0]
        p = torque_norm[1]
        y = torque_norm[2]
        mix = self._mix
        lo = 1e9
        hi = -1e9
        i = 0
        for row in self._rows:
            m = r * row[0] + p * row[1] + y * row[2]
            mix[i] = m
            i += 1
            if m < lo:
                lo = m
            if m > hi:
                hi = m
        n = i
        span = hi - lo
        saturated = False
        if span > 1.0:
            # More torque asked than the motors can give: keep the ratios, give up collective.
            scale = 1.0 / span
            for i in range(n):
                mix[i] *= scale
            lo *= scale
            hi *= scale
            throttle = 0.5 if airmode_active else throttle_norm
            saturated = True
        else:
            throttle = throttle_norm
        if airmode_active or span > 1.0:
            # Shift the collective so that no motor clips (air mode).
            if throttle + hi > 1.0:
                throttle = 1.0 - hi
            if throttle + lo < 0.0:
                throttle = -lo
        for i in range(n):
            m = throttle + mix[i]
            if m < 0.0:
                m = 0.0
                saturated = True
            elif m > 1.0:
                m = 1.0
                saturated = True
            motor_norm[i] = m
        if self.servo_yaw:
            s = y * 2.0
            if s > 1.0:
                s = 1.0
            elif s < -1.0:
                s = -1.0
            self.servo_norm[0] = s
        self.saturated = saturated
