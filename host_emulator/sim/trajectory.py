"""Truth trajectories at 200 Hz in the Earth-fixed local ENU frame (float64, vectorised).

Frame: the navigation frame n is the East-North-Up tangent plane at an `Origin` (integer lat/lon
in 1e-7 deg, ellipsoidal height), fixed to the Earth. Body b: x right, y forward, z up. Attitude
`ypr` = [yaw, pitch, roll] with C_n^b = R_y(roll) R_x(pitch) R_z(yaw) (seed eq. 5-6; yaw > 0 turns
the nose from north towards west, so compass heading = -yaw), `q_bn` = [w, x, y, z] body to nav
with w >= 0, exactly as `firmware/lib/rot.py` states.

How a trajectory is made: a `DriveScript` (drive_script.py) holds commanded profiles as sums
of smooth steps,
    forward speed v(t), yaw rate r(t)        (functions of time)
    road grade g(s), road bank k(s)          (functions of distance travelled s)
each step S(u) = u - sin(2 pi u) / (2 pi) over its length (a raised-cosine rate), so the profile,
its first and its second derivative are continuous. Everything a sensor needs is evaluated in
closed form at each sample time (no numerical differentiation):
    yaw    = yaw0 + integral r dt
    pitch  = g(s) + K_pitch dv/dt             (squat when accelerating, dive when braking)
    roll   = k(s) + K_roll v r                 (the body leans out of a turn)
    v_n    = v [-sin(yaw) cos(g), cos(yaw) cos(g), sin(g)]    (along the road: non-holonomic)
    a_n    = dv_n/dt                           (closed form)
    w_nb_b = [0, roll', 0] + R_y(roll) [pitch', 0, 0] + R_y(roll) R_x(pitch) [0, 0, yaw']
    w_ib_b = w_nb_b + C_nb w_ie_n,   w_ie_n = Omega [0, cos L0, sin L0]
    f_b    = C_nb (a_n + 2 w_ie_n x v_n - g_n(p))
The body velocity is therefore [0, v, 0] except for the small suspension pitch (|v_b_z| =
v |sin(K_pitch dv/dt)|, < 0.1 m/s in these scenarios). Position is the integral of v_n by 3-point
Gauss-Legendre quadrature on each 5 ms interval (order 6), so the IMU samples and the
position/attitude truth agree to far better than any navigator can resolve: RK4 over the
samples of 60 s of urban driving with a 90-degree turn closes to 7e-6 m, 1.4e-6 m/s and
1.3e-8 rad (tests/sim).

Gravity g_n(p): magnitude from Somigliana's normal gravity (WGS-84) at the origin latitude
plus the free-air term -3.086e-6 m/s^2 per metre of height h0 + U; direction along the local
vertical at p to first order, -[E/(R_N+h0), N/(R_M+h0), 1] normalised, with R_N and R_M the
prime-vertical and meridian radii at the origin. A road that is flat in the tangent plane
therefore climbs slowly relative to the local vertical (d / R: 0.8 mrad after 5 km); the
geodetic truth (lat, lon, h) is the exact pymap3d.enu2geodetic of p_n.
"""

from dataclasses import dataclass, field

import numpy as np
import pymap3d

from .drive_script import CAR_ANTENNA_B_M, DriveScript
from .drive_script import Ramps as Ramps  # re-exported: trajectory.Ramps as before
from .hand import AS_HELD, Hand

RATE_HZ = 200
DT_S = 1.0 / RATE_HZ

# WGS-84 and normal gravity (Somigliana's closed form, WGS-84 constants).
OMEGA_IE_RAD_S = 7.292115e-5
WGS84_A_M = 6378137.0
WGS84_E2 = 6.69437999014e-3
GAMMA_E_M_S2 = 9.7803253359
SOMIGLIANA_K = 1.93185265241e-3
FREE_AIR_M_S2_PER_M = -3.086e-6

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class Origin:
    """Origin of the ENU frame: integer latitude/longitude in 1e-7 deg, ellipsoidal height in m."""

    lat_e7: int = 342600000
    lon_e7: int = 1089400000
    h_m: float = 400.0

    @property
    def lat_rad(self):
        return np.deg2rad(self.lat_e7 * 1e-7)

    def radii_m(self):
        """(R_N, R_M): WGS-84 prime-vertical and meridian radii of curvature at the origin."""
        s2 = np.sin(self.lat_rad) ** 2
        w2 = 1.0 - WGS84_E2 * s2
        r_n = WGS84_A_M / np.sqrt(w2)
        return r_n, r_n * (1.0 - WGS84_E2) / w2

    def w_ie_n(self):
        """Earth rate in the ENU axes of the origin (constant: the frame is Earth-fixed), rad/s."""
        lat = self.lat_rad
        return OMEGA_IE_RAD_S * np.array([0.0, np.cos(lat), np.sin(lat)])

    def gravity_m_s2(self, u_m=0.0):
        """Normal gravity magnitude at the origin latitude and height h0 + U (m/s^2)."""
        s2 = np.sin(self.lat_rad) ** 2
        g0 = GAMMA_E_M_S2 * (1.0 + SOMIGLIANA_K * s2) / np.sqrt(1.0 - WGS84_E2 * s2)
        return g0 + FREE_AIR_M_S2_PER_M * (self.h_m + np.asarray(u_m, dtype=float))

    def gravity_n(self, p_n):
        """Gravity vector g_n (..., 3) at ENU positions p_n (..., 3), m/s^2."""
        p_n = np.asarray(p_n, dtype=float)
        r_n, r_m = self.radii_m()
        up = np.stack(
            [
                p_n[..., 0] / (r_n + self.h_m),
                p_n[..., 1] / (r_m + self.h_m),
                np.ones(p_n.shape[:-1]),
            ],
            axis=-1,
        )
        up /= np.linalg.norm(up, axis=-1, keepdims=True)
        return -self.gravity_m_s2(p_n[..., 2])[..., None] * up

    def to_geodetic(self, p_n):
        """(lat_e7, lon_e7, h_m) of ENU positions p_n (..., 3): int64, int64, float64."""
        p_n = np.asarray(p_n, dtype=float)
        lat, lon, h = pymap3d.enu2geodetic(
            p_n[..., 0], p_n[..., 1], p_n[..., 2], self.lat_e7 * 1e-7, self.lon_e7 * 1e-7, self.h_m
        )
        lat_e7 = np.rint(np.asarray(lat) * 1e7).astype(np.int64)
        lon_e7 = np.rint(np.asarray(lon) * 1e7).astype(np.int64)
        return lat_e7, lon_e7, np.asarray(h, dtype=float)


ORIGIN_XIAN = Origin()


# --- rotations in float64 (same conventions as firmware/lib/rot.py) ---


def euler_to_dcm(ypr):
    """C_bn (..., 3, 3) from ypr (..., 3); C_bn = (R_y(roll) R_x(pitch) R_z(yaw))^T."""
    ypr = np.asarray(ypr, dtype=float)
    sy, cy = np.sin(ypr[..., 0]), np.cos(ypr[..., 0])
    sp, cp = np.sin(ypr[..., 1]), np.cos(ypr[..., 1])
    sr, cr = np.sin(ypr[..., 2]), np.cos(ypr[..., 2])
    rows = [
        [cr * cy - sr * sp * sy, -cp * sy, sr * cy + cr * sp * sy],
        [cr * sy + sr * sp * cy, cp * cy, sr * sy - cr * sp * cy],
        [-sr * cp, sp, cr * cp],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def euler_to_q(ypr):
    """q_bn (..., 4) = q_z(yaw) (x) q_x(pitch) (x) q_y(roll), sign chosen so that w >= 0."""
    ypr = np.asarray(ypr, dtype=float)
    sz, cz = np.sin(0.5 * ypr[..., 0]), np.cos(0.5 * ypr[..., 0])
    sx, cx = np.sin(0.5 * ypr[..., 1]), np.cos(0.5 * ypr[..., 1])
    sr, cr = np.sin(0.5 * ypr[..., 2]), np.cos(0.5 * ypr[..., 2])
    q = np.stack(
        [
            cz * cx * cr - sz * sx * sr,
            cz * sx * cr - sz * cx * sr,
            cz * cx * sr + sz * sx * cr,
            sz * cx * cr + cz * sx * sr,
        ],
        axis=-1,
    )
    return np.where(q[..., :1] < 0.0, -q, q)


def q_to_dcm(q):
    """C_bn (..., 3, 3) of unit quaternions q_bn (..., 4)."""
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def wrap_pi(a):
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % TWO_PI - np.pi


def nav_to_body(c_bn, x_n):
    """C_nb x_n = C_bn^T x_n for stacks (N, 3, 3) and (N, 3)."""
    return np.einsum("nji,nj->ni", c_bn, x_n)


def body_to_nav(c_bn, x_b):
    """C_bn x_b for stacks (N, 3, 3) and (N, 3) or a single (3,) vector."""
    return np.einsum("nij,nj->ni", c_bn, np.broadcast_to(x_b, (len(c_bn), 3)))


class Sway:
    """Periodic motion of a carried sensor on top of its path (a walker's hand, a rider's
    frame), in closed form like the rest: each channel is A g(t) sin(w t + phase) with the
    gate g = v(t) / v_ref_m_s, so it scales with the pace and fades out at a stop.

    Position, along the path's horizontal forward axis u, its right axis r and up: surge and
    bob at the step frequency, lateral sway at half of it (the weight moves from foot to foot).
    Attitude added to the path's: pitch at the step frequency, roll and yaw at half of it (the
    arm and the torso swing with the stride). The sensor's heading therefore differs from the
    direction of travel by up to `yaw_rad`: nothing holds the body velocity to its forward axis.
    """

    CHANNELS = ("surge", "lateral", "bob", "yaw", "pitch", "roll")
    _HALF = ("lateral", "yaw", "roll")  # at half the step frequency

    def __init__(self, step_hz, v_ref_m_s, amplitudes, phases):
        self.step_hz = float(step_hz)
        self.v_ref_m_s = float(v_ref_m_s)
        self.amplitudes = {k: float(amplitudes.get(k, 0.0)) for k in self.CHANNELS}
        self.phases = {k: float(phases.get(k, 0.0)) for k in self.CHANNELS}

    def channel(self, name, t, v, dv, d2v):
        """(x, dx/dt, d2x/dt2) of one channel at times t, given the path speed and its
        derivatives there."""
        a = self.amplitudes[name]
        w = TWO_PI * self.step_hz * (0.5 if name in self._HALF else 1.0)
        ph = w * t + self.phases[name]
        s, c = np.sin(ph), np.cos(ph)
        g, g1, g2 = v / self.v_ref_m_s, dv / self.v_ref_m_s, d2v / self.v_ref_m_s
        return a * g * s, a * (g1 * s + g * w * c), a * (g2 * s + 2.0 * g1 * w * c - g * w * w * s)


@dataclass(frozen=True, eq=False)
class Truth:
    """Truth at every IMU sample (N of them, 200 Hz). SI units; frames as in the module doc."""

    name: str
    description: str
    seed: int
    origin: Origin
    t_s: np.ndarray  # (N,) s, t_s[k] = k * DT_S
    p_n: np.ndarray  # (N, 3) ENU position of the IMU, m
    v_n: np.ndarray  # (N, 3) ENU velocity, m/s
    a_n: np.ndarray  # (N, 3) ENU acceleration relative to the Earth, m/s^2
    ypr: np.ndarray  # (N, 3) yaw (wrapped to [-pi, pi)), pitch, roll, rad
    q_bn: np.ndarray  # (N, 4) [w, x, y, z], w >= 0
    w_nb_b: np.ndarray  # (N, 3) body rate w.r.t. the ENU frame, body axes, rad/s
    w_ib_b: np.ndarray  # (N, 3) body rate w.r.t. inertial space, body axes, rad/s (gyro truth)
    f_b: np.ndarray  # (N, 3) specific force, body axes, m/s^2 (accelerometer truth)
    g_n: np.ndarray  # (N, 3) gravity used, m/s^2
    speed_m_s: np.ndarray  # (N,) commanded forward speed along the road, m/s
    lat_e7: np.ndarray  # (N,) int64, 1e-7 deg
    lon_e7: np.ndarray  # (N,) int64, 1e-7 deg
    h_m: np.ndarray  # (N,) ellipsoidal height, m
    w_ie_n: np.ndarray  # (3,) Earth rate in ENU, rad/s
    outages: tuple = field(default=())  # GNSS outage windows ((start_s, length_s), ...)
    antenna_b_m: tuple = CAR_ANTENNA_B_M  # IMU -> GNSS antenna, body axes (sim.gnss uses it)
    board_profile: int = 0  # the board's profile setting (config.py): 0 car, 1 handheld
    sensor_grade: str = "calibrated"  # the IMU that goes with it (sim/imu.py `model_for`)
    receiver: dict = field(default_factory=dict)  # the receiver that goes with it (sim/gnss.py)

    dt_s = DT_S

    def __len__(self):
        return self.t_s.size

    @property
    def duration_s(self):
        return float(self.t_s[-1])

    @property
    def c_bn(self):
        """(N, 3, 3) body-to-nav DCMs (computed on demand)."""
        return euler_to_dcm(self.ypr)

    def index(self, t_s):
        """Sample index (or indices) of time(s) t_s, rounded to the nearest sample."""
        return np.rint(np.asarray(t_s, dtype=float) / DT_S).astype(np.int64)


# Gauss-Legendre, 3 nodes on [0, 1].
_GL_NODES = np.array([0.5 - np.sqrt(15.0) / 10.0, 0.5, 0.5 + np.sqrt(15.0) / 10.0])
_GL_WEIGHTS = np.array([5.0, 8.0, 5.0]) / 18.0


def _road_direction(yaw, grade):
    """Unit vector along the road in ENU: the body forward axis at (yaw, pitch = grade)."""
    cg = np.cos(grade)
    return np.stack([-np.sin(yaw) * cg, np.cos(yaw) * cg, np.sin(grade)], axis=-1)


def _velocity_n(script, t_s):
    speed, _, _, dist = script.speed.eval(t_s)
    yaw = script.yaw0_rad + script.yaw_rate.eval(t_s)[3]
    grade = script.grade.eval(dist)[0]
    return speed[:, None] * _road_direction(yaw, grade)


def _road_motion(v, dv, r, yaw, grade, dgrade):
    """(v_n, a_n): the velocity along the road at speed v, and its exact time derivative (dv
    the acceleration, r the yaw rate, dgrade the grade's rate)."""
    n = v.size
    # Velocity along the road and its exact time derivative.
    sy, cy = np.sin(yaw), np.cos(yaw)
    sg, cg = np.sin(grade), np.cos(grade)
    u = np.stack([-sy * cg, cy * cg, sg], axis=-1)
    du_dyaw = np.stack([-cy * cg, -sy * cg, np.zeros(n)], axis=-1)
    du_dgrade = np.stack([sy * sg, -cy * sg, cg], axis=-1)
    v_n = v[:, None] * u
    a_n = dv[:, None] * u + v[:, None] * (r[:, None] * du_dyaw + dgrade[:, None] * du_dgrade)
    return v_n, a_n


def _position_n(script, t):
    """p_n at times t (t[0] = 0, DT_S apart): 3-point Gauss-Legendre quadrature of v_n over
    every 5 ms interval."""
    n = t.size
    nodes = (t[:-1, None] + DT_S * _GL_NODES).ravel()
    v_nodes = _velocity_n(script, nodes).reshape(n - 1, 3, 3)
    steps = DT_S * np.einsum("k,nkj->nj", _GL_WEIGHTS, v_nodes)
    p_n = np.zeros((n, 3))
    np.cumsum(steps, axis=0, out=p_n[1:])
    return p_n


def _sway_motion(sw, t, speed, rate, yaw):
    """(dp_n, dv_n, da_n): what the sway's surge, lateral and bob channels add to the path's
    position, velocity and acceleration; speed: (v, dv, d2v) along the path, rate: its yaw rate
    and that rate's derivative (r, dr), yaw: the path's yaw."""
    v, dv, d2v = speed
    r, dr = rate
    n = t.size
    sy, cy = np.sin(yaw), np.cos(yaw)
    s0, s1, s2 = sw.channel("surge", t, v, dv, d2v)
    l0, l1, l2 = sw.channel("lateral", t, v, dv, d2v)
    b0, b1, b2 = sw.channel("bob", t, v, dv, d2v)
    # horizontal forward u_h and right r_h of the path: du_h/dyaw = -r_h, dr_h/dyaw = u_h
    zero = np.zeros(n)
    u_h = np.stack([-sy, cy, zero], axis=-1)
    r_h = np.stack([cy, sy, zero], axis=-1)
    up = np.stack([zero, zero, np.ones(n)], axis=-1)
    dp_n = s0[:, None] * u_h + l0[:, None] * r_h + b0[:, None] * up
    dv_n = (s1 + l0 * r)[:, None] * u_h + (l1 - s0 * r)[:, None] * r_h + b1[:, None] * up
    da_n = (
        (s2 + 2.0 * l1 * r + l0 * dr - s0 * r * r)[:, None] * u_h
        + (l2 - 2.0 * s1 * r - s0 * dr - l0 * r * r)[:, None] * r_h
        + b2[:, None] * up
    )
    return dp_n, dv_n, da_n


def _rate_nb_b(pitch, roll, dpitch, droll, r_b):
    """w_nb_b: the body rate w.r.t. the ENU frame, body axes, from the Euler angles' rates
    (r_b: the body's yaw rate)."""
    sr, cr = np.sin(roll), np.cos(roll)
    sp, cp = np.sin(pitch), np.cos(pitch)
    return np.stack(
        [cr * dpitch - sr * cp * r_b, droll + sp * r_b, sr * dpitch + cr * cp * r_b], axis=-1
    )


def truth_from_script(
    script, duration_s, *, origin=ORIGIN_XIAN, name="", description="", seed=0, outages=()
):
    """Evaluate a DriveScript on t = 0, 5 ms, ..., duration_s and build the Truth."""
    n = int(round(duration_s * RATE_HZ)) + 1
    t = np.arange(n) * DT_S

    v, dv, d2v, dist = script.speed.eval(t)
    r, dr, _, yaw_int = script.yaw_rate.eval(t)
    yaw = script.yaw0_rad + yaw_int
    grade, dgrade_ds, _, _ = script.grade.eval(dist)
    bank, dbank_ds, _, _ = script.bank.eval(dist)
    dgrade = dgrade_ds * v
    dbank = dbank_ds * v

    kp, kr = script.PITCH_PER_ACCEL, script.ROLL_PER_ACCEL
    pitch = grade + kp * dv
    dpitch = dgrade + kp * d2v
    roll = bank + kr * v * r
    droll = dbank + kr * (dv * r + v * dr)

    v_n, a_n = _road_motion(v, dv, r, yaw, grade, dgrade)
    p_n = _position_n(script, t)

    yaw_b, r_b = yaw, r  # the body's yaw and yaw rate: the path's unless the sensor sways
    if script.sway is not None:
        sw = script.sway
        dp_n, dv_n, da_n = _sway_motion(sw, t, (v, dv, d2v), (r, dr), yaw)
        p_n += dp_n
        v_n = v_n + dv_n
        a_n = a_n + da_n
        psi, dpsi, _ = sw.channel("yaw", t, v, dv, d2v)
        yaw_b, r_b = yaw + psi, r + dpsi
        th, dth, _ = sw.channel("pitch", t, v, dv, d2v)
        pitch, dpitch = pitch + th, dpitch + dth
        ph, dph, _ = sw.channel("roll", t, v, dv, d2v)
        roll, droll = roll + ph, droll + dph

    ypr = np.stack([yaw_b, pitch, roll], axis=-1)
    c_bn = euler_to_dcm(ypr)
    w_nb_b = _rate_nb_b(pitch, roll, dpitch, droll, r_b)
    w_ie_n = origin.w_ie_n()
    w_ib_b = w_nb_b + nav_to_body(c_bn, np.broadcast_to(w_ie_n, (n, 3)))
    g_n = origin.gravity_n(p_n)
    f_b = nav_to_body(c_bn, a_n + 2.0 * np.cross(w_ie_n, v_n) - g_n)

    lat_e7, lon_e7, h_m = origin.to_geodetic(p_n)
    ypr_out = ypr.copy()
    ypr_out[:, 0] = wrap_pi(yaw_b)
    return Truth(
        name=name,
        description=description,
        seed=seed,
        origin=origin,
        t_s=t,
        p_n=p_n,
        v_n=v_n,
        a_n=a_n,
        ypr=ypr_out,
        q_bn=euler_to_q(ypr),
        w_nb_b=w_nb_b,
        w_ib_b=w_ib_b,
        f_b=f_b,
        g_n=g_n,
        speed_m_s=v,
        lat_e7=lat_e7,
        lon_e7=lon_e7,
        h_m=h_m,
        w_ie_n=w_ie_n,
        antenna_b_m=tuple(script.antenna_b_m),
        board_profile=int(script.board_profile),
        sensor_grade=str(script.sensor_grade),
        receiver=dict(script.receiver),
        outages=tuple(
            (float(s), float(min(length, duration_s - s)))
            for s, length in outages
            if s < duration_s
        ),
    )


# --- scenarios ---

SCENARIOS = {}  # name -> function(duration_s=None, seed=0, *, origin=ORIGIN_XIAN) -> Truth
OUTAGES = {}  # name -> ((start_s, length_s), ...): GNSS outage windows of the full scenario


def _scenario(name, description, default_duration_s, outages=()):
    def register(build):
        def scenario(duration_s=None, seed=0, *, origin=ORIGIN_XIAN):
            duration = default_duration_s if duration_s is None else float(duration_s)
            script = build(duration, seed, outages)
            return truth_from_script(
                script,
                duration,
                origin=origin,
                name=name,
                description=description,
                seed=seed,
                outages=outages,
            )

        scenario.__name__ = scenario.__qualname__ = build.__name__
        scenario.__doc__ = description
        scenario.description = description
        scenario.default_duration_s = default_duration_s
        scenario.outages = outages
        SCENARIOS[name] = scenario
        OUTAGES[name] = outages
        return scenario

    return register


def _streams(seed):
    """Independent generators for the route and the road shape, so a shorter duration gives a
    prefix of the longer run with the same seed."""
    return np.random.default_rng([seed, 1]), np.random.default_rng([seed, 2])


@_scenario("static", "board on a desk, slightly tilted, not moving", 120.0)
def static(duration_s, seed, outages):
    rng, _ = _streams(seed)
    tilt = np.deg2rad(rng.uniform(0.5, 2.5, size=2)) * rng.choice([-1.0, 1.0], size=2)
    script = DriveScript(rng.uniform(-np.pi, np.pi), grade0_rad=tilt[0], bank0_rad=tilt[1])
    script.hold(duration_s)
    return script


def _overlaps(t0, t1, windows):
    return any(t0 < w1 and w0 < t1 for w0, w1 in windows)


@_scenario(
    "urban_drive",
    "60 s static, then city driving up to 15 m/s: 90-degree turns both ways, stops of 10-20 s, "
    "a 270-degree roundabout; GNSS outages of 10 s and 30 s while moving",
    600.0,
    ((200.0, 10.0), (400.0, 30.0)),
)
def urban_drive(duration_s, seed, outages):
    rng, road_rng = _streams(seed)
    script = DriveScript(rng.uniform(-np.pi, np.pi))
    script.add_road(
        road_rng,
        length_m=15.0 * duration_s,
        grade_max_rad=np.arctan(0.03),
        bank_max_rad=np.deg2rad(1.5),
        spacing_m=(100.0, 300.0),
        transition_m=(30.0, 80.0),
    )
    script.hold(60.0)
    # Never stand still within 3 s of an outage: the outages are meant to be at speed.
    guards = [(s - 3.0, s + length + 3.0) for s, length in outages]
    pattern = ("left", "stop", "right", "roundabout", "right", "stop", "left", "left", "stop")
    i = 0
    while script.t_s < duration_s:
        script.speed_to(rng.uniform(8.0, 15.0), rng.uniform(0.8, 1.5))
        script.hold(rng.uniform(8.0, 25.0))
        kind = pattern[i % len(pattern)]
        i += 1
        if kind == "stop":
            brake = rng.uniform(1.0, 1.8)
            brake_s = script.v_m_s / brake
            stop_s = rng.uniform(10.0, 20.0)
            while _overlaps(script.t_s + brake_s, script.t_s + brake_s + stop_s, guards):
                script.hold(1.0)
            script.speed_to(0.0, brake)
            script.hold(stop_s)
        else:
            v_turn = rng.uniform(4.5, 7.0)
            radius = rng.uniform(15.0, 25.0) if kind == "roundabout" else rng.uniform(10.0, 20.0)
            angle = {"left": 0.5 * np.pi, "right": -0.5 * np.pi, "roundabout": 1.5 * np.pi}[kind]
            script.speed_to(v_turn, rng.uniform(1.0, 1.8))
            script.turn(angle, v_turn / radius, ramp_s=rng.uniform(1.5, 2.5))
    return script


@_scenario(
    "quick_start",
    "10 s static, then city driving up to 12 m/s with 90-degree turns both ways and a stop; "
    "no outages: navigation within seconds, for short runs (the emulated Cortex-M4F runs at "
    "about real time)",
    60.0,
)
def quick_start(duration_s, seed, outages):
    rng, road_rng = _streams(seed)
    script = DriveScript(rng.uniform(-np.pi, np.pi))
    script.add_road(
        road_rng,
        length_m=12.0 * duration_s,
        grade_max_rad=np.arctan(0.03),
        bank_max_rad=np.deg2rad(1.5),
        spacing_m=(100.0, 300.0),
        transition_m=(30.0, 80.0),
    )
    script.hold(10.0)
    pattern = ("left", "right", "stop")
    i = 0
    while script.t_s < duration_s:
        script.speed_to(rng.uniform(8.0, 12.0), rng.uniform(1.0, 1.5))
        script.hold(rng.uniform(4.0, 8.0))
        kind = pattern[i % len(pattern)]
        i += 1
        if kind == "stop":
            brake = rng.uniform(1.0, 1.8)
            script.speed_to(0.0, brake)
            script.hold(rng.uniform(3.0, 6.0))
        else:
            v_turn = rng.uniform(4.5, 7.0)
            angle = 0.5 * np.pi if kind == "left" else -0.5 * np.pi
            script.speed_to(v_turn, rng.uniform(1.0, 1.8))
            script.turn(angle, v_turn / rng.uniform(10.0, 20.0), ramp_s=rng.uniform(1.5, 2.5))
    return script


@_scenario(
    "highway_outage",
    "30 s static, accelerate to 30 m/s, long straight road with gentle curves; "
    "a 60 s GNSS outage at speed",
    300.0,
    ((180.0, 60.0),),
)
def highway_outage(duration_s, seed, outages):
    rng, road_rng = _streams(seed)
    script = DriveScript(rng.uniform(-np.pi, np.pi))
    script.add_road(
        road_rng,
        length_m=32.0 * duration_s,
        grade_max_rad=np.arctan(0.02),
        bank_max_rad=np.deg2rad(1.0),
        spacing_m=(300.0, 800.0),
        transition_m=(100.0, 300.0),
    )
    script.hold(30.0)
    script.speed_to(30.0, 1.5)
    while script.t_s < duration_s:
        script.hold(rng.uniform(10.0, 30.0))
        v = rng.uniform(28.0, 32.0)
        script.speed_to(v, 0.3)
        angle = np.deg2rad(rng.uniform(5.0, 25.0)) * rng.choice([-1.0, 1.0])
        script.turn(angle, v / rng.uniform(1000.0, 2500.0), ramp_s=rng.uniform(4.0, 8.0))
    return script


def _phases(rng):
    return {k: rng.uniform(-np.pi, np.pi) for k in Sway.CHANNELS}


@_scenario(
    "walk_ideal",
    "a walk with the board in a perfectly steady hand: 30 s held still, then 1.0-1.6 m/s with "
    "smooth sinusoidal motion (2-3 cm bob and sway, +-4 deg of heading wobble), 90-degree turns "
    "both ways, stops of 5-15 s; a 10 s GNSS outage; a calibrated IMU",
    300.0,
    ((150.0, 10.0),),
)
def walk_ideal(duration_s, seed, outages):
    rng, _ = _streams(seed)
    script = DriveScript(rng.uniform(-np.pi, np.pi))
    deg = np.deg2rad
    sway = Sway(
        step_hz=rng.uniform(1.7, 2.0),
        v_ref_m_s=1.3,
        amplitudes={
            "surge": 0.02,
            "lateral": 0.03,
            "bob": 0.03,
            "yaw": deg(4.0),
            "pitch": deg(2.0),
            "roll": deg(3.0),
        },  # fmt: skip
        phases=_phases(rng),
    )
    _in_hand(script, sway)
    _walk_route(script, rng, duration_s, outages)
    return script


@_scenario(
    "walk",
    "a walk with the board in hand, as unkind as a real one: 30 s standing with the hand's "
    "tremor and sway, then 1.0-1.6 m/s with heel strikes of 0.3-1 g at 1.6-2.2 steps/s, the "
    "hand pitching, rolling and yawing with each step and stride, 90-degree turns both ways, "
    "stops of 5-15 s; the board held pitched up 10-35 deg; an uncalibrated BMI055 (turn-on "
    "biases up to the datasheet's, temperature drift, g-sensitivity, free-running sample "
    "clocks); a 10 s GNSS outage",
    300.0,
    ((150.0, 10.0),),
)
def walk(duration_s, seed, outages):
    rng, _ = _streams(seed)
    hand_rng = np.random.default_rng([seed, 3])  # the walker apart from the route
    script = DriveScript(rng.uniform(-np.pi, np.pi))
    _in_hand(script, Hand.draw(hand_rng))
    script.sensor_grade = "uncalibrated"
    _walk_route(script, rng, duration_s, outages)
    return script


@_scenario(
    "walk_real",
    "a walk as real hands make it: 10 s standing, then 0.4-1.2 m/s with pauses of 2-10 s, "
    "turns of 45-180 deg on 1-4 m radii, the board held in front pitched up 40-70 deg, pointed "
    "anywhere against the walk and re-pointed by 15-60 deg, steps of 0.02-0.2 g at the hand; "
    "an uncalibrated BMI055; a phone-grade receiver at 1 Hz, 3-8 m per axis",
    300.0,
    (),
)
def walk_real(duration_s, seed, outages):
    rng, _ = _streams(seed)
    hand_rng = np.random.default_rng([seed, 3])
    script = DriveScript(rng.uniform(-np.pi, np.pi))
    _in_hand(script, Hand.draw(hand_rng, v_ref_m_s=0.8, style=AS_HELD))
    script.sensor_grade = "uncalibrated"
    sigma = rng.uniform(3.0, 8.0)
    script.receiver = {"sigma_h_m": sigma, "sigma_v_m": 2.0 * sigma}
    script.hold(10.0)
    while script.t_s < duration_s:
        v = rng.uniform(0.4, 1.2)
        script.speed_to(v, rng.uniform(0.3, 0.6), min_s=1.0)
        script.hold(rng.uniform(3.0, 12.0))
        kind = rng.uniform()
        if kind < 0.2:  # a pause: looking around, reading the screen
            script.speed_to(0.0, rng.uniform(0.4, 0.8), min_s=1.0)
            script.hold(rng.uniform(2.0, 10.0))
        else:  # a turn at walking pace on a 1-4 m radius
            angle = np.copysign(np.deg2rad(rng.uniform(45.0, 180.0)), kind - 0.6)
            script.turn(angle, v / rng.uniform(1.0, 4.0), ramp_s=rng.uniform(0.3, 0.6))
    return script


def _in_hand(script, sway):
    """A board in a person's hand, moved by `sway` (a Sway or a hand.Hand)."""
    script.PITCH_PER_ACCEL = 0.0  # a hand neither squats nor leans like a car body
    script.ROLL_PER_ACCEL = 0.0
    script.sway = sway
    # a hand-held board carries its own antenna: a car's 1 m lever would swing at the hand's
    # rates (0.4 m/s)
    script.antenna_b_m = (0.0, 0.05, 0.0)
    script.board_profile = 1  # handheld: no NHC, a hand's standstill detector (navcfg)


def _walk_route(script, rng, duration_s, outages):
    """30 s standing, then walking legs with corners and stops (no stop next to an outage)."""
    script.hold(30.0)
    guards = [(s - 3.0, s + length + 3.0) for s, length in outages]
    pattern = ("left", "stop", "right", "right", "stop", "left")
    i = 0
    while script.t_s < duration_s:
        script.speed_to(rng.uniform(1.0, 1.6), rng.uniform(0.4, 0.7), min_s=1.0)
        script.hold(rng.uniform(10.0, 25.0))
        kind = pattern[i % len(pattern)]
        i += 1
        if kind == "stop":
            stop_s = rng.uniform(5.0, 15.0)
            while _overlaps(script.t_s, script.t_s + 3.0 + stop_s, guards):
                script.hold(1.0)
            script.speed_to(0.0, rng.uniform(0.5, 0.8), min_s=1.0)
            script.hold(stop_s)
        else:
            # a corner taken at walking pace: ~0.8 rad/s, a radius of 1-2 m
            angle = 0.5 * np.pi if kind == "left" else -0.5 * np.pi
            script.turn(angle, rng.uniform(0.6, 1.0), ramp_s=rng.uniform(0.4, 0.7))


@_scenario(
    "bicycle",
    "20 s static, then riding 3-7 m/s in town: leaning into 90-degree turns, stops of 5-15 s at "
    "crossings, the frame's pedalling sway; a 10 s GNSS outage",
    300.0,
    ((150.0, 10.0),),
)
def bicycle(duration_s, seed, outages):
    rng, road_rng = _streams(seed)
    script = DriveScript(rng.uniform(-np.pi, np.pi))
    script.add_road(
        road_rng,
        length_m=7.0 * duration_s,
        grade_max_rad=np.arctan(0.03),
        bank_max_rad=np.deg2rad(0.5),
        spacing_m=(50.0, 200.0),
        transition_m=(20.0, 50.0),
    )
    script.PITCH_PER_ACCEL = 0.0
    # a bicycle leans into a turn until gravity balances the lateral acceleration:
    # tan(lean) = v r / g, to first order (a car's body rolls the other way)
    script.ROLL_PER_ACCEL = -1.0 / 9.81
    deg = np.deg2rad
    script.sway = Sway(
        step_hz=rng.uniform(2.2, 2.8),  # two pedal strokes per crank turn at 66-84 rpm
        v_ref_m_s=5.0,
        amplitudes={"surge": 0.01, "lateral": 0.01, "yaw": deg(1.0), "roll": deg(1.5)},
        phases=_phases(rng),
    )
    script.antenna_b_m = (0.0, 0.2, 0.3)  # board and antenna in a bag on the frame
    script.hold(20.0)
    guards = [(s - 3.0, s + length + 3.0) for s, length in outages]
    pattern = ("left", "stop", "right", "left", "stop", "right")
    i = 0
    while script.t_s < duration_s:
        script.speed_to(rng.uniform(3.0, 7.0), rng.uniform(0.5, 1.0), min_s=1.0)
        script.hold(rng.uniform(8.0, 25.0))
        kind = pattern[i % len(pattern)]
        i += 1
        if kind == "stop":
            brake = rng.uniform(1.0, 2.0)
            brake_s = script.v_m_s / brake
            stop_s = rng.uniform(5.0, 15.0)
            while _overlaps(script.t_s + brake_s, script.t_s + brake_s + stop_s, guards):
                script.hold(1.0)
            script.speed_to(0.0, brake)
            script.hold(stop_s)
        else:
            v_turn = rng.uniform(2.5, 4.0)
            angle = 0.5 * np.pi if kind == "left" else -0.5 * np.pi
            script.speed_to(v_turn, rng.uniform(1.0, 1.5), min_s=1.0)
            script.turn(angle, v_turn / rng.uniform(5.0, 10.0), ramp_s=rng.uniform(1.0, 1.5))
    return script
