"""Attitude: quaternions, direction cosine matrices and Euler angles, in float32.

Conventions (stated once for the whole firmware; docs/requirements.md, algorithm):

- Navigation frame n: local East-North-Up. Body frame b: x right, y forward, z up.
- `q_bn` = [w, x, y, z] (scalar first, Hamilton product) rotates body vectors into the
  navigation frame: v_n = q_bn (x) v_b (x) q_bn*, i.e. v_n = C_bn v_b. Canonical sign w >= 0.
- `C_bn` (body to nav, = C_b^n) is a flat row-major 3x3 buffer; C_nb = C_bn^T.
- Euler angles in buffers ordered `ypr` = [yaw, pitch, roll], radians. Seed eq. 5-6: starting
  with the body aligned to ENU, rotate yaw about up, then pitch about the (new) right axis,
  then roll about the (new) forward axis, all right-handed:
      C_n^b = R_y(roll) R_x(pitch) R_z(yaw)
  so yaw > 0 turns the nose from north towards west (yaw is not compass heading: heading
  clockwise from north = -yaw), pitch > 0 raises the nose, roll > 0 lowers the right side.
  Ranges: yaw and roll in [-pi, pi], pitch in [-pi/2, pi/2].
- Attitude update by a body-frame rotation vector theta (rad) over one step, seed eq. 5-17:
      q(t+T) = (cos(|theta|/2) I + sin(|theta|/2)/|theta| [theta]) q(t)
  with [theta] the 4x4 matrix of eq. 5-16; this equals q(t) (x) [cos(|theta|/2), theta_unit
  sin(|theta|/2)], a right-multiplication by the body increment.

Every function writes into caller buffers and allocates nothing but float results.
The NumPy model `host_emulator/model/rot.py` mirrors each operation in order.
"""

import f32
from fmath import asin, atan2, cos, sin, sqrt

# Indices into a ypr buffer.
YAW = 0
PITCH = 1
ROLL = 2

# Small-angle series for eq. 5-17 with n2 = |theta|^2 (radians^2):
#   cos(|theta|/2)         = 1   - n2/8  + n2^2/384  - ...
#   sin(|theta|/2)/|theta| = 1/2 - n2/48 + n2^2/3840 - ...
# Below |theta| = 1/8 rad (1432 deg/s at 200 Hz) the next terms are < 1e-10, far below a
# float32 ulp of the result, so the series is exact to float32 and needs no division.
SERIES_MAX_N2 = f32.ratio(1, 64)
C8 = f32.ratio(1, 8)
C384 = f32.ratio(1, 384)
C48 = f32.ratio(1, 48)
C3840 = f32.ratio(1, 3840)


def _store_canonical(q, w, x, y, z):
    """q = (w, x, y, z), negated if needed so that w >= 0 (q and -q are the same rotation)."""
    if w < 0.0:
        w = -w
        x = -x
        y = -y
        z = -z
    q[0] = w
    q[1] = x
    q[2] = y
    q[3] = z


def q_identity(q):
    q[0] = 1.0
    q[1] = 0.0
    q[2] = 0.0
    q[3] = 0.0


def q_mul(out, p, q):
    """out = p (x) q (Hamilton). `out` must not alias p or q."""
    pw = p[0]
    px = p[1]
    py = p[2]
    pz = p[3]
    qw = q[0]
    qx = q[1]
    qy = q[2]
    qz = q[3]
    out[0] = pw * qw - px * qx - py * qy - pz * qz
    out[1] = pw * qx + px * qw + py * qz - pz * qy
    out[2] = pw * qy - px * qz + py * qw + pz * qx
    out[3] = pw * qz + px * qy - py * qx + pz * qw


def q_normalize(q):
    """Scale q to unit norm in place; a zero or non-finite q becomes identity (returns False)."""
    w = q[0]
    x = q[1]
    y = q[2]
    z = q[3]
    n2 = w * w + x * x + y * y + z * z
    if not (n2 > 0.0) or n2 - n2 != 0.0:  # zero, NaN or inf
        q_identity(q)
        return False
    inv = 1.0 / sqrt(n2)
    q[0] = w * inv
    q[1] = x * inv
    q[2] = y * inv
    q[3] = z * inv
    return True


def _half_angle(cs, n2):
    """cs = [cos(|theta|/2), sin(|theta|/2)/|theta|] for n2 = |theta|^2 (series when small)."""
    if n2 < SERIES_MAX_N2:
        cs[0] = 1.0 - n2 * (C8 - n2 * C384)
        cs[1] = 0.5 - n2 * (C48 - n2 * C3840)
    else:
        n = sqrt(n2)
        h = 0.5 * n
        cs[0] = cos(h)
        cs[1] = sin(h) / n


_CS = f32.zeros(2)


def q_update(q, theta):
    """q <- q advanced by the body rotation vector theta (rad), seed eq. 5-17, then normalized."""
    tx = theta[0]
    ty = theta[1]
    tz = theta[2]
    cs = _CS
    _half_angle(cs, tx * tx + ty * ty + tz * tz)
    c = cs[0]
    s = cs[1]
    w = q[0]
    x = q[1]
    y = q[2]
    z = q[3]
    q[0] = c * w - s * (tx * x + ty * y + tz * z)
    q[1] = c * x + s * (tx * w + tz * y - ty * z)
    q[2] = c * y + s * (ty * w - tz * x + tx * z)
    q[3] = c * z + s * (tz * w + ty * x - tx * y)
    return q_normalize(q)


def q_from_rotvec(out, theta):
    """out = unit quaternion of the rotation vector theta (rad): [cos(|t|/2), sin(|t|/2) t/|t|]."""
    tx = theta[0]
    ty = theta[1]
    tz = theta[2]
    cs = _CS
    _half_angle(cs, tx * tx + ty * ty + tz * tz)
    s = cs[1]
    out[0] = cs[0]
    out[1] = s * tx
    out[2] = s * ty
    out[3] = s * tz


def q_to_dcm(c_bn, q):
    """C_bn from a unit q_bn."""
    w = q[0]
    x = q[1]
    y = q[2]
    z = q[3]
    xx = x * x
    yy = y * y
    zz = z * z
    xy = x * y
    xz = x * z
    yz = y * z
    wx = w * x
    wy = w * y
    wz = w * z
    c_bn[0] = 1.0 - 2.0 * (yy + zz)
    c_bn[1] = 2.0 * (xy - wz)
    c_bn[2] = 2.0 * (xz + wy)
    c_bn[3] = 2.0 * (xy + wz)
    c_bn[4] = 1.0 - 2.0 * (xx + zz)
    c_bn[5] = 2.0 * (yz - wx)
    c_bn[6] = 2.0 * (xz - wy)
    c_bn[7] = 2.0 * (yz + wx)
    c_bn[8] = 1.0 - 2.0 * (xx + yy)


def dcm_to_q(q, c_bn):
    """q_bn (w >= 0) from a rotation matrix C_bn, Shepperd's method: take the square root of
    the largest of 4w^2, 4x^2, 4y^2, 4z^2 so the division is always well conditioned."""
    c0 = c_bn[0]
    c4 = c_bn[4]
    c8 = c_bn[8]
    tr = c0 + c4 + c8
    if tr > 0.0:
        s = sqrt(tr + 1.0)  # 2|w|
        inv = 0.5 / s
        w = 0.5 * s
        x = (c_bn[7] - c_bn[5]) * inv
        y = (c_bn[2] - c_bn[6]) * inv
        z = (c_bn[3] - c_bn[1]) * inv
    elif c0 > c4 and c0 > c8:
        s = sqrt(1.0 + c0 - c4 - c8)  # 2|x|
        inv = 0.5 / s
        w = (c_bn[7] - c_bn[5]) * inv
        x = 0.5 * s
        y = (c_bn[1] + c_bn[3]) * inv
        z = (c_bn[2] + c_bn[6]) * inv
    elif c4 > c8:
        s = sqrt(1.0 + c4 - c0 - c8)  # 2|y|
        inv = 0.5 / s
        w = (c_bn[2] - c_bn[6]) * inv
        x = (c_bn[1] + c_bn[3]) * inv
        y = 0.5 * s
        z = (c_bn[5] + c_bn[7]) * inv
    else:
        s = sqrt(1.0 + c8 - c0 - c4)  # 2|z|
        inv = 0.5 / s
        w = (c_bn[3] - c_bn[1]) * inv
        x = (c_bn[2] + c_bn[6]) * inv
        y = (c_bn[5] + c_bn[7]) * inv
        z = 0.5 * s
    _store_canonical(q, w, x, y, z)


def euler_to_dcm(c_bn, ypr):
    """C_bn = (R_y(roll) R_x(pitch) R_z(yaw))^T, seed eq. 5-6 transposed."""
    sy = sin(ypr[YAW])
    cy = cos(ypr[YAW])
    sp = sin(ypr[PITCH])
    cp = cos(ypr[PITCH])
    sr = sin(ypr[ROLL])
    cr = cos(ypr[ROLL])
    srsp = sr * sp
    crsp = cr * sp
    c_bn[0] = cr * cy - srsp * sy
    c_bn[1] = -(cp * sy)
    c_bn[2] = sr * cy + crsp * sy
    c_bn[3] = cr * sy + srsp * cy
    c_bn[4] = cp * cy
    c_bn[5] = sr * sy - crsp * cy
    c_bn[6] = -(sr * cp)
    c_bn[7] = sp
    c_bn[8] = cr * cp


def dcm_to_euler(ypr, c_bn):
    """ypr from C_bn. At pitch = +-90 deg yaw and roll are not separable; roll is then 0 when
    C_bn's last row is exactly (0, +-1, 0), and atan2's choice otherwise."""
    s = c_bn[7]
    if s > 1.0:
        s = 1.0
    elif s < -1.0:
        s = -1.0
    ypr[PITCH] = asin(s)
    ypr[ROLL] = atan2(-c_bn[6], c_bn[8])
    ypr[YAW] = atan2(-c_bn[1], c_bn[4])


def euler_to_q(q, ypr):
    """q_bn = q_z(yaw) (x) q_x(pitch) (x) q_y(roll), the quaternion form of eq. 5-6."""
    hy = 0.5 * ypr[YAW]
    hp = 0.5 * ypr[PITCH]
    hr = 0.5 * ypr[ROLL]
    sz = sin(hy)
    cz = cos(hy)
    sx = sin(hp)
    cx = cos(hp)
    sr = sin(hr)
    cr = cos(hr)
    czcx = cz * cx
    szsx = sz * sx
    czsx = cz * sx
    szcx = sz * cx
    w = czcx * cr - szsx * sr
    x = czsx * cr - szcx * sr
    y = czcx * sr + szsx * cr
    z = szcx * cr + czsx * sr
    _store_canonical(q, w, x, y, z)


def skew(out, v):
    """out = [v x], the 3x3 cross-product matrix: [v x] u = v x u (seed eq. 5-9, 5-29)."""
    x = v[0]
    y = v[1]
    z = v[2]
    out[0] = 0.0
    out[1] = -z
    out[2] = y
    out[3] = z
    out[4] = 0.0
    out[5] = -x
    out[6] = -y
    out[7] = x
    out[8] = 0.0
