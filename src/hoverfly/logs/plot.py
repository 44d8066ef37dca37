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
from hoverfly.logs.analysis import euler_deg  # noqa: E402

_DEG = 180.0 / np.pi
AXES = ("roll", "pitch", "yaw")


def _save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


_MODE_COLOURS = {0: "#fde7d0", 1: "#dcebf7", 2: "#e3f3dd"}  # acro, angle, horizon: light bands behind traces


def _events(log):
    """(t_s, kind, text) of the logged arming, failsafe and mode messages; kind picks the marker."""
    out = []
    for m in log.messages:
        text = str(m["text"])
        word = text.split(" ", 1)[0]
        t = (m["timestamp_us"] - log.start_us) * 1e-6
        if word in ("armed", "disarmed"):
            out.append((t, word, text))
        elif word.startswith("failsafe") or word in ("rx_lost", "imu_fault", "output_failsafe"):
            out.append((t, "failsafe", text))
    return out


def _mode_spans(log):
    """[(t0, t1, mode code)] from hoverfly_pid's mode, or [] without it."""
    pid = log.topic("hoverfly_pid")
    if pid is None or "mode" not in pid or len(pid["t_s"]) < 2:
        return []
    t = pid["t_s"]
    mode = pid["mode"].astype(int)
    cut = np.nonzero(np.diff(mode) != 0)[0] + 1
    starts = np.concatenate([[0], cut])
    ends = np.concatenate([cut, [len(t) - 1]])
    return [(float(t[i]), float(t[j]), int(mode[i])) for i, j in zip(starts, ends, strict=True)]


def _mark(log, axs, label_top=True):
    """Flight mode as background bands, arm/disarm and failsafe as vertical lines, on every panel."""
    from matplotlib.patches import Patch

    from hoverfly.core.stages.control import MODE_NAMES

    spans = _mode_spans(log)
    seen = set()
    for t0, t1, mode in spans:
        for ax in axs:
            ax.axvspan(t0, t1, color=_MODE_COLOURS.get(mode, "#eeeeee"), lw=0, zorder=0)
        seen.add(mode)
    style = {"armed": ("tab:green", "-"), "disarmed": ("tab:red", "-"), "failsafe": ("magenta", "--")}
    kinds = set()
    for t, kind, _text in _events(log):
        c, ls = style[kind]
        for ax in axs:
            ax.axvline(t, color=c, ls=ls, lw=1.0, zorder=1)
        kinds.add(kind)
    handles = [Patch(color=_MODE_COLOURS[m], label=MODE_NAMES[m] + " mode") for m in sorted(seen)
               if m in _MODE_COLOURS]
    from matplotlib.lines import Line2D

    handles += [Line2D([], [], color=style[k][0], ls=style[k][1], label=k) for k in ("armed", "disarmed", "failsafe")
                if k in kinds]
    if handles and label_top:
        # In the bottom panel's lower right, beside (not over) that panel's own legend and the title.
        ax = axs[-1]
        own = ax.get_legend()
        ax.legend(handles=handles, loc="lower right", ncol=len(handles), fontsize=7, framealpha=0.8)
        if own is not None:
            ax.add_artist(own)


def angle_setpoint_deg(log):
    """(t_s, (n, 2) roll and pitch angle set point in deg, NaN outside angle/horizon mode) from input_rc: the
    stick as core.stages.rc reads it times angle_limit; None without input_rc."""
    from hoverfly.logs.analysis import _mode_at, _stick_norm

    vals = log.vector("input_rc", "values", 18)
    rc = log.topic("input_rc")
    if vals is None or rc is None or len(rc["t_s"]) < 2:
        return None
    from hoverfly.core.stages.rc import map_channels

    try:
        chmap = map_channels(int(log.param("rc_map", 12435678)))
    except (ValueError, TypeError, IndexError):
        chmap = map_channels(12435678)
    db = float(log.param("deadband", 5))
    limit = float(log.param("angle_limit", 60))
    t = rc["t_s"]
    roll = _stick_norm(vals[:, chmap[0]], db) * limit
    pitch = -_stick_norm(vals[:, chmap[1]], db) * limit  # stick forward: nose down
    sp = np.stack([roll, pitch], axis=1)
    mode = _mode_at(log, t)
    sp[mode == 0] = np.nan
    return t, sp


def plot_attitude(log, path):
    q = log.vector("vehicle_attitude", "q", 4)
    if q is None or len(q) < 2:
        return None
    t = log.topic("vehicle_attitude")["t_s"]
    e = euler_deg(q)
    sp = angle_setpoint_deg(log)
    fig, axs = plt.subplots(3, 1, figsize=(11, 7.5), sharex=True)
    for i, ax in enumerate(axs):
        if sp is not None and i < 2:
            ax.step(sp[0], sp[1][:, i], where="post", lw=1.0, color="tab:orange",
                    label=AXES[i] + " set point (angle mode: stick x angle_limit)")
        ax.plot(t, e[:, i], lw=0.8, color="tab:blue", label=AXES[i] + " estimate")
        ax.set_ylabel(AXES[i] + " (deg)")
        ax.grid(alpha=0.3)
        ax.legend(loc="lower left", fontsize=8)
    _mark(log, axs)
    axs[0].set_title("Attitude against the angle set point (angle/horizon mode; acro flies a rate set point: "
                     "rates.png)", loc="left", fontsize=10)
    axs[-1].set_xlabel("time (s)")
    return _save(fig, path)


def plot_rates(log, path):
    g = log.vector("vehicle_angular_velocity", "xyz", 3)
    sp = log.topic("vehicle_rates_setpoint")
    if g is None or sp is None or len(g) < 2:
        return None
    t = log.topic("vehicle_angular_velocity")["t_s"]
    fig, axs = plt.subplots(3, 1, figsize=(11, 7.5), sharex=True)
    for i, ax in enumerate(axs):
        ax.plot(t, g[:, i] * _DEG, lw=0.7, color="tab:blue", label="gyro (filtered)", zorder=2)
        ax.plot(sp["t_s"], sp[AXES[i]] * _DEG, lw=1.1, color="tab:orange", label="rate set point", zorder=3)
        ax.set_ylabel(AXES[i] + " (deg/s)")
        ax.grid(alpha=0.3)
        ax.legend(loc="lower left", fontsize=8)
    _mark(log, axs)
    axs[0].set_title("Rates against set points (in angle mode the set point is the angle loop's output)", loc="left")
    axs[-1].set_xlabel("time (s)")
    return _save(fig, path)


def plot_motors(log, path):
    out = log.topic("actuator_outputs")
    if out is None or len(out["t_s"]) < 2:
        return None
    n = log.motor_count()
    cols = [(i, out.get("output[%d]" % i)) for i in range(n)]
    cols = [(i, c) for i, c in cols if c is not None]
    if not cols:
        return None
    sp = log.topic("vehicle_rates_setpoint")
    fig, axs = plt.subplots(len(cols), 1, figsize=(11, 1.6 + 1.5 * len(cols)), sharex=True, sharey=True,
                            squeeze=False)
    axs = axs[:, 0]
    for ax, (i, c) in zip(axs, cols, strict=True):
        ax.plot(out["t_s"], c, lw=0.7, color="tab:blue", label="motor %d" % (i + 1))
        if sp is not None and "thrust_body[2]" in sp:
            ax.plot(sp["t_s"], -sp["thrust_body[2]"], lw=0.9, color="k", ls="--", label="throttle")
        ax.set_ylim(-0.05, 1.05)
        ax.set_ylabel("motor %d" % (i + 1))
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=7, ncol=2)
    _mark(log, axs)
    axs[0].set_title("Motors, one panel each (output 0 = stop, idle..1 = full) against throttle", loc="left")
    axs[-1].set_xlabel("time (s)")
    return _save(fig, path)


def plot_servos(log, path):
    """A plane's (or a tricopter's) servo widths from actuator_servos (PX4's control -1..1 back to µs), one panel
    each, with the stabilised commands (hoverfly_pid's sum) that drive them; None for a log without servos."""
    sv = log.topic("actuator_servos")
    if sv is None or len(sv["t_s"]) < 2:
        return None
    cols = []
    for i in range(8):
        c = sv.get("control[%d]" % i)
        if c is not None and np.any(c != 0.0):
            cols.append((i, 1500.0 + 500.0 * c))
    if not cols:
        return None
    pid = log.topic("hoverfly_pid")
    fig, axs = plt.subplots(len(cols), 1, figsize=(11, 1.6 + 1.5 * len(cols)), sharex=True, squeeze=False)
    axs = axs[:, 0]
    for ax, (i, us) in zip(axs, cols, strict=True):
        ax.plot(sv["t_s"], us, lw=0.8, color="tab:blue", label="servo %d (us)" % i)
        ax.set_ylabel("servo %d (us)" % i)
        ax.grid(alpha=0.3)
        if pid is not None:
            tw = ax.twinx()
            for k, (axis, color) in enumerate((("roll", "tab:red"), ("pitch", "tab:green"), ("yaw", "tab:purple"))):
                c = pid.get("sum[%d]" % k)
                if c is not None:
                    tw.plot(pid["t_s"], c, lw=0.5, color=color, alpha=0.6, label="stabilised %s" % axis)
            tw.set_ylim(-1.05, 1.05)
            tw.set_ylabel("command -1..1", fontsize=7)
            if i == cols[0][0]:
                tw.legend(loc="upper right", fontsize=7, ncol=3)
        ax.legend(loc="upper left", fontsize=7)
    _mark(log, axs)
    axs[0].set_title("Servos (pulse width) against the stabilised roll, pitch and yaw commands", loc="left")
    axs[-1].set_xlabel("time (s)")
    return _save(fig, path)


def plot_airspeed(log, path):
    """A plane's pitot airspeed (PX4's airspeed topic) over the pitch angle and throttle it follows: a pilot reads
    the energy trade (nose down, speed up) and a stall's approach from these two panels; None without the topic."""
    a = log.topic("airspeed")
    if a is None or len(a["t_s"]) < 2 or "indicated_airspeed_m_s" not in a:
        return None
    ias = a["indicated_airspeed_m_s"]
    fig, axs = plt.subplots(2, 1, figsize=(11, 5.5), sharex=True, gridspec_kw={"height_ratios": (3, 2)})
    ax = axs[0]
    ax.plot(a["t_s"], ias, lw=0.9, color="tab:blue", label="indicated airspeed")
    tas = a.get("true_airspeed_m_s")
    if tas is not None and np.any(np.abs(tas - ias) > 0.05):
        ax.plot(a["t_s"], tas, lw=0.7, color="tab:cyan", label="true airspeed")
    mean = float(np.mean(ias))
    ax.axhline(mean, lw=0.8, ls=":", color="k", label="mean %.1f m/s (min %.1f, max %.1f)"
               % (mean, float(np.min(ias)), float(np.max(ias))))
    ax.set_ylabel("airspeed (m/s)")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=7, ncol=3)
    ax = axs[1]
    q = log.vector("vehicle_attitude", "q", 4)
    if q is not None and len(q) >= 2:
        ax.plot(log.topic("vehicle_attitude")["t_s"], euler_deg(q)[:, 1], lw=0.7, color="tab:green", label="pitch")
    ax.set_ylabel("pitch (deg)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=7)
    sp = log.topic("vehicle_rates_setpoint")
    if sp is not None and "thrust_body[2]" in sp:
        tw = ax.twinx()
        tw.plot(sp["t_s"], -sp["thrust_body[2]"], lw=0.7, color="k", ls="--", label="throttle")
        tw.set_ylim(-0.05, 1.05)
        tw.set_ylabel("throttle 0..1", fontsize=7)
        tw.legend(loc="upper right", fontsize=7)
    _mark(log, axs)
    axs[0].set_title("Airspeed (pitot) against pitch and throttle", loc="left")
    axs[-1].set_xlabel("time (s)")
    return _save(fig, path)


def _robust_lim(arrays, q=99.5):
    """y limits holding all but the rarest spikes of these arrays (q-th percentile of |x|, 20 % margin)."""
    vals = np.concatenate([np.abs(a[np.isfinite(a)]) for a in arrays if a is not None and len(a)] or [np.zeros(1)])
    m = float(np.percentile(vals, q)) if len(vals) else 0.0
    m = max(m * 1.2, 1e-3)
    return -m, m


def plot_pid(log, path):
    pid = log.topic("hoverfly_pid")
    if pid is None or len(pid["t_s"]) < 2:
        return None
    t = pid["t_s"]
    fig, axs = plt.subplots(3, 2, figsize=(13, 8.5), sharex=True, gridspec_kw={"width_ratios": (3, 2)})
    colours = {"p": "tab:blue", "i": "tab:green", "d": "tab:red"}
    for i in range(3):
        ax = axs[i, 0]
        shown = []
        for term in ("sum", "p", "i", "d"):  # the sum behind, light: it must not hide the terms
            c = pid.get("%s[%d]" % (term, i))
            if c is None:
                continue
            if term == "sum":
                ax.plot(t, c, lw=0.8, color="0.7", label="sum (P+I+D+F)", zorder=2)
            else:
                ax.plot(t, c, lw=0.7, color=colours[term], label=term.upper(), zorder=3)
                shown.append(c)
        lo, hi = _robust_lim(shown)
        ax.set_ylim(lo, hi)
        ax.set_ylabel(AXES[i] + " torque (1 = full)")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", ncol=4, fontsize=8)
        f = pid.get("f[%d]" % i)
        axf = axs[i, 1]
        if f is not None:
            axf.plot(t, f, lw=0.7, color="tab:purple", label="F (feed-forward)")
            axf.legend(loc="upper left", fontsize=8)
        axf.set_ylabel(AXES[i] + " F torque (1 = full)")
        axf.grid(alpha=0.3)
    _mark(log, axs.ravel(), label_top=False)
    axs[0, 0].set_title("P, I, D in front of their sum (scaled to P, I, D: feed-forward spikes leave the panel)",
                        loc="left", fontsize=10)
    axs[0, 1].set_title("Feed-forward on its own scale", loc="left", fontsize=10)
    fig.suptitle("Rate PID terms (hoverfly_pid)")
    axs[-1, 0].set_xlabel("time (s)")
    axs[-1, 1].set_xlabel("time (s)")
    return _save(fig, path)


def filter_cutoffs(log):
    """[(Hz, label)] of the gyro filters the log's parameters switch on, as the flight configures them."""
    out = []
    loop_hz = float(log.param("loop_hz", 1000) or 1000)
    lpf1 = float(log.param("gyro_lpf1_hz", 0) or 0)
    if lpf1 > 0:
        out.append((lpf1, "gyro_lpf1_hz %g (%s)" % (lpf1, log.param("gyro_lpf1_type", "pt1"))))
    lpf2 = float(log.param("gyro_lpf2_hz", 0) or 0)
    if 0 < lpf2 < loop_hz / 2:
        out.append((lpf2, "gyro_lpf2_hz %g (pt1)" % lpf2))
    notch = float(log.param("gyro_notch1_hz", 0) or 0)
    if notch > 0:
        out.append((notch, "gyro_notch1_hz %g (cut %g)" % (notch, float(log.param("gyro_notch1_cut", 0) or 0))))
    dterm = float(log.param("dterm_lpf1_hz", 0) or 0)
    if dterm > 0:
        out.append((dterm, "dterm_lpf1_hz %g (D term only)" % dterm))
    return out


def plot_gyro_spectrum(log, path):
    raw = log.vector("sensor_combined", "gyro_rad", 3)
    filt = log.vector("vehicle_angular_velocity", "xyz", 3)
    rate = log.rate_hz("sensor_combined")
    if raw is None or rate <= 0 or len(raw) < 64:
        return None
    cuts = filter_cutoffs(log)
    notches = analysis.notch_frequencies(log)
    styles = ("--", ":", "-.", (0, (5, 1, 1, 1)))
    fig, axs = plt.subplots(3, 1, figsize=(11, 7.5), sharex=True)
    for i, ax in enumerate(axs):
        s = analysis.amplitude_spectrum(raw[:, i] * _DEG, rate)
        if s is not None:
            ax.semilogy(s[0], s[1], lw=0.8, color="tab:blue", label="raw gyro")
        if filt is not None:
            s = analysis.amplitude_spectrum(filt[:, i] * _DEG, log.rate_hz("vehicle_angular_velocity"))
            if s is not None:
                ax.semilogy(s[0], s[1], lw=0.8, color="tab:orange", label="filtered gyro")
        for k, (hz, label) in enumerate(cuts):
            ax.axvline(hz, color="tab:red" if "dterm" not in label else "tab:gray", ls=styles[k % len(styles)],
                       lw=1.0, label=label)
        if notches is not None:  # where the RPM filter's and the dynamic notch's notches sat (their medians)
            for k, (hz, _label) in enumerate(notches["rpm_notches_hz"]):
                ax.axvline(hz, color="tab:purple", lw=0.9, alpha=0.7,
                           label="RPM filter: %d notches (motors' Hz x harmonic)" % len(notches["rpm_notches_hz"])
                           if k == 0 else None)
            for hz in notches["dyn_notch_hz"][i]:
                ax.axvline(hz, color="tab:green", lw=1.2, ls="--", label="dynamic notch %.0f Hz" % hz)
        ax.set_ylabel(AXES[i] + " amplitude (deg/s)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(loc="upper right", fontsize=8)
    axs[0].set_title("Gyro amplitude spectrum, filter cut-offs and notches marked (sampled at %.0f Hz: up to %.0f "
                     "Hz shown)\nthe gyro filters' delay at 100 Hz: %.2f ms (roll, from the log's parameters and "
                     "where the notches sat)" % (rate, rate / 2, analysis.filter_delay_ms(log)),
                     loc="left", fontsize=10)
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
        for hz, label in filter_cutoffs(log):
            if "dterm" not in label:
                ax.axvline(hz, color="w", ls="--", lw=0.9)
                ax.text(hz, edges[-1] * 100 - 3, label.split(" (")[0], color="k", fontsize=7, va="top", ha="center",
                        rotation=90, bbox={"facecolor": "w", "edgecolor": "none", "alpha": 0.8, "pad": 1})
        ax.set_title(AXES[i])
        ax.set_xlabel("frequency (Hz)")
        drawn = True
    if not drawn:
        plt.close(fig)
        return None
    axs[0].set_ylabel("throttle (%)")
    fig.colorbar(m, ax=axs, label="log10 amplitude (deg/s)")
    fig.suptitle("Raw gyro spectrum against throttle (blank: throttle never flown there; dashed: gyro filter "
                 "cut-offs)")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def plot_step_response(log, path, steps=None):
    """Each held step's response as a fraction of the step (logs/steps.py's windows), per axis and mode."""
    steps = analysis.log_steps(log) if steps is None else steps
    if not steps:
        return None
    groups = []
    for st in steps:
        key = (st["axis"], st["mode"])
        if key not in groups:
            groups.append(key)
    fig, axs = plt.subplots(1, len(groups), figsize=(max(8.0, 4.6 * len(groups) + 1), 4.6), squeeze=False, sharey=True)
    axs = axs[0]
    for ax, (axis, mode) in zip(axs, groups, strict=True):
        for st in steps:
            if (st["axis"], st["mode"]) != (axis, mode):
                continue
            tm, frac = st["curve"]
            ax.plot(tm, frac, lw=1.0, label="%.0f->%.0f %s at %.2f s: rise %s ms, over %s %%, settle %s ms"
                    % (st["from"], st["to"], st["unit"], st["t_s"], st["rise_ms"], st["overshoot_pct"],
                       st["settle_ms"]))
        ax.axhline(1.0, color="k", lw=0.7)
        ax.axhspan(0.95, 1.05, color="tab:green", alpha=0.12, lw=0, label="±5 % settle band")
        ax.set_title("%s, %s steps" % (axis, mode))
        ax.set_xlabel("time from the stick's move (ms)")
        ax.set_xlim(0, 300 if mode == "rate" else 600)
        ax.grid(alpha=0.3)
        ax.legend(loc="center right", fontsize=7)
    axs[0].set_ylabel("response / step (1 = set point reached)")
    fig.suptitle("Step response of each held stick step (the same measurement as hoverfly fly)", fontsize=10)
    return _save(fig, path)


PLOTS = (
    ("attitude", plot_attitude, "Attitude"),
    ("rates", plot_rates, "Rates against setpoints"),
    ("motors", plot_motors, "Motors and throttle"),
    ("servos", plot_servos, "Servos against the stabilised commands"),
    ("airspeed", plot_airspeed, "Airspeed against pitch and throttle"),
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
