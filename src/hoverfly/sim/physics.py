"""Rigid-body multirotor physics in plain floats (no numpy per step).

State: position and velocity in NED (m, m/s), attitude quaternion body->NED, body
rates FRD (rad/s), rotor speeds (rad/s), battery state. Motors are first-order lags
toward a speed that scales with the loaded battery voltage (thrust ~ V²); thrust
kT·ω², reaction torque kQ·ω²; quadratic body drag against the air (wind), linear
angular damping; ArduPilot's ground rule (no contact solver: clamp at the ground,
level, stop). Semi-implicit Euler at the loop rate, the scheme the reference measured
at 13.5 µs per step (sim-physics-and-logs.md §4.1).

Motor geometry comes from the mixer table of the chosen frame, so the simulated
craft and the controller always agree on which motor is where and how it spins.
"""

import math

from hoverfly.core.stages.mixer import MIXER_TABLES

G_M_S2 = 9.80665
RHO_KG_M3 = 1.225


class Battery:
    """Cells with a linear-ish open-circuit curve and internal resistance (sag)."""

    # Open-circuit volts per cell against state of charge, 0 %..100 % in 10 % steps (LiPo, typical).
    _OCV = (3.30, 3.60, 3.69, 3.73, 3.77, 3.81, 3.86, 3.92, 3.99, 4.08, 4.20)

    def __init__(self, cells, capacity_mah, r_int_ohm, soc=1.0):
        self.cells = cells
        self.capacity_mah = capacity_mah
        self.r_int_ohm = r_int_ohm
        self.soc = soc
        self.current_a = 0.0
        self.voltage_v = self.ocv_v()
        self.mah_drawn = 0.0

    def ocv_v(self):
        x: float = self.soc * 10.0
        if x <= 0.0:
            return self._OCV[0] * self.cells
        if x >= 10.0:
            return self._OCV[10] * self.cells
        i = int(x)
        f: float = x - i
        return (self._OCV[i] * (1.0 - f) + self._OCV[i + 1] * f) * self.cells

    def step(self, current_a: float, dt_s: float):
        self.current_a = current_a
        self.voltage_v = self.ocv_v() - current_a * self.r_int_ohm
        used: float = current_a * dt_s / 3.6  # mAh
        self.mah_drawn += used
        soc: float = self.soc - used / self.capacity_mah
        self.soc = 0.0 if soc < 0.0 else soc


class Vehicle:
    def __init__(self, airframe, frame):
        a = airframe
        self.mass_kg = a["mass_kg"]
        self.ixx, self.iyy, self.izz = a["inertia_kg_m2"]
        self.kt = a["kt"]
        self.kq = a["kq"]
        self.tau_up_s = a["motor_tau_up_s"]
        self.tau_down_s = a["motor_tau_down_s"]
        self.omega_per_volt = a["omega_per_volt"]
        self.drag_n_per_m2_s2 = a["drag_coef"]
        self.ang_damping = a.get("angular_damping", 0.0)
        self.rotor_drag = a.get("rotor_drag_coef", 0.0)
        # The rotor plane sits above the centre of mass: the H-force acts there, so air moving across the
        # discs (wind, a gust, turbulence) pitches and rolls the craft as well as pushing it.
        self.rotor_height_m = a.get("rotor_height_m", 0.0)
        self.idle_current_a = a.get("idle_current_a", 0.5)
        # Momentum theory: power = T^1.5 / sqrt(2 rho A) / figure of merit / drive efficiency.
        disc = math.pi * (a["prop_diameter_m"] * 0.5) ** 2
        self._power_k = 1.0 / (math.sqrt(2.0 * RHO_KG_M3 * disc) * a.get("figure_of_merit", 0.5)
                               * a.get("drive_efficiency", 0.75))
        b = a["battery"]
        self.battery = Battery(b["cells"], b["capacity_mah"], b["r_int_ohm"])
        table = MIXER_TABLES[frame]
        arm = a["arm_m"]
        self.n = len(table)
        self.px = []
        self.py = []
        self.spin = []  # +1: prop turns clockwise seen from above (reaction torque yaws left)
        for row in table:
            roll_w, pitch_w, yaw_w = row[1], row[2], row[3]
            norm = math.sqrt(roll_w * roll_w + pitch_w * pitch_w) or 1.0
            self.px.append(arm * pitch_w / norm)
            self.py.append(-arm * roll_w / norm)
            self.spin.append(-1.0 if yaw_w > 0 else (1.0 if yaw_w < 0 else 0.0))
        if frame == "tri":
            # Tail motor on a yaw servo; the front pair counter-rotate, the tail's torque is trimmed by tilt.
            self.spin = [0.0, 1.0, -1.0]
        self.tri = frame == "tri"
        self.servo_max_rad = math.radians(a.get("tri_servo_deg", 40.0))
        self.servo_cmd = 0.0
        self._lag_dt = None
        self.reset()

    def reset(self, altitude_m=0.0, roll_rad=0.0, pitch_rad=0.0, yaw_rad=0.0):
        self.pn = 0.0
        self.pe = 0.0
        self.pd = -altitude_m
        self.vn = 0.0
        self.ve = 0.0
        self.vd = 0.0
        cr, sr = math.cos(roll_rad / 2), math.sin(roll_rad / 2)
        cp, sp = math.cos(pitch_rad / 2), math.sin(pitch_rad / 2)
        cy, sy = math.cos(yaw_rad / 2), math.sin(yaw_rad / 2)
        self.qw = cr * cp * cy + sr * sp * sy
        self.qx = sr * cp * cy - cr * sp * sy
        self.qy = cr * sp * cy + sr * cp * sy
        self.qz = cr * cp * sy - sr * sp * cy
        self.p = 0.0
        self.q = 0.0
        self.r = 0.0
        self.omega = [0.0] * self.n
        self.on_ground = altitude_m <= 0.0
        self.crashed = False
        self.impact_m_s = 0.0
        # specific force in the body frame (what an accelerometer reads), m/s²
        self.fx = 0.0
        self.fy = 0.0
        self.fz = -G_M_S2
        self.wind_n = 0.0
        self.wind_e = 0.0
        self.wind_d = 0.0
        # An outside torque on the body (a scenario's `torque` disturbance), N m, FRD.
        self.torque_x_nm = 0.0
        self.torque_y_nm = 0.0
        self.torque_z_nm = 0.0

    def hover_omega(self):
        return math.sqrt(self.mass_kg * G_M_S2 / (self.n * self.kt))

    def step(self, dt: float, motor_cmd):
        """Advance dt seconds with motor commands 0 (stop) or idle..1 (ESC throttle)."""
        # The `: float` locals are C doubles on the compiled twin (hoverfly/native.py) and plain annotations on
        # CPython: the same IEEE arithmetic either way (no `**` or `%` on them), without a float object per
        # operation, which is most of a step's cost there (bench/sim_rtf.py).
        kt: float = self.kt
        kq: float = self.kq
        omega = self.omega
        bat = self.battery
        omega_max: float = self.omega_per_volt * bat.voltage_v
        if dt != self._lag_dt:  # the motors' lag factors for this step length (the same every step)
            self._lag_dt = dt
            self._a_up = dt / (self.tau_up_s + dt)
            self._a_dn = dt / (self.tau_down_s + dt)
        a_up: float = self._a_up
        a_dn: float = self._a_dn
        thrust: float = 0.0
        tx: float = 0.0
        ty: float = 0.0
        tz: float = 0.0
        power: float = 0.0
        px = self.px
        py = self.py
        spin = self.spin
        sqrt = math.sqrt
        omega_sum: float = 0.0
        target: float
        w: float
        t: float
        arm_x: float
        arm_y: float
        turn: float
        for i in range(self.n):
            # list items taken into C doubles first, so the arithmetic below stays in C on the twin
            target = motor_cmd[i]
            target = target * omega_max
            w = omega[i]
            w += (a_up if target > w else a_dn) * (target - w)
            if w < 0.0:
                w = 0.0
            omega[i] = w
            omega_sum += w
            t = kt * w * w
            thrust += t
            arm_x = px[i]
            arm_y = py[i]
            turn = spin[i]
            tx -= arm_y * t
            ty += arm_x * t
            tz -= turn * kq * w * w
            power += t * sqrt(t)
        fz_body: float = -thrust
        fx_body: float = 0.0
        fy_body: float = 0.0
        if self.tri:
            # Tail thrust tilted by the servo: a sideways force at the tail gives yaw.
            t_tail = kt * omega[0] * omega[0]
            ang = self.servo_cmd * self.servo_max_rad
            side = t_tail * math.sin(ang)
            fy_body += side
            tz += -px[0] * side  # tail is behind (px < 0): force to the right yaws the nose right
        current: float = power * self._power_k / (bat.voltage_v if bat.voltage_v > 1.0 else 1.0) + self.idle_current_a
        bat.step(current, dt)

        # Rotation matrix body->NED from the quaternion.
        w = self.qw
        x: float = self.qx
        y: float = self.qy
        z: float = self.qz
        r00: float = 1 - 2 * (y * y + z * z)
        r01: float = 2 * (x * y - w * z)
        r02: float = 2 * (x * z + w * y)
        r10: float = 2 * (x * y + w * z)
        r11: float = 1 - 2 * (x * x + z * z)
        r12: float = 2 * (y * z - w * x)
        r20: float = 2 * (x * z - w * y)
        r21: float = 2 * (y * z + w * x)
        r22: float = 1 - 2 * (x * x + y * y)

        m: float = self.mass_kg
        vn0: float = self.vn
        ve0: float = self.ve
        vd0: float = self.vd
        # Drag against the air, world frame.
        an: float = vn0 - self.wind_n
        ae: float = ve0 - self.wind_e
        ad: float = vd0 - self.wind_d
        speed: float = sqrt(an * an + ae * ae + ad * ad)
        c: float = self.drag_n_per_m2_s2 * speed
        dn: float = -c * an
        de: float = -c * ae
        dd: float = -c * ad
        # Rotor drag (H-force): spinning rotors resist air moving across the disc, in the body plane.
        kd: float = self.rotor_drag * omega_sum
        bx: float
        by: float
        h: float
        if kd > 0.0:
            bx = r00 * an + r10 * ae + r20 * ad
            by = r01 * an + r11 * ae + r21 * ad
            fx_body -= kd * bx
            fy_body -= kd * by
            # acting at the rotor plane, h above the centre of mass (r = (0, 0, -h)): r x F
            h = self.rotor_height_m
            tx -= h * kd * by
            ty += h * kd * bx
        # Non-gravitational force in the world frame.
        fn: float = r00 * fx_body + r01 * fy_body + r02 * fz_body + dn
        fe: float = r10 * fx_body + r11 * fy_body + r12 * fz_body + de
        fd: float = r20 * fx_body + r21 * fy_body + r22 * fz_body + dd
        vn: float = vn0 + fn / m * dt
        ve: float = ve0 + fe / m * dt
        vd: float = vd0 + (fd / m + G_M_S2) * dt
        self.pn += vn * dt
        self.pe += ve * dt
        pd: float = self.pd + vd * dt

        # Rotational dynamics, body frame (Euler's equations).
        p: float = self.p
        q: float = self.q
        r: float = self.r
        ixx: float = self.ixx
        iyy: float = self.iyy
        izz: float = self.izz
        damp: float = self.ang_damping
        tx += self.torque_x_nm - damp * p
        ty += self.torque_y_nm - damp * q
        tz += self.torque_z_nm - damp * r
        p += (tx - (izz - iyy) * q * r) / ixx * dt
        q += (ty - (ixx - izz) * p * r) / iyy * dt
        r += (tz - (iyy - ixx) * p * q) / izz * dt

        # Ground: ArduPilot's rule. At the ground: clamp, stop sinking; while the rotors cannot lift
        # the craft it sits level (yaw kept), still.
        if pd >= 0.0:
            if not self.on_ground and vd > 0.05:
                self.impact_m_s = vd
                if vd > 3.0 or r22 < 0.5:
                    self.crashed = True
            pd = 0.0
            if vd > 0.0:
                vd = 0.0
            if -fd < m * G_M_S2:
                self.on_ground = True
                vn = 0.0
                ve = 0.0
                vd = 0.0
                p = 0.0
                q = 0.0
                r *= 0.5
                yaw: float = math.atan2(r10, r00)
                w = math.cos(yaw / 2)
                x = 0.0
                y = 0.0
                z = math.sin(yaw / 2)
            else:
                self.on_ground = False
        else:
            self.on_ground = False
        self.pd = pd
        self.vn = vn
        self.ve = ve
        self.vd = vd
        self.p = p
        self.q = q
        self.r = r

        # Attitude: q <- q * exp(omega dt / 2), then normalise.
        h = 0.5 * dt
        hx: float = p * h
        hy: float = q * h
        hz: float = r * h
        nw: float = w - x * hx - y * hy - z * hz
        nx: float = x + w * hx + y * hz - z * hy
        ny: float = y + w * hy - x * hz + z * hx
        nz: float = z + w * hz + x * hy - y * hx
        inv: float = 1.0 / sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
        self.qw = nw * inv
        self.qx = nx * inv
        self.qy = ny * inv
        self.qz = nz * inv

        # Specific force in the body (accelerometer): (dv/dt - g) rotated into the body.
        an_w: float = (vn - vn0) / dt
        ae_w: float = (ve - ve0) / dt
        ad_w: float = (vd - vd0) / dt - G_M_S2
        self.fx = r00 * an_w + r10 * ae_w + r20 * ad_w
        self.fy = r01 * an_w + r11 * ae_w + r21 * ad_w
        self.fz = r02 * an_w + r12 * ae_w + r22 * ad_w

    # -------------------------------------------------------------- truth
    def euler_rad(self):
        w: float = self.qw
        x: float = self.qx
        y: float = self.qy
        z: float = self.qz
        roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
        s: float = 2 * (w * y - z * x)
        pitch = math.asin(1.0 if s > 1.0 else (-1.0 if s < -1.0 else s))
        yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        return roll, pitch, yaw

    def tilt_rad(self):
        c = 1 - 2 * (self.qx * self.qx + self.qy * self.qy)
        return math.acos(1.0 if c > 1.0 else (-1.0 if c < -1.0 else c))

    def altitude_m(self):
        return -self.pd
