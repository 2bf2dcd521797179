"""The simulation: truth self-consistency, IMU model, GNSS model, determinism."""

import dataclasses
import math

import numpy as np
import pymap3d
import pytest

from host_emulator.model import rot as ref_rot
from host_emulator.sim import gnss, imu
from host_emulator.sim import trajectory as tr
from host_emulator.sim.noise import gauss_markov

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def urban():
    return tr.urban_drive(seed=0)


@pytest.fixture(scope="module")
def static():
    return tr.static(seed=0)


@pytest.fixture(scope="module")
def highway():
    return tr.highway_outage(seed=0)


# --- truth ---


def _rk4_closure(truth, k0, k1):
    """Integrate truth.w_ib_b and truth.f_b from the truth state at sample k0 to sample k1
    (k1 - k0 even) in float64: classical RK4 with a 10 ms step whose half-step input is the
    middle 5 ms sample. Navigation equations in the Earth-fixed ENU frame:
        q' = q (x) [0, (w_ib_b - C_nb w_ie_n) / 2]
        v' = C_bn f_b - 2 w_ie_n x v + g_n(p),   p' = v
    Returns (q, v, p) at k1."""
    o = truth.origin
    r_n, r_m = o.radii_m()
    re, rm = r_n + o.h_m, r_m + o.h_m
    ex, ey, ez = (float(x) for x in truth.w_ie_n)
    g0 = float(o.gravity_m_s2(0.0))
    kfa = tr.FREE_AIR_M_S2_PER_M
    gyro, acc = truth.w_ib_b.tolist(), truth.f_b.tolist()

    def deriv(x, w, f):
        qw, qx, qy, qz, vx, vy, vz, px, py, pz = x
        c00, c01, c02 = (
            1 - 2 * (qy * qy + qz * qz),
            2 * (qx * qy - qw * qz),
            2 * (qx * qz + qw * qy),
        )
        c10, c11, c12 = (
            2 * (qx * qy + qw * qz),
            1 - 2 * (qx * qx + qz * qz),
            2 * (qy * qz - qw * qx),
        )
        c20, c21, c22 = (
            2 * (qx * qz - qw * qy),
            2 * (qy * qz + qw * qx),
            1 - 2 * (qx * qx + qy * qy),
        )
        wx = w[0] - (c00 * ex + c10 * ey + c20 * ez)
        wy = w[1] - (c01 * ex + c11 * ey + c21 * ez)
        wz = w[2] - (c02 * ex + c12 * ey + c22 * ez)
        ux, uy = px / re, py / rm
        g = (g0 + kfa * pz) / math.sqrt(ux * ux + uy * uy + 1.0)
        return (
            0.5 * (-qx * wx - qy * wy - qz * wz),
            0.5 * (qw * wx + qy * wz - qz * wy),
            0.5 * (qw * wy - qx * wz + qz * wx),
            0.5 * (qw * wz + qx * wy - qy * wx),
            c00 * f[0] + c01 * f[1] + c02 * f[2] - 2 * (ey * vz - ez * vy) - g * ux,
            c10 * f[0] + c11 * f[1] + c12 * f[2] - 2 * (ez * vx - ex * vz) - g * uy,
            c20 * f[0] + c21 * f[1] + c22 * f[2] - 2 * (ex * vy - ey * vx) - g,
            vx,
            vy,
            vz,
        )

    def step(x, d, h):
        return [a + h * b for a, b in zip(x, d, strict=True)]

    x = [*truth.q_bn[k0].tolist(), *truth.v_n[k0].tolist(), *truth.p_n[k0].tolist()]
    h = 2.0 * truth.dt_s
    for k in range(k0, k1, 2):
        d1 = deriv(x, gyro[k], acc[k])
        d2 = deriv(step(x, d1, h / 2), gyro[k + 1], acc[k + 1])
        d3 = deriv(step(x, d2, h / 2), gyro[k + 1], acc[k + 1])
        d4 = deriv(step(x, d3, h), gyro[k + 2], acc[k + 2])
        incr = zip(d1, d2, d3, d4, strict=True)
        x = [a + h / 6 * (b + 2 * c + 2 * d + e) for a, (b, c, d, e) in zip(x, incr, strict=True)]
        n = math.sqrt(sum(a * a for a in x[:4]))
        x[:4] = [a / n for a in x[:4]]
    return np.array(x[:4]), np.array(x[4:7]), np.array(x[7:])


def _angle_between(q1, q2):
    """Rotation angle (rad) between unit quaternions."""
    return 2.0 * math.asin(min(1.0, float(np.linalg.norm(_qmul_conj(q1, q2)[1:]))))


def _qmul_conj(q1, q2):
    """q1* (x) q2."""
    w1, x1, y1, z1 = q1[0], -q1[1], -q1[2], -q1[3]
    w2, x2, y2, z2 = q2
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def test_ideal_imu_integrates_back_to_the_truth(urban):
    # 60 s of driving (60-120 s: accelerate to 8-15 m/s, a 90-degree turn, ~450 m).
    k0, k1 = urban.index(60.0), urban.index(120.0)
    yaw = np.unwrap(urban.ypr[k0:k1, 0])
    assert np.ptp(yaw) > 80 * DEG and np.linalg.norm(urban.p_n[k1] - urban.p_n[k0]) > 300
    q, v, p = _rk4_closure(urban, k0, k1)
    # Measured: 7e-6 m, 1.4e-6 m/s, 1.3e-8 rad.
    assert np.linalg.norm(p - urban.p_n[k1]) < 1e-3
    assert np.linalg.norm(v - urban.v_n[k1]) < 1e-4
    assert _angle_between(q, urban.q_bn[k1]) < 1e-6


def test_rates_and_accelerations_are_derivatives_of_the_truth(urban):
    n = urban.index(200.0)
    dt = urban.dt_s
    c = tr.euler_to_dcm(urban.ypr[:n])
    cdot = (c[2:] - c[:-2]) / (2 * dt)
    skew = np.einsum("nji,njk->nik", c[1:-1], cdot)  # C_nb dC_bn/dt = [w_nb_b x]
    w_fd = np.stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]], axis=-1)
    assert np.abs(w_fd - urban.w_nb_b[1 : n - 1]).max() < 1e-4
    assert (
        np.abs((urban.v_n[2:n] - urban.v_n[: n - 2]) / (2 * dt) - urban.a_n[1 : n - 1]).max() < 1e-4
    )
    assert (
        np.abs((urban.p_n[2:n] - urban.p_n[: n - 2]) / (2 * dt) - urban.v_n[1 : n - 1]).max() < 1e-4
    )


@pytest.mark.parametrize("name", ["walk_ideal", "walk", "bicycle"])
def test_carried_sensor_motion_is_consistent_and_as_described(name):
    """The walks' hand motion (trajectory.Sway, hand.Hand) and the bicycle's lean and sway are in
    the truth as exact derivatives: an ideal IMU integrates back to it, and the finite
    differences of position, velocity and attitude give the velocity, acceleration and rates."""
    truth = tr.SCENARIOS[name](duration_s=120.0, seed=0)
    k0, k1 = truth.index(30.0), truth.index(90.0)
    q, v, p = _rk4_closure(truth, k0, k1)
    assert np.linalg.norm(p - truth.p_n[k1]) < 1e-3
    assert np.linalg.norm(v - truth.v_n[k1]) < 1e-4
    assert _angle_between(q, truth.q_bn[k1]) < 1e-6
    dt = truth.dt_s
    c = tr.euler_to_dcm(truth.ypr)
    skew = np.einsum("nji,njk->nik", c[1:-1], (c[2:] - c[:-2]) / (2 * dt))
    w_fd = np.stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]], axis=-1)
    # a centred difference errs by (w dt)^2 / 6 of a derivative at w: of the ideal walk's 2 Hz
    # bob (4.7 m/s^2) 3e-3; of the real walk's heel-strike harmonics and tremor (up to 11 Hz)
    # ~2.5 % of theirs
    real = name == "walk"
    assert np.abs(w_fd - truth.w_nb_b[1:-1]).max() < (3e-3 if real else 1e-3)
    fd_tol = 5e-2 if real else 1e-2
    assert np.abs((truth.v_n[2:] - truth.v_n[:-2]) / (2 * dt) - truth.a_n[1:-1]).max() < fd_tol
    moving = truth.speed_m_s > 0.5
    speed = np.linalg.norm(truth.v_n[:, :2], axis=1)
    # the heading is not the course: a hand wobbles it, a rider's frame sways
    course_yaw = np.arctan2(-truth.v_n[:, 0], truth.v_n[:, 1])
    off_deg = np.degrees(np.abs(tr.wrap_pi(truth.ypr[:, 0] - course_yaw)))[moving]
    if name == "walk_ideal":
        assert 1.0 <= speed[moving].mean() <= 1.6 and speed.max() < 2.0
        assert 5.0 < off_deg.max() < 20.0  # 4 deg of wobble, sway at ~0.2 m/s
        bob = truth.p_n[moving, 2] - truth.p_n[0, 2]
        assert 0.01 < np.ptp(bob) < 0.1
    elif name == "walk":
        assert 1.0 <= speed[moving].mean() <= 1.6 and speed.max() < 2.0
        assert 5.0 < off_deg.max() < 25.0  # the hold's 8 deg, the stride's yaw, the sway
        walking = truth.speed_m_s > 1.0
        assert 0.3 < np.abs(truth.a_n[walking, 2]).max() / 9.80665 < 1.3  # heel strikes
        assert 0.15 < np.linalg.norm(truth.a_n[walking, :2], axis=1).max() / 9.80665 < 1.0
        # what the standstill detector sees of a walking hand (navcfg's handheld thresholds: 3
        # deg/s, 0.5 m/s^2): seeds 0-4, 28-47 deg/s and 2.8-5.5 m/s^2 rms
        rate_rms = np.degrees(np.sqrt(np.mean(np.sum(truth.w_nb_b[walking] ** 2, axis=1))))
        assert rate_rms > 10.0 and np.sqrt(np.sum(np.var(truth.f_b[walking], axis=0))) > 2.0
        # standing is never still: the hand's tremor and sway, small beside a step
        still = truth.speed_m_s == 0.0
        rate_dps = np.degrees(np.linalg.norm(truth.w_nb_b[still], axis=1))
        assert 0.3 < np.sqrt(np.mean(rate_dps**2)) < 3.0
        f_dev = truth.f_b[still] - truth.f_b[still].mean(axis=0)
        assert 0.02 < np.linalg.norm(f_dev, axis=1).std() < 0.3
        assert 0.005 < np.linalg.norm(truth.v_n[still], axis=1).max() < 0.1
        assert 10.0 < np.degrees(truth.ypr[still, 1]).mean() < 36.0  # held up to the face
    else:
        assert speed.max() < 7.5 and speed[moving].mean() > 2.5
        roll = np.degrees(np.abs(truth.ypr[moving, 2]))
        assert roll.max() > 5.0  # leaning into the turns
        assert off_deg.max() < 5.0


def test_rotations_match_the_firmware_conventions(urban):
    ypr = urban.ypr[::997]
    assert np.abs(ref_rot.euler_to_dcm(ypr) - tr.euler_to_dcm(ypr)).max() < 1e-6
    assert np.abs(ref_rot.euler_to_q(ypr) - urban.q_bn[::997]).max() < 1e-6
    assert np.abs(tr.q_to_dcm(urban.q_bn) - urban.c_bn).max() < 1e-12
    # Forward axis in ENU is C_bn[:, 1]; velocity follows it, heading = -yaw.
    moving = urban.speed_m_s > 1.0
    fwd = urban.c_bn[moving][:, :, 1]
    vel = urban.v_n[moving] / np.linalg.norm(urban.v_n[moving], axis=1, keepdims=True)
    assert np.einsum("ni,ni->n", fwd, vel).min() > 0.9999


def test_static_specific_force_is_local_gravity_pointing_up(static):
    g = 9.780327 * (
        1 + 0.0053024 * math.sin(34.26 * DEG) ** 2 - 0.0000058 * math.sin(2 * 34.26 * DEG) ** 2
    )  # International Gravity Formula 1980, an independent check of Somigliana
    g -= 3.086e-6 * 400.0
    assert static.origin.gravity_m_s2() == pytest.approx(g, abs=5e-6)
    assert np.abs(np.linalg.norm(static.f_b, axis=1) - static.origin.gravity_m_s2()).max() < 1e-12
    f_n = tr.body_to_nav(static.c_bn, static.f_b)
    assert np.abs(f_n - [0.0, 0.0, static.origin.gravity_m_s2()]).max() < 1e-12
    tilt = np.abs(static.ypr[0, 1:])
    assert np.all((tilt > 0.4 * DEG) & (tilt < 3 * DEG))  # slightly tilted
    assert np.abs(static.f_b[:, :2]).min() > 0.05  # so gravity shows on x and y
    # The gyro sees only the Earth rate, whose vertical part is Omega sin(L).
    assert np.abs(np.linalg.norm(static.w_ib_b, axis=1) - tr.OMEGA_IE_RAD_S).max() < 1e-15
    assert np.abs(static.p_n).max() == 0.0 and np.all(static.lat_e7 == static.origin.lat_e7)


def test_car_obeys_the_non_holonomic_constraint(urban, highway):
    for truth in (urban, highway):
        v_b = tr.nav_to_body(truth.c_bn, truth.v_n)
        assert np.abs(v_b[:, 0]).max() < 5e-3  # lateral
        assert np.abs(v_b[:, 2]).max() < 0.15  # vertical: only suspension pitch
        assert np.abs(v_b[:, 1] - truth.speed_m_s).max() < 2e-3
        cruising = np.abs(np.gradient(truth.speed_m_s, truth.dt_s)) < 1e-9
        assert np.abs(v_b[cruising][:, [0, 2]]).max() < 1e-9


def test_urban_drive_has_the_promised_manoeuvres(urban):
    assert urban.duration_s == 600.0 and len(urban) == 120001
    assert np.all(urban.speed_m_s[: urban.index(60.0)] == 0.0)
    assert 12.0 < urban.speed_m_s.max() <= 15.0
    stopped = np.concatenate([[0], (urban.speed_m_s < 1e-9).astype(int), [0]])
    edges = np.flatnonzero(np.diff(stopped))
    lengths = (edges[1::2] - edges[::2]) * urban.dt_s
    assert np.sum((lengths >= 10.0) & (lengths <= 20.5)) >= 2
    rate = urban.w_nb_b[:, 2]
    assert rate.max() > 0.2 and rate.min() < -0.2  # turns both ways
    # A 270-degree turn: the largest yaw change within a single continuous turn.
    turning = np.concatenate([[0], (np.abs(rate) > 1e-6).astype(int), [0]])
    edges = np.flatnonzero(np.diff(turning))
    angles = [np.sum(rate[a:b]) * urban.dt_s for a, b in zip(edges[::2], edges[1::2], strict=True)]
    assert max(angles) == pytest.approx(1.5 * math.pi, abs=0.05)
    assert sum(abs(abs(a) - 0.5 * math.pi) < 0.05 for a in angles) >= 4


def test_geodetic_truth_matches_pymap3d(urban):
    k = urban.index(599.0)
    lat, lon, h = pymap3d.enu2geodetic(*urban.p_n[k], 34.26, 108.94, 400.0)
    assert urban.lat_e7[k] == round(lat * 1e7) and urban.lon_e7[k] == round(lon * 1e7)
    assert urban.h_m[k] == pytest.approx(h, abs=1e-9)
    assert urban.lat_e7.dtype == np.int64


# --- IMU ---


def test_imu_counts_are_int16_at_the_datasheet_sensitivity(urban):
    data = imu.simulate(urban, seed=0)
    assert data.gyro_counts.dtype == np.int16 and data.accel_counts.dtype == np.int16
    assert np.abs(data.accel_counts).max() <= 2048
    assert imu.GYRO_LSB_PER_DPS == 131.2 and imu.ACCEL_LSB_PER_G == 1024.0
    np.testing.assert_allclose(
        data.w_b_rad_s, data.gyro_counts / 131.2 * DEG, rtol=1e-14, atol=1e-18
    )
    np.testing.assert_allclose(
        data.f_b_m_s2, data.accel_counts / 1024.0 * 9.80665, rtol=1e-14, atol=1e-18
    )
    ideal = imu.simulate(urban, imu.ImuModel.ideal(), seed=0)
    assert np.array_equal(ideal.gyro_counts, np.rint(urban.w_ib_b / DEG * 131.2))
    assert np.abs(ideal.w_b_rad_s - urban.w_ib_b).max() <= 0.5 * DEG / 131.2 + 1e-15
    assert np.abs(ideal.f_b_m_s2 - urban.f_b).max() <= 0.5 * 9.80665 / 1024 + 1e-15
    assert not data.saturated.any()


def test_imu_saturation_flags_rates_beyond_full_scale(static):
    n = 50
    w = static.w_ib_b[:n].copy()
    f = static.f_b[:n].copy()
    w[10, 0] = 300 * DEG
    w[20, 2] = -260 * DEG
    w[30, 1] = 240 * DEG  # within range
    f[40, 1] = 2.5 * 9.80665
    clipped = dataclasses.replace(static, t_s=static.t_s[:n], w_ib_b=w, f_b=f)
    data = imu.simulate(clipped, imu.ImuModel.ideal())
    assert np.flatnonzero(data.saturated).tolist() == [10, 20, 40]
    assert data.gyro_counts[10, 0] == 32767 and data.gyro_counts[20, 2] == -32768
    assert data.gyro_counts[30, 1] == round(240 * 131.2)
    assert data.accel_counts[40, 1] == 2047


def test_imu_noise_and_bias_statistics(static):
    model = imu.ImuModel()
    data = imu.simulate(static, model, seed=5)
    gyro_res = data.w_b_rad_s - static.w_ib_b @ data.gyro_matrix.T - data.bg_rad_s
    accel_res = data.f_b_m_s2 - static.f_b @ data.accel_matrix.T - data.ba_m_s2
    sigma_g = 0.014 * DEG * math.sqrt(200.0)  # ARW / sqrt(dt)
    sigma_a = 150e-6 * 9.80665 * math.sqrt(200.0)  # VRW / sqrt(dt)
    assert model.gyro_noise_rad_s == pytest.approx(sigma_g)
    np.testing.assert_allclose(gyro_res.std(axis=0), sigma_g, rtol=0.1)
    np.testing.assert_allclose(accel_res.std(axis=0), sigma_a, rtol=0.1)
    assert np.abs(gyro_res.mean(axis=0)).max() < 0.05 * sigma_g
    # Turn-on biases within their ranges; the instability part is small on top.
    bg0 = np.abs(data.bg_rad_s[0]) / DEG
    ba0 = np.abs(data.ba_m_s2[0]) / 9.80665e-3
    assert np.all((bg0 > 0.09) & (bg0 < 0.21)) and np.all((ba0 > 1.9) & (ba0 < 4.1))
    assert np.ptp(data.bg_rad_s, axis=0).max() < 5 * 10 * DEG / 3600
    off = ~np.eye(3, dtype=bool)
    assert np.abs(np.diag(data.gyro_matrix) - 1).max() < 0.015  # 5 sigma of 0.3 %
    assert 0 < np.abs(data.gyro_matrix[off]).max() < 5e-3


def test_uncalibrated_imu_has_the_datasheets_errors_and_free_running_sample_clocks():
    """ImuModel.uncalibrated (the realistic walk's): turn-on biases up to the datasheet's, the
    gyro's g-sensitivity, and each die's own sample clock: a tick reads a sample up to one of
    its periods old (gyro 400 Hz, accel 250 Hz), the age sliding between 0 and the period."""
    walk = tr.SCENARIOS["walk"](duration_s=60.0, seed=1)
    assert walk.sensor_grade == "uncalibrated" and imu.model_for(walk).gyro_odr_hz == 400.0
    model = imu.ImuModel.uncalibrated()
    bare = dataclasses.replace(
        model, gyro_noise_dps_rt_hz=0.0, accel_noise_ug_rt_hz=0.0, gyro_scale_error=0.0,
        accel_scale_error=0.0, gyro_misalignment_rad=0.0, accel_misalignment_rad=0.0,
    )  # fmt: skip
    data = imu.simulate(walk, bare, seed=3)
    bg0 = np.abs(data.bg_rad_s[0]) / DEG
    ba0 = np.abs(data.ba_m_s2[0]) / 9.80665e-3
    assert np.all((bg0 > 0.15) & (bg0 < 1.05)) and np.all((ba0 > 9.0) & (ba0 < 51.0))
    g_dps_per_g = data.gyro_g_matrix / DEG * 9.80665
    assert 0.02 < np.abs(g_dps_per_g).mean() < 0.3
    # what the gyro saw, less its bias and g-sensitivity, is the truth some time ago: find the
    # age tick by tick from the rate's derivative while walking
    w = data.w_b_rad_s - data.bg_rad_s - data.f_b_m_s2 @ data.gyro_g_matrix.T
    dw = np.gradient(walk.w_ib_b, walk.dt_s, axis=0)
    walking = np.flatnonzero(walk.speed_m_s > 1.0)
    strong = walking[np.linalg.norm(dw[walking], axis=1) > 3.0]
    age = np.einsum("ni,ni->n", walk.w_ib_b[strong] - w[strong], dw[strong]) / np.einsum(
        "ni,ni->n", dw[strong], dw[strong]
    )
    q = np.percentile(age, [2, 50, 98]) * 1e3
    assert -0.2 < q[0] < 0.3 and 0.8 < q[1] < 1.7 and 2.2 < q[2] < 2.7, q  # 0..2.5 ms
    # a model without sample clocks samples at the tick
    ideal = imu.simulate(walk, imu.ImuModel.ideal(), seed=3)
    assert np.array_equal(ideal.gyro_counts, np.rint(walk.w_ib_b / DEG * 131.2))


def test_gauss_markov_has_the_stated_sigma_and_correlation():
    rng = np.random.default_rng(1)
    x = gauss_markov(rng, 400_000, 1.0, 50.0, 2.0, (2,))
    assert x.std() == pytest.approx(2.0, rel=0.03)
    lag = np.mean(x[50:] * x[:-50]) / np.mean(x * x)
    assert lag == pytest.approx(math.exp(-1.0), abs=0.04)


# --- GNSS ---


def _angle_diff_deg(a, b):
    return (np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0


def test_course_over_ground_follows_the_heading(urban):
    exact = gnss.simulate(urban, gnss.GnssModel(sigma_vel_m_s=0.0), seed=0)
    idx = urban.index(exact.t_fix_s)
    moving = exact.valid & (urban.speed_m_s[idx] > 2.0)
    heading = -np.degrees(urban.ypr[idx, 0])
    # Without noise the course differs from the heading only by the lever arm's velocity.
    lever_v = np.linalg.norm(np.cross(urban.w_nb_b[idx], [0.0, 0.5, 1.0]), axis=1)
    bound = np.degrees(np.arcsin(np.minimum(1.0, lever_v / urban.speed_m_s[idx]))) + 1e-6
    err = np.abs(_angle_diff_deg(exact.course_deg, heading))
    assert np.all(err[moving] <= bound[moving] * 1.01)
    assert np.median(err[moving]) < 1e-3
    noisy = gnss.simulate(urban, seed=0)
    err = np.abs(_angle_diff_deg(noisy.course_deg, heading))
    assert np.median(err[moving]) < 1.0
    slow = noisy.valid & (noisy.speed_m_s < 0.5)
    assert slow.any() and np.all(np.isnan(noisy.course_deg[slow]))
    assert np.all((noisy.course_deg[moving] >= 0) & (noisy.course_deg[moving] < 360))


def test_outages_give_no_fix_while_moving(urban, highway):
    assert tr.OUTAGES["urban_drive"] == ((200.0, 10.0), (400.0, 30.0))
    assert tr.OUTAGES["highway_outage"] == ((180.0, 60.0),)
    for truth, min_speed in ((urban, 1.0), (highway, 25.0)):
        data = gnss.simulate(truth, seed=0)
        out = np.zeros(len(data), bool)
        for start, length in truth.outages:
            inside = (data.t_fix_s >= start) & (data.t_fix_s < start + length)
            out |= inside
            ks = truth.index(np.arange(start, start + length, truth.dt_s))
            assert truth.speed_m_s[ks].min() > min_speed
            assert not np.any((data.pps_s >= start) & (data.pps_s < start + length))
        assert not data.valid[out].any() and data.valid[~out].all()
        assert np.all(data.lat_e7[out] == 0) and np.all(np.isnan(data.h_m[out]))
        assert np.all(data.nsat[out] < 4) and np.all(data.nsat[~out] >= 4)
        assert len(data.pps_s) == np.sum(~out)  # 1 Hz: one PPS per epoch with a fix
    # Other seeds keep moving through the outages too.
    for seed in (1, 2):
        truth = tr.urban_drive(seed=seed)
        for start, length in truth.outages:
            ks = truth.index(np.arange(start, start + length, truth.dt_s))
            assert truth.speed_m_s[ks].min() > 1.0


def test_gnss_errors_match_the_reported_sigmas():
    truth = tr.static(600.0, seed=0)
    model = gnss.GnssModel()
    norm, lag1, vel, runs = [], [], [], []
    for seed in range(30):
        data = gnss.simulate(truth, model, seed=seed)
        runs.append(data)
        assert data.valid.all()
        # Decode what the receiver reports back to ENU and compare with the antenna truth.
        e, n, u = pymap3d.geodetic2enu(
            data.lat_e7 * 1e-7, data.lon_e7 * 1e-7, data.h_m, 34.26, 108.94, 400.0
        )
        err = np.stack([e, n, u], axis=1) - data.p_ant_n
        assert np.abs(err - data.err_n_m).max() < 0.02  # 1e-7 deg rounding
        z = err / np.stack([data.sigma_h_m, data.sigma_h_m, data.sigma_v_m], axis=1)
        norm.append(z)
        lag1.append(np.mean(z[1:] * z[:-1], axis=0))
        vel.append(data.speed_m_s / data.sigma_vel_m_s)
    z = np.concatenate(norm)
    std = z.std(axis=0)
    assert std[:2] == pytest.approx([1.0, 1.0], rel=0.1) and std[2] == pytest.approx(1.0, rel=0.15)
    # Half the variance is white, half Gauss-Markov with 60 s correlation.
    assert np.mean(lag1) == pytest.approx(0.5 * math.exp(-1 / 60), abs=0.1)
    # At rest the reported speed is the norm of 2-D velocity noise: Rayleigh, mean sigma sqrt(pi/2)
    assert np.mean(np.concatenate(vel)) == pytest.approx(math.sqrt(math.pi / 2), rel=0.05)
    # Sigmas follow HDOP: 0.8-1.2 mostly, excursions to 2-4 now and then.
    hdop = np.concatenate([d.hdop for d in runs])
    sigma_h = np.concatenate([d.sigma_h_m for d in runs])
    np.testing.assert_allclose(sigma_h, 2.0 * hdop, rtol=1e-12)
    assert 0.8 <= hdop.min() and hdop.max() <= 4.0
    assert np.mean(hdop <= 1.2) > 0.9 and np.sum(hdop > 2.0) >= 10


def test_gnss_timing_latency_and_rate(urban):
    data = gnss.simulate(urban, gnss.GnssModel(rate_hz=10.0), seed=3)
    assert len(data) == 6001
    np.testing.assert_allclose(data.t_fix_s, np.arange(6001) * 0.1, atol=1e-9)
    assert np.all(urban.t_s[urban.index(data.t_fix_s)] == data.t_fix_s)
    latency = data.t_avail_s - data.t_fix_s
    assert latency.min() >= 0.05 and latency.max() <= 0.15
    whole = data.pps_s
    assert np.all(whole == np.round(whole)) and whole[0] == 0.0
    with pytest.raises(ValueError):
        gnss.simulate(urban, gnss.GnssModel(rate_hz=3.0))
    late = gnss.simulate(urban, gnss.GnssModel(ttff_s=30.0), seed=0, outages=())
    assert not late.valid[late.t_fix_s < 30].any() and late.valid[late.t_fix_s >= 30].all()
    assert late.pps_s[0] == 30.0
    fix = late[100]
    assert isinstance(fix, gnss.GnssFix) and fix.quality == 1 and isinstance(fix.lat_e7, int)


def test_antenna_lever_arm(highway):
    data = gnss.simulate(highway, seed=0)
    idx = highway.index(data.t_fix_s)
    offset = tr.body_to_nav(highway.c_bn[idx], [0.0, 0.5, 1.0])
    assert np.abs(data.p_ant_n - highway.p_n[idx] - offset).max() < 1e-12
    up = data.p_ant_n[:, 2] - highway.p_n[idx, 2]
    assert np.all(np.abs(up - 1.0) < 0.02)


# --- determinism and speed ---


def test_same_seed_same_data_and_shorter_runs_are_prefixes():
    a = tr.urban_drive(150.0, seed=7)
    b = tr.urban_drive(150.0, seed=7)
    c = tr.urban_drive(150.0, seed=8)
    long = tr.urban_drive(300.0, seed=7)
    for name in ("p_n", "q_bn", "w_ib_b", "f_b", "lat_e7"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
        assert not np.array_equal(getattr(a, name), getattr(c, name))
        assert np.array_equal(getattr(a, name), getattr(long, name)[: len(a)])
    ia, ib, ic = imu.simulate(a, seed=1), imu.simulate(a, seed=1), imu.simulate(a, seed=2)
    assert np.array_equal(ia.gyro_counts, ib.gyro_counts)
    assert np.array_equal(ia.accel_counts, ib.accel_counts)
    assert not np.array_equal(ia.gyro_counts, ic.gyro_counts)
    ga, gb, gc = gnss.simulate(a, seed=1), gnss.simulate(a, seed=1), gnss.simulate(a, seed=2)
    assert np.array_equal(ga.lat_e7, gb.lat_e7) and np.array_equal(ga.t_avail_s, gb.t_avail_s)
    assert not np.array_equal(ga.lat_e7, gc.lat_e7)


def test_scenarios_are_registered_with_descriptions():
    assert set(tr.SCENARIOS) == {
        "static",
        "urban_drive",
        "quick_start",
        "highway_outage",
        "walk_ideal",
        "walk",
        "walk_real",
        "bicycle",
    }
    for name, build in tr.SCENARIOS.items():
        assert build.description and "\n" not in build.description
        truth = build(2.0, seed=0)
        assert truth.name == name and len(truth) == 401 and truth.duration_s == 2.0
        assert truth.outages == ()  # outages after the end are dropped


def test_imu_ranges_pick_the_datasheet_sensitivity(urban):
    model = imu.ImuModel.ideal()
    wide = dataclasses.replace(model, gyro_range_dps=2000, accel_range_g=8)
    assert wide.gyro_lsb_per_dps == 16.4 and wide.accel_lsb_per_g == 256.0
    data = imu.simulate(urban, wide)
    assert np.array_equal(data.gyro_counts, np.rint(urban.w_ib_b / DEG * 16.4))
    assert np.array_equal(data.accel_counts, np.rint(urban.f_b / 9.80665 * 256.0))


def test_walk_real_is_the_hand_as_real_walks_show_it():
    """walk_real's ranges (sim/hand.py AS_HELD): slow, turning hard, steps damped at the hand,
    the board pitched up to be read, a phone-grade receiver."""
    from host_emulator.replay import carrier

    for seed in (0, 1):
        t = tr.SCENARIOS["walk_real"](duration_s=300.0, seed=seed)
        moving = t.speed_m_s > 0.1
        assert 0.5 < t.speed_m_s[moving].mean() < 0.9 and t.speed_m_s.max() <= 1.2 + 1e-9
        w = np.linalg.norm(t.w_ib_b, axis=1)
        rms_deg_s = np.degrees(np.sqrt(np.mean(w[moving] ** 2)))
        assert 25.0 < rms_deg_s < 60.0  # real walks: 35-55 deg/s (the city car: a few)
        assert np.percentile(w, 99) > 1.2  # rad/s
        assert carrier.gait(t.f_b, t.dt_s).strongest_g < 0.2  # no heel strike of 0.3-1 g
        pitch_deg = np.degrees(np.median(t.ypr[:, 1]))
        assert 35.0 < pitch_deg < 75.0
        assert 3.0 <= t.receiver["sigma_h_m"] <= 8.0 and t.board_profile == 1
