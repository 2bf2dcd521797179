"""NumPy float32 model of `firmware/lib/yaw_gsf.py`: the yaw estimator's bank of hypotheses.

`GsfModel` is a mixin of `NavModel` (nav.py): the bank's per-tick sums, its step at a fix
and what the navigator does with it (nav_align.py's `_gsf_align`, `_gsf_reset`, `_gsf_turn`,
nav.py's `_gsf_watch`). The bank lives in `self.gsf`, a float32 array with the
firmware's layout (yaw_gsf._G_*), so that the comparison takes it whole but its scratch; the
hypotheses are rows of a (GSF_N, _NH) view of it, and every statement the firmware repeats
per hypothesis is one vector expression over them here (elementwise float32 rounds as the
scalar statement does; sums over hypotheses stay loops, left to right).
"""

import numpy as np

from common import firmware_env
from host_emulator.model import fmath as ref_fmath
from host_emulator.model import rot as ref_rot
from host_emulator.model.eskf import IX_ATT
from host_emulator.model.f32ops import F32, HALF, ONE, ZERO

firmware_env.install()
import fmath as fw_fmath  # noqa: E402
import nav as fw_nav  # noqa: E402
import nav_aid as fw_nav_aid  # noqa: E402
import navcfg as fw_navcfg  # noqa: E402
import rot as fw_rot  # noqa: E402
import yaw_gsf as fw  # noqa: E402  (the layout and the tuning: the firmware's own objects)

K = fw.GSF_N
NST = fw._NST
PI = fw_fmath.PI
TWO_PI = fw_fmath.TWO_PI
# the bank's parts the comparison takes (the scratch, P h and F P, is left out)
PARTS = {
    "gsf_sums": (fw._G_A1, fw._G_YAW),
    "gsf_out": (fw._G_YAW, fw._G_QA),
    "gsf_tuning": (fw._G_QA, fw._G_PH),
    "gsf_weighing": (fw._G_D, fw._G_HYP),
    "gsf_hypotheses": (fw._G_HYP, fw.NG),
}


def wrap(a):
    """yaw_gsf._wrap, elementwise."""
    return np.where(a > PI, a - TWO_PI, np.where(a < -PI, a + TWO_PI, a)).astype(F32)


def exp_neg(y):
    """yaw_gsf.exp_neg, elementwise."""
    t = y * fw.SIXTYFOURTH
    p = ONE + t * (ONE + t * (HALF + t * (fw.SIXTH + t * fw.TWENTYFOURTH)))
    r = ONE / p
    for _ in range(6):
        r = r * r
    return np.where(y < fw.EXP_CUT, r, ZERO).astype(F32)


class GsfModel:
    def _gsf_init_tuning(self, cfg):
        self.gsf = np.zeros(fw.NG, F32)
        g = self.gsf
        g[fw._G_QA] = cfg.yaw_gsf_accel_sigma * cfg.yaw_gsf_accel_sigma
        g[fw._G_QW] = cfg.yaw_gsf_rate_sigma * cfg.yaw_gsf_rate_sigma
        g[fw._G_READY] = cfg.yaw_gsf_ready_sigma * cfg.yaw_gsf_ready_sigma
        g[fw._G_RMIN] = cfg.yaw_gsf_reset_min * cfg.yaw_gsf_reset_min
        g[fw._G_QB] = cfg.yaw_gsf_bias_walk * cfg.yaw_gsf_bias_walk
        rv = (
            cfg.yaw_gsf_vel_sigma
            if cfg.yaw_gsf_vel_sigma >= cfg.gnss_vel_sigma
            else cfg.gnss_vel_sigma
        )
        g[fw._G_RV] = rv * rv
        self.gsf_state = 0  # nav._C_GSF: 0, fw.GSF_ON or fw.GSF_HELD
        self.gsf_dis = 0  # nav._C_GSF_DIS
        self.ticks_gsf = int(cfg.yaw_gsf_reset_s / cfg.dt_s + 0.5)

    def _hyp(self):
        return self.gsf[fw._G_HYP :].reshape(K, fw._NH)

    # ---- the kernels ----

    def _gsf_accum(self):
        """yaw_gsf.gsf_accum."""
        g = self.gsf
        ins = self.ins
        dt = self.cfg.dt_s
        f = self.f_b - ins.ba
        c = ins.c_bn
        de = (c[0, 0] * f[0] + c[0, 1] * f[1] + c[0, 2] * f[2]) * dt
        dn = (c[1, 0] * f[0] + c[1, 1] * f[1] + c[1, 2] * f[2]) * dt
        g[fw._G_A1] = g[fw._G_A1] + de
        g[fw._G_A1 + 1] = g[fw._G_A1 + 1] + dn
        g[fw._G_A2] = g[fw._G_A2] + g[fw._G_A1] * dt
        g[fw._G_A2 + 1] = g[fw._G_A2 + 1] + g[fw._G_A1 + 1] * dt
        g[fw._G_T] = g[fw._G_T] + dt

    def _gsf_step(self):
        """yaw_gsf.gsf_step: the bank's first fix (with a speed), its chord start (without),
        or its predict, update and weighing."""
        g = self.gsf
        sh = self._sigma_h()
        if self.gsf_state == fw.GSF_HELD and g[fw._G_T] > 0.0:
            self._gsf_chord(sh)
            self.gsf_state = fw.GSF_ON
        elif self.gsf_state == fw.GSF_ON:
            self._gsf_bank(sh * sh)
        elif self.fix[2] >= 0.0:
            self._gsf_first(sh)
            self.gsf_state = fw.GSF_ON
        else:
            g[fw._G_HYP : fw._G_HYP + 2] = self.gnss_p[0:2]
            self.gsf_state = fw.GSF_HELD
        g[0:6] = ZERO
        if self.gsf_state != fw.GSF_ON:
            return 0
        return self._gsf_result()

    def _gsf_first(self, sh):
        sp = self.fix[2]
        vv = fw.V0_VAR
        if sp > 0.0:
            vv = vv + sp * sp
        self._gsf_spread(sh * sh, vv)

    def _gsf_chord(self, sh):
        """yaw_gsf._init_chord."""
        g = self.gsf
        t = g[fw._G_T]
        h = self._hyp()
        ve = (self.gnss_p[0] - h[0, 0]) / t
        vn = (self.gnss_p[1] - h[0, 1]) / t
        de = g[fw._G_A1] - g[fw._G_A2] / t
        dn = g[fw._G_A1 + 1] - g[fw._G_A2 + 1] / t
        r = sh * sh
        self._gsf_spread(r, ZERO)
        yv = h[0, fw._H_P + 32]
        vv = (r + r) / (t * t) + (de * de + dn * dn) * yv + fw.B0_VAR * (t * t) * HALF
        vv = vv + fw.V0_CHORD_VAR
        pv = r / t
        s = ref_fmath.sin(h[:, 4])
        c = ref_fmath.cos(h[:, 4])
        h[:, 2] = ve + (c * de - s * dn)
        h[:, 3] = vn + (s * de + c * dn)
        p = fw._H_P
        for i, v in ((2, pv), (14, pv), (10, pv), (22, pv), (16, vv), (24, vv)):
            h[:, p + i] = v

    def _gsf_spread(self, pp, vv):
        dy = TWO_PI / F32(K)
        yv = dy * HALF
        yv = yv * yv
        h = self._hyp()
        h[:] = ZERO
        h[:, 0] = self.gnss_p[0]
        h[:, 1] = self.gnss_p[1]
        h[:, 4] = (np.arange(K, dtype=F32) + HALF) * dy - PI
        p = fw._H_P
        for i, v in ((0, pp), (8, pp), (16, vv), (24, vv), (32, yv),
                     (40, fw.B0_VAR), (48, fw.B0_VAR)):  # fmt: skip
            h[:, p + i] = v
        h[:, fw._H_W] = ONE / F32(K)

    def _gsf_bank(self, rp):
        g = self.gsf
        h = self._hyp()
        x = h[:, 0:NST]
        P = h[:, fw._H_P : fw._H_W].reshape(K, NST, NST)
        t = g[fw._G_T]
        age = F32(self.tick - self.fix_tick) * self.cfg.dt_s
        if age < 0.0:
            age = ZERO
        self._gsf_predict(x, P, t, wrap(g[fw._G_DYAW]))
        d = self._gsf_update(x, P, 0, -age, self.gnss_p[0], rp)
        sp2 = self._s
        d = d + self._gsf_update(x, P, 1, -age, self.gnss_p[1], rp)
        sp2 = sp2 * self._s
        sp, co = self.fix[2], self.fix[3]
        if sp >= 0.0 and co >= 0.0:
            rv = g[fw._G_RV]
            d = d + self._gsf_update(x, P, 2, ZERO, sp * ref_fmath.sin(co), rv)
            sp2 = sp2 * self._s
            d = d + self._gsf_update(x, P, 3, ZERO, sp * ref_fmath.cos(co), rv)
            sp2 = sp2 * self._s
        x[:, 4] = wrap(x[:, 4])
        g[fw._G_D : fw._G_D + K] = d
        g[fw._G_S : fw._G_S + K] = sp2
        dmin = d.min()
        w = h[:, fw._H_W] * exp_neg((d - dmin) * HALF) / np.sqrt(sp2)
        total = ZERO
        for k in range(K):
            total = total + w[k]
        w = w / total if total > 0.0 else np.full(K, ONE / F32(K), F32)
        h[:, fw._H_W] = np.maximum(w, fw.W_MIN)

    def _gsf_predict(self, x, P, t, dyaw):
        g = self.gsf
        y = wrap(x[:, 4] - dyaw)
        x[:, 4] = y
        s = ref_fmath.sin(y)
        c = ref_fmath.cos(y)
        h2 = t * t * HALF
        u1e = g[fw._G_A1] - x[:, 5] * t
        u1n = g[fw._G_A1 + 1] - x[:, 6] * t
        u2e = g[fw._G_A2] - x[:, 5] * h2
        u2n = g[fw._G_A2 + 1] - x[:, 6] * h2
        r1e = c * u1e - s * u1n
        r1n = s * u1e + c * u1n
        r2e = c * u2e - s * u2n
        r2n = s * u2e + c * u2n
        x[:, 0] = x[:, 0] + x[:, 2] * t + r2e
        x[:, 1] = x[:, 1] + x[:, 3] * t + r2n
        x[:, 2] = x[:, 2] + r1e
        x[:, 3] = x[:, 3] + r1n
        ch, sh, ct, st = c * h2, s * h2, c * t, s * t
        col = (slice(None), None)  # a per-hypothesis factor against a row of 7
        fp = P.copy()
        b5, b6 = P[:, 5, :], P[:, 6, :]
        fp[:, 0] = P[:, 0] + t * P[:, 2] - r2n[col] * P[:, 4] - ch[col] * b5 + sh[col] * b6
        fp[:, 1] = P[:, 1] + t * P[:, 3] + r2e[col] * P[:, 4] - sh[col] * b5 - ch[col] * b6
        fp[:, 2] = P[:, 2] - r1n[col] * P[:, 4] - ct[col] * b5 + st[col] * b6
        fp[:, 3] = P[:, 3] + r1e[col] * P[:, 4] - st[col] * b5 - ct[col] * b6
        b5, b6 = fp[:, :, 5], fp[:, :, 6]
        q = fp.copy()
        q[:, :, 0] = (
            fp[:, :, 0] + t * fp[:, :, 2] - r2n[col] * fp[:, :, 4] - ch[col] * b5 + sh[col] * b6
        )
        q[:, :, 1] = (
            fp[:, :, 1] + t * fp[:, :, 3] + r2e[col] * fp[:, :, 4] - sh[col] * b5 - ch[col] * b6
        )
        q[:, :, 2] = fp[:, :, 2] - r1n[col] * fp[:, :, 4] - ct[col] * b5 + st[col] * b6
        q[:, :, 3] = fp[:, :, 3] + r1e[col] * fp[:, :, 4] - st[col] * b5 - ct[col] * b6
        qa = g[fw._G_QA]
        t2 = t * t
        qp = qa * (t2 * t) * fw.THIRD
        qx = qa * t2 * HALF
        qv = qa * t
        for i in range(2):
            q[:, i, i] = q[:, i, i] + qp
            q[:, i, i + 2] = q[:, i, i + 2] + qx
            q[:, i + 2, i] = q[:, i + 2, i] + qx
            q[:, i + 2, i + 2] = q[:, i + 2, i + 2] + qv
        q[:, 4, 4] = q[:, 4, 4] + g[fw._G_QW] * t
        qb = g[fw._G_QB] * t
        q[:, 5, 5] = q[:, 5, 5] + qb
        q[:, 6, 6] = q[:, 6, 6] + qb
        P[:] = q

    def _gsf_update(self, x, P, i, a, z, r):
        """yaw_gsf._update for every hypothesis: y^2 / S (S in self._s)."""
        i2 = i + 2 if i < 2 else i
        ph = P[:, :, i] + a * P[:, :, i2]
        s = ph[:, i] + a * ph[:, i2] + r
        y = z - (x[:, i] + a * x[:, i2])
        k = ph / s[:, None]
        x[:] = x + k * y[:, None]
        upd = P - k[:, :, None] * ph[:, None, :]  # row j: P[j] - k_j ph (its q >= j part)
        upper = np.triu(np.ones((NST, NST), bool))
        P[:] = np.where(upper, upd, np.swapaxes(upd, 1, 2))
        self._s = s
        return y * y / s

    def _gsf_result(self):
        g = self.gsf
        h = self._hyp()
        w = h[:, fw._H_W]
        sy = ref_fmath.sin(h[:, 4])
        cy = ref_fmath.cos(h[:, 4])
        se = ce = ve = vn = be = bn = ZERO
        for k in range(K):
            se = se + w[k] * sy[k]
            ce = ce + w[k] * cy[k]
            ve = ve + w[k] * h[k, 2]
            vn = vn + w[k] * h[k, 3]
            be = be + w[k] * h[k, 5]
            bn = bn + w[k] * h[k, 6]
        y = F32(ref_fmath.atan2(se, ce))
        dd = wrap(h[:, 4] - y)
        terms = w * (dd * dd + h[:, fw._H_P + 32])
        var = ZERO
        for k in range(K):
            var = var + terms[k]
        g[fw._G_YAW] = y
        g[fw._G_VAR] = var
        g[fw._G_V] = ve
        g[fw._G_V + 1] = vn
        g[fw._G_B] = be
        g[fw._G_B + 1] = bn
        if not var < g[fw._G_READY]:
            return 0
        if not (self.fix[2] >= 0.0 and self.fix[3] >= 0.0):  # positions alone: a start only
            if self.state == fw_nav.NAVIGATING or not var * fw.FOUR < g[fw._G_READY]:
                return 0
        r = fw.GSF_READY
        if self.state == fw_nav.NAVIGATING:
            y2 = y * y
            if y2 > fw.NINE * (var + self.kf.P[IX_ATT + 2, IX_ATT + 2]) and y2 > g[fw._G_RMIN]:
                r |= fw.GSF_DISAGREES
                if self.consistency[fw_nav._CN_MH] > fw.INNOV_BAD:
                    r |= fw.GSF_NAV_BAD
        return r

    # ---- the navigator's use of it ----

    def _gsf_watch(self):
        """nav._gsf_watch: True when the heading was reset to the bank's at this fix."""
        r = self._gsf_step()
        if not r & fw.GSF_DISAGREES:
            self.gsf_dis = 0
            return False
        t = self.tick
        if not self.gsf_dis:
            self.gsf_dis = t
        if t - self.gsf_dis < self.ticks_gsf:
            return False
        if self.rejects and self.jumped:  # nav._gsf_watch: the receiver jumped
            return False
        if not (r & fw.GSF_NAV_BAD or self.rejects or t < self.gated_until
                or t < self.drift_until):  # fmt: skip
            return False
        self._gsf_reset()
        return True

    def _gsf_align(self):
        """nav_align._gsf_align: True when navigation started from the bank."""
        if not self._gsf_step() & fw.GSF_READY:
            return False
        g = self.gsf
        ve, vn = g[fw._G_V], g[fw._G_V + 1]
        yaw = ref_rot.dcm_to_euler(self.ins.c_bn)[fw_rot.YAW] + g[fw._G_YAW]
        course = F32(ref_fmath.atan2(ve, vn))
        self._start_navigation(course, np.sqrt(ve * ve + vn * vn), self.cfg.init_vel_sigma,
                               g[fw._G_VAR])  # fmt: skip
        self._gsf_turn(yaw + course)
        return True

    def _gsf_reset(self):
        """nav_align._gsf_reset: heading, velocity and covariance from the bank."""
        g = self.gsf
        self._yaw_var(g[fw._G_VAR])
        v = np.array([g[fw._G_V], g[fw._G_V + 1], ZERO], F32)
        sh = self._sigma_h()
        self._restart(self.gnss_p, v, self.tick - self.fix_tick, sh, self._sigma_v(sh),
                      self.cfg.init_vel_sigma)  # fmt: skip
        self._gsf_turn(g[fw._G_YAW])
        self.rejects = 0
        self.v_rejects = 0
        self.gsf_dis = 0
        self.reset_until = fw_nav_aid.UNCONFIRMED
        self.resets += 1

    def _yaw_var(self, var):
        y = self.cfg.init_yaw_sigma
        y = y * y
        self.init_diag[IX_ATT + 2] = var if var > y else y

    def _gsf_turn(self, d):
        """nav_align._gsf_turn: the attitude turned by (b_N / g, -b_E / g, d) as a
        correction is applied; the bank's offsets less d, its force errors less b."""
        g = self.gsf
        be, bn = g[fw._G_B], g[fw._G_B + 1]
        d = wrap(F32(d))[()]
        dx = self.kf.dx
        dx[IX_ATT] = bn / fw_navcfg.G0_M_S2
        dx[IX_ATT + 1] = -be / fw_navcfg.G0_M_S2
        dx[IX_ATT + 2] = d
        self._apply_dx()
        self._turned(d)
        h = self._hyp()
        h[:, 5] = h[:, 5] - be
        h[:, 6] = h[:, 6] - bn

    def _turned(self, d):
        g = self.gsf
        g[fw._G_DYAW] = g[fw._G_DYAW] + wrap(F32(d))[()]
