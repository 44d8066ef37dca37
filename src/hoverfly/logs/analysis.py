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
