"""The navigator's alignment (state ALIGNING): levelling, the heading, the start of navigation.

A mixin of `nav.Navigator` (its methods run on the Navigator's buffers, made in nav.py):
- `_align` every tick while aligning: sums specific force and rate while levelling, keeps roll
  and pitch current with the gyros once levelled, and takes a pending fix (`_align_fix`);
  natively all but the fix is in nav_tick (navtick.c `align_step`, which mirrors `_align`
  and `_level`), so an aligning tick calls Python only when a fix arrived;
- `_level`: roll and pitch from the mean specific force (it points up at rest), the gyro bias
  from the mean rate when standing still; the heading is kept;
- `_align_fix`: a usable fix (`gnss_stable_fixes` in a row) places the origin and the
  position; once levelled, the heading comes from the receiver's course over ground above
  `heading_speed_m_s` (this board has no magnetometer: a static board cannot know its
  heading), or from the track of the fixes when the receiver reports no course (`_track`);
- `_start_navigation`: heading, velocity along it, position and covariance from the fix, and
  the switch to NAVIGATING.

Frames and units as everywhere (rot.py): ENU navigation frame, yaw counter-clockwise from
north, course over ground clockwise from north (so yaw = -course); rad, m, m/s, ticks.
Runs only while aligning (natively: at fix ticks only); nothing here runs in a navigating tick.
"""

import kern
from micropython import const

import f32
import rot
from fmath import PI, TWO_PI, asin, atan2, cos, sin, sqrt

# Indices into the Navigator's buffers, as nav.py defines them (an underscore const is inlined
# and exists only in its own module; tests/lib/test_nav.py checks that the copies agree).
_NAVIGATING = const(2)  # nav.NAVIGATING
_C_TICK = const(0)  # self.ctl: the control state
_C_STATE = const(1)
_C_STILL = const(3)
_C_ACCEPT_TICK = const(9)
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
_FX_H = const(0)  # self._fx: the pending fix's floats
_FX_SPEED = const(2)
_FX_COURSE = const(3)

# self._trk: the track anchor (heading from GNSS positions, see _track); used only here
_TR_E = const(0)  # antenna position of the anchor fix in the frame, m
_TR_N = const(1)
_TR_YAW = const(2)  # yaw of the attitude when the anchor fix was processed, rad

MIN_LEVEL_F = f32.ratio(49, 10)  # m/s^2: less mean specific force than this cannot be gravity


_nav_start = kern.pick("nav_start", None)  # the reference: _start_navigation_py
_euler = kern.pick("euler", rot.dcm_to_euler)
_fix_usable = kern.pick("fix_usable", None)  # the reference: Navigator._fix_usable


class Alignment:
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
        if not (self._fix_usable() if _fix_usable is None else _fix_usable(c, self.mem)):
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
        course = fx[_FX_COURSE]
        if course >= 0.0:
            c[_C_TRK_SET] = 0
            if fx[_FX_SPEED] >= self.cfg.heading_speed_m_s:
                self._start_navigation(course, fx[_FX_SPEED], self.cfg.init_vel_sigma)
        else:
            self._track()

    def _set_origin(self):
        """The first stable fix becomes the origin of the navigation frame; False if it cannot
        (geo.LocalFrame.set_origin)."""
        c = self.ctl
        fr = self.frame
        if not fr.set_origin(c[_C_FIX_LAT], c[_C_FIX_LON_DEG], c[_C_FIX_LON_FRAC],
                             self._fx[_FX_H]):  # fmt: skip
            return False
        self.ins.set_frame(fr)
        return True

    def _track(self):
        """Heading and velocity from the track of a receiver that reports no course.

        The anchor is an earlier usable fix (antenna position, measurement tick) and the yaw
        of the attitude when it was processed (the gyros keep the attitude current while
        levelled, `_align`). At a fix `track_s` or more after it (at most twice that), the
        chord d from the anchor gives the mean speed |d| / T; from `heading_speed_m_s` on, d's
        direction is the course at the window's middle, and the heading has turned since by
        half the yaw change dyaw over the window (a steady turn): course = atan2(d_E, d_N) -
        dyaw / 2 (course is clockwise, yaw counter-clockwise). Too slow, a turn beyond
        `track_turn_max` or a window too long: this fix becomes the anchor. The chord speed is
        a mean, behind a car accelerating at a by a T / 2, so the filter starts with the
        horizontal velocity sigma `track_vel_sigma`. Cost, at fix ticks while aligning only:
        the yaw from the `euler` kernel; a window's evaluation (`_track_window`) boxes the
        floats of a Python atan2 and sqrt on the board."""
        c = self.ctl
        ypr = self._tmp3  # scratch
        _euler(ypr, self.ins.c_bn)
        if c[_C_TRK_SET]:
            n = c[_C_FIX_TICK] - c[_C_TRK_TICK]
            if n < c[_C_T_TRACK]:
                return  # window not long enough yet: keep the anchor
            if n <= 2 * c[_C_T_TRACK] and self._track_window(n, ypr[rot.YAW]):
                return
        trk = self._trk
        gp = self._gp
        trk[_TR_E] = gp[0]
        trk[_TR_N] = gp[1]
        trk[_TR_YAW] = ypr[rot.YAW]
        c[_C_TRK_TICK] = c[_C_FIX_TICK]
        c[_C_TRK_SET] = 1

    def _track_window(self, n, yaw):
        """The chord over n ticks from the anchor to this fix and the yaw now: navigation
        starts (True) when fast enough and turning little enough (see _track). Locals few:
        its frame stays on the C stack (tests/runtimes/test_frames.py)."""
        de = self._gp[0] - self._trk[_TR_E]
        dn = self._gp[1] - self._trk[_TR_N]
        sp = sqrt(de * de + dn * dn) / (f32.f32(n) * self.cfg.dt_s)
        yaw = yaw - self._trk[_TR_YAW]  # the yaw change over the window
        if yaw > PI:
            yaw = yaw - TWO_PI
        elif yaw < -PI:
            yaw = yaw + TWO_PI
        if sp >= self.cfg.heading_speed_m_s and (
            -self.cfg.track_turn_max <= yaw <= self.cfg.track_turn_max
        ):
            self.ctl[_C_TRK_SET] = 0
            self._start_navigation(atan2(de, dn) - yaw * 0.5, sp, self.cfg.track_vel_sigma)
            return True
        return False

    def _start_navigation(self, course, sp, sigma_vel):
        """Heading from course (rad clockwise from north), horizontal velocity sp along it, at
        the current fix's position; sigma_vel: 1-sigma of the horizontal velocity. Natively
        one kernel (`nav_start`), which mirrors `_start_navigation_py` and `_restart`."""
        if _nav_start is None:
            self._start_navigation_py(course, sp, sigma_vel)
            return
        s = self._ns
        s[0] = course
        s[1] = sp
        s[2] = sigma_vel
        _nav_start(self.ctl, self.kf.i, self.mem)

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
