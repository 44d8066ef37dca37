"""The attitude estimator (Mahony) in fixed point: the gyro average, the update and the Euler angles as integers.

Takes the float stage's configured gains (core/stages/estimator.py `Mahony`), the pass's filtered gyro and
accelerometer, and the quaternion and gyro bias where the float stage keeps them (`Attitude.q`,
`Mahony.bias_rad_s`: float32 arrays, read and written as such, so either stage can run the next
update and nothing needs handing over); gives the quaternion, the bias and `Attitude.angles` (roll,
pitch, yaw in radians and the tilt cosine) with no float object made on MicroPython, where the float
update made about 123 of them a call (3.9 kB on the 64-bit VM). `FixedAttitude.step` runs every pass:
it sums the gyro and, every `every` passes (att_rate_hz), updates on the average, as Flight.step does
for the float stage. `att_pass` below is the one source of that arithmetic; on MicroPython its viper
twin (accel/att.py, generated from it by hoverfly.fastgen, docs/fastpass.md) is that method itself,
and tests/portable/test_fixedatt.py holds the two equal bit for bit.

Formats (value = integer / 2**q):
- gyro samples and their sum Q16, clamped to +-64 rad/s (2**22; gyros saturate near 35 rad/s), the
  average and the corrected rate Q22 (clamped to 2**28); accelerometer Q16, clamped to +-256 m/s^2;
  the bias Q30, clamped to +-0.5 rad/s; the quaternion, the rotation step, the angles and the tilt
  cosine Q28; the correction error Q29; the trust in the accelerometer Q15.
- The update's dt is the ticks summed over the averaged passes, clamped to 25 ms (the slowest
  att_rate_hz, 50 Hz, with room for jitter: a longer gap is a stall, not a step).
- Products of two wide words (the quaternion's) are `(a * b + 2**27) >> 28` with |a| < 2**30,
  |b| < 2**29 - 2**15 and a result within 2**30 (here at most |n|^2 < 3.7 times 1/|n| < 1.16, the
  other words within 1.91): `_mulw`, which the generated code builds from 15-bit halves; a gain or a dt
  times a word is `_mul`, `(c * x + 2**(s-1)) >> s` with |c| < 2**15, built from x's 16-bit halves.
  tests/test_fixedatt_bounds.py runs this twin with every intermediate checked against 2**31.
- The accelerometer is scaled by a power of two to 13-14 bits, its norm is an integer square root,
  and the measured down is its components over the norm (Q15); 1/|q| is an integer square root's
  reciprocal refined by two Newton steps; atan2 and asin are CORDIC (26 rotations, shifts and adds
  only): roll is atan2 of the rotation matrix's last row, whose length the same rotations give
  (cos pitch), so pitch is atan2(sin pitch, cos pitch).
Inputs that are not numbers (NaN) read as 0, infinities as the clamp; a quaternion whose squared
length is off 1 by more than a quarter (none that an update writes: a bad one written from outside,
or NaN) restarts at level.
"""

import math
from array import array

from hoverfly.compat import IS_MICROPYTHON, const
from hoverfly.core.fastpass.fixedmath import dec as _dec
from hoverfly.core.fastpass.fixedmath import mul as _mul
from hoverfly.core.fastpass.fixedmath import mulw as _mulw

# co: the gains (a 15-bit mantissa m and a shift s, value = m / 2**s), the averaging, then tables
CO_KP_M = const(0)
CO_KP_S = const(1)
CO_KPB_M = const(2)  # kp times the disarmed boost
CO_KPB_S = const(3)
CO_KI_M = const(4)  # ki * 2**15 * 1e-6: the bias step in Q30 from e * dt_us in Q15
CO_KI_S = const(5)
CO_KI_ON = const(6)
CO_EVERY = const(7)  # passes averaged per update
CO_DT_NOM = const(8)  # one pass's µs at loop_hz, for a pass whose ticks did not advance
CO_K = const(9)  # the CORDIC gain, Q28
CO_ATAN = const(10)  # atan(2**-i) in Q28, i < N_CORDIC
N_CORDIC = const(26)
CO_SIZE = const(36)

# st: the gyro sum (Q16), the passes summed, their µs
S_GSUM = const(0)
S_N = const(3)
S_US = const(4)
ST_SIZE = const(8)

F_ARMED = const(1)
# att_pass's result: the update ran, and it wrote the bias
R_UPDATED = const(1)
R_BIAS = const(2)

_G_LIM = const(0x400000)  # 2**22: 64 rad/s in Q16
_A_LIM = const(0x1000000)  # 2**24: 256 m/s^2 in Q16
_B_LIM = const(0x20000000)  # 2**29: 0.5 rad/s in Q30
_Q_LIM = const(0x10000000)  # 2**28: 1 in Q28
_R_LIM = const(0x10000000)  # 2**28: 64 rad/s in Q22
_ONE28 = const(0x10000000)
_Q2_LO = const(0xC000000)  # |q|^2 of 0.75 and 1.25, Q28: the quaternions taken as they are
_Q2_HI = const(0x14000000)
_ONE15 = const(32768)
_DT_MAX = const(25000)
_G16 = const(642690)  # 9.80665 m/s^2 in Q16
_DEV5 = const(32134)  # 5 % of 1 g in Q16: trusted fully below
_DEV10 = const(64269)  # 10 %: not at all beyond
_TRUST_K = const(33414)  # 20 / 1 g in Q15 per Q16 of |a| - g: (0.1 - dev) * 20 as Q15, over 2**15
_HALF_PI = const(421657428)  # pi / 2 in Q28
_DT_K = const(25468)  # 2**15 / 31250 - 1 = 0.048576, over 2**19: Q22 rad/s * µs to a Q28 half-angle
_INV28 = 1.0 / 268435456.0
_INV30 = 1.0 / 1073741824.0

# The CORDIC gain of N_CORDIC rotations, Q28 (1.6467602...)
_k = 1.0
for _i in range(N_CORDIC):
    _k *= math.sqrt(1.0 + 2.0 ** (-2 * _i))
_CORDIC_K = int(_k * 268435456.0 + 0.5)

_viper = None
if IS_MICROPYTHON:
    try:  # generated from att_pass below by hoverfly.fastgen; absent, or a port without viper: the Python runs
        from hoverfly.accel import att as _viper
    except (ImportError, SyntaxError, NameError, ValueError, TypeError):  # TypeError: ViperTypeError
        pass
HAS_ACCEL = _viper is not None


def coef(value, cap=40):
    """(m, s) with value ~ m / 2**s, 2**14 <= |m| < 2**15 (smaller only where s would pass `cap`)."""
    if value <= 0:
        return 0, 0
    s = 0
    while value * (1 << s) < 16384.0 and s < cap:
        s += 1
    m = int(value * (1 << s) + 0.5)
    if m >= 32768:
        if s == 0:
            raise ValueError("coefficient out of range")
        s -= 1
        m = int(value * (1 << s) + 0.5)
    return m, s


def _isqrt(n):
    """floor(sqrt(n)) for 0 <= n < 2**31, bit by bit."""
    r = 0
    b = 0x40000000
    while b > n:
        b >>= 2
    while b:
        if n >= r + b:
            n -= r + b
            r = (r >> 1) + b
        else:
            r >>= 1
        b >>= 2
    return r


def _atan2(co, y, x):
    """(atan2(y, x) in Q28, the CORDIC gain times |(x, y)|): vectoring rotations, shifts and adds."""
    z = 0
    if x < 0:  # a quarter turn into the right half-plane first
        if y >= 0:
            x, y = y, -x
            z = _HALF_PI
        else:
            x, y = -y, x
            z = -_HALF_PI
    for i in range(N_CORDIC):
        if y > 0:
            x, y = x + (y >> i), y - (x >> i)
            z += co[CO_ATAN + i]
        else:
            x, y = x - (y >> i), y + (x >> i)
            z -= co[CO_ATAN + i]
    return z, x


# fastpass: FixedAttitude.step co:i st:i gyro:f accel:f qa:f ang:f bias:f
def att_pass(co, st, io, flags, dt_us):
    """One pass (the Python twin): io = (gyro rad/s[3], accel m/s^2[3], quaternion[4], angles[4], bias
    rad/s[3]), float arrays. Sums the gyro; every co[CO_EVERY] passes updates the quaternion, the
    bias and the angles from the average. Returns R_UPDATED | R_BIAS as they happened, else 0."""
    gyro, accel, qa, ang, bias = io
    if dt_us > _DT_MAX:
        dt_us = _DT_MAX
    elif dt_us < -_DT_MAX:
        dt_us = -_DT_MAX
    gs0 = st[S_GSUM] + _dec(gyro[0], 65536.0, _G_LIM)
    gs1 = st[S_GSUM + 1] + _dec(gyro[1], 65536.0, _G_LIM)
    gs2 = st[S_GSUM + 2] + _dec(gyro[2], 65536.0, _G_LIM)
    us = st[S_US] + dt_us
    n = st[S_N] + 1
    if n < co[CO_EVERY]:
        st[S_GSUM] = gs0
        st[S_GSUM + 1] = gs1
        st[S_GSUM + 2] = gs2
        st[S_US] = us
        st[S_N] = n
        return 0
    st[S_GSUM] = st[S_GSUM + 1] = st[S_GSUM + 2] = 0
    st[S_US] = 0
    st[S_N] = 0
    dt = us if us > 0 else n * co[CO_DT_NOM]
    if dt > _DT_MAX:
        dt = _DT_MAX
    g = [0, 0, 0]
    for i, s in enumerate((gs0, gs1, gs2)):  # the average, Q16 sum to Q22, truncated toward 0
        a = s if s >= 0 else -s
        d = a // n
        v = (d << 6) + (((a - d * n) << 6) // n)
        g[i] = v if s >= 0 else -v
    w = _dec(qa[0], 268435456.0, _Q_LIM)
    x = _dec(qa[1], 268435456.0, _Q_LIM)
    y = _dec(qa[2], 268435456.0, _Q_LIM)
    z = _dec(qa[3], 268435456.0, _Q_LIM)
    q2 = _mulw(w, w) + _mulw(x, x) + _mulw(y, y) + _mulw(z, z)
    if q2 < _Q2_LO or q2 > _Q2_HI:  # not a quaternion an update wrote (none, or a bad one): start level
        w = _ONE28
        x = y = z = 0
    b = [_dec(bias[0], 1073741824.0, _B_LIM), _dec(bias[1], 1073741824.0, _B_LIM),
         _dec(bias[2], 1073741824.0, _B_LIM)]
    acc = [_dec(accel[0], 65536.0, _A_LIM), _dec(accel[1], 65536.0, _A_LIM), _dec(accel[2], 65536.0, _A_LIM)]
    result = R_UPDATED
    # the accelerometer: its length (how far from 1 g: the trust) and its direction, 13-14 bits
    m = 0
    for v in acc:
        if v < 0:
            v = -v
        if v > m:
            m = v
    trust = 0
    e = [0, 0, 0]
    if m > 0:
        sh = 0
        while (m >> sh) >= 0x4000:
            sh += 1
        ls = 0
        while (m << ls) < 0x2000:
            ls += 1
        an = [0, 0, 0]
        for i in range(3):
            v = acc[i]
            a = v if v >= 0 else -v
            a = (a >> sh) << ls
            an[i] = a if v >= 0 else -a
        nrm = _isqrt(an[0] * an[0] + an[1] * an[1] + an[2] * an[2])
        norm = (nrm << sh) >> ls  # |a|, Q16
        d = norm - _G16
        if d < 0:
            d = -d
        if d < _DEV5:
            trust = _ONE15
        elif d < _DEV10:
            trust = ((_DEV10 - d) * _TRUST_K) >> 15
            if trust > _ONE15:
                trust = _ONE15
        if trust:
            u = [0, 0, 0]  # the measured down: the specific force's opposite, Q15
            for i in range(3):
                v = an[i]
                a = ((v if v >= 0 else -v) << 15) // nrm
                u[i] = -a if v >= 0 else a
            # the estimated down (NED z in the body frame) from the quaternion, Q14
            vx = (2 * (_mulw(x, z) - _mulw(w, y)) + 8192) >> 14
            vy = (2 * (_mulw(w, x) + _mulw(y, z)) + 8192) >> 14
            vz = (_mulw(w, w) - _mulw(x, x) - _mulw(y, y) + _mulw(z, z) + 8192) >> 14
            # the rotation that takes the estimate onto the measurement, Q29
            e[0] = u[1] * vz - u[2] * vy
            e[1] = u[2] * vx - u[0] * vz
            e[2] = u[0] * vy - u[1] * vx
            if trust != _ONE15:
                for i in range(3):
                    e[i] = _mul(trust, e[i], 15)
            if co[CO_KI_ON]:
                for i in range(3):
                    v = b[i] - _mul(co[CO_KI_M], _mul(dt, e[i], 14), co[CO_KI_S])
                    if v > _B_LIM:
                        v = _B_LIM
                    elif v < -_B_LIM:
                        v = -_B_LIM
                    b[i] = v
                result |= R_BIAS
    if flags & F_ARMED:
        km = co[CO_KP_M]
        ks = co[CO_KP_S] + 7
    else:
        km = co[CO_KPB_M]
        ks = co[CO_KPB_S] + 7
    t = [0, 0, 0]
    for i in range(3):
        r = g[i] - ((b[i] + 128) >> 8)
        if trust:
            r += _mul(km, e[i], ks)
        if r > _R_LIM:
            r = _R_LIM
        elif r < -_R_LIM:
            r = -_R_LIM
        v = _mul(dt, r, 15)  # r * dt / 2: Q22 * µs / 31250 is the Q28 half-angle
        t[i] = v + _mul(_DT_K, v, 19)
    tx, ty, tz = t
    nw = w - _mulw(x, tx) - _mulw(y, ty) - _mulw(z, tz)
    nx = x + _mulw(w, tx) + _mulw(y, tz) - _mulw(z, ty)
    ny = y + _mulw(w, ty) - _mulw(x, tz) + _mulw(z, tx)
    nz = z + _mulw(w, tz) + _mulw(x, ty) - _mulw(y, tx)
    # |n| >= |q| >= 0.87 (a rotation does not shorten it): 1/|n| is within 1.16, and n2 within 3.7
    n2 = _mulw(nw, nw) + _mulw(nx, nx) + _mulw(ny, ny) + _mulw(nz, nz)
    inv = (0x40000000 // _isqrt(n2)) << 12  # 1/|n|, Q28, to 2**-14
    for _ in range(2):  # Newton: inv += inv * (1 - n2 * inv^2) / 2
        r = _mulw(_mulw(n2, inv), inv)
        inv += _mulw(inv, _ONE28 - r) >> 1
    w = _mulw(nw, inv)
    x = _mulw(nx, inv)
    y = _mulw(ny, inv)
    z = _mulw(nz, inv)
    qa[0] = w * _INV28
    qa[1] = x * _INV28
    qa[2] = y * _INV28
    qa[3] = z * _INV28
    if result & R_BIAS:
        bias[0] = b[0] * _INV30
        bias[1] = b[1] * _INV30
        bias[2] = b[2] * _INV30
    # the angles (Attitude.set_from's): roll and yaw from the rotation matrix, pitch from its last row
    xx = _mulw(x, x)
    yy = _mulw(y, y)
    c = _ONE28 - 2 * (xx + yy)
    roll, cp = _atan2(co, 2 * (_mulw(w, x) + _mulw(y, z)), c)
    s = 2 * (_mulw(w, y) - _mulw(z, x))
    if s > _ONE28:
        s = _ONE28
    elif s < -_ONE28:
        s = -_ONE28
    pitch = _atan2(co, _mulw(s, _CORDIC_K), cp)[0]  # cp is cos(pitch) times the CORDIC gain
    yaw = _atan2(co, 2 * (_mulw(w, z) + _mulw(x, y)), _ONE28 - 2 * (yy + _mulw(z, z)))[0]
    ang[0] = roll * _INV28
    ang[1] = pitch * _INV28
    ang[2] = yaw * _INV28
    ang[3] = c * _INV28
    return result


def _fill_tables(co):
    co[CO_K] = _CORDIC_K
    for i in range(N_CORDIC):
        co[CO_ATAN + i] = int(math.atan(2.0 ** -i) * 268435456.0 + 0.5)


class FixedAttitude:
    """The Mahony update of a flight as one fixed-point pass (see the module docstring).

    `configure(mahony, attitude, signals, loop_hz, every, on)` returns whether the fixed pass runs:
    it reads the float stage's configured gains. `step(dt_us, armed)` then stands in, every pass, for
    Flight.step's gyro average and `Mahony.update`. The quaternion and the bias stay in the float
    stage's arrays, so `release()` has nothing to hand back, and `Mahony.level_from_accel` or `reset`
    between steps are seen by the next one."""

    def __init__(self):
        self.co = array("i", [0] * CO_SIZE)
        self.st = array("i", [0] * ST_SIZE)
        _fill_tables(self.co)
        self.active = False
        # Also set the Attitude's float attributes (roll_rad ...) after each update, as the float
        # stage does: 4 floats a call, for the readers that have not moved to Attitude.angles.
        self.angle_floats = True
        self._io = None
        # the viper twin's table of the arrays' addresses (accel/att.py), written by configure
        self._tab = array("i", [0] * _viper.TAB_SIZE) if HAS_ACCEL else None
        self._mahony = None
        self._attitude = None

    def configure(self, mahony, attitude, signals, loop_hz, every, on):
        """Call after the float stage's configure; the gyro sum starts again."""
        self.release()
        if not on or every > 255:
            return False
        co = self.co
        co[CO_KP_M], co[CO_KP_S] = coef(mahony.kp)
        co[CO_KPB_M], co[CO_KPB_S] = coef(mahony.kp * mahony.boost)
        co[CO_KI_M], co[CO_KI_S] = coef(mahony.ki * 0.032768)
        co[CO_KI_ON] = 1 if mahony.ki > 0 else 0
        co[CO_EVERY] = every if every > 1 else 1
        co[CO_DT_NOM] = 1000000 // loop_hz
        st = self.st
        for i in range(ST_SIZE):
            st[i] = 0
        self._mahony = mahony
        self._attitude = attitude
        self._io = (signals.gyro_rad_s, signals.accel_m_s2, attitude.q, attitude.angles, mahony.bias_rad_s)
        if HAS_ACCEL:
            tab = self._tab
            _viper.bind(tab, 0, co)
            _viper.bind(tab, 1, st)
            for k in range(5):
                _viper.bind(tab, 2 + k, self._io[k])
            _viper.bind(tab, 7, _viper.LOG2)
        self.active = True
        return True

    def release(self):
        """The fixed pass stops (its state is the float stage's own; the gyro sum is dropped)."""
        self.active = False

    def step(self, dt_us, armed):
        """This pass's gyro into the average, and the update when it is due (Flight.step's step 2);
        returns att_pass's result. On MicroPython the viper twin (accel/att.py `step`) stands in for
        this method; `step_python` keeps it."""
        r = att_pass(self.co, self.st, self._io, F_ARMED if armed else 0, dt_us)
        if r & R_BIAS:
            self._mahony._bias_zero = False
        if r and self.angle_floats:
            self._attitude.set_from_angles()
        return r


step_python = FixedAttitude.step
if HAS_ACCEL:
    FixedAttitude.step = _viper.step
