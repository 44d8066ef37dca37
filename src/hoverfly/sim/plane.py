"""Fixed-wing physics: a JSBSim aircraft stepped in lockstep at the loop rate.

The plane offers the same truth as the quad's physics.Vehicle (body rates p/q/r, specific force
fx/fy/fz at the IMU, attitude quaternion qw..qz, NED position pn/pe/pd and velocity vn/ve/vd,
on_ground, crashed, wind_n/e/d, a battery, the motor speed in `omega` for the vibration model), so
sensors.ImuModel, the sim board and the flight core read it without knowing which physics flies.
Extra for a plane: airspeed_m_s, alpha_rad, and the surfaces it was last commanded.

Inputs: the board's servo positions (-1..1, after each simulated servo's own end points, see
sim/esc.SimServo) and the motor command (0..1). The airframe's [servos] table says which servo
drives which surface and which way: `direction = 1` means the servo moving towards its max end
point rolls right / pitches up / yaws right (for an elevon: raises its trailing edge). The
JSBSim models take JSBSim's usual signs (+aileron-cmd rolls right, +elevator-cmd pitches nose
down, +rudder-cmd yaws nose left), so pitch and yaw are negated on the way in.

JSBSim works in feet, pounds and knots; everything is converted here, at this one boundary.
"""

import math
import pathlib

from hoverfly.errors import UserError
from hoverfly.sim.physics import Battery

ROOT = pathlib.Path(__file__).parent / "jsbsim"
FT = 0.3048
LBF_N = 4.4482216
HP_W = 745.69987
G_M_S2 = 9.80665
_START_LAT_DEG = 47.0
_START_LON_DEG = 8.0
_EARTH_M = 6371000.0
# A belly landing harder than this (vertical speed at first contact) breaks the plane.
_CRASH_DOWN_M_S = 4.0
_DRIVE_EFFICIENCY = 0.75  # motor x ESC: shaft power -> battery power

# Read every step, in this order, through property nodes (one C call each, no name lookups).
_READ = ("velocities/p-rad_sec", "velocities/q-rad_sec", "velocities/r-rad_sec",
         "accelerations/a-pilot-x-ft_sec2", "accelerations/a-pilot-y-ft_sec2", "accelerations/a-pilot-z-ft_sec2",
         "attitude/phi-rad", "attitude/theta-rad", "attitude/psi-rad",
         "position/lat-geod-deg", "position/long-gc-deg", "position/h-agl-ft",
         "velocities/v-north-fps", "velocities/v-east-fps", "velocities/v-down-fps",
         "velocities/vt-fps", "forces/fbz-gear-lbs", "propulsion/engine/propeller-rpm",
         "aero/alpha-rad", "propulsion/engine/power-hp")

# surface -> (aileron, elevator, rudder) JSBSim command per unit of servo position (direction +1)
SURFACES = {
    "aileron": (1.0, 0.0, 0.0),
    "elevator": (0.0, -1.0, 0.0),
    "rudder": (0.0, 0.0, -1.0),
    # an elevon raising its trailing edge pitches up and rolls towards its own side
    "elevon_left": (-0.5, -0.5, 0.0),
    "elevon_right": (0.5, -0.5, 0.0),
    # a V-tail ruddervator raising its trailing edge pitches up and yaws towards its own side
    "ruddervator_left": (0.0, -0.5, 0.5),
    "ruddervator_right": (0.0, -0.5, -0.5),
}


def _jsbsim():
    try:
        import jsbsim
    except ImportError:
        raise UserError("the plane simulator needs JSBSim: pip install jsbsim") from None
    return jsbsim


def model_file(airframe):
    """The JSBSim XML an airframe flies: a built-in model, or the user's own file (`xml`)."""
    if airframe.get("xml"):
        return pathlib.Path(airframe["xml"])
    return ROOT / "aircraft" / airframe["model"] / (airframe["model"] + ".xml")


def engine_dir(xml):
    """Where a model's engine and propeller files are: an engine/ folder beside the XML, or the
    engine/ of the JSBSim root it sits in (root/aircraft/<name>/<name>.xml), else hoverfly's own."""
    xml = pathlib.Path(xml)
    for d in (xml.parent / "engine", xml.parent.parent.parent / "engine"):
        if d.is_dir() and any(d.glob("*.xml")):
            return d
    return ROOT / "engine"


def _flush_c_stdio():
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # no C library to reach: nothing buffered there to lose
        pass


def load_fdm(airframe, dt_s):
    """A JSBSim executive with the airframe's model loaded; UserError if JSBSim refuses it.

    JSBSim reports its problems on the process's own stdout/stderr (C++ streams, several lines):
    they are caught at the file-descriptor level while the model loads, so `hoverfly fly --json`
    stays clean and a refusal is one line naming JSBSim's first complaint."""
    import contextlib
    import io
    import os
    import tempfile

    jsbsim = _jsbsim()
    jsbsim.FGJSBBase().debug_lvl = 0  # keep JSBSim's banner off stdout (fly --json prints there)
    xml = model_file(airframe)
    if not xml.exists():
        raise UserError("airframe %s: no JSBSim model %s" % (airframe["name"], xml))
    fdm = jsbsim.FGFDMExec(root_dir=str(ROOT))
    fdm.set_debug_level(0)
    fdm.set_dt(dt_s)
    ok = False
    failure = ""
    py_out = io.StringIO()
    with tempfile.TemporaryFile(mode="w+b") as caught:
        saved = [os.dup(1), os.dup(2)]
        try:
            os.dup2(caught.fileno(), 1)
            os.dup2(caught.fileno(), 2)
            # under a Python that has replaced sys.stdout (pytest, a notebook) JSBSim writes there
            with contextlib.redirect_stdout(py_out), contextlib.redirect_stderr(py_out):
                try:
                    ok = fdm.load_model_with_paths(xml.stem, str(xml.parent), str(engine_dir(xml)),
                                                   str(ROOT / "systems"), False)
                except Exception as exc:  # JSBSim raises its own types for malformed XML
                    failure = str(exc)
        finally:
            _flush_c_stdio()  # JSBSim's C++ streams buffer when not on a terminal
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
        caught.seek(0)
        said = caught.read().decode("utf-8", "replace") + py_out.getvalue()
    if not ok:
        lines = [ln.strip() for ln in (failure + "\n" + said).splitlines()
                 if ln.strip() and not ln.strip().startswith("In file")]
        telling = [ln for ln in lines if "could not" in ln.lower() or "error" in ln.lower()] or lines
        raise UserError("airframe %s: JSBSim cannot load %s%s"
                        % (airframe["name"], xml.name, (": " + telling[0]) if telling else ""))
    return fdm


def plane_servos(airframe):
    """The simulated servos of a plane, each with its own end points from the airframe's wiring
    (for the sim board's servo outputs: index -> sim/esc.SimServo)."""
    from hoverfly.sim.esc import SimServo

    return {spec["servo"]: SimServo(spec["min_us"], spec["mid_us"], spec["max_us"])
            for spec in airframe["servos"].values()}


class Plane:
    """One JSBSim aircraft in lockstep: step(dt, motor_cmd) advances one loop period."""

    kind = "plane"

    def __init__(self, airframe, loop_hz):
        self.airframe = airframe
        self.dt_s = 1.0 / loop_hz
        self.fdm = load_fdm(airframe, self.dt_s)
        pm = self.fdm.get_property_manager()
        self._nodes = []
        for name in _READ:
            node = pm.get_node(name, False)
            if node is None:
                raise UserError("airframe %s: JSBSim model %s lacks %s" % (airframe["name"], airframe["model"], name))
            self._nodes.append(node)
        self._set_nodes = [pm.get_node(n, True) for n in
                           ("fcs/aileron-cmd-norm", "fcs/elevator-cmd-norm", "fcs/rudder-cmd-norm",
                            "fcs/throttle-cmd-norm", "external_reactions/hand-forward/magnitude",
                            "external_reactions/hand-up/magnitude")]
        self.mass_kg = self.fdm["inertia/weight-lbs"] * LBF_N / G_M_S2
        b = airframe["battery"]
        self.battery = Battery(b["cells"], b["capacity_mah"], b["r_int_ohm"])
        # servo wiring: (servo index, aileron, elevator, rudder) per wired surface
        self.wiring = []
        for surface, spec in airframe["servos"].items():
            ka, ke, kr = SURFACES[surface]
            d = spec["direction"]
            self.wiring.append((spec["servo"], ka * d, ke * d, kr * d))
        self.servo_pos = [0.0] * 4  # the runner hands the board's servo positions list in here
        self.n = 1
        self.omega = [0.0]
        self.servo_cmd = 0.0
        self.hand_forward_n = 0.0
        self.hand_up_n = 0.0
        self.reset()

    def hover_omega(self):
        """The motor speed the vibration model scales by: full-throttle static speed (a plane never hovers)."""
        return self.airframe.get("motor_rad_s", 900.0)

    # ------------------------------------------------------------------ start
    def reset(self, altitude_m=0.0, roll_rad=0.0, pitch_rad=0.0, yaw_rad=0.0, airspeed_m_s=0.0):
        """Start on the ground (altitude 0: resting on its contacts) or in flight at airspeed."""
        fdm = self.fdm
        fdm["ic/lat-geod-deg"] = _START_LAT_DEG
        fdm["ic/long-gc-deg"] = _START_LON_DEG
        fdm["ic/terrain-elevation-ft"] = 0.0
        # on the ground the contacts touch at a few cm: start just above them and let it settle
        fdm["ic/h-agl-ft"] = (altitude_m if altitude_m > 0.0 else self.airframe.get("rest_height_m", 0.08)) / FT
        fdm["ic/phi-rad"] = roll_rad
        fdm["ic/theta-rad"] = pitch_rad
        fdm["ic/psi-true-rad"] = yaw_rad
        fdm["ic/vc-kts"] = airspeed_m_s / 0.514444
        for k in ("ic/p-rad_sec", "ic/q-rad_sec", "ic/r-rad_sec"):
            fdm[k] = 0.0
        fdm.run_ic()
        fdm["propulsion/set-running"] = -1
        # JSBSim's electric motor is an ideal constant-power source: its torque (power / speed) is
        # unbounded at standstill and a motor start would kick the airframe into a roll it cannot
        # have. Without a sense the propeller still makes its thrust; the torque reaction and
        # gyroscopic moments (a few % of the aileron's authority on these models) are left out.
        fdm["propulsion/engine/propeller-sense"] = 0.0
        self._cos_lat0 = math.cos(math.radians(_START_LAT_DEG))
        self.wind_n = self.wind_e = self.wind_d = 0.0
        self._wind_sent = (0.0, 0.0, 0.0)
        self.crashed = False
        self.impact_m_s = 0.0
        self.hand_forward_n = 0.0
        self.hand_up_n = 0.0
        self.aileron_cmd = self.elevator_cmd = self.rudder_cmd = self.throttle_cmd = 0.0
        self.on_ground = altitude_m <= 0.0
        self._read()
        self.on_ground = altitude_m <= 0.0

    # ------------------------------------------------------------------ step
    def step(self, dt, motor_cmd):
        pos = self.servo_pos
        ail = ele = rud = 0.0
        for servo, ka, ke, kr in self.wiring:
            s = pos[servo]
            ail += ka * s
            ele += ke * s
            rud += kr * s
        ail = -1.0 if ail < -1.0 else (1.0 if ail > 1.0 else ail)
        ele = -1.0 if ele < -1.0 else (1.0 if ele > 1.0 else ele)
        rud = -1.0 if rud < -1.0 else (1.0 if rud > 1.0 else rud)
        thr = motor_cmd[0]
        thr = 0.0 if thr < 0.0 else (1.0 if thr > 1.0 else thr)
        self.aileron_cmd = ail
        self.elevator_cmd = ele
        self.rudder_cmd = rud
        self.throttle_cmd = thr
        sn = self._set_nodes
        sn[0].set_double_value(ail)
        sn[1].set_double_value(ele)
        sn[2].set_double_value(rud)
        sn[3].set_double_value(thr)
        sn[4].set_double_value(self.hand_forward_n / LBF_N)
        sn[5].set_double_value(self.hand_up_n / LBF_N)
        wind = (self.wind_n, self.wind_e, self.wind_d)
        if wind != self._wind_sent:  # the runner's wind and gust events
            fdm = self.fdm
            fdm["atmosphere/wind-north-fps"] = wind[0] / FT
            fdm["atmosphere/wind-east-fps"] = wind[1] / FT
            fdm["atmosphere/wind-down-fps"] = wind[2] / FT
            self._wind_sent = wind
        self.fdm.run()
        was_on_ground = self.on_ground
        vd_before = self.vd
        self._read()
        if self.on_ground and not was_on_ground:
            self.impact_m_s = max(vd_before, self.vd)
            if self.impact_m_s > _CRASH_DOWN_M_S:
                self.crashed = True
        if self.battery is not None:
            power_w = self._power_hp * HP_W / _DRIVE_EFFICIENCY
            v = self.battery.voltage_v
            self.battery.step(power_w / v if v > 1.0 else 0.0, dt)

    def _read(self):
        (p, q, r, ax, ay, az, phi, theta, psi, lat, lon, h_agl, vn, ve, vd, vt, fbz, rpm, alpha,
         power_hp) = [n.get_double_value() for n in self._nodes]
        self.p = p
        self.q = q
        self.r = r
        self.fx = ax * FT
        self.fy = ay * FT
        self.fz = az * FT
        self.roll_rad = phi
        self.pitch_rad = theta
        if psi > math.pi:  # JSBSim's heading runs 0..2 pi; the quad physics' yaw -pi..pi
            psi -= 2.0 * math.pi
        self.yaw_rad = psi
        cr = math.cos(phi * 0.5)
        sr = math.sin(phi * 0.5)
        cp = math.cos(theta * 0.5)
        sp = math.sin(theta * 0.5)
        cy = math.cos(psi * 0.5)
        sy = math.sin(psi * 0.5)
        self.qw = cr * cp * cy + sr * sp * sy
        self.qx = sr * cp * cy - cr * sp * sy
        self.qy = cr * sp * cy + sr * cp * sy
        self.qz = cr * cp * sy - sr * sp * cy
        self.pn = math.radians(lat - _START_LAT_DEG) * _EARTH_M
        self.pe = math.radians(lon - _START_LON_DEG) * _EARTH_M * self._cos_lat0
        self.pd = -h_agl * FT
        self.vn = vn * FT
        self.ve = ve * FT
        self.vd = vd * FT
        self.airspeed_m_s = vt * FT
        self.alpha_rad = alpha
        # STRUCTURE contacts never set gear/wow: any ground force means contact
        self.on_ground = fbz < -1e-3
        self.omega[0] = rpm * (math.pi / 30.0)
        self._power_hp = power_hp if power_hp > 0.0 else 0.0

    # ------------------------------------------------------------------ hand launch
    def hold(self, holding):
        """The pilot holds the plane up (weight carried by the hand) or lets go."""
        self.hand_up_n = self.mass_kg * G_M_S2 if holding else 0.0

    def throw(self, forward_n, up_n):
        """The throw's push through the hand (N along the body x axis, N upwards); zero: let go."""
        self.hand_forward_n = forward_n
        self.hand_up_n = up_n

    # ------------------------------------------------------------------ truth
    def euler_rad(self):
        return self.roll_rad, self.pitch_rad, self.yaw_rad

    def tilt_rad(self):
        c = math.cos(self.roll_rad) * math.cos(self.pitch_rad)
        return math.acos(1.0 if c > 1.0 else (-1.0 if c < -1.0 else c))

    def altitude_m(self):
        return -self.pd


# ---------------------------------------------------------------------- model figures
# Open-loop measurements of a model's flying qualities (bench/plane_model.py, tests): the figures a
# pilot knows a plane by, measured in the same JSBSim flight the simulator flies.

def _surfaces(plane, aileron=0.0, elevator=0.0, rudder=0.0):
    """Servo positions that command these JSBSim-signed surface values (the wiring inverted)."""
    pos = plane.servo_pos
    for i in range(len(pos)):
        pos[i] = 0.0
    want = (aileron, elevator, rudder)
    for servo, ka, ke, kr in plane.wiring:
        # the wiring's columns are orthogonal (one surface each, or an elevon/ruddervator pair),
        # so each servo is the wanted command projected onto its own column
        n = ka * ka + ke * ke + kr * kr
        pos[servo] = (ka * want[0] + ke * want[1] + kr * want[2]) / n


def glide(plane, elevator=0.0, seconds=40.0, settle_s=20.0, altitude_m=300.0, airspeed_m_s=12.0):
    """Motor off, wings held level by nothing but the model's own stability: mean airspeed and the
    glide ratio (distance over height lost) once the phugoid has died down."""
    plane.reset(altitude_m=altitude_m, airspeed_m_s=airspeed_m_s)
    _surfaces(plane, elevator=elevator)
    dt = plane.dt_s
    n = int(settle_s / dt)
    for _ in range(n):
        plane.step(dt, (0.0,))
    n0, e0, h0 = plane.pn, plane.pe, plane.altitude_m()
    speed = 0.0
    m = int((seconds - settle_s) / dt)
    for _ in range(m):
        plane.step(dt, (0.0,))
        speed += plane.airspeed_m_s
    dist = math.hypot(plane.pn - n0, plane.pe - e0)
    lost = h0 - plane.altitude_m()
    return {"airspeed_m_s": speed / m, "glide_ratio": dist / lost if lost > 0 else float("inf"),
            "sink_m_s": lost / (seconds - settle_s), "bank_deg": math.degrees(plane.roll_rad)}


def stall(plane, airspeed_m_s=12.0, ramp_s=8.0):
    """A power-off stall as a pilot flies one: wings level, the elevator eased back until the wing
    quits. Measures the highest lift coefficient reached (JSBSim's lift force over qS) and the 1 g
    stall speed it gives, sqrt(2 m g / (rho S CLmax)), plus the lowest airspeed seen."""
    plane.reset(altitude_m=300.0, airspeed_m_s=airspeed_m_s)
    fdm = plane.fdm
    s_m2 = fdm["metrics/Sw-sqft"] * FT * FT
    dt = plane.dt_s
    cl_max = 0.0
    v_min = 1e9
    alpha_at = 0.0
    n = int(ramp_s / dt)
    for k in range(n):
        _surfaces(plane, elevator=-k / n)  # pitch up: negative elevator-cmd
        plane.step(dt, (0.0,))
        qbar_pa = fdm["aero/qbar-psf"] * LBF_N / (FT * FT)
        if qbar_pa > 1.0:
            cl = fdm["forces/fwz-aero-lbs"] * LBF_N / (qbar_pa * s_m2)  # JSBSim: +fwz is lift
            if cl > cl_max:
                cl_max = cl
                alpha_at = plane.alpha_rad
        if plane.airspeed_m_s < v_min:
            v_min = plane.airspeed_m_s
    rho = fdm["atmosphere/rho-slugs_ft3"] * 515.378818
    return {"cl_max": cl_max, "alpha_deg": math.degrees(alpha_at), "min_airspeed_m_s": v_min,
            "stall_speed_m_s": math.sqrt(2.0 * plane.mass_kg * G_M_S2 / (rho * s_m2 * cl_max))}


def roll_rate(plane, airspeed_m_s, seconds=1.0, direction=1.0):
    """Full aileron from wings level at airspeed: the roll rate once the roll mode has settled
    (0.3 s in; what a pilot calls the plane's roll rate), the highest rate within `seconds` (it
    grows a little as the nose drops and the plane speeds up) and the bank reached at 0.3 s."""
    plane.reset(altitude_m=300.0, airspeed_m_s=airspeed_m_s)
    _surfaces(plane, aileron=direction)
    dt = plane.dt_s
    best = 0.0
    at = None
    n_settled = int(0.3 / dt)
    for k in range(int(seconds / dt)):
        plane.step(dt, (0.0,))
        if k == n_settled:
            at = (plane.p, plane.roll_rad)
        if abs(plane.p) > abs(best):
            best = plane.p
    return {"roll_rate_dps": math.degrees(at[0]), "peak_roll_rate_dps": math.degrees(best),
            "bank_at_0_3_s_deg": math.degrees(at[1]), "airspeed_m_s": airspeed_m_s}


def level_flight(plane, airspeed_m_s, throttle, seconds=10.0):
    """Elevator centred at a throttle: the speed, climb rate and bank the plane settles to."""
    plane.reset(altitude_m=300.0, airspeed_m_s=airspeed_m_s)
    _surfaces(plane)
    dt = plane.dt_s
    h0 = None
    speed = 0.0
    n = int(seconds / dt)
    for k in range(n):
        plane.step(dt, (throttle,))
        if k == n // 2:
            h0 = plane.altitude_m()
        if k >= n // 2:
            speed += plane.airspeed_m_s
    return {"airspeed_m_s": speed / (n - n // 2), "climb_m_s": (plane.altitude_m() - h0) / (seconds / 2),
            "bank_deg": math.degrees(plane.roll_rad), "pitch_deg": math.degrees(plane.pitch_rad)}


# ---------------------------------------------------------------------- flying a scenario
class HandLaunch:
    """A pilot's throw: the arm swings the plane forward (and a little up) for duration_s, then lets
    go. 40 m/s2 for 0.3 s leaves the hand at about 12 m/s, a firm overhand throw; the push is well
    above INAV's launch detection threshold (nav_fw_launch_accel 1863 cm/s2 for 40 ms)."""

    def __init__(self, plane, forward_m_s2=40.0, up_m_s2=12.0, duration_s=0.3):
        self.plane = plane
        self.forward_n = plane.mass_kg * forward_m_s2
        self.up_n = plane.mass_kg * up_m_s2
        self.duration_s = duration_s
        self.t0_s = None

    def start(self, t_s):
        self.t0_s = t_s
        self.plane.throw(self.forward_n, self.up_n)

    def tick(self, t_s):
        """Call every step; returns True while the hand still pushes."""
        if self.t0_s is None:
            return False
        if t_s - self.t0_s >= self.duration_s:
            self.plane.throw(0.0, 0.0)
            self.t0_s = None
            return False
        return True


class PlaneJudge:
    """What a pilot watches on a plane, per step while airborne: airspeed (min, mean, max), the
    steepest bank, altitude, stalls (airspeed under the airframe's stall speed for 0.2 s or more)
    and spins (stalled and yawing faster than 60 deg/s for a second: autorotation, not a turn)."""

    STALL_HOLD_S = 0.2
    SPIN_YAW_RAD_S = math.radians(60.0)
    SPIN_HOLD_S = 1.0

    def __init__(self, stall_speed_m_s):
        self.stall_speed_m_s = stall_speed_m_s
        self.n = 0
        self.speed_sum = 0.0
        self.speed_min = math.inf
        self.speed_max = 0.0
        self.max_bank_rad = 0.0
        self.alt_min = math.inf
        self.alt_max = -math.inf
        self.stalls = []  # times (s) each stall began
        self.spins = []
        self._slow_since = None
        self._spin_since = None
        self._in_stall = False
        self._in_spin = False

    def add(self, t_s, plane):
        if plane.on_ground:
            self._slow_since = self._spin_since = None
            self._in_stall = self._in_spin = False
            return
        v = plane.airspeed_m_s
        self.n += 1
        self.speed_sum += v
        if v < self.speed_min:
            self.speed_min = v
        if v > self.speed_max:
            self.speed_max = v
        bank = abs(plane.roll_rad)
        if bank > self.max_bank_rad:
            self.max_bank_rad = bank
        alt = -plane.pd
        if alt < self.alt_min:
            self.alt_min = alt
        if alt > self.alt_max:
            self.alt_max = alt
        slow = v < self.stall_speed_m_s
        if slow:
            if self._slow_since is None:
                self._slow_since = t_s
            if not self._in_stall and t_s - self._slow_since >= self.STALL_HOLD_S:
                self._in_stall = True
                self.stalls.append(round(self._slow_since, 3))
        else:
            self._slow_since = None
            self._in_stall = False
        if self._in_stall and abs(plane.r) > self.SPIN_YAW_RAD_S:
            if self._spin_since is None:
                self._spin_since = t_s
            if not self._in_spin and t_s - self._spin_since >= self.SPIN_HOLD_S:
                self._in_spin = True
                self.spins.append(round(self._spin_since, 3))
        else:
            self._spin_since = None
            self._in_spin = False

    def result(self):
        """The plane's part of `hoverfly fly --json`."""
        if self.n == 0:
            return {"airspeed_m_s": None, "max_bank_deg": None, "stalls": [], "spins": [], "altitude_m": None}
        return {
            "airspeed_m_s": {"min": round(self.speed_min, 2), "mean": round(self.speed_sum / self.n, 2),
                             "max": round(self.speed_max, 2)},
            "max_bank_deg": round(math.degrees(self.max_bank_rad), 1),
            "stall_speed_m_s": self.stall_speed_m_s,
            "stalls": self.stalls,
            "spins": self.spins,
            "altitude_m": {"min": round(self.alt_min, 2), "max": round(self.alt_max, 2)},
        }
