"""Tuning numbers from a flight log (numpy only): step response, gyro spectrum, spectrogram vs throttle.

Step response, PIDtoolbox-style: the flight is cut into overlapping windows; in each window
with enough stick activity on an axis the impulse response from the rate setpoint to the
gyro is estimated by Wiener deconvolution (H = Y·X* / (|X|² + λ), λ a small fraction of the
input's mean power, so frequencies the pilot never excited do not blow up), integrated into
a step response and averaged over the windows. From the mean response: 10-90 % rise time,
overshoot, delay to 50 % and the settled level.

Spectra: Welch-averaged amplitude spectrum of the raw gyro per axis, and a spectrogram of
gyro amplitude against throttle (bins of the throttle, mean spectrum per bin), where motor
noise shows up as lines rising with throttle.
"""

import numpy as np

WINDOW_S = 1.0
STEP_RESPONSE_S = 0.5
MIN_SETPOINT_DPS = 40.0  # a window counts when the setpoint moves this much (PIDtoolbox uses ~20-100)
_DEG = 180.0 / np.pi


def wiener_step_response(setpoint, gyro, rate_hz, window_s=WINDOW_S, response_s=STEP_RESPONSE_S,
                         min_setpoint=MIN_SETPOINT_DPS / _DEG, noise_ratio=1e-3):
    """Mean step response of gyro to setpoint (same units). Returns dict or None when no window qualifies.

    Keys: t_s (response time axis), response (mean, settles near 1), windows (count used),
    rise_ms (10-90 %), t90_ms, delay_ms (to 50 %), overshoot_pct, settled (mean of 0.2..0.5 s).
    """
    x = np.asarray(setpoint, dtype=float)
    y = np.asarray(gyro, dtype=float)
    n = min(len(x), len(y))
    x = x[:n]
    y = y[:n]
    win = int(round(window_s * rate_hz))
    m = int(round(response_s * rate_hz))
    if n < win or win < 8 or m < 4 or m > win:
        return None
    hop = max(1, win // 4)
    taper = np.hanning(win)
    steps = []
    for start in range(0, n - win + 1, hop):
        xs = x[start : start + win]
        if np.ptp(xs) < min_setpoint:
            continue
        xs = xs * taper
        ys = y[start : start + win] * taper
        # Zero-padded to twice the window: a linear, not circular, deconvolution.
        X = np.fft.rfft(xs, 2 * win)
        Y = np.fft.rfft(ys, 2 * win)
        power = (X * np.conj(X)).real
        lam = noise_ratio * np.mean(power) + 1e-30
        H = Y * np.conj(X) / (power + lam)
        impulse = np.fft.irfft(H, 2 * win)[:m]
        step = np.cumsum(impulse)
        steps.append(step)
    if not steps:
        return None
    resp = np.mean(np.stack(steps), axis=0)
    t = np.arange(m) / rate_hz
    return dict(step_metrics(t, resp), t_s=t, response=resp, windows=len(steps))


def step_metrics(t_s, resp):
    """Rise (10-90 %), t90, delay (50 %), overshoot against the settled level (mean of 0.2..0.5 s)."""
    t_s = np.asarray(t_s)
    resp = np.asarray(resp)
    tail = resp[(t_s >= 0.2) & (t_s <= 0.5)]
    settled = float(np.mean(tail)) if len(tail) else float(resp[-1])
    if settled == 0 or not np.isfinite(settled):
        return {"rise_ms": None, "t90_ms": None, "delay_ms": None, "overshoot_pct": None, "settled": settled}
    frac = resp / settled

    def first(level):
        idx = np.nonzero(frac >= level)[0]
        return float(t_s[idx[0]]) if len(idx) else None

    t10 = first(0.1)
    t50 = first(0.5)
    t90 = first(0.9)
    peak = float(np.max(frac))
    return {
        "rise_ms": None if t10 is None or t90 is None else round((t90 - t10) * 1000.0, 1),
        "t90_ms": None if t90 is None else round(t90 * 1000.0, 1),
        "delay_ms": None if t50 is None else round(t50 * 1000.0, 1),
        "overshoot_pct": round(max(0.0, peak - 1.0) * 100.0, 2),
        "settled": round(settled, 3),
    }


def step_responses(log):
    """Per axis: the step-response dict (or None) from vehicle_rates_setpoint to vehicle_angular_velocity."""
    rate = log.rate_hz("vehicle_angular_velocity")
    sp = log.topic("vehicle_rates_setpoint")
    gyro = log.vector("vehicle_angular_velocity", "xyz", 3)
    out = {}
    for i, axis in enumerate(("roll", "pitch", "yaw")):
        if sp is None or gyro is None or rate <= 0 or axis not in sp:
            out[axis] = None
            continue
        out[axis] = wiener_step_response(sp[axis], gyro[:, i], rate)
    return out


def amplitude_spectrum(signal, rate_hz, segment=512):
    """Welch-averaged amplitude spectrum: (freq_hz, amplitude in the signal's unit), or None."""
    x = np.asarray(signal, dtype=float)
    if len(x) < segment:
        segment = 1 << int(np.log2(max(8, len(x))))
        if len(x) < segment:
            return None
    taper = np.hanning(segment)
    hop = segment // 2
    acc = None
    k = 0
    for start in range(0, len(x) - segment + 1, hop):
        s = x[start : start + segment]
        s = (s - np.mean(s)) * taper
        a = np.abs(np.fft.rfft(s)) * 2.0 / np.sum(taper)
        acc = a if acc is None else acc + a
        k += 1
    freq = np.fft.rfftfreq(segment, 1.0 / rate_hz)
    return freq, acc / k


def spectrogram_vs_throttle(signal, throttle, rate_hz, segment=256, bins=20):
    """Mean amplitude spectrum per throttle bin: (freq_hz, throttle_edges, matrix[bins, freqs]) or None.

    Bins with no segment are NaN. Throttle is 0..1 (the setpoint's collective)."""
    x = np.asarray(signal, dtype=float)
    thr = np.asarray(throttle, dtype=float)
    n = min(len(x), len(thr))
    if n < segment:
        return None
    taper = np.hanning(segment)
    freq = np.fft.rfftfreq(segment, 1.0 / rate_hz)
    edges = np.linspace(0.0, 1.0, bins + 1)
    acc = np.zeros((bins, len(freq)))
    cnt = np.zeros(bins)
    hop = segment // 2
    for start in range(0, n - segment + 1, hop):
        s = x[start : start + segment]
        s = (s - np.mean(s)) * taper
        a = np.abs(np.fft.rfft(s)) * 2.0 / np.sum(taper)
        b = int(np.clip(np.mean(thr[start : start + segment]) * bins, 0, bins - 1))
        acc[b] += a
        cnt[b] += 1
    with np.errstate(invalid="ignore", divide="ignore"):
        mat = acc / cnt[:, None]
    mat[cnt == 0] = np.nan
    return freq, edges, mat
