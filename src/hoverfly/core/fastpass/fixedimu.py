"""The IMU filters of the pass in fixed point: the gyro's PT1 and the accelerometer's PT2 as integers.

Takes the float filter stages' configured gains (core/stages/filters.py `GyroFilter`, `AccelFilter`) and
the pass's sample arrays; gives the filtered gyro and accelerometer in the same arrays as the float
stages, with no float object made on MicroPython. Every float result there is a heap object: the
float filters make 39 of them a pass (1.2 kB on the 64-bit VM, bench/core_stages.py), and what the
pass allocates sets how often the board must collect. `FixedImuFilter` runs the filters on small
integers instead: `filter_pass` below is the one source of that arithmetic. On MicroPython its viper
twin (accel/imufilter.py, generated from it by hoverfly.fastgen, docs/fastpass.md) stands in for
`update`; tests/portable/test_fixedimu.py holds the two equal bit for bit.

Chosen with the fixed rate loop (core/fastpass/fixedrate.py): where `pid_math` runs the controller and
mixer in fixed point, the IMU filters go too, for the default gyro chain only (low-pass 1 a PT1,
low-pass 2 and the notch off); any other chain keeps the float stages.

Formats (value = integer / 2**q): samples and filter state Q16; the gyro and its calibration bias
clamped to +-128 rad/s (2**23), the accelerometer to +-256 m/s^2 (2**24, 26 g); gains Q15 (a
gain of 1, a filter that is off, is 2**15). A step is `y += floor((k * (x - y) + 2**14) / 2**15)`;
|x - y| < 2**25, so the viper twin's product on x's 16-bit halves stays below 2**31. Inputs that
are not numbers (NaN) read as 0, infinities as the clamp. A Q16 PT1 settles within half an LSB
over k of its input: 1e-5 rad/s for the gyro's default 250 Hz, 2e-4 m/s^2 for the accelerometer's
25 Hz.
"""

from array import array

from hoverfly.compat import IS_MICROPYTHON, const
from hoverfly.core.fastpass.fixedmath import dec as _dec
from hoverfly.core.fastpass.fixedmath import mul as _mul

# co: the gyro PT1's gain per axis, then the accelerometer PT2's stage gain per axis (Q15)
CO_GYRO_K = const(0)
CO_ACC_K = const(3)
CO_SIZE = const(6)
# st: the gyro PT1's output per axis, the accelerometer PT2's first stage and output per axis (Q16);
# st[9..17] hold the viper twin's decoded inputs
S_GYRO = const(0)
S_ACC1 = const(3)
S_ACC2 = const(6)
ST_SIZE = const(18)

_ONE15 = const(32768)
_GYRO_LIM = const(0x800000)  # 2**23: 128 rad/s in Q16
_ACC_LIM = const(0x1000000)  # 2**24: 256 m/s^2 in Q16
_Q16 = 65536.0
_INV16 = 1.0 / 65536.0

_viper = None
if IS_MICROPYTHON:
    try:  # generated from filter_pass below by hoverfly.fastgen; absent, or a port without viper: the Python runs
        from hoverfly.accel import imufilter as _viper
    except (ImportError, SyntaxError, NameError, ValueError, TypeError):  # TypeError: ViperTypeError
        pass
HAS_ACCEL = _viper is not None


def _step(k, x, y):
    """One PT1 step in Q16 with a Q15 gain: y + floor((k * (x - y) + 2**14) / 2**15)."""
    return y + _mul(k, x - y, 15)


# fastpass: FixedImuFilter.update co:i st:i graw:f bias:f gout:f araw:f aout:f
def filter_pass(co, st, io):
    """One pass of both filters (the Python twin): io = (gyro raw, gyro bias, gyro out, accel raw,
    accel out), arrays of three; the outputs are written as floats."""
    graw, bias, gout, araw, aout = io
    for i in range(3):
        y = _step(co[CO_GYRO_K + i], _dec(graw[i], _Q16, _GYRO_LIM) - _dec(bias[i], _Q16, _GYRO_LIM), st[S_GYRO + i])
        st[S_GYRO + i] = y
        gout[i] = y * _INV16
        k = co[CO_ACC_K + i]
        s1 = _step(k, _dec(araw[i], _Q16, _ACC_LIM), st[S_ACC1 + i])
        st[S_ACC1 + i] = s1
        y = _step(k, s1, st[S_ACC2 + i])
        st[S_ACC2 + i] = y
        aout[i] = y * _INV16


def _gain(k):
    """A PT1 gain (0 < k <= 1) in Q15, rounded."""
    g = int(k * _ONE15 + 0.5)
    if g > _ONE15:
        return _ONE15
    return g if g > 0 else 0


class FixedImuFilter:
    """The gyro and accelerometer filters of a flight as one fixed-point pass (see the module docstring).

    `configure(gyro_filter, accel_filter, signals, bias, on)` returns whether the fixed pass runs
    (`on`, and the gyro chain is the default one): it reads the float stages' configured gains and
    takes over their state. `update()` then stands in for `GyroFilter.update` plus
    `AccelFilter.update`; `release()` hands the state back to the float stages."""

    def __init__(self):
        self.co = array("i", [0] * CO_SIZE)
        self.st = array("i", [0] * ST_SIZE)
        self.active = False
        self._io = None
        # the viper twin's table of the arrays' addresses (accel/imufilter.py), written by configure
        self._tab = array("i", [0] * _viper.TAB_SIZE) if HAS_ACCEL else None
        self._gyro = None
        self._accel = None

    def configure(self, gyro_filter, accel_filter, signals, bias, on):
        """Call after the float stages' own configure (Flight.configure), with `release()` before it."""
        self.release()  # the float stages were configured (and the accelerometer's reset): start from them
        if not (on and gyro_filter._pt1_only):
            return False
        self._gyro = gyro_filter
        self._accel = accel_filter
        self._io = (signals.gyro_raw_rad_s, bias, signals.gyro_rad_s, signals.accel_raw_m_s2, signals.accel_m_s2)
        co = self.co
        st = self.st
        for i in range(3):
            f = gyro_filter.lpf1[i]._pt1
            co[CO_GYRO_K + i] = _gain(f.k)
            st[S_GYRO + i] = _dec(f.y, _Q16, _GYRO_LIM)
            f = accel_filter.f[i]
            co[CO_ACC_K + i] = _gain(f.k)
            st[S_ACC1 + i] = _dec(f.s1, _Q16, _ACC_LIM)
            st[S_ACC2 + i] = _dec(f.y, _Q16, _ACC_LIM)
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
        """Give the state back to the float stages (the fixed pass stops)."""
        if self.active:
            st = self.st
            for i in range(3):
                self._gyro.lpf1[i]._pt1.y = st[S_GYRO + i] * _INV16
                f = self._accel.f[i]
                f.s1 = st[S_ACC1 + i] * _INV16
                f.y = st[S_ACC2 + i] * _INV16
            self.active = False

    def update(self):
        """Both filters for this pass's sample (Flight.step's step 1). On MicroPython the viper twin
        (accel/imufilter.py `update`) stands in for this method; `update_python` keeps it."""
        filter_pass(self.co, self.st, self._io)


update_python = FixedImuFilter.update
if HAS_ACCEL:
    FixedImuFilter.update = _viper.update
