"""NumPy float32 model of `firmware/lib/nav_aid.py`: the measurement rows and the GNSS reset.

`AidingModel` is a mixin of `NavModel` (nav.py), as the firmware's `Aiding` is of `Navigator`:
the GNSS position and velocity rows with the lever arm, the zero-velocity update, the
non-holonomic constraint, the reset to GNSS, the lever arm in the navigation frame and the
fix's sigmas. Rows are queued as (z, r, [(k, h_k), ...]) in the firmware's order of non-zeros.
"""

import numpy as np

from common import firmware_env
from host_emulator.model import fmath as ref_fmath
from host_emulator.model.eskf import IX_ATT, IX_POS, IX_VEL
from host_emulator.model.f32ops import F32, ONE, ZERO, cross, mat_vec, vec

firmware_env.install()
import nav as fw_nav  # noqa: E402  (the buffers' indices)
import nav_aid as fw_nav_aid  # noqa: E402  (UNCONFIRMED)


class AidingModel:
    def _lever_n(self):
        """C_bn lever_b: the antenna offset in the navigation frame."""
        return mat_vec(self.ins.c_bn, self.cfg.lever_b_m)

    def _lever_vel_n(self):
        """C_bn ((w - bg) x lever_b): the antenna's velocity from the lever arm
        (nav_aid.lever_vel)."""
        return mat_vec(self.ins.c_bn, cross(self.w_b - self.ins.bg, self.cfg.lever_b_m))

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

    def _start_gnss_update(self, slot, rk):
        """Antenna position p + C_bn l against the fix at its measurement time (ring slot
        `slot`, plus the corrections injected since): z = dp + [(C l) x] phi; and, with a
        course, the horizontal velocity v + C_bn (w x l) against speed (sin, cos course). The
        position variances times rk (nav_kern.rate_r)."""
        kf = self.kf
        p_then = self.ring_p[slot]
        v_then = self.ring_v[slot]
        corr = self.corr
        lx, ly, lz = self._lever_n()
        sh = self._sigma_h()
        sv = self._sigma_v(sh)
        rh = sh * sh * rk
        rv = sv * sv * rk
        gp = self.gnss_p
        sv_used = sv
        if self.fix[5] < 0.0:  # no height: the state's own, and v_U held at 0 instead
            gp[2] = (p_then[2] + corr[2]) + lz
            sv_used = -sv
        self.used = np.array([gp[0], gp[1], gp[2], self.fix[2], self.fix[3], sh, sv_used], F32)
        self.used_tick = self.fix_tick
        att = IX_ATT
        z = (p_then[0] + corr[0] + lx) - gp[0]
        kf.add_scalar(z, rh, [(0, ONE), (att + 1, -lz), (att + 2, ly)])
        z = (p_then[1] + corr[1] + ly) - gp[1]
        kf.add_scalar(z, rh, [(1, ONE), (att, lz), (att + 2, -lx)])
        if sv_used > 0.0:
            z = (p_then[2] + corr[2] + lz) - gp[2]
            kf.add_scalar(z, rv, [(2, ONE), (att, -ly), (att + 1, lx)])
        else:  # a level world's vertical velocity, 1-sigma 1 m/s
            kf.add_scalar(v_then[2] + corr[5], ONE, [(IX_VEL + 2, ONE)])
        course = self.fix[3]
        sp = self.fix[2]
        if course >= 0.0:
            ve = sp * ref_fmath.sin(course)
            vn = sp * ref_fmath.cos(course)
            lever_vel_n = self._lever_vel_n()
            rvel = self.consistency[fw_nav._CN_RVEL]  # learned (nav_kern.vel_noise)
            z = (v_then[0] + corr[3] + lever_vel_n[0]) - ve
            kf.add_scalar(z, rvel, [(IX_VEL, ONE)])
            z = (v_then[1] + corr[4] + lever_vel_n[1]) - vn
            kf.add_scalar(z, rvel, [(IX_VEL + 1, ONE)])
        kf.start_update()

    def _start_zupt(self):
        """Zero-velocity update: z = v_n[i] = dv_i + noise."""
        kf = self.kf
        r = self.cfg.zupt_sigma * self.cfg.zupt_sigma
        for i in range(3):
            kf.add_scalar(self.ins.v_n[i], r, [(IX_VEL + i, ONE)])
        kf.start_update()

    def _start_nhc(self):
        """Body x (lateral) and z (vertical) velocity are zero: z = c_k . v_n with c_k the k-th
        column of C_bn, h = [0, c_k, v_n x c_k, 0, 0]."""
        kf = self.kf
        ins = self.ins
        v = ins.v_n
        r = self.cfg.nhc_sigma * self.cfg.nhc_sigma
        body_v = mat_vec(ins.c_bn.T, v)  # C_bn^T v: (c_k . v) summed in the firmware's order
        for k in (0, 2):
            c_k = ins.c_bn[:, k]
            h_att = cross(v, c_k)
            terms = [(IX_VEL + j, c_k[j]) for j in range(3)]
            terms += [(IX_ATT + j, h_att[j]) for j in range(3)]
            kf.add_scalar(body_v[k], r, terms)
        kf.start_update()

    def _reset_to_gnss(self):
        """From the fix the last update rejected: p, horizontal v (from its course, else the
        INS's), a fresh P; attitude kept, bias estimates back to 0 (the calibration).
        (Not asked for after a jump: nav._inject.)"""
        ins = self.ins
        u = self.used
        course, sp = u[4], u[3]
        p = self.kf.P
        var_h = p[IX_POS, IX_POS] + p[IX_POS + 1, IX_POS + 1] + F32(2) * (u[5] * u[5])
        prev_d = self.reset_d.copy()
        drift = self.rejects < self.cfg.reset_after_rejects  # nav_aid: a sensor step's reset
        vz = ins.v_n[2] if drift else F32(0)
        if course >= 0.0:
            v = vec(sp * ref_fmath.sin(course), sp * ref_fmath.cos(course), 0)
        else:
            v = vec(ins.v_n[0], ins.v_n[1], 0)
            if sp >= 0.0:  # nav_aid: the navigator's direction, no faster than the fix's speed
                v2 = v[0] * v[0] + v[1] * v[1]
                if v2 > sp * sp:
                    k = sp / np.sqrt(v2)
                    v[0] = v[0] * k
                    v[1] = v[1] * k
        v[2] = vz
        sigma_vel = self.cfg.init_vel_sigma if course >= 0.0 else self.cfg.track_vel_sigma
        self._restart(u[0:3], v, self.tick - self.used_tick, u[5], u[6], sigma_vel, drift)
        ins.bg = np.zeros(3, F32)
        ins.ba = np.zeros(3, F32) if not drift else np.array([0, 0, ins.ba[2]], F32)
        self.rejects = 0
        self.v_rejects = 0
        self.reset_until = fw_nav_aid.UNCONFIRMED
        self.resets += 1
        self._hold(var_h, prev_d)

    def _hold(self, var_h, prev_d):
        """nav_aid.Aiding._hold: gnss_implausible held after a reset whose step is beyond
        _HOLD_K2 var_h, until _STEP_HOLD_S after the last accepted fix; ended by a reset that
        undoes the one before (prev_d) within _STEP_M."""
        d = self.reset_d
        if self.tick < self.implausible_until:
            u = d + prev_d
            if u[0] * u[0] + u[1] * u[1] < fw_nav_aid._STEP_M * fw_nav_aid._STEP_M:
                self.implausible_until = self.tick
                return
        if d[0] * d[0] + d[1] * d[1] > fw_nav_aid._HOLD_K2 * var_h:
            u = self.last_accept_tick + fw_nav_aid._STEP_HOLD_S * self.ticks_second
            self.implausible_until = max(self.implausible_until, u)

    def _jumped(self):
        """nav_aid._jumped: the fix just used farther from the last one the filter took than
        the INS's speed times the time between them, plus _JUMP_M and _STEP_HALF_A t^2; or,
        with a course and t up to _JUMP_VEL_S, farther than that margin from it moved by the
        fix's own velocity."""
        if self.last_used_tick == 0:
            return False
        t = F32(self.used_tick - self.last_used_tick) * self.cfg.dt_s
        de = self.used[0] - self.last_fix_en[0]
        dn = self.used[1] - self.last_fix_en[1]
        v = self.ins.v_n
        margin = fw_nav_aid._JUMP_M + fw_nav_aid._STEP_HALF_A * (t * t)
        reach = np.sqrt(v[0] * v[0] + v[1] * v[1]) * t + margin
        if de * de + dn * dn > reach * reach:
            return True
        course, sp = self.used[4], self.used[3]
        if course < 0.0 or t > fw_nav_aid._JUMP_VEL_S:
            return False
        de = de - sp * ref_fmath.sin(course) * t
        dn = dn - sp * ref_fmath.cos(course) * t
        return bool(de * de + dn * dn > margin * margin)

    def _last_fix(self):
        """nav_aid._last_fix."""
        self.last_fix_en = self.used[0:2].copy()
        self.last_used_tick = self.used_tick

    def _beyond_drift(self, ye, yn):
        """nav_aid._beyond_drift: an east/north innovation beyond _STEP_M + _STEP_HALF_A t^2,
        t the time since the last accepted fix."""
        t = F32(self.tick - self.last_accept_tick) * self.cfg.dt_s
        lim = fw_nav_aid._STEP_M + fw_nav_aid._STEP_HALF_A * (t * t)
        return bool(ye * ye + yn * yn > lim * lim)

    def _refused(self):
        """nav_aid.refused: the reset to a jumped run's fix refused unless the jump undoes the
        last reset: beyond the drift bound, or within _STEP_HOLD_S unless the INS drifted
        from where the jump put the fixes beyond the bound."""
        d = self.jump_y0 - self.reset_d
        if d[0] * d[0] + d[1] * d[1] < fw_nav_aid._STEP_M * fw_nav_aid._STEP_M:
            return False
        ye, yn = self.kf.innov[0][0], self.kf.innov[1][0]
        if self._beyond_drift(ye, yn):
            return True
        if self.tick - self.last_accept_tick >= fw_nav_aid._STEP_HOLD_S * self.ticks_second:
            return False
        return not self._beyond_drift(ye - self.jump_y0[0], yn - self.jump_y0[1])

    def _reset_vertical(self):
        """The height from the fix the last update rejected, vertical velocity 0, their rows
        and columns of P afresh; the step into the corrections (the delay ring's reference)."""
        ins = self.ins
        h = self.used[2] - self._lever_n()[2]
        self.corr[2] = self.corr[2] + (h - ins.p_n[2])
        self.corr[5] = self.corr[5] - ins.v_n[2]
        ins.p_n[2] = h
        ins.v_n[2] = ZERO
        ins.p_comp[2] = ZERO
        P = self.kf.P
        sv = self.used[6]
        for i, var in ((IX_POS + 2, sv * sv), (IX_VEL + 2, self.init_diag[IX_VEL + 2])):
            P[i, :] = ZERO
            P[:, i] = ZERO
            P[i, i] = var
        self.v_rejects = 0
        self.reset_until = fw_nav_aid.UNCONFIRMED
        self.resets += 1
