"""The dynamic notch: notches that follow the strongest peaks of the gyro spectrum (Betaflight's dyn_notch).

Takes the filtered gyro (rad/s, three axes, after the RPM filter, so it goes after what the motors'
telemetry does not explain: frame resonances, a bent prop's harmonics); gives it with `dyn_notch_count`
notches per axis applied, in place. Step 1 of the pass, last of the gyro filters.

As Betaflight: a sliding DFT (SDFT) of each axis over the last WINDOW samples, its bins between
`dyn_notch_min_hz` and `dyn_notch_max_hz` (at most 0.48 x loop_hz) searched for their strongest local
maxima (of the Hann-windowed spectrum), each peak's frequency interpolated between bins (Jacobsen's
estimator on the peak's and its neighbours' complex values) and smoothed, the axis's notches (Q
`dyn_notch_q` / 100) set to the peaks in frequency order. The SDFT takes every sample on every axis;
the peak search and the notches' coefficients are one axis a pass, round-robin, as Betaflight spreads
them. Betaflight's window is 72 bins at a decimated rate; this one is 32 samples at the loop rate (31 Hz
bins at 1 kHz, 12 of them in 100..480 Hz): what a pass in Python can afford, with the interpolation
giving the peak within a few Hz.

A peak counts when it stands out of its band: at least PEAK_OVER_FLOOR times the band's noise floor (the
magnitude a third of the searched bins stay below) and PROMINENCE times the spectrum two bins either
side. A notch with no peak to follow keeps its frequency and fades out (depth to 0 over about ten
updates), so a quiet gyro is not notched at random and a peak that comes back is notched at once.

The fixed-point form, for MicroPython's zero-allocation pass, is `dyn_pass` in core/fastpass/fixeddyn.py:
the same steps on integers, run where the fixed IMU filter runs. This float stage allocates 11-24 kB a
pass on MicroPython (bench/notch_filters.py): it is the simulator's.
"""

import math

from hoverfly.compat import const

WINDOW = const(32)
MAX_NOTCHES = const(3)
# A peak below this multiple of its band's noise floor (_floor) is noise, not a resonance: white noise's
# bins (Rayleigh-distributed) pass 4 x their lower-third magnitude about once in 700.
PEAK_OVER_FLOOR = 4.0
# ... and this multiple of the spectrum two bins either side: a sine's Hann main lobe falls to a quarter of
# its peak there at worst, a bump of a sloping noise floor (the low-passes' skirt, the pilot's manoeuvres
# leaking up) does not
PROMINENCE = 3.0
SMOOTHING = 0.4  # each update moves a notch this fraction of the way to its peak (round-robin: every 3rd pass)
WEIGHT_STEP = 0.1
_DAMP = 0.9999  # the SDFT's pole radius: round-off cannot accumulate in a bin
_TWO_PI = 2.0 * math.pi


class DynNotch:
    """The SDFT, the peak search and the notches (see the module docstring)."""

    def __init__(self):
        self.active = False
        self.count = 0
        self.loop_hz = 1000
        self.q = 3.0
        self.min_hz = 100.0
        self.max_hz = 480.0
        self.k_lo = 2  # the bins searched, k_lo..k_hi (two neighbours each side are kept too)
        self.k_hi = 1
        self.cos_k = []
        self.sin_k = []
        self.re = []  # per axis per bin (k_lo - 1 .. k_hi + 1)
        self.im = []
        self.ring = [0.0] * (3 * WINDOW)
        self.at = 0
        self.damp_n = _DAMP ** WINDOW
        n = 3 * MAX_NOTCHES
        self.hz = [0.0] * n  # per axis per notch
        self.weight = [0.0] * n
        self.b0 = [1.0] * n
        self.b1 = [0.0] * n
        self.a2 = [0.0] * n
        self.state = [0.0] * (n * 4)
        self.next_axis = 0
        self._mag = []
        self._sorted = []
        self._peaks = [0.0] * MAX_NOTCHES
        self._peak_mag = [0.0] * MAX_NOTCHES

    def configure(self, params, loop_hz):
        self.count = params.get("dyn_notch_count")
        self.active = self.count > 0
        self.loop_hz = loop_hz
        self.q = params.get("dyn_notch_q") * 0.01
        top = 0.48 * loop_hz
        self.max_hz = min(float(params.get("dyn_notch_max_hz")), top)
        self.min_hz = min(float(params.get("dyn_notch_min_hz")), self.max_hz)
        bin_hz = loop_hz / WINDOW
        self.k_lo = max(1, int(self.min_hz / bin_hz + 0.5))
        self.k_lo = max(2, self.k_lo)
        self.k_hi = max(self.k_lo, min(WINDOW // 2 - 2, int(self.max_hz / bin_hz + 0.5)))
        bins = self.k_hi - self.k_lo + 5  # two more each side: the Hann window's and the peak test's neighbours
        self.cos_k = [0.0] * bins
        self.sin_k = [0.0] * bins
        for j in range(bins):
            w = _TWO_PI * (self.k_lo - 2 + j) / WINDOW
            self.cos_k[j] = math.cos(w)
            self.sin_k[j] = math.sin(w)
        self.re = [0.0] * (3 * bins)
        self.im = [0.0] * (3 * bins)
        self._mag = [0.0] * bins
        self._sorted = [0.0] * bins
        self.reset()

    def reset(self):
        """The SDFT empty, every notch faded out at the middle of the band."""
        for i in range(len(self.re)):
            self.re[i] = 0.0
            self.im[i] = 0.0
        for i in range(len(self.ring)):
            self.ring[i] = 0.0
        self.at = 0
        mid = 0.5 * (self.min_hz + self.max_hz)
        for k in range(3 * MAX_NOTCHES):
            self.weight[k] = 0.0
            self._set(k, mid)
        for i in range(len(self.state)):
            self.state[i] = 0.0
        self.next_axis = 0

    def _set(self, k, hz):
        self.hz[k] = hz
        w = _TWO_PI * hz / self.loop_hz
        alpha = math.sin(w) / (2.0 * self.q)
        inv = 1.0 / (1.0 + alpha)
        self.b0[k] = inv
        self.b1[k] = -2.0 * math.cos(w) * inv
        self.a2[k] = (1.0 - alpha) * inv

    def _push(self, gyro):
        """Every axis's sample into its SDFT bins: X_k = e^(j 2 pi k / N) (r X_k + x_n - r^N x_(n-N))."""
        at = self.at
        ring = self.ring
        bins = len(self.cos_k)
        cos_k = self.cos_k
        sin_k = self.sin_k
        re = self.re
        im = self.im
        rn = self.damp_n
        for axis in range(3):
            x = gyro[axis]
            slot = axis * WINDOW + at
            delta = x - rn * ring[slot]
            ring[slot] = x
            o = axis * bins
            for j in range(bins):
                a = _DAMP * re[o + j] + delta
                b = _DAMP * im[o + j]
                c = cos_k[j]
                s = sin_k[j]
                re[o + j] = a * c - b * s
                im[o + j] = a * s + b * c
        self.at = at + 1 if at + 1 < WINDOW else 0

    def _floor(self, bins):
        """The band's noise floor: the lower third's top magnitude of the searched bins (a peak takes two or
        three of the dozen bins, two peaks half of them: they must not lift the floor they are judged by)."""
        mag = self._mag
        srt = self._sorted
        n = 0
        for j in range(2, bins - 2):  # insertion sort into a list made at configure: nothing allocated
            v = mag[j]
            k = n - 1
            while k >= 0 and srt[k] > v:
                srt[k + 1] = srt[k]
                k -= 1
            srt[k + 1] = v
            n += 1
        return srt[n // 3]

    def _search(self, axis):
        """The axis's strongest peaks, interpolated, to its notches in frequency order."""
        bins = len(self.cos_k)
        o = axis * bins
        mag = self._mag
        re = self.re
        im = self.im
        # Hann-windowed magnitudes, from each bin and its neighbours (0.5 X[k] - 0.25 (X[k-1] + X[k+1])): the
        # rectangular window's leakage from one strong peak would bury a second one
        for j in range(1, bins - 1):
            r = 0.5 * re[o + j] - 0.25 * (re[o + j - 1] + re[o + j + 1])
            i = 0.5 * im[o + j] - 0.25 * (im[o + j - 1] + im[o + j + 1])
            mag[j] = math.sqrt(r * r + i * i)
        mag[0] = mag[1]  # beyond the kept bins: their neighbours' (only the prominence test reads them)
        mag[bins - 1] = mag[bins - 2]
        floor = self._floor(bins)
        peaks = self._peaks
        pmag = self._peak_mag
        for n in range(MAX_NOTCHES):
            peaks[n] = 0.0
            pmag[n] = 0.0
        bin_hz = self.loop_hz / WINDOW
        for j in range(2, bins - 2):
            m = mag[j]
            side = mag[j - 2] if mag[j - 2] > mag[j + 2] else mag[j + 2]
            if m > mag[j - 1] and m >= mag[j + 1] and m > PEAK_OVER_FLOOR * floor and m > PROMINENCE * side:
                # Jacobsen's estimator on the complex bins (the SDFT's are the window's DFT, rectangular):
                # the offset from bin j is Re((X[j-1] - X[j+1]) / (2 X[j] - X[j-1] - X[j+1]))
                nr = re[o + j - 1] - re[o + j + 1]
                ni = im[o + j - 1] - im[o + j + 1]
                dr = 2.0 * re[o + j] - re[o + j - 1] - re[o + j + 1]
                di = 2.0 * im[o + j] - im[o + j - 1] - im[o + j + 1]
                dd = dr * dr + di * di
                d = (nr * dr + ni * di) / dd if dd > 0.0 else 0.0
                d = 0.5 if d > 0.5 else (-0.5 if d < -0.5 else d)
                hz = (self.k_lo - 2 + j + d) * bin_hz
                # keep the `count` strongest: replace the weakest held one
                low = 0
                for n in range(1, self.count):
                    if pmag[n] < pmag[low]:
                        low = n
                if m > pmag[low]:
                    pmag[low] = m
                    peaks[low] = hz
        # the peaks found, lowest first, to the notches lowest first: a notch follows its own peak
        found = 0
        for n in range(self.count):
            if pmag[n] > 0.0:
                peaks[found] = peaks[n]
                found += 1
        for n in range(1, found):  # insertion sort of at most three
            v = peaks[n]
            m = n - 1
            while m >= 0 and peaks[m] > v:
                peaks[m + 1] = peaks[m]
                m -= 1
            peaks[m + 1] = v
        for n in range(self.count):
            k = axis * MAX_NOTCHES + n
            w = self.weight[k]
            if n < found:
                hz = peaks[n]
                hz = self.min_hz if hz < self.min_hz else (self.max_hz if hz > self.max_hz else hz)
                if w > 0.0:
                    hz = self.hz[k] + SMOOTHING * (hz - self.hz[k])
                self._set(k, hz)
                w = w + WEIGHT_STEP if w < 1.0 - WEIGHT_STEP else 1.0
            else:
                w = w - WEIGHT_STEP if w > WEIGHT_STEP else 0.0
            self.weight[k] = w

    def update(self, gyro):
        """One pass: the SDFT takes the sample, one axis's peaks are searched, every notch is applied."""
        self._push(gyro)
        axis = self.next_axis
        self._search(axis)
        self.next_axis = axis + 1 if axis < 2 else 0
        count = self.count
        st = self.state
        for axis in range(3):
            x = gyro[axis]
            for n in range(count):
                k = axis * MAX_NOTCHES + n
                o = 4 * k
                x1 = st[o]
                x2 = st[o + 1]
                y1 = st[o + 2]
                y2 = st[o + 3]
                y = self.b0[k] * (x + x2) + self.b1[k] * (x1 - y1) - self.a2[k] * y2
                st[o] = x
                st[o + 1] = x1
                st[o + 2] = y
                st[o + 3] = y1
                x = x + self.weight[k] * (y - x)
            gyro[axis] = x

    def centres_hz(self, axis, out):
        """The axis's notch centres now, 0 for one that is off or fading (below half depth: logs and tests)."""
        for n in range(self.count):
            k = axis * MAX_NOTCHES + n
            out[n] = self.hz[k] if self.weight[k] >= 0.5 else 0.0
