"""Attitude: board alignment, boot gyro calibration, and the Mahony quaternion filter.

Takes body-frame (FRD) gyro in rad/s and accelerometer in m/s²; gives the attitude
quaternion (body to NED, w x y z), Euler angles in radians (roll right, pitch up, yaw
right positive) and the gyro-bias estimate. An external source (an IMU that fuses on
its own, like the BNO055 of seed 001) can replace the filter: ExternalAttitude takes
its quaternion instead. Step 2 of the pass.
"""

import math
from array import array

_DEG = math.pi / 180.0
_G = 9.80665


class BoardAlignment:
    """Rotates sensor vectors by the board's mounting angles (roll, pitch, yaw in degrees)."""

    def __init__(self):
        self.m = array("f", [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])
        self.identity = True

    def configure(self, params):
        r = params.get("board_roll_deg") * _DEG
        p = params.get("board_pitch_deg") * _DEG
        y = params.get("board_yaw_deg") * _DEG
        self.identity = r == 0 and p == 0 and y == 0
        cr, sr = math.cos(r), math.sin(r)
        cp, sp = math.cos(p), math.sin(p)
        cy, sy = math.cos(y), math.sin(y)
        # v_body = R(yaw) R(pitch) R(roll) v_sensor: the sensor is turned by these angles in the frame.
        m = self.m
        m[0] = cy * cp
        m[1] = cy * sp * sr - sy * cr
        m[2] = cy * sp * cr + sy * sr
        m[3] = sy * cp
        m[4] = sy * sp * sr + cy * cr
        m[5] = sy * sp * cr - cy * sr
        m[6] = -sp
        m[7] = cp * sr
        m[8] = cp * cr

    def apply(self, v):
        if self.identity:
            return
        m = self.m
        x = v[0]
        y = v[1]
        z = v[2]
        v[0] = m[0] * x + m[1] * y + m[2] * z
        v[1] = m[3] * x + m[4] * y + m[5] * z
        v[2] = m[6] * x + m[7] * y + m[8] * z


class GyroCalibration:
    """Averages the gyro while the craft is still (seed 000: average before arming).

    Restarts whenever any axis moves further than `gyro_cal_dps` from the running mean.
    `bias_rad_s` is valid once `calibrated` is True.
    """

    def __init__(self):
        self.bias_rad_s = array("f", [0.0, 0.0, 0.0])
        self._sum = array("f", [0.0, 0.0, 0.0])
        self._first = array("f", [0.0, 0.0, 0.0])
        self.calibrated = False
        self.restarts = 0
        self._count = 0
        self._needed = 1000
        self._limit_rad_s = 4.0 * _DEG

    def configure(self, params, loop_hz):
        self._needed = int(params.get("gyro_cal_ms") * loop_hz // 1000)
        if self._needed < 1:
            self._needed = 1
        self._limit_rad_s = params.get("gyro_cal_dps") * _DEG

    def reset(self):
        self.calibrated = False
        self._count = 0

    def update(self, gyro_rad_s):
        """Feed one raw sample; returns True when calibration completed on this sample."""
        if self.calibrated:
            return False
        s = self._sum
        if self._count == 0:
            for i in range(3):
                self._first[i] = gyro_rad_s[i]
                s[i] = 0.0
        lim = self._limit_rad_s
        for i in range(3):
            d = gyro_rad_s[i] - self._first[i]
            if not (-lim <= d <= lim):  # NaN too (a NaN or an infinity makes d NaN): no bias from them
                self._count = 0
                self.restarts += 1
                return False
            s[i] += d
        self._count += 1
        if self._count >= self._needed:
            n = self._count
            for i in range(3):
                self.bias_rad_s[i] = self._first[i] + s[i] / n
            self.calibrated = True
            return True
        return False


# Attitude.angles: roll_rad, pitch_rad, yaw_rad, cos_tilt
ROLL = 0
PITCH = 1
YAW = 2
COS_TILT = 3


class Attitude:
    """The estimate every stage reads: quaternion body->NED and Euler angles in radians.

    The angles are both attributes and the array `angles` (ROLL, PITCH, YAW, COS_TILT): the fixed-point
    estimator (core/fastpass/fixedatt.py) writes the array without making a float object, and the attributes
    from it when asked (`set_from_angles`)."""

    def __init__(self):
        self.q = array("f", [1.0, 0.0, 0.0, 0.0])
        self.angles = array("f", [0.0, 0.0, 0.0, 1.0])
        self.roll_rad = 0.0
        self.pitch_rad = 0.0
        self.yaw_rad = 0.0
        self.cos_tilt = 1.0  # cosine of the angle between body z and down

    def set_from_angles(self):
        """The attributes from `angles` (after the fixed-point estimator wrote it)."""
        a = self.angles
        self.roll_rad = a[0]
        self.pitch_rad = a[1]
        self.yaw_rad = a[2]
        self.cos_tilt = a[3]

    def set_from_quaternion(self):
        q = self.q
        self.set_from(q[0], q[1], q[2], q[3])

    def set_from(self, w, x, y, z):
        """Euler angles and tilt from the quaternion's components (already stored in `q`)."""
        # 1 - 2(x² + y²) is both roll's denominator and the tilt cosine: worked out once.
        c = 1.0 - 2.0 * (x * x + y * y)
        self.roll_rad = math.atan2(2.0 * (w * x + y * z), c)
        s = 2.0 * (w * y - z * x)
        if s > 1.0:
            s = 1.0
        elif s < -1.0:
            s = -1.0
        self.pitch_rad = math.asin(s)
        self.yaw_rad = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        self.cos_tilt = c
        a = self.angles
        a[0] = self.roll_rad
        a[1] = self.pitch_rad
        a[2] = self.yaw_rad
        a[3] = c


class Mahony:
    """Mahony complementary filter on the quaternion.

    The accelerometer's gravity direction corrects the gyro integration with gain kp;
    the integral of the correction (gain ki) estimates the remaining gyro bias. The
    correction fades out when |accel| is more than 5-10 % from 1 g (manoeuvres, impacts), and runs
    ten times stronger while disarmed so the estimate settles quickly on the bench.
    """

    def __init__(self):
        self.bias_rad_s = array("f", [0.0, 0.0, 0.0])
        self.kp = 0.25
        self.ki = 0.01
        self.boost = 10.0
        # True while bias_rad_s holds zeros (no bias integral yet): the pass then skips reading it.
        self._bias_zero = True

    def configure(self, params):
        self.kp = params.get("imu_dcm_kp") * 1e-4
        self.ki = params.get("imu_dcm_ki") * 1e-4

    def reset(self, attitude):
        q = attitude.q
        q[0] = 1.0
        q[1] = 0.0
        q[2] = 0.0
        q[3] = 0.0
        for i in range(3):
            self.bias_rad_s[i] = 0.0
        self._bias_zero = True
        attitude.set_from_quaternion()

    def level_from_accel(self, accel_m_s2, attitude):
        """Set roll and pitch straight from the accelerometer (yaw 0): a good start at boot."""
        ax = accel_m_s2[0]
        ay = accel_m_s2[1]
        az = accel_m_s2[2]
        roll = math.atan2(-ay, -az)
        pitch = math.atan2(ax, math.sqrt(ay * ay + az * az))
        cr = math.cos(roll * 0.5)
        sr = math.sin(roll * 0.5)
        cp = math.cos(pitch * 0.5)
        sp = math.sin(pitch * 0.5)
        q = attitude.q
        q[0] = cr * cp
        q[1] = sr * cp
        q[2] = cr * sp
        q[3] = -sr * sp
        attitude.set_from_quaternion()

    def update(self, gyro_rad_s, accel_m_s2, dt_s, armed, attitude):
        q = attitude.q
        w = q[0]
        x = q[1]
        y = q[2]
        z = q[3]
        gx = gyro_rad_s[0]
        gy = gyro_rad_s[1]
        gz = gyro_rad_s[2]
        ax = accel_m_s2[0]
        ay = accel_m_s2[1]
        az = accel_m_s2[2]
        norm = math.sqrt(ax * ax + ay * ay + az * az)
        trust = 0.0
        if norm > 0.1:
            # A multirotor's accelerometer sees thrust, not gravity, while it manoeuvres: trust it
            # fully within 5 % of 1 g, not at all beyond 10 % (Betaflight ignores it beyond 10 %).
            dev = norm / _G - 1.0
            if dev < 0:
                dev = -dev
            if dev < 0.05:
                trust = 1.0
            elif dev <= 0.1:
                trust = (0.1 - dev) * 20.0
        if trust != 0.0:
            kp = self.kp
            if not armed:
                kp *= self.boost
            inv = -1.0 / norm  # specific force points up: gravity's direction is its negative
            ax *= inv
            ay *= inv
            az *= inv
            # Estimated "down" (NED z) in the body frame.
            vx = 2.0 * (x * z - w * y)
            vy = 2.0 * (w * x + y * z)
            vz = w * w - x * x - y * y + z * z
            # Error: rotation that takes the estimate onto the measurement (x 1.0 is exact: skipped).
            ex = ay * vz - az * vy
            ey = az * vx - ax * vz
            ez = ax * vy - ay * vx
            if trust != 1.0:
                ex *= trust
                ey *= trust
                ez *= trust
            if self.ki > 0:
                b = self.bias_rad_s
                ki = self.ki
                b[0] -= ki * ex * dt_s
                b[1] -= ki * ey * dt_s
                b[2] -= ki * ez * dt_s
                self._bias_zero = False
            if self._bias_zero:
                gx += kp * ex
                gy += kp * ey
                gz += kp * ez
            else:
                b = self.bias_rad_s
                gx += kp * ex - b[0]
                gy += kp * ey - b[1]
                gz += kp * ez - b[2]
        elif not self._bias_zero:
            # No usable gravity (free fall, impact, or more than 10 % off 1 g): gyro only.
            b = self.bias_rad_s
            gx -= b[0]
            gy -= b[1]
            gz -= b[2]
        h = 0.5 * dt_s
        gx *= h
        gy *= h
        gz *= h
        nw = w - x * gx - y * gy - z * gz
        nx = x + w * gx + y * gz - z * gy
        ny = y + w * gy - x * gz + z * gx
        nz = z + w * gz + x * gy - y * gx
        inv = 1.0 / math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
        q[0] = nw * inv
        q[1] = nx * inv
        q[2] = ny * inv
        q[3] = nz * inv
        attitude.set_from_quaternion()


class ExternalAttitude:
    """Attitude from an IMU that fuses on its own (BNO055-style, seed 001).

    The board supplies the quaternion; the first one after boot can be taken as the
    level reference (seed 001 takes its first roll/pitch as the IMU offset).
    """

    def __init__(self):
        self.bias_rad_s = array("f", [0.0, 0.0, 0.0])

    def configure(self, params):
        pass

    def reset(self, attitude):
        attitude.set_from_quaternion()

    def level_from_accel(self, accel_m_s2, attitude):
        pass

    def update_from_quaternion(self, q_in, attitude):
        q = attitude.q
        q[0] = q_in[0]
        q[1] = q_in[1]
        q[2] = q_in[2]
        q[3] = q_in[3]
        attitude.set_from_quaternion()
