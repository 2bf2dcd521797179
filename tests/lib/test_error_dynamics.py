"""The ESKF's error-state model checked in float64 against matrices written independently of
the firmware: F (eskf.py) and the measurement rows the navigator queues (nav_aid.py).

Bit-for-bit parity with the NumPy model cannot catch a sign or a term that the firmware and
its mirror share, so every expectation here comes from the error definitions alone (eskf.py's
docstring, docs/requirements.md, conventions; ENU navigation frame, state order dp, dv, phi, dbg,
dba):
    dp = p_nominal - p_true,  dv = v_nominal - v_true,  C_nominal = (I - [phi x]) C_true,
    dbg = b_g,true - b_g,estimate,  dba = b_a,true - b_a,estimate.
Here a true state is built from a nominal one and dx with C_true = exp([phi x]) C_nominal (the
same definition to first order, and exactly what `_inject` applies).

1. F typed from docs/requirements.md eq. 5-28/5-29 plus the Earth-fixed frame's terms, against
   `Eskf._phi_apply` (Phi = I + F T), within Higham's float32 rounding bound; and deliberately
   wrong F's fail the same comparison.
2. F derived numerically from the continuous nominal and true dynamics (finite differences of
   the error's rate), against the typed F.
3. Every measurement row the navigator queues (GNSS position with the lever arm, GNSS velocity,
   zero-velocity update, non-holonomic constraint), against the derivative of (nominal
   prediction - prediction from the true state); and z against h dx for a measurement made
   from the true state, which pins the sign of z as well.
4. `_inject` turns the nominal state into the true state of the definitions above.
"""

from dataclasses import dataclass

import numpy as np
import pytest

import eskf
import f32
import nav as nav_mod
import navcfg
import rot

POS = slice(0, 3)
VEL = slice(3, 6)
ATT = slice(6, 9)
BG = slice(9, 12)
BA = slice(12, 15)
N = 15
I3 = np.eye(3)
U32 = 2.0**-24  # float32 unit roundoff
OMEGA_E = 7.292115e-5  # rad/s, WGS-84


def gamma(k):
    """Higham's bound on k float32 roundings: |fl(s) - s| <= gamma_k sum |terms of s|."""
    return k * U32 / (1 - k * U32)


# The longest path through `_phi_apply` rounds 8 times (f_n = dvn_sum / T once; a velocity row
# sums 3 C dba products, 2 [f x] products and 2 Coriolis products, then T (.) and x + (.)),
# the bias rows 3 times (1 - T/tau, then the product): gamma_10 bounds every entry.
PHI_RTOL = gamma(10)  # 6.0e-7


# ---- independent float64 building blocks ----------------------------------------------------


def skew(a):
    """[a x]: skew(a) @ b == np.cross(a, b)."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def rotation(r):
    """exp([r x]) by Rodrigues' formula (r a rotation vector, rad)."""
    t = np.linalg.norm(r)
    if t == 0.0:
        return np.eye(3)
    k = skew(r / t)
    return np.eye(3) + np.sin(t) * k + (1.0 - np.cos(t)) * (k @ k)


def quaternion(r):
    """Hamilton [w, x, y, z] of the rotation vector r."""
    t = np.linalg.norm(r)
    return np.concatenate([[np.cos(t / 2)], np.sin(t / 2) * r / t])


def random_rotvec(rng, max_angle=np.pi):
    axis = rng.standard_normal(3)
    return axis / np.linalg.norm(axis) * rng.uniform(0.1, max_angle)


def earth_rate_n(lat_rad):
    """Earth rate in ENU: no east component at any latitude."""
    return OMEGA_E * np.array([0.0, np.cos(lat_rad), np.sin(lat_rad)])


def f32buf(values):
    buf = f32.zeros(len(values))
    for i, x in enumerate(values):
        buf[i] = x
    return buf


def as64(buf):
    return np.asarray(buf, dtype=np.float64)


def textbook_F(C_bn, f_n, w_ie_n, inv_tau_g, inv_tau_a, earth_terms):
    """Continuous-time F: docs/requirements.md eq. 5-28 (F_av = [f_n x], eq. 5-29), plus Coriolis
    and Earth rate on the attitude in the Earth-fixed tangent frame, plus first-order Gauss-Markov
    biases."""
    F = np.zeros((N, N))
    F[POS, VEL] = I3
    F[VEL, ATT] = skew(f_n)
    F[VEL, BA] = C_bn
    F[ATT, BG] = -C_bn
    if earth_terms:
        F[VEL, VEL] = -2.0 * skew(w_ie_n)
        F[ATT, ATT] = -skew(w_ie_n)
    F[BG, BG] = -inv_tau_g * I3
    F[BA, BA] = -inv_tau_a * I3
    return F


@dataclass
class State:
    p_n: np.ndarray  # m, ENU
    v_n: np.ndarray  # m/s
    C_bn: np.ndarray
    bg: np.ndarray  # rad/s
    ba: np.ndarray  # m/s^2


def true_from(nominal, dx):
    """The true state whose error, by the definitions above, is dx."""
    return State(
        p_n=nominal.p_n - dx[POS],
        v_n=nominal.v_n - dx[VEL],
        C_bn=rotation(dx[ATT]) @ nominal.C_bn,
        bg=nominal.bg + dx[BG],
        ba=nominal.ba + dx[BA],
    )


def jacobian(fun, eps):
    """Central differences of fun(dx) at dx = 0, one column per error state."""
    cols = []
    for j in range(N):
        e = np.zeros(N)
        e[j] = eps
        cols.append((fun(e) - fun(-e)) / (2 * eps))
    return np.array(cols).T


# ---- 1. F typed from the equations, against Eskf._phi_apply --------------------------------


@dataclass
class PropagationCase:
    C_bn: np.ndarray
    f_n: np.ndarray  # the mean specific force the filter sees, m/s^2
    w_ie_n: np.ndarray
    t_s: float
    inv_tau_g: float
    inv_tau_a: float
    kf: eskf.Eskf


def propagation_case(seed, earth_terms, inv_tau_s=None):
    """An Eskf started on a random propagation (bias 1/tau random unless given, 0 is a random
    walk); the case holds its float32 inputs as float64."""
    rng = np.random.default_rng(seed)
    C_bn = rotation(random_rotvec(rng)).astype(np.float32)
    t_s = np.float32(rng.uniform(0.005, 1.0))
    f_n = np.array([0.0, 0.0, 9.8]) + 3.0 * rng.standard_normal(3)
    dvn_sum = (f_n * t_s).astype(np.float32)
    w_ie_n = earth_rate_n(rng.uniform(-1.4, 1.4)).astype(np.float32)
    tau_s = rng.choice([np.inf, 600.0, 20.0], 2) if inv_tau_s is None else 1.0 / inv_tau_s
    inv_tau = np.float32(1.0) / tau_s.astype(np.float32)
    kf = eskf.Eskf(earth_terms)
    kf.set_gate(f32.f32(5), inv_tau[0], inv_tau[1])
    kf.start_propagation(f32buf(dvn_sum), t_s, f32buf(C_bn.ravel()), f32buf(w_ie_n))
    return PropagationCase(
        C_bn=C_bn.astype(np.float64),
        f_n=dvn_sum.astype(np.float64) / np.float64(t_s),
        w_ie_n=w_ie_n.astype(np.float64),
        t_s=float(t_s),
        inv_tau_g=float(inv_tau[0]),
        inv_tau_a=float(inv_tau[1]),
        kf=kf,
    )


def phi_mismatch(case, F, seed=0):
    """Worst |Phi_fw x - (I + F T) x| over the unit vectors and random x, in units of the float32
    bound PHI_RTOL (|x| + T |F| |x|) entry by entry: <= 1 means equal up to rounding. Entry by
    entry, so the Earth-rate terms (1e-5 of the specific-force terms) are held to their own
    precision; where every term is zero the firmware must give an exact zero."""
    rng = np.random.default_rng(seed)
    xs = list(np.eye(N)) + list(rng.standard_normal((6, N)))
    worst = 0.0
    src = f32.zeros(N)
    for x in xs:
        for i in range(N):
            src[i] = x[i]
        case.kf._phi_apply(src, 0)
        x64 = as64(src)
        u = as64(case.kf._u)
        expected = x64 + case.t_s * (F @ x64)
        bound = PHI_RTOL * (np.abs(x64) + case.t_s * (np.abs(F) @ np.abs(x64)))
        err = np.abs(u - expected)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(err == 0.0, 0.0, err / bound)
        worst = max(worst, float(ratio.max()))
    return worst


CASES = [(seed, earth) for seed in (11, 12, 13, 14) for earth in (True, False)]


@pytest.mark.parametrize("seed, earth_terms", CASES)
def test_phi_apply_is_I_plus_textbook_F_times_T(seed, earth_terms):
    # given: a propagation with a random attitude, specific force, latitude, interval and taus
    case = propagation_case(seed, earth_terms)
    # (earth_terms=False must ignore the Earth rate it is handed)
    F = textbook_F(case.C_bn, case.f_n, case.w_ie_n, case.inv_tau_g, case.inv_tau_a, earth_terms)
    # when / then: Phi x from the firmware equals (I + F T) x up to float32 rounding
    assert phi_mismatch(case, F, seed) <= 1.0


def _flip_f_cross(F, c):
    F[VEL, ATT] = -skew(c.f_n)


def _drop_coriolis(F, c):
    F[VEL, VEL] = 0.0


def _coriolis_once(F, c):
    F[VEL, VEL] = -skew(c.w_ie_n)


def _gyro_bias_sign(F, c):
    F[ATT, BG] = c.C_bn


def _earth_rate_sign(F, c):
    F[ATT, ATT] = skew(c.w_ie_n)


def _accel_bias_transposed(F, c):
    F[VEL, BA] = c.C_bn.T


def _no_bias_decay(F, c):
    F[BA, BA] = 0.0


MUTANTS = [
    _flip_f_cross,
    _drop_coriolis,
    _coriolis_once,
    _gyro_bias_sign,
    _earth_rate_sign,
    _accel_bias_transposed,
    _no_bias_decay,
]


@pytest.mark.parametrize("mutate", MUTANTS, ids=lambda m: m.__name__.strip("_"))
def test_a_wrong_F_fails_the_same_comparison(mutate):
    """Non-vacuity: one wrong sign or missing term misses by orders of magnitude."""
    case = propagation_case(seed=12, earth_terms=True, inv_tau_s=np.array([1 / 600, 1 / 20]))
    F = textbook_F(case.C_bn, case.f_n, case.w_ie_n, case.inv_tau_g, case.inv_tau_a, True)
    assert phi_mismatch(case, F) <= 1.0
    mutate(F, case)
    assert phi_mismatch(case, F) > 1e3


# ---- 2. F from the continuous dynamics, numerically -----------------------------------------

# Normal gravity in the tangent frame, of ins.py's form: it points at the Earth's centre (tilting
# by E/R_N, N/R_M) and weakens with height. Mid-latitude radii are enough here.
R_N_M = 6.39e6
R_M_M = 6.36e6
G_M_S2 = 9.80
FREE_AIR = 3.086e-6  # (m/s^2)/m


def gravity_n(p_n, earth_terms):
    if not earth_terms:
        return np.array([0.0, 0.0, -G_M_S2])  # ins.py's simple model: straight down, constant
    g = G_M_S2 - FREE_AIR * p_n[2]
    return np.array([-g * p_n[0] / R_N_M, -g * p_n[1] / R_M_M, -g])


def state_rate(s, w_ib_b, f_b, w_ie_n, earth_terms):
    """p', v', C' of the continuous mechanization (ins.py's docstring) for IMU readings w_ib_b,
    f_b corrected by the state's own biases."""
    w_b = w_ib_b - s.bg
    a_n = s.C_bn @ (f_b - s.ba) - 2.0 * np.cross(w_ie_n, s.v_n) + gravity_n(s.p_n, earth_terms)
    C_dot = s.C_bn @ skew(w_b) - skew(w_ie_n) @ s.C_bn
    return s.v_n, a_n, C_dot


def error_rate(nominal, true, w_ib_b, f_b, w_ie_n, inv_tau_g, inv_tau_a, earth_terms):
    """d/dt of the error between a nominal and a true state, both moving under the same IMU
    readings. The nominal biases are held (ins.py changes them only at injection); the true
    biases decay as first-order Gauss-Markov processes (so at dx = 0 the bias error still moves,
    by -b_estimate / tau: an offset, which central differences cancel and F does not hold).
    For the attitude, E = C_true C_nom^T = exp([phi x]) gives [phi' x] = E' E^T up to a term
    of order |phi| |phi'| (zero at dx = 0)."""
    pn_dot, vn_dot, Cn_dot = state_rate(nominal, w_ib_b, f_b, w_ie_n, earth_terms)
    pt_dot, vt_dot, Ct_dot = state_rate(true, w_ib_b, f_b, w_ie_n, earth_terms)
    E = true.C_bn @ nominal.C_bn.T
    E_dot = Ct_dot @ nominal.C_bn.T + true.C_bn @ Cn_dot.T
    S = E_dot @ E.T
    S = 0.5 * (S - S.T)
    phi_dot = np.array([S[2, 1], S[0, 2], S[1, 0]])
    return np.concatenate(
        [
            pn_dot - pt_dot,
            vn_dot - vt_dot,
            phi_dot,
            -inv_tau_g * true.bg,  # minus the held estimate's rate, zero
            -inv_tau_a * true.ba,
        ]
    )


@pytest.mark.parametrize("seed, earth_terms", CASES)
def test_textbook_F_is_the_jacobian_of_the_continuous_dynamics(seed, earth_terms):
    # given: a random nominal state, IMU readings and Earth rate
    rng = np.random.default_rng(100 + seed)
    nominal = State(
        p_n=rng.uniform(-2000.0, 2000.0, 3),
        v_n=20.0 * rng.standard_normal(3),
        C_bn=rotation(random_rotvec(rng)),
        bg=1e-3 * rng.standard_normal(3),
        ba=5e-2 * rng.standard_normal(3),
    )
    w_ib_b = 0.5 * rng.standard_normal(3)
    f_b = nominal.C_bn.T @ np.array([0.0, 0.0, 9.8]) + 3.0 * rng.standard_normal(3)
    w_ie_n = earth_rate_n(rng.uniform(-1.4, 1.4)) if earth_terms else np.zeros(3)
    inv_tau_g, inv_tau_a = 1.0 / 600.0, 1.0 / 20.0

    # when: F is the derivative of the error's rate with respect to the error
    def rate(dx):
        true = true_from(nominal, dx)
        return error_rate(nominal, true, w_ib_b, f_b, w_ie_n, inv_tau_g, inv_tau_a, earth_terms)

    F_numeric = jacobian(rate, eps=1e-5)

    # then: ins.py's gravity depends on position but eskf.py's F has no dv/dp block; that
    # neglected gravity gradient is -g/R horizontally (the Schuler frequency squared,
    # 1.5e-6 s^-2) and +3.1e-6 s^-2 vertically (free air), felt only over minutes without GNSS
    gravity_gradient = F_numeric[VEL, POS].copy()
    assert np.abs(gravity_gradient).max() < 4e-6
    F_numeric[VEL, POS] = 0.0
    f_n = nominal.C_bn @ (f_b - nominal.ba)
    F = textbook_F(nominal.C_bn, f_n, w_ie_n, inv_tau_g, inv_tau_a, earth_terms)
    # central differences: truncation ~eps^2 |f| and cancellation ~1e-16 |a| / eps, both < 1e-9
    np.testing.assert_allclose(F_numeric, F, rtol=0, atol=1e-9)


# ---- 3. measurement rows queued by the navigator -------------------------------------------


def navigator_at(rng, speed_m_s, lever_b_m=(0.0, 0.0, 0.0)):
    """A navigator holding a random nominal state (car profile); returns it and that state as
    float64 (the values the firmware actually holds)."""
    cfg = navcfg.NavConfig("car")
    for i in range(3):
        cfg.lever_b_m[i] = lever_b_m[i]  # the navigator takes its configuration when made
    nav = nav_mod.Navigator(cfg)
    nav.state = nav_mod.NAVIGATING
    ins = nav.ins
    q = quaternion(random_rotvec(rng))
    for i in range(4):
        ins.q_bn[i] = q[i]
    rot.q_to_dcm(ins.c_bn, ins.q_bn)
    C_bn = as64(ins.c_bn).reshape(3, 3)
    v_n = C_bn @ np.array([0.02, speed_m_s, -0.01]) + 0.01 * rng.standard_normal(3)
    for i in range(3):
        ins.p_n[i] = rng.uniform(-300.0, 300.0)
        ins.v_n[i] = v_n[i]
        ins.bg[i] = 1e-3 * rng.standard_normal()
        ins.ba[i] = 5e-2 * rng.standard_normal()
    return nav, nominal_of(nav)


def nominal_of(nav):
    ins = nav.ins
    return State(
        p_n=as64(ins.p_n),
        v_n=as64(ins.v_n),
        C_bn=as64(ins.c_bn).reshape(3, 3),
        bg=as64(ins.bg),
        ba=as64(ins.ba),
    )


def queued_rows(kf):
    """The rows the filter will use (only the columns each scalar names) and their z."""
    H = np.zeros((kf.n_scalars, N))
    z = np.zeros(kf.n_scalars)
    for m in range(kf.n_scalars):
        full = as64(kf._h[m * N : (m + 1) * N])
        cols = [kf.i[eskf.I_NZ + m * eskf.MAX_NZ + t] for t in range(kf.i[eskf.I_NNZ + m])]
        H[m, cols] = full[cols]
        assert np.array_equal(H[m], full), "a non-zero outside the listed columns"
        z[m] = kf._z[m]
    return H, z


def numeric_h(predict, nominal):
    """h = d(nominal prediction - prediction from the true state) / d dx."""
    return jacobian(lambda dx: predict(nominal) - predict(true_from(nominal, dx)), eps=1e-6)


def small_error(rng, phi_rad=1e-3):
    scale = np.repeat([0.5, 0.05, phi_rad, 1e-3, 5e-2], 3)
    return scale * rng.standard_normal(N)


def test_gnss_rows_are_the_derivative_of_the_antenna_prediction():
    # given: a navigator at a random attitude and velocity, turning, with a lever arm
    rng = np.random.default_rng(7)
    lever_b_m = np.array([0.4, 1.3, 0.9])
    nav, nominal = navigator_at(rng, speed_m_s=15.0, lever_b_m=lever_b_m)
    w_ib_b = 0.4 * rng.standard_normal(3)
    for i in range(3):
        nav._w[i] = w_ib_b[i]  # the calibrated body rate of this tick
    w_ib_b = as64(nav._w)

    def antenna_p(s):
        return s.p_n + s.C_bn @ lever_b_m

    def antenna_v(s):
        return (s.v_n + s.C_bn @ np.cross(w_ib_b - s.bg, lever_b_m))[:2]

    # and: a fix made by the true state, measured at this tick
    dx = small_error(rng)
    true = true_from(nominal, dx)
    p_fix, v_fix = antenna_p(true), antenna_v(true)
    nav.tick = 1000
    nav.ctl[nav_mod._C_FIX_TICK] = nav.tick
    b = (nav.tick % nav_mod.RING) * 3
    for i in range(3):
        nav._ring_p[b + i] = nominal.p_n[i]
        nav._ring_v[b + i] = nominal.v_n[i]
        nav._gp[i] = p_fix[i]
    nav._fx[nav_mod._FX_SIG_H] = 1.0
    nav._fx[nav_mod._FX_SPEED] = np.hypot(v_fix[0], v_fix[1])
    nav._fx[nav_mod._FX_COURSE] = np.arctan2(v_fix[0], v_fix[1]) % (2 * np.pi)  # from north

    # when (b: the ring slot of the fix's measurement tick, as nav._schedule picks it)
    nav._start_gnss_update(b, 1.0)
    H_fw, z_fw = queued_rows(nav.kf)

    # then: position E, N, U (dp + [(C l) x] phi), then velocity E, N
    assert H_fw.shape == (5, N)
    h_p = numeric_h(antenna_p, nominal)
    h_v = numeric_h(antenna_v, nominal)
    np.testing.assert_allclose(H_fw[:3], h_p, rtol=0, atol=1e-6 * np.abs(h_p).max())
    # The velocity rows keep only dv: the antenna velocity's sensitivity to attitude,
    # [(C (w x l)) x] phi, and to the gyro bias, -C [l x] dbg, are neglected, as nav_aid.py
    # says. In this fast turn (|w x l| = 1 m/s)
    # they reach 1 m/s per rad (17 mm/s for a 1 deg error) and 1 m/s per rad/s (1 mm/s for a
    # 1e-3 rad/s bias error), against the 0.1 m/s fix sigma.
    neglected = np.zeros_like(h_v)
    neglected[:, ATT] = h_v[:, ATT]
    neglected[:, BG] = h_v[:, BG]
    assert np.abs(neglected[:, ATT]).max() > 0.1 and np.abs(neglected[:, BG]).max() > 0.1
    np.testing.assert_allclose(H_fw[3:], h_v - neglected, rtol=0, atol=1e-6)
    # and z = nominal prediction - measured = h dx to first order (h the full derivative):
    # second-order terms ~ |l| |phi|^2 ~ 2e-6 m, float32 positions (300 m) ~ 3e-5 m
    np.testing.assert_allclose(z_fw[:3], h_p @ dx, rtol=0, atol=1e-4)
    np.testing.assert_allclose(z_fw[3:], h_v @ dx, rtol=0, atol=1e-4)


def test_zero_velocity_rows_are_the_derivative_of_the_velocity():
    # given: a navigator standing still (true velocity zero) with a small velocity error, the
    # filter idle, propagation not due and the zero-velocity update due
    rng = np.random.default_rng(8)
    nav, nominal = navigator_at(rng, speed_m_s=0.0)
    dx = small_error(rng)
    dx[VEL] = nominal.v_n  # the truth stands still
    nav.still = True
    c = nav.ctl
    c[nav_mod._C_SINCE_PROP] = 0
    c[nav_mod._C_SINCE_ZUPT] = c[nav_mod._C_T_ZUPT]
    c[nav_mod._C_FIX_QUEUED] = 0

    # when
    nav._schedule()
    H_fw, z_fw = queued_rows(nav.kf)

    # then
    assert nav.kf.job == eskf.UPDATING and H_fw.shape == (3, N)
    h = numeric_h(lambda s: s.v_n, nominal)
    np.testing.assert_allclose(H_fw, h, rtol=0, atol=1e-9)
    np.testing.assert_allclose(z_fw, h @ dx, rtol=0, atol=1e-9)


def test_nonholonomic_rows_are_the_derivative_of_the_body_velocity():
    # given: a car at a random attitude whose true velocity is along its body y axis, seen by
    # a nominal state with small attitude and velocity errors
    rng = np.random.default_rng(9)
    nav, nominal = navigator_at(rng, speed_m_s=12.0)
    dx = small_error(rng, phi_rad=5e-4)
    C_true = rotation(dx[ATT]) @ nominal.C_bn
    dx[VEL] = nominal.v_n - C_true @ np.array([0.0, 12.0, 0.0])
    nav.still = False

    # when
    nav._start_nhc()
    H_fw, z_fw = queued_rows(nav.kf)

    # then: body x and z velocity, h = [0, c_k^T, (v x c_k)^T, 0, 0]
    assert H_fw.shape == (2, N)
    h = numeric_h(lambda s: (s.C_bn.T @ s.v_n)[[0, 2]], nominal)
    np.testing.assert_allclose(H_fw, h, rtol=0, atol=1e-6 * np.abs(h).max())
    # z = C^T v - 0 = h dx to first order; the second-order terms |dv| |phi| + |v| |phi|^2 / 2
    # are ~3e-5 m/s here, a wrong sign in the attitude columns 2 |v| |phi| ~ 2e-2 m/s
    phi, dv = np.linalg.norm(dx[ATT]), np.linalg.norm(dx[VEL])
    second_order = phi * dv + 12.0 * phi**2 / 2
    np.testing.assert_allclose(z_fw, h @ dx, rtol=0, atol=2 * second_order + 1e-5)


# ---- 4. injection undoes the error as defined ------------------------------------------------


def test_inject_turns_the_nominal_state_into_the_true_one():
    # given: a nominal state and a finished update's dx
    rng = np.random.default_rng(10)
    nav, nominal = navigator_at(rng, speed_m_s=10.0)
    dx = small_error(rng, phi_rad=1e-2)
    for i in range(N):
        nav.kf.dx[i] = dx[i]
    dx = as64(nav.kf.dx)
    nav.kf.ready = True

    # when
    nav._inject()

    # then: the corrected state is the true state the definitions give for dx (a wrong sign
    # would miss by 2 |dx|: 1 m, 0.1 m/s, 2e-2 rad)
    true = true_from(nominal, dx)
    after = nominal_of(nav)
    for name, atol in (("p_n", 1e-4), ("v_n", 1e-5), ("C_bn", 1e-6), ("bg", 1e-9), ("ba", 1e-7)):
        np.testing.assert_allclose(getattr(after, name), getattr(true, name), rtol=0, atol=atol)
    assert not np.any(as64(nav.kf.dx))


def test_state_order_is_the_one_assumed_here():
    assert (eskf.IX_POS, eskf.IX_VEL, eskf.IX_ATT, eskf.IX_BG, eskf.IX_BA) == (0, 3, 6, 9, 12)
