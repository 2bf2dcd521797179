"""NumPy float32 model of `firmware/lib/eskf.py`: the 15-state error-state Kalman filter.

Written at matrix level where the firmware loops, with every float32 operation in the
firmware's order and grouping (f32ops.py says how), and time distribution mirrored slice for
slice: `work(n)` runs the firmware's n slices per tick, so the covariance matches between
ticks, not only at job ends. Where the firmware branches per element (diagonal clamping, the
gate) the model branches too.
"""

import numpy as np

from common import firmware_env
from host_emulator.model.f32ops import F32, ONE, TWO, ZERO, cross, mat_vec, vec

firmware_env.install()
import eskf as fw_eskf  # noqa: E402  (constants and state indices, shared with the firmware)

N = fw_eskf.N
IX_POS = fw_eskf.IX_POS
IX_VEL = fw_eskf.IX_VEL
IX_ATT = fw_eskf.IX_ATT
IX_BG = fw_eskf.IX_BG
IX_BA = fw_eskf.IX_BA
IDLE = fw_eskf.IDLE
PROPAGATING = fw_eskf.PROPAGATING
UPDATING = fw_eskf.UPDATING


class EskfModel:
    """Error state x = [dp, dv, phi, dbg, dba] (15), covariance P (15x15), time-distributed.

    Propagation P <- Phi P Phi^T + Q T with Phi = I + F T (F of docs/requirements.md eq. 5-28 plus
    the Earth-rate terms), as 15 column slices A[:, j] = Phi P[j, :] (P symmetric), 15 row slices
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
        self.T = ZERO
        self.decay_g = ZERO  # 1 - T / tau_g
        self.decay_a = ZERO
        self.S = ZERO
        self.Y = ZERO
        self.gate2 = ZERO
        self.inv_tau_g = ZERO
        self.inv_tau_a = ZERO
        self.scalars = []  # queued (z, r, [(k, h_k), ...]) in the firmware's non-zero order
        self.job = IDLE
        self.step = 0
        self.m = 0
        self.ready = False
        self.accepted = 0
        self.rejected = 0
        self.gate_mask = 0
        self.innov = []

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
        self.decay_g = ONE - t_s * self.inv_tau_g
        self.decay_a = ONE - t_s * self.inv_tau_a
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
        dv_rate = cross(self.f_n, att) + mat_vec(c, dba)
        att_rate = mat_vec(c, dbg)  # negated below
        if self.earth_terms:
            w1, w2 = self.w_ie_n[1], self.w_ie_n[2]
            dv_rate = vec(
                dv_rate[0] - TWO * (w1 * dvel[2] - w2 * dvel[1]),
                dv_rate[1] - TWO * (w2 * dvel[0]),
                dv_rate[2] + TWO * (w1 * dvel[0]),
            )
            att_rate = vec(
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
        self.innov = []  # (y, S) of each scalar, after its gate step

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
            hv = ZERO
            hx = ZERO
            for k, hk in terms:
                hv = hv + hk * self.v[k]
                hx = hx + hk * self.dx[k]
            s = hv + r
            y = z - hx
            self.innov.append((y, s))
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
