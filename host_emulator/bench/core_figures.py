"""The accuracy figures of the rotation and
lat/lon kernels quoted in docs/float32.md, measured on the firmware (float32, desktop) against
independent float64 references: docs/requirements.md eq. 5-6 and 5-11 written out, and pymap3d (part
of `python -m host_emulator float32`)."""

import numpy as np
import pymap3d

from common import firmware_env
from host_emulator.sim.trajectory import wrap_pi

firmware_env.install()

import f32  # noqa: E402
import geo  # noqa: E402
import rot  # noqa: E402

F32 = np.float32
RNG = np.random.default_rng(2026)


def seed_c_bn(yaw, pitch, roll):
    """C_bn = (R_y(roll) R_x(pitch) R_z(yaw))^T, docs/requirements.md eq. 5-6."""
    cy, sy, cp, sp, cr, sr = (
        np.cos(yaw),
        np.sin(yaw),
        np.cos(pitch),
        np.sin(pitch),
        np.cos(roll),
        np.sin(roll),
    )
    r_y = np.array([[cr, 0, -sr], [0, 1, 0], [sr, 0, cr]])
    r_x = np.array([[1, 0, 0], [0, cp, sp], [0, -sp, cp]])
    r_z = np.array([[cy, sy, 0], [-sy, cy, 0], [0, 0, 1]])
    return (r_y @ r_x @ r_z).T


def seed_exp(theta):
    """exp([theta x]), docs/requirements.md eq. 5-11."""
    t = np.linalg.norm(theta)
    k = np.array([[0, -theta[2], theta[1]], [theta[2], 0, -theta[0]], [-theta[1], theta[0], 0]])
    return np.eye(3) + np.sin(t) / t * k + (1 - np.cos(t)) / t**2 * (k @ k)


def angle(c_a, c_b):
    d = np.asarray(c_a, float).T @ np.asarray(c_b, float)
    vee = np.array([d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]]) / 2
    return float(np.arctan2(np.linalg.norm(vee), (np.trace(d) - 1) / 2))


def buf(x):
    b = f32.zeros(len(x))
    b[:] = np.asarray(x, F32)
    return b


def rotation_figures(n=3000):
    c = f32.zeros(9)
    ypr = f32.zeros(3)
    worst_dcm = worst_euler = 0.0
    for _ in range(n):
        a = np.array(
            [
                RNG.uniform(-np.pi, np.pi),
                RNG.uniform(-np.pi / 2, np.pi / 2),
                RNG.uniform(-np.pi, np.pi),
            ],
            F32,
        )
        rot.euler_to_dcm(c, buf(a))
        worst_dcm = max(
            worst_dcm, np.abs(np.asarray(c, float) - seed_c_bn(*a.astype(float)).ravel()).max()
        )
        a[1] = F32(np.clip(a[1], -np.radians(85), np.radians(85)))
        rot.dcm_to_euler(ypr, buf(seed_c_bn(*a.astype(float)).ravel()))
        d = wrap_pi(np.asarray(ypr, float) - a.astype(float))
        worst_euler = max(worst_euler, np.abs(d).max())
    theta = (np.radians(100.0) * np.array([0.36, -0.48, 0.8]) * 0.005).astype(F32)
    q = buf([1, 0, 0, 0])
    th = buf(theta)
    drift = {}
    for k in range(1, 12001):
        rot.q_update(q, th)
        if k in (200, 1000, 12000):
            rot.q_to_dcm(c, q)
            drift[k] = angle(np.asarray(c, float).reshape(3, 3), seed_exp(theta.astype(float) * k))
    return worst_dcm, worst_euler, drift


def geo_figures(points=300):
    origins = [
        (0, 0, 0.0),
        (342600000, 1089400000, 400.0),
        (600000000, -1500000000, 50.0),
        (-800000000, 1200000000, 2500.0),
    ]
    enu = f32.zeros(3)
    rows = []
    for lat0, lon0, h0 in origins:
        fr = geo.LocalFrame()
        fr.set_origin(lat0, lon0, F32(h0))
        row = []
        for d in (2000.0, 10000.0, 20000.0):
            worst = 0.0
            for _ in range(points):
                az, dh = RNG.uniform(0, 2 * np.pi), RNG.uniform(-300, 300)
                lat, lon, h = pymap3d.enu2geodetic(
                    d * np.sin(az), d * np.cos(az), h0 + dh, lat0 / 1e7, lon0 / 1e7, h0
                )
                la, lo, h32 = int(round(lat * 1e7)), int(round(lon * 1e7)), F32(h)
                fr.to_enu(enu, la, lo, h32)
                t = pymap3d.geodetic2enu(
                    la / 1e7, lo / 1e7, float(h32), lat0 / 1e7, lon0 / 1e7, float(F32(h0))
                )
                worst = max(worst, float(np.linalg.norm(np.asarray(enu, float) - t)))
            row.append(worst)
        rows.append((lat0 / 1e7, row))
    return rows


def main():
    worst_dcm, worst_euler, drift = rotation_figures()
    print("## Rotations")
    print(f"euler_to_dcm vs eq. 5-6 (3000 attitudes): max entry error {worst_dcm:.2g}")
    print(f"dcm_to_euler of eq. 5-6 (pitch within 85 deg): max angle error {worst_euler:.2g} rad")
    print(
        "q_update at 100 deg/s, 5 ms steps, vs eq. 5-11 in double: "
        + ", ".join(f"{k} steps {v * 1e6:.2f} micro-rad" for k, v in drift.items())
    )
    print("\n## Lat/lon -> ENU vs pymap3d (worst of 300 points, heights +-300 m)")
    print("| origin latitude | 2 km | 10 km | 20 km |")
    print("|---|---|---|---|")
    for lat, row in geo_figures():
        print(f"| {lat:g} deg | " + " | ".join(f"{x * 1000:.1f} mm" for x in row) + " |")
