"""`python -m host_emulator demo`: a short, honest tour of the float32 core.

Until the emulator exists (it will replace this with a simulated drive), the demo shows what
the rest stands on: the firmware's attitude code integrating 10 s of 200 Hz gyro data exactly
like the NumPy model and close to double precision, the accuracy of the math functions and of
the lat/lon conversion, and the same code running in the real MicroPython VM.
"""

import time

import numpy as np

from host_emulator import firmware_env, mpvm

firmware_env.install()

import f32  # noqa: E402
import geo  # noqa: E402
import rot  # noqa: E402
from host_emulator.reference import fmath as fmath_model  # noqa: E402
from host_emulator.reference import rot as rot_model  # noqa: E402

F32 = np.float32
DT_S = 0.005
STEPS = 2000  # 10 s at 200 Hz


def gyro_increments():
    """Body rotation increments (rad) of a 10 s manoeuvre: a 2 Hz coning motion of 20 deg/s
    amplitude on top of a 30 deg/s turn, sampled at 200 Hz."""
    t = np.arange(STEPS) * DT_S
    w = np.radians(20.0)
    rate = np.stack(
        [
            w * np.sin(2 * np.pi * 2 * t),
            w * np.cos(2 * np.pi * 2 * t),
            np.full_like(t, np.radians(30.0)),
        ],
        axis=-1,
    )
    return (rate * DT_S).astype(F32)


def exact_attitude(thetas):
    """Double-precision integration of the same increments (quaternion exponential)."""
    q = np.array([1.0, 0, 0, 0])
    for th in thetas.astype(float):
        n = np.linalg.norm(th)
        dq = (
            np.concatenate([[np.cos(n / 2)], np.sin(n / 2) / n * th])
            if n
            else np.array([1.0, 0, 0, 0])
        )
        w0, v0, w1, v1 = q[0], q[1:], dq[0], dq[1:]
        q = np.concatenate([[w0 * w1 - v0 @ v1], w0 * v1 + w1 * v0 + np.cross(v0, v1)])
    return q / np.linalg.norm(q)


def angle_urad(q_a, q_b):
    """Angle (micro-radians) between two attitudes: 2 atan2(|v|, |w|) of q_a* (x) q_b, well
    conditioned at small angles."""
    a, b = np.asarray(q_a, float), np.asarray(q_b, float)
    w = a[0] * b[0] + a[1:] @ b[1:]
    v = a[0] * b[1:] - b[0] * a[1:] - np.cross(a[1:], b[1:])
    return float(2 * np.arctan2(np.linalg.norm(v), abs(w)) * 1e6)


def attitude_section(thetas):
    q_fw = f32.zeros(4)
    rot.q_identity(q_fw)
    th = f32.zeros(3)
    q_model = np.array([1, 0, 0, 0], dtype=F32)
    first_difference = None
    t0 = time.perf_counter()
    for k in range(STEPS):
        th[:] = thetas[k]
        rot.q_update(q_fw, th)
        q_model, _ = rot_model.q_update(q_model, thetas[k])
        if first_difference is None and not np.array_equal(
            q_fw.view(np.uint32), q_model.view(np.uint32)
        ):
            first_difference = k
    wall = time.perf_counter() - t0
    return q_fw.copy(), q_model, first_difference, wall


def vm_section(thetas):
    out = mpvm.run_json(f"""
import json, rot, f32
q = f32.zeros(4)
rot.q_identity(q)
ths = _buf({mpvm.hex_of(thetas)!r})
th = f32.zeros(3)
for k in range({STEPS}):
    th[0] = ths[3 * k]
    th[1] = ths[3 * k + 1]
    th[2] = ths[3 * k + 2]
    rot.q_update(q, th)
print(json.dumps([_hex(q), _blocks(lambda: rot.q_update(q, th))]))
""")
    return mpvm.from_hex(out[0]), out[1]


def ulp_error(fn_f32, fn_exact, x):
    y = fn_f32(x).astype(float)
    exact = fn_exact(x.astype(float))
    ulp = np.spacing(np.abs(exact).astype(F32)).astype(float)
    return float(np.max(np.abs(y - exact) / ulp))


def math_section(rng):
    x = rng.uniform(-np.pi, np.pi, 200_000).astype(F32)
    u = rng.uniform(-1, 1, 200_000).astype(F32)
    yx = rng.normal(size=(2, 200_000)).astype(F32)
    return [
        ("sin", "[-pi, pi]", ulp_error(fmath_model.sin, np.sin, x)),
        ("cos", "[-pi, pi]", ulp_error(fmath_model.cos, np.cos, x)),
        ("asin", "[-1, 1]", ulp_error(fmath_model.asin, np.arcsin, u)),
        (
            "atan2",
            "normal (y, x)",
            ulp_error(
                lambda v: fmath_model.atan2(v[0], v[1]), lambda v: np.arctan2(v[0], v[1]), yx
            ),
        ),
    ]


def geo_section():
    import pymap3d

    lat0, lon0, h0 = 342600000, 1089400000, 400.0  # Xi'an, where seed 001's drives were made
    frame = geo.LocalFrame()
    frame.set_origin(lat0, lon0, F32(h0))
    enu = f32.zeros(3)
    rows = []
    for d_m in (100.0, 1000.0, 5000.0, 20000.0):
        lat, lon, h = pymap3d.enu2geodetic(d_m * 0.6, d_m * 0.8, h0, lat0 / 1e7, lon0 / 1e7, h0)
        lat_e7, lon_e7 = int(round(lat * 1e7)), int(round(lon * 1e7))
        frame.to_enu(enu, lat_e7, lon_e7, F32(h))
        truth = pymap3d.geodetic2enu(
            lat_e7 / 1e7, lon_e7 / 1e7, float(F32(h)), lat0 / 1e7, lon0 / 1e7, h0
        )
        rows.append((d_m, float(np.linalg.norm(np.asarray(enu, float) - truth))))
    return rows


def navigator_section():
    from host_emulator import nav_runner
    from host_emulator.sim import gnss as sim_gnss
    from host_emulator.sim import imu as sim_imu
    from host_emulator.sim import trajectory

    truth = trajectory.SCENARIOS["urban_drive"](duration_s=240, seed=0)
    imu = sim_imu.simulate(truth, seed=0)
    gnss = sim_gnss.simulate(truth, sim_gnss.GnssModel(white_fraction=1.0), seed=0)
    run = nav_runner.run(truth, imu, gnss)
    m = nav_runner.metrics(run, truth, [o for o in truth.outages if o[0] + o[1] < 240])
    ok = gnss.quality > 0
    m["gnss_horiz_rms_m"] = float(np.sqrt(np.mean(np.sum(gnss.err_n_m[ok, :2] ** 2, axis=1))))
    return m, run.align_time_s, run.wall_s


def main():
    print("MicroPython INS/GNSS firmware: float32 core self-check")
    print("(the full emulator run replaces this demo once it exists)\n")
    thetas = gyro_increments()
    q_fw, q_model, first_diff, wall = attitude_section(thetas)
    q_exact = exact_attitude(thetas)
    print(f"1. Attitude: {STEPS} gyro increments (10 s at 200 Hz, coning + 30 deg/s turn)")
    print("   integrated by firmware/lib/rot.py q_update (seed 001 eq. 5-17) in float32")
    same = "identical in every bit" if first_diff is None else f"DIFFERENT from step {first_diff}"
    print(f"   firmware vs NumPy model, all {STEPS} steps: {same}")
    err = angle_urad(q_fw, q_exact)
    err_deg = np.degrees(err * 1e-6)
    print(f"   float32 vs double precision after 10 s: {err:.2f} micro-rad ({err_deg:.1e} deg)")
    print(f"   desktop speed: {wall / STEPS * 1e6:.0f} us per step (firmware + model)\n")

    q_vm, blocks = vm_section(thetas)
    print("2. The same 2000 steps in the real MicroPython 1.29 VM (double-precision floats):")
    print(f"   difference from the float32 model: {angle_urad(q_vm, q_model):.2f} micro-rad")
    print(f"   allocations per q_update: {blocks} float boxes (nothing else)\n")

    print("3. Deterministic float32 math (max error over 200k random points, in float32 ulp):")
    for name, dom, err in math_section(np.random.default_rng(1)):
        print(f"   {name:5s} over {dom:14s} {err:5.2f} ulp")
    print("   full-domain figures: docs/float32.md (make accuracy)\n")

    print("4. Integer lat/lon -> local ENU metres, Xi'an origin, against pymap3d:")
    for d_m, err in geo_section():
        print(f"   {d_m / 1000:5.1f} km from the origin: error {err * 1000:7.1f} mm")
    print("\n5. The navigator (INS + 15-state ESKF) on a simulated city drive, first 240 s:")
    print("   60 s standing still, then driving up to 15 m/s with a 10 s GNSS outage at 200 s")
    m, align_t, wall = navigator_section()
    print(f"   navigation starts at {align_t:.1f} s (heading from the GNSS course once moving)")
    print(
        f"   horizontal RMS {m['horiz_rms_m']:.2f} m (raw GNSS {m['gnss_horiz_rms_m']:.2f} m), "
        f"yaw RMS {m['yaw_rms_deg']:.2f} deg"
    )
    for o in m["outages"]:
        print(f"   {o['length_s']:g} s without GNSS: {o['horiz_err_end_m']:.2f} m off at its end")
    print(f"   ({wall:.1f} s on this PC; full benchmark: make bench-nav)")
    print("\nThe tests (`make test`) check each of these against stated bounds.")
    return 0 if first_diff is None else 1
