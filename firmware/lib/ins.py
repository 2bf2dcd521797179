"""Strapdown inertial mechanization in float32 (docs/requirements.md: strapdown INS and
attitude, INS background).

Frame: the navigation frame n is the local tangent plane (ENU) at the navigator's integer
origin (see geo.py). It is fixed to the Earth and does not move with the vehicle, so there is
no transport rate: the equations are those of an Earth-fixed Cartesian frame,
    q_bn' = 1/2 q_bn (x) w_ib_b  -  1/2 w_ie_n (x) q_bn
    v_n'  = C_bn f_b - 2 w_ie_n x v_n + g_n(p_n)
    p_n'  = v_n
with g_n the normal gravity (Somigliana at the origin latitude, free-air term with height),
pointing at the Earth's centre, so it tilts by E/(R_N+h), N/(R_M+h) away from the origin.
`earth_terms=False` drops Earth rate, Coriolis and the tilt (gravity straight down, constant
magnitude): the board's simple model. The navigator re-anchors the origin within a couple of
kilometres (`shift_origin`), where the tangent plane and the local level differ by < 0.02 deg.

Each tick (`step`, dt fixed): bias-compensated increments theta = (w - b_g) dt and
dv = (f - b_a) dt; optionally the two-sample coning correction theta += theta_prev x theta / 12
and sculling dv += (theta_prev x dv + dv_prev x theta) / 12; the rotation correction
dv += theta x dv / 2; then v += C_bn(k-1) dv + a_n dt, the attitude update of seed eq. 5-17, and
a trapezoidal position step summed with Kahan compensation (float32 metres keep mm resolution at
km ranges, and the compensation stops 5 ms steps from rounding the same way every tick).
The slow terms (Earth rate on the attitude, Coriolis, gravity) are refreshed by `slow_update`
every few hundred milliseconds: they change slowly and cost too much per tick.

Units: rad, rad/s, m, m/s, m/s^2. Buffers are public and owned here.
"""

from micropython import const

import f32
import geo
import kern
import rot
from fmath import sqrt

OMEGA_E = f32.from_bits(0x3898ED3F)  # 7.292115e-5 rad/s, WGS-84 Earth rate
GAMMA_E = f32.from_bits(0x411C7C36)  # 9.7803253359 m/s^2, normal gravity at the equator
SOMIGLIANA_K = f32.from_bits(0x3AFD3638)  # 0.00193185265241
FREE_AIR = f32.from_bits(0x364F1914)  # 3.086e-6 (m/s^2)/m
TWELFTH = f32.ratio(1, 12)

# The state buffer `Ins.x` (one buffer, so a native kernel takes it as one argument; the
# public names are views of it). firmware/native/navk.c repeats these offsets (X_*).
X_P = const(0)  # p_n (3): position of the IMU, m, from the origin
X_V = const(3)  # v_n (3), m/s
X_Q = const(6)  # q_bn (4)
X_C = const(10)  # c_bn (9)
X_BG = const(19)  # bg (3): gyro bias estimate, rad/s
X_BA = const(22)  # ba (3): accelerometer bias estimate, m/s^2
X_DVS = const(25)  # dvn_sum (3): sum of C_bn dv since `take_dvn` (specific force x time)
X_AN = const(28)  # a_n (3): gravity + Coriolis, m/s^2, refreshed by slow_update
X_WIE = const(31)  # w_ie_n (3): Earth rate in n, rad/s
X_PK = const(34)  # Kahan compensation of p_n (3)
X_TH = const(37)  # this tick's rotation vector (3)
X_THP = const(40)  # the previous tick's rotation vector (3, coning)
X_DVP = const(43)  # the previous tick's velocity increment (3, sculling)
X_DT = const(46)  # tick, s
X_HDT = const(47)  # tick / 2
X_G0 = const(48)  # normal gravity at the origin, m/s^2
X_INV_RN = const(49)
X_INV_RM = const(50)
X_H0 = const(51)
NX = const(52)


class Ins:
    """Nominal navigation state and its mechanization."""

    def __init__(self, dt_s, earth_terms=True, coning=True, x=None):
        """x: the NX-float state buffer to use (a view into a larger one), or None for a new."""
        if x is None:
            x = f32.zeros(NX)
        self.x = x
        x[X_DT] = f32.f32(dt_s)
        x[X_HDT] = x[X_DT] * 0.5
        self.earth_terms = earth_terms
        self.coning = 1 if coning else 0  # an int: the kernel's argument
        self.p_n = f32.view(x, X_P, 3)
        self.v_n = f32.view(x, X_V, 3)
        self.q_bn = f32.view(x, X_Q, 4)
        self.c_bn = f32.view(x, X_C, 9)
        self.bg = f32.view(x, X_BG, 3)
        self.ba = f32.view(x, X_BA, 3)
        self.dvn_sum = f32.view(x, X_DVS, 3)
        self.a_n = f32.view(x, X_AN, 3)
        self.w_ie_n = f32.view(x, X_WIE, 3)
        self._pk = f32.view(x, X_PK, 3)
        self._th_prev = f32.view(x, X_THP, 3)
        self._dv_prev = f32.view(x, X_DVP, 3)
        self._tmp4 = f32.zeros(4)
        self._tmp4b = f32.zeros(4)
        rot.q_identity(self.q_bn)
        rot.q_to_dcm(self.c_bn, self.q_bn)

    def set_frame(self, frame):
        """Take the Earth model of a geo.LocalFrame origin (at start and after re-anchoring)."""
        c = frame.coef
        s = c[geo.SIN_LAT]
        co = c[geo.COS_LAT]
        s2 = s * s
        x = self.x
        x[X_G0] = GAMMA_E * (1.0 + SOMIGLIANA_K * s2) / sqrt(1.0 - geo.E2 * s2)
        x[X_INV_RN] = c[geo.INV_RN]
        x[X_INV_RM] = c[geo.INV_RM]
        x[X_H0] = c[geo.H0]
        w = self.w_ie_n
        w[0] = 0.0
        if self.earth_terms:
            w[1] = OMEGA_E * co
            w[2] = OMEGA_E * s
        else:
            w[1] = 0.0
            w[2] = 0.0
        self.slow_update(f32.f32(0))

    def reset_kinematics(self, p_n, v_n):
        """Set position and velocity (alignment, recovery); clears integration memory."""
        for i in range(3):
            self.p_n[i] = p_n[i]
            self.v_n[i] = v_n[i]
            self._pk[i] = 0.0
            self._th_prev[i] = 0.0
            self._dv_prev[i] = 0.0

    def clear_memory(self, i):
        """Forget the position sum's compensation of axis i (after that axis alone was set)."""
        self._pk[i] = 0.0

    def step(self, w_b, f_b):
        """Advance one tick with body rate w_b (rad/s) and specific force f_b (m/s^2)."""
        step(self.x, w_b, f_b, self.coning)

    def take_dvn(self, out):
        """out = the specific-force increment summed since the last call; restarts the sum."""
        s = self.dvn_sum
        for i in range(3):
            out[i] = s[i]
            s[i] = 0.0

    def slow_update(self, t_s):
        """Earth rate on the attitude over the last t_s seconds; then a_n = g_n - 2 w x v anew."""
        v = self.v_n
        p = self.p_n
        x = self.x
        g = x[X_G0] - FREE_AIR * (x[X_H0] + p[2])
        a = self.a_n
        if not self.earth_terms:
            a[0] = 0.0
            a[1] = 0.0
            a[2] = -g
            return
        w = self.w_ie_n
        if t_s > 0.0:
            # q <- q(-w_ie t) (x) q: the navigation frame turns with the Earth
            r = self._tmp4b
            r[0] = 1.0
            r[1] = 0.0
            r[2] = -(w[1] * t_s) * 0.5
            r[3] = -(w[2] * t_s) * 0.5
            q = self._tmp4
            q[0] = self.q_bn[0]
            q[1] = self.q_bn[1]
            q[2] = self.q_bn[2]
            q[3] = self.q_bn[3]
            rot.q_mul(self.q_bn, r, q)
            rot.q_normalize(self.q_bn)
            rot.q_to_dcm(self.c_bn, self.q_bn)
        wy2 = w[1] + w[1]
        wz2 = w[2] + w[2]
        # -2 w x v with w = (0, wy, wz)
        a[0] = -(g * p[0] * x[X_INV_RN]) - (wy2 * v[2] - wz2 * v[1])
        a[1] = -(g * p[1] * x[X_INV_RM]) - wz2 * v[0]
        a[2] = wy2 * v[0] - g

    def shift_origin(self, dp_n, rho_n):
        """Re-express the state in a new tangent frame: the old frame's point dp_n is the new
        origin and the frames differ by the small rotation rho_n (rad, old -> new: x_new =
        x_old - rho x x_old)."""
        p = self.p_n
        v = self.v_n
        rx = rho_n[0]
        ry = rho_n[1]
        rz = rho_n[2]
        _rotate_small(p, p[0] - dp_n[0], p[1] - dp_n[1], p[2] - dp_n[2], rx, ry, rz)
        _rotate_small(v, v[0], v[1], v[2], rx, ry, rz)
        r = self._tmp4b
        r[0] = 1.0
        r[1] = -rx * 0.5
        r[2] = -ry * 0.5
        r[3] = -rz * 0.5
        q = self._tmp4
        for i in range(4):
            q[i] = self.q_bn[i]
        rot.q_mul(self.q_bn, r, q)
        rot.q_normalize(self.q_bn)
        rot.q_to_dcm(self.c_bn, self.q_bn)
        for i in range(3):
            self._pk[i] = 0.0


def _rotate_small(out, x, y, z, rx, ry, rz):
    """out = (x, y, z) - rho x (x, y, z) for a small rotation vector rho."""
    out[0] = x - (ry * z - rz * y)
    out[1] = y - (rz * x - rx * z)
    out[2] = z - (rx * y - ry * x)


def _step_py(x, w_b, f_b, coning):
    """The reference of navk_ins_step: one tick on the state buffer x (see Ins.step)."""
    dt = x[X_DT]
    tx = (w_b[0] - x[X_BG]) * dt
    ty = (w_b[1] - x[X_BG + 1]) * dt
    tz = (w_b[2] - x[X_BG + 2]) * dt
    dx = (f_b[0] - x[X_BA]) * dt
    dy = (f_b[1] - x[X_BA + 1]) * dt
    dz = (f_b[2] - x[X_BA + 2]) * dt
    if coning:
        px = x[X_THP]
        py = x[X_THP + 1]
        pz = x[X_THP + 2]
        qx = x[X_DVP]
        qy = x[X_DVP + 1]
        qz = x[X_DVP + 2]
        x[X_THP] = tx
        x[X_THP + 1] = ty
        x[X_THP + 2] = tz
        x[X_DVP] = dx
        x[X_DVP + 1] = dy
        x[X_DVP + 2] = dz
        # sculling with the uncorrected increments, then coning
        sx = ((py * dz - pz * dy) + (qy * tz - qz * ty)) * TWELFTH
        sy = ((pz * dx - px * dz) + (qz * tx - qx * tz)) * TWELFTH
        sz = ((px * dy - py * dx) + (qx * ty - qy * tx)) * TWELFTH
        cx = (py * tz - pz * ty) * TWELFTH
        cy = (pz * tx - px * tz) * TWELFTH
        cz = (px * ty - py * tx) * TWELFTH
        tx = tx + cx
        ty = ty + cy
        tz = tz + cz
        dx = dx + sx
        dy = dy + sy
        dz = dz + sz
    # rotation of the velocity increment within the tick
    ux = dx + (ty * dz - tz * dy) * 0.5
    uy = dy + (tz * dx - tx * dz) * 0.5
    uz = dz + (tx * dy - ty * dx) * 0.5
    ex = x[X_C] * ux + x[X_C + 1] * uy + x[X_C + 2] * uz
    ey = x[X_C + 3] * ux + x[X_C + 4] * uy + x[X_C + 5] * uz
    ez = x[X_C + 6] * ux + x[X_C + 7] * uy + x[X_C + 8] * uz
    x[X_DVS] = x[X_DVS] + ex
    x[X_DVS + 1] = x[X_DVS + 1] + ey
    x[X_DVS + 2] = x[X_DVS + 2] + ez
    x[X_TH] = tx
    x[X_TH + 1] = ty
    x[X_TH + 2] = tz
    # views made per call: the Python kernels allocate anyway (float results); native does not
    q = f32.view(x, X_Q, 4)
    rot.q_update(q, f32.view(x, X_TH, 3))
    rot.q_to_dcm(f32.view(x, X_C, 9), q)
    _advance(x, 0, ex)
    _advance(x, 1, ey)
    _advance(x, 2, ez)


def _advance(x, i, dv):
    """v[i] += dv + a[i] dt; p[i] += (v_old + v_new) dt/2, Kahan-compensated."""
    v0 = x[X_V + i]
    v1 = v0 + dv + x[X_AN + i] * x[X_DT]
    x[X_V + i] = v1
    y = (v0 + v1) * x[X_HDT] - x[X_PK + i]
    p0 = x[X_P + i]
    t = p0 + y
    x[X_PK + i] = (t - p0) - y
    x[X_P + i] = t


step = kern.pick("ins_step", _step_py)
