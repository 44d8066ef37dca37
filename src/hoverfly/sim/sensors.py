"""IMU model: what a gyro and accelerometer on the simulated frame read.

Truth (body rates, specific force) plus white noise (density × sqrt(rate/2) per sample),
a turn-on bias, a bias random walk, vibration at each rotor's frequency with amplitude
growing as ω², and range clipping. Seeded and deterministic: the noise comes from a table
drawn once from the seed, so a sample costs no random-number calls.
"""

import math
import random

_TABLE = 65521  # prime, so the six axes' strides never line up


class ImuModel:
    def __init__(self, cfg, seed, loop_hz, hover_omega, motor_count):
        rng = random.Random(seed)
        self.noise = [rng.gauss(0.0, 1.0) for _ in range(_TABLE)]
        self._k = 0
        rate = float(loop_hz)
        self.dt = 1.0 / rate
        self.gyro_sigma = cfg["gyro_noise_rad_s_rthz"] * math.sqrt(rate / 2.0)
        self.accel_sigma = cfg["accel_noise_m_s2_rthz"] * math.sqrt(rate / 2.0)
        bs = cfg["gyro_bias_sigma_rad_s"]
        self.gyro_bias = [rng.gauss(0.0, bs) for _ in range(3)]
        ab = cfg["accel_bias_sigma_m_s2"]
        self.accel_bias = [rng.gauss(0.0, ab) for _ in range(3)]
        self.walk_sigma = cfg["gyro_bias_walk_rad_s_rts"] * math.sqrt(self.dt * 16)
        self._rng = rng
        self.gyro_vib = cfg["gyro_vibration_rad_s"] / (hover_omega * hover_omega)
        self.accel_vib = cfg["accel_vibration_m_s2"] / (hover_omega * hover_omega)
        self.phase = [rng.uniform(0.0, 2.0 * math.pi) for _ in range(motor_count)]
        # each motor shakes along its own direction in the body plane (imbalance)
        self.vib_dir = [rng.uniform(0.0, 2.0 * math.pi) for _ in range(motor_count)]
        self._vib_cos = [math.cos(d) for d in self.vib_dir]
        self._vib_sin = [math.sin(d) for d in self.vib_dir]
        self.gyro_max = math.radians(cfg["gyro_range_dps"])
        self.accel_max = cfg["accel_range_g"] * 9.80665
        self.frozen = False
        self._steps = 0
        self.enabled = True

    def sample(self, v, gyro_out, accel_out):
        if self.frozen:
            return
        # The `: float` locals are C doubles on the compiled twin and plain annotations on CPython: the same
        # arithmetic without a float object per operation (as in sim/physics.py's Vehicle.step).
        nz = self.noise
        k = self._k
        gs: float = self.gyro_sigma
        acs: float = self.accel_sigma
        gb = self.gyro_bias
        ab = self.accel_bias
        self._steps += 1
        if self._steps & 15 == 0:
            w = self.walk_sigma
            rng = self._rng
            gb[0] += rng.gauss(0.0, w)
            gb[1] += rng.gauss(0.0, w)
            gb[2] += rng.gauss(0.0, w)
        # vibration: sum of rotor sinusoids
        vib_g: float = 0.0
        vib_x: float = 0.0
        vib_y: float = 0.0
        dt: float = self.dt
        w: float
        p: float
        a: float
        ph = self.phase
        omega = v.omega
        dir_cos = self._vib_cos
        dir_sin = self._vib_sin
        sin = math.sin
        s: float
        c: float
        for i in range(len(omega)):
            # list items and sin() taken into C doubles first, so the arithmetic stays in C on the twin
            w = omega[i]
            p = ph[i]
            p += w * dt
            if p > 6.283185307179586:
                p -= 6.283185307179586 * int(p / 6.283185307179586)
            ph[i] = p
            s = sin(p)
            a = w * w * s
            vib_g += a
            c = dir_cos[i]
            vib_x += a * c
            s = dir_sin[i]
            vib_y += a * s
        gv: float = self.gyro_vib
        av: float = self.accel_vib
        # truth, bias and noise read into C doubles, then summed in the same order as written out:
        # truth + bias + sigma * noise + vibration
        x: float = v.p
        b: float = gb[0]
        n: float = nz[k]
        gx: float = x + b + gs * n + gv * vib_x
        x = v.q
        b = gb[1]
        n = nz[k + 1]
        gy: float = x + b + gs * n + gv * vib_y
        x = v.r
        b = gb[2]
        n = nz[k + 2]
        gz: float = x + b + gs * n + gv * 0.3 * vib_g
        x = v.fx
        b = ab[0]
        n = nz[k + 3]
        ax: float = x + b + acs * n + av * vib_x
        x = v.fy
        b = ab[1]
        n = nz[k + 4]
        ay: float = x + b + acs * n + av * vib_y
        x = v.fz
        b = ab[2]
        n = nz[k + 5]
        az: float = x + b + acs * n + av * vib_g
        k += 6
        if k > _TABLE - 7:
            k -= _TABLE - 7
        self._k = k
        gm: float = self.gyro_max
        am: float = self.accel_max
        gyro_out[0] = gm if gx > gm else (-gm if gx < -gm else gx)
        gyro_out[1] = gm if gy > gm else (-gm if gy < -gm else gy)
        gyro_out[2] = gm if gz > gm else (-gm if gz < -gm else gz)
        accel_out[0] = am if ax > am else (-am if ax < -am else ax)
        accel_out[1] = am if ay > am else (-am if ay < -am else ay)
        accel_out[2] = am if az > am else (-am if az < -am else az)
