"""Sensor-to-body axis maps: how an IMU chip sits in the airframe.

Takes the chip's own axes (its datasheet frame: right-handed, z out of the top of the
package, a level chip at rest reads +1 g on z) and gives body-frame FRD vectors
(x forward, y right, z down). Drivers call it last in `read()`, so nothing downstream
flips a sign.

Reference mounting `CW0`: chip top up, chip +x forward, chip +y to the left. Then
FRD = (x, -y, -z) of the chip. `CW90/CW180/CW270` turn the chip that many degrees
clockwise seen from above; the `_FLIP` variants first turn it upside down about its
y axis. These are Betaflight's `align_gyro` names and relative rotations (Betaflight
`sensors/boardalignment.c`: CW90 gives X = y, Y = -x; CW0_FLIP gives X = -x, Z = -z;
CW90_FLIP gives X = y, Y = x, Z = -z), expressed in our FRD body frame. On top of the
axis map an arbitrary alignment can be given: the board turned by roll, pitch, yaw
(radians) in the frame, v_body = Rz(yaw) Ry(pitch) Rx(roll) v_board, the convention of
core/stages/estimator.py BoardAlignment. Do not apply the same angles in both places.

`rotate(x, y, z, out)` and `rotate_scaled(x, y, z, k, out)` write out[0..2] and make no
containers. A pure axis map (no alignment angles) runs as signed index selection on
the raw integers, so only the three final products are floats.
"""

import math

CW0 = 0
CW90 = 1
CW180 = 2
CW270 = 3
CW0_FLIP = 4
CW90_FLIP = 5
CW180_FLIP = 6
CW270_FLIP = 7

# Names as the parameter table / CLI spell them (index = the constant above).
ALIGN_NAMES = ("cw0", "cw90", "cw180", "cw270", "cw0flip", "cw90flip", "cw180flip", "cw270flip")


def _axis_map_flu(mount):
    """Rows of the chip-to-FLU matrix for a Betaflight mount (FLU = x fwd, y left, z up).

    dest = CWn(FLIP(v)), FLIP = 180° about y (x -> -x, z -> -z), CWn as Betaflight.
    """
    flip = mount >= CW0_FLIP
    turn = mount & 3
    # Start from the identity, optionally flipped.
    sx = -1 if flip else 1
    sz = -1 if flip else 1
    # v' = (sx*x, y, sz*z); CW90: (y', -x', z'); CW180: (-x', -y', z'); CW270: (-y', x', z')
    if turn == 0:
        rows = ((sx, 0, 0), (0, 1, 0), (0, 0, sz))
    elif turn == 1:
        rows = ((0, 1, 0), (-sx, 0, 0), (0, 0, sz))
    elif turn == 2:
        rows = ((-sx, 0, 0), (0, -1, 0), (0, 0, sz))
    else:
        rows = ((0, -1, 0), (sx, 0, 0), (0, 0, sz))
    return rows


def _matmul(a, b):
    out = []
    for i in range(3):
        row = []
        for j in range(3):
            row.append(a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j])
        out.append(row)
    return out


def alignment_matrix(roll_rad, pitch_rad, yaw_rad):
    """Rz(yaw) Ry(pitch) Rx(roll) as rows (board to body)."""
    cr = math.cos(roll_rad)
    sr = math.sin(roll_rad)
    cp = math.cos(pitch_rad)
    sp = math.sin(pitch_rad)
    cy = math.cos(yaw_rad)
    sy = math.sin(yaw_rad)
    return [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]


class Orientation:
    """Chip axes to body FRD: a Betaflight axis map plus optional roll/pitch/yaw alignment."""

    def __init__(self, mount=CW0, roll_rad=0.0, pitch_rad=0.0, yaw_rad=0.0):
        if mount < CW0 or mount > CW270_FLIP:
            raise ValueError("mount must be CW0..CW270_FLIP")
        self.mount = mount
        flu = _axis_map_flu(mount)
        # FLU to FRD: y and z change sign.
        frd = [[flu[0][0], flu[0][1], flu[0][2]],
               [-flu[1][0], -flu[1][1], -flu[1][2]],
               [-flu[2][0], -flu[2][1], -flu[2][2]]]
        self.axis_map_only = roll_rad == 0 and pitch_rad == 0 and yaw_rad == 0
        if self.axis_map_only:
            m = frd
        else:
            m = _matmul(alignment_matrix(roll_rad, pitch_rad, yaw_rad), frd)
        self._set_matrix(m)

    @classmethod
    def from_name(cls, name, roll_rad=0.0, pitch_rad=0.0, yaw_rad=0.0):
        """'cw270flip' (any case, '_' and 'deg' ignored) -> Orientation; ValueError if unknown."""
        key = name.lower().replace("_", "").replace("deg", "")
        for i in range(len(ALIGN_NAMES)):
            if ALIGN_NAMES[i] == key:
                return cls(i, roll_rad, pitch_rad, yaw_rad)
        raise ValueError("unknown IMU alignment %r (one of %s)" % (name, ", ".join(ALIGN_NAMES)))

    def _set_matrix(self, m):
        self.m00 = float(m[0][0])
        self.m01 = float(m[0][1])
        self.m02 = float(m[0][2])
        self.m10 = float(m[1][0])
        self.m11 = float(m[1][1])
        self.m12 = float(m[1][2])
        self.m20 = float(m[2][0])
        self.m21 = float(m[2][1])
        self.m22 = float(m[2][2])
        # Signed index form of an axis map: body axis i = sign_i * chip axis index_i.
        if self.axis_map_only:
            for i in range(3):
                row = m[i]
                for j in range(3):
                    if row[j] != 0:
                        if i == 0:
                            self._i0 = j
                            self._s0 = int(row[j])
                        elif i == 1:
                            self._i1 = j
                            self._s1 = int(row[j])
                        else:
                            self._i2 = j
                            self._s2 = int(row[j])

    def matrix(self):
        """The 3×3 chip-to-body matrix as nested lists (configuration time only)."""
        return [[self.m00, self.m01, self.m02],
                [self.m10, self.m11, self.m12],
                [self.m20, self.m21, self.m22]]

    def rotate(self, x, y, z, out):
        """out[0..2] = M (x, y, z): chip-frame vector to body FRD."""
        out[0] = self.m00 * x + self.m01 * y + self.m02 * z
        out[1] = self.m10 * x + self.m11 * y + self.m12 * z
        out[2] = self.m20 * x + self.m21 * y + self.m22 * z

    def rotate_scaled(self, x, y, z, k, out):
        """out[0..2] = k * M (x, y, z) for raw integer chip counts x, y, z and a scale k.

        For a pure axis map the selection and sign stay integer (no float made until * k).
        """
        if self.axis_map_only:
            i = self._i0
            out[0] = self._s0 * (x if i == 0 else (y if i == 1 else z)) * k
            i = self._i1
            out[1] = self._s1 * (x if i == 0 else (y if i == 1 else z)) * k
            i = self._i2
            out[2] = self._s2 * (x if i == 0 else (y if i == 1 else z)) * k
        else:
            out[0] = (self.m00 * x + self.m01 * y + self.m02 * z) * k
            out[1] = (self.m10 * x + self.m11 * y + self.m12 * z) * k
            out[2] = (self.m20 * x + self.m21 * y + self.m22 * z) * k

    def unrotate(self, x, y, z, out):
        """out[0..2] = Mᵀ (x, y, z): body FRD vector to chip frame (register models, tests)."""
        out[0] = self.m00 * x + self.m10 * y + self.m20 * z
        out[1] = self.m01 * x + self.m11 * y + self.m21 * z
        out[2] = self.m02 * x + self.m12 * y + self.m22 * z

    def quaternion(self):
        """Unit quaternion (w, x, y, z) of the chip-to-body rotation (configuration time only)."""
        return matrix_to_quaternion(self.matrix())


def matrix_to_quaternion(m):
    """(w, x, y, z) of a proper rotation matrix given as rows (Shepperd's method)."""
    tr = m[0][0] + m[1][1] + m[2][2]
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        w = 0.25 * s
        x = (m[2][1] - m[1][2]) / s
        y = (m[0][2] - m[2][0]) / s
        z = (m[1][0] - m[0][1]) / s
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = math.sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2.0
        w = (m[2][1] - m[1][2]) / s
        x = 0.25 * s
        y = (m[0][1] + m[1][0]) / s
        z = (m[0][2] + m[2][0]) / s
    elif m[1][1] > m[2][2]:
        s = math.sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2.0
        w = (m[0][2] - m[2][0]) / s
        x = (m[0][1] + m[1][0]) / s
        y = 0.25 * s
        z = (m[1][2] + m[2][1]) / s
    else:
        s = math.sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2.0
        w = (m[1][0] - m[0][1]) / s
        x = (m[0][2] + m[2][0]) / s
        y = (m[1][2] + m[2][1]) / s
        z = 0.25 * s
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    return (w, x, y, z)
