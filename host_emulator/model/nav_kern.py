"""NumPy float32 model of `firmware/lib/nav_kern.py`: the navigator's Python kernels.

`KernelsModel` is a mixin of `NavModel` (nav.py), holding the model's counterparts of the
kernels nav.py calls from its per-tick flow, bit for bit with the firmware's
(`tests/model/test_nav_model.py`): the sample check (nav_kern.imu_check), the covariance's
uncertainty (nav_kern.uncertain), the drift and aiding watches (nav_kern.drift_watch,
nav_kern.aid_watch), the fixes' rate factor (nav_kern.rate_r), the receiver's unseen error
(nav_kern.consistency), its velocity noise (nav_kern.vel_noise) and the lag search
(nav_kern.lag_search). They work on NavModel's
named attributes where the firmware's work on the Navigator's buffers; the tuning constants
are nav_kern's own objects, the buffers' indices nav.py's.
"""

import numpy as np

from common import firmware_env
from host_emulator.model import fmath as ref_fmath
from host_emulator.model.f32ops import F32, HALF, ONE, ZERO

firmware_env.install()
import nav as fw_nav  # noqa: E402  (the buffers' indices, the status bits)
import nav_kern as fw_kern  # noqa: E402  (the kernels' tuning)

RING = fw_nav.RING


class KernelsModel:
    def _imu_check(self, g, a):
        """nav_kern.imu_check: over range, no new accel sample, all-zero or all-ones words, or
        counts unchanged for ticks_stuck ticks: not a sample."""
        st = self.imu_status
        if not st & fw_nav.IMU_REPEAT:  # a repeat of the same read is no evidence
            if g == self.prev_g:
                self.n_same_g = min(self.n_same_g + 1, self.ticks_stuck)
            else:
                self.n_same_g = 0
            if a == self.prev_a:
                self.n_same_a = min(self.n_same_a + 1, self.ticks_stuck)
            else:
                self.n_same_a = 0
            self.prev_g = g
            self.prev_a = a
        if st & fw_nav.IMU_OVER_RANGE or not st & fw_nav.IMU_FRESH:
            return True
        if a[0] in (0, -1) and set(g + a) == {a[0]}:
            return True
        return self.n_same_g >= self.ticks_stuck or self.n_same_a >= self.ticks_stuck

    def _uncertain(self):
        """nav_kern.uncertain: 1 if P puts the position's east or north 1-sigma beyond
        fault_sigma_m, or its vertical one beyond fault_sigma_v_m, else 0."""
        lim2 = self.cfg.fault_sigma_m * self.cfg.fault_sigma_m
        lim2_v = self.cfg.fault_sigma_v_m * self.cfg.fault_sigma_v_m
        P = self.kf.P
        # the height is not checked while the receiver gives none (the newest fix's sigma < 0)
        vert = P[2, 2] > lim2_v and self.fix[5] >= 0.0
        return 1 if max(P[0, 0], P[1, 1]) > lim2 or vert else 0

    def _drift_watch(self, innov, held):
        """nav_kern.drift_watch: running means of y / sqrt(S) of the position east, north, up
        and the velocity east and north; 2 (and both sets restarted) when one passes the
        limit, else 1 when one of the suspicion's (each ratio clipped at _BS_CLIP) passes
        _BS_LIMIT (the height's, while a drift is `held`: _BS_LEAVE), else 0; plus _DRIFT_H
        when a mean beyond its limit is a horizontal one."""
        bw, bs = self.drift_watch, self.suspect_watch
        a = fw_kern._BW_ALPHA / self.consistency[fw_nav._CN_RK]  # a fix: 1 / rk of a second's
        hit = 0
        hz = 0
        for j, (y, s) in enumerate(innov[: fw_nav._BW_N]):
            if s > 0.0:
                q = min(max(y / np.sqrt(s), -fw_kern._BW_CLIP), fw_kern._BW_CLIP)
                bw[j] = bw[j] + a * (q - bw[j])
                beyond = abs(bw[j]) > fw_kern._BW_LIMIT
                if beyond:
                    hit = 2
                q = min(max(q, -fw_kern._BS_CLIP), fw_kern._BS_CLIP)
                bs[j] = bs[j] + a * (q - bs[j])
                if abs(bs[j]) > fw_kern._BS_LIMIT:
                    beyond = True
                    hit = max(hit, 1)
                elif held and j == 2 and hit == 0 and abs(bs[j]) > fw_kern._BS_LEAVE:
                    hit = 1
                if beyond and j != 2:  # not the height's
                    hz = fw_nav._DRIFT_H
        if hit == 2:
            bw[:] = ZERO
            bs[:] = ZERO
        return hit | hz

    def _aid_watch(self, innov):
        """nav_kern.aid_watch: running means of y / sqrt(S) (clipped at _BW_CLIP) of the
        non-holonomic constraint's lateral and vertical rows, and of the zero-velocity
        update's up row into the vertical one; the _AW_HIT_* bits of those beyond their
        limits."""
        if len(innov) == 2:
            rows = ((fw_nav._AW_LAT, innov[0]), (fw_nav._AW_UP, innov[1]))
        elif len(innov) == 3:
            rows = ((fw_nav._AW_UP, innov[2]),)
        else:
            return 0
        aw = self.aid_watch
        hit = 0
        for k, (y, s) in rows:
            if s > 0.0:
                q = min(max(y / np.sqrt(s), -fw_kern._BW_CLIP), fw_kern._BW_CLIP)
                aw[k] = aw[k] + fw_kern._BW_ALPHA * (q - aw[k])
                lim = fw_kern._AW_LIMIT_LAT if k == fw_nav._AW_LAT else fw_kern._AW_LIMIT_UP
                if abs(aw[k]) > lim:
                    hit |= 1 << k
        return hit

    def _rate_r(self):
        """nav_kern.rate_r: the factor on the fix's position variances, the fixes a second the
        filter takes (1 to 10), from this fix's measurement tick and the last one taken."""
        d = self.fix_tick - self.last_used_tick
        if self.last_used_tick == 0 or d <= 0 or d >= self.ticks_second:
            return ONE
        d = max(d, self.ticks_second // 10)
        return F32(self.ticks_second) / F32(d)

    def _consistency(self, innov, mask):
        """nav_kern.consistency: after a fix whose three position rows were accepted, the running
        means of y^2/S (east/north, up) over _CN_N seconds of fixes and the unseen variances
        (1 - mean) sigma^2, or (mean - 1) times P's above a mean of 1; then, from
        the velocity rows, the fixes' lag behind their stamps and the ticks applied."""
        if len(innov) < 3 or mask & 7:
            return
        (ye, se), (yn, sn), (yu, su) = innov[:3]
        if not (se > 0.0 and sn > 0.0 and su > 0.0):
            return
        cn = self.consistency
        k = min(cn[fw_nav._CN_K] + ONE / cn[fw_nav._CN_RK], fw_kern._CN_N)
        cn[fw_nav._CN_K] = k
        a = ONE / k
        qe = min(ye * ye / se, fw_kern._CN_CLIP)
        qn = min(yn * yn / sn, fw_kern._CN_CLIP)
        qu = min(yu * yu / su, fw_kern._CN_CLIP)
        qh = (qe + qn) * HALF
        cn[fw_nav._CN_MH] = cn[fw_nav._CN_MH] + a * (qh - cn[fw_nav._CN_MH])
        sig = self.used[5]
        p = self.kf.P
        if cn[fw_nav._CN_MH] < ONE:
            cn[fw_nav._CN_VH] = (ONE - cn[fw_nav._CN_MH]) * (sig * sig)
        else:  # more scatter than S says: (mean - 1) times P's
            cn[fw_nav._CN_VH] = (cn[fw_nav._CN_MH] - ONE) * ((p[0, 0] + p[1, 1]) * HALF)
        sig = self.used[6]  # < 0: the fix had no height, and the state's is unknown
        cn[fw_nav._CN_VV] = fw_kern.NO_HEIGHT_VAR
        if sig > 0.0:
            cn[fw_nav._CN_MV] = cn[fw_nav._CN_MV] + a * (qu - cn[fw_nav._CN_MV])
            if cn[fw_nav._CN_MV] < ONE:
                cn[fw_nav._CN_VV] = (ONE - cn[fw_nav._CN_MV]) * (sig * sig)
            else:
                cn[fw_nav._CN_VV] = (cn[fw_nav._CN_MV] - ONE) * p[2, 2]

    def _vel_noise(self, innov, mask):
        """nav_kern.vel_noise: after a fix whose velocity rows (the 4th and 5th scalars) were
        accepted with S - R below _VR_MAX, the innovation kept and, when the last fix's was
        kept too, the running mean of its change squared over 2 less S - R: the receiver's
        velocity variance the rows take next, between gnss_vel_sigma^2 and _VR_MAX."""
        cn = self.consistency
        rv = cn[fw_nav._CN_RVEL]
        if len(innov) < 5 or mask & 0x18:
            cn[fw_nav._CN_VOK] = ZERO
            return
        (ye, se), (yn, sn) = innov[3:5]
        if not (se > 0.0 and sn > 0.0) or se - rv > fw_kern._VR_MAX or sn - rv > fw_kern._VR_MAX:
            cn[fw_nav._CN_VOK] = ZERO
            return
        de = ye - cn[fw_nav._CN_VE]
        dn = yn - cn[fw_nav._CN_VN]
        ok = cn[fw_nav._CN_VOK]
        cn[fw_nav._CN_VE], cn[fw_nav._CN_VN], cn[fw_nav._CN_VOK] = ye, yn, ONE
        if not ok > 0.0:
            return
        k = min(cn[fw_nav._CN_KR] + ONE / cn[fw_nav._CN_RK], fw_kern._VR_N)
        cn[fw_nav._CN_KR] = k
        k = max(k, ONE)
        a = ONE / k
        q = ((de * de + dn * dn) * HALF - ((se - rv) + (sn - rv))) * HALF
        cn[fw_nav._CN_V2] = cn[fw_nav._CN_V2] + a * (q - cn[fw_nav._CN_V2])
        lo = self.cfg.gnss_vel_sigma * self.cfg.gnss_vel_sigma
        rv = lo
        if k >= fw_kern._VR_K0:
            rv = min(max(cn[fw_nav._CN_V2], lo), fw_kern._VR_MAX)
        cn[fw_nav._CN_RVEL] = rv

    def _lag_search(self, age):
        """nav_kern.lag_search: per candidate lag, the change of the velocity residual against the
        ring's track between consecutive fixes, its running mean of squares, and the lag
        applied (the least, shrunk by the evidence against no lag)."""
        cn = self.consistency
        ls = self.lag_search
        nc, step = fw_nav._LS_C, fw_nav._LS_STEP
        t = self.fix_tick - self.lag_tick
        if self.lag_tick != 0 and 0 <= t < self.ticks_second - self.ticks_second // 4:
            return  # pairs about a second apart at any rate
        self.lag_tick = self.fix_tick
        course, sp = self.fix[3], self.fix[2]
        if (not self.cfg.gnss_lag_learn or course < 0.0 or not sp * sp > fw_kern._LAG_V2
                or age < 0 or age + step * (nc - 1) > RING - 1
                or self.tick < self.drift_until or self.tick < self.gated_until):  # fmt: skip
            self.lag_tick = 0
            return
        ve = sp * ref_fmath.sin(course)
        vn = sp * ref_fmath.cos(course)
        le, ln = self._lever_vel_n()[:2]
        pair = 1 <= t <= 2 * self.ticks_second
        k = cn[fw_nav._CN_KL]
        if pair:
            k = min(k + ONE, fw_kern._CN_N)
            cn[fw_nav._CN_KL] = k
        a = ONE / k if pair else ZERO
        best = 0
        for j in range(nc):
            v = self.ring_v[(self.tick - (age + j * step)) % RING]
            ye = (v[0] + le) - ve
            yn = (v[1] + ln) - vn
            if pair:
                de = ye - ls[fw_nav._LS_E + j]
                dn = yn - ls[fw_nav._LS_N + j]
                m = fw_nav._LS_M + j
                ls[m] = ls[m] + a * ((de * de + dn * dn) - ls[m])
                if ls[m] < ls[fw_nav._LS_M + best]:
                    best = j
            ls[fw_nav._LS_E + j] = ye
            ls[fw_nav._LS_N + j] = yn
        if not pair:
            return
        dt = self.ins.dt
        lag = F32(best * step) * dt
        cn[fw_nav._CN_LAG] = lag
        cn[fw_nav._CN_LAGT] = ZERO
        if best == 0 or k < fw_kern._LAG_K0:
            return
        m = ls[fw_nav._LS_M + best]
        if not m > 0.0:
            return
        q = k * (ls[fw_nav._LS_M] - m) / m
        if q < ONE:
            return
        lag = lag * q / (ONE + q)
        cn[fw_nav._CN_LAGT] = F32(int(lag / dt + HALF))
