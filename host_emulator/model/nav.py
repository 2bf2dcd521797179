"""NumPy float32 model of the navigator: `firmware/lib/ins.py`, `eskf.py` and `nav.py`.

An independent implementation of the same equations, written at matrix level where the
firmware loops, that repeats every float32 operation of the firmware in the same order and
grouping. Fed the same inputs, its state equals the firmware's bit for bit after every tick
(`tests/reference/test_nav_model.py`): position, velocity, attitude, biases, the 15x15
covariance *between* the slices of the time-distributed filter, the state-history ring, the
standstill detector and every counter. Frames, units and sign conventions are the firmware's
(ENU navigation frame at an integer origin, body x right / y forward / z up, error state
dp dv phi dbg dba with nominal-minus-true errors); see the firmware modules.

How it stays bit-exact:
- every value is a `numpy.float32` scalar or array; Python floats only meet float32 operands
  (NumPy 2 turns `0.5 * x` into one float32 operation, like the board);
- elementwise array operations round each element exactly as the firmware's scalar statement,
  so a statement repeated over i = 0, 1, 2 becomes one vector expression; sums keep the
  firmware's left-to-right grouping, written out term by term (`_mat_vec`, `_cross`), never `@`;
- sums that start from `0.0` in the firmware start from a float32 zero here (0.0 + -0.0 = +0.0);
- where the firmware branches per element (diagonal clamping, the gate) the model branches too;
- sin, cos, atan2, asin, quaternion updates and the geodetic series come from the bit-exact
  models `reference/fmath.py`, `reference/rot.py` and `reference/geo.py`;
- constants are the firmware modules' own objects; the few the firmware builds inline (P floors
  and ceilings) are rebuilt from the same integer ratios.

Time distribution (eskf.py) is mirrored slice for slice: `work(n)` runs n slices per tick, the
same slices as the firmware, so the covariance matches between ticks, not only at job ends.
"""

import numpy as np

from host_emulator import firmware_env
from host_emulator.model import fmath as ref_fmath
from host_emulator.model import geo as ref_geo
from host_emulator.model import rot as ref_rot

firmware_env.install()
import eskf as fw_eskf  # noqa: E402  (constants and state indices, shared with the firmware)
import ins as fw_ins  # noqa: E402
import nav as fw_nav  # noqa: E402

import fmath as fw_fmath  # noqa: E402
import geo as fw_geo  # noqa: E402
import rot as fw_rot  # noqa: E402

F32 = np.float32
_ZERO = F32(0.0)
_HALF = F32(0.5)
_ONE = F32(1.0)
_TWO = F32(2.0)

N = fw_eskf.N
IX_POS = fw_eskf.IX_POS
IX_VEL = fw_eskf.IX_VEL
IX_ATT = fw_eskf.IX_ATT
IX_BG = fw_eskf.IX_BG
IX_BA = fw_eskf.IX_BA
IDLE = fw_eskf.IDLE
PROPAGATING = fw_eskf.PROPAGATING
UPDATING = fw_eskf.UPDATING

ALIGNING = fw_nav.ALIGNING
NAVIGATING = fw_nav.NAVIGATING
RING = fw_nav.RING
JOB_NONE = fw_nav._JOB_NONE
JOB_GNSS = fw_nav._JOB_GNSS
JOB_AID = fw_nav._JOB_AID


# ---- small float32 helpers ------------------------------------------------------------------


def _ratio(num, den):
    """num / den as one float32 division (the firmware's f32.ratio)."""
    return F32(num) / F32(den)


def _vec(*xs):
    return np.array(xs, dtype=F32)


def _cross(a, b):
    """a x b, component k = a_i b_j - a_j b_i as the firmware writes each cross product."""
    return _vec(a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _mat_vec(c, x):
    """C x for a 3x3 C, every row summed left to right: (c_i0 x0 + c_i1 x1) + c_i2 x2."""
    return (c[:, 0] * x[0] + c[:, 1] * x[1]) + c[:, 2] * x[2]


def _sum_left(xs):
    """x0 + x1 + ... evaluated left to right."""
    s = xs[0]
    for x in xs[1:]:
        s = s + x
    return s


def _ticks(seconds, dt):
    """Whole ticks in `seconds`: int(seconds / dt + 0.5), rounded in float32, truncated."""
    return int(F32(seconds) / dt + _HALF)


def _q_from_rotvec(theta):
    """[cos(|t|/2), sin(|t|/2) t/|t|] with rot.py's series below |t|^2 = 1/64 (no normalising)."""
    n2 = (theta[0] * theta[0] + theta[1] * theta[1]) + theta[2] * theta[2]
    if n2 < fw_rot._SERIES_MAX_N2:
        c = _ONE - n2 * (fw_rot._C8 - n2 * fw_rot._C384)
        s = _HALF - n2 * (fw_rot._C48 - n2 * fw_rot._C3840)
    else:
        n = np.sqrt(n2)
        h = _HALF * n
        c = ref_fmath.cos(h)
        s = ref_fmath.sin(h) / n
    return _vec(c, s * theta[0], s * theta[1], s * theta[2])


def _q_normalized(q):
    return ref_rot.q_normalize(q)[0]


# ---- strapdown mechanization (ins.py) -------------------------------------------------------


class InsModel:
    """Nominal state in the Earth-fixed ENU frame of the origin.

        q_bn' = 1/2 q_bn (x) w_ib_b - 1/2 w_ie_n (x) q_bn
        v_n'  = C_bn f_b - 2 w_ie_n x v_n + g_n(p_n)
        p_n'  = v_n
    per tick: theta = (w - b_g) dt, dv = (f - b_a) dt, optional two-sample coning/sculling,
    dv += theta x dv / 2, v += C_bn(k-1) dv + a_n dt, q <- q (x) q(theta), and the trapezoidal
    position step with Kahan compensation. a_n = g_n - 2 w_ie x v and the Earth rotation of
    the attitude are refreshed by `slow_update`.
    """

    def __init__(self, dt_s, earth_terms=True, coning=True):
        self.dt = F32(dt_s)
        self.half_dt = self.dt * _HALF
        self.earth_terms = earth_terms
        self.coning = coning
        self.p_n = np.zeros(3, F32)  # m
        self.v_n = np.zeros(3, F32)  # m/s
        self.q_bn = _vec(1, 0, 0, 0)
        self.c_bn = ref_rot.q_to_dcm(self.q_bn)  # (3, 3)
        self.bg = np.zeros(3, F32)  # rad/s
        self.ba = np.zeros(3, F32)  # m/s^2
        self.dvn_sum = np.zeros(3, F32)  # sum of C_bn dv since take_dvn, m/s
        self.a_n = np.zeros(3, F32)  # gravity + Coriolis, m/s^2
        self.w_ie_n = np.zeros(3, F32)  # Earth rate, rad/s
        self.p_comp = np.zeros(3, F32)  # Kahan compensation of p_n
        self.theta_prev = np.zeros(3, F32)
        self.dv_prev = np.zeros(3, F32)
        self.g0 = _ZERO  # normal gravity at the origin
        self.inv_rn = _ZERO
        self.inv_rm = _ZERO
        self.h0 = _ZERO

    def set_frame(self, coef):
        """Earth model of the origin: g0 = gamma_e (1 + k sin^2 L) / sqrt(1 - e^2 sin^2 L)."""
        s = coef[fw_geo.SIN_LAT]
        co = coef[fw_geo.COS_LAT]
        s2 = s * s
        self.g0 = (
            fw_ins._GAMMA_E * (_ONE + fw_ins._SOMIGLIANA_K * s2) / np.sqrt(_ONE - fw_geo.E2 * s2)
        )
        self.inv_rn = coef[fw_geo.INV_RN]
        self.inv_rm = coef[fw_geo.INV_RM]
        self.h0 = coef[fw_geo.H0]
        if self.earth_terms:
            self.w_ie_n = _vec(0, fw_ins.OMEGA_E * co, fw_ins.OMEGA_E * s)
        else:
            self.w_ie_n = _vec(0, 0, 0)
        self.slow_update(_ZERO)

    def reset_kinematics(self, p_n, v_n):
        self.p_n = np.array(p_n, F32)
        self.v_n = np.array(v_n, F32)
        self.p_comp = np.zeros(3, F32)
        self.theta_prev = np.zeros(3, F32)
        self.dv_prev = np.zeros(3, F32)

    def step(self, w_b, f_b):
        """One tick with body rate w_b (rad/s) and specific force f_b (m/s^2)."""
        theta = (w_b - self.bg) * self.dt
        dv = (f_b - self.ba) * self.dt
        if self.coning:
            th_prev, dv_prev = self.theta_prev, self.dv_prev
            self.theta_prev, self.dv_prev = theta, dv
            # sculling (th_prev x dv + dv_prev x theta) / 12 and coning th_prev x theta / 12,
            # both from the uncorrected increments
            scull = (_cross(th_prev, dv) + _cross(dv_prev, theta)) * fw_ins._TWELFTH
            cone = _cross(th_prev, theta) * fw_ins._TWELFTH
            theta = theta + cone
            dv = dv + scull
        u = dv + _cross(theta, dv) * _HALF  # rotation of dv within the tick
        dv_n = _mat_vec(self.c_bn, u)  # with C_bn of the previous tick
        self.dvn_sum = self.dvn_sum + dv_n
        self.q_bn = ref_rot.q_update(self.q_bn, theta)[0]
        self.c_bn = ref_rot.q_to_dcm(self.q_bn)
        # v1 = v0 + dv_n + a_n dt; p += (v0 + v1) dt/2, Kahan-compensated
        v0 = self.v_n
        v1 = (v0 + dv_n) + self.a_n * self.dt
        self.v_n = v1
        y = (v0 + v1) * self.half_dt - self.p_comp
        t = self.p_n + y
        self.p_comp = (t - self.p_n) - y
        self.p_n = t

    def take_dvn(self):
        out = self.dvn_sum
        self.dvn_sum = np.zeros(3, F32)
        return out

    def slow_update(self, t_s):
        """Earth rate on the attitude over t_s (q <- q(-w_ie t) (x) q), then
        a_n = -g [E/(R_N+h), N/(R_M+h), 1] - 2 w_ie x v with w_ie = (0, wy, wz)."""
        p, v = self.p_n, self.v_n
        g = self.g0 - fw_ins._FREE_AIR * (self.h0 + p[2])
        if not self.earth_terms:
            self.a_n = _vec(0, 0, -g)
            return
        w = self.w_ie_n
        if t_s > 0.0:
            r = _vec(1, 0, -(w[1] * t_s) * _HALF, -(w[2] * t_s) * _HALF)
            self.q_bn = _q_normalized(ref_rot.q_mul(r, self.q_bn))
            self.c_bn = ref_rot.q_to_dcm(self.q_bn)
        wy2 = w[1] + w[1]
        wz2 = w[2] + w[2]
        self.a_n = _vec(
            -(g * p[0] * self.inv_rn) - (wy2 * v[2] - wz2 * v[1]),
            -(g * p[1] * self.inv_rm) - wz2 * v[0],
            wy2 * v[0] - g,
        )

    def shift_origin(self, dp_n, rho_n):
        """Re-express the state in the frame whose origin is the old frame's dp_n, rotated by
        the small rho_n: x_new = x_old - rho x x_old, q_new = q(-rho) (x) q_old."""
        p = self.p_n - dp_n
        self.p_n = p - _cross(rho_n, p)
        self.v_n = self.v_n - _cross(rho_n, self.v_n)
        r = _vec(1, -rho_n[0] * _HALF, -rho_n[1] * _HALF, -rho_n[2] * _HALF)
        self.q_bn = _q_normalized(ref_rot.q_mul(r, self.q_bn))
        self.c_bn = ref_rot.q_to_dcm(self.q_bn)
        self.p_comp = np.zeros(3, F32)


# ---- 15-state error-state Kalman filter (eskf.py) -------------------------------------------


class EskfModel:
    """Error state x = [dp, dv, phi, dbg, dba] (15), covariance P (15x15), time-distributed.

    Propagation P <- Phi P Phi^T + Q T with Phi = I + F T (F of seed 001 eq. 5-28 plus the
    Earth-rate terms), as 15 column slices A[:, j] = Phi P[j, :] (P symmetric), 15 row slices
    P[i, i:] = P[i:, i] = (Phi A[i, :])[i:], and one slice adding Q T and clamping the diagonal.
    Update: per scalar z = h x + noise(r), 3 slices of v = P h^T (5 rows each), one slice for
    S = h v + r, the gate y^2 <= gate^2 S and K = v / S, x += K y, then 15 Joseph rows
    P[i, i:] = P[i, i:] - K_i v[i:] - v_i K[i:] + S K_i K[i:]; a last slice clamps the
    diagonal and raises `ready`.
    """

    def __init__(self, earth_terms=True):
        self.earth_terms = earth_terms
        self.P = np.zeros((N, N), F32)
        self.dx = np.zeros(N, F32)
        self.q_psd = np.zeros(N, F32)
        self.p_floor = np.zeros(N, F32)
        self.p_ceiling = np.zeros(N, F32)
        self.A = np.zeros((N, N), F32)  # Phi P, built column by column
        self.v = np.zeros(N, F32)  # P h^T of the current scalar
        self.K = np.zeros(N, F32)  # gain of the last accepted scalar
        self.f_n = np.zeros(3, F32)  # mean specific force over T
        self.c_bn = np.zeros((3, 3), F32)
        self.w_ie_n = np.zeros(3, F32)
        self.T = _ZERO
        self.decay_g = _ZERO  # 1 - T / tau_g
        self.decay_a = _ZERO
        self.S = _ZERO
        self.Y = _ZERO
        self.gate2 = _ZERO
        self.inv_tau_g = _ZERO
        self.inv_tau_a = _ZERO
        self.scalars = []  # queued (z, r, [(k, h_k), ...]) in the firmware's non-zero order
        self.job = IDLE
        self.step = 0
        self.m = 0
        self.ready = False
        self.accepted = 0
        self.rejected = 0
        self.gate_mask = 0

    def set_gate(self, gate_sigma, inv_tau_g, inv_tau_a):
        self.gate2 = gate_sigma * gate_sigma
        self.inv_tau_g = inv_tau_g
        self.inv_tau_a = inv_tau_a

    def reset_p(self, diag):
        self.P = np.zeros((N, N), F32)
        self.P[np.arange(N), np.arange(N)] = diag
        self.dx = np.zeros(N, F32)
        self.job = IDLE
        self.ready = False
        self.scalars = []

    # propagation

    def start_propagation(self, dvn_sum, t_s, c_bn, w_ie_n):
        self.T = t_s
        self.decay_g = _ONE - t_s * self.inv_tau_g
        self.decay_a = _ONE - t_s * self.inv_tau_a
        self.f_n = dvn_sum / t_s
        self.w_ie_n = np.array(w_ie_n, F32)
        self.c_bn = np.array(c_bn, F32)
        self.job = PROPAGATING
        self.step = 0

    def phi_apply(self, x):
        """Phi x for a 15-vector x: F's non-zero blocks
            dp'  = dv
            dv'  = f_n x phi + C_bn dba - 2 w_ie x dv
            phi' = -C_bn dbg - w_ie x phi
            db'  = -db / tau
        with w_ie = (0, w1, w2), so the Earth-rate products keep only their non-zero terms."""
        t = self.T
        dpos, dvel, att = x[0:3], x[3:6], x[6:9]
        dbg, dba = x[9:12], x[12:15]
        c = self.c_bn
        dv_rate = _cross(self.f_n, att) + _mat_vec(c, dba)
        att_rate = _mat_vec(c, dbg)  # negated below
        if self.earth_terms:
            w1, w2 = self.w_ie_n[1], self.w_ie_n[2]
            dv_rate = _vec(
                dv_rate[0] - _TWO * (w1 * dvel[2] - w2 * dvel[1]),
                dv_rate[1] - _TWO * (w2 * dvel[0]),
                dv_rate[2] + _TWO * (w1 * dvel[0]),
            )
            att_rate = _vec(
                att_rate[0] + (w1 * att[2] - w2 * att[1]),
                att_rate[1] + w2 * att[0],
                att_rate[2] - w1 * att[0],
            )
        return np.concatenate(
            [
                dpos + t * dvel,
                dvel + t * dv_rate,
                att - t * att_rate,
                self.decay_g * dbg,
                self.decay_a * dba,
            ]
        )

    def _propagation_slice(self):
        st = self.step
        if st < N:
            self.A[:, st] = self.phi_apply(self.P[st, :])  # column st of Phi P
        elif st < 2 * N:
            i = st - N
            row = self.phi_apply(self.A[i, :])[i:]  # row i of (Phi P) Phi^T, upper part
            self.P[i, i:] = row
            self.P[i:, i] = row
        else:
            d = np.arange(N)
            self.P[d, d] = self.P[d, d] + self.q_psd * self.T
            self._clamp_diagonal()
            self.job = IDLE
        self.step = st + 1

    # measurement update

    def add_scalar(self, z, r, terms):
        """Queue z = h x + noise of variance r; terms = [(k, h_k), ...] in the firmware's order
        (a repeated k would read the last h_k stored, as the firmware's h row does)."""
        h = dict(terms)
        self.scalars.append((z, r, [(k, h[k]) for k, _ in terms]))

    def start_update(self):
        self.job = UPDATING
        self.step = 0
        self.m = 0
        self.accepted = 0
        self.rejected = 0
        self.gate_mask = 0

    def _update_slice(self):
        m = self.m
        if m >= len(self.scalars):
            self._clamp_diagonal()
            self.scalars = []
            self.job = IDLE
            self.ready = True
            return
        z, r, terms = self.scalars[m]
        st = self.step
        if st < 3:
            rows = slice(5 * st, 5 * st + 5)
            acc = np.zeros(5, F32)
            for k, hk in terms:
                acc = acc + self.P[rows, k] * hk
            self.v[rows] = acc
            self.step = st + 1
            return
        if st == 3:
            hv = _ZERO
            hx = _ZERO
            for k, hk in terms:
                hv = hv + hk * self.v[k]
                hx = hx + hk * self.dx[k]
            s = hv + r
            y = z - hx
            if not (s > 0.0) or y * y > self.gate2 * s:
                self.rejected += 1
                self.gate_mask |= 1 << m
                self.m = m + 1
                self.step = 0
                return
            self.S = s
            self.Y = y
            self.K = self.v / s
            self.dx = self.dx + self.K * y
            self.accepted += 1
            self.step = 4
            return
        # Joseph form P - K v^T - v K^T + S K K^T, row i, upper triangle mirrored
        i = st - 4
        k, v = self.K, self.v
        ki = k[i]
        row = ((self.P[i, i:] - ki * v[i:]) - v[i] * k[i:]) + (self.S * ki) * k[i:]
        self.P[i, i:] = row
        self.P[i:, i] = row
        if i == N - 1:
            self.m = m + 1
            self.step = 0
        else:
            self.step = st + 1

    # common

    def work(self, n):
        while n > 0 and self.job != IDLE:
            if self.job == PROPAGATING:
                self._propagation_slice()
            else:
                self._update_slice()
            n -= 1

    def _clamp_diagonal(self):
        """Floor each variance; a variance d above its ceiling scales row and column i by
        sqrt(ceiling / d) (the diagonal element twice), in index order."""
        P = self.P
        for i in range(N):
            d = P[i, i]
            if d < self.p_floor[i]:
                P[i, i] = self.p_floor[i]
            elif d > self.p_ceiling[i]:
                g = np.sqrt(self.p_ceiling[i] / d)
                P[i, :] = P[i, :] * g
                P[:, i] = P[:, i] * g

    def diagonal_ok(self):
        d = np.diagonal(self.P)
        return bool(np.all(d > 0.0) and np.all(d - d == 0.0))


# ---- the navigator (nav.py) -----------------------------------------------------------------


class NavModel:
    """Alignment, mechanization, filter scheduling, GNSS/ZUPT/NHC updates, injection, health
    and re-anchoring, tick by tick like `nav.Navigator` (same inputs: `imu_raw`/`imu`, `gnss`).
    """

    def __init__(self, cfg):
        self.cfg = cfg
        dt = cfg.dt_s
        self.ins = InsModel(dt, cfg.earth_terms, cfg.coning)
        self.kf = EskfModel(cfg.earth_terms)
        # the integer origin and its float32 coefficients (geo.LocalFrame)
        self.origin_lat_e7 = 0
        self.origin_lon_e7 = 0
        self.frame_valid = False
        self.coef = np.zeros(fw_geo._NCOEF, F32)
        self.state = ALIGNING
        self.health = 0
        self.tick = 0
        self.ypr = np.zeros(3, F32)
        self.w_b = np.zeros(3, F32)  # calibrated body rate, rad/s
        self.f_b = np.zeros(3, F32)  # calibrated specific force, m/s^2
        self.ring_p = np.zeros((RING, 3), F32)  # p_n - corrections, per tick % RING
        self.ring_v = np.zeros((RING, 3), F32)
        self.corr = np.zeros(6, F32)  # injected corrections of p and v since the last reset
        self.gnss_p = np.zeros(3, F32)  # antenna position of the fix in the frame, m
        # the pending fix: height, HDOP, speed, course, sigma_h, sigma_v
        self.fix = np.zeros(6, F32)
        # the fix of the running GNSS update: antenna position (3), speed, course, sigma_h,
        # sigma_v (a reset to GNSS needs it after newer fixes have arrived)
        self.used = np.zeros(7, F32)
        # standstill detector: low-passed f (3), low-passed |df|^2, low-passed |w - b_g|^2
        # and the speed of the last usable fix
        self.still_lp = np.zeros(6, F32)
        self.level_sums = np.zeros(6, F32)  # sums of f and w while levelling
        self.init_diag = np.zeros(N, F32)
        # the track anchor (heading without a receiver course): antenna E, N of the anchor fix
        # and the yaw of the attitude when it was processed
        self.track = np.zeros(3, F32)
        self.ticks_prop = _ticks(cfg.prop_period_s, dt)
        self.ticks_zupt = _ticks(cfg.zupt_period_s, dt)
        self.ticks_nhc = _ticks(cfg.nhc_period_s, dt)
        self.ticks_level = _ticks(cfg.level_s, dt)
        self.ticks_still = _ticks(cfg.still_s, dt)
        self.ticks_timeout = _ticks(cfg.gnss_timeout_s, dt)
        self.ticks_latency = _ticks(cfg.gnss_latency_s, dt)
        self.ticks_second = _ticks(F32(1), dt)
        self.ticks_track = max(_ticks(cfg.track_s, dt), 1)
        self._set_noise(cfg)
        self._reset_counters()

    def _set_noise(self, cfg):
        """Q per second: velocity VRW^2, attitude ARW^2, biases 2 sigma^2 / tau (first-order
        Gauss-Markov); P floors and ceilings; the initial diagonal (its position part is set
        from the fix when navigation starts); the gate and 1/tau."""
        kf = self.kf
        vrw2 = cfg.accel_vrw * cfg.accel_vrw
        arw2 = cfg.gyro_arw * cfg.gyro_arw
        qbg = _TWO * cfg.gyro_bias_sigma * cfg.gyro_bias_sigma / cfg.gyro_bias_tau_s
        qba = _TWO * cfg.accel_bias_sigma * cfg.accel_bias_sigma / cfg.accel_bias_tau_s
        # per block of three: position, velocity, attitude, gyro bias, accelerometer bias
        kf.q_psd = np.repeat(_vec(0, vrw2, arw2, qbg, qba), 3)
        kf.p_floor = np.repeat(
            _vec(
                _ratio(1, 10000),  # (1 cm)^2
                _ratio(1, 1000000),  # (1 mm/s)^2
                _ratio(1, 100000000),  # (0.1 mrad)^2
                _ratio(1, 1000000) * _ratio(1, 1000000),  # (1e-6 rad/s)^2
                _ratio(1, 100000000),  # (1e-4 m/s^2)^2
            ),
            3,
        )
        kf.p_ceiling = np.repeat(_vec(100000000, 10000, 10, _ratio(1, 100), 1), 3)
        ini = self.init_diag
        ini[IX_VEL : IX_VEL + 3] = cfg.init_vel_sigma * cfg.init_vel_sigma
        ini[IX_BG : IX_BG + 3] = cfg.init_gyro_bias_sigma * cfg.init_gyro_bias_sigma
        ini[IX_BA : IX_BA + 3] = cfg.init_accel_bias_sigma * cfg.init_accel_bias_sigma
        tilt2 = cfg.init_tilt_sigma * cfg.init_tilt_sigma
        ini[IX_ATT] = tilt2
        ini[IX_ATT + 1] = tilt2
        ini[IX_ATT + 2] = cfg.init_yaw_sigma * cfg.init_yaw_sigma
        kf.set_gate(cfg.gate_sigma, _ONE / cfg.gyro_bias_tau_s, _ONE / cfg.accel_bias_tau_s)

    def _reset_counters(self):
        self.leveled = False
        self.still = False
        self.n_level = 0
        self.n_still = 0
        self.n_stable = 0
        self.fix_pending = False  # arrived, not screened
        self.fix_queued = False  # usable, waiting for the filter
        self.used_tick = 0
        self.fix_lat_e7 = 0
        self.fix_lon_e7 = 0
        self.fix_quality = 0
        self.fix_tick = 0
        self.last_fix_tick = -1000000
        self.speed_tick = -1000000  # tick of the last usable fix with a speed
        self.trk_set = False  # a track anchor is held
        self.trk_tick = 0  # its measurement tick
        self.last_accept_tick = 0
        self.rejects = 0
        self.gated_until = 0
        self.fault_until = 0
        self.sat_until = 0
        self.since_prop = 0
        self.since_zupt = 0
        self.since_nhc = 0
        self.job = JOB_NONE
        self.updates = 0  # GNSS updates run
        self.resets = 0  # resets to GNSS and fault resets
        self.reanchors = 0  # origin moves

    # ---- frame (geo.LocalFrame) ----

    def _set_origin(self, lat_e7, lon_e7, h_m):
        if lat_e7 > fw_geo._MAX_LAT_E7 or lat_e7 < -fw_geo._MAX_LAT_E7:
            return False
        self.coef = ref_geo.coefficients(lat_e7, h_m)
        self.origin_lat_e7 = lat_e7
        self.origin_lon_e7 = lon_e7
        self.frame_valid = True
        return True

    def _to_enu(self, lat_e7, lon_e7, h_m):
        dlon = lon_e7 - self.origin_lon_e7
        if dlon > fw_geo._HALF_TURN_E7:
            dlon -= fw_geo._FULL_TURN_E7
        elif dlon < -fw_geo._HALF_TURN_E7:
            dlon += fw_geo._FULL_TURN_E7
        return ref_geo.offset_to_enu(self.coef, lat_e7 - self.origin_lat_e7, dlon, h_m)

    # ---- inputs ----

    def imu_raw(self, gyro_counts, accel_counts, saturated=False):
        w = np.asarray(gyro_counts, dtype=F32) / self.cfg.gyro_counts_per_rad_s
        f = np.asarray(accel_counts, dtype=F32) / self.cfg.accel_counts_per_m_s2
        self.imu(w, f, saturated)

    def imu(self, w_in, f_in, saturated=False):
        self.tick += 1
        if saturated:
            self.sat_until = self.tick + self.ticks_second
        if not self._calibrate(w_in, f_in):
            self.fault_until = self.tick + self.ticks_second
            self._update_health()
            return
        if self.tick & 3 == 0:
            self._still_update()
        if self.state == NAVIGATING:
            self._navigate()
        else:
            self._align()
        self._update_health()

    def gnss(
        self,
        lat_e7,
        lon_e7,
        h_m,
        quality,
        hdop,
        speed_m_s,
        course_rad,
        fix_tick=-1,
        sigma_h_m=0.0,
        sigma_v_m=0.0,
    ):
        self.fix_lat_e7 = lat_e7
        self.fix_lon_e7 = lon_e7
        self.fix_quality = quality
        if fix_tick < 0:
            fix_tick = self.tick - self.ticks_latency
        self.fix_tick = fix_tick
        self.fix = np.array([h_m, hdop, speed_m_s, course_rad, sigma_h_m, sigma_v_m], F32)
        self.fix_pending = True

    # ---- per tick ----

    def _calibrate(self, w_in, f_in):
        """x_b = M (x_raw - b0) (M None: identity); False if anything is not finite."""
        cfg = self.cfg
        self.w_b = _apply_cal(w_in, cfg.gyro_bias0, cfg.gyro_matrix)
        self.f_b = _apply_cal(f_in, cfg.accel_bias0, cfg.accel_matrix)
        s = _sum_left([*self.w_b, *self.f_b])
        return s - s == 0.0

    def _still_update(self):
        """Every 4th tick: low-pass (weight 1/8) of f, of |f - f_lp|^2 and of |w - b_g|^2;
        quiet when both are below their thresholds and the speed agrees (a recent fix's, else the
        INS's);
        still after `still_s` of quiet."""
        cfg = self.cfg
        lp = self.still_lp
        alpha = fw_nav._STILL_ALPHA
        if self.tick == 4:
            lp[0:3] = self.f_b
        d = self.f_b - lp[0:3]
        lp[0:3] = lp[0:3] + alpha * d
        var = _sum_left([_ZERO, d[0] * d[0], d[1] * d[1], d[2] * d[2]])
        lp[3] = lp[3] + alpha * (var - lp[3])
        w = self.w_b - self.ins.bg
        lp[4] = lp[4] + alpha * (((w[0] * w[0] + w[1] * w[1]) + w[2] * w[2]) - lp[4])
        quiet = (
            lp[3] < cfg.still_accel * cfg.still_accel and lp[4] < cfg.still_gyro * cfg.still_gyro
        )
        if quiet:
            if self.tick - self.speed_tick < self.ticks_second:  # a recent usable fix's speed
                if lp[5] > cfg.still_gnss_speed:
                    quiet = False
            elif self.state == NAVIGATING:  # else the navigator's own
                v = self.ins.v_n
                if v[0] * v[0] + v[1] * v[1] > cfg.still_max_speed * cfg.still_max_speed:
                    quiet = False
        self.n_still = self.n_still + 4 if quiet else 0
        self.still = self.n_still >= self.ticks_still

    def _align(self):
        ins = self.ins
        if self.still or not self.leveled:
            self.level_sums[0:3] = self.level_sums[0:3] + self.f_b
            self.level_sums[3:6] = self.level_sums[3:6] + self.w_b
            self.n_level += 1
            if self.n_level >= self.ticks_level:
                self._level()
        if self.leveled and not self.still:
            # keep roll and pitch current while waiting for a heading
            theta = (self.w_b - ins.bg) * self.cfg.dt_s
            ins.q_bn = ref_rot.q_update(ins.q_bn, theta)[0]
            ins.c_bn = ref_rot.q_to_dcm(ins.q_bn)
        if self.fix_pending:
            self.fix_pending = False
            self._align_fix()

    def _level(self):
        """pitch = asin(f_y / |f|), roll = atan2(-f_x, f_z) from the mean specific force, yaw
        kept; b_g = mean rate if still."""
        ins = self.ins
        n = F32(self.n_level)
        f_mean = self.level_sums[0:3] / n
        fx, fy, fz = f_mean
        g = np.sqrt((fx * fx + fy * fy) + fz * fz)
        if not g > fw_nav._MIN_LEVEL_F:  # no gravity to level on: start over
            self.level_sums = np.zeros(6, F32)
            self.n_level = 0
            return
        ypr = ref_rot.dcm_to_euler(ins.c_bn)
        ypr[fw_rot.PITCH] = ref_fmath.asin(fy / g)
        ypr[fw_rot.ROLL] = ref_fmath.atan2(-fx, fz)
        self.ypr = ypr
        ins.q_bn = ref_rot.euler_to_q(ypr)
        ins.c_bn = ref_rot.q_to_dcm(ins.q_bn)
        if self.still:
            ins.bg = self.level_sums[3:6] / n
        self.level_sums = np.zeros(6, F32)
        self.n_level = 0
        self.leveled = True

    def _fix_usable(self):
        """Quality and HDOP acceptable; remembers a usable fix's speed for standstill, unless
        the speed is unknown (< 0 or NaN)."""
        cfg = self.cfg
        if self.fix_quality >= cfg.gnss_min_quality and self.fix[1] <= cfg.gnss_hdop_max:
            if self.fix[2] >= 0.0:
                self.still_lp[5] = self.fix[2]
                self.speed_tick = self.tick
            return True
        return False

    def _align_fix(self):
        cfg = self.cfg
        self.last_fix_tick = self.tick
        if not self._fix_usable():
            self.n_stable = 0
            self.trk_set = False
            return
        self.n_stable += 1
        if self.n_stable < cfg.gnss_stable_fixes:
            return
        h = self.fix[0]
        if not self.frame_valid:
            if not self._set_origin(self.fix_lat_e7, self.fix_lon_e7, h):
                return
            self.ins.set_frame(self.coef)
        self.gnss_p = self._to_enu(self.fix_lat_e7, self.fix_lon_e7, h)
        self.ins.p_n = self.gnss_p.copy()
        if not self.leveled:
            self.trk_set = False
            return
        course = self.fix[3]
        if course >= 0.0:  # the receiver's course over ground
            self.trk_set = False
            if self.fix[2] >= cfg.heading_speed_m_s:
                self._start_navigation(course, self.fix[2], cfg.init_vel_sigma)
        else:
            self._track()

    def _track(self):
        """No course: the chord d = p - p_anchor over T = n dt (track_s <= T <= 2 track_s)
        gives the mean speed |d| / T and, from heading_speed_m_s on and for a yaw change
        |dyaw| <= track_turn_max (wrapped to +-pi), the course atan2(d_E, d_N) - dyaw / 2 now;
        otherwise this fix becomes the anchor."""
        cfg = self.cfg
        gp = self.gnss_p
        c = self.ins.c_bn
        yaw = ref_fmath.atan2(-c[0, 1], c[1, 1])  # dcm_to_euler's yaw
        if self.trk_set:
            n = self.fix_tick - self.trk_tick
            if n < self.ticks_track:
                return
            if n <= 2 * self.ticks_track:
                de = gp[0] - self.track[0]
                dn = gp[1] - self.track[1]
                sp = np.sqrt(de * de + dn * dn) / (F32(n) * cfg.dt_s)
                dyaw = yaw - self.track[2]
                if dyaw > fw_fmath.PI:
                    dyaw = dyaw - fw_fmath.TWO_PI
                elif dyaw < -fw_fmath.PI:
                    dyaw = dyaw + fw_fmath.TWO_PI
                lim = cfg.track_turn_max
                if sp >= cfg.heading_speed_m_s and -lim <= dyaw <= lim:
                    self.trk_set = False
                    course = ref_fmath.atan2(de, dn) - dyaw * _HALF
                    self._start_navigation(course, sp, cfg.track_vel_sigma)
                    return
        self.track = _vec(gp[0], gp[1], yaw)
        self.trk_tick = self.fix_tick
        self.trk_set = True

    def _start_navigation(self, course, sp, sigma_vel):
        """Heading = course (yaw = -course), v = sp (sin, cos course, 0), p = antenna
        - C_bn lever, P = diag(init) with the fix's sigmas and sigma_vel horizontally."""
        ins = self.ins
        ypr = ref_rot.dcm_to_euler(ins.c_bn)
        ypr[fw_rot.YAW] = -course
        self.ypr = ypr
        ins.q_bn = ref_rot.euler_to_q(ypr)
        ins.c_bn = ref_rot.q_to_dcm(ins.q_bn)
        v = _vec(sp * ref_fmath.sin(course), sp * ref_fmath.cos(course), 0)
        sh = self._sigma_h()
        age = self.tick - self.fix_tick
        self._restart(self.gnss_p, v, age, sh, self._sigma_v(sh), sigma_vel)
        ins.take_dvn()
        ins.slow_update(_ZERO)
        self.since_prop = 0
        self.last_accept_tick = self.tick
        self.state = NAVIGATING

    def _restart(self, gp, v, age, sigma_h, sigma_v, sigma_vel):
        """p = (antenna - C_bn lever) + v age dt, the fix carried forward over its age; P from
        the initial diagonal with the fix's sigmas and the horizontal velocity's sigma_vel."""
        t = F32(max(age, 0)) * self.cfg.dt_s
        p = (gp - self._lever_n()) + v * t
        self.ins.reset_kinematics(p, v)
        self.init_diag[0] = sigma_h * sigma_h
        self.init_diag[1] = sigma_h * sigma_h
        self.init_diag[2] = sigma_v * sigma_v
        self.init_diag[IX_VEL : IX_VEL + 2] = sigma_vel * sigma_vel
        self.kf.reset_p(self.init_diag)
        self.corr = np.zeros(6, F32)

    def _lever_n(self):
        """C_bn lever_b: the antenna offset in the navigation frame."""
        return _mat_vec(self.ins.c_bn, self.cfg.lever_b_m)

    def _sigma_h(self):
        cfg = self.cfg
        s = self.fix[4]
        if not s > 0.0:
            s = self.fix[1] * cfg.gnss_uere_m
        if s < cfg.gnss_sigma_floor_m:
            s = cfg.gnss_sigma_floor_m
        return s

    def _sigma_v(self, sigma_h):
        cfg = self.cfg
        s = self.fix[5]
        if not s > 0.0:
            s = sigma_h * cfg.gnss_vert_factor
        if s < cfg.gnss_sigma_floor_m:
            s = cfg.gnss_sigma_floor_m
        return s

    def _navigate(self):
        ins = self.ins
        kf = self.kf
        ins.step(self.w_b, self.f_b)
        slot = self.tick % RING
        self.ring_p[slot] = ins.p_n - self.corr[0:3]
        self.ring_v[slot] = ins.v_n - self.corr[3:6]
        self.since_prop += 1
        self.since_zupt += 1
        self.since_nhc += 1
        if self.fix_pending:
            self.fix_pending = False
            self._nav_fix()
        if kf.job == IDLE and not kf.ready:
            self._schedule()
        busy = kf.job != IDLE
        kf.work(self.cfg.slices_per_tick)
        if kf.ready:
            self._inject()
        if busy and kf.job == IDLE and not kf.diagonal_ok():  # P changed only if a job ended
            self._fault_reset()
            return
        p, v = ins.p_n, ins.v_n
        s = _sum_left([p[0], p[1], p[2], v[0], v[1], v[2], ins.q_bn[0]])
        if s - s != 0.0:
            self._fault_reset()

    def _nav_fix(self):
        """Screen a new fix once, re-anchor if far, convert it and queue it for the filter."""
        self.last_fix_tick = self.tick
        if not self._fix_usable():
            self.gated_until = self.tick + self.ticks_second
            return
        p = self.ins.p_n
        lim = self.cfg.reanchor_m
        if p[0] > lim or p[0] < -lim or p[1] > lim or p[1] < -lim:
            self._reanchor()
        self.gnss_p = self._to_enu(self.fix_lat_e7, self.fix_lon_e7, self.fix[0])
        self.fix_queued = True

    def _reanchor(self):
        """New integer origin at the current position; the tangent plane there is tilted by
        rho = (-N / (R_M+h), E / (R_N+h), E tan(L) / (R_N+h)) from the old one."""
        ins = self.ins
        c = self.coef
        lat, lon, h = ref_geo.to_e7(c, self.origin_lat_e7, self.origin_lon_e7, ins.p_n)
        lat, lon, h = int(lat), int(lon), F32(h)
        dp = self._to_enu(lat, lon, h)  # the new origin in the old frame
        rho = _vec(
            -dp[1] * c[fw_geo.INV_RM],
            dp[0] * c[fw_geo.INV_RN],
            dp[0] * c[fw_geo.INV_RN] * (c[fw_geo.SIN_LAT] / c[fw_geo.COS_LAT]),
        )
        ins.shift_origin(dp, rho)
        self.corr[0:3] = self.corr[0:3] - dp
        self._set_origin(lat, lon, h)
        ins.set_frame(self.coef)
        self.reanchors += 1

    def _schedule(self):
        """The filter is idle: a pending fix (unless propagation is overdue), else propagation,
        else a zero-velocity update at standstill, else the non-holonomic constraint."""
        cfg = self.cfg
        kf = self.kf
        ins = self.ins
        overdue = self.since_prop >= 2 * self.ticks_prop
        if self.fix_queued and not overdue:
            self.fix_queued = False
            self._start_gnss_update()
        elif self.since_prop >= self.ticks_prop:
            t = F32(self.since_prop) * cfg.dt_s
            dvn = ins.take_dvn()
            ins.slow_update(t)
            kf.start_propagation(dvn, t, ins.c_bn, ins.w_ie_n)
            self.since_prop = 0
        elif cfg.zupt and self.still and self.since_zupt >= self.ticks_zupt:
            self.since_zupt = 0
            r = cfg.zupt_sigma * cfg.zupt_sigma
            for i in range(3):  # z = v_n[i] = dv_i + noise
                kf.add_scalar(ins.v_n[i], r, [(IX_VEL + i, _ONE)])
            kf.start_update()
            self.job = JOB_AID
        elif cfg.nhc and not self.still and self.since_nhc >= self.ticks_nhc:
            self.since_nhc = 0
            self._start_nhc()

    def _start_gnss_update(self):
        """Antenna position p + C_bn l against the fix at its measurement time (from the ring,
        plus the corrections injected since): z = dp + [(C l) x] phi; and, with a course, the
        horizontal velocity v + C_bn (w x l) against speed (sin, cos course)."""
        cfg = self.cfg
        kf = self.kf
        ins = self.ins
        age = min(max(self.tick - self.fix_tick, 0), RING - 1)
        slot = (self.tick - age) % RING
        p_then = self.ring_p[slot]
        v_then = self.ring_v[slot]
        corr = self.corr
        lx, ly, lz = self._lever_n()
        sh = self._sigma_h()
        sv = self._sigma_v(sh)
        rh = sh * sh
        rv = sv * sv
        gp = self.gnss_p
        self.used = np.array([gp[0], gp[1], gp[2], self.fix[2], self.fix[3], sh, sv], F32)
        self.used_tick = self.fix_tick
        att = IX_ATT
        z = (p_then[0] + corr[0] + lx) - gp[0]
        kf.add_scalar(z, rh, [(0, _ONE), (att + 1, -lz), (att + 2, ly)])
        z = (p_then[1] + corr[1] + ly) - gp[1]
        kf.add_scalar(z, rh, [(1, _ONE), (att, lz), (att + 2, -lx)])
        z = (p_then[2] + corr[2] + lz) - gp[2]
        kf.add_scalar(z, rv, [(2, _ONE), (att, -ly), (att + 1, lx)])
        course = self.fix[3]
        sp = self.fix[2]
        if course >= 0.0:
            ve = sp * ref_fmath.sin(course)
            vn = sp * ref_fmath.cos(course)
            lever_vel_n = _mat_vec(ins.c_bn, _cross(self.w_b - ins.bg, cfg.lever_b_m))
            rvel = cfg.gnss_vel_sigma * cfg.gnss_vel_sigma
            z = (v_then[0] + corr[3] + lever_vel_n[0]) - ve
            kf.add_scalar(z, rvel, [(IX_VEL, _ONE)])
            z = (v_then[1] + corr[4] + lever_vel_n[1]) - vn
            kf.add_scalar(z, rvel, [(IX_VEL + 1, _ONE)])
        kf.start_update()
        self.job = JOB_GNSS
        self.updates += 1

    def _start_nhc(self):
        """Body x (lateral) and z (vertical) velocity are zero: z = c_k . v_n with c_k the k-th
        column of C_bn, h = [0, c_k, v_n x c_k, 0, 0]."""
        kf = self.kf
        ins = self.ins
        v = ins.v_n
        r = self.cfg.nhc_sigma * self.cfg.nhc_sigma
        body_v = _mat_vec(ins.c_bn.T, v)  # C_bn^T v: (c_k . v) summed in the firmware's order
        for k in (0, 2):
            c_k = ins.c_bn[:, k]
            h_att = _cross(v, c_k)
            terms = [(IX_VEL + j, c_k[j]) for j in range(3)]
            terms += [(IX_ATT + j, h_att[j]) for j in range(3)]
            kf.add_scalar(body_v[k], r, terms)
        kf.start_update()
        self.job = JOB_AID

    def _inject(self):
        """Closed loop: p -= dp, v -= dv (also into the corrections), b += db,
        q = q(phi) (x) q, dx = 0; then GNSS bookkeeping (all three positions gated: a reject)."""
        kf = self.kf
        ins = self.ins
        dx = kf.dx
        dp = dx[IX_POS : IX_POS + 3]
        dv = dx[IX_VEL : IX_VEL + 3]
        ins.p_n = ins.p_n - dp
        self.corr[0:3] = self.corr[0:3] - dp
        ins.v_n = ins.v_n - dv
        self.corr[3:6] = self.corr[3:6] - dv
        ins.bg = ins.bg + dx[IX_BG : IX_BG + 3]
        ins.ba = ins.ba + dx[IX_BA : IX_BA + 3]
        dq = _q_from_rotvec(dx[IX_ATT : IX_ATT + 3])
        ins.q_bn = _q_normalized(ref_rot.q_mul(dq, ins.q_bn))
        ins.c_bn = ref_rot.q_to_dcm(ins.q_bn)
        kf.dx = np.zeros(N, F32)
        kf.ready = False
        if self.job == JOB_GNSS:
            if kf.gate_mask & 3:
                self.rejects += 1
                self.gated_until = self.tick + self.ticks_second
                if self.rejects >= self.cfg.reset_after_rejects:
                    self._reset_to_gnss()
            else:
                self.rejects = 0
                self.last_accept_tick = self.tick
                if kf.gate_mask:
                    self.gated_until = self.tick + self.ticks_second
        self.job = JOB_NONE

    def _reset_to_gnss(self):
        """From the fix the last update rejected: p, horizontal v (from its course, else the
        INS's), a fresh P; attitude and biases kept."""
        ins = self.ins
        u = self.used
        course, sp = u[4], u[3]
        if course >= 0.0:
            v = _vec(sp * ref_fmath.sin(course), sp * ref_fmath.cos(course), ins.v_n[2])
        else:
            v = _vec(ins.v_n[0], ins.v_n[1], ins.v_n[2])
        sigma_vel = self.cfg.init_vel_sigma if course >= 0.0 else self.cfg.track_vel_sigma
        self._restart(u[0:3], v, self.tick - self.used_tick, u[5], u[6], sigma_vel)
        self.rejects = 0
        self.resets += 1

    def _fault_reset(self):
        ins = self.ins
        self.state = ALIGNING
        ins.q_bn = _vec(1, 0, 0, 0)
        ins.c_bn = ref_rot.q_to_dcm(ins.q_bn)
        ins.bg = np.zeros(3, F32)
        ins.ba = np.zeros(3, F32)
        ins.reset_kinematics(self.gnss_p, np.zeros(3, F32))
        self.kf.reset_p(self.init_diag)
        self.level_sums = np.zeros(6, F32)
        self.corr = np.zeros(6, F32)
        self.n_level = 0
        self.n_stable = 0
        self.fix_queued = False
        self.trk_set = False
        self.leveled = False
        self.fault_until = self.tick + self.ticks_second
        self.resets += 1

    def _update_health(self):
        t = self.tick
        if t < self.fault_until:
            self.health = 2
        elif t < self.sat_until or t < self.gated_until:
            self.health = 1
        elif self.state == NAVIGATING and t - self.last_accept_tick > self.ticks_timeout:
            self.health = 1
        else:
            self.health = 0

    # ---- state for comparisons ----

    def snapshot(self):
        """(floats, ints): every piece of state by name (float32 arrays, Python ints)."""
        ins, kf = self.ins, self.kf
        floats = {
            "p_n": ins.p_n,
            "v_n": ins.v_n,
            "q_bn": ins.q_bn,
            "c_bn": ins.c_bn,
            "bg": ins.bg,
            "ba": ins.ba,
            "dvn_sum": ins.dvn_sum,
            "a_n": ins.a_n,
            "w_ie_n": ins.w_ie_n,
            "p_comp": ins.p_comp,
            "theta_prev": ins.theta_prev,
            "dv_prev": ins.dv_prev,
            "earth_model": _vec(ins.g0, ins.inv_rn, ins.inv_rm, ins.h0),
            "P": kf.P,
            "dx": kf.dx,
            "kf_A": kf.A,
            "kf_v": kf.v,
            "kf_K": kf.K,
            "kf_f_n": kf.f_n,
            "kf_c_bn": kf.c_bn,
            "kf_w_ie_n": kf.w_ie_n,
            "kf_scalars": _vec(
                kf.T,
                kf.decay_g,
                kf.decay_a,
                kf.S,
                kf.Y,
                kf.gate2,
                kf.inv_tau_g,
                kf.inv_tau_a,
            ),
            "q_psd": kf.q_psd,
            "p_floor": kf.p_floor,
            "p_ceiling": kf.p_ceiling,
            "w_b": self.w_b,
            "f_b": self.f_b,
            "still_lp": self.still_lp,
            "level_sums": self.level_sums,
            "init_diag": self.init_diag,
            "track": self.track,
            "ring_p": self.ring_p,
            "ring_v": self.ring_v,
            "corr": self.corr,
            "gnss_p": self.gnss_p,
            "fix": self.fix,
            "used_fix": self.used,
            "ypr": self.ypr,
            "frame_coef": self.coef,
        }
        ints = {
            "tick": self.tick,
            "state": self.state,
            "health": self.health,
            "leveled": self.leveled,
            "still": self.still,
            "n_level": self.n_level,
            "n_still": self.n_still,
            "n_stable": self.n_stable,
            "fix_pending": self.fix_pending,
            "fix_queued": self.fix_queued,
            "used_tick": self.used_tick,
            "speed_tick": self.speed_tick,
            "trk_set": self.trk_set,
            "trk_tick": self.trk_tick,
            "fix_lat_e7": self.fix_lat_e7,
            "fix_lon_e7": self.fix_lon_e7,
            "fix_quality": self.fix_quality,
            "fix_tick": self.fix_tick,
            "last_fix_tick": self.last_fix_tick,
            "last_accept_tick": self.last_accept_tick,
            "rejects": self.rejects,
            "gated_until": self.gated_until,
            "fault_until": self.fault_until,
            "sat_until": self.sat_until,
            "since_prop": self.since_prop,
            "since_zupt": self.since_zupt,
            "since_nhc": self.since_nhc,
            "job": self.job,
            "updates": self.updates,
            "resets": self.resets,
            "reanchors": self.reanchors,
            "kf_job": self.kf.job,
            "kf_step": self.kf.step,
            "kf_m": self.kf.m,
            "kf_ready": self.kf.ready,
            "kf_n_scalars": len(self.kf.scalars),
            "kf_accepted": self.kf.accepted,
            "kf_rejected": self.kf.rejected,
            "kf_gate_mask": self.kf.gate_mask,
            "origin_lat_e7": self.origin_lat_e7,
            "origin_lon_e7": self.origin_lon_e7,
            "frame_valid": self.frame_valid,
        }
        return floats, {k: int(v) for k, v in ints.items()}


def _apply_cal(x, b0, m):
    """M (x - b0), or x - b0 when M is None (row sums left to right)."""
    d = np.asarray(x, F32) - b0
    if m is None:
        return d
    return _mat_vec(np.asarray(m, F32).reshape(3, 3), d)
