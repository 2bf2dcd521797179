"""NumPy float32 model of `firmware/lib/rot.py`, vectorised over leading axes.

Shapes: q (..., 4) as [w, x, y, z]; C_bn (..., 3, 3); ypr (..., 3) as [yaw, pitch, roll];
theta (..., 3). Every expression repeats the firmware's operation order, so results are
bit-identical; conventions are those stated in the firmware module.
"""

import numpy as np

from common import firmware_env
from host_emulator.model import fmath

firmware_env.install()
import rot as fw  # noqa: E402  (the firmware module: constants shared, not retyped)

F32 = np.float32


def _f32(a):
    return np.asarray(a, dtype=F32)


def _stack(*parts):
    return np.stack(np.broadcast_arrays(*parts), axis=-1)


def q_mul(p, q):
    p, q = _f32(p), _f32(q)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return _stack(
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )


def q_normalize(q):
    """(unit q, valid flag); invalid (zero or non-finite) inputs become identity."""
    q = _f32(q)
    w, x, y, z = np.moveaxis(q, -1, 0)
    with np.errstate(all="ignore"):
        n2 = w * w + x * x + y * y + z * z
        valid = (n2 > 0) & (n2 - n2 == 0)
        inv = F32(1.0) / np.sqrt(np.where(valid, n2, F32(1.0)))
        out = _stack(w * inv, x * inv, y * inv, z * inv)
    identity = np.array([1, 0, 0, 0], dtype=F32)
    return np.where(valid[..., None], out, identity), valid


def _half_angle(n2):
    """(cos(|theta|/2), sin(|theta|/2)/|theta|) for n2 = |theta|^2, the series when small."""
    series = n2 < fw.SERIES_MAX_N2
    c_series = F32(1.0) - n2 * (fw.C8 - n2 * fw.C384)
    s_series = F32(0.5) - n2 * (fw.C48 - n2 * fw.C3840)
    with np.errstate(all="ignore"):
        n = np.sqrt(n2)
        h = F32(0.5) * n
        c_trig = fmath.cos(h)
        s_trig = fmath.sin(h) / n
    return np.where(series, c_series, c_trig), np.where(series, s_series, s_trig)


def q_update(q, theta):
    """Seed eq. 5-17 then normalisation; returns (q, valid)."""
    q, theta = _f32(q), _f32(theta)
    tx, ty, tz = np.moveaxis(theta, -1, 0)
    c, s = _half_angle(tx * tx + ty * ty + tz * tz)
    w, x, y, z = np.moveaxis(q, -1, 0)
    out = _stack(
        c * w - s * (tx * x + ty * y + tz * z),
        c * x + s * (tx * w + tz * y - ty * z),
        c * y + s * (ty * w - tz * x + tx * z),
        c * z + s * (tz * w + ty * x - tx * y),
    )
    return q_normalize(out)


def q_from_rotvec(theta):
    """Unit quaternion of the rotation vector theta: [cos(|t|/2), sin(|t|/2) t/|t|]."""
    tx, ty, tz = np.moveaxis(_f32(theta), -1, 0)
    c, s = _half_angle(tx * tx + ty * ty + tz * tz)
    return _stack(c, s * tx, s * ty, s * tz)


def q_to_dcm(q):
    w, x, y, z = np.moveaxis(_f32(q), -1, 0)
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    one, two = F32(1.0), F32(2.0)
    rows = [
        [one - two * (yy + zz), two * (xy - wz), two * (xz + wy)],
        [two * (xy + wz), one - two * (xx + zz), two * (yz - wx)],
        [two * (xz - wy), two * (yz + wx), one - two * (xx + yy)],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def dcm_to_q(c_bn):
    c = _f32(c_bn).reshape(*np.shape(c_bn)[:-2], 9)
    c0, c1, c2, c3, c4, c5, c6, c7, c8 = np.moveaxis(c, -1, 0)
    one, half = F32(1.0), F32(0.5)
    tr = c0 + c4 + c8
    b_w = tr > 0
    b_x = ~b_w & (c0 > c4) & (c0 > c8)
    b_y = ~b_w & ~b_x & (c4 > c8)
    with np.errstate(all="ignore"):
        s_w = np.sqrt(tr + one)
        s_x = np.sqrt(one + c0 - c4 - c8)
        s_y = np.sqrt(one + c4 - c0 - c8)
        s_z = np.sqrt(one + c8 - c0 - c4)
        i_w, i_x, i_y, i_z = half / s_w, half / s_x, half / s_y, half / s_z
        q_w = _stack(half * s_w, (c7 - c5) * i_w, (c2 - c6) * i_w, (c3 - c1) * i_w)
        q_x = _stack((c7 - c5) * i_x, half * s_x, (c1 + c3) * i_x, (c2 + c6) * i_x)
        q_y = _stack((c2 - c6) * i_y, (c1 + c3) * i_y, half * s_y, (c5 + c7) * i_y)
        q_z = _stack((c3 - c1) * i_z, (c2 + c6) * i_z, (c5 + c7) * i_z, half * s_z)
    q = np.where(
        b_w[..., None], q_w, np.where(b_x[..., None], q_x, np.where(b_y[..., None], q_y, q_z))
    )
    return np.where((q[..., :1] < 0), -q, q)


def euler_to_dcm(ypr):
    yaw, pitch, roll = np.moveaxis(_f32(ypr), -1, 0)
    sy, cy = fmath.sin(yaw), fmath.cos(yaw)
    sp, cp = fmath.sin(pitch), fmath.cos(pitch)
    sr, cr = fmath.sin(roll), fmath.cos(roll)
    srsp, crsp = sr * sp, cr * sp
    rows = [
        [cr * cy - srsp * sy, -(cp * sy), sr * cy + crsp * sy],
        [cr * sy + srsp * cy, cp * cy, sr * sy - crsp * cy],
        [-(sr * cp), sp, cr * cp],
    ]
    return np.stack([np.stack(np.broadcast_arrays(*r), axis=-1) for r in rows], axis=-2)


def dcm_to_euler(c_bn):
    c = _f32(c_bn)
    s = np.clip(c[..., 2, 1], F32(-1.0), F32(1.0))
    pitch = fmath.asin(s)
    roll = fmath.atan2(-c[..., 2, 0], c[..., 2, 2])
    yaw = fmath.atan2(-c[..., 0, 1], c[..., 1, 1])
    return _stack(yaw, pitch, roll)


def euler_to_q(ypr):
    half = F32(0.5)
    yaw, pitch, roll = np.moveaxis(_f32(ypr), -1, 0)
    hy, hp, hr = half * yaw, half * pitch, half * roll
    sz, cz = fmath.sin(hy), fmath.cos(hy)
    sx, cx = fmath.sin(hp), fmath.cos(hp)
    sr, cr = fmath.sin(hr), fmath.cos(hr)
    czcx, szsx, czsx, szcx = cz * cx, sz * sx, cz * sx, sz * cx
    q = _stack(
        czcx * cr - szsx * sr,
        czsx * cr - szcx * sr,
        czcx * sr + szsx * cr,
        szcx * cr + czsx * sr,
    )
    return np.where(q[..., :1] < 0, -q, q)


def skew(v):
    x, y, z = np.moveaxis(_f32(v), -1, 0)
    zero = np.zeros_like(x)
    return np.stack([_stack(zero, -z, y), _stack(z, zero, -x), _stack(-y, x, zero)], axis=-2)
