"""NumPy float32 model of `firmware/lib/nav.py`: the navigator, tick by tick, bit for bit.

An independent implementation of the same equations, written at vector level where the
firmware loops, that repeats every float32 operation of the firmware in the same order and
grouping (f32ops.py says how). Fed the same inputs, its state equals the firmware's bit for bit
after every tick (`tests/model/test_nav_model.py`): position, velocity, attitude, biases, the
15x15 covariance *between* the slices of the time-distributed filter, the state-history ring,
the standstill detector and every counter. Frames, units and sign conventions are the
firmware's (ENU navigation frame at an integer origin, body x right / y forward / z up, error
state dp dv phi dbg dba with nominal-minus-true errors); see the firmware modules.

The files mirror the firmware's, one model beside each firmware module:
- ins.py `InsModel` (firmware/lib/ins.py), eskf.py `EskfModel` (eskf.py);
- here `NavModel` (nav.py): inputs, calibration, standstill, the per-tick flow, fix screening
  and re-anchoring (with geo.LocalFrame's origin), the delay ring, scheduling, injection,
  resets, health, and `snapshot` for the comparisons;
- nav_align.py `AlignmentModel` (nav_align.py) and nav_aid.py `AidingModel` (nav_aid.py),
  mixins of NavModel as the firmware's are of Navigator; nav_kern.py `KernelsModel`
  (nav_kern.py: the sample check, the watches, rate_r, consistency, the lag search), a mixin
  holding the counterparts of the Python kernels nav.py calls;
- sin, cos, atan2, asin, quaternions and the geodetic series from the bit-exact models
  fmath.py, rot.py and geo.py; constants are the firmware modules' own objects (the few the
  firmware builds inline, P floors and ceilings, are rebuilt from the same integer ratios).
"""

import numpy as np

from common import firmware_env
from host_emulator.model import geo as ref_geo
from host_emulator.model import rot as ref_rot
from host_emulator.model.eskf import IDLE, IX_ATT, IX_BA, IX_BG, IX_POS, IX_VEL, EskfModel, N
from host_emulator.model.f32ops import (
    F32,
    HALF,
    ONE,
    TWO,
    ZERO,
    mat_vec,
    ratio,
    sum_left,
    vec,
)  # fmt: skip
from host_emulator.model.ins import InsModel
from host_emulator.model.nav_aid import AidingModel
from host_emulator.model.nav_align import AlignmentModel
from host_emulator.model.nav_kern import KernelsModel
from host_emulator.model.yaw_gsf import PARTS as GSF_PARTS
from host_emulator.model.yaw_gsf import GsfModel

firmware_env.install()
import geo as fw_geo  # noqa: E402
import nav as fw_nav  # noqa: E402  (constants shared with the firmware)
import nav_align as fw_nav_align  # noqa: E402
import nav_kern  # noqa: E402  (... and the kernels' tuning)
import yaw_gsf as fw_gsf  # noqa: E402


def _rate_slices(interval, configured):
    """nav._rate_slices: 4 slices per tick for fixes fewer than _SLICES_4_BELOW ticks apart,
    2 below _SLICES_2_BELOW, else 1; never fewer than configured."""
    if 0 < interval < fw_nav._SLICES_4_BELOW:
        return max(4, configured)
    if 0 < interval < fw_nav._SLICES_2_BELOW:
        return max(2, configured)
    return configured


ALIGNING = fw_nav.ALIGNING
NAVIGATING = fw_nav.NAVIGATING
RING = fw_nav.RING
# The job codes are private consts in the firmware (inlined on the board, no global there);
# on CPython they are plain module attributes, so the model reads them rather than retyping.
JOB_NONE = fw_nav._JOB_NONE
JOB_GNSS = fw_nav._JOB_GNSS
JOB_AID = fw_nav._JOB_AID


def _ticks(seconds, dt):
    """Whole ticks in `seconds`: int(seconds / dt + 0.5), rounded in float32, truncated."""
    return int(F32(seconds) / dt + HALF)


class NavModel(AlignmentModel, AidingModel, KernelsModel, GsfModel):
    """The navigator tick by tick like `nav.Navigator` (same inputs: `imu_raw`/`imu`, `gnss`):
    mechanization, scheduling, injection, resets, health and re-anchoring here, alignment in
    AlignmentModel (nav_align.py), the measurement rows in AidingModel (nav_aid.py), the
    kernels nav.py calls (sample check, watches, lag search...) in KernelsModel (nav_kern.py)."""

    def __init__(self, cfg):
        self.cfg = cfg
        self.slices = cfg.slices_per_tick  # filter slices per tick (_nav_fix: the fix rate's)
        dt = cfg.dt_s
        self.ins = InsModel(dt, cfg.earth_terms, cfg.coning)
        self.kf = EskfModel(cfg.earth_terms)
        # the integer origin and its float32 coefficients (geo.LocalFrame)
        self.origin_lat_e7 = 0
        self.origin_lon_e7 = 0
        self.frame_valid = False
        self.coef = np.zeros(fw_geo.NCOEF, F32)
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
        # the track anchors (heading without a receiver course), oldest first: antenna E, N
        # of the anchor fix and the yaw of the attitude when it was processed; their ticks
        self.track = np.zeros((fw_nav_align._TR_SLOTS, 3), F32)
        self.trk_ticks = [0] * fw_nav_align._TR_SLOTS
        self.ticks_prop = _ticks(cfg.prop_period_s, dt)
        self.ticks_zupt = _ticks(cfg.zupt_period_s, dt)
        self.ticks_nhc = _ticks(cfg.nhc_period_s, dt)
        self.ticks_level = _ticks(cfg.level_s, dt)
        self.ticks_still = _ticks(cfg.still_s, dt)
        self.ticks_timeout = _ticks(cfg.gnss_timeout_s, dt)
        self.ticks_latency = _ticks(cfg.gnss_latency_s, dt)
        self.ticks_stamp_lag = _ticks(cfg.gnss_stamp_lag_s, dt)
        self.ticks_second = _ticks(F32(1), dt)
        self.ticks_track = max(_ticks(cfg.track_max_s, dt), 1)
        self.ticks_track_min = _ticks(cfg.track_s, dt)
        self.ticks_stuck = max(_ticks(cfg.imu_stuck_s, dt), 1)
        self.imu_status = 0  # the IMU driver's status word of this tick (nav.IMU_*)
        self.prev_g = [0, 0, 0]  # the last counts
        self.prev_a = [0, 0, 0]
        self._set_noise(cfg)
        self._gsf_init_tuning(cfg)
        self._reset_counters()

    def _set_noise(self, cfg):
        """Q per second: velocity VRW^2, attitude ARW^2, biases 2 sigma^2 / tau (first-order
        Gauss-Markov); P floors and ceilings; the initial diagonal (its position part is set
        from the fix when navigation starts); the gate and 1/tau."""
        kf = self.kf
        vrw2 = cfg.accel_vrw * cfg.accel_vrw
        arw2 = cfg.gyro_arw * cfg.gyro_arw
        qbg = TWO * cfg.gyro_bias_sigma * cfg.gyro_bias_sigma / cfg.gyro_bias_tau_s
        qba = TWO * cfg.accel_bias_sigma * cfg.accel_bias_sigma / cfg.accel_bias_tau_s
        # per block of three: position, velocity, attitude, gyro bias, accelerometer bias
        kf.q_psd = np.repeat(vec(0, vrw2, arw2, qbg, qba), 3)
        kf.p_floor = np.repeat(
            vec(
                ratio(1, 10000),  # (1 cm)^2
                ratio(1, 1000000),  # (1 mm/s)^2
                ratio(1, 100000000),  # (0.1 mrad)^2
                ratio(1, 1000000) * ratio(1, 1000000),  # (1e-6 rad/s)^2
                ratio(1, 100000000),  # (1e-4 m/s^2)^2
            ),
            3,
        )
        kf.p_ceiling = np.repeat(vec(100000000, 10000, 10, ratio(1, 100), 1), 3)
        ini = self.init_diag
        ini[IX_VEL : IX_VEL + 3] = cfg.init_vel_sigma * cfg.init_vel_sigma
        ini[IX_BG : IX_BG + 3] = cfg.init_gyro_bias_sigma * cfg.init_gyro_bias_sigma
        ini[IX_BA : IX_BA + 3] = cfg.init_accel_bias_sigma * cfg.init_accel_bias_sigma
        tilt2 = cfg.init_tilt_sigma * cfg.init_tilt_sigma
        ini[IX_ATT] = tilt2
        ini[IX_ATT + 1] = tilt2
        ini[IX_ATT + 2] = cfg.init_yaw_sigma * cfg.init_yaw_sigma
        kf.set_gate(cfg.gate_sigma, ONE / cfg.gyro_bias_tau_s, ONE / cfg.accel_bias_tau_s)

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
        self.trk_set = 0  # track anchors held
        self.trk_tick = 0  # the newest one's measurement tick
        self.last_accept_tick = 0
        self.rejects = 0
        self.v_rejects = 0  # heights rejected in a row
        self.gated_until = 0
        self.fault_until = 0
        self.sat_until = 0
        self.held_until = 0
        self.dead_until = 0
        self.reset_until = 0
        self.data_until = 0
        self.causes = 0
        self.uncertain = 0
        self.n_held = 0  # IMU samples held in a row
        self.n_same_g = 0  # unchanged gyro / accel samples in a row
        self.n_same_a = 0
        self.inflate = 0  # nav._INFLATE_* bits: P to widen at the next job
        self.drift_until = 0
        self.step_until = 0  # nav._C_STEP_UNTIL: a constraint broken (a sensor step) until
        self.implausible_until = 0  # nav._C_IMPLAUSIBLE_UNTIL
        self.jumped = False  # nav._C_JUMPED
        self.jump_y0 = np.zeros(2, F32)  # nav._M_JUMP: the jumped run's first innovation
        self.reset_d = np.zeros(2, F32)  # nav._M_RESET_D: the last reset's step in position
        self.last_fix_en = np.zeros(2, F32)  # nav._M_LAST: the last fix the filter took
        self.last_used_tick = 0  # ... its measurement tick (nav._C_LAST_TICK; 0: none)
        self.prev_fix = (0, 0)  # the last usable fix's lat, lon (1e-7 deg; nav._C_PREV_FIX)
        self.frozen = False  # nav._C_FROZEN
        self.drift_watch = np.zeros(fw_nav._BW_N, F32)  # running means of normalised innovations
        self.suspect_watch = np.zeros(fw_nav._BW_N, F32)  # ... clipped at _BS_CLIP: suspicion
        self.aid_watch = np.zeros(2, F32)  # nav._M_AW: the aiding watch's running means
        # the receiver's unseen error and the fixes' lag (nav_kern.consistency, layout nav._CN_*)
        self.consistency = np.zeros(fw_nav._NCN, F32)
        # ... and its velocity noise, from the setting (nav_kern.vel_noise)
        self.consistency[fw_nav._CN_RVEL] = self.cfg.gnss_vel_sigma * self.cfg.gnss_vel_sigma
        self.lag_search = np.zeros(fw_nav._NLS, F32)  # nav_kern.lag_search's residuals and means
        self.lag_tick = 0  # measurement tick of the last fix the lag search took (0: none)
        self.since_prop = 0
        self.since_zupt = 0
        self.since_nhc = 0
        self.job = JOB_NONE
        self.updates = 0  # GNSS updates run
        self.resets = 0  # resets to GNSS and fault resets
        self.reanchors = 0  # origin moves

    # ---- frame (geo.LocalFrame) ----

    def _set_origin(self, lat_e7, lon_e7, h_m):
        if lat_e7 > fw_geo.MAX_LAT_E7 or lat_e7 < -fw_geo.MAX_LAT_E7:
            return False
        self.coef = ref_geo.coefficients(lat_e7, h_m)
        self.origin_lat_e7 = lat_e7
        self.origin_lon_e7 = lon_e7
        self.frame_valid = True
        return True

    def _to_enu(self, lat_e7, lon_e7, h_m):
        dlon = lon_e7 - self.origin_lon_e7
        if dlon > ref_geo.HALF_TURN_E7:
            dlon -= ref_geo.FULL_TURN_E7
        elif dlon < -ref_geo.HALF_TURN_E7:
            dlon += ref_geo.FULL_TURN_E7
        return ref_geo.offset_to_enu(self.coef, lat_e7 - self.origin_lat_e7, dlon, h_m)

    # ---- inputs ----

    def imu_raw(self, gyro_counts, accel_counts, saturated=False, fresh=True, repeat=False):
        """A tick of BMI055 counts; a sample that cannot be a working sensor's is replaced by
        the previous one (nav_kern.imu_check); repeat: a missed tick's repeat of the last read."""
        self.imu_status = (1 if saturated else 0) | (fw_nav.IMU_FRESH if fresh else 0)
        if repeat:
            self.imu_status |= fw_nav.IMU_REPEAT
        g = [int(v) for v in gyro_counts]
        a = [int(v) for v in accel_counts]
        if self._imu_check(g, a):
            s = sum_left([*self.w_b, *self.f_b])
            self._tick(s - s == 0.0, True)
            return
        w = np.asarray(g, dtype=F32) / self.cfg.gyro_counts_per_rad_s
        f = np.asarray(a, dtype=F32) / self.cfg.accel_counts_per_m_s2
        self._tick(self._calibrate(w, f), False)

    def imu(self, w_in, f_in, saturated=False):
        self.imu_status = 1 if saturated else 0
        self._tick(self._calibrate(w_in, f_in), False)

    def _tick(self, finite, held):
        self.tick += 1
        t = self.tick
        if self.imu_status & fw_nav.IMU_OVER_RANGE:
            self.sat_until = t + self.ticks_second
        if held:
            self.held_until = t + self.ticks_second
            self.n_held = min(self.n_held + 1, self.ticks_stuck)
            if self.n_held >= self.ticks_stuck:
                self.dead_until = t + self.ticks_second
        else:
            if self.n_held >= self.ticks_stuck:
                self.inflate |= fw_nav._INFLATE_MOTION
            self.n_held = 0
        if not finite:
            self.fault_until = t + self.ticks_second
            self._update_health()
            return
        if t & 3 == 0 and not held:
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
        if quality < 0:  # an epoch the app dropped for an impossible field
            self.data_until = self.tick + self.ticks_second
        if fix_tick < 0:
            fix_tick = self.tick - self.ticks_latency
        self.fix_tick = fix_tick - self.ticks_stamp_lag
        self.fix = np.array([h_m, hdop, speed_m_s, course_rad, sigma_h_m, sigma_v_m], F32)
        self.fix_pending = True

    # ---- per tick ----

    def _calibrate(self, w_in, f_in):
        """x_b = M (x_raw - b0) (M None: identity); False if anything is not finite."""
        cfg = self.cfg
        self.w_b = _apply_cal(w_in, cfg.gyro_bias0, cfg.gyro_matrix)
        self.f_b = _apply_cal(f_in, cfg.accel_bias0, cfg.accel_matrix)
        s = sum_left([*self.w_b, *self.f_b])
        return s - s == 0.0

    def _still_update(self):
        """Every 4th tick: low-pass (weight 1/8) of f, of |f - f_lp|^2 and of |w - b_g|^2;
        quiet when both are below their thresholds and the speed agrees (a recent fix's, else the
        INS's);
        still after `still_s` of quiet."""
        cfg = self.cfg
        lp = self.still_lp
        alpha = fw_nav.STILL_ALPHA
        if self.tick == 4:
            lp[0:3] = self.f_b
        d = self.f_b - lp[0:3]
        lp[0:3] = lp[0:3] + alpha * d
        var = sum_left([ZERO, d[0] * d[0], d[1] * d[1], d[2] * d[2]])
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

    def _fix_usable(self):
        """Quality and HDOP acceptable (any HDOP while a drift is held); remembers a usable
        fix's speed for standstill, unless the speed is unknown (< 0 or NaN)."""
        cfg = self.cfg
        hdop_ok = self.tick < self.drift_until or self.fix[1] <= cfg.gnss_hdop_max
        if self.fix_quality >= cfg.gnss_min_quality and hdop_ok:
            if self.fix[2] >= 0.0:
                self.still_lp[5] = self.fix[2]
                self.speed_tick = self.tick
            return True
        return False

    def _restart(self, gp, v, age, sigma_h, sigma_v, sigma_vel, keep_height=False):
        """p = (antenna - C_bn lever) + v age dt, the fix carried forward over its age; P from
        the initial diagonal with the fix's sigmas and the horizontal velocity's sigma_vel; the
        step in position east, north into reset_d. keep_height: the height, and the variances
        of the height, vertical velocity and vertical accelerometer bias, kept."""
        t = F32(max(age, 0)) * self.cfg.dt_s
        p = (gp - self._lever_n()) + v * t
        kept = [IX_POS + 2, IX_VEL + 2, IX_BA + 2]
        if keep_height:
            p[2] = self.ins.p_n[2]
            k_var = self.kf.P[kept, kept].copy()
        self.reset_d = p[0:2] - self.ins.p_n[0:2]
        self.ins.reset_kinematics(p, v)
        self.init_diag[0] = sigma_h * sigma_h
        self.init_diag[1] = sigma_h * sigma_h
        self.init_diag[2] = sigma_v * sigma_v
        self.init_diag[IX_VEL : IX_VEL + 2] = sigma_vel * sigma_vel
        self.kf.reset_p(self.init_diag)
        if keep_height:
            self.kf.P[kept, kept] = k_var
        self.corr = np.zeros(6, F32)
        self.lag_tick = 0  # nav._restart: no pair for the lag search

    def _navigate(self):
        ins = self.ins
        kf = self.kf
        ins.step(self.w_b, self.f_b)
        slot = self.tick % RING
        self.ring_p[slot] = ins.p_n - self.corr[0:3]
        self.ring_v[slot] = ins.v_n - self.corr[3:6]
        if self.gsf_state:
            self._gsf_accum()
        self.since_prop += 1
        self.since_zupt += 1
        self.since_nhc += 1
        if self.fix_pending:
            self.fix_pending = False
            self._nav_fix()
        if kf.job == IDLE and not kf.ready:
            self._schedule()
        busy = kf.job != IDLE
        kf.work(self.slices)
        if kf.ready:
            self._inject()
        if busy and kf.job == IDLE:  # P changed only if a job ended
            if not kf.diagonal_ok():
                self._fault_reset()
                return
            self.uncertain = self._uncertain()
        p, v = ins.p_n, ins.v_n
        s = sum_left([p[0], p[1], p[2], v[0], v[1], v[2], ins.q_bn[0]])
        if s - s != 0.0:
            self._fault_reset()

    def _nav_fix(self):
        """Screen a new fix once, re-anchor if far, convert it and queue it for the filter;
        the slices per tick follow the receiver's rate (nav._rate_slices)."""
        self.slices = _rate_slices(self.tick - self.last_fix_tick, self.cfg.slices_per_tick)
        self.last_fix_tick = self.tick
        if not self._fix_usable():
            self.gated_until = self.tick + self.ticks_second
            return
        if self._frozen():
            return
        p = self.ins.p_n
        lim = self.cfg.reanchor_m
        if p[0] > lim or p[0] < -lim or p[1] > lim or p[1] < -lim:
            self._reanchor()
        self.gnss_p = self._to_enu(self.fix_lat_e7, self.fix_lon_e7, self.fix[0])
        if self.cfg.yaw_gsf and self._gsf_watch():
            return  # nav._nav_fix: the heading was reset to the bank's at this fix
        self.fix_queued = True

    def _frozen(self):
        """nav._frozen: the usable fix repeats the last one while moving above 1 m/s and 3
        sigma of the horizontal velocity, and the receiver does not say it stands (its speed
        unknown or above 1 m/s: fix_check)."""
        same = (self.fix_lat_e7, self.fix_lon_e7) == self.prev_fix
        self.prev_fix = (self.fix_lat_e7, self.fix_lon_e7)
        v = self.ins.v_n
        sp = self.fix[2]
        v2 = v[0] * v[0] + v[1] * v[1]
        p = self.kf.P
        moving = (
            v2 > nav_kern._FROZEN_V2
            and v2 > F32(nav_kern._FROZEN_K2) * (p[IX_VEL, IX_VEL] + p[IX_VEL + 1, IX_VEL + 1])
            and not (sp >= 0.0 and sp * sp <= nav_kern._FROZEN_V2)
        )
        if same and (moving or self.frozen):
            self.frozen = True  # nav._C_FROZEN: until the fix changes
            self.implausible_until = max(self.implausible_until, self.tick + self.ticks_second)
            return True
        self.frozen = False
        return False

    def _reanchor(self):
        """New integer origin at the current position; the tangent plane there is tilted by
        rho = (-N / (R_M+h), E / (R_N+h), E tan(L) / (R_N+h)) from the old one."""
        ins = self.ins
        c = self.coef
        lat, lon, h = ref_geo.to_e7(c, self.origin_lat_e7, self.origin_lon_e7, ins.p_n)
        lat, lon, h = int(lat), int(lon), F32(h)
        dp = self._to_enu(lat, lon, h)  # the new origin in the old frame
        rho = vec(
            -dp[1] * c[fw_geo.INV_RM],
            dp[0] * c[fw_geo.INV_RN],
            dp[0] * c[fw_geo.INV_RN] * (c[fw_geo.SIN_LAT] / c[fw_geo.COS_LAT]),
        )
        ins.shift_origin(dp, rho)
        self.corr[0:3] = self.corr[0:3] - dp
        self.last_fix_en = self.last_fix_en - dp[0:2]
        hyp = self._hyp()  # the bank's positions, in the new frame
        hyp[:, 0] = hyp[:, 0] - dp[0]
        hyp[:, 1] = hyp[:, 1] - dp[1]
        self._set_origin(lat, lon, h)
        ins.set_frame(self.coef)
        self.reanchors += 1

    def _schedule(self):
        """The filter is idle: a pending fix (unless propagation or the aiding that applies
        is overdue), else propagation, else a zero-velocity update at standstill, else the
        non-holonomic constraint (the measurement rows: nav_aid.py)."""
        cfg = self.cfg
        kf = self.kf
        ins = self.ins
        if self.inflate & fw_nav._INFLATE_MOTION:  # velocity and attitude: initial ones at least
            d = np.arange(IX_VEL, IX_VEL + 6)
            kf.P[d, d] = np.maximum(kf.P[d, d], self.init_diag[d])
        if self.inflate & fw_nav._INFLATE_VERTICAL:  # vertical velocity, accelerometer bias
            d = np.array([IX_VEL + 2, IX_BA + 2])
            kf.P[d, d] = np.maximum(kf.P[d, d], self.init_diag[d])
        self.inflate = 0
        overdue = self.since_prop >= 2 * self.ticks_prop
        if cfg.zupt and self.still and self.since_zupt >= 2 * self.ticks_zupt:
            overdue = True  # nav._schedule: an overdue aiding job before the fix
        elif cfg.nhc and not self.still and self.since_nhc >= 2 * self.ticks_nhc:
            overdue = True
        if self.fix_queued and not overdue:
            self.fix_queued = False
            # the state at the fix's measurement time: the ring holds the last RING ticks
            age = self.tick - self.fix_tick
            self._lag_search(age)
            age = age + int(self.consistency[fw_nav._CN_LAGT])
            age = min(max(age, 0), RING - 1)
            rk = self._rate_r()
            self.consistency[fw_nav._CN_RK] = rk
            self._start_gnss_update((self.tick - age) % RING, rk)
            self.job = JOB_GNSS
            self.updates += 1
        elif self.since_prop >= self.ticks_prop:
            t = F32(self.since_prop) * cfg.dt_s
            dvn = ins.take_dvn()
            ins.slow_update(t)
            kf.start_propagation(dvn, t, ins.c_bn, ins.w_ie_n)
            self.since_prop = 0
        elif cfg.zupt and self.still and self.since_zupt >= self.ticks_zupt:
            self.since_zupt = 0
            self._start_zupt()
            self.job = JOB_AID
        elif cfg.nhc and not self.still and self.since_nhc >= self.ticks_nhc:
            self.since_nhc = 0
            self._start_nhc()
            self.job = JOB_AID

    def _inject(self):
        """Closed loop: p -= dp, v -= dv (also into the corrections), b += db,
        q = q(phi) (x) q, dx = 0; then GNSS bookkeeping (all three positions gated: a reject)."""
        kf = self.kf
        g = self.gsf  # nav._inject: the bank's offsets less the yaw correction
        g[fw_gsf._G_DYAW] = g[fw_gsf._G_DYAW] + kf.dx[IX_ATT + 2]
        self._apply_dx()
        kf.ready = False
        self._inject_bookkeeping()

    def _apply_dx(self):
        """nav_kern.inject: p -= dp, v -= dv (also into the corrections), b += db,
        q = q(phi) (x) q, dx = 0."""
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
        dq = ref_rot.q_from_rotvec(dx[IX_ATT : IX_ATT + 3])
        ins.q_bn = ref_rot.q_normalize(ref_rot.q_mul(dq, ins.q_bn))[0]
        ins.c_bn = ref_rot.q_to_dcm(ins.q_bn)
        kf.dx = np.zeros(N, F32)

    def _inject_bookkeeping(self):
        """nav._inject after the correction: the watches, rejects and resets of the job."""
        kf = self.kf
        if self.job == JOB_AID:
            hit = self._aid_watch(kf.innov)
            if hit:  # nav._inject: a sensor step, for 5 s
                self.drift_until = max(self.drift_until, self.tick + 5 * self.ticks_second)
                self.step_until = self.tick + 5 * self.ticks_second
                if hit & fw_nav._AW_HIT_UP:
                    self.inflate |= fw_nav._INFLATE_VERTICAL
        if self.job == JOB_GNSS:
            w = self._drift_watch(kf.innov, self.tick < self.drift_until)
            if w & 3:  # nav._inject: a drift for 5 s, a suspected one for 1.5 s
                hold = 5 * self.ticks_second if w & 3 == 2 else 3 * self.ticks_second // 2
                self.drift_until = max(self.drift_until, self.tick + hold)
            # nav._inject: a sensor step, the bank agreeing with the heading: resets at once
            step = self.tick < self.step_until and not self.gsf_dis
            self._consistency(kf.innov, kf.gate_mask)
            self._vel_noise(kf.innov, kf.gate_mask)
            self.v_rejects = self.v_rejects + 1 if kf.gate_mask & 4 else 0
            if kf.gate_mask & 0x1B:  # east or north, position or velocity
                self.rejects += 1
                if self.rejects == 1:
                    self.jumped = self._jumped()
                    self.jump_y0 = np.array([kf.innov[0][0], kf.innov[1][0]], F32)
                self.gated_until = self.tick + self.ticks_second
                self._last_fix()
                if self.rejects >= self.cfg.reset_after_rejects or step:
                    if self.jumped and self._refused():  # nav._inject: no reset
                        t = self.tick + self.ticks_second  # not shortening a reset's hold
                        self.implausible_until = max(self.implausible_until, t)
                    else:
                        if self.rejects < self.cfg.reset_after_rejects:
                            self._drift_reset()
                        self._reset_to_gnss()
            else:
                self._last_fix()
                self.rejects = 0
                self.last_accept_tick = self.tick
                if kf.gate_mask:
                    self.gated_until = self.tick + self.ticks_second
                elif self.reset_until > self.tick:
                    self.reset_until = self.tick
                if self.v_rejects >= self.cfg.reset_after_rejects:
                    self._reset_vertical()
                elif step and w & fw_nav._DRIFT_H:
                    self._drift_reset()
                    self._reset_to_gnss()
        self.job = JOB_NONE

    def _drift_reset(self):
        """nav._drift_reset: the drift held _DRIFT_HOLD_S after the reset it calls for."""
        hold = fw_nav._DRIFT_HOLD_S * self.ticks_second
        self.drift_until = max(self.drift_until, self.tick + hold)

    def p_diag(self):
        """The covariance diagonal as the extended frame reports it (Navigator.p_diag)."""
        d = np.diagonal(self.kf.P).copy()
        cn = self.consistency
        d[0:3] = d[0:3] + np.array([cn[fw_nav._CN_VH], cn[fw_nav._CN_VH], cn[fw_nav._CN_VV]], F32)
        return d

    def _fault_reset(self):
        ins = self.ins
        self.state = ALIGNING
        ins.q_bn = vec(1, 0, 0, 0)
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
        self.trk_set = 0
        self.leveled = False
        self.rejects = 0
        self.v_rejects = 0
        self.gsf_state = 0
        self.gsf_dis = 0
        self.last_used_tick = 0  # nav._fault_reset: the frame may move
        self.lag_tick = 0
        self.fault_until = self.tick + self.ticks_second
        self.resets += 1

    def _update_health(self):
        """The causes (nav.CAUSE_*) and the health code they make."""
        t = self.tick
        held = (
            (self.sat_until, fw_nav.CAUSE_IMU_SAT),
            (self.held_until, fw_nav.CAUSE_IMU_HELD),
            (self.dead_until, fw_nav.CAUSE_IMU_DEAD),
            (self.fault_until, fw_nav.CAUSE_NUMERIC),
            (self.gated_until, fw_nav.CAUSE_GNSS_GATED),
            (self.data_until, fw_nav.CAUSE_GNSS_DATA),
            (self.reset_until, fw_nav.CAUSE_RESET),
            (self.drift_until, fw_nav.CAUSE_DRIFT),
            (self.implausible_until, fw_nav.CAUSE_GNSS_IMPLAUSIBLE),
        )
        k = sum(bit for until, bit in held if t < until)
        if self.state == NAVIGATING:
            if t - self.last_accept_tick > self.ticks_timeout:
                k |= fw_nav.CAUSE_GNSS_LOST
            if self.rejects >= 2 or self.v_rejects >= 2:
                k |= fw_nav.CAUSE_GNSS_REJECTS
            if self.uncertain:
                k |= fw_nav.CAUSE_UNCERTAIN
        else:
            k |= fw_nav.CAUSE_NOT_NAVIGATING
        self.causes = k
        self.health = 2 if k & fw_nav.CAUSE_FAULTS else (1 if k else 0)

    # ---- state for comparisons ----

    def snapshot(self):
        """(floats, ints): every piece of state by name (float32 arrays, Python ints): the INS's
        and the filter's floats, then the navigator's; the navigator's ints, then the filter's
        and the frame's."""
        floats = {**self._ins_kf_floats(), **self._nav_floats()}
        ints = {**self._nav_ints(), **self._kf_frame_ints()}
        return floats, {k: int(v) for k, v in ints.items()}

    def _ins_kf_floats(self):
        """The INS's and the filter's float32 state by name (snapshot)."""
        ins, kf = self.ins, self.kf
        return {
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
            "earth_model": vec(ins.g0, ins.inv_rn, ins.inv_rm, ins.h0),
            "P": kf.P,
            "dx": kf.dx,
            "kf_A": kf.A,
            "kf_v": kf.v,
            "kf_K": kf.K,
            "kf_f_n": kf.f_n,
            "kf_c_bn": kf.c_bn,
            "kf_w_ie_n": kf.w_ie_n,
            "kf_scalars": vec(
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
        }

    def _nav_floats(self):
        """The navigator's own float32 state by name (snapshot)."""
        return {
            "w_b": self.w_b,
            "f_b": self.f_b,
            "still_lp": self.still_lp,
            "level_sums": self.level_sums,
            "init_diag": self.init_diag,
            "track": self.track.reshape(-1),
            "ring_p": self.ring_p,
            "ring_v": self.ring_v,
            "corr": self.corr,
            "drift_watch": self.drift_watch,
            "suspect_watch": self.suspect_watch,
            "aid_watch": self.aid_watch,
            "consistency": self.consistency,
            "lag_search": self.lag_search,
            "gnss_p": self.gnss_p,
            "fix": self.fix,
            "used_fix": self.used,
            "ypr": self.ypr,
            "frame_coef": self.coef,
            **{name: self.gsf[a:b] for name, (a, b) in GSF_PARTS.items()},
        }

    def _nav_ints(self):
        """The navigator's counters, flags and ticks by name (snapshot)."""
        return {
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
            "held_until": self.held_until,
            "dead_until": self.dead_until,
            "reset_until": self.reset_until,
            "data_until": self.data_until,
            "causes": self.causes,
            "uncertain": self.uncertain,
            "v_rejects": self.v_rejects,
            "n_held": self.n_held,
            "n_same_g": self.n_same_g,
            "n_same_a": self.n_same_a,
            "inflate": self.inflate,
            "drift_until": self.drift_until,
            "step_until": self.step_until,
            "lag_tick": self.lag_tick,
            "since_prop": self.since_prop,
            "since_zupt": self.since_zupt,
            "since_nhc": self.since_nhc,
            "job": self.job,
            "updates": self.updates,
            "resets": self.resets,
            "reanchors": self.reanchors,
            "gsf_state": self.gsf_state,
            "gsf_dis": self.gsf_dis,
        }

    def _kf_frame_ints(self):
        """The filter's job and counters, the frame's origin by name (snapshot)."""
        return {
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


def _apply_cal(x, b0, m):
    """M (x - b0), or x - b0 when M is None (row sums left to right)."""
    d = np.asarray(x, F32) - b0
    if m is None:
        return d
    return mat_vec(np.asarray(m, F32).reshape(3, 3), d)
