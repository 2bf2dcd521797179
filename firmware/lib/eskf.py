"""15-state error-state Kalman filter in float32, time-distributed (docs/requirements.md:
integrated navigation and Kalman filter, error-state filter formulation).

Error state, in the error-state order of docs/requirements.md, with its signs (errors of the
navigation quantities are nominal minus true, errors of the biases are true minus estimate):
     0-2  dp  = p_nominal - p_true              m, ENU
     3-5  dv  = v_nominal - v_true              m/s, ENU
     6-8  phi : C_nominal = (I - [phi x]) C_true  rad, ENU
     9-11 dbg = b_g,true - b_g,estimate          rad/s, body
    12-14 dba = b_a,true - b_a,estimate          m/s^2, body
So a measurement is written z = (nominal prediction - measured) = h dx + noise, and the
closed-loop correction (docs/requirements.md, error-state filter formulation) is p -= dp,
v -= dv, q = q(phi) (x) q, b_g += dbg, b_a += dba, then dx = 0.

Dynamics, docs/requirements.md eq. 5-28 plus the terms of the Earth-fixed frame (`earth_terms`):
    dp'  = dv
    dv'  = [f_n x] phi + C_bn dba - [2 w_ie x] dv
    phi' = -C_bn dbg - [w_ie x] phi
    dbg' = -dbg / tau_g + w_g,   dba' = -dba / tau_a + w_a   (1/tau = 0: random walk)
Propagation uses Phi = I + F T over T, the time since the last propagation, with f_n the mean
specific force over T (accumulated by the INS), and P <- Phi P Phi^T + Q T. F is never formed:
`_phi_apply` applies Phi to one 15-vector through F's five non-zero blocks, and since P is
symmetric, A = Phi P is built column by column and P = A Phi^T row by row with it.

Updates are sequential scalar measurements (independent noises), each in the Joseph form of
eq. 5-26, which for a row h with v = P h^T, S = h v + r and K = v / S reads
    P' = (I - K h) P (I - K h)^T + K r K^T = P - K v^T - v K^T + S K K^T.
Only the upper triangle is computed and then mirrored, so P stays exactly symmetric; the
Joseph form is positive semi-definite for any K, so rounding in K costs only second-order
errors, whereas the short form P - v v^T / S loses definiteness when r << h P h^T in float32.
Each scalar is gated: rejected when y^2 > gate^2 S (y the innovation). After each job the
diagonal is held between floors and ceilings (a ceiling scales the row and column, which keeps
P positive semi-definite).

Time distribution (PSINS-style): a job runs in slices and `work(n)` performs n slices per tick.
    propagation: 15 column slices (A = Phi P), 15 row slices (P = A Phi^T), 1 finishing slice
    update:      per scalar 3 slices for v = P h^T, 1 gain/gate slice, 15 row slices (none if
                 gated out); then 1 finishing slice, after which `ready` asks for injection.
Inputs are copied when a job starts and only jobs change P, so the result does not depend on
where the slices fall. Measurement rows are sparse: each names its non-zero columns.
"""

from array import array

from micropython import const

import f32
import kern

N = const(15)
IX_POS = const(0)
IX_VEL = const(3)
IX_ATT = const(6)
IX_BG = const(9)
IX_BA = const(12)
MAX_SCALARS = const(8)
MAX_NZ = const(6)

IDLE = const(0)
PROPAGATING = const(1)
UPDATING = const(2)

# self._s: scalars of the running job
_S_T = const(0)  # propagation interval, s
_S_DECAY_G = const(1)  # 1 - T/tau_g
_S_DECAY_A = const(2)  # 1 - T/tau_a
_S_S = const(3)  # innovation variance of the current scalar
_S_Y = const(4)  # innovation of the current scalar
_S_GATE2 = const(5)  # gate^2 (sigmas squared)
_S_INV_TAU_G = const(6)
_S_INV_TAU_A = const(7)
_NS = const(8)

# The float buffer `Eskf.e` (its parts are the views P, dx, ...) and the int buffer `Eskf.i`
# (the job's state), so that a native kernel takes the filter as two arguments.
# firmware/native/layout.h is generated from these offsets (common/native/layout.py).
E_P = const(0)  # P (N x N)
E_A = const(225)  # A = Phi P during propagation (N x N)
E_U = const(450)  # Phi x (N)
E_V = const(465)  # P h^T (N)
E_K = const(480)  # gain (N)
E_FN = const(495)  # mean specific force over T (3)
E_C = const(498)  # C_bn at the start of the propagation (9)
E_W = const(507)  # w_ie_n (3)
E_S = const(510)  # job scalars (_NS)
E_H = const(518)  # measurement rows (MAX_SCALARS x N)
E_Z = const(638)  # measurements (MAX_SCALARS); after its gate step, a scalar's innovation
E_R = const(646)  # their noise variances (MAX_SCALARS); ... and the innovation's variance S
E_DX = const(654)  # error state (N)
E_Q = const(669)  # process noise per second (N)
E_LO = const(684)  # P diagonal floor (N)
E_HI = const(699)  # P diagonal ceiling (N)
NE = const(714)
I_JOB = const(0)  # IDLE, PROPAGATING, UPDATING
I_STEP = const(1)  # slice of the job
I_M = const(2)  # scalar being processed (update)
I_NSCAL = const(3)  # scalars queued
I_READY = const(4)  # an update finished: dx waits for injection
I_ACCEPTED = const(5)  # scalars accepted / gated out by the last update
I_REJECTED = const(6)
I_GATE_MASK = const(7)  # bit m set: scalar m of the last update was gated out
I_EARTH = const(8)  # earth_terms
I_NNZ = const(9)  # non-zeros per scalar (MAX_SCALARS)
I_NZ = const(17)  # their column indices (MAX_SCALARS x MAX_NZ)
NI = const(65)

_work = kern.pick("eskf_work", None)
_diagonal_ok = kern.pick("eskf_diagonal_ok", None)


class Eskf:
    def __init__(self, earth_terms=True, e=None):
        """e: the NE-float buffer to use (a view into a larger one), or None for a new."""
        if e is None:
            e = f32.zeros(NE)
        self.e = e
        self.i = ii = array("i", bytes(4 * NI))
        ii[I_EARTH] = 1 if earth_terms else 0
        self.P = f32.view(e, E_P, N * N)
        self.dx = f32.view(e, E_DX, N)
        self.q_psd = f32.view(e, E_Q, N)  # process noise per second on the diagonal
        self.p_floor = f32.view(e, E_LO, N)
        self.p_ceiling = f32.view(e, E_HI, N)
        self._a = f32.view(e, E_A, N * N)
        self._u = f32.view(e, E_U, N)
        self._v = f32.view(e, E_V, N)
        self._k = f32.view(e, E_K, N)
        self._fn = f32.view(e, E_FN, 3)
        self._c = f32.view(e, E_C, 9)
        self._w = f32.view(e, E_W, 3)
        self._s = f32.view(e, E_S, _NS)
        self._h = f32.view(e, E_H, MAX_SCALARS * N)
        self._z = f32.view(e, E_Z, MAX_SCALARS)
        self._r = f32.view(e, E_R, MAX_SCALARS)

    # the job's state, by name (the navigator reads self.i directly in its per-tick path)
    @property
    def job(self):
        return self.i[I_JOB]

    @property
    def ready(self):
        return self.i[I_READY] != 0

    @ready.setter
    def ready(self, value):
        self.i[I_READY] = 1 if value else 0

    @property
    def n_scalars(self):
        return self.i[I_NSCAL]

    @property
    def accepted(self):
        return self.i[I_ACCEPTED]

    @property
    def rejected(self):
        return self.i[I_REJECTED]

    @property
    def gate_mask(self):
        return self.i[I_GATE_MASK]

    # ---- configuration ---------------------------------------------------------------------

    def set_gate(self, gate_sigma, inv_tau_g, inv_tau_a):
        s = self._s
        s[_S_GATE2] = gate_sigma * gate_sigma
        s[_S_INV_TAU_G] = inv_tau_g
        s[_S_INV_TAU_A] = inv_tau_a

    def reset_p(self, diag):
        """P = diag(diag); drops any running job and pending dx."""
        p = self.P
        for i in range(N * N):
            p[i] = 0.0
        for i in range(N):
            p[i * (N + 1)] = diag[i]
            self.dx[i] = 0.0
        ii = self.i
        ii[I_JOB] = IDLE
        ii[I_READY] = 0
        ii[I_NSCAL] = 0

    def widen(self, var, i0, n):
        """P's variances i0 + j at least var[j], j < n (between jobs)."""
        p = self.P
        for j in range(n):
            k = (i0 + j) * (N + 1)
            if p[k] < var[j]:
                p[k] = var[j]

    def reset_rows(self, i, p_ii, j, p_jj):
        """Rows and columns i and j of P zeroed, their variances p_ii and p_jj: the reset of
        one channel (between jobs)."""
        p = self.P
        for k in range(N):
            p[i * N + k] = 0.0
            p[k * N + i] = 0.0
            p[j * N + k] = 0.0
            p[k * N + j] = 0.0
        p[i * (N + 1)] = p_ii
        p[j * (N + 1)] = p_jj

    # ---- propagation -----------------------------------------------------------------------

    def start_propagation(self, dvn_sum, t_s, c_bn, w_ie_n):
        """Begin P <- Phi P Phi^T + Q T with the specific-force sum dvn_sum (m/s) over t_s."""
        s = self._s
        s[_S_T] = t_s
        s[_S_DECAY_G] = 1.0 - t_s * s[_S_INV_TAU_G]
        s[_S_DECAY_A] = 1.0 - t_s * s[_S_INV_TAU_A]
        fn = self._fn
        for i in range(3):
            fn[i] = dvn_sum[i] / t_s
            self._w[i] = w_ie_n[i]
        for i in range(9):
            self._c[i] = c_bn[i]
        self.i[I_JOB] = PROPAGATING
        self.i[I_STEP] = 0

    def _phi_apply(self, src, base):
        """self._u = Phi x, for x = src[base:base+15]."""
        t = self._s[_S_T]
        x0 = src[base]
        x1 = src[base + 1]
        x2 = src[base + 2]
        x3 = src[base + 3]
        x4 = src[base + 4]
        x5 = src[base + 5]
        x6 = src[base + 6]
        x7 = src[base + 7]
        x8 = src[base + 8]
        x9 = src[base + 9]
        x10 = src[base + 10]
        x11 = src[base + 11]
        x12 = src[base + 12]
        x13 = src[base + 13]
        x14 = src[base + 14]
        f = self._fn
        f0 = f[0]
        f1 = f[1]
        f2 = f[2]
        c = self._c
        c0 = c[0]
        c1 = c[1]
        c2 = c[2]
        c3 = c[3]
        c4 = c[4]
        c5 = c[5]
        c6 = c[6]
        c7 = c[7]
        c8 = c[8]
        # dv' = [f x] phi + C dba ; phi' = -C dbg
        dv0 = (f1 * x8 - f2 * x7) + (c0 * x12 + c1 * x13 + c2 * x14)
        dv1 = (f2 * x6 - f0 * x8) + (c3 * x12 + c4 * x13 + c5 * x14)
        dv2 = (f0 * x7 - f1 * x6) + (c6 * x12 + c7 * x13 + c8 * x14)
        da0 = c0 * x9 + c1 * x10 + c2 * x11
        da1 = c3 * x9 + c4 * x10 + c5 * x11
        da2 = c6 * x9 + c7 * x10 + c8 * x11
        if self.i[I_EARTH]:
            # w = (0, w1, w2): dv' -= 2 w x dv ; phi' -= w x phi
            w = self._w
            w1 = w[1]
            w2 = w[2]
            dv0 = dv0 - 2.0 * (w1 * x5 - w2 * x4)
            dv1 = dv1 - 2.0 * (w2 * x3)
            dv2 = dv2 + 2.0 * (w1 * x3)
            da0 = da0 + (w1 * x8 - w2 * x7)
            da1 = da1 + w2 * x6
            da2 = da2 - w1 * x6
        u = self._u
        u[0] = x0 + t * x3
        u[1] = x1 + t * x4
        u[2] = x2 + t * x5
        u[3] = x3 + t * dv0
        u[4] = x4 + t * dv1
        u[5] = x5 + t * dv2
        u[6] = x6 - t * da0
        u[7] = x7 - t * da1
        u[8] = x8 - t * da2
        g = self._s[_S_DECAY_G]
        a = self._s[_S_DECAY_A]
        u[9] = g * x9
        u[10] = g * x10
        u[11] = g * x11
        u[12] = a * x12
        u[13] = a * x13
        u[14] = a * x14

    def _propagation_slice(self):
        ii = self.i
        st = ii[I_STEP]
        u = self._u
        if st < N:
            # column st of A = Phi P: Phi times column st of P (= row st, P symmetric)
            self._phi_apply(self.P, st * N)
            a = self._a
            for k in range(N):
                a[k * N + st] = u[k]
        elif st < 2 * N:
            # row i of P = A Phi^T: Phi times row i of A; upper triangle, mirrored
            i = st - N
            self._phi_apply(self._a, i * N)
            p = self.P
            for j in range(i, N):
                x = u[j]
                p[i * N + j] = x
                p[j * N + i] = x
        else:
            t = self._s[_S_T]
            p = self.P
            q = self.q_psd
            for i in range(N):
                d = i * (N + 1)
                p[d] = p[d] + q[i] * t
            self._clamp_diagonal()
            ii[I_JOB] = IDLE
        ii[I_STEP] = st + 1

    # ---- measurement update ----------------------------------------------------------------

    def add_scalar(self, z, r, nnz, i0, h0, i1=0, h1=0.0, i2=0, h2=0.0):
        """Queue z = h dx + noise of variance r, h with nnz non-zeros (index, value); more than
        three non-zeros: call add_scalar_terms afterwards. Returns the scalar's slot."""
        ii = self.i
        m = ii[I_NSCAL]
        ii[I_NSCAL] = m + 1
        hb = m * N
        h = self._h
        for k in range(N):
            h[hb + k] = 0.0
        self._z[m] = z
        self._r[m] = r
        nz = ii
        b = I_NZ + m * MAX_NZ
        nz[b] = i0
        h[hb + i0] = h0
        if nnz > 1:
            nz[b + 1] = i1
            h[hb + i1] = h1
        if nnz > 2:
            nz[b + 2] = i2
            h[hb + i2] = h2
        ii[I_NNZ + m] = nnz
        return m

    def add_scalar_terms(self, m, i0, h0, i1, h1, i2, h2):
        """Three more non-zeros for queued scalar m."""
        h = self._h
        hb = m * N
        nz = self.i
        b = I_NZ + m * MAX_NZ + nz[I_NNZ + m]
        nz[b] = i0
        nz[b + 1] = i1
        nz[b + 2] = i2
        h[hb + i0] = h0
        h[hb + i1] = h1
        h[hb + i2] = h2
        nz[I_NNZ + m] = nz[I_NNZ + m] + 3

    def start_update(self):
        ii = self.i
        ii[I_JOB] = UPDATING
        ii[I_STEP] = 0
        ii[I_M] = 0
        ii[I_ACCEPTED] = 0
        ii[I_REJECTED] = 0
        ii[I_GATE_MASK] = 0

    def _update_slice(self):
        ii = self.i
        m = ii[I_M]
        if m >= ii[I_NSCAL]:
            self._clamp_diagonal()
            ii[I_NSCAL] = 0
            ii[I_JOB] = IDLE
            ii[I_READY] = 1
            return
        st = ii[I_STEP]
        hb = m * N
        b = I_NZ + m * MAX_NZ
        nnz = ii[I_NNZ + m]
        nz = ii
        h = self._h
        p = self.P
        v = self._v
        if st < 3:
            # v = P h^T, five rows per slice
            for i in range(5 * st, 5 * st + 5):
                acc = 0.0
                for t in range(nnz):
                    k = nz[b + t]
                    acc = acc + p[i * N + k] * h[hb + k]
                v[i] = acc
            ii[I_STEP] = st + 1
            return
        s = self._s
        kg = self._k
        if st == 3:
            hv = 0.0
            hx = 0.0
            dx = self.dx
            for t in range(nnz):
                k = nz[b + t]
                hk = h[hb + k]
                hv = hv + hk * v[k]
                hx = hx + hk * dx[k]
            sv = hv + self._r[m]
            y = self._z[m] - hx
            self._z[m] = y  # from here on: the innovation and its variance (nav's bias watch)
            self._r[m] = sv
            if not (sv > 0.0) or y * y > s[_S_GATE2] * sv:
                ii[I_REJECTED] += 1
                ii[I_GATE_MASK] |= 1 << m
                ii[I_M] = m + 1
                ii[I_STEP] = 0
                return
            s[_S_S] = sv
            s[_S_Y] = y
            for i in range(N):
                ki = v[i] / sv
                kg[i] = ki
                dx[i] = dx[i] + ki * y
            ii[I_ACCEPTED] += 1
            ii[I_STEP] = 4
            return
        # Joseph form, row i, upper triangle: P - K v^T - v K^T + S K K^T
        i = st - 4
        ki = kg[i]
        vi = v[i]
        ski = s[_S_S] * ki
        for j in range(i, N):
            kj = kg[j]
            x = ((p[i * N + j] - ki * v[j]) - vi * kj) + ski * kj
            p[i * N + j] = x
            p[j * N + i] = x
        if i == N - 1:
            ii[I_M] = m + 1
            ii[I_STEP] = 0
        else:
            ii[I_STEP] = st + 1

    # ---- common ----------------------------------------------------------------------------

    def work(self, n):
        """Run up to n slices of the current job."""
        if _work is not None:
            _work(self.e, self.i, n)
            return
        ii = self.i
        while n > 0 and ii[I_JOB] != IDLE:
            if ii[I_JOB] == PROPAGATING:
                self._propagation_slice()
            else:
                self._update_slice()
            n -= 1

    def _clamp_diagonal(self):
        p = self.P
        lo = self.p_floor
        hi = self.p_ceiling
        for i in range(N):
            d = p[i * (N + 1)]
            if d < lo[i]:
                p[i * (N + 1)] = lo[i]
            elif d > hi[i]:
                # scale row and column i by sqrt(hi/d): a congruence, P stays PSD
                g = f32.sqrt(hi[i] / d)
                for j in range(N):
                    p[i * N + j] = p[i * N + j] * g
                    p[j * N + i] = p[j * N + i] * g

    def diagonal_ok(self):
        """False if any variance is NaN, infinite or not positive (P must be reset)."""
        if _diagonal_ok is not None:
            return _diagonal_ok(self.e) != 0
        p = self.P
        for i in range(N):
            d = p[i * (N + 1)]
            if not (d > 0.0) or d - d != 0.0:
                return False
        return True
