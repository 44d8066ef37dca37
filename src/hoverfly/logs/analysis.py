"""Tuning numbers from a flight log (numpy): the commanded steps' responses, gyro spectrum, spectrogram vs throttle.

Step response: the same measurement as `hoverfly fly` (logs/steps.py), on the steps the log
holds. A step is a stick that moved by at least MIN_STEP_US between two receiver frames and
then held within HOLD_US for at least MIN_HOLD_S; its window ends where the stick leaves the
hold, another stick jumps or the flight mode changes. In acro the set point is the logged
vehicle_rates_setpoint and the response the filtered gyro (deg/s); in angle or horizon mode the
set point is the stick times angle_limit (what the angle loop is asked for) and the response
the attitude estimate (deg). The stick is read as the flight reads it: rc_map, deadband.

Spectra: Welch-averaged amplitude spectrum of the raw gyro per axis, and a spectrogram of
gyro amplitude against throttle (bins of the throttle, mean spectrum per bin), where motor
noise shows up as lines rising with throttle.
"""

import numpy as np

from hoverfly.core.stages.rc import map_channels
from hoverfly.logs.steps import measure_step

MIN_STEP_US = 50  # a tenth of the stick's half travel in one frame: a step, not a pilot's sweep
HOLD_US = 5  # the stick held: within the deadband's width of where it jumped to
MIN_HOLD_S = 0.1  # shorter holds are too short to settle and are not measured
_DEG = 180.0 / np.pi
AXES = ("roll", "pitch", "yaw")
_RC_CHANNELS = 18


def _stick_norm(us, deadband):
    """core.stages.rc.RcInput._stick on an array: µs to -1..1 with the deadband taken out."""
    d = np.asarray(us, dtype=float) - 1500.0
    d = np.where(d > deadband, d - deadband, np.where(d < -deadband, d + deadband, 0.0))
    return np.clip(d / (500.0 - deadband), -1.0, 1.0)


def _mode_at(log, t_s):
    """Flight mode code (control.MODE_NAMES: 0 acro, 1 angle, 2 horizon) at each time, from hoverfly_pid."""
    pid = log.topic("hoverfly_pid")
    if pid is None or "mode" not in pid or not len(pid["t_s"]):
        return np.zeros(len(t_s), dtype=int)
    j = np.clip(np.searchsorted(pid["t_s"], t_s, side="right") - 1, 0, len(pid["t_s"]) - 1)
    return pid["mode"][j].astype(int)


def find_steps(log):
    """The held stick steps in the log: [(axis index, t0_s, t_end_s, mode code, stick before, stick after)]."""
    rc = log.topic("input_rc")
    vals = log.vector("input_rc", "values", _RC_CHANNELS)
    if rc is None or vals is None or len(rc["t_s"]) < 3:
        return []
    try:
        chmap = map_channels(int(log.param("rc_map", 12435678)))
    except (ValueError, TypeError, IndexError):
        chmap = map_channels(12435678)
    t = rc["t_s"]
    us = np.stack([vals[:, chmap[i]] for i in range(3)], axis=1).astype(float)  # roll, pitch, yaw µs
    mode = _mode_at(log, t)
    jumps = np.abs(np.diff(us, axis=0)) >= MIN_STEP_US  # jumps[j] : between frame j and j + 1
    any_jump = np.nonzero(jumps.any(axis=1))[0] + 1
    mode_change = np.nonzero(np.diff(mode) != 0)[0] + 1
    ends = np.union1d(any_jump, mode_change)
    db = (float(log.param("deadband", 5)), float(log.param("deadband", 5)), float(log.param("yaw_deadband", 5)))
    steps = []
    for j in any_jump:
        for a in range(3):
            if not jumps[j - 1, a]:
                continue
            held = np.abs(us[j:, a] - us[j, a]) > HOLD_US
            leave = j + int(np.argmax(held)) if held.any() else len(t)
            later = ends[ends > j]
            end = min(leave, int(later[0]) if len(later) else len(t))
            t_end = t[end] if end < len(t) else t[-1]
            if t_end - t[j] < MIN_HOLD_S:
                continue
            sign = -1.0 if a == 1 else 1.0  # stick forward is nose down (FRD), as core.stages.rc reads it
            before = sign * float(_stick_norm(us[j - 1, a], db[a]))
            after = sign * float(_stick_norm(us[j, a], db[a]))
            steps.append((a, float(t[j]), float(t_end), int(mode[j]), before, after))
    steps.sort(key=lambda s: s[1])
    return steps


def euler_deg(q):
    """(n, 4) quaternions w, x, y, z (body to NED) -> (n, 3) roll, pitch, yaw in degrees."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1, 1))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=1) * _DEG


def _window(t, y, t0, t1):
    m = (t >= t0) & (t < t1)
    return t[m] - t0, y[m]


def log_steps(log, rate_t_s=None, rate_sp_rad_s=None, gyro_rad_s=None):
    """Each held step measured with logs/steps.py: dicts as `hoverfly fly` gives (axis, mode, from, to, unit,
    rise_ms, t90_ms, overshoot_pct, settle_ms, steady_error) plus t_s (the step's time in the log) and
    curve (t_ms, response as a fraction of the step) for plots. The rate set point and gyro can be given
    (replay passes its own); by default the logged ones."""
    if rate_sp_rad_s is None:
        sp = log.topic("vehicle_rates_setpoint")
        g = log.vector("vehicle_angular_velocity", "xyz", 3)
        if sp is not None and g is not None:
            rate_t_s = log.topic("vehicle_angular_velocity")["t_s"]
            n = min(len(rate_t_s), len(sp["t_s"]))
            rate_t_s = rate_t_s[:n]
            rate_sp_rad_s = np.stack([np.interp(rate_t_s, sp["t_s"], sp[a]) for a in AXES], axis=1)
            gyro_rad_s = g[:n]
    att = log.vector("vehicle_attitude", "q", 4)
    euler = None if att is None else (log.topic("vehicle_attitude")["t_s"], euler_deg(att))
    limit_deg = float(log.param("angle_limit", 60))
    out = []
    for a, t0, t1, mode, before, after in find_steps(log):
        angle = mode in (1, 2) and a < 2
        if angle:
            if euler is None:
                continue
            start, target = before * limit_deg, after * limit_deg
            tt, y = _window(euler[0], euler[1][:, a], t0, t1)
            unit = "deg"
        else:
            if rate_sp_rad_s is None:
                continue
            tt, y = _window(rate_t_s, gyro_rad_s[:, a] * _DEG, t0, t1)
            _, spw = _window(rate_t_s, rate_sp_rad_s[:, a] * _DEG, t0, t1)
            if len(spw) < 4:
                continue
            # The set point the controller got: before the step, and where the smoothing brought it.
            before_i = max(0, int(np.searchsorted(rate_t_s, t0, side="left")) - 1)
            start = float(rate_sp_rad_s[before_i, a] * _DEG)
            target = float(np.median(spw[len(spw) // 2 :]))
            unit = "dps"
        if len(tt) < 4 or target == start:
            continue
        r = {"axis": AXES[a], "mode": "angle" if angle else "rate", "from": round(start, 3) + 0.0,
             "to": round(target, 3) + 0.0, "unit": unit, "t_s": round(t0, 3)}
        r.update(measure_step(list(zip(tt.tolist(), y.tolist(), strict=True)), start, target))
        r["curve"] = (tt * 1000.0, (y - start) / (target - start))
        out.append(r)
    return out


def axis_summary(steps):
    """Per axis and mode: number of steps, mean rise, t90 and settle, largest overshoot."""
    groups = {}
    for s in steps:
        groups.setdefault((s["axis"], s["mode"]), []).append(s)
    out = []
    for (axis, mode), ss in sorted(groups.items(), key=lambda kv: (AXES.index(kv[0][0]), kv[0][1])):
        def mean(k, ss=ss):
            v = [s[k] for s in ss if s[k] is not None]
            return round(sum(v) / len(v), 1) if v else None

        over = [s["overshoot_pct"] for s in ss if s["overshoot_pct"] is not None]
        out.append({"axis": axis, "mode": mode, "steps": len(ss), "rise_ms": mean("rise_ms"),
                    "t90_ms": mean("t90_ms"), "settle_ms": mean("settle_ms"),
                    "overshoot_pct": max(over) if over else None})
    return out


def public(step):
    """A log step without its plotting curve (for JSON)."""
    return {k: v for k, v in step.items() if k != "curve"}


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


# ------------------------------------------------------------------ gyro notch filters (RPM filter, dynamic notch)
def _p(log, name, default):
    v = log.param(name, default)
    return default if v is None else v


def notch_frequencies(log):
    """What the gyro's notches sat on over the log (hoverfly_notch, about 10 Hz): {"motor_hz": median
    rotation frequency per motor with telemetry, "rpm_notches_hz": [(Hz, label)] the RPM filter's notches at
    those medians (each harmonic the filter ran, in 0.48 x loop_hz), "dyn_notch_hz": per axis the medians of
    its dynamic notches that were on}, or None without the topic."""
    motor = log.vector("hoverfly_notch", "motor_hz", 8)
    if motor is None or len(motor) == 0:
        return None
    dyn = log.vector("hoverfly_notch", "dyn_notch_hz", 9)
    loop_hz = float(_p(log, "loop_hz", 1000))
    harmonics = int(_p(log, "rpm_harmonics", 0))
    min_hz = float(_p(log, "rpm_min_hz", 100))
    medians = []
    for m in range(8):
        col = motor[:, m]
        col = col[col > 0]
        if len(col):
            medians.append(float(np.median(col)))
    rpm = []
    for h in range(1, harmonics + 1):
        for m, hz in enumerate(medians):
            if min_hz < hz * h < 0.48 * loop_hz:
                rpm.append((hz * h, "RPM filter: motor %d x%d" % (m + 1, h)))
    dyn_hz = [[], [], []]
    if dyn is not None and int(_p(log, "dyn_notch_count", 0)) > 0:
        for axis in range(3):
            for n in range(3):
                col = dyn[:, 3 * axis + n]
                col = col[col > 0]
                if len(col) > len(dyn) // 4:  # on for at least a quarter of the log
                    dyn_hz[axis].append(float(np.median(col)))
    return {"motor_hz": medians, "rpm_notches_hz": rpm, "dyn_notch_hz": dyn_hz}


def _biquad_response(b0, b1, b2, a1, a2, z1):
    """H(z) of a normalised biquad at z**-1 = z1 (an array)."""
    return (b0 + b1 * z1 + b2 * z1 * z1) / (1.0 + a1 * z1 + a2 * z1 * z1)


def _notch_response(hz, q, loop_hz, weight, z1):
    """The weighted RBJ notch the RPM filter and the dynamic notch run: 1 + weight (H - 1)."""
    w = 2.0 * np.pi * hz / loop_hz
    alpha = np.sin(w) / (2.0 * q)
    inv = 1.0 / (1.0 + alpha)
    h = _biquad_response(inv, -2.0 * np.cos(w) * inv, inv, -2.0 * np.cos(w) * inv, (1.0 - alpha) * inv, z1)
    return 1.0 + weight * (h - 1.0)


def gyro_filter_response(log, freq_hz, axis=0):
    """The gyro filter chain's complex response at freq_hz (an array) as the log's parameters configure it
    (core/stages/filters.py's low-passes and static notch, then the RPM filter's and the dynamic notch's
    notches where they sat, notch_frequencies), on the given axis."""
    from hoverfly.core.config.params import Params
    from hoverfly.core.stages.filters import GyroFilter

    loop_hz = float(_p(log, "loop_hz", 1000))
    p = Params()
    for name in ("gyro_lpf1_type", "gyro_lpf1_hz", "gyro_lpf2_hz", "gyro_notch1_hz", "gyro_notch1_cut"):
        v = log.param(name)
        if v is not None:
            p.set(name, v)
    g = GyroFilter()
    g.configure(p, int(loop_hz))
    z1 = np.exp(-2j * np.pi * np.asarray(freq_hz, dtype=float) / loop_hz)
    h = np.ones_like(z1)
    lpf = g.lpf1[0]._active
    if hasattr(lpf, "b0"):
        h *= _biquad_response(lpf.b0, lpf.b1, lpf.b2, lpf.a1, lpf.a2, z1)
    elif hasattr(lpf, "s1"):  # PT2: two PT1 stages of gain k
        h *= (lpf.k / (1.0 - (1.0 - lpf.k) * z1)) ** 2
    else:
        h *= lpf.k / (1.0 - (1.0 - lpf.k) * z1)
    if g.lpf2_on:
        k = g.lpf2[0].k
        h *= k / (1.0 - (1.0 - k) * z1)
    if g.notch_on:
        n = g.notch[0]
        h *= _biquad_response(n.b0, n.b1, n.b2, n.a1, n.a2, z1)
    found = notch_frequencies(log)
    if found is not None:
        q = float(_p(log, "rpm_filter_q", 500)) * 0.01
        weights = [float(_p(log, "rpm_weight%d_pct" % (i + 1), 100)) * 0.01 for i in range(3)]
        for hz, label in found["rpm_notches_hz"]:
            h *= _notch_response(hz, q, loop_hz, weights[int(label[-1]) - 1], z1)
        q = float(_p(log, "dyn_notch_q", 300)) * 0.01
        for hz in found["dyn_notch_hz"][axis]:
            h *= _notch_response(hz, q, loop_hz, 1.0, z1)
    return h


def filter_delay_ms(log, at_hz=100.0, axis=0):
    """The gyro filter chain's group delay at at_hz (ms): -d(phase)/d(omega) of gyro_filter_response."""
    f = np.array([at_hz - 0.5, at_hz + 0.5])
    h = gyro_filter_response(log, f, axis)
    dphi = np.angle(h[1] / h[0])
    return float(-dphi / (2.0 * np.pi * (f[1] - f[0])) * 1000.0)


def motor_peak_attenuation(log, after_s=None):
    """Per axis, at each motor's median rotation frequency (notch_frequencies) and its harmonics below
    Nyquist: the raw and the filtered gyro's amplitude (deg/s) and the filtered over the raw in dB. Only
    the part of the log where the craft was armed and the motors turned (motor_hz > 0 throughout a segment)
    counts. [(axis, Hz, raw, filtered, dB)] or None without the motors' frequencies."""
    found = notch_frequencies(log)
    raw = log.vector("sensor_combined", "gyro_rad", 3)
    filt = log.vector("vehicle_angular_velocity", "xyz", 3)
    rate = log.rate_hz("sensor_combined")
    if found is None or not found["motor_hz"] or raw is None or filt is None or rate <= 0:
        return None
    t = log.topic("sensor_combined")["t_s"]
    motor = log.vector("hoverfly_notch", "motor_hz", 8)
    tn = log.topic("hoverfly_notch")["t_s"]
    spinning = np.interp(t, tn, (motor.max(axis=1) > 0).astype(float)) > 0.99
    if after_s is not None:
        spinning &= t >= after_s
    if spinning.sum() < 512:
        return None
    hz = float(np.median(found["motor_hz"]))
    out = []
    for axis in range(3):
        f, a = amplitude_spectrum(raw[spinning, axis] * _DEG, rate)
        _, b = amplitude_spectrum(filt[spinning, axis] * _DEG, rate)
        for h in (1, 2, 3):
            if hz * h >= rate / 2:
                break
            k = int(np.argmin(abs(f - hz * h)))
            k = k - 1 + int(np.argmax(a[k - 1 : k + 2]))  # the raw peak's own bin, next to the nearest
            out.append((AXES[axis], round(float(f[k]), 1), float(a[k]), float(b[k]),
                        round(float(20.0 * np.log10(b[k] / a[k])), 1)))
    return out
