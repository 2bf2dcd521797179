"""The navigator's aiding measurements: the rows it queues in the filter, and the GNSS reset.

A mixin of `nav.Navigator` (its methods run on the Navigator's buffers, made in nav.py, and
nav.py decides when each runs: `_schedule`, `_inject`):
- `_start_gnss_update`: the antenna position p + C_bn l against the fix, compared with the
  state at the fix's measurement time (from the GNSS delay ring, nav.py), and with a course the
  horizontal antenna velocity v + C_bn (w x l) against speed (sin, cos course); a fix
  without height (an RMC-only receiver: fix_in's _FX_SIG_V < 0) compares east and north, and
  its vertical row is v_U = 0 (1 m/s): nothing else holds the vertical channel of a walker;
- `_start_zupt`: the zero-velocity update at standstill, z = v_n;
- `_start_nhc`: the non-holonomic constraint of a car, body lateral and vertical velocity 0;
- `_reset_to_gnss`: position and velocity from the fix the filter last rejected;
  `_reset_vertical`: the height alone, when only the height keeps being rejected;
- `_lever_n` (antenna lever arm in the navigation frame) and the fix's 1-sigma errors
  `_sigma_h`, `_sigma_v` (given, else from HDOP).

Each measurement is z = (nominal prediction - measured) = h dx + noise in eskf.py's error
state (dp, dv, phi, dbg, dba; nominal minus true), ENU navigation frame, body x right,
y forward, z up; m, m/s, rad. The rows are queued with `eskf.add_scalar` and the update is
started; the filter works them off over the next ticks.
"""

from micropython import const

import eskf
import f32
import ins as ins_mod
import kern
from fmath import cos, sin

# The Navigator's buffers, as nav.py lays them out (an underscore const is inlined and exists
# only in its own module, so a module that indexes them repeats what it uses)
# ---- nav.py's consts used here: `python -m common.native.layout` writes them ----
_FX_HDOP = const(1)
_FX_SPEED = const(2)
_FX_COURSE = const(3)
_FX_SIG_H = const(4)
_FX_SIG_V = const(5)
_C_TICK = const(0)
_C_ACCEPT_TICK = const(9)
_C_REJECTS = const(10)
_C_FIX_TICK = const(19)
_C_USED_TICK = const(20)
_C_T_SECOND = const(32)
_C_RESET_AFTER = const(42)
_C_V_REJECTS = const(47)
_C_RESET_UNTIL = const(62)
_C_IMPLAUSIBLE_UNTIL = const(67)
_C_LAST_TICK = const(72)
_M_X = const(0)
_M_E = const(52)
_M_US = const(1595)
_M_CN = const(1645)
_M_LAST = const(1660)
_M_JUMP = const(2145)
_M_RESET_D = const(2147)
_CN_RVEL = const(14)
_RESTART_GNSS = const(0)
# ---- end of nav.py's consts ----
# ---- ins.py's consts used here: `python -m common.native.layout` writes them ----
_X_V = const(3)
# ---- end of ins.py's consts ----
UNCONFIRMED = const(0x3FFFFFFF)  # as a tick: "until further notice" (nav._inject ends it)
# the references: _reset_to_gnss, nav_align._gsf_reset, _gsf_start and _course_start
_nav_restart = kern.pick("nav_restart", None)

# self._used: the fix of the running GNSS update (a reset to GNSS needs it after newer fixes);
# used only here
_US_P = const(0)  # antenna position in the frame (3)
_US_SPEED = const(3)
_US_COURSE = const(4)
_US_SIG_H = const(5)
_US_SIG_V = const(6)  # < 0: the fix had no height (its magnitude: the sigma it would have had)
NO_HEIGHT_VAR = f32.f32(100000000)  # m^2: the height's reported variance without one, (10 km)^2
# A receiver that jumps is told from an INS that drifts by the receiver's own track: a fix
# farther from the receiver's previous fix than the board can have moved between them (the
# INS's speed times the time, plus _JUMP_M: twice a fix's scatter at HDOP 2.5, plus
# _STEP_HALF_A t^2: a speed that changed by 0.1 g since, as after an outage) jumped (100 m,
# 2000 km, the pole); so did one whose fix is farther than that margin from where its own
# velocity (speed and course) put it from its previous fix _JUMP_VEL_S or less before,
# whatever the INS believes: a step across the board's motion (20 m north while the car drives
# south-east at 12.7 m/s moved the fix 15 m in the second, no farther than the car could go).
# Over a longer gap the fix's velocity says little of the chord: a car turning at 12 m/s,
# 0.3 rad/s (2.4 m/s^2) for 8 s comes 98 m from where its velocity of now puts it, a jump
# that refused the resets a 1 deg/s gyro bias needed across 8 s of fixes over hdop_max
# (bench-faults seed 1: 964 m, never back; 223 m by the distance alone). 2 s: one missed
# fix at 1 Hz, and 7.1 m off in that turn against its 17 m. A faulty IMU drifts away from
# fixes that go on as the board moves (a 1 deg/s gyro bias tilts the INS and its drift
# passes 0.1 g within seconds; a walker's INS without a heading runs off faster than the
# fixes walk on), so its runs of rejected fixes never begin with a jump. (Judged by the
# innovation instead, at 4de8e41, the GGA-only walk looked like a jump: `bench-nav --trial
# walk --receiver "GGA only"` 10.63 m, now 4.87 m.)
# While a run that did lasts, the reset to GNSS is refused (`refused`) while the fix is beyond
# what the INS could have drifted since its last accepted fix t s ago: _STEP_M +
# _STEP_HALF_A t^2 (15 m: the receiver's scatter; then a constant error of 1 m/s^2, 0.1 g).
# Within that bound it is refused too for _STEP_HOLD_S while the fixes stay where the jump
# put them (the innovation less the run's first, within the same bound: the INS agrees with
# the receiver's motion, only not with its place). Neither when the jump undoes the last
# reset (the receiver coming back to where the INS was before a reset followed it). Reset to
# at once, a receiver 20 or 40 m off for 30 s was followed (239 and 198 frames above 10 m
# without health 2, `make bench-faults` at 1cff419, seed 0); one that stays there is believed
# after _STEP_HOLD_S (a judgement: longer refuses longer a receiver wrong before its jump).
_JUMP_M = f32.f32(15)
_JUMP_VEL_S = f32.f32(2)
_STEP_M = f32.f32(15)
_STEP_HALF_A = f32.ratio(1, 2)
_STEP_HOLD_S = const(60)
# A reset beyond 3 sigma of the filter's and the fix's horizontal variance (Aiding._hold): for
# both honest, a chance of exp(-9), 1e-4 (a reset follows fixes beyond the gate, though)
_HOLD_K2 = f32.f32(9)


def refused(self):
    """True when the reset to the fix of the GNSS update just done is refused, in a run of
    rejected fixes that began with a jump of the receiver (_C_JUMPED; the module's
    comment above _JUMP_M says when). self: the Navigator. A function, not an Aiding method:
    as a method it left the emulated Cortex-M4F's status page 297 bytes short of heap at
    start-up (tests/runtimes/test_m4f.py). On the board navtick.c's `refused` decides."""
    c = self.ctl
    m = self.mem
    de = m[_M_JUMP] - m[_M_RESET_D]
    dn = m[_M_JUMP + 1] - m[_M_RESET_D + 1]
    if de * de + dn * dn < _STEP_M * _STEP_M:
        return False  # the jump undoes the last reset
    ye = m[_M_E + eskf.E_Z]
    yn = m[_M_E + eskf.E_Z + 1]
    if self._beyond_drift(ye, yn):
        return True
    if c[_C_TICK] - c[_C_ACCEPT_TICK] >= _STEP_HOLD_S * c[_C_T_SECOND]:
        return False
    return not self._beyond_drift(ye - m[_M_JUMP], yn - m[_M_JUMP + 1])


def lever_vel(out, x, w, lv):
    """out[0], out[1] = east, north of C_bn ((w - bg) x l): the antenna's velocity from the
    lever arm (x the INS state, w the body rate, lv the lever arm in body axes)."""
    wx = w[0] - x[ins_mod.X_BG]
    wy = w[1] - x[ins_mod.X_BG + 1]
    wz = w[2] - x[ins_mod.X_BG + 2]
    ax = wy * lv[2] - wz * lv[1]
    ay = wz * lv[0] - wx * lv[2]
    az = wx * lv[1] - wy * lv[0]
    c = ins_mod.X_C
    out[0] = x[c] * ax + x[c + 1] * ay + x[c + 2] * az
    out[1] = x[c + 3] * ax + x[c + 4] * ay + x[c + 5] * az


class Aiding:
    def _lever_n(self, out):
        """out[0:3] = C_bn lever_b (antenna offset in the navigation frame)."""
        c = self.ins.c_bn
        lv = self.cfg.lever_b_m
        lx = lv[0]
        ly = lv[1]
        lz = lv[2]
        out[0] = c[0] * lx + c[1] * ly + c[2] * lz
        out[1] = c[3] * lx + c[4] * ly + c[5] * lz
        out[2] = c[6] * lx + c[7] * ly + c[8] * lz

    def _sigma_h(self):
        cfg = self.cfg
        fx = self._fx
        s = fx[_FX_SIG_H]
        if not s > 0.0:
            s = fx[_FX_HDOP] * cfg.gnss_uere_m
        if s < cfg.gnss_sigma_floor_m:
            s = cfg.gnss_sigma_floor_m
        return s

    def _sigma_v(self, sigma_h):
        cfg = self.cfg
        s = self._fx[_FX_SIG_V]
        if not s > 0.0:
            s = sigma_h * cfg.gnss_vert_factor
        if s < cfg.gnss_sigma_floor_m:
            s = cfg.gnss_sigma_floor_m
        return s

    def _start_gnss_update(self, b, rk):
        """The fix in self._gp against the state at its measurement time, at offset b of the
        delay ring (self._ring_p, self._ring_v) plus the corrections injected since; its
        position variances times rk (nav_kern.rate_r)."""
        self.ctl[_C_USED_TICK] = self.ctl[_C_FIX_TICK]
        cfg = self.cfg
        kf = self.kf
        ins = self.ins
        rp = self._ring_p
        rv = self._ring_v
        corr = self._corr
        ln = self._tmp4
        self._lever_n(ln)
        sh = self._sigma_h()
        sv = self._sigma_v(sh)
        rh = sh * sh * rk
        rv_ = sv * sv * rk
        gp = self._gp
        fx = self._fx
        used = self._used
        lx = ln[0]
        ly = ln[1]
        lz = ln[2]
        used[_US_SIG_V] = sv
        if fx[_FX_SIG_V] < 0.0:
            # a fix without height (RMC only): its height is the state's own (a reset keeps
            # it), and the vertical row holds the vertical velocity at 0 +- 1 m/s instead
            gp[2] = rp[b + 2] + corr[2] + lz
            used[_US_SIG_V] = -sv
        for i in range(3):
            used[_US_P + i] = gp[i]
        used[_US_SPEED] = fx[_FX_SPEED]
        used[_US_COURSE] = fx[_FX_COURSE]
        used[_US_SIG_H] = sh
        # z = (p + C l) - p_gnss = dp + [(C l) x] phi
        z = (rp[b] + corr[0] + lx) - gp[0]
        kf.add_scalar(z, rh, 3, 0, 1.0, eskf.IX_ATT + 1, -lz, eskf.IX_ATT + 2, ly)
        z = (rp[b + 1] + corr[1] + ly) - gp[1]
        kf.add_scalar(z, rh, 3, 1, 1.0, eskf.IX_ATT, lz, eskf.IX_ATT + 2, -lx)
        if used[_US_SIG_V] > 0.0:
            z = (rp[b + 2] + corr[2] + lz) - gp[2]
            kf.add_scalar(z, rv_, 3, 2, 1.0, eskf.IX_ATT, -ly, eskf.IX_ATT + 1, lx)
        else:  # z = v_U = dv_U: a level world's vertical velocity, 1-sigma 1 m/s
            kf.add_scalar(rv[b + 2] + corr[5], 1.0, 1, eskf.IX_VEL + 2, 1.0)
        course = fx[_FX_COURSE]
        sp = fx[_FX_SPEED]
        if course >= 0.0:
            # (no course, no velocity: standing still is the zero-velocity update's business)
            ve = sp * sin(course)
            vn = sp * cos(course)
            # antenna velocity = v + C (w x l); its attitude and gyro-bias sensitivities are
            # neglected (tests/lib/test_error_dynamics.py sizes them: mm/s against 0.1 m/s)
            lever_vel(ln, ins.x, self._w, cfg.lever_b_m)
            rvel = self.mem[_M_CN + _CN_RVEL]  # learned (nav_kern.vel_noise)
            z = (rv[b] + corr[3] + ln[0]) - ve
            kf.add_scalar(z, rvel, 1, eskf.IX_VEL, 1.0)
            z = (rv[b + 1] + corr[4] + ln[1]) - vn
            kf.add_scalar(z, rvel, 1, eskf.IX_VEL + 1, 1.0)
        kf.start_update()

    def _start_zupt(self):
        """Zero-velocity update: z = v_n[i] = dv_i + noise, i = E, N, U."""
        cfg = self.cfg
        kf = self.kf
        r = cfg.zupt_sigma * cfg.zupt_sigma
        v = self.ins.v_n
        for i in range(3):
            kf.add_scalar(v[i], r, 1, eskf.IX_VEL + i, 1.0)
        kf.start_update()

    def _start_nhc(self):
        """Body lateral (x) and vertical (z) velocity are zero for a car: z = (C_bn^T v)_k,
        h = [0, c_k^T, (v x c_k)^T, 0, 0] with c_k the k-th column of C_bn."""
        kf = self.kf
        ins = self.ins
        c = ins.c_bn
        v = ins.v_n
        v0 = v[0]
        v1 = v[1]
        v2 = v[2]
        r = self.cfg.nhc_sigma * self.cfg.nhc_sigma
        for k in range(0, 3, 2):
            c0 = c[k]
            c1 = c[3 + k]
            c2 = c[6 + k]
            z = c0 * v0 + c1 * v1 + c2 * v2
            m = kf.add_scalar(z, r, 3, eskf.IX_VEL, c0, eskf.IX_VEL + 1, c1, eskf.IX_VEL + 2, c2)
            kf.add_scalar_terms(
                m,
                eskf.IX_ATT,
                v1 * c2 - v2 * c1,
                eskf.IX_ATT + 1,
                v2 * c0 - v0 * c2,
                eskf.IX_ATT + 2,
                v0 * c1 - v1 * c0,
            )
        kf.start_update()

    def _reset_to_gnss(self):
        """Recovery when the filter keeps rejecting GNSS (e.g. after a long outage): position
        and horizontal velocity from the fix it last rejected (the navigator's own velocity,
        with the track start's wider sigma, when the fix has no course, no faster than the
        fix's speed when it has one), a fresh covariance;
        the attitude is kept. The bias estimates go back to the calibration (0 on top of
        gyro_bias0/accel_bias0): what the filter learned while it drifted away from GNSS is
        what let it drift (after a bias step, a learned 1 deg/s outlives the step and
        defeats standstill detection), and the fresh covariance lets it learn them again.
        Not asked for (nav._inject, navtick.c inject) when the rejected run began with a
        jump of the receiver (_C_JUMPED: _jumped) and `refused` says so: the rejects go on
        counting and the next rejected fix asks again. A sensor step's reset (nav._drift_reset,
        asked for before RESET_AFTER rejects) is horizontal: the height, the vertical velocity
        and the vertical accelerometer bias stay, with their variances. Natively the
        `nav_restart` kernel, which allocates nothing (_restart_native)."""
        if _nav_restart is not None:
            self._restart_native(_RESTART_GNSS)
            self.resets += 1
            return
        c = self.ctl
        self._room()
        ins = self.ins
        used = self._used
        v = self._tmp3
        m = self.mem
        pk = self.kf.P
        sh = used[_US_SIG_H]
        # the filter's and the fix's horizontal variance, and the last reset's step: _hold's
        var_h = pk[0] + pk[eskf.N + 1] + 2.0 * (sh * sh)
        pe = m[_M_RESET_D]
        pn = m[_M_RESET_D + 1]
        course = used[_US_COURSE]
        sp = used[_US_SPEED]
        # a sensor step's reset (nav._drift_reset: before RESET_AFTER rejects) is horizontal:
        # the height channel has its own containment, and a height from the fix (4 m noise),
        # vertical velocity 0 and a vertical bias back to 0 at each such reset left
        # `make bench-faults`' gyro steps 19 m off in height, never back
        drift = c[_C_REJECTS] < c[_C_RESET_AFTER]
        v[2] = ins.v_n[2] if drift else 0.0  # a vertical velocity that let it drift: not kept
        if course >= 0.0:
            v[0] = sp * sin(course)
            v[1] = sp * cos(course)
        else:
            v[0] = ins.v_n[0]
            v[1] = ins.v_n[1]
            # no course but a speed (an RMC's below its course threshold): the navigator's
            # direction at no more than the receiver's speed; kept as it was, a walk's INS
            # that had run off at 20-60 m/s went on from each reset to fixes of 0.4-0.5 m/s
            # (`run --scenario walk_real --duration 120 --seed 1`: 78 m horizontal RMS)
            if sp >= 0.0:
                v2 = v[0] * v[0] + v[1] * v[1]
                if v2 > sp * sp:
                    k = sp / f32.sqrt(v2)
                    v[0] = v[0] * k
                    v[1] = v[1] * k
        sv = used[_US_SIG_V]
        sigma_vel = self.cfg.init_vel_sigma
        if course < 0.0:  # the velocity is the navigator's own, and it has drifted
            sigma_vel = self.cfg.track_vel_sigma
        self._restart(used, v, c[_C_TICK] - c[_C_USED_TICK], sh, sv, sigma_vel, drift)
        for i in range(3):
            ins.bg[i] = 0.0
            if i < 2 or not drift:
                ins.ba[i] = 0.0
        c[_C_REJECTS] = 0
        c[_C_V_REJECTS] = 0
        c[_C_RESET_UNTIL] = UNCONFIRMED  # until a fix agrees with the reset state
        self.resets += 1
        self._hold(var_h, pe, pn)

    def _restart_native(self, kind):
        """A start or a reset by the `nav_restart` kernel (kind _RESTART_*: _reset_to_gnss,
        nav_align's _gsf_reset, _gsf_start, _course_start), their Python floats (heap objects
        on the board, ~2 KB a reset: collections while a walk navigated) in C; the settings
        it reads go into self._ns, which nav_start uses too."""
        s = self._ns
        cfg = self.cfg
        s[0] = cfg.init_vel_sigma
        s[1] = cfg.track_vel_sigma
        s[2] = cfg.init_yaw_sigma
        _nav_restart(self.ctl, self.kf.i, self.mem, kind)

    def _hold(self, var_h, pe, pn):
        """CAUSE_GNSS_IMPLAUSIBLE held after a reset to GNSS whose step (_M_RESET_D) the
        filter's and the fix's own horizontal variance (var_h, both axes) did not allow, d^2 >
        _HOLD_K2 var_h: either the INS or the receiver was wrong, and one receiver cannot say
        which. Held until _STEP_HOLD_S after the last accepted fix (when `refused`, too,
        believes a receiver that stays where it jumped); a later reset that undoes this one's
        step within _STEP_M (pe, pn: the step before this reset) ends it: the receiver came
        back. A receiver that jumped 20 or 40 m while its fixes were over gnss_hdop_max is
        no jump to `_jumped` when they are back (the last fix the filter took is 17 s old),
        and the navigator followed it with health 0 (`make bench-faults`, gnss-jump@250+30:20
        and :40, seed 1: 148 frames above 10 m without health 2 each)."""
        c = self.ctl
        m = self.mem
        t = c[_C_TICK]
        de = m[_M_RESET_D]
        dn = m[_M_RESET_D + 1]
        if t < c[_C_IMPLAUSIBLE_UNTIL]:
            ue = de + pe
            un = dn + pn
            if ue * ue + un * un < _STEP_M * _STEP_M:
                c[_C_IMPLAUSIBLE_UNTIL] = t
                return
        if de * de + dn * dn > _HOLD_K2 * var_h:
            u = c[_C_ACCEPT_TICK] + _STEP_HOLD_S * c[_C_T_SECOND]
            if u > c[_C_IMPLAUSIBLE_UNTIL]:
                c[_C_IMPLAUSIBLE_UNTIL] = u

    def _jumped(self):
        """True when the fix of the GNSS update just done (self._used) is farther from the last
        fix the filter took (_M_LAST) than the board can have moved between their moments at
        the INS's horizontal speed, plus _JUMP_M and what a speed changing by 1 m/s^2 adds
        (_STEP_HALF_A t^2: after an outage the car that slowed to 2 m/s had come 300 m, which
        at the speed alone was a jump and 60 s of refused resets); or, with a course, farther
        than _JUMP_M + _STEP_HALF_A t^2 from the previous fix moved by the fix's own velocity
        times the time, t up to _JUMP_VEL_S. nav._inject asks it at the first rejected fix of
        a run: _C_JUMPED."""
        c = self.ctl
        if c[_C_LAST_TICK] == 0:
            return False
        m = self.mem
        t = f32.f32(c[_C_USED_TICK] - c[_C_LAST_TICK]) * self.cfg.dt_s
        de = m[_M_US] - m[_M_LAST]
        dn = m[_M_US + 1] - m[_M_LAST + 1]
        ve = m[_M_X + _X_V]
        vn = m[_M_X + _X_V + 1]
        margin = _JUMP_M + _STEP_HALF_A * (t * t)
        reach = f32.sqrt(ve * ve + vn * vn) * t + margin
        if de * de + dn * dn > reach * reach:
            return True
        course = m[_M_US + _US_COURSE]
        if course < 0.0 or t > _JUMP_VEL_S:
            return False
        sp = m[_M_US + _US_SPEED]
        de = de - sp * sin(course) * t
        dn = dn - sp * cos(course) * t
        return de * de + dn * dn > margin * margin

    def _last_fix(self):
        """The fix of the GNSS update just done becomes the last one the filter took."""
        m = self.mem
        m[_M_LAST] = m[_M_US]
        m[_M_LAST + 1] = m[_M_US + 1]
        self.ctl[_C_LAST_TICK] = self.ctl[_C_USED_TICK]

    def _beyond_drift(self, ye, yn):
        """True when an east/north innovation (ye, yn) is beyond what the INS can have
        drifted since the last accepted fix (_STEP_M)."""
        c = self.ctl
        t = f32.f32(c[_C_TICK] - c[_C_ACCEPT_TICK]) * self.cfg.dt_s
        lim = _STEP_M + _STEP_HALF_A * (t * t)
        return ye * ye + yn * yn > lim * lim

    def _reset_vertical(self):
        """Recovery when the filter keeps rejecting the height while it accepts east and north
        (a vertical channel driven away by bad IMU data or a bad height): the height from the
        fix it last rejected, vertical velocity 0, their covariance rows afresh (the fix's
        vertical sigma, the initial velocity sigma). The step goes into the injected
        corrections, as a filter correction would, so fixes still in the delay ring compare
        with the reset state."""
        self._room()
        ins = self.ins
        c = self.ctl
        ln = self._tmp4
        self._lever_n(ln)
        p = ins.p_n
        v = ins.v_n
        h = self._used[_US_P + 2] - ln[2]
        corr = self._corr
        corr[2] = corr[2] + (h - p[2])
        corr[5] = corr[5] - v[2]
        p[2] = h
        v[2] = 0.0
        ins.clear_memory(2)
        sv = self._used[_US_SIG_V]
        self.kf.reset_rows(2, sv * sv, eskf.IX_VEL + 2, self._init[eskf.IX_VEL + 2])
        c[_C_V_REJECTS] = 0
        c[_C_RESET_UNTIL] = UNCONFIRMED  # until a fix agrees with the reset state
        self.resets += 1
