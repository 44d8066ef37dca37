"""`hoverfly log replay`: a logged flight's sensor and receiver streams through a fresh Flight, new gains.

Takes a hoverfly log written at the loop rate (blackbox_rate_hz = loop_hz: one sensor_combined
sample per pass) and optional parameter changes. A `ReplayBoard` serves the logged IMU samples
(gyro_integral_dt = 0 marks a pass without a new sample), battery and attitude; a
`ReplayReceiver` stands in for the receiver codec and hands over each logged input_rc frame in
the pass it arrived. The Flight runs on the logged tick times, so every dt is the original's.

It is an open-loop replay: the craft's motion is the logged one, whatever the new outputs
would have done to it. What it shows is what the controller would have commanded: with the
logged parameters the outputs match the log to float rounding (a check that the log is
complete); with changed ones, how the P/I/D/F terms, the PID sums and the motors change.

sensor_combined holds the samples after board alignment (body frame), so the replay runs
with board alignment zeroed.
"""

import os

import numpy as np

from hoverfly.compat import TICKS_PERIOD, ticks_add
from hoverfly.core.board import Board
from hoverfly.core.config.params import Params
from hoverfly.core.flight import Flight
from hoverfly.errors import UserError

AXES = ("roll", "pitch", "yaw")
_ORIGIN_TICKS = TICKS_PERIOD - 3_000_000  # as the simulator: the replay crosses the tick wrap
_ALIGNMENT = ("board_roll_deg", "board_pitch_deg", "board_yaw_deg")
_RC_CHANNELS = 18


class ReplayBoard(Board):
    name = "replay"

    def __init__(self, log):
        sc = log.topic("sensor_combined")
        self.t64 = sc["timestamp"].astype(np.int64)
        self.gyro = log.vector("sensor_combined", "gyro_rad", 3).astype(np.float32).tolist()
        self.accel = log.vector("sensor_combined", "accelerometer_m_s2", 3).astype(np.float32).tolist()
        self.fresh = (sc["gyro_integral_dt"] > 0).tolist()
        self.k = -1
        self.now = 0
        att = log.vector("vehicle_attitude", "q", 4)
        self.q = None if att is None else att.tolist()
        bat = log.topic("battery_status")
        self._bat_t = None if bat is None else bat["timestamp"].astype(np.int64)
        self._bat = None if bat is None else np.stack([bat["voltage_v"], bat["current_a"]], axis=1).tolist()

    def now_us(self):
        return self.now

    def read_imu(self, gyro_rad_s, accel_m_s2):
        k = self.k
        if not self.fresh[k]:
            return False
        g = self.gyro[k]
        a = self.accel[k]
        for i in range(3):
            gyro_rad_s[i] = g[i]
            accel_m_s2[i] = a[i]
        return True

    def read_attitude(self, q_out):
        if self.q is None or self.k >= len(self.q):
            return False
        q = self.q[self.k]
        for i in range(4):
            q_out[i] = q[i]
        return True

    def write_motors(self, motor_out, count):
        pass

    def read_battery(self, signals):
        if self._bat_t is None:
            return
        j = int(np.searchsorted(self._bat_t, self.t64[self.k], side="right")) - 1
        if j >= 0:
            signals.battery_v = self._bat[j][0]
            signals.current_a = self._bat[j][1]


class ReplayReceiver:
    """Stands in for core.stages.receiver.Receiver: the logged frames, each in the pass it arrived."""

    def __init__(self, log, board):
        self.board = board
        rc = log.topic("input_rc")
        self.frames_at = {}
        self.values = []
        vals = log.vector("input_rc", "values", _RC_CHANNELS)
        if rc is not None and vals is not None:
            for j, t in enumerate(rc["timestamp"].astype(np.int64).tolist()):
                self.frames_at[t] = j
            self.values = vals.astype(int).tolist()
            self.lq = rc["link_quality"].astype(int).tolist() if "link_quality" in rc else None
        self.channels_us = [1500] * _RC_CHANNELS
        self.frames = 0
        self.errors = 0
        self.frame_rate_hz = 0
        self.link_quality_pct = 0
        self.rssi_dbm = 0
        self.rx_failsafe = False
        self.new_frames = 0
        self.telemetry = None

    def configure(self, params):
        pass

    def start(self, now_us):
        pass

    def update(self, now_us, board):
        b = self.board
        j = self.frames_at.get(int(b.t64[b.k]))
        if j is None:
            self.new_frames = 0
            return 0
        self.channels_us = self.values[j]
        self.frames += 1
        self.new_frames = 1
        return 1

    def telemetry_due(self, now_us):
        return False

    def frame_age_us(self, now_us):
        return 0


def _set_logged(params, name, value):
    """params.set for a value read from a log (any bytes a file holds): its refusal as text."""
    try:
        return params.set(name, value)
    except (ValueError, OverflowError, TypeError) as exc:  # a damaged value the table's check let through
        return "%s = %r: %s" % (name, value, exc)


def params_from_log(log, overrides=()):
    """The logged parameters (board alignment zeroed), then `overrides` (name, value).

    Returns (Params, [parameters that could not be applied]); raises UserError on a bad override."""
    params = Params()
    unknown = []
    for name, value in log.params.items():
        if name in params.values:
            err = _set_logged(params, name, value)
            if err:
                unknown.append("%s (%s)" % (name, err))
    for name in _ALIGNMENT:
        params.set(name, 0.0)
    for name, value in overrides:
        err = params.set(name, value)
        if err:
            raise UserError("--set %s" % err)
    return params, unknown


class ReplayResult:
    """Old (logged) and new (replayed) controller outputs, pass by pass."""

    def __init__(self, t_s, old, new, warnings, overrides):
        self.t_s = t_s
        self.old = old
        self.new = new
        self.warnings = warnings
        self.overrides = list(overrides)

    def max_abs_diff(self):
        return {k: float(np.max(np.abs(self.new[k] - self.old[k]))) if len(self.old[k]) else 0.0
                for k in self.old if k in self.new}

    def rms(self, which):
        d = self.old if which == "old" else self.new
        return {k: float(np.sqrt(np.mean(np.square(v)))) if len(v) else 0.0 for k, v in d.items()}

    def steps(self, log):
        """The held steps measured as `hoverfly fly` and `log report` do (logs/steps.py), on the replayed rate
        set point and filtered gyro. Open loop: the gyro is the logged motion through the replay's filters,
        so these are the logged flight's figures, not what new gains would fly."""
        from hoverfly.logs.analysis import log_steps, public

        if "setpoint_roll" not in self.new or "gyro_roll" not in self.new:
            return []
        sp = np.stack([self.new["setpoint_" + a] for a in AXES], axis=1)
        g = np.stack([self.new["gyro_" + a] for a in AXES], axis=1)
        return [public(st) for st in log_steps(log, self.t_s, sp, g)]

    def to_dict(self):
        return {"passes": len(self.t_s), "overrides": [[n, v] for n, v in self.overrides],
                "max_abs_diff": self.max_abs_diff(), "rms_old": self.rms("old"), "rms_new": self.rms("new"),
                "warnings": self.warnings}


def _logged_outputs(log, n_motors, n):
    old = {}
    pid = log.topic("hoverfly_pid")
    for term in ("p", "i", "d", "f", "sum"):
        for a, axis in enumerate(AXES):
            key = "%s_%s" % (term, axis)
            if pid is not None and "%s[%d]" % (term, a) in pid:
                old[key] = pid["%s[%d]" % (term, a)][:n].astype(np.float64)
    out = log.topic("actuator_outputs")
    for m in range(n_motors):
        if out is not None and "output[%d]" % m in out:
            old["motor%d" % m] = out["output[%d]" % m][:n].astype(np.float64)
    sp = log.topic("vehicle_rates_setpoint")
    if sp is not None:
        for axis in AXES:
            old["setpoint_" + axis] = sp[axis][:n].astype(np.float64)
    g = log.vector("vehicle_angular_velocity", "xyz", 3)
    if g is not None:
        for a, axis in enumerate(AXES):
            old["gyro_" + axis] = g[:n, a].astype(np.float64)
    return old


def replay(log, overrides=()):
    """Run the log through a fresh Flight with `overrides` applied; returns a ReplayResult."""
    warnings = []
    if log.topic("sensor_combined") is None or log.vector("sensor_combined", "gyro_rad", 3) is None:
        raise UserError("%s: no sensor_combined samples: not a hoverfly flight log, nothing to replay"
                        % log.path)
    if log.topic("input_rc") is None or log.vector("input_rc", "values", _RC_CHANNELS) is None:
        warnings.append("no input_rc frames in the log: the replay has no pilot input")
    params, unknown = params_from_log(log, overrides)
    for u in unknown:
        warnings.append("logged parameter not applied: " + u)
    loop_hz = params.get("loop_hz")
    rate = log.rate_hz("sensor_combined")
    if rate > 0 and abs(rate - loop_hz) > 0.02 * loop_hz:
        warnings.append("sensors logged at %.0f Hz but the loop ran at %d Hz: a faithful replay needs "
                        "blackbox_rate_hz = loop_hz" % (rate, loop_hz))
    board = ReplayBoard(log)
    flight = Flight(board, params)
    flight.receiver = ReplayReceiver(log, board)
    changes = sorted(log.changed_params, key=lambda c: c[0])
    override_names = {n for n, _ in overrides}
    ci = 0
    n = len(board.t64)
    n_motors = log.motor_count()
    new = {}
    for term in ("p", "i", "d", "f", "sum"):
        for axis in AXES:
            new["%s_%s" % (term, axis)] = np.zeros(n)
    for m in range(n_motors):
        new["motor%d" % m] = np.zeros(n)
    for axis in AXES:
        new["setpoint_" + axis] = np.zeros(n)
        new["gyro_" + axis] = np.zeros(n)
    t64 = board.t64.tolist()
    flight.start(_ORIGIN_TICKS)
    s = flight.signals
    c = flight.controller
    pids = (c.roll, c.pitch, c.yaw)
    cols_pid = [[new["%s_%s" % (term, axis)] for term in ("p", "i", "d", "f", "sum")] for axis in AXES]
    cols_m = [new["motor%d" % m] for m in range(n_motors)]
    cols_sp = [new["setpoint_" + a] for a in AXES]
    cols_g = [new["gyro_" + a] for a in AXES]
    for k in range(n):
        t = t64[k]
        while ci < len(changes) and changes[ci][0] <= t:
            _, name, value = changes[ci]
            ci += 1
            if name not in override_names and name not in _ALIGNMENT and name in params.values:
                err = _set_logged(params, name, value)
                if err and len(warnings) < 20:
                    warnings.append("logged parameter change not applied: " + err)
        board.k = k
        now = ticks_add(_ORIGIN_TICKS, t)
        board.now = now
        flight.step(now)
        for a in range(3):
            pid = pids[a]
            col = cols_pid[a]
            col[0][k] = pid.p()
            col[1][k] = pid.i
            col[2][k] = pid.d()
            col[3][k] = pid.f()
            col[4][k] = s.torque_norm[a]
            cols_sp[a][k] = s.setpoint.rate_rad_s[a]
            cols_g[a][k] = s.gyro_rad_s[a]
        for m in range(n_motors):
            cols_m[m][k] = s.motor_out[m]
    # The logged values are float32: compare the replay at the same precision.
    new = {k: v.astype(np.float32).astype(np.float64) for k, v in new.items()}
    old = _logged_outputs(log, n_motors, n)
    new = {k: v for k, v in new.items() if k in old}
    t_s = (board.t64 - log.start_us) * 1e-6
    # A damaged log can hold fewer samples of an output topic than of sensor_combined: compare
    # (and plot) the passes every logged series covers.
    short = min([len(v) for v in old.values()] + [n])
    if short < n:
        warnings.append("the logged outputs hold %d samples for %d sensor samples: compared over the first %d "
                        "passes" % (short, n, short))
        old = {k: v[:short] for k, v in old.items()}
        new = {k: v[:short] for k, v in new.items()}
        t_s = t_s[:short]
    return ReplayResult(t_s, old, new, warnings, overrides)


def _zoom_window(result, keys, width_s=0.6):
    """(t0, t1): width_s around the pass where the replay differs most from the log on these keys."""
    t = result.t_s
    if not len(t):
        return 0.0, width_s
    best = np.zeros(len(t))
    for k in keys:
        if k in result.old:
            best = np.maximum(best, np.abs(result.new[k] - result.old[k]))
    i = int(np.argmax(best)) if best.any() else len(t) // 2
    t0 = max(float(t[0]), float(t[i]) - width_s / 2)
    return t0, t0 + width_s


def _title(result, what):
    changes = ", ".join("%s=%s" % (nm, v) for nm, v in result.overrides) or "the logged parameters (no change)"
    return "Replay (open loop: the logged motion, so this is what the controller would command) - %s: %s" % (
        what, changes)


def plot_replay(result, out_dir, n_motors=4):
    """replay_pid.png and replay_motors.png: on the left the difference (replayed - logged) over the whole
    log, on the right logged against replayed over the 0.6 s where they differ most. Returns the paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(out_dir, exist_ok=True)
    t = result.t_s
    paths = []
    terms = (("p", "tab:blue"), ("i", "tab:green"), ("d", "tab:red"), ("f", "tab:purple"), ("sum", "k"))
    keys = ["%s_%s" % (term, axis) for term, _ in terms for axis in AXES]
    z0, z1 = _zoom_window(result, keys)
    zoom = (t >= z0) & (t <= z1)
    fig, axs = plt.subplots(3, 2, figsize=(14, 8.5), sharex="col", gridspec_kw={"width_ratios": (3, 2)})
    for a, axis in enumerate(AXES):
        axd, axz = axs[a, 0], axs[a, 1]
        for term, color in terms:
            key = "%s_%s" % (term, axis)
            if key not in result.old:
                continue
            label = term.upper() if term != "sum" else "sum"
            axd.plot(t, result.new[key] - result.old[key], color=color, lw=0.7, label=label)
            if term in ("p", "d", "sum"):
                axz.plot(t[zoom], result.old[key][zoom], color=color, lw=1.0, alpha=0.6, label=label + " logged")
                axz.plot(t[zoom], result.new[key][zoom], color=color, lw=1.0, ls="--", label=label + " replayed")
        axd.set_ylabel("%s: replayed - logged\n(torque, 1 = full)" % axis)
        axz.set_ylabel("%s torque (1 = full)" % axis)
        for ax in (axd, axz):
            ax.grid(alpha=0.3)
            ax.legend(loc="upper right", ncol=3, fontsize=7)
    axs[0, 0].set_title("difference over the whole log", loc="left", fontsize=10)
    axs[0, 1].set_title("logged (solid), replayed (dashed), %.2f-%.2f s" % (z0, z1),
                        loc="left", fontsize=10)
    axs[-1, 0].set_xlabel("time (s)")
    axs[-1, 1].set_xlabel("time (s)")
    fig.suptitle(_title(result, "PID terms"), fontsize=10)
    fig.tight_layout()
    p = os.path.join(out_dir, "replay_pid.png")
    fig.savefig(p, dpi=90)
    plt.close(fig)
    paths.append(p)
    mkeys = ["motor%d" % m for m in range(n_motors) if "motor%d" % m in result.old]
    z0, z1 = _zoom_window(result, mkeys)
    zoom = (t >= z0) & (t <= z1)
    fig, (axd, axz) = plt.subplots(1, 2, figsize=(14, 4.8), gridspec_kw={"width_ratios": (3, 2)})
    for key in mkeys:
        m = int(key[5:])
        line = axd.plot(t, result.new[key] - result.old[key], lw=0.7, label="motor %d" % (m + 1))
        c = line[0].get_color()
        axz.plot(t[zoom], result.old[key][zoom], lw=1.0, alpha=0.6, color=c, label="motor %d logged" % (m + 1))
        axz.plot(t[zoom], result.new[key][zoom], lw=1.0, ls="--", color=c, label="motor %d replayed" % (m + 1))
    axd.set_ylabel("replayed - logged (output, 1 = full)")
    axz.set_ylabel("output (0 = stop, idle..1)")
    axd.set_title("difference over the whole log", loc="left", fontsize=10)
    axz.set_title("logged (solid) against replayed (dashed), %.2f-%.2f s" % (z0, z1), loc="left", fontsize=10)
    for ax in (axd, axz):
        ax.set_xlabel("time (s)")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", ncol=2, fontsize=7)
    fig.suptitle(_title(result, "motors"), fontsize=10)
    fig.tight_layout()
    p = os.path.join(out_dir, "replay_motors.png")
    fig.savefig(p, dpi=90)
    plt.close(fig)
    paths.append(p)
    return paths
