"""NumPy float32 model of `firmware/lib/nav_align.py`: levelling, heading, navigation start.

`AlignmentModel` is a mixin of `NavModel` (nav.py), as the firmware's `Alignment` is of
`Navigator`: levelling from the mean specific force, the heading from the receiver's course or
from the track of the fixes, and the start of navigation.
"""

import numpy as np

from common import firmware_env
from host_emulator.model import fmath as ref_fmath
from host_emulator.model import rot as ref_rot
from host_emulator.model.eskf import IX_ATT
from host_emulator.model.f32ops import F32, HALF, TWO, ZERO, vec

firmware_env.install()
import fmath as fw_fmath  # noqa: E402
import nav as fw_nav  # noqa: E402  (constants shared with the firmware)
import nav_align as fw_nav_align  # noqa: E402
import rot as fw_rot  # noqa: E402

TR_SLOTS = fw_nav_align._TR_SLOTS


class AlignmentModel:
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
        if self.gsf_state:
            self._gsf_accum()
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
        if not g > fw_nav_align.MIN_LEVEL_F:  # no gravity to level on: start over
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

    def _align_fix(self):
        cfg = self.cfg
        self.last_fix_tick = self.tick
        if not self._fix_usable():
            self.n_stable = 0
            self.trk_set = 0
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
            self.trk_set = 0
            return
        # nav_align._align_fix: the yaw estimator's start, and the course's or the track's
        # with it (heading_from_course) or without it
        if cfg.yaw_gsf and (self._gsf_align() or not cfg.heading_from_course):
            return
        course = self.fix[3]
        sp = self.fix[2]
        # the receiver's course over ground, or its speed says it (nearly) stands: no track
        if course >= 0.0 or 0.0 <= sp < cfg.heading_speed_m_s:
            self.trk_set = 0
            if course >= 0.0 and sp >= cfg.heading_speed_m_s:
                s = cfg.gnss_vel_sigma / sp
                self._start_navigation(course, sp, cfg.init_vel_sigma, s * s)
        else:
            self._track()

    def _track(self):
        """No course: anchors (antenna E, N and yaw of earlier usable fixes, one per
        TR_SLOTS-th of track_max_s, the newest TR_SLOTS kept); the newest anchor track_s to
        track_max_s old whose chord d = p - p_anchor reaches track_min_m gives, for a yaw change
        |dyaw| <= track_turn_max (wrapped to +-pi) and a mean speed |d| / T from
        heading_speed_m_s on, the course atan2(d_E, d_N) - dyaw / 2 now, of variance
        2 sigma_h^2 / |d|^2; a failed window drops the anchors. This fix is added as an anchor
        when the newest is a slot's spacing old."""
        cfg = self.cfg
        gp = self.gnss_p
        c = self.ins.c_bn
        yaw = ref_fmath.atan2(-c[0, 1], c[1, 1])  # dcm_to_euler's yaw
        min2 = cfg.track_min_m * cfg.track_min_m
        i = self.trk_set - 1
        while i >= 0 and self.fix_tick - self.trk_ticks[i] <= self.ticks_track:
            if self.fix_tick - self.trk_ticks[i] >= self.ticks_track_min:
                de = gp[0] - self.track[i, 0]
                dn = gp[1] - self.track[i, 1]
                if de * de + dn * dn >= min2:
                    break
            i -= 1
        else:
            i = -1
        if i >= 0:
            self.trk_set = 0
            dyaw = yaw - self.track[i, 2]
            if dyaw > fw_fmath.PI:
                dyaw = dyaw - fw_fmath.TWO_PI
            elif dyaw < -fw_fmath.PI:
                dyaw = dyaw + fw_fmath.TWO_PI
            lim = cfg.track_turn_max
            if -lim <= dyaw <= lim:
                de = gp[0] - self.track[i, 0]
                dn = gp[1] - self.track[i, 1]
                d = np.sqrt(de * de + dn * dn)
                sp = d / (F32(self.fix_tick - self.trk_ticks[i]) * cfg.dt_s)
                if sp >= cfg.heading_speed_m_s:
                    course = ref_fmath.atan2(de, dn) - dyaw * HALF
                    r = self._sigma_h() / d
                    self._start_navigation(course, sp, cfg.track_vel_sigma, TWO * r * r)
                    return
        k = self.trk_set
        if k and self.fix_tick - self.trk_tick < self.ticks_track // TR_SLOTS:
            return
        if k == TR_SLOTS:
            self.track[:-1] = self.track[1:].copy()
            self.trk_ticks[:-1] = self.trk_ticks[1:]
            k -= 1
        self.track[k] = vec(gp[0], gp[1], yaw)
        self.trk_ticks[k] = self.fix_tick
        self.trk_tick = self.fix_tick
        self.trk_set = k + 1

    def _start_navigation(self, course, sp, sigma_vel, var_course):
        """Heading = course (yaw = -course), v = sp (sin, cos course, 0), p = antenna
        - C_bn lever, P = diag(init) with the fix's sigmas, sigma_vel horizontally and the
        yaw's max(init_yaw_sigma^2, var_course) (kept in init for later resets)."""
        y = self.cfg.init_yaw_sigma
        y = y * y
        self.init_diag[IX_ATT + 2] = var_course if var_course > y else y
        self._turned(-course - ref_rot.dcm_to_euler(self.ins.c_bn)[fw_rot.YAW])
        if self.fix[5] < 0.0:  # a receiver without height: the height is unknown
            self.consistency[fw_nav._CN_VV] = fw_nav_align.NO_HEIGHT_VAR
        ins = self.ins
        ypr = ref_rot.dcm_to_euler(ins.c_bn)
        ypr[fw_rot.YAW] = -course
        self.ypr = ypr
        ins.q_bn = ref_rot.euler_to_q(ypr)
        ins.c_bn = ref_rot.q_to_dcm(ins.q_bn)
        v = vec(sp * ref_fmath.sin(course), sp * ref_fmath.cos(course), 0)
        sh = self._sigma_h()
        age = self.tick - self.fix_tick
        self._restart(self.gnss_p, v, age, sh, self._sigma_v(sh), sigma_vel)
        ins.take_dvn()
        ins.slow_update(ZERO)
        self.since_prop = 0
        self.last_accept_tick = self.tick
        self.state = fw_nav.NAVIGATING
