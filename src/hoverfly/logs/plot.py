"""PNG plots of a flight log (matplotlib, Agg backend: no display needed).

Each `plot_<name>(log, path)` writes one PNG and returns its path, or None when the log lacks
the topics it needs. `PLOTS` lists them in report order; `plot_all(log, out_dir)` writes every
one it can. Units at this edge: degrees and deg/s, time in seconds from the log's start.
"""

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402 - after the backend is chosen
import numpy as np  # noqa: E402

from hoverfly.logs import analysis  # noqa: E402

_DEG = 180.0 / np.pi
AXES = ("roll", "pitch", "yaw")


def _save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def euler_deg(q):
    """(n, 4) quaternions w, x, y, z (body to NED) -> (n, 3) roll, pitch, yaw in degrees."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1, 1))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=1) * _DEG


def plot_attitude(log, path):
    q = log.vector("vehicle_attitude", "q", 4)
    if q is None or len(q) < 2:
        return None
    t = log.topic("vehicle_attitude")["t_s"]
    e = euler_deg(q)
    fig, axs = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for i, ax in enumerate(axs):
        ax.plot(t, e[:, i], lw=0.8, label=AXES[i] + " estimate")
        ax.set_ylabel(AXES[i] + " (deg)")
        ax.grid(alpha=0.3)
    axs[0].set_title("Attitude (vehicle_attitude)")
    axs[-1].set_xlabel("time (s)")
    return _save(fig, path)


def plot_rates(log, path):
    g = log.vector("vehicle_angular_velocity", "xyz", 3)
    sp = log.topic("vehicle_rates_setpoint")
    if g is None or sp is None or len(g) < 2:
        return None
    t = log.topic("vehicle_angular_velocity")["t_s"]
    fig, axs = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for i, ax in enumerate(axs):
        ax.plot(sp["t_s"], sp[AXES[i]] * _DEG, lw=0.9, color="tab:orange", label="setpoint")
        ax.plot(t, g[:, i] * _DEG, lw=0.7, color="tab:blue", label="gyro (filtered)")
        ax.set_ylabel(AXES[i] + " (deg/s)")
        ax.grid(alpha=0.3)
    axs[0].legend(loc="upper right")
    axs[0].set_title("Rates against setpoints")
    axs[-1].set_xlabel("time (s)")
    return _save(fig, path)


def plot_motors(log, path):
    out = log.topic("actuator_outputs")
    if out is None or len(out["t_s"]) < 2:
        return None
    n = log.motor_count()
    fig, ax = plt.subplots(figsize=(10, 4.5))
    for i in range(n):
        c = out.get("output[%d]" % i)
        if c is not None:
            ax.plot(out["t_s"], c, lw=0.7, label="motor %d" % (i + 1))
    sp = log.topic("vehicle_rates_setpoint")
    if sp is not None and "thrust_body[2]" in sp:
        ax.plot(sp["t_s"], -sp["thrust_body[2]"], lw=1.0, color="k", ls="--", label="throttle")
    ax.set_ylabel("output (0 = stop, idle..1)")
    ax.set_xlabel("time (s)")
    ax.set_title("Motors (actuator_outputs)")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def plot_pid(log, path):
    pid = log.topic("hoverfly_pid")
    if pid is None or len(pid["t_s"]) < 2:
        return None
    fig, axs = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    for i, ax in enumerate(axs):
        for term in ("p", "i", "d", "f", "sum"):
            c = pid.get("%s[%d]" % (term, i))
            if c is not None:
                ax.plot(pid["t_s"], c, lw=0.7 if term != "sum" else 1.0, label=term.upper() if term != "sum"
                        else "sum")
        ax.set_ylabel(AXES[i] + " (torque, 1 = full)")
        ax.grid(alpha=0.3)
    axs[0].legend(loc="upper right", ncol=5, fontsize=8)
    axs[0].set_title("Rate PID terms (hoverfly_pid)")
    axs[-1].set_xlabel("time (s)")
    return _save(fig, path)


def plot_gyro_spectrum(log, path):
    raw = log.vector("sensor_combined", "gyro_rad", 3)
    filt = log.vector("vehicle_angular_velocity", "xyz", 3)
    rate = log.rate_hz("sensor_combined")
    if raw is None or rate <= 0 or len(raw) < 64:
        return None
    fig, axs = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for i, ax in enumerate(axs):
        s = analysis.amplitude_spectrum(raw[:, i] * _DEG, rate)
        if s is not None:
            ax.semilogy(s[0], s[1], lw=0.8, label="raw")
        if filt is not None:
            s = analysis.amplitude_spectrum(filt[:, i] * _DEG, log.rate_hz("vehicle_angular_velocity"))
            if s is not None:
                ax.semilogy(s[0], s[1], lw=0.8, label="filtered")
        ax.set_ylabel(AXES[i] + " (deg/s)")
        ax.grid(alpha=0.3, which="both")
    axs[0].legend(loc="upper right")
    axs[0].set_title("Gyro amplitude spectrum")
    axs[-1].set_xlabel("frequency (Hz)")
    return _save(fig, path)


def plot_spectrogram(log, path):
    raw = log.vector("sensor_combined", "gyro_rad", 3)
    sp = log.topic("vehicle_rates_setpoint")
    rate = log.rate_hz("sensor_combined")
    if raw is None or sp is None or rate <= 0 or "thrust_body[2]" not in sp:
        return None
    thr = -np.interp(log.topic("sensor_combined")["t_s"], sp["t_s"], sp["thrust_body[2]"])
    fig, axs = plt.subplots(1, 3, figsize=(13, 4.5), sharey=True)
    drawn = False
    for i, ax in enumerate(axs):
        got = analysis.spectrogram_vs_throttle(raw[:, i] * _DEG, thr, rate)
        if got is None:
            continue
        freq, edges, mat = got
        with np.errstate(divide="ignore", invalid="ignore"):
            img = np.log10(mat)
        extent = (freq[0], freq[-1], edges[0] * 100, edges[-1] * 100)
        m = ax.imshow(img, aspect="auto", origin="lower", extent=extent,
                      cmap="viridis", interpolation="nearest")
        ax.set_title(AXES[i])
        ax.set_xlabel("frequency (Hz)")
        drawn = True
    if not drawn:
        plt.close(fig)
        return None
    axs[0].set_ylabel("throttle (%)")
    fig.colorbar(m, ax=axs, label="log10 amplitude (deg/s)")
    fig.suptitle("Raw gyro spectrum against throttle")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def plot_step_response(log, path, responses=None):
    responses = analysis.step_responses(log) if responses is None else responses
    if not any(responses.values()):
        return None
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for axis in AXES:
        r = responses.get(axis)
        if r is None:
            continue
        ax.plot(r["t_s"] * 1000.0, r["response"], lw=1.2,
                label="%s: rise %s ms, overshoot %s %% (%d windows)"
                % (axis, r["rise_ms"], r["overshoot_pct"], r["windows"]))
    ax.axhline(1.0, color="k", lw=0.6, ls="--")
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("response to a unit setpoint step")
    ax.set_title("Step response estimated from the flight (setpoint -> gyro, Wiener deconvolution)")
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


PLOTS = (
    ("attitude", plot_attitude, "Attitude"),
    ("rates", plot_rates, "Rates against setpoints"),
    ("motors", plot_motors, "Motors and throttle"),
    ("pid", plot_pid, "Rate PID terms"),
    ("gyro_spectrum", plot_gyro_spectrum, "Gyro spectrum"),
    ("spectrogram", plot_spectrogram, "Gyro spectrum against throttle"),
    ("step_response", plot_step_response, "Step response"),
)
NAMES = tuple(p[0] for p in PLOTS)


def plot_all(log, out_dir, names=None):
    """Write the plots (all, or `names`) into out_dir; returns [(name, title, path)] of those written."""
    os.makedirs(out_dir, exist_ok=True)
    done = []
    for name, fn, title in PLOTS:
        if names and name not in names:
            continue
        p = fn(log, os.path.join(out_dir, name + ".png"))
        if p is not None:
            done.append((name, title, p))
    return done
