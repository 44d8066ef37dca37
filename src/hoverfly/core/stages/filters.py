"""Single-axis digital filters for the pass: PT1, PT2, biquad low-pass and notch, alpha-beta.

Each filter keeps its own state; `configure(cutoff_hz, sample_hz)` computes
coefficients once, `update(x)` filters one sample and returns it. A cutoff of 0
passes the input through. Formulas follow Betaflight's filter.c shapes (PT1 gain
from the RC time constant, PT2 as two PT1 with the cutoff corrected so the -3 dB
point stays where asked, RBJ cookbook biquads); the alpha-beta tracker is seed 001's
stick filter.
"""

import math

_TWO_PI = 2.0 * math.pi


def pt1_gain(cutoff_hz, dt_s):
    """PT1 gain k for y += k*(x - y): dt / (RC + dt)."""
    if cutoff_hz <= 0:
        return 1.0
    rc = 1.0 / (_TWO_PI * cutoff_hz)
    return dt_s / (rc + dt_s)


class Pt1:
    """First-order low-pass."""

    def __init__(self, cutoff_hz=0.0, sample_hz=1000.0):
        self.y = 0.0
        self.k = 1.0
        self.configure(cutoff_hz, sample_hz)

    def configure(self, cutoff_hz, sample_hz):
        self.k = pt1_gain(cutoff_hz, 1.0 / sample_hz)

    def reset(self, value=0.0):
        self.y = value

    def update(self, x):
        y = self.y
        y = y + self.k * (x - y)
        self.y = y
        return y


# Two cascaded PT1s at fc put -3 dB at fc*sqrt(2^(1/2)-1); scale the stage cutoff up to compensate.
_PT2_CUTOFF_CORRECTION = 1.0 / math.sqrt(math.pow(2.0, 1.0 / 2.0) - 1.0)


class Pt2:
    """Second-order low-pass: two PT1 stages, -3 dB at the asked cutoff."""

    def __init__(self, cutoff_hz=0.0, sample_hz=1000.0):
        self.s1 = 0.0
        self.y = 0.0
        self.k = 1.0
        self.configure(cutoff_hz, sample_hz)

    def configure(self, cutoff_hz, sample_hz):
        if cutoff_hz <= 0:
            self.k = 1.0
        else:
            self.k = pt1_gain(cutoff_hz * _PT2_CUTOFF_CORRECTION, 1.0 / sample_hz)

    def reset(self, value=0.0):
        self.s1 = value
        self.y = value

    def update(self, x):
        k = self.k
        s1 = self.s1
        s1 = s1 + k * (x - s1)
        self.s1 = s1
        y = self.y
        y = y + k * (s1 - y)
        self.y = y
        return y


class Biquad:
    """Direct form 2 transposed biquad: low-pass (Butterworth Q) or notch."""

    def __init__(self):
        self.b0 = 1.0
        self.b1 = 0.0
        self.b2 = 0.0
        self.a1 = 0.0
        self.a2 = 0.0
        self.z1 = 0.0
        self.z2 = 0.0

    def _set(self, b0, b1, b2, a0, a1, a2):
        inv = 1.0 / a0
        self.b0 = b0 * inv
        self.b1 = b1 * inv
        self.b2 = b2 * inv
        self.a1 = a1 * inv
        self.a2 = a2 * inv

    def passthrough(self):
        self._set(1.0, 0.0, 0.0, 1.0, 0.0, 0.0)

    def configure_lowpass(self, cutoff_hz, sample_hz, q=0.7071067811865476):
        if cutoff_hz <= 0 or cutoff_hz >= 0.5 * sample_hz:
            self.passthrough()
            return
        w = _TWO_PI * cutoff_hz / sample_hz
        sn = math.sin(w)
        cs = math.cos(w)
        alpha = sn / (2.0 * q)
        b1 = 1.0 - cs
        self._set(0.5 * b1, b1, 0.5 * b1, 1.0 + alpha, -2.0 * cs, 1.0 - alpha)

    def configure_notch(self, centre_hz, cutoff_hz, sample_hz):
        """Notch at centre_hz whose lower -3 dB edge is cutoff_hz (Betaflight's notch_hz / notch_cutoff)."""
        if centre_hz <= 0 or cutoff_hz <= 0 or cutoff_hz >= centre_hz or centre_hz >= 0.5 * sample_hz:
            self.passthrough()
            return
        q = centre_hz * cutoff_hz / (centre_hz * centre_hz - cutoff_hz * cutoff_hz)
        w = _TWO_PI * centre_hz / sample_hz
        sn = math.sin(w)
        cs = math.cos(w)
        alpha = sn / (2.0 * q)
        self._set(1.0, -2.0 * cs, 1.0, 1.0 + alpha, -2.0 * cs, 1.0 - alpha)

    def reset(self, value=0.0):
        # Steady state for a constant input `value`: y = value * DC gain.
        b_sum = self.b0 + self.b1 + self.b2
        a_sum = 1.0 + self.a1 + self.a2
        y = value * b_sum / a_sum if a_sum != 0 else value
        self.z1 = y - self.b0 * value
        self.z2 = self.b2 * value - self.a2 * y

    def update(self, x):
        y = self.b0 * x + self.z1
        self.z1 = self.b1 * x - self.a1 * y + self.z2
        self.z2 = self.b2 * x - self.a2 * y
        return y


class LowPass:
    """A low-pass of the type a parameter names ("pt1", "pt2", "biquad"): one interface for all three."""

    def __init__(self):
        self._pt1 = Pt1()
        self._pt2 = Pt2()
        self._biquad = Biquad()
        self._active = self._pt1

    def configure(self, kind, cutoff_hz, sample_hz):
        if kind == "pt2":
            self._pt2.configure(cutoff_hz, sample_hz)
            self._active = self._pt2
        elif kind == "biquad":
            self._biquad.configure_lowpass(cutoff_hz, sample_hz)
            self._active = self._biquad
        else:
            self._pt1.configure(cutoff_hz, sample_hz)
            self._active = self._pt1
        self.update = self._active.update

    def reset(self, value=0.0):
        self._active.reset(value)

    def update(self, x):  # replaced by the active filter's bound method in configure()
        return self._active.update(x)


class AlphaBeta:
    """Seed 001's alpha-beta tracker for stick inputs: position and velocity estimate.

    Predict x += v*dt; correct with the residual r: x += alpha*r, v += beta*r/dt.
    alpha = 1, beta = 0 is a pass-through.
    """

    def __init__(self, alpha=1.0, beta=0.0, sample_hz=100.0):
        self.x = 0.0
        self.v = 0.0
        self.alpha = alpha
        self.beta = beta
        self.dt_s = 1.0 / sample_hz

    def configure(self, alpha, beta, sample_hz):
        self.alpha = alpha
        self.beta = beta
        self.dt_s = 1.0 / sample_hz

    def reset(self, value=0.0):
        self.x = value
        self.v = 0.0

    def update(self, measured):
        dt = self.dt_s
        x = self.x + self.v * dt
        r = measured - x
        x += self.alpha * r
        self.v += self.beta * r / dt
        self.x = x
        return x


class GyroFilter:
    """Step 1 of the pass for the gyro: per axis low-pass 1 (type by parameter), low-pass 2 (PT1), notch.

    `update(raw, bias, out)` takes the aligned gyro and the calibration bias (rad/s, arrays of
    three) and writes the filtered rate. The default chain (one PT1, nothing else) runs as one
    straight-line pass over the three axes, on the same Pt1 objects and with the same arithmetic
    as the general chain: the numbers are the same, only calls and lookups are saved.
    """

    def __init__(self):
        self.lpf1 = (LowPass(), LowPass(), LowPass())
        self.lpf2 = (Pt1(), Pt1(), Pt1())
        self.notch = (Biquad(), Biquad(), Biquad())
        self.notch_on = False
        self.lpf2_on = False
        self._pt1_only = False

    def configure(self, params, loop_hz):
        kind = params.get("gyro_lpf1_type")
        for i in range(3):
            self.lpf1[i].configure(kind, params.get("gyro_lpf1_hz"), loop_hz)
            self.lpf2[i].configure(params.get("gyro_lpf2_hz"), loop_hz)
            self.notch[i].configure_notch(params.get("gyro_notch1_hz"), params.get("gyro_notch1_cut"), loop_hz)
        self.notch_on = params.get("gyro_notch1_hz") > 0 and params.get("gyro_notch1_cut") > 0
        self.lpf2_on = 0 < params.get("gyro_lpf2_hz") < loop_hz // 2
        self._pt1_only = self.lpf1[0]._active is self.lpf1[0]._pt1 and not self.notch_on and not self.lpf2_on

    def update(self, raw, bias, out):
        if self._pt1_only:
            lpf1 = self.lpf1
            f = lpf1[0]._pt1
            x = raw[0] - bias[0]
            y = f.y
            y = y + f.k * (x - y)
            f.y = y
            out[0] = y
            f = lpf1[1]._pt1
            x = raw[1] - bias[1]
            y = f.y
            y = y + f.k * (x - y)
            f.y = y
            out[1] = y
            f = lpf1[2]._pt1
            x = raw[2] - bias[2]
            y = f.y
            y = y + f.k * (x - y)
            f.y = y
            out[2] = y
            return
        lpf1 = self.lpf1
        lpf2 = self.lpf2
        if self.notch_on:  # the full chain
            notch = self.notch
            for i in range(3):
                out[i] = notch[i].update(lpf2[i].update(lpf1[i].update(raw[i] - bias[i])))
        elif self.lpf2_on:
            for i in range(3):
                out[i] = lpf2[i].update(lpf1[i].update(raw[i] - bias[i]))
        else:
            for i in range(3):
                out[i] = lpf1[i].update(raw[i] - bias[i])


class AccelFilter:
    """Step 1 of the pass for the accelerometer: PT2 per axis at acc_lpf_hz (m/s² in, m/s² out).

    Starts at rest, level (0, 0, -1 g). The three PT2s run inline, same arithmetic as Pt2.update.
    """

    def __init__(self):
        self.f = (Pt2(), Pt2(), Pt2())

    def configure(self, params, loop_hz):
        for f in self.f:
            f.configure(params.get("acc_lpf_hz"), loop_hz)
            f.reset(0.0)
        self.f[2].reset(-9.80665)

    def update(self, raw, out):
        filters = self.f
        f = filters[0]
        k = f.k
        s1 = f.s1
        s1 = s1 + k * (raw[0] - s1)
        f.s1 = s1
        y = f.y
        y = y + k * (s1 - y)
        f.y = y
        out[0] = y
        f = filters[1]
        k = f.k
        s1 = f.s1
        s1 = s1 + k * (raw[1] - s1)
        f.s1 = s1
        y = f.y
        y = y + k * (s1 - y)
        f.y = y
        out[1] = y
        f = filters[2]
        k = f.k
        s1 = f.s1
        s1 = s1 + k * (raw[2] - s1)
        f.s1 = s1
        y = f.y
        y = y + k * (s1 - y)
        f.y = y
        out[2] = y
