"""The navigator's alignment (state ALIGNING): levelling, the heading, the start of navigation.

A mixin of `nav.Navigator` (its methods run on the Navigator's buffers, made in nav.py):
- `_align` every tick while aligning: sums specific force and rate while levelling, keeps roll
  and pitch current with the gyros once levelled, and takes a pending fix (`_align_fix`);
  natively all but the fix is in nav_tick (navtick.c `align_step`, which mirrors `_align`
  and `_level`), so an aligning tick calls Python only when a fix arrived;
- `_level`: roll and pitch from the mean specific force (it points up at rest), the gyro bias
  from the mean rate when standing still; the heading is kept;
- `_align_fix`: a usable fix (`gnss_stable_fixes` in a row) places the origin and the
  position; once levelled, the heading comes from the receiver's course over ground from
  `heading_speed_m_s` on (0.8 m/s: a walk; this board has no magnetometer: a static board
  cannot know its heading), or from the track of the fixes when the receiver reports no
  course (`_track`);
- `_start_navigation`: heading, velocity along it, position and covariance from the fix, and
  the switch to NAVIGATING. The heading's variance is `init_yaw_sigma`^2 (how far the body may
  point away from its direction of travel, the course's usual noise included) or, when larger,
  that of the course it came from, which grows as the speed falls: (gnss_vel_sigma / speed)^2
  for the receiver's course, 2 sigma_h^2 / |chord|^2 for the track's.

Frames and units as everywhere (rot.py): ENU navigation frame, yaw counter-clockwise from
north, course over ground clockwise from north (so yaw = -course); rad, m, m/s, ticks.
Runs only while aligning (natively: at fix ticks only); nothing here runs in a navigating tick.
"""

from array import array

from micropython import const

import f32
import kern
import rot
from fmath import asin, atan2, cos, sin, sqrt
from fmath import wrap as _wrap
from nav_aid import NO_HEIGHT_VAR, UNCONFIRMED
from navcfg import G0_M_S2

# The Navigator's buffers, as nav.py lays them out (an underscore const is inlined and exists
# only in its own module, so a module that indexes them repeats what it uses)
_IX_YAW = const(8)  # eskf.IX_ATT + 2: the yaw's row of the covariance (tests/lib/test_nav.py)
# ---- nav.py's consts used here: `python -m common.native.layout` writes them ----
_NAVIGATING = const(2)
_FX_H = const(0)
_FX_SPEED = const(2)
_FX_COURSE = const(3)
_FX_SIG_V = const(5)
_FC_SPEED = const(2)
_FC_COURSE = const(16)
_FC_FAST = const(32)
_C_TICK = const(0)
_C_STATE = const(1)
_C_STILL = const(3)
_C_ACCEPT_TICK = const(9)
_C_REJECTS = const(10)
_C_SINCE_PROP = const(11)
_C_FIX_PENDING = const(15)
_C_FIX_TICK = const(19)
_C_FIX_LAT = const(22)
_C_FIX_LON_DEG = const(23)
_C_FIX_LON_FRAC = const(24)
_C_LAST_FIX_TICK = const(26)
_C_N_LEVEL = const(27)
_C_LEVELED = const(28)
_C_N_STABLE = const(29)
_C_TRK_SET = const(30)
_C_TRK_TICK = const(31)
_C_T_LEVEL = const(38)
_C_T_TRACK = const(39)
_C_OPTS = const(43)
_C_V_REJECTS = const(47)
_C_RESET_UNTIL = const(62)
_C_GSF = const(75)
_C_GSF_DIS = const(76)
_OPT_GSF = const(16)
_OPT_COURSE = const(32)
_M_CN = const(1645)
_M_GSF = const(1717)
_CN_VV = const(4)
_RESTART_GSF = const(1)
_RESTART_GSF_START = const(2)
_RESTART_COURSE_START = const(3)
# ---- end of nav.py's consts ----
# ---- eskf.py's consts used here: `python -m common.native.layout` writes them ----
_IX_ATT = const(6)
_E_DX = const(654)
# ---- end of eskf.py's consts ----
# ---- yaw_gsf.py's consts used here: `python -m common.native.layout` writes them ----
_GSF_N = const(6)
_NH = const(57)
_G_DYAW = const(5)
_G_YAW = const(6)
_G_VAR = const(7)
_G_V = const(8)
_G_B = const(84)
_G_HYP = const(86)
_GSF_READY = const(1)
# ---- end of yaw_gsf.py's consts ----

# self._trk: the track anchors (heading from GNSS positions, see _track), used only here: a
# float array, 3 floats per anchor, oldest first, and an int array of their measurement ticks,
# with the shortest window (track_s) in ticks after them; None until the first fix without a
# course (_track_buffers)
_TR_SLOTS = const(8)
_TR_E = const(0)  # antenna position of the anchor fix in the frame, m
_TR_N = const(1)
_TR_YAW = const(2)  # yaw of the attitude when the anchor fix was processed, rad

MIN_LEVEL_F = f32.ratio(49, 10)  # m/s^2: less mean specific force than this cannot be gravity


_nav_start = kern.pick("nav_start", None)  # the reference: _start_navigation_py
_euler = kern.pick("euler", rot.dcm_to_euler)
_fix_usable = kern.pick("fix_usable", None)  # the reference: Navigator._fix_usable


class Alignment:
    def _track_buffers(self):
        """The track anchors' buffers (self._trk), made at the first fix without a course:
        most receivers report one, and the 200 bytes stay free. The shortest window (track_s)
        in ticks after the anchors' ticks, rounded as nav._ticks."""
        tk = array("i", bytes(4 * (_TR_SLOTS + 1)))
        tk[_TR_SLOTS] = int(self.cfg.track_s / self.cfg.dt_s + 0.5)
        self._trk = (f32.zeros(3 * _TR_SLOTS), tk)

    def _align(self):
        """An aligning tick: the reference of nav_tick's aligning step (firmware/native/
        navtick.c, align_step) and then the pending fix, which is Python's part there."""
        cfg = self.cfg
        ins = self.ins
        w = self._w
        f = self._f
        lv = self._lvl
        c = self.ctl
        still = c[_C_STILL]
        if still or not c[_C_LEVELED]:
            for i in range(3):
                lv[i] = lv[i] + f[i]
                lv[3 + i] = lv[3 + i] + w[i]
            c[_C_N_LEVEL] += 1
            if c[_C_N_LEVEL] >= c[_C_T_LEVEL]:
                self._level()
        if c[_C_LEVELED] and not still:
            # keep roll and pitch current while waiting for a heading
            th = self._tmp3
            dt = cfg.dt_s
            bg = ins.bg
            for i in range(3):
                th[i] = (w[i] - bg[i]) * dt
            rot.q_update(ins.q_bn, th)
            rot.q_to_dcm(ins.c_bn, ins.q_bn)
        if c[_C_GSF]:
            self._gsf_accum()
        if c[_C_FIX_PENDING]:
            c[_C_FIX_PENDING] = 0
            self._align_fix()

    def _level(self):
        """Roll and pitch from the mean specific force (it points up at rest), gyro bias from
        the mean rate when static; the heading is kept (zero until the GNSS course gives it)."""
        ins = self.ins
        lv = self._lvl
        c = self.ctl
        n = f32.f32(c[_C_N_LEVEL])
        fx = lv[0] / n
        fy = lv[1] / n
        fz = lv[2] / n
        g = sqrt(fx * fx + fy * fy + fz * fz)
        if not g > MIN_LEVEL_F:  # a dead accelerometer or free fall: nothing to level on
            for i in range(6):
                lv[i] = 0.0
            c[_C_N_LEVEL] = 0
            return
        ypr = self.ypr
        rot.dcm_to_euler(ypr, ins.c_bn)
        s = fy / g
        ypr[rot.PITCH] = asin(s)
        ypr[rot.ROLL] = atan2(-fx, fz)
        rot.euler_to_q(ins.q_bn, ypr)
        rot.q_to_dcm(ins.c_bn, ins.q_bn)
        if c[_C_STILL]:
            for i in range(3):
                ins.bg[i] = lv[3 + i] / n
        for i in range(6):
            lv[i] = 0.0
        c[_C_N_LEVEL] = 0
        c[_C_LEVELED] = 1

    def _align_fix(self):
        """A fix while aligning: stable fixes place the origin and the position; once
        levelled, the heading from the course or the track starts navigation. Its frame stays
        within the VM's on-stack limit (tests/runtimes/test_frames.py): few locals."""
        c = self.ctl
        c[_C_LAST_FIX_TICK] = c[_C_TICK]
        u = self._fix_usable() if _fix_usable is None else _fix_usable(c, self.mem)
        if not u:
            c[_C_N_STABLE] = 0
            c[_C_TRK_SET] = 0
            return
        c[_C_N_STABLE] += 1
        if c[_C_N_STABLE] < self.cfg.gnss_stable_fixes:
            return
        if not self.frame.valid and not self._set_origin():
            return
        fx = self._fx
        self.frame.to_enu(self._gp, c[_C_FIX_LAT], c[_C_FIX_LON_DEG], c[_C_FIX_LON_FRAC], fx)
        self.ins.p_n[0:3] = self._gp  # a copy of the buffer: no float is boxed
        if not c[_C_LEVELED]:
            c[_C_TRK_SET] = 0
            return
        if c[_C_OPTS] & _OPT_GSF and (self._gsf_align() or not c[_C_OPTS] & _OPT_COURSE):
            return
        # fix_check's bits, not the floats: an aligning fix boxes no float (nav_kern.fix_check)
        if u & _FC_COURSE or (u & _FC_SPEED and not u & _FC_FAST):
            # the receiver's course, or its speed says it (nearly) stands: the track's chord
            # would be the fixes' noise (an RMC's course is empty at a standstill)
            c[_C_TRK_SET] = 0
            if u & _FC_COURSE and u & _FC_FAST:
                self._course_start()
        else:
            self._track()

    def _gsf_align(self):
        """The yaw estimator's step at an aligning fix (yaw_gsf.py): once it knows the
        heading, navigation starts from it (_gsf_start), and True. Every aligning fix calls
        it, so its frame stays within the VM's on-stack limit (tests/runtimes/test_frames.py):
        a frame on the heap is allocated and freed at each call, which the app's heap watch
        counts as an allocation, and each fix then cost a look at the heap (a scan of
        ~180,000 instructions, 5 ms with a raw record: docs/image.md)."""
        if not self._gsf_step() & _GSF_READY:
            return False
        self._gsf_start()
        return True

    def _gsf_start(self):
        """Navigation starts from the yaw estimator's heading and velocity, whatever the course
        (a board in a hand points anywhere); the heading's variance is the larger of the bank's
        and init_yaw_sigma^2. Natively the `nav_restart` kernel (nav_aid._restart_native)."""
        if kern.NATIVE:
            self._restart_native(_RESTART_GSF_START)
            return
        self._room()  # the start computes in Python floats
        m = self.mem
        yaw = self._yaw_now() + m[_M_GSF + _G_YAW]
        course = atan2(m[_M_GSF + _G_V], m[_M_GSF + _G_V + 1])
        self._start_navigation(course, self._gsf_speed(), self.cfg.init_vel_sigma,
                               m[_M_GSF + _G_VAR])  # fmt: skip
        self._gsf_turn(yaw + course)  # the start set the yaw to -course

    def _gsf_speed(self):
        """The yaw estimator's horizontal speed, m/s."""
        m = self.mem
        ve = m[_M_GSF + _G_V]
        vn = m[_M_GSF + _G_V + 1]
        return sqrt(ve * ve + vn * vn)

    def _gsf_reset(self):
        """The heading, horizontal velocity and covariance from the yaw estimator, the
        position from the fix, when the bank and the navigator's own innovations agree that
        its heading is wrong (nav._gsf_watch); a reset as _reset_to_gnss's (CAUSE_RESET
        until a fix agrees with it). The biases are kept: a heading wrong from the start is
        no bias's doing. Natively the `nav_restart` kernel (nav_aid._restart_native)."""
        if kern.NATIVE:
            self._restart_native(_RESTART_GSF)
            self.resets += 1
            return
        self._room()
        c = self.ctl
        m = self.mem
        self._yaw_var(m[_M_GSF + _G_VAR])
        v = self._tmp3
        v[0] = m[_M_GSF + _G_V]
        v[1] = m[_M_GSF + _G_V + 1]
        v[2] = 0.0
        sh = self._sigma_h()
        self._restart(self._gp, v, c[_C_TICK] - c[_C_FIX_TICK], sh, self._sigma_v(sh),
                      self.cfg.init_vel_sigma)  # fmt: skip
        self._gsf_turn(m[_M_GSF + _G_YAW])
        c[_C_REJECTS] = 0
        c[_C_V_REJECTS] = 0
        c[_C_GSF_DIS] = 0
        c[_C_RESET_UNTIL] = UNCONFIRMED
        self.resets += 1

    def _gsf_turn(self, d):
        """After a start or a reset (no filter job, dx 0): the attitude turned by the bank,
        about the vertical by d (rad) and in roll and pitch by its weighted specific force
        error b (east, north in the navigator's frame): phi = (b_N / g, -b_E / g, d), which
        takes b out of C_bn f (phi x g_up = -b), applied as a correction is (the navigator's
        `inject` kernel: q = q(phi) (x) q); the bank's offsets less d and its force errors
        less b. Levelling needs a standstill; a hand or a car that never stops leaves a tilt
        (and an accelerometer bias that looks like one) which the turns reveal to the bank."""
        m = self.mem
        e = self.kf.e
        be = m[_M_GSF + _G_B]
        bn = m[_M_GSF + _G_B + 1]
        d = _wrap(d)
        e[_E_DX + _IX_ATT] = bn / G0_M_S2
        e[_E_DX + _IX_ATT + 1] = -be / G0_M_S2
        e[_E_DX + _IX_ATT + 2] = d
        self._apply_dx()
        self._turned(d)
        for k in range(_GSF_N):
            h = _M_GSF + _G_HYP + k * _NH
            m[h + 5] = m[h + 5] - be
            m[h + 6] = m[h + 6] - bn

    def _yaw_now(self):
        ypr = self._tmp3
        _euler(ypr, self.ins.c_bn)
        return ypr[rot.YAW]

    def _turned(self, d):
        """The navigator's yaw was set, turned by d (rad): the bank's offsets less d."""
        m = self.mem
        m[_M_GSF + _G_DYAW] = m[_M_GSF + _G_DYAW] + _wrap(d)

    def _course_start(self):
        """Navigation starts from the receiver's course and speed (the fix's); the course's
        1-sigma is gnss_vel_sigma / speed. Natively the `nav_restart` kernel
        (nav_aid._restart_native)."""
        if kern.NATIVE:
            self._restart_native(_RESTART_COURSE_START)
            return
        self._room()  # the course's sigma and the start compute in Python floats
        fx = self._fx
        sp = fx[_FX_SPEED]
        s = self.cfg.gnss_vel_sigma / sp
        self._start_navigation(fx[_FX_COURSE], sp, self.cfg.init_vel_sigma, s * s)

    def _set_origin(self):
        """The first stable fix becomes the origin of the navigation frame; False if it cannot
        (geo.LocalFrame.set_origin)."""
        self._room()  # the origin's conversions compute in Python floats (~850 bytes)
        c = self.ctl
        fr = self.frame
        if not fr.set_origin(c[_C_FIX_LAT], c[_C_FIX_LON_DEG], c[_C_FIX_LON_FRAC],
                             self._fx[_FX_H]):  # fmt: skip
            return False
        self.ins.set_frame(fr)
        return True

    def _track(self):
        """Heading and velocity from the track of a receiver that reports no course.

        Anchors are earlier usable fixes (antenna position, measurement tick) with the yaw of
        the attitude when each was processed (the gyros keep the attitude current while
        levelled, `_align`): up to _TR_SLOTS of them, one per _TR_SLOTS-th of `track_max_s`. At
        each fix the shortest window from `track_s` on whose chord d reaches `track_min_m`
        (long against the fixes' noise: a walker needs ~10 s) is looked at: at a mean
        speed |d| / T from `heading_speed_m_s` on, d's direction is the course at the
        window's middle, and the heading has turned since by half the yaw change dyaw over
        the window (a steady turn): course = atan2(d_E, d_N) - dyaw / 2 (course is clockwise,
        yaw counter-clockwise). Too slow or a turn beyond `track_turn_max`: the anchors are
        dropped and this fix is the first of new ones. The chord speed is a mean, behind a
        car accelerating at a by a T / 2, so the filter starts with the horizontal velocity
        sigma `track_vel_sigma`. Cost, at fix ticks while aligning only: the yaw from the
        `euler` kernel; a window's evaluation boxes the floats of a Python atan2 and sqrt on
        the board."""
        self._room()  # a window's chord and speed are Python floats
        if self._trk is None:
            self._track_buffers()
        ypr = self._tmp3  # scratch
        _euler(ypr, self.ins.c_bn)
        i = self._track_anchor()
        if i >= 0 and self._track_window(i, ypr[rot.YAW]):
            return
        c = self.ctl
        if c[_C_TRK_SET] and c[_C_FIX_TICK] - c[_C_TRK_TICK] < c[_C_T_TRACK] // _TR_SLOTS:
            return  # the newest anchor is recent enough
        self._track_push(ypr[rot.YAW])

    def _track_push(self, yaw):
        """This fix becomes the newest anchor (the oldest goes when all slots are held)."""
        c = self.ctl
        k = c[_C_TRK_SET]
        trk, tk = self._trk
        if k == _TR_SLOTS:
            for j in range(3, 3 * _TR_SLOTS):
                trk[j - 3] = trk[j]
            for j in range(1, _TR_SLOTS):
                tk[j - 1] = tk[j]
            k -= 1
        trk[3 * k + _TR_E] = self._gp[0]
        trk[3 * k + _TR_N] = self._gp[1]
        trk[3 * k + _TR_YAW] = yaw
        tk[k] = c[_C_FIX_TICK]
        c[_C_TRK_TICK] = c[_C_FIX_TICK]
        c[_C_TRK_SET] = k + 1

    def _track_anchor(self):
        """The newest anchor from track_s to track_max_s old whose chord to this fix reaches
        track_min_m, or -1."""
        c = self.ctl
        i = c[_C_TRK_SET] - 1
        trk, tk = self._trk
        while i >= 0 and c[_C_FIX_TICK] - tk[i] <= c[_C_T_TRACK]:
            if c[_C_FIX_TICK] - tk[i] >= tk[_TR_SLOTS]:
                de = self._gp[0] - trk[3 * i + _TR_E]
                dn = self._gp[1] - trk[3 * i + _TR_N]
                if de * de + dn * dn >= self.cfg.track_min_m * self.cfg.track_min_m:
                    return i
            i -= 1
        return -1

    def _track_window(self, i, yaw):
        """The chord from anchor i to this fix and the yaw now: True when navigation starts
        (fast enough, turning little enough), else False with the anchors dropped (see
        _track). Its frame, and _track_start's, stay within the VM's on-stack limit
        (tests/runtimes/test_frames.py): the chord goes through the scratch self._tmp3."""
        self.ctl[_C_TRK_SET] = 0
        yaw = _wrap(yaw - self._trk[0][3 * i + _TR_YAW])  # the yaw change over the window
        if not -self.cfg.track_turn_max <= yaw <= self.cfg.track_turn_max:
            return False
        t = self._tmp3
        t[0] = self._gp[0] - self._trk[0][3 * i + _TR_E]
        t[1] = self._gp[1] - self._trk[0][3 * i + _TR_N]
        d = sqrt(t[0] * t[0] + t[1] * t[1])
        t[2] = self._sigma_h() / d  # the chord's direction: 1-sigma sqrt(2) sigma_h / |d|
        t[2] = 2.0 * t[2] * t[2]
        i = self.ctl[_C_FIX_TICK] - self._trk[1][i]  # the window, ticks
        d = d / (f32.f32(i) * self.cfg.dt_s)  # the mean speed
        if d < self.cfg.heading_speed_m_s:
            return False
        self._track_start(yaw, d)
        return True

    def _track_start(self, yaw, sp):
        """Navigation starts from the chord in self._tmp3 (E, N, the course's variance), turned
        by half the window's yaw change, at the mean speed sp."""
        t = self._tmp3
        self._start_navigation(atan2(t[0], t[1]) - yaw * 0.5, sp, self.cfg.track_vel_sigma, t[2])

    def _start_navigation(self, course, sp, sigma_vel, var_course):
        """Heading from course (rad clockwise from north), horizontal velocity sp along it, at
        the current fix's position; sigma_vel: 1-sigma of the horizontal velocity; var_course:
        the course's variance, rad^2: the heading's is the larger of it and init_yaw_sigma^2.
        Natively
        one kernel (`nav_start`), which mirrors `_start_navigation_py` and `_restart`."""
        self._yaw_var(var_course)  # (the caller asked for heap room: _course_start, _track)
        self._turned(-course - self._yaw_now())
        if self._fx[_FX_SIG_V] < 0.0:  # a receiver without height: the height is unknown
            self.mem[_M_CN + _CN_VV] = NO_HEIGHT_VAR
        if _nav_start is None:
            self._start_navigation_py(course, sp, sigma_vel)
            return
        s = self._ns
        s[0] = course
        s[1] = sp
        s[2] = sigma_vel
        _nav_start(self.ctl, self.kf.i, self.mem)

    def _yaw_var(self, var_course):
        """The heading's initial variance, kept in the initial diagonal for later resets
        (nav._restart): the larger of init_yaw_sigma^2 and the course's."""
        y = self.cfg.init_yaw_sigma
        y = y * y
        if var_course > y:
            y = var_course
        self._init[_IX_YAW] = y

    def _start_navigation_py(self, course, sp, sigma_vel):
        """_start_navigation with the Python kernels (the reference of `nav_start`)."""
        ins = self.ins
        ypr = self.ypr
        rot.dcm_to_euler(ypr, ins.c_bn)
        ypr[rot.YAW] = -course
        rot.euler_to_q(ins.q_bn, ypr)
        rot.q_to_dcm(ins.c_bn, ins.q_bn)
        v = self._tmp3
        v[0] = sp * sin(course)
        v[1] = sp * cos(course)
        v[2] = 0.0
        sh = self._sigma_h()
        c = self.ctl
        self._restart(self._gp, v, c[_C_TICK] - c[_C_FIX_TICK], sh, self._sigma_v(sh), sigma_vel)
        ins.take_dvn(self._tmp3)
        ins.slow_update(f32.f32(0))
        c[_C_SINCE_PROP] = 0
        c[_C_ACCEPT_TICK] = c[_C_TICK]
        c[_C_STATE] = _NAVIGATING
