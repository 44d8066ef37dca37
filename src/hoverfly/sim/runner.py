"""Fly a scenario on the simulator in lockstep and judge the flight.

Each step: the pilot moves the sticks, the physics advances one loop period, the IMU
model samples it into the sim board, and the flight core runs one pass. Deterministic
for a seed. The result is what `hoverfly fly --json` prints: tilt, altitude, drift,
events, every commanded step's rise/overshoot/settle, every disturbance's recovery (kick, torque,
gust), and the loop's own cost.
"""

import math
import random
import time

from hoverfly.compat import ticks_diff
from hoverfly.core.command.autopilot import DISABLED_NAMES, OVERRIDE_NAMES
from hoverfly.core.command.launch import LAUNCH_EVENTS
from hoverfly.core.config.params import Params
from hoverfly.core.events import (
    DISARM_REASONS,
    EV_ARMED,
    EV_ARMING_BLOCKED,
    EV_AUTOPILOT_DISABLED,
    EV_AUTOPILOT_OVERRIDE,
    EV_DISARMED,
    EV_FAILSAFE_STAGE1,
    EV_FAILSAFE_STAGE2,
    EV_IMU_FAULT,
    EV_LAUNCH,
    EV_MODE,
    EV_RX_LOST,
    EVENT_NAMES,
)
from hoverfly.core.flight import Flight
from hoverfly.core.links.mspserver import MspServer
from hoverfly.core.safety.arming import REASONS, SOURCE_NAMES
from hoverfly.core.safety.failsafe import CAUSES, FAULT_NAMES, PROCEDURES
from hoverfly.core.scheduler import PS_JITTER_MAX
from hoverfly.core.stages.control import MODE_NAMES
from hoverfly.core.stages.mixer import MIXER_TABLES
from hoverfly.core.stages.rc import aux_channel, map_channels
from hoverfly.core.stages.servos import ServoMixer
from hoverfly.errors import UserError
from hoverfly.logs.steps import measure_step
from hoverfly.protocols import msp
from hoverfly.sim.airframes import load_airframe
from hoverfly.sim.board import SimBoard
from hoverfly.sim.companion import Companion
from hoverfly.sim.physics import Vehicle
from hoverfly.sim.pilot import Pilot
from hoverfly.sim.scenario import load_scenario
from hoverfly.sim.sensors import ImuModel

_DEG = 180.0 / math.pi
# event -> words for its detail code (the events the safety code records with a reason)
DETAIL_NAMES = {EV_ARMED: SOURCE_NAMES, EV_AUTOPILOT_OVERRIDE: OVERRIDE_NAMES, EV_AUTOPILOT_DISABLED: DISABLED_NAMES,
                EV_FAILSAFE_STAGE2: PROCEDURES, EV_IMU_FAULT: ("no_samples",) + FAULT_NAMES[1:],
                EV_RX_LOST: CAUSES, EV_FAILSAFE_STAGE1: CAUSES, EV_LAUNCH: LAUNCH_EVENTS}


def build_params(airframe, scenario, overrides):
    """Defaults, then the airframe's tune, then the scenario's, then --set: each checked."""
    params = Params()
    err = params.set("mixer_type", airframe.get("frame", "quadx"))
    if err:
        raise UserError(err)
    for layer, values in (("airframe " + airframe["name"], airframe.get("params", {})),
                          ("scenario", scenario.get("params", {}))):
        for name, value in values.items():
            err = params.set(name, value)
            if err:
                raise UserError("%s: %s" % (layer, err))
    for name, value in overrides:
        err = params.set(name, value)
        if err:
            raise UserError("--set %s" % err)
    return params


class StepMeter:
    """Collects one commanded step's response; logs/steps.py measures it, as the log tools do."""

    def __init__(self, axis, mode, start, target, unit, t0_s):
        self.axis = axis
        self.mode = mode
        self.start = start
        self.target = target
        self.unit = unit
        self.t0_s = t0_s
        self.samples = []

    def add(self, t_s, value):
        self.samples.append((t_s - self.t0_s, value))

    def result(self):
        r = {"axis": self.axis, "mode": self.mode, "from": round(self.start, 3), "to": round(self.target, 3),
             "unit": self.unit, "t_s": round(self.t0_s, 3)}
        r.update(measure_step(self.samples, self.start, self.target))
        return r


RECOVERED_DEG = 2.0  # a disturbance is over once the attitude is back within this of where it was


class DisturbanceMeter:
    """One disturbance (a rate kick, an outside torque, a gust): how far the attitude was pushed from where
    it was when the disturbance began (roll and pitch, deg) and when it was back within RECOVERED_DEG for
    good. Measured on the true attitude, as the steps are, from the disturbance's start until the next
    disturbance, step or mode change."""

    def __init__(self, kind, detail, t0_s, roll_rad, pitch_rad, duration_s):
        self.kind = kind
        self.detail = detail
        self.t0_s = t0_s
        self.roll0 = roll_rad
        self.pitch0 = pitch_rad
        self.duration_s = duration_s
        self.peak_deg = 0.0
        self.last_out_s = None  # the last time the attitude was further off than RECOVERED_DEG
        self.end_s = t0_s
        self.sq = 0.0
        self.n = 0

    def add(self, t_s, roll_rad, pitch_rad):
        dr = roll_rad - self.roll0
        dp = pitch_rad - self.pitch0
        dev = math.sqrt(dr * dr + dp * dp) * _DEG
        if dev > self.peak_deg:
            self.peak_deg = dev
        if dev > RECOVERED_DEG:
            self.last_out_s = t_s
        self.sq += dev * dev
        self.n += 1
        self.end_s = t_s

    def result(self):
        back = 0.0
        if self.last_out_s is not None:
            # still out at the window's end: never back (None)
            back = None if self.last_out_s >= self.end_s else round((self.last_out_s - self.t0_s) * 1000.0 + 1.0, 1)
        r = {"kind": self.kind, "t_s": round(self.t0_s, 3), "duration_s": round(self.duration_s, 3),
             "peak_deg": round(self.peak_deg, 2), "back_within_2deg_ms": back,
             "rms_deg": round(math.sqrt(self.sq / self.n), 3) if self.n else 0.0}
        r.update(self.detail)
        return r


class SimRun:
    def __init__(self, airframe="5inch", scenario="demo", seed=1, overrides=(), duration_s=None,
                 realtime=False, firmware="cpython", micropython=None, rx="crsf", esc="dshot600",
                 log_path=None, hil=None, baud=115200, bundle=None):
        self.airframe = load_airframe(airframe) if isinstance(airframe, str) else airframe
        self.scenario = load_scenario(scenario) if isinstance(scenario, str) else scenario
        self.seed = seed
        if self.airframe.get("kind") != "plane" and (self.scenario.get("start")
                                                     or any("throw" in e for e in self.scenario["events"])):
            raise UserError("scenario %s is flown by a plane (a hand launch or a start in flight): "
                            "fly it with --airframe trainer or wing" % self.scenario["name"])
        self.params = build_params(self.airframe, self.scenario, overrides)
        # The simulated transmitter speaks `rx`; the flight controller is set up to match.
        err = self.params.set("rx_provider", rx)
        if err:
            raise UserError("--rx: " + err)
        self.duration_s = duration_s if duration_s is not None else self.scenario["duration_s"]
        if not (0 < self.duration_s <= 3600):
            raise UserError("--duration must be between 0 and 3600 s")
        self.realtime = realtime
        frame = self.params.get("mixer_type")
        if len(MIXER_TABLES[frame]) != len(MIXER_TABLES[self.airframe["frame"]]):
            raise UserError("mixer_type %s does not fit the %s airframe (%s)"
                            % (frame, self.airframe["name"], self.airframe["frame"]))
        self.loop_hz = self.params.get("loop_hz")
        self.plane_judge = None
        self.hand_launch = None
        if self.airframe.get("kind") == "plane":
            self.vehicle = self._plane()
        else:
            self.vehicle = Vehicle(self.airframe, frame)
        self.board = SimBoard(self.vehicle.n, self.params.get("rx_provider"), self.params.get("rx_pwm_channels"))
        if self.plane_judge is not None:
            from hoverfly.sim.plane import plane_servos

            for i, servo in plane_servos(self.airframe).items():  # each servo's own end points
                self.board.servos[i] = servo
            self.vehicle.servo_pos = self.board.servo_cmd
            self.board.fit_pitot(self.vehicle, seed)
        self.imu = ImuModel(self.airframe["imu"], seed, self.loop_hz, self.vehicle.hover_omega(), self.vehicle.n)
        # The simulated ESCs speak `esc` and the flight controller's output codec is set up to match;
        # they read the real frames or pulse widths and answer bidirectional DShot from the rotors.
        err = self.params.set("motor_protocol", esc)
        if err:
            raise UserError("--esc: " + err)
        self.board.set_escs(esc, self.airframe.get("motor_poles", 14))
        self.board.rotor_omega_rad_s = self.vehicle.omega
        # the servo lines the core drives (its servo mixer's, or a tricopter's tail): a bridged firmware's
        # widths land on these, with no Flight.configure here to set them up
        mix = ServoMixer()
        mix.configure(self.params)
        servo_count = mix.count if mix.count else (1 if frame == "tri" else 0)
        self.board.configure_outputs(self.params, self.vehicle.n, servo_count)
        self.flight = Flight(self.board, self.params)
        # Firmware bridge: with firmware other than "cpython" the flight runs in another
        # process (sim/bridge.py), or on a device at serial port `hil` (firmware "hil");
        # the physics, pilot and judging stay here.
        self.firmware = "hil" if hil else firmware
        self.firmware_stats = None
        if bundle is not None and self.firmware != "micropython":
            raise UserError("--bundle runs the firmware under MicroPython: add --firmware micropython")
        if self.firmware != "cpython":
            from hoverfly.sim.bridge import BridgedFlight

            self.flight = BridgedFlight(self.board, self.params, self.firmware, micropython, port=hil, baud=baud,
                                        bundle=bundle)
        self.pilot = Pilot(self.board.channels_us, self.scenario["mode"])
        self.pilot.map = map_channels(self.params.get("rc_map"))  # the transmitter as the flight reads it
        self.pilot.hover_guess = self._hover_throttle_guess()
        self.events_out = []
        self.disturbances = []  # DisturbanceMeter, in the order they began
        self._torque_until = None
        self._turbulence = None  # a gust's random wind: [rms m/s, n, e, d], while the gust lasts
        self._gust_wind = (0.0, 0.0, 0.0)
        self.on_step = None  # optional hook: fn(run) after every pass (logger, ground station)
        self.companion = None  # the scripted companion computer (msp_rc events), made on first use
        self._msp = None  # the MSP server acc_calibration events talk to, made on first use
        self.log = None  # flight log (logs/writer.py): the logger's ring written out to log_path
        if log_path:
            from hoverfly.logs.writer import attach

            self.log = attach(self, log_path)

    def _plane(self):
        """A JSBSim plane (sim/plane.py): on the ground for a hand launch, or in flight at the
        scenario's [start]; its judge and the pilot's throwing arm."""
        from hoverfly.sim.plane import HandLaunch, Plane, PlaneJudge

        plane = Plane(self.airframe, self.loop_hz)
        # the core's mixer may drive more motors than the plane has (they drive nothing)
        plane.n = len(MIXER_TABLES[self.params.get("mixer_type")])
        plane.omega.extend([0.0] * (plane.n - 1))
        start = self.scenario.get("start")
        if start:
            plane.reset(altitude_m=start.get("altitude_m", 50.0), yaw_rad=math.radians(start.get("heading_deg", 0.0)),
                        airspeed_m_s=start.get("airspeed_m_s", 13.0))
        else:  # on the ground: it starts just above its contacts; settled on them before the core boots (the
            # models tip slowly onto a wingtip contact, from rest, within 2 s), at least 3 s, until still, at most 10 s
            idle = [0.0] * plane.n
            still = 0
            for k in range(10 * self.loop_hz):
                plane.step(1.0 / self.loop_hz, idle)
                still = still + 1 if abs(plane.p) + abs(plane.q) + abs(plane.r) < 0.002 else 0
                if k > 3 * self.loop_hz and still > self.loop_hz // 5:
                    break
        self.plane_judge = PlaneJudge(self.airframe["stall_speed_m_s"])
        self.hand_launch = HandLaunch(plane)
        return plane

    def _hover_throttle_guess(self):
        v = self.vehicle
        if self.plane_judge is not None:
            return 0.35  # a plane never hovers: the pilot's cruise throttle
        omega_max = v.omega_per_volt * v.battery.voltage_v
        u = v.hover_omega() / omega_max
        idle = self.params.get("motor_idle_pct") * 0.01
        # A pilot knows roughly where the hover is; the altitude loop's integral finds the rest.
        return max(0.05, (u - idle) / (1.0 - idle)) * 0.9

    # ------------------------------------------------------------------- run
    def run(self):
        """Fly the scenario; the log and the firmware process are closed however the flight ends
        (an exception, Ctrl-C, a server's stop), so everything logged before it stays readable."""
        try:
            return self._run()
        finally:
            self.close()

    def close(self):
        if self.log is not None:
            self.log.close()
        if self.firmware != "cpython":
            self.firmware_stats = self.flight.close()

    def _run(self):
        v = self.vehicle
        board = self.board
        flight = self.flight
        pilot = self.pilot
        imu = self.imu
        period_us = 1_000_000 // self.loop_hz
        dt = period_us * 1e-6
        n_steps = int(round(self.duration_s * self.loop_hz))
        events = list(self.scenario["events"])
        ev_i = 0
        boot = board.now_us()
        flight.start(boot)
        ev_seen = 0

        # The judging runs every pass: its running figures are locals, not a dict, and the `: float` ones are C
        # doubles on the compiled twin (hoverfly/native.py), no float object per operation.
        tilt_sq: float = 0.0
        tilt_n = 0
        max_tilt: float = 0.0
        alt_min: float = 1e9
        alt_max: float = -1e9
        drift: float = 0.0
        takeoff_n: float = 0.0
        takeoff_e: float = 0.0
        alt: float
        dn: float
        de: float
        d: float
        c: float
        tilt: float
        airborne_at = None
        judge_from = self.scenario.get("judge_from_s", 0.0)
        steps_open = {}
        steps_done = []
        last_cmd = {"roll": 0.0, "pitch": 0.0, "yaw": 0.0}
        gust_until = None
        base_wind = [0.0, 0.0, 0.0]
        loop_sum: float = 0.0
        loop_max: float = 0.0
        took: float
        overruns = 0
        perf = time.perf_counter
        period_s: float = dt
        frozen = False
        self._imu_stuck = False
        self._stall_until = -1.0
        output_fs = False
        flips = []
        flip = None
        next_ev_t = events[0]["t"] if events else math.inf
        on_event = self._event
        sqrt = math.sqrt
        cos = math.cos
        acos = math.acos
        gyro = board.gyro
        accel = board.accel
        q = board.quaternion
        bat = v.battery
        motor_cmd = board.motor_cmd
        servo_cmd = board.servo_cmd
        flight_events = flight.events
        realtime = self.realtime
        plane_judge = self.plane_judge
        hand_launch = self.hand_launch
        # A plane that starts in flight is held still at its start (as on a launch rail) until it is armed: the
        # core boots, calibrates its gyro and levels its estimator as on the ground, not while the untrimmed
        # plane pitches and slows down (that calibrated its motion as gyro bias).
        held = plane_judge is not None and bool(self.scenario.get("start"))
        if held:  # what a plane held still reads: no rotation, gravity's specific force alone
            roll0, pitch0, _ = v.euler_rad()
            g = 9.80665
            v.p = v.q = v.r = 0.0
            v.fx = g * math.sin(pitch0)
            v.fy = -g * math.sin(roll0) * math.cos(pitch0)
            v.fz = -g * math.cos(roll0) * math.cos(pitch0)
        wall0 = perf()

        for k in range(n_steps):
            t = (k + 1) * dt
            # scenario events due now
            if next_ev_t <= t + 1e-9:
                while ev_i < len(events) and events[ev_i]["t"] <= t + 1e-9:
                    ev = events[ev_i]
                    ev_i += 1
                    gust_until = self._apply_event(ev, t, v, last_cmd, steps_open, steps_done,
                                                   base_wind) or gust_until
                    if "imu_freeze" in ev or "imu_stuck" in ev:
                        frozen = ev.get("imu_freeze", False) or ev.get("imu_stuck", False)
                next_ev_t = events[ev_i]["t"] if ev_i < len(events) else math.inf
            if gust_until is not None and t >= gust_until:
                v.wind_n, v.wind_e, v.wind_d = base_wind
                gust_until = None
                self._turbulence = None
            elif self._turbulence is not None:
                self._turbulent_wind(v, base_wind, dt)
            if self._torque_until is not None and t >= self._torque_until:
                v.torque_x_nm = v.torque_y_nm = v.torque_z_nm = 0.0
                self._torque_until = None
            euler = v.euler_rad()  # what the pilot sees: the state at the start of this step
            pilot.update(t, dt, v, euler)
            if self.companion is not None:  # the companion computer's MSP RC, due before this pass
                self.companion.tick(t, board.now_us(), v)
            if board.output_tick() != output_fs:  # the board's output timer: the output failsafe's watchdog
                output_fs = not output_fs
                self._output_event(output_fs)
            v.servo_cmd = servo_cmd[0]
            if held and flight.arming.armed:
                held = False
            if not held:
                v.step(dt, motor_cmd)
            if plane_judge is not None:
                hand_launch.tick(t)
                plane_judge.add(t, v)
            board.sim_us += period_us
            if not frozen:
                imu.sample(v, gyro, accel)
                board.imu_fresh = True
            elif self._imu_stuck:
                board.imu_fresh = True  # the same sample again: a sensor stuck on its last value
            q[0], q[1], q[2], q[3] = v.qw, v.qx, v.qy, v.qz
            board.battery_v = bat.voltage_v
            board.current_a = bat.current_a
            now = board.now_us()
            w0 = perf()
            if t >= self._stall_until:  # a stall event: no pass, while the board's output timer runs on
                flight.step(now)
            took = perf() - w0
            loop_sum += took
            if took > loop_max:
                loop_max = took
            if took > period_s:
                overruns += 1
            if self.on_step is not None:
                self.on_step(self)
            # judge (on the attitude the pilot saw: at most one loop period old)
            roll, pitch, yaw = euler
            airborne = not v.on_ground
            if airborne and airborne_at is None:
                airborne_at = t
                takeoff_n = v.pn
                takeoff_e = v.pe
            alt = -v.pd
            if airborne_at is not None:
                if alt < alt_min:
                    alt_min = alt
                if alt > alt_max:
                    alt_max = alt
                dn = v.pn - takeoff_n
                de = v.pe - takeoff_e
                d = sqrt(dn * dn + de * de)
                if d > drift:
                    drift = d
                if airborne and t >= judge_from and t - airborne_at > 1.0:
                    c = cos(roll) * cos(pitch)
                    tilt = acos(1.0 if c > 1.0 else (-1.0 if c < -1.0 else c)) * _DEG
                    tilt_sq += tilt * tilt
                    tilt_n += 1
                    if tilt > max_tilt:
                        max_tilt = tilt
            if steps_open:
                for meter in steps_open.values():
                    meter.add(t, self._step_signal(meter, v, roll, pitch))
            if self.disturbances:
                meter = self.disturbances[-1]
                if meter is not None:
                    meter.add(t, roll, pitch)
            if flip is None:
                if pilot._flip_phase:
                    flip = {"axis": pilot.flip_axis, "t_s": round(t, 3), "start_alt_m": alt, "min_alt_m": alt,
                            "peak_alt_m": alt}
            if flip is not None:
                # Height lost: from the highest point of the manoeuvre to the lowest after it.
                if alt > flip["peak_alt_m"]:
                    flip["peak_alt_m"] = alt
                    flip["min_alt_m"] = alt
                if alt < flip["min_alt_m"]:
                    flip["min_alt_m"] = alt
                if not pilot._flip_phase:
                    flip["end_tilt_deg"] = round(v.tilt_rad() * _DEG, 2)
                    flip["alt_loss_m"] = round(flip["peak_alt_m"] - flip["min_alt_m"], 3)
                    flip["peak_alt_m"] = round(flip["peak_alt_m"], 3)
                    flip["duration_ms"] = round((t - flip["t_s"]) * 1000.0)
                    flip["start_alt_m"] = round(flip["start_alt_m"], 3)
                    flip["min_alt_m"] = round(flip["min_alt_m"], 3)
                    flips.append(flip)
                    flip = None
            if flight_events.count != ev_seen:
                ev_seen = flight_events.drain(ev_seen, on_event)
            if realtime:
                lag = (wall0 + t) - perf()
                if lag > 0:
                    time.sleep(lag)
        wall = perf() - wall0
        self.close()
        for meter in steps_open.values():
            steps_done.append(meter)
        steps_done.sort(key=lambda m: m.t0_s)
        sim_time = n_steps * dt
        alt_now = v.altitude_m()
        n_tilt = tilt_n
        sched = flight.scheduler
        result = {
            "scenario": self.scenario["name"],
            "airframe": self.airframe["name"],
            "seed": self.seed,
            "sim_time_s": round(sim_time, 4),
            "wall_time_s": round(wall, 3),
            "realtime_factor": round(sim_time / wall, 2) if wall > 0 else None,
            "loop_hz": self.loop_hz,
            "crashed": v.crashed,
            "armed": flight.arming.armed,
            "events": self.events_out,
            "tilt_rms_deg": round(math.sqrt(tilt_sq / n_tilt), 3) if n_tilt else 0.0,
            "max_tilt_deg": round(max_tilt, 2),
            "altitude_m": {
                "min": round(alt_min, 3) if airborne_at is not None else 0.0,
                "max": round(alt_max, 3) if airborne_at is not None else 0.0,
                "final": round(alt_now, 3),
            },
            "horizontal_drift_m": round(drift, 3),
            "steps": [m.result() for m in steps_done],
            "disturbances": [m.result() for m in self.disturbances if m is not None],
            "flips": flips,
            "loop": {
                "mean_us": round(loop_sum / n_steps * 1e6, 2) if n_steps else 0.0,
                "max_us": round(loop_max * 1e6, 1),
                # Wall-clock passes longer than the loop period: a count that means something only when the
                # flight is paced to the wall clock; a lockstep run's timing is the modelled one (the jitter).
                "overruns": overruns if self.realtime else None,
                "timing": "realtime" if self.realtime else "lockstep",
                "cycle_jitter_max_us": sched.stats[PS_JITTER_MAX],
            },
            "battery": {"voltage_v": round(v.battery.voltage_v, 3), "mah_drawn": round(v.battery.mah_drawn, 1)},
            "outputs": self._outputs_report(),
            "autopilot": self.companion.report() if self.companion is not None else None,
            "receiver": self.params.get("rx_provider"),
            "firmware_runtime": self.firmware,
        }
        if plane_judge is not None:  # airspeed, bank, stalls and spins; the altitude is the runner's own
            plane = plane_judge.result()
            del plane["altitude_m"]
            result.update(plane)
        return result

    # ---------------------------------------------------------------- helpers
    def _output_event(self, tripped):
        out = self.board.output
        if tripped and out.failsafe_trips:
            self.events_out.append({"t_s": round(self._sim_s(out.failsafe_at_us), 4),
                                    "event": "output_failsafe", "detail": "no command for %d ms: outputs disarmed"
                                    % (out.timeout_us // 1000)})
        elif not tripped:
            self.events_out.append({"t_s": round(self.board.sim_us * 1e-6, 4),
                                    "event": "output_failsafe", "detail": "commands resumed"})

    def _outputs_report(self):
        b = self.board
        out = b.output
        r = {"esc": b.esc_protocol, "frames": sum(e.frames for e in b.escs),
             "errors": sum(e.errors for e in b.escs), "clamped": out.clamped,
             "failsafe_trips": out.failsafe_trips, "bidir": out.bidir}
        if out.bidir and hasattr(self.flight, "signals"):
            r["rpm"] = [self.flight.signals.motor_rpm[i] for i in range(b.motor_count)]
        return r

    def _sim_s(self, t_us):
        """A board tick time in seconds of simulated time: by its age, since a tick difference from boot wraps
        after 2**29 us (about 9 minutes of flight)."""
        b = self.board
        return (b.sim_us - ticks_diff(b.now_us(), t_us)) * 1e-6

    def _event(self, t_us, event, detail):
        t_s = self._sim_s(t_us)
        name = EVENT_NAMES[event] if 0 <= event < len(EVENT_NAMES) else "event%d" % event
        if event == EV_MODE:
            text = MODE_NAMES[detail] if 0 <= detail < len(MODE_NAMES) else str(detail)
        elif event == EV_ARMING_BLOCKED:
            text = "%s: %s" % REASONS[detail] if detail in REASONS else str(detail)
        elif event == EV_DISARMED:
            text = DISARM_REASONS[detail] if 0 <= detail < len(DISARM_REASONS) else str(detail)
        elif event in DETAIL_NAMES:
            names = DETAIL_NAMES[event]
            text = names[detail] if 0 <= detail < len(names) else str(detail)
        else:
            text = str(detail)
        self.events_out.append({"t_s": round(t_s, 4), "event": name, "detail": text})

    def _acc_calibration(self, t):
        """The pilot's accelerometer calibration, as the configurator sends it: an MSP_ACC_CALIBRATION to the
        flight's own MSP server (a bridged firmware's attitude is the one its output frames report), so the
        trims are what the estimate reads on the ground, never the simulator's true bias."""
        if self._msp is None:
            self._msp = MspServer(self.flight)
        srv = self._msp
        req = msp.encode_request(msp.MSP_ACC_CALIBRATION, b"")
        replies = msp.MspParser(max_payload=16, queue_depth=1)
        srv.feed(req, len(req), replies.feed)
        ok = replies.pop() and replies.direction == msp.DIR_REPLY
        p = self.params
        detail = ("roll %.2f deg, pitch %.2f deg" % (p.get("acc_trim_roll"), p.get("acc_trim_pitch")) if ok
                  else "refused: %s" % srv.last_error)
        self.events_out.append({"t_s": round(t, 4), "event": "acc_calibration", "detail": detail})

    def _step_signal(self, meter, v, roll, pitch):
        i = ("roll", "pitch", "yaw").index(meter.axis)
        if meter.unit == "dps":
            return (v.p, v.q, v.r)[i] * _DEG
        return (roll, pitch, 0.0)[i] * _DEG

    def _stick_for(self, axis, value, unit):
        """The stick deflection that asks for `value` (pitch up positive) on `axis`: where a pilot holds
        the stick for it, so through the flight's whole stick path (its deadband taken out and the rest
        rescaled, as core/stages/rc.py does) and on the whole microsecond nearest to it."""
        rc = self.flight.rc
        i = ("roll", "pitch", "yaw").index(axis)
        if unit == "dps":
            curve = rc.rates[i].rate_rad_s
            want = value / _DEG
            s = rc.rates[i].stick_for_rate(want)
        else:
            lim = rc.angle_limit_rad
            if self.plane_judge is not None:  # a plane: full stick is its bank or pitch limit (fwcontrol.py)
                lim = self.params.get("fw_max_pitch_deg" if axis == "pitch" else "fw_max_bank_deg") / _DEG
            want = value / _DEG

            def curve(x):
                return x * lim

            s = max(-1.0, min(1.0, want / lim))
        db = float(self.params.get("yaw_deadband" if axis == "yaw" else "deadband"))
        if s == 0.0:
            return 0.0
        a = abs(s)
        d = db + a * (500.0 - db)  # the pulse offset the flight reads as `a`
        best = None
        for us in (math.floor(d), math.ceil(d)):
            us = min(500, max(0, us))
            x = max(0.0, us - db) / (500.0 - db)
            err = abs(abs(curve(x)) - abs(want))
            if best is None or err < best[0]:
                best = (err, us)
        # the channel moves the other way for pitch up (the stick pulled back)
        up = (s > 0) != (axis == "pitch")
        # a quarter microsecond towards 2000: the pilot's int() of 1500 + 500 * stick lands on this pulse
        mag = (best[1] + 0.25) / 500.0 if up else (best[1] - 0.25) / 500.0
        mag = min(1.0, mag)
        return mag if up else -mag

    def _disturbance(self, kind, detail, t, v, duration_s):
        """Start measuring a disturbance from the attitude it meets (the one before it ends)."""
        roll, pitch, _ = v.euler_rad()
        self.disturbances.append(DisturbanceMeter(kind, detail, t, roll, pitch, duration_s))

    def _turbulent_wind(self, v, base_wind, dt):
        """A gust's turbulence: each wind component a first-order Gauss-Markov process of the asked RMS
        and a 1 s correlation time (Dryden's low-altitude scale over a few m/s), on top of the gust."""
        tb = self._turbulence
        rms = tb[0]
        a = dt / 1.0
        k = rms * math.sqrt(2.0 * a)
        gauss = self._turb_rng.gauss
        for i in (1, 2, 3):
            tb[i] += -a * tb[i] + k * gauss(0.0, 1.0)
        gw = self._gust_wind
        v.wind_n = base_wind[0] + gw[0] + tb[1]
        v.wind_e = base_wind[1] + gw[1] + tb[2]
        v.wind_d = base_wind[2] + gw[2] + tb[3] * 0.5  # vertical turbulence is weaker near the ground

    def _apply_event(self, ev, t, v, last_cmd, steps_open, steps_done, base_wind):
        p = self.pilot
        gust_until = None
        if ("step" in ev or "mode" in ev) and self.disturbances:
            self.disturbances.append(None)  # a step or mode change ends the window of the disturbance before
        if "arm" in ev:
            p.arm = ev["arm"]
        if "mode" in ev:
            p.mode = ev["mode"]
        if "throttle" in ev:
            p.throttle = ev["throttle"]
            p.hold_alt_m = None
        if "throttle_us" in ev:
            p.throttle = (ev["throttle_us"] - 1000) / 1000.0
            p.hold_alt_m = None
        for axis in ("roll", "pitch", "yaw"):
            if axis in ev:
                setattr(p, axis, ev[axis])
            if axis + "_us" in ev:
                setattr(p, axis, (ev[axis + "_us"] - 1500) / 500.0)
        if "hold_altitude_m" in ev:
            p.set_hold(ev["hold_altitude_m"], v)
        if "fly_to" in ev:
            p.fly_to = tuple(ev["fly_to"])
        if "land" in ev and ev["land"]:
            p.start_land(v)
        if "flip" in ev:
            p.start_flip(ev["flip"], t)
        if "throw" in ev and self.hand_launch is not None:
            th = ev["throw"] if isinstance(ev["throw"], dict) else {}
            h = self.hand_launch
            h.forward_n = v.mass_kg * th.get("forward_m_s2", 40.0)
            h.up_n = v.mass_kg * th.get("up_m_s2", 12.0)
            h.duration_s = th.get("duration_s", 0.3)
            h.start(t)
        if "step" in ev or "mode" in ev:
            # A new step, or a mode change, ends the windows of the steps still being measured.
            for axis_open in list(steps_open):
                if "step" not in ev or ev["step"]["axis"] != axis_open:
                    steps_done.append(steps_open.pop(axis_open))
        if "step" in ev:
            st = ev["step"]
            axis = st["axis"]
            unit = st.get("unit", "dps" if p.mode == "acro" else "deg")
            to = float(st["to"])
            setattr(p, axis, self._stick_for(axis, to, unit))
            old = steps_open.pop(axis, None)
            if old is not None:
                steps_done.append(old)
            start = last_cmd[axis] if old is not None else 0.0
            last_cmd[axis] = to
            mode = "rate" if unit == "dps" else "angle"
            steps_open[axis] = StepMeter(axis, mode, start, to, unit, t)
        if "kick" in ev:
            k = ev["kick"]
            self._disturbance("kick", dict(k), t, v, 0.0)
            v.p += k.get("roll_dps", 0.0) / _DEG
            v.q += k.get("pitch_dps", 0.0) / _DEG
            v.r += k.get("yaw_dps", 0.0) / _DEG
        if "wind" in ev:
            w = ev["wind"]
            base_wind[0] = w.get("north_m_s", 0.0)
            base_wind[1] = w.get("east_m_s", 0.0)
            base_wind[2] = w.get("down_m_s", 0.0)
            v.wind_n, v.wind_e, v.wind_d = base_wind
        if "gust" in ev:
            g = ev["gust"]
            self._gust_wind = (g.get("north_m_s", 0.0), g.get("east_m_s", 0.0), g.get("down_m_s", 0.0))
            v.wind_n = base_wind[0] + self._gust_wind[0]
            v.wind_e = base_wind[1] + self._gust_wind[1]
            v.wind_d = base_wind[2] + self._gust_wind[2]
            gust_until = t + g.get("duration_s", 1.0)
            self._turbulence = None
            if g.get("turbulence_m_s", 0.0) > 0.0:
                if not hasattr(self, "_turb_rng"):
                    self._turb_rng = random.Random(self.seed * 7919 + 17)
                rms = g["turbulence_m_s"]
                gauss = self._turb_rng.gauss
                self._turbulence = [rms, rms * gauss(0.0, 1.0), rms * gauss(0.0, 1.0), rms * gauss(0.0, 1.0)]
            self._disturbance("gust", dict(g), t, v, g.get("duration_s", 1.0))
        if "torque" in ev:
            tq = ev["torque"]
            v.torque_x_nm = tq.get("roll_nm", 0.0)
            v.torque_y_nm = tq.get("pitch_nm", 0.0)
            v.torque_z_nm = tq.get("yaw_nm", 0.0)
            self._torque_until = t + tq.get("duration_s", 0.1)
            self._disturbance("torque", dict(tq), t, v, tq.get("duration_s", 0.1))
        if "stall_ms" in ev:
            self._stall_until = t + ev["stall_ms"] * 1e-3
            self.events_out.append({"t_s": round(t, 4), "event": "stall", "detail": "%g ms" % ev["stall_ms"]})
        if "rx_lost" in ev:
            self.board.rx_alive = not ev["rx_lost"]
        # safety and autopilot (issue 5): the companion computer, the autopilot switch, open sessions
        if "imu_stuck" in ev:
            self._imu_stuck = ev["imu_stuck"]
        if "autopilot_switch" in ev:
            ch = aux_channel(self.pilot.map, self.params.get("ap_ch"))  # AUX3 where rc_map puts it
            if ch > 0:
                p.overrides_us[ch - 1] = 2000 if ev["autopilot_switch"] else 1000
        if "msp_rc" in ev:
            if self.companion is None:
                # in process: wired to the flight's CLI/MSP port (MSP bytes); the bridge takes MSP_RC frames
                self.companion = Companion(self.flight, self.params, p.hover_guess,
                                           board=self.board if self.firmware == "cpython" else None)
            self.companion.set(ev["msp_rc"], t)
        if ev.get("acc_calibration"):
            self._acc_calibration(t)
        if "config_session" in ev:
            self.flight.config_session = ev["config_session"]
        if "channel" in ev:  # an AUX switch (or any channel) set by hand: {ch = 1-based, us = pulse}
            p.overrides_us[ev["channel"]["ch"] - 1] = ev["channel"]["us"]
        if "set" in ev:
            for name, value in ev["set"].items():
                err = self.params.set(name, value)
                if err:
                    raise UserError(err)
        return gust_until


def fly(scenario="demo", airframe="5inch", seed=1, overrides=(), duration_s=None, realtime=False,
        firmware="cpython", micropython=None, rx="crsf", esc="dshot600", log_path=None, hil=None, baud=115200,
        bundle=None):
    """Fly and judge; returns the result dict. `hil`: a serial port with the firmware on a device;
    `bundle`: a `hoverfly flash --out DIR --chip unix-x64` folder the MicroPython firmware runs from."""
    run = SimRun(airframe, scenario, seed, overrides, duration_s, realtime, firmware=firmware,
                 micropython=micropython, rx=rx, esc=esc, log_path=log_path, hil=hil, baud=baud, bundle=bundle)
    result = run.run()
    if run.log is not None:
        result["log"] = run.log.stats()
    if run.firmware_stats is not None:
        result["firmware"] = run.firmware_stats
    return result
