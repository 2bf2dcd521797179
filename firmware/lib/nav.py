"""The navigator: alignment, strapdown INS and the 15-state ESKF, driven tick by tick.

The loop calls `imu(w_b, f_b)` (SI, or `imu_raw`/`imu_counts` with BMI055 counts) every tick and
`gnss(...)`/`gnss_fix()` when a fix completes. Between calls everything lives in buffers made at
start-up: the control state in `ctl` (ints), every float a tick touches in `mem` (Ins.x and
Eskf.e are views into it). With the native kernels `imu_counts` is one call of `nav_tick` (the
events it cannot handle come back to Python, and `imu_counts` runs them) and allocates nothing;
with the Python kernels every float result is a heap object.

One class, `Navigator`, its methods in three files by job (as PX4's EKF2 splits its Ekf class):
- nav.py (here): inputs, calibration, the standstill detector, the per-tick flow, fix
  screening and re-anchoring, the GNSS delay ring, filter-job scheduling, injection of the
  correction, resets, health and outputs; it owns every buffer and counter;
- nav_align.py (mixin `Alignment`): levelling, the heading, the start of navigation;
- nav_aid.py (mixin `Aiding`): the measurement rows (GNSS position and velocity with the lever
  arm, zero-velocity update, non-holonomic constraint) and the reset to GNSS;
and nav_kern.py holds the Python kernels, the reference of the native ones (navk) this flow
calls: the sample check, the watches, the receiver's unseen error, the lag search...
nav.py stays over 800 lines: its methods share the Navigator's buffers and counters, and a
further module costs the image's code region, which has a few hundred bytes left
(`make image` prints what is left: docs/image.md, "The budget").
Frames and units: ENU navigation frame at the integer origin (geo.py), body x right, y forward,
z up (rot.py), the error state of eskf.py; rad, m, m/s, s, ticks of `dt_s`.

States (docs/requirements.md, original main loop): ALIGNING (1) levels roll and pitch and averages
the gyro bias while the vehicle stands still, waits until GNSS is stable (consecutive good fixes),
and takes the heading from the GNSS course over ground from `heading_speed_m_s` (a walk) on: this
board has no magnetometer, so a static board cannot know its heading. A receiver that reports no
course (GGA only, or position-only data) gives the heading from its track instead: the chord from an
anchor fix once it is `track_min_m` long, whose direction is the course at the window's
middle, turned by half the yaw change the gyros saw over the window (see `nav_align._track`).
Then NAVIGATING (2): INS every tick (ins.py), filter work spread over ticks (eskf.py), GNSS
position and velocity updates with the antenna lever arm, zero-velocity updates at standstill
and the non-holonomic constraint for cars.

GNSS delay (docs/requirements.md, GNSS delay compensation): a ring keeps the last RING ticks of
position and velocity; a fix is compared with the state at its measurement time (the PPS tick when
the caller knows it, else arrival minus the configured latency) and the correction is applied to the
current state. The ring stores each state minus the corrections injected so far, so a correction
injected between the fix time and the update does not make the comparison stale.

Health (docs/requirements.md, FR009): 0 normal, 1 warning, 2 fault, with its causes (CAUSE_* below,
docs/health.md): IMU samples that cannot be right are held, channels whose innovations keep
failing are reset, and the filter's own uncertainty and drift say when not to trust it.
"""

from array import array

from micropython import const

import eskf
import f32
import geo
import ins as ins_mod
import kern
import nav_aid
import rot
from ins import Ins
from nav_aid import Aiding
from nav_align import Alignment

# ---- yaw_gsf.py's consts used here: `python -m common.native.layout` writes them ----
_GSF_N = const(6)
_NH = const(57)
_G_DYAW = const(5)
_G_QA = const(10)
_G_QW = const(11)
_G_READY = const(12)
_G_RMIN = const(13)
_G_QB = const(14)
_G_RV = const(15)
_G_HYP = const(86)
_GSF_DISAGREES = const(2)
_GSF_NAV_BAD = const(4)
# ---- end of yaw_gsf.py's consts ----

ALIGNING = const(1)
NAVIGATING = const(2)
RING = const(128)  # ticks of state history for the GNSS delay (640 ms at 200 Hz): the fix
# latency plus the wait for the filter (a propagation is 31 ticks at one slice per tick)

# The IMU driver's status word (drivers/bmi055.py `status`): the axes that read over range
# (bits 0-5) and the accel die's new_data bits (6-8; all clear: no sample since the last read)
IMU_OVER_RANGE = const(0x3F)
IMU_FRESH = const(0x1C0)
# and the app's bit 9: a missed tick's repeat of the last sample (app._catch_up), not a read of
# its own, so not counted as an unchanged sample (a stall is not a stuck IMU)
IMU_REPEAT = const(0x200)

# Health (docs/requirements.md, FR009: 0 normal, 1 warning, 2 fault) says why in CAUSE_* bits
# (self.ctl[_C_CAUSES], the extended frame): 2 when a CAUSE_FAULTS bit is set, else 1 when any
# bit is. "(1 s)": held for a second after the last occurrence. docs/health.md has the list.
CAUSE_IMU_SAT = const(0x1)  # an IMU axis read over range (1 s)
CAUSE_IMU_HELD = const(0x2)  # an IMU sample unusable, the previous one used instead (1 s)
CAUSE_IMU_DEAD = const(0x4)  # IMU samples held T_STUCK ticks in a row: no IMU data (1 s)
CAUSE_NUMERIC = const(0x8)  # non-finite IMU input, state or covariance (1 s)
CAUSE_GNSS_LOST = const(0x10)  # navigating, no accepted fix for gnss_timeout_s
CAUSE_GNSS_GATED = const(0x20)  # a fix, or part of it, gated out or unusable (1 s)
CAUSE_GNSS_REJECTS = const(0x40)  # 2+ fixes in a row gated out: GNSS and INS disagree
CAUSE_GNSS_DATA = const(0x80)  # the receiver's epoch had an impossible field: unused (1 s)
CAUSE_RESET = const(0x100)  # position and velocity, or the height, reset to a fix (until
# a later fix is accepted whole: the reset may have been onto a bad one)
CAUSE_UNCERTAIN = const(0x200)  # the filter's position 1-sigma above fault_sigma_(v_)m
CAUSE_DRIFT = const(0x400)  # innovations one-sided for several fixes or updates: drift
CAUSE_GNSS_IMPLAUSIBLE = const(0x20000)  # fixes that moved as the board cannot have: a repeated
# (frozen) position while the navigator moves, or a reset refused for a step the IMU cannot
# have drifted (a jump; a receiver far off) (1 s)
CAUSE_NOT_NAVIGATING = const(0x80000)  # aligning (or re-aligning after a fault reset): no
# navigation solution yet, whatever else holds
CAUSE_FAULTS = const(0x2074C)  # IMU_DEAD, NUMERIC, GNSS_REJECTS, RESET, UNCERTAIN, DRIFT,
# GNSS_IMPLAUSIBLE: health 2

# Filter jobs (self.ctl[_C_JOB]). Private consts are inlined and cost no global on the board; the
# NumPy model reads these names through CPython, where they are plain module attributes.
_JOB_NONE = const(0)
_JOB_GNSS = const(1)
_JOB_AID = const(2)  # zero-velocity update or non-holonomic constraint

# Buffer layouts. nav_kern.py, nav_align.py, nav_aid.py, app.py and status_page.py repeat the
# indices they use (an underscore const exists only in its own module), generated from here
# (common/native/const_copies.py).
# self._fx: floats of the pending GNSS fix
_FX_H = const(0)  # height above the ellipsoid, m
_FX_HDOP = const(1)
_FX_SPEED = const(2)  # m/s, < 0 if unknown
_FX_COURSE = const(3)  # rad clockwise from north, < 0 if unknown
_FX_SIG_H = const(4)  # 1-sigma horizontal error, m (0: from HDOP)
_FX_SIG_V = const(5)  # 1-sigma vertical error, m (0: from the horizontal one; < 0: no height)
# self._st: standstill detector
_ST_FX = const(0)  # low-passed specific force (3)
_ST_VAR = const(3)  # low-passed |f - f_lp|^2
_ST_GYRO = const(4)  # low-passed |w - b_g|^2
_ST_SPEED = const(5)  # speed of the last usable fix, m/s
# self._used (the fix of the running GNSS update): nav_aid.py; self._trk (the track
# anchor): nav_align.py

STILL_ALPHA = f32.ratio(1, 8)  # low-pass weight per detector step (50 Hz): ~0.16 s

# self._cal: the calibration of raw counts, and its flags (self.ctl[_C_CAL_FLAGS])
_CAL_G = const(0)  # gyro counts per rad/s
_CAL_A = const(1)  # accel counts per m/s^2
_CAL_GB = const(2)  # gyro bias (3), rad/s
_CAL_AB = const(5)  # accel bias (3), m/s^2
_CAL_GM = const(8)  # gyro matrix (9), when _CAL_HAS_GM
_CAL_AM = const(17)  # accel matrix (9), when _CAL_HAS_AM
_NCAL = const(26)
_CAL_HAS_GM = const(1)
_CAL_HAS_AM = const(2)
# self._stp: the standstill detector's parameters; flags of its kernel
_STP_ALPHA = const(0)
_STP_ACCEL = const(1)
_STP_GYRO = const(2)
_STP_GNSS_SPEED = const(3)
_STP_MAX_SPEED = const(4)
_NSTP = const(5)
_STILL_FIRST = const(1)
_STILL_GNSS_SPEED = const(2)
_STILL_NAVIGATING = const(4)
# self._aid: the aiding parameters (layout.h AID_*; nav_aid.py reads them from cfg)
_AID_UERE = const(0)
_AID_FLOOR = const(1)
_AID_VERT = const(2)
_AID_VEL_SIGMA = const(3)
_AID_ZUPT_SIGMA = const(4)
_AID_NHC_SIGMA = const(5)
_AID_LEVER = const(6)
_AID_HDOP_MAX = const(9)  # worst HDOP accepted (and assumed when a fix gives none)
_AID_REANCHOR = const(10)  # re-anchor the origin beyond this east or north distance, m
_AID_FAULT_SIGMA = const(11)  # health 2 beyond this east or north 1-sigma, m
_AID_FAULT_SIGMA_V = const(12)  # ... or this vertical 1-sigma, m
_AID_HEADING_V = const(13)  # the course is the heading from this speed, m/s
_NAID = const(14)
# self.fix_in: a fix as the receiver gives it, in ints (the app fills it; `gnss_fix`)
FI_LAT_E7 = const(0)
FI_LON_DEG = const(1)  # longitude: whole degrees and 1e-7 deg fraction with their sign
FI_LON_FRAC = const(2)
FI_ALT_MM = const(3)  # height above the ellipsoid, mm; FI_NO_HEIGHT: none (RMC only)
FI_QUALITY = const(4)  # GGA fix quality, 0 none
FI_HDOP_X100 = const(5)  # < 0 if unknown
FI_SPEED_MM_S = const(6)  # < 0 if unknown
FI_COURSE_CDEG = const(7)  # < 0 if unknown
FI_TICK = const(8)  # measurement tick (< 0: arrival less the configured latency)
NFI = const(9)
FI_NO_HEIGHT = const(0x3FFFFFFF)  # fix_in[FI_ALT_MM] of a receiver that never gave a height
# fix_check's result bits
_FC_USABLE = const(1)  # HDOP acceptable
_FC_SPEED = const(2)  # ... and the fix has a speed (now in self._st)
_FC_REANCHOR = const(4)  # the position is beyond reanchor_m from the origin
_FC_MOVING = const(8)  # the navigator moves faster than _FROZEN_V2 allows a repeated fix
_FC_COURSE = const(16)  # the fix has a course
_FC_FAST = const(32)  # ... and a speed of heading_speed_m_s or more (nav_align._align_fix)
# self.ctl: the per-tick control state and the integer configuration it needs, one int buffer
# so that the native `nav_tick` runs a whole navigating tick (layout.h C_*, generated from it)
_C_TICK = const(0)  # ticks since start
_C_STATE = const(1)  # ALIGNING, NAVIGATING
_C_HEALTH = const(2)
_C_STILL = const(3)  # 1: standing still (zero-velocity updates)
_C_N_STILL = const(4)  # ticks the standstill detector has been quiet
_C_SAT_UNTIL = const(5)  # CAUSE_IMU_SAT until this tick
_C_FAULT_UNTIL = const(6)  # CAUSE_NUMERIC until this tick
_C_GATED_UNTIL = const(7)  # CAUSE_GNSS_GATED until this tick
_C_SPEED_TICK = const(8)  # tick of the last usable fix with a speed (its speed: self._st)
_C_ACCEPT_TICK = const(9)  # tick of the last accepted GNSS update
_C_REJECTS = const(10)  # GNSS updates rejected in a row
_C_SINCE_PROP = const(11)  # ticks since the last propagation started
_C_SINCE_ZUPT = const(12)
_C_SINCE_NHC = const(13)
_C_JOB = const(14)  # _JOB_*: what the running filter job is for
_C_FIX_PENDING = const(15)  # 1: a fix arrived, not screened yet
_C_FIX_QUEUED = const(16)  # 1: a usable fix waits for the filter
_C_PHASE = const(17)  # nav_tick: where the tick resumes after an event (0: a new tick)
_C_BUSY = const(18)  # nav_tick: the filter had a job before this tick's slices
_C_FIX_TICK = const(19)  # measurement tick of the pending or queued fix
_C_USED_TICK = const(20)  # measurement tick of the fix in self._used
_C_UPDATES = const(21)  # GNSS updates started (reports: self.updates)
_C_FIX_LAT = const(22)  # the pending fix: lat (1e-7 deg), lon (degrees, 1e-7 deg fraction)
_C_FIX_LON_DEG = const(23)
_C_FIX_LON_FRAC = const(24)
_C_FIX_QUALITY = const(25)
_C_LAST_FIX_TICK = const(26)  # tick a fix last arrived
_C_N_LEVEL = const(27)  # ticks summed in self._lvl (levelling)
_C_LEVELED = const(28)  # 1: roll and pitch levelled
_C_N_STABLE = const(29)  # usable fixes in a row (aligning)
_C_TRK_SET = const(30)  # track anchors held (self._trk; nav_align._track)
_C_TRK_TICK = const(31)  # measurement tick of the newest anchor fix
_C_T_SECOND = const(32)  # configuration in ticks (from here on: set once)
_C_T_STILL = const(33)
_C_T_TIMEOUT = const(34)
_C_T_PROP = const(35)
_C_T_ZUPT = const(36)
_C_T_NHC = const(37)
_C_T_LEVEL = const(38)  # levelling sums this many ticks
_C_T_TRACK = const(39)  # the track window's longest, ticks (at least 1)
_C_T_LATENCY = const(40)  # a fix without a PPS edge was measured this long before arrival
_C_SLICES = const(41)  # filter slices per tick
_C_RESET_AFTER = const(42)  # reset to GNSS after this many rejected updates in a row
_C_OPTS = const(43)  # _OPT_* bits
_C_CAL_FLAGS = const(44)  # 1: gyro matrix, 2: accel matrix
_C_MIN_QUALITY = const(45)  # least GGA fix quality used
_C_IMU_STATUS = const(46)  # the IMU driver's status word this tick (IMU_*: nav_tick's input)
_C_V_REJECTS = const(47)  # GNSS heights rejected in a row
_C_CAUSES = const(48)  # CAUSE_* bits of this tick: why health is not 0
_C_UNCERTAIN = const(49)  # 1: the covariance puts the position beyond fault_sigma_(v_)m
_C_N_HELD = const(50)  # IMU samples held in a row (see nav_kern.imu_check)
_C_N_SAME_G = const(51)  # gyro samples equal to the one before, in a row
_C_N_SAME_A = const(52)  # ... accel samples
_C_PREV_G = const(53)  # the last gyro counts (3)
_C_PREV_A = const(56)  # the last accel counts (3)
_C_T_STUCK = const(59)  # IMU samples held or unchanged this many ticks in a row: dead
_C_HELD_UNTIL = const(60)  # CAUSE_IMU_HELD until this tick
_C_DEAD_UNTIL = const(61)  # CAUSE_IMU_DEAD until this tick
_C_RESET_UNTIL = const(62)  # CAUSE_RESET until this tick (a reset: until a fix agrees)
_C_DATA_UNTIL = const(63)  # CAUSE_GNSS_DATA until this tick
_C_INFLATE = const(64)  # _INFLATE_* bits: P to widen at the next job
_C_DRIFT_UNTIL = const(65)  # CAUSE_DRIFT until this tick
_C_LAG_TICK = const(66)  # measurement tick of the last fix the lag search took (0: none)
_C_IMPLAUSIBLE_UNTIL = const(67)  # CAUSE_GNSS_IMPLAUSIBLE until this tick
_C_PREV_FIX = const(68)  # the last usable fix: lat, lon degrees, lon fraction (3; _frozen)
_C_JUMPED = const(71)  # 1: the run of rejected fixes began with a jump (nav_aid._jumped)
_C_LAST_TICK = const(72)  # measurement tick of the last fix the filter took (0: none; _M_LAST)
_C_FROZEN = const(73)  # 1: the repeats of the last fix were judged frozen (_frozen)
_C_T_STAMP_LAG = const(74)  # the fixes' positions are this much older than their stamps
_C_GSF = const(75)  # 1: the yaw estimator's bank runs (yaw_gsf.py; from the first levelled fix)
_C_GSF_DIS = const(76)  # tick of the first fix of a run the bank disagrees with (0: none)
_C_T_GSF = const(77)  # a disagreement this long, and the navigator's innovations: a reset
_C_STEP_UNTIL = const(78)  # a constraint the INS keeps breaking was seen (a sensor step) until
_NC = const(79)
# (the ints live here, not in attributes, also because a store into an attribute of a class
# with properties searches the class first: thousands of instructions on the board)
_OPT_ZUPT = const(1)
_OPT_NHC = const(2)
_OPT_CONING = const(4)
_OPT_LAG = const(8)  # search the fixes' lag (cfg.gnss_lag_learn)
_OPT_GSF = const(16)  # the heading from the yaw estimator (cfg.yaw_gsf)
_OPT_COURSE = const(32)  # ... or, until it knows, from the course (cfg.heading_from_course)
# self.mem: every float buffer a tick touches, in one (layout.h M_*), so that the native
# `nav_tick` takes few arguments: a call of many arguments makes its caller's frame too large
# for the C stack, and MicroPython then allocates the frame on the heap at every call
_M_X = const(0)  # Ins.x (ins.NX)
_M_E = const(52)  # Eskf.e (eskf.NE)
_M_YPR = const(766)  # yaw, pitch, roll (3)
_M_W = const(769)  # calibrated body rate, rad/s (3)
_M_F = const(772)  # calibrated specific force, m/s^2 (3)
_M_CAL = const(775)  # the calibration (_NCAL)
_M_ST = const(801)  # the standstill detector (6)
_M_STP = const(807)  # its parameters (_NSTP)
_M_CORR = const(812)  # cumulative injected corrections of p and v (6)
_M_RING_P = const(818)  # the delay ring: positions (3 * RING)
_M_RING_V = const(1202)  # ... and velocities (3 * RING)
_M_GP = const(1586)  # the fix's antenna position in the frame, m (3): self._gp
_M_FX = const(1589)  # the pending fix's floats (_FX_*, 6): self._fx
_M_US = const(1595)  # the fix of the running GNSS update (nav_aid.py, 7): self._used
_M_AID = const(1602)  # the aiding parameters (_AID_*): self._aid
_M_INIT = const(1616)  # the initial P diagonal (eskf.N): self._init
_M_NS = const(1631)  # nav_start's course, speed and velocity sigma (3): self._ns
_M_LVL = const(1634)  # sums of f and w while levelling (6): self._lvl
_M_BW = const(1640)  # the drift watch: running means of normalised innovations (5)
_M_CN = const(1645)  # the receiver's unseen error, lag and velocity noise (_CN_*, _NCN)
_M_LAST = const(1660)  # the last fix the filter took: its antenna east, north in the frame (2)
_M_LS = const(1662)  # the lag search (nav_kern.lag_search): residuals east, north and their means
_M_BS = const(1710)  # ... and the suspicion's, each ratio clipped at _BS_CLIP (5)
_M_AW = const(1715)  # the aiding watch: running means of normalised innovations (_AW_*, 2)
_M_GSF = const(1717)  # the yaw estimator's bank (yaw_gsf.py, _G_*: NG)
_M_JUMP = const(2145)  # the innovation east, north at the first fix of a jumped run (2)
_M_RESET_D = const(2147)  # the last reset's step in position east, north (_restart, 2)
_NM = const(2149)
# mem's _M_BW and _M_BS: the scalars the drift watch follows, position E, N, U, velocity E, N
_BW_N = const(5)
# mem's _M_AW: the aiding watch (nav_kern.aid_watch), and its result's bits
_AW_LAT = const(0)  # lateral (the non-holonomic constraint's row 0)
_AW_UP = const(1)  # vertical (the constraint's row 1, the zero-velocity update's row 2)
_AW_HIT_LAT = const(1)
_AW_HIT_UP = const(2)
# ctl's _C_INFLATE: the variances to widen at the next filter job
_INFLATE_MOTION = const(1)  # velocity and attitude (the IMU back after a dead spell)
_INFLATE_VERTICAL = const(2)  # vertical velocity and accelerometer bias (nav_kern.aid_watch)
# nav_kern.drift_watch's bit for a horizontal mean (position or velocity east or north) beyond
# its limit, next to its 1 (suspected) and 2 (drift); and how long the drift is held after
# the reset it caused (s): the biases are then the calibration's again, not yet learned
_DRIFT_H = const(4)
_DRIFT_HOLD_S = const(10)
# mem's _M_CN: the receiver's unseen error, lag, velocity noise (nav_kern.consistency, vel_noise)
_CN_K = const(0)  # seconds of fixes in the running means so far (float, up to _CN_N)
_CN_MH = const(1)  # running mean of y^2/S, east and north
_CN_MV = const(2)  # ... up
_CN_VH = const(3)  # unseen variance per horizontal axis, m^2 (Navigator.cv[0])
_CN_VV = const(4)  # ... vertical, m^2 (Navigator.cv[1])
_CN_KL = const(5)  # pairs of fixes in the lag search's running means (float, up to _CN_N)
_CN_LAG = const(6)  # the lag of the fixes behind their stamps that fits best, s (lag_search)
_CN_LAGT = const(7)  # the lag applied, ticks (float; shrunk towards 0 while uncertain)
_CN_RK = const(8)  # the factor on the position variances of the running update (rate_r)
_CN_KR = const(9)  # seconds of velocity fixes in the velocity noise's means (nav_kern.vel_noise)
_CN_VE = const(10)  # the last fix's velocity innovation east, m/s (_CN_VOK: valid)
_CN_VN = const(11)  # ... north
_CN_VOK = const(12)  # 1.0: the last GNSS update's velocity rows were taken (0.0: none)
_CN_V2 = const(13)  # running mean of the change of y squared less H P H', m^2/s^2
_CN_RVEL = const(14)  # the receiver's velocity variance per horizontal axis, m^2/s^2 (learned)
_NCN = const(15)
# mem's _M_LS: per candidate lag j (j _LS_STEP ticks): the last fix's velocity residual east
# (_LS_E + j), north (_LS_N + j), and the running mean of its change between fixes squared
# (_LS_M + j)
_LS_C = const(16)  # candidates: 0, 20 ms, ... 0.3 s
_LS_STEP = const(4)  # ticks between candidates
_LS_E = const(0)
_LS_N = const(16)
_LS_M = const(32)
_NLS = const(48)
# nav_tick's results: what Python must do before calling it again (0: the tick is done)
_EV_ALIGN = const(1)  # a fix arrived while aligning: _align_fix
_EV_FIX = const(2)  # a fix is pending while navigating: _nav_fix
_EV_RESET = const(3)  # the filter kept rejecting GNSS: _reset_to_gnss
_EV_FAULT = const(4)  # non-finite state or covariance: _fault_reset
_EV_VRESET = const(5)  # the filter kept rejecting the height: _reset_vertical
# the nav_restart kernel's kinds (nav_aid._restart_native)
_RESTART_GNSS = const(0)  # nav_aid._reset_to_gnss
_RESTART_GSF = const(1)  # nav_align._gsf_reset
_RESTART_GSF_START = const(2)  # nav_align._gsf_start
_RESTART_COURSE_START = const(3)  # nav_align._course_start


def _ticks(seconds, dt):
    return int(seconds / dt + 0.5)


class Navigator(Alignment, Aiding):
    @staticmethod
    def memory():
        """A zeroed block for Navigator(cfg, mem): a caller may make it first (app.py)."""
        return f32.zeros(_NM)

    def __init__(self, cfg, mem=None):
        """mem: Navigator.memory(), the block that holds the state (made here if None)."""
        self.cfg = cfg
        dt = cfg.dt_s
        self.mem = m = f32.zeros(_NM) if mem is None else mem
        self.ins = Ins(dt, cfg.earth_terms, cfg.coning, f32.view(m, _M_X, ins_mod.NX))
        self.kf = eskf.Eskf(cfg.earth_terms, f32.view(m, _M_E, eskf.NE))
        self.frame = geo.LocalFrame()
        self.ctl = c = array("i", bytes(4 * _NC))
        c[_C_STATE] = ALIGNING
        self.ypr = f32.view(m, _M_YPR, 3)
        self._w = f32.view(m, _M_W, 3)
        self._f = f32.view(m, _M_F, 3)
        self._tmp3 = f32.zeros(3)
        self._tmp4 = f32.zeros(4)
        self._e7 = array("i", bytes(12))  # lat, lon degrees, lon fraction
        self._h = f32.zeros(1)  # a height (m) for geo.to_enu
        self.fix_in = array("i", bytes(4 * NFI))
        self._ring_p = f32.view(m, _M_RING_P, 3 * RING)
        self._ring_v = f32.view(m, _M_RING_V, 3 * RING)
        self._corr = f32.view(m, _M_CORR, 6)
        self._gp = f32.view(m, _M_GP, 3)  # GNSS antenna position in the frame, m
        self._fx = f32.view(m, _M_FX, 6)
        self._used = f32.view(m, _M_US, 7)
        self._st = f32.view(m, _M_ST, 6)
        self._lvl = f32.view(m, _M_LVL, 6)  # sums of f and w while levelling
        self._init = f32.view(m, _M_INIT, eskf.N)  # initial P diagonal
        self._ns = f32.view(m, _M_NS, 3)
        self._init_motion = f32.view(m, _M_INIT + eskf.IX_VEL, 6)  # for widen
        self._init_vz = f32.view(m, _M_INIT + eskf.IX_VEL + 2, 1)
        self._init_baz = f32.view(m, _M_INIT + eskf.IX_BA + 2, 1)
        # the receiver's error variance the filter cannot see (east/north per axis, up; m^2):
        # what the extended frame adds to P's position diagonal (nav_kern.consistency)
        self.cv = f32.view(m, _M_CN + _CN_VH, 2)
        self._trk = None  # nav_align: the track anchors, made at the first fix without a course
        # configuration derived once
        c[_C_T_PROP] = _ticks(cfg.prop_period_s, dt)
        c[_C_T_ZUPT] = _ticks(cfg.zupt_period_s, dt)
        c[_C_T_NHC] = _ticks(cfg.nhc_period_s, dt)
        c[_C_T_STILL] = _ticks(cfg.still_s, dt)
        c[_C_T_LEVEL] = _ticks(cfg.level_s, dt)
        c[_C_T_TIMEOUT] = _ticks(cfg.gnss_timeout_s, dt)
        c[_C_T_SECOND] = _ticks(f32.f32(1), dt)
        c[_C_SLICES] = cfg.slices_per_tick
        c[_C_RESET_AFTER] = cfg.reset_after_rejects
        c[_C_MIN_QUALITY] = cfg.gnss_min_quality
        c[_C_OPTS] = (
            (_OPT_ZUPT if cfg.zupt else 0)
            | (_OPT_NHC if cfg.nhc else 0)
            | (_OPT_CONING if self.ins.coning else 0)
            | (_OPT_LAG if cfg.gnss_lag_learn else 0)
            | (_OPT_GSF if cfg.yaw_gsf else 0)
            | (_OPT_COURSE if cfg.heading_from_course or not cfg.yaw_gsf else 0)
        )
        c[_C_T_LATENCY] = _ticks(cfg.gnss_latency_s, dt)
        c[_C_T_STAMP_LAG] = _ticks(cfg.gnss_stamp_lag_s, dt)
        c[_C_T_TRACK] = max(1, _ticks(cfg.track_max_s, dt))
        c[_C_T_STUCK] = max(1, _ticks(cfg.imu_stuck_s, dt))
        c[_C_T_GSF] = _ticks(cfg.yaw_gsf_reset_s, dt)
        # called before a step that allocates while navigating (re-anchoring, a reset): the
        # app makes room on the heap then (it checks nothing while navigating otherwise)
        self.heap_check = None
        self._set_calibration(cfg)
        self._set_noise(cfg)
        self._reset_counters()

    def _set_noise(self, cfg):
        kf = self.kf
        q = kf.q_psd
        fl = kf.p_floor
        ce = kf.p_ceiling
        ini = self._init
        arw2 = cfg.gyro_arw * cfg.gyro_arw
        vrw2 = cfg.accel_vrw * cfg.accel_vrw
        gb = cfg.gyro_bias_sigma
        ab = cfg.accel_bias_sigma
        qbg = 2.0 * gb * gb / cfg.gyro_bias_tau_s
        qba = 2.0 * ab * ab / cfg.accel_bias_tau_s
        for i in range(3):
            q[eskf.IX_POS + i] = 0.0
            q[eskf.IX_VEL + i] = vrw2
            q[eskf.IX_ATT + i] = arw2
            q[eskf.IX_BG + i] = qbg
            q[eskf.IX_BA + i] = qba
            fl[eskf.IX_POS + i] = f32.ratio(1, 10000)  # (1 cm)^2
            fl[eskf.IX_VEL + i] = f32.ratio(1, 1000000)  # (1 mm/s)^2
            fl[eskf.IX_ATT + i] = f32.ratio(1, 100000000)  # (0.1 mrad)^2
            fl[eskf.IX_BG + i] = f32.ratio(1, 1000000) * f32.ratio(1, 1000000)  # (1e-6 rad/s)^2
            fl[eskf.IX_BA + i] = f32.ratio(1, 100000000)  # (1e-4 m/s^2)^2
            ce[eskf.IX_POS + i] = f32.f32(100000000)  # (10 km)^2
            ce[eskf.IX_VEL + i] = f32.f32(10000)  # (100 m/s)^2
            ce[eskf.IX_ATT + i] = f32.f32(10)  # ~ (pi)^2
            ce[eskf.IX_BG + i] = f32.ratio(1, 100)  # (0.1 rad/s = 5.7 deg/s)^2
            ce[eskf.IX_BA + i] = f32.f32(1)  # (1 m/s^2)^2
            ini[eskf.IX_VEL + i] = cfg.init_vel_sigma * cfg.init_vel_sigma
            ini[eskf.IX_BG + i] = cfg.init_gyro_bias_sigma * cfg.init_gyro_bias_sigma
            ini[eskf.IX_BA + i] = cfg.init_accel_bias_sigma * cfg.init_accel_bias_sigma
        tilt2 = cfg.init_tilt_sigma * cfg.init_tilt_sigma
        ini[eskf.IX_ATT] = tilt2
        ini[eskf.IX_ATT + 1] = tilt2
        ini[eskf.IX_ATT + 2] = cfg.init_yaw_sigma * cfg.init_yaw_sigma
        kf.set_gate(cfg.gate_sigma, 1.0 / cfg.gyro_bias_tau_s, 1.0 / cfg.accel_bias_tau_s)
        g = f32.view(self.mem, _M_GSF, _G_HYP)  # the yaw estimator's tuning (yaw_gsf.py)
        g[_G_QA] = cfg.yaw_gsf_accel_sigma * cfg.yaw_gsf_accel_sigma
        g[_G_QW] = cfg.yaw_gsf_rate_sigma * cfg.yaw_gsf_rate_sigma
        g[_G_READY] = cfg.yaw_gsf_ready_sigma * cfg.yaw_gsf_ready_sigma
        g[_G_RMIN] = cfg.yaw_gsf_reset_min * cfg.yaw_gsf_reset_min
        g[_G_QB] = cfg.yaw_gsf_bias_walk * cfg.yaw_gsf_bias_walk
        rv = cfg.yaw_gsf_vel_sigma
        if cfg.gnss_vel_sigma > rv:
            rv = cfg.gnss_vel_sigma
        g[_G_RV] = rv * rv

    def _set_calibration(self, cfg):
        cal = f32.view(self.mem, _M_CAL, _NCAL)
        self._cal = cal
        cal[_CAL_G] = cfg.gyro_counts_per_rad_s
        cal[_CAL_A] = cfg.accel_counts_per_m_s2
        flags = 0
        for i in range(3):
            cal[_CAL_GB + i] = cfg.gyro_bias0[i]
            cal[_CAL_AB + i] = cfg.accel_bias0[i]
        if cfg.gyro_matrix is not None:
            flags |= _CAL_HAS_GM
            for i in range(9):
                cal[_CAL_GM + i] = cfg.gyro_matrix[i]
        if cfg.accel_matrix is not None:
            flags |= _CAL_HAS_AM
            for i in range(9):
                cal[_CAL_AM + i] = cfg.accel_matrix[i]
        self.ctl[_C_CAL_FLAGS] = flags
        self._counts_g = array("h", bytes(6))
        self._counts_a = array("h", bytes(6))
        stp = f32.view(self.mem, _M_STP, _NSTP)
        self._stp = stp
        stp[_STP_ALPHA] = STILL_ALPHA
        stp[_STP_ACCEL] = cfg.still_accel
        stp[_STP_GYRO] = cfg.still_gyro
        stp[_STP_GNSS_SPEED] = cfg.still_gnss_speed
        stp[_STP_MAX_SPEED] = cfg.still_max_speed
        aid = f32.view(self.mem, _M_AID, _NAID)
        self._aid = aid
        aid[_AID_UERE] = cfg.gnss_uere_m
        aid[_AID_FLOOR] = cfg.gnss_sigma_floor_m
        aid[_AID_VERT] = cfg.gnss_vert_factor
        aid[_AID_VEL_SIGMA] = cfg.gnss_vel_sigma
        aid[_AID_ZUPT_SIGMA] = cfg.zupt_sigma
        aid[_AID_NHC_SIGMA] = cfg.nhc_sigma
        for i in range(3):
            aid[_AID_LEVER + i] = cfg.lever_b_m[i]
        aid[_AID_HDOP_MAX] = cfg.gnss_hdop_max
        aid[_AID_REANCHOR] = cfg.reanchor_m
        aid[_AID_FAULT_SIGMA] = cfg.fault_sigma_m
        aid[_AID_FAULT_SIGMA_V] = cfg.fault_sigma_v_m
        aid[_AID_HEADING_V] = cfg.heading_speed_m_s
        # the receiver's velocity noise starts at the setting (nav_kern.vel_noise)
        self.mem[_M_CN + _CN_RVEL] = cfg.gnss_vel_sigma * cfg.gnss_vel_sigma

    def _reset_counters(self):
        c = self.ctl
        for i in range(_C_T_SECOND):
            c[i] = 0
        c[_C_STATE] = ALIGNING
        c[_C_SPEED_TICK] = -1000000
        c[_C_LAST_FIX_TICK] = -1000000
        self.resets = 0  # recoveries: reset to GNSS after rejects, or after a fault
        self.reanchors = 0  # origin moves

    # the control state by name (the per-tick code reads self.ctl)
    @property
    def tick(self):
        return self.ctl[_C_TICK]

    @tick.setter
    def tick(self, value):
        self.ctl[_C_TICK] = value

    @property
    def state(self):
        return self.ctl[_C_STATE]

    @state.setter
    def state(self, value):
        self.ctl[_C_STATE] = value

    @property
    def health(self):
        return self.ctl[_C_HEALTH]

    @property
    def causes(self):
        """CAUSE_* bits: why health is not 0."""
        return self.ctl[_C_CAUSES]

    @property
    def updates(self):
        """GNSS updates started since the start (reports)."""
        return self.ctl[_C_UPDATES]

    @property
    def leveled(self):
        """Roll and pitch levelled (aligning)."""
        return self.ctl[_C_LEVELED] != 0

    @property
    def still(self):
        return self.ctl[_C_STILL] != 0

    @still.setter
    def still(self, value):
        self.ctl[_C_STILL] = 1 if value else 0

    # ---- inputs --------------------------------------------------------------------------

    def imu_raw(self, gyro_counts, accel_counts, saturated=False, fresh=True):
        """One tick from BMI055 counts (3 ints each, sensor axes, any sequence); saturated: an
        axis read over range; fresh: the accel die had a new sample (its new_data bits)."""
        cg = self._counts_g
        ca = self._counts_a
        for i in range(3):
            cg[i] = gyro_counts[i]
            ca[i] = accel_counts[i]
        self.imu_counts(cg, ca, (1 if saturated else 0) | (IMU_FRESH if fresh else 0))

    def imu_counts(self, gyro_h, accel_h, status=IMU_FRESH):
        """imu_raw for counts already in array('h') buffers (the BMI055 driver's: no copy) and
        the driver's status word (IMU_*).

        A sample that cannot be right (an axis over range, no new accel sample, the all-zero
        or idle-bus pattern, counts unchanged for T_STUCK ticks: nav_kern.imu_check) is not
        used: the previous sample is integrated again (CAUSE_IMU_HELD, and CAUSE_IMU_DEAD when
        that goes on for T_STUCK ticks), so a dead or stuck IMU costs the dead reckoning of a
        constant rate and specific force, not the integration of garbage.

        With the native kernels the whole tick is one call of `nav_tick`, which mirrors
        `_imu_counts_py` and `_tick` below (the reference) on the same buffers (self.mem,
        self.ctl). It returns at each step that runs in Python (alignment, a fix's screening,
        a reset: _EV_*) and is called again to resume after it. This method's frame stays
        within the VM's on-stack limit (tests/runtimes/test_frames.py): keep its locals and
        arguments few."""
        self.ctl[_C_IMU_STATUS] = status
        if _nav_tick is None:
            self._imu_counts_py(gyro_h, accel_h)
            return
        ev = _nav_tick(self.ctl, self.kf.i, self.mem, gyro_h, accel_h)
        while ev:
            # the events of a tick with a fix dispatched here: a Python call less
            if ev == _EV_ALIGN:
                self._align_fix()
            elif ev == _EV_FIX:
                self._nav_fix()
            else:
                self._reset_event(ev)
            ev = _nav_tick(self.ctl, self.kf.i, self.mem, gyro_h, accel_h)

    def _imu_counts_py(self, gyro_h, accel_h):
        if nav_kern.imu_check(self.ctl, gyro_h, accel_h):
            self._tick(nav_kern.finite6(self._w, self._f), True)  # the previous sample, again
            return
        finite = imu_cal(self._w, self._f, gyro_h, accel_h, self._cal, self.ctl[_C_CAL_FLAGS])
        self._tick(finite, False)

    def _reset_event(self, ev):
        """nav_tick's rare events (_EV_RESET, _EV_VRESET, _EV_FAULT): the reset they ask for."""
        if ev == _EV_RESET:
            self._reset_to_gnss()
        elif ev == _EV_VRESET:
            self._reset_vertical()
        else:
            self._fault_reset()

    def imu(self, w_in, f_in, saturated=False):
        """One tick: sensor-axes rate (rad/s) and specific force (m/s^2), used as given (the
        sample checks of imu_counts are on counts)."""
        if nav_kern is None:  # the Python flow below calls the Python kernels (see there)
            _load_python_kernels()
        self.ctl[_C_IMU_STATUS] = 1 if saturated else 0
        self._tick(self._calibrate(w_in, f_in), False)

    def _tick(self, finite, held):
        c = self.ctl
        c[_C_TICK] += 1
        t = c[_C_TICK]
        if c[_C_IMU_STATUS] & IMU_OVER_RANGE:
            c[_C_SAT_UNTIL] = t + c[_C_T_SECOND]
        if held:
            c[_C_HELD_UNTIL] = t + c[_C_T_SECOND]
            if c[_C_N_HELD] < c[_C_T_STUCK]:
                c[_C_N_HELD] += 1
            if c[_C_N_HELD] >= c[_C_T_STUCK]:
                c[_C_DEAD_UNTIL] = t + c[_C_T_SECOND]
        else:
            if c[_C_N_HELD] >= c[_C_T_STUCK]:
                c[_C_INFLATE] |= _INFLATE_MOTION  # the IMU is back after a dead spell
            c[_C_N_HELD] = 0
        if not finite:
            c[_C_FAULT_UNTIL] = t + c[_C_T_SECOND]
            self._update_health()
            return
        if t & 3 == 0 and not held:  # the standstill detector sees only real samples
            self._still_update()
        if c[_C_STATE] == NAVIGATING:
            self._navigate()
        else:
            self._align()
        self._update_health()

    def gnss(self, lat_e7, lon_deg, lon_frac, h_m, quality, hdop, speed_m_s, course_rad,
             fix_tick=-1, sigma_h_m=0.0, sigma_v_m=0.0):  # fmt: skip
        """A completed fix of the antenna in floats (hosts, tests): integer lat (1e-7 deg) and
        lon (whole degrees and 1e-7 deg fraction of the same sign: geo.split_e7), height (m),
        fix quality (0 none), HDOP, speed (m/s, < 0 if unknown) and course over ground (rad
        clockwise from north, < 0 if unknown), the tick of its measurement time (the PPS tick;
        < 0: arrival - latency), and optional 1-sigma errors (0: from HDOP; sigma_v_m < 0: the
        fix has no height, and h_m serves only as the origin's and the start's, as the app's 0
        does). Processed at the next tick. The board's app uses `gnss_fix` (ints, no
        allocation)."""
        fx = self._fx
        fx[_FX_H] = h_m
        fx[_FX_HDOP] = hdop
        fx[_FX_SPEED] = speed_m_s
        fx[_FX_COURSE] = course_rad
        fx[_FX_SIG_H] = sigma_h_m
        fx[_FX_SIG_V] = sigma_v_m
        self._take_fix(lat_e7, lon_deg, lon_frac, quality, fix_tick)

    def gnss_fix(self):
        """The fix in self.fix_in (FI_*: the receiver's integers) as `gnss` takes it; the
        conversion to floats is one kernel (`fix_in`), so nothing is allocated. Natively the
        whole method is one kernel (`gnss_fix`: fix_in and _take_fix)."""
        if _gnss_fix is not None:
            _gnss_fix(self.ctl, self.mem, self.fix_in)
            return
        fi = self.fix_in
        fix_in(self._fx, fi, self._aid)
        self._take_fix(fi[FI_LAT_E7], fi[FI_LON_DEG], fi[FI_LON_FRAC], fi[FI_QUALITY],
                       fi[FI_TICK])  # fmt: skip

    def _take_fix(self, lat_e7, lon_deg, lon_frac, quality, fix_tick):
        c = self.ctl
        c[_C_FIX_LAT] = lat_e7
        c[_C_FIX_LON_DEG] = lon_deg
        c[_C_FIX_LON_FRAC] = lon_frac
        c[_C_FIX_QUALITY] = quality
        if quality < 0:  # the app dropped an epoch with an impossible field
            c[_C_DATA_UNTIL] = c[_C_TICK] + c[_C_T_SECOND]
        if fix_tick < 0:
            fix_tick = c[_C_TICK] - c[_C_T_LATENCY]
        c[_C_FIX_TICK] = fix_tick - c[_C_T_STAMP_LAG]
        c[_C_FIX_PENDING] = 1

    # ---- per tick ------------------------------------------------------------------------

    def _calibrate(self, w_in, f_in):
        return nav_kern.cal_si(self._w, self._f, w_in, f_in, self._cal, self.ctl[_C_CAL_FLAGS])

    def _still_update(self):
        """Standstill detector at 50 Hz: low-passed specific-force changes and rotation rate
        (the float work: `still`, below)."""
        c = self.ctl
        flags = 0
        if c[_C_TICK] == 4:
            flags = _STILL_FIRST  # start the low-pass at the first sample, not at zero
        if c[_C_TICK] - c[_C_SPEED_TICK] < c[_C_T_SECOND]:
            flags |= _STILL_GNSS_SPEED
        if c[_C_STATE] == NAVIGATING:
            flags |= _STILL_NAVIGATING
        if still(self._st, self._f, self._w, self.ins.x, self._stp, flags):
            c[_C_N_STILL] += 4
        else:
            c[_C_N_STILL] = 0
        c[_C_STILL] = 1 if c[_C_N_STILL] >= c[_C_T_STILL] else 0

    def _fix_usable(self):
        """fix_check's bits, non-zero when quality and HDOP are acceptable (_FC_REANCHOR: see
        _nav_fix); a usable fix's speed, if it has one, also feeds standstill detection (an
        unknown speed, < 0 or NaN, is no speed measurement). While a drift is held
        (_C_DRIFT_UNTIL) any HDOP is acceptable: a fix of 8 m is worth more than an INS with a
        bias it has not learned (`make bench-faults`, seed 1: through 8 s of HDOP over
        gnss_hdop_max a 1 deg/s gyro step ran to 223 m, 96 m with this alone). Natively one kernel
        (`fix_usable`), which the callers call instead."""
        c = self.ctl
        if c[_C_FIX_QUALITY] < c[_C_MIN_QUALITY]:
            return 0
        any_hdop = 1 if c[_C_TICK] < c[_C_DRIFT_UNTIL] else 0
        r = fix_check(self._st, self._fx, self.ins.x, self._aid, self.kf.e, any_hdop)
        if r & _FC_SPEED:
            c[_C_SPEED_TICK] = c[_C_TICK]
        return r

    def _navigate(self):
        ins = self.ins
        x = ins.x
        c = self.ctl
        ins_step(x, self._w, self._f, ins.coning)
        # ring of state history, minus the corrections injected so far
        ring_put(self._ring_p, self._ring_v, x, self._corr, (c[_C_TICK] % RING) * 3)
        if c[_C_GSF]:
            self._gsf_accum()
        c[_C_SINCE_PROP] += 1
        c[_C_SINCE_ZUPT] += 1
        c[_C_SINCE_NHC] += 1
        if c[_C_FIX_PENDING]:
            c[_C_FIX_PENDING] = 0
            self._nav_fix()
        kf = self.kf
        ki = kf.i
        if ki[eskf.I_JOB] == eskf.IDLE and not ki[eskf.I_READY]:
            self._schedule()
        busy = ki[eskf.I_JOB] != eskf.IDLE
        kf.work(c[_C_SLICES])
        if ki[eskf.I_READY]:
            self._inject()
        # P changes only when a job finishes: check it then, not every tick
        if busy and ki[eskf.I_JOB] == eskf.IDLE:
            if not kf.diagonal_ok():
                self._fault_reset()
                return
            c[_C_UNCERTAIN] = nav_kern.uncertain(kf.e, self._aid, self.mem)
        if not ins_finite(x):
            self._fault_reset()

    def _nav_fix(self):
        """A new fix while navigating: screen it, re-anchor if far, queue it for the filter.
        The filter's slices per tick follow the receiver's rate (the ticks since the last
        fix): one update a second leaves it time, five or ten do not, and a fix that waits
        is replaced by the next (_rate_slices)."""
        c = self.ctl
        c[_C_SLICES] = _rate_slices(c[_C_TICK] - c[_C_LAST_FIX_TICK], self.cfg.slices_per_tick)
        c[_C_LAST_FIX_TICK] = c[_C_TICK]
        usable = self._fix_usable() if _fix_usable is None else _fix_usable(c, self.mem)
        if not usable:
            c[_C_GATED_UNTIL] = c[_C_TICK] + c[_C_T_SECOND]
            return
        if self._frozen(usable):
            return
        if usable & _FC_REANCHOR:
            self._reanchor()
        # the height is fx[_FX_H], at index 0: fx serves as to_enu's height buffer
        self.frame.to_enu(self._gp, c[_C_FIX_LAT], c[_C_FIX_LON_DEG], c[_C_FIX_LON_FRAC],
                          self._fx)  # fmt: skip
        if c[_C_OPTS] & _OPT_GSF and self._gsf_watch():
            return  # the heading was reset to the yaw estimator's, at this fix
        c[_C_FIX_QUEUED] = 1  # until the filter is free (see _schedule)

    def _gsf_watch(self):
        """The yaw estimator's step at a navigating fix (yaw_gsf.py): True when it has
        disagreed with the navigator's heading for _C_T_GSF ticks (ready, beyond 3 sigma of
        both) and the navigator's own innovations say it is wrong too (fixes rejected, gated
        or drifting away, or its positions' y^2 / S high on the mean: GSF_NAV_BAD), and the
        heading, velocity and covariance were reset (_gsf_reset). Never while the fixes are
        rejected in a run that began with a jump of the receiver (_C_JUMPED): the bank, fed
        the same fixes, disagrees then too, and the reset would take the receiver's position.
        The float work is the step's (a native kernel on the board): nothing allocates."""
        c = self.ctl
        r = self._gsf_step()
        if not r & _GSF_DISAGREES:
            c[_C_GSF_DIS] = 0
            return False
        t = c[_C_TICK]
        if not c[_C_GSF_DIS]:
            c[_C_GSF_DIS] = t
        if t - c[_C_GSF_DIS] < c[_C_T_GSF]:
            return False
        if c[_C_REJECTS] and c[_C_JUMPED]:
            # the receiver's fault, not the heading's: a reset here took the position of a
            # receiver 2000 km off (`make bench-faults`, gnss-jump@250+30:2000000, seeds 0, 2)
            return False
        if not (r & _GSF_NAV_BAD or c[_C_REJECTS] or t < c[_C_GATED_UNTIL]
                or t < c[_C_DRIFT_UNTIL]):  # fmt: skip
            return False
        self._gsf_reset()
        return True

    def _apply_dx(self):
        """The filter's dx into the state (the `inject` kernel), without a job's bookkeeping:
        nav_align._gsf_turn's rotation."""
        inject(self.ins.x, self.kf.e, self._corr)

    def _gsf_accum(self):
        """The yaw estimator's share of a tick (the Python flow's: natively nav_tick's)."""
        yaw_gsf.gsf_accum(self.mem)

    def _gsf_step(self):
        if _gsf_step is None:
            return yaw_gsf.gsf_step(self.ctl, self.mem)
        return _gsf_step(self.ctl, self.mem)

    def _frozen(self, usable):
        """True, and CAUSE_GNSS_IMPLAUSIBLE for a second, when the usable fix repeats the last
        one to the 1e-7 degree while the navigator moves faster than _FROZEN_V2 allows and
        than 3 sigma of its own velocity, and the receiver does not report a speed under it
        (fix_check's _FC_MOVING: the float work is the kernel's): a receiver that keeps
        sending its last solution (a real one's noise moves every fix; one that holds its
        position at a standstill holds it where the navigator stands too, and says so with
        its speed or, without one, by the navigator's not knowing that it moves: a hand-held
        walk's phone at each waypoint, while the navigator's velocity had drifted over 1 m/s,
        was judged frozen and the walk ran away by 100 m; without speeds, at 1.1 m/s with a
        sigma of 1.8 m/s, by 62.9 m). Such a fix is not used, nor are its repeats once the
        navigator stops (the position is stale by the way driven since). The fix becomes the
        last one either way."""
        c = self.ctl
        same = (
            c[_C_FIX_LAT] == c[_C_PREV_FIX]
            and c[_C_FIX_LON_DEG] == c[_C_PREV_FIX + 1]
            and c[_C_FIX_LON_FRAC] == c[_C_PREV_FIX + 2]
        )
        c[_C_PREV_FIX] = c[_C_FIX_LAT]
        c[_C_PREV_FIX + 1] = c[_C_FIX_LON_DEG]
        c[_C_PREV_FIX + 2] = c[_C_FIX_LON_FRAC]
        if same and (usable & _FC_MOVING or c[_C_FROZEN]):
            c[_C_FROZEN] = 1  # until the fix changes: a stop does not make it fresh
            self._implausible()
            return True
        c[_C_FROZEN] = 0
        return False

    def _room(self):
        """Before a step that allocates: the app's heap check, if it gave one."""
        if self.heap_check is not None:
            self.heap_check()

    def _reanchor(self):
        """New integer origin at the current position; state re-expressed in the new frame."""
        self._room()
        fr = self.frame
        ins = self.ins
        e7 = self._e7
        hb = self._h
        hb[0] = fr.to_e7(e7, ins.p_n)
        dp = self._tmp3
        fr.to_enu(dp, e7[0], e7[1], e7[2], hb)  # the new origin, in the old frame
        c = fr.coef
        rho = self._tmp4
        # the tangent plane tilts by the angle subtended at the Earth's centre
        rho[0] = -dp[1] * c[geo.INV_RM]
        rho[1] = dp[0] * c[geo.INV_RN]
        rho[2] = dp[0] * c[geo.INV_RN] * (c[geo.SIN_LAT] / c[geo.COS_LAT])
        ins.shift_origin(dp, rho)
        corr = self._corr
        for i in range(3):
            corr[i] = corr[i] - dp[i]
        m = self.mem
        m[_M_LAST] = m[_M_LAST] - dp[0]
        m[_M_LAST + 1] = m[_M_LAST + 1] - dp[1]
        for k in range(_GSF_N):  # the yaw estimator's positions, in the new frame
            h = _M_GSF + _G_HYP + k * _NH
            m[h] = m[h] - dp[0]
            m[h + 1] = m[h + 1] - dp[1]
        fr.set_origin(e7[0], e7[1], e7[2], hb[0])
        ins.set_frame(fr)
        self.reanchors += 1

    # ---- filter jobs, injection, resets ----------------------------------------------------

    def _schedule(self):
        """Start the next filter job (the filter is idle): a queued fix (unless propagation,
        or the zero-velocity update or non-holonomic constraint that applies, is overdue:
        twice its period), else propagation, else a zero-velocity update at standstill, else
        the non-holonomic constraint (the measurement rows: nav_aid.py). Without the overdue
        aiding rule a 10 Hz receiver's updates left the constraint 38 turns in 165 s of
        highway instead of 330, and the heading drifted (`make bench-nav` at 11585ba,
        highway_outage at 10 Hz: 3.08 m, 0.45 deg yaw; with the rule 1.74 m, 0.15 deg)."""
        c = self.ctl
        kf = self.kf
        if c[_C_INFLATE] & _INFLATE_MOTION:
            # what the held samples missed: velocity and attitude variances at least their
            # initial ones again, so that GNSS corrects them instead of being gated out
            kf.widen(self._init_motion, eskf.IX_VEL, 6)
        if c[_C_INFLATE] & _INFLATE_VERTICAL:
            # a vertical accelerometer step (nav_kern.aid_watch): vertical velocity and
            # accelerometer bias variances at least their initial ones, so that the constraints
            # that gated it out take it and the filter learns the new bias
            kf.widen(self._init_vz, eskf.IX_VEL + 2, 1)
            kf.widen(self._init_baz, eskf.IX_BA + 2, 1)
        c[_C_INFLATE] = 0
        overdue = c[_C_SINCE_PROP] >= 2 * c[_C_T_PROP]
        if c[_C_OPTS] & _OPT_ZUPT and c[_C_STILL] and c[_C_SINCE_ZUPT] >= 2 * c[_C_T_ZUPT]:
            overdue = True
        elif c[_C_OPTS] & _OPT_NHC and not c[_C_STILL] and c[_C_SINCE_NHC] >= 2 * c[_C_T_NHC]:
            overdue = True
        if c[_C_FIX_QUEUED] and not overdue:
            self._start_queued_fix()
        elif c[_C_SINCE_PROP] >= c[_C_T_PROP]:
            ins = self.ins
            if _prop_start is not None:
                _prop_start(ins.x, kf.e, kf.i, c[_C_SINCE_PROP])
            else:
                t = f32.f32(c[_C_SINCE_PROP]) * self.cfg.dt_s
                ins.take_dvn(self._tmp3)
                ins.slow_update(t)
                kf.start_propagation(self._tmp3, t, ins.c_bn, ins.w_ie_n)
            c[_C_SINCE_PROP] = 0
        elif c[_C_OPTS] & _OPT_ZUPT and c[_C_STILL] and c[_C_SINCE_ZUPT] >= c[_C_T_ZUPT]:
            c[_C_SINCE_ZUPT] = 0
            c[_C_JOB] = _JOB_AID
            self._start_zupt()
        elif c[_C_OPTS] & _OPT_NHC and not c[_C_STILL] and c[_C_SINCE_NHC] >= c[_C_T_NHC]:
            c[_C_SINCE_NHC] = 0
            c[_C_JOB] = _JOB_AID
            self._start_nhc()

    def _start_queued_fix(self):
        """The GNSS update of the queued fix, against the state at its measurement time (the
        ring holds the last RING ticks)."""
        c = self.ctl
        c[_C_FIX_QUEUED] = 0
        # a receiver whose fixes are older than their stamps: the lag its search applies
        age = c[_C_TICK] - c[_C_FIX_TICK]
        nav_kern.lag_search(c, self.mem, age)
        age = age + int(self.mem[_M_CN + _CN_LAGT])
        if age < 0:
            age = 0
        elif age > RING - 1:
            age = RING - 1
        c[_C_JOB] = _JOB_GNSS
        c[_C_UPDATES] += 1
        rk = nav_kern.rate_r(c)
        self.mem[_M_CN + _CN_RK] = rk
        self._start_gnss_update(((c[_C_TICK] - age) % RING) * 3, rk)

    def _inject(self):
        """Closed-loop correction (docs/requirements.md, error-state filter formulation): p -= dp, v
        -= dv, q = q(phi) (x) q, b += db."""
        kf = self.kf
        c = self.ctl
        # the yaw correction turns the navigator, not the truth: the bank's offsets less it
        m = self.mem
        m[_M_GSF + _G_DYAW] = m[_M_GSF + _G_DYAW] + kf.e[eskf.E_DX + eskf.IX_ATT + 2]
        inject(self.ins.x, kf.e, self._corr)
        kf.i[eskf.I_READY] = 0
        job = c[_C_JOB]
        c[_C_JOB] = _JOB_NONE
        if job == _JOB_AID:
            hit = nav_kern.aid_watch(kf.e, self.mem, kf.i[eskf.I_ACCEPTED] + kf.i[eskf.I_REJECTED])
            if hit:
                # a constraint the INS keeps breaking: a sensor step, for 5 s after each update
                # that shows it, as a drift (the mean hovers at its limit while the step acts,
                # and the error it left outlasts the hits: 1.5 s left 44 frames above 10 m
                # without health 2 in `make bench-faults`, 5 s none)
                w = c[_C_TICK] + 5 * c[_C_T_SECOND]
                if w > c[_C_DRIFT_UNTIL]:
                    c[_C_DRIFT_UNTIL] = w
                c[_C_STEP_UNTIL] = w
                if hit & _AW_HIT_UP:
                    c[_C_INFLATE] |= _INFLATE_VERTICAL
        if job == _JOB_GNSS:
            # a fix whose east or north position or velocity was gated out counts as rejected:
            # one axis drifting away (or a wrong heading turning the velocity) while the others
            # are accepted must still end in a reset; the height is a channel of its own (a
            # diverged vertical channel is reset alone)
            mask = kf.i[eskf.I_GATE_MASK]
            ki = kf.i
            n = ki[eskf.I_ACCEPTED] + ki[eskf.I_REJECTED]
            w = nav_kern.drift_watch(kf.e, self.mem, n, c[_C_TICK] < c[_C_DRIFT_UNTIL])
            if w & 3:
                # a drift: for 5 s; a suspected one: for 1.5 s after the fix that shows it
                t = c[_C_TICK] + (5 * c[_C_T_SECOND] if w & 3 == 2 else 3 * c[_C_T_SECOND] // 2)
                if t > c[_C_DRIFT_UNTIL]:
                    c[_C_DRIFT_UNTIL] = t
            # a sensor step the constraints show (_C_STEP_UNTIL), the yaw estimator agreeing
            # with the heading: a rejected fix, or a horizontal drift, resets now (_drift_reset)
            step = c[_C_TICK] < c[_C_STEP_UNTIL] and not c[_C_GSF_DIS]
            nav_kern.consistency(kf.e, self.mem, n, mask)
            nav_kern.vel_noise(kf.e, self.mem, n, mask)
            if mask & 4:
                c[_C_V_REJECTS] += 1
            else:
                c[_C_V_REJECTS] = 0
            if mask & 0x1B:
                c[_C_REJECTS] += 1
                if c[_C_REJECTS] == 1:
                    c[_C_JUMPED] = 1 if self._jumped() else 0
                    m[_M_JUMP] = m[_M_E + eskf.E_Z]
                    m[_M_JUMP + 1] = m[_M_E + eskf.E_Z + 1]
                c[_C_GATED_UNTIL] = c[_C_TICK] + c[_C_T_SECOND]
                self._last_fix()
                if c[_C_REJECTS] >= c[_C_RESET_AFTER] or step:
                    if c[_C_JUMPED] and nav_aid.refused(self):  # the receiver jumped: no reset
                        self._implausible()
                    else:
                        if c[_C_REJECTS] < c[_C_RESET_AFTER]:
                            self._drift_reset()
                        self._reset_to_gnss()
            else:
                self._last_fix()
                c[_C_REJECTS] = 0
                c[_C_ACCEPT_TICK] = c[_C_TICK]
                if mask:
                    c[_C_GATED_UNTIL] = c[_C_TICK] + c[_C_T_SECOND]
                elif c[_C_RESET_UNTIL] > c[_C_TICK]:
                    c[_C_RESET_UNTIL] = c[_C_TICK]  # a whole fix agrees with the reset state
                if c[_C_V_REJECTS] >= c[_C_RESET_AFTER]:
                    self._reset_vertical()
                elif step and w & _DRIFT_H:
                    self._drift_reset()
                    self._reset_to_gnss()

    def _implausible(self):
        """CAUSE_GNSS_IMPLAUSIBLE for a second, or longer if a reset holds it (Aiding._hold)."""
        c = self.ctl
        t = c[_C_TICK] + c[_C_T_SECOND]
        if t > c[_C_IMPLAUSIBLE_UNTIL]:
            c[_C_IMPLAUSIBLE_UNTIL] = t

    def _drift_reset(self):
        """A reset to GNSS before RESET_AFTER rejected fixes, for a sensor step: while the
        aiding watch sees a constraint broken (_C_STEP_UNTIL, nav_kern.aid_watch), at a fix
        rejected or at one whose innovations the drift watch finds drifting horizontally
        (_DRIFT_H), suspected or not. A bias step runs the INS off faster than five rejected
        fixes let it (`make bench-faults`, a 1 deg/s gyro step: 223 m before this, see
        docs/health.md); the constraints tell such a step from late fixes or a walker's wrong
        heading, which drift as much but break no constraint, and which resets do not mend
        (every drift reset at once took `bench-nav`'s walk from 0.71 to 4.77 m and its
        urban_drive with fixes 0.2 s late from 2.27 to 11.86 m); a car's wrong heading breaks
        the constraint too, and while the yaw estimator disagrees with it (_C_GSF_DIS) its own
        reset mends the heading (_gsf_watch), not this one. The drift is held _DRIFT_HOLD_S
        after it (health 2): the reset puts the biases back to the calibration, and while the
        filter learns them again a step still acting runs off again (a 1 deg/s gyro step left
        10-13 m without health 2 within 8 s of its reset). navtick.c inject does the same."""
        c = self.ctl
        t = c[_C_TICK] + _DRIFT_HOLD_S * c[_C_T_SECOND]
        if t > c[_C_DRIFT_UNTIL]:
            c[_C_DRIFT_UNTIL] = t

    def _restart(self, gp, v, age, sigma_h, sigma_v, sigma_vel, keep_height=False):
        """Position and velocity from a fix (antenna gp, velocity v, taken `age` ticks ago),
        covariance from the initial diagonal, the fix's sigmas and the horizontal velocity's
        sigma_vel; the step in position east, north into mem's _M_RESET_D (nav_aid.refused).
        keep_height: the height stays the navigator's, and the variances of the height, the
        vertical velocity and the vertical accelerometer bias stay P's (their covariances
        with the rest restart at 0)."""
        ins = self.ins
        p = self._tmp4
        self._lever_n(p)
        if age < 0:
            age = 0
        t = f32.f32(age) * self.cfg.dt_s
        for i in range(3):
            # IMU = antenna - C_bn lever, carried forward over the fix's age
            p[i] = (gp[i] - p[i]) + v[i] * t
        pk = self.kf.P
        kh = eskf.N + 1
        if keep_height:
            p[2] = ins.p_n[2]
            k_h = pk[2 * kh]
            k_v = pk[(eskf.IX_VEL + 2) * kh]
            k_b = pk[(eskf.IX_BA + 2) * kh]
        m = self.mem
        m[_M_RESET_D] = p[0] - ins.p_n[0]
        m[_M_RESET_D + 1] = p[1] - ins.p_n[1]
        ins.reset_kinematics(p, v)
        ini = self._init
        ini[0] = sigma_h * sigma_h
        ini[1] = sigma_h * sigma_h
        ini[2] = sigma_v * sigma_v
        vv = sigma_vel * sigma_vel
        ini[eskf.IX_VEL] = vv
        ini[eskf.IX_VEL + 1] = vv
        self.kf.reset_p(ini)
        if keep_height:
            pk[2 * kh] = k_h
            pk[(eskf.IX_VEL + 2) * kh] = k_v
            pk[(eskf.IX_BA + 2) * kh] = k_b
        for i in range(6):
            self._corr[i] = 0.0
        self.ctl[_C_LAG_TICK] = 0  # the velocity track jumps: no pair for the lag search

    def _fault_reset(self):
        """Non-finite state or covariance: back to a safe state and re-align."""
        self._room()
        ins = self.ins
        c = self.ctl
        c[_C_STATE] = ALIGNING
        rot.q_identity(ins.q_bn)
        rot.q_to_dcm(ins.c_bn, ins.q_bn)
        z = self._tmp3
        for i in range(3):
            z[i] = 0.0
            ins.bg[i] = 0.0
            ins.ba[i] = 0.0
        ins.reset_kinematics(self._gp, z)
        self.kf.reset_p(self._init)
        for i in range(6):
            self._lvl[i] = 0.0
            self._corr[i] = 0.0
        c[_C_N_LEVEL] = 0
        c[_C_N_STABLE] = 0
        c[_C_FIX_QUEUED] = 0
        c[_C_TRK_SET] = 0
        c[_C_LEVELED] = 0
        c[_C_REJECTS] = 0
        c[_C_V_REJECTS] = 0
        c[_C_GSF] = 0  # the attitude the bank's offsets were relative to is gone
        c[_C_GSF_DIS] = 0
        c[_C_LAST_TICK] = 0  # the frame may move with the re-alignment
        c[_C_LAG_TICK] = 0
        c[_C_FAULT_UNTIL] = c[_C_TICK] + c[_C_T_SECOND]
        self.resets += 1

    def _update_health(self):
        """ctl[_C_CAUSES] and the health code they make (CAUSE_*)."""
        c = self.ctl
        t = c[_C_TICK]
        k = 0
        if t < c[_C_SAT_UNTIL]:
            k |= CAUSE_IMU_SAT
        if t < c[_C_HELD_UNTIL]:
            k |= CAUSE_IMU_HELD
        if t < c[_C_DEAD_UNTIL]:
            k |= CAUSE_IMU_DEAD
        if t < c[_C_FAULT_UNTIL]:
            k |= CAUSE_NUMERIC
        if t < c[_C_GATED_UNTIL]:
            k |= CAUSE_GNSS_GATED
        if t < c[_C_DATA_UNTIL]:
            k |= CAUSE_GNSS_DATA
        if t < c[_C_RESET_UNTIL]:
            k |= CAUSE_RESET
        if t < c[_C_DRIFT_UNTIL]:
            k |= CAUSE_DRIFT
        if t < c[_C_IMPLAUSIBLE_UNTIL]:
            k |= CAUSE_GNSS_IMPLAUSIBLE
        if c[_C_STATE] == NAVIGATING:
            if t - c[_C_ACCEPT_TICK] > c[_C_T_TIMEOUT]:
                k |= CAUSE_GNSS_LOST
            if c[_C_REJECTS] >= 2 or c[_C_V_REJECTS] >= 2:
                k |= CAUSE_GNSS_REJECTS
            if c[_C_UNCERTAIN]:
                k |= CAUSE_UNCERTAIN
        else:
            k |= CAUSE_NOT_NAVIGATING
        c[_C_CAUSES] = k
        if k & CAUSE_FAULTS:
            c[_C_HEALTH] = 2
        elif k:
            c[_C_HEALTH] = 1
        else:
            c[_C_HEALTH] = 0

    # ---- outputs -------------------------------------------------------------------------

    def euler(self):
        """self.ypr = yaw, pitch, roll (rad) of the current attitude."""
        euler(self.ypr, self.ins.c_bn)
        return self.ypr

    def p_diag(self, out):
        """The covariance diagonal as the extended frame reports it: P's, the position's
        plus the receiver's error the filter cannot see (self.cv, nav_kern.consistency)."""
        p = self.kf.P
        for i in range(eskf.N):
            out[i] = p[i * (eskf.N + 1)]
        cv = self.cv
        out[0] = out[0] + cv[0]
        out[1] = out[1] + cv[0]
        out[2] = out[2] + cv[1]

    def lat_lon(self, out_e7):
        """Integrated position into out_e7: lat (1e-7 deg), lon as (degrees, 1e-7 deg
        fraction); returns the height (m)."""
        return self.frame.to_e7(out_e7, self.ins.p_n)


# The filter's work a second at one slice per tick: propagation takes 31 of every 40 ticks
# (eskf.py), so a second fix a second already waits. Ticks between fixes (200 Hz) below which
# the slices double, and quadruple (the configured slices_per_tick is the least). At one slice
# for every rate (before this rule; its commit has the figures) the 2 Hz vertical velocity on
# urban_drive was 0.109 m/s RMS against 0.021 at 1 Hz; with it, bench-nav's table "Receivers by
# their rate" (`bench-nav --trial urban_drive --rate 2` for one row).
_SLICES_2_BELOW = const(150)  # ticks: faster than 1.33 fixes a second
_SLICES_4_BELOW = const(75)  # faster than 2.67


def _rate_slices(interval, configured):
    """Slices per tick for fixes `interval` ticks apart (no less than configured)."""
    want = 1
    if 0 < interval < _SLICES_4_BELOW:
        want = 4
    elif 0 < interval < _SLICES_2_BELOW:
        want = 2
    return want if want > configured else configured


ins_step = ins_mod.step

# The Python kernels, nav_kern.py: loaded here where navk is not and on CPython; on MicroPython
# with navk by the first call of `imu` (the SI input), whose flow (Navigator._tick) calls them.
# A board with navk never runs them (nav_tick does their work), and their functions and floats
# would take about a kilobyte of its heap (docs/benchmarks/board.md, "Heap and start-up").
nav_kern = None
yaw_gsf = None


def _load_python_kernels():
    global nav_kern, yaw_gsf
    try:
        import nav_kern as mod
        import yaw_gsf as gsf
    except ImportError as e:  # a board image does not freeze them: kern.Missing, main.py says so
        raise kern.missing(e) from None
    nav_kern = mod
    yaw_gsf = gsf


if not kern.NATIVE or kern.HOST:
    _load_python_kernels()
_k = kern.navk if kern.NATIVE else nav_kern
_prop_start = kern.pick("prop_start", None)
_nav_tick = kern.pick("nav_tick", None)  # the reference: Navigator._tick and its callees
fix_in = _k.fix_in
_gnss_fix = kern.pick("gnss_fix", None)  # the reference: Navigator.gnss_fix
_fix_usable = kern.pick("fix_usable", None)  # the reference: Navigator._fix_usable
_gsf_step = kern.pick("gsf_step", None)  # the reference: yaw_gsf.gsf_step
fix_check = _k.fix_check
imu_cal = _k.imu_cal
still = _k.still
ring_put = _k.ring_put
ins_finite = _k.ins_finite
inject = _k.inject
euler = kern.pick("euler", rot.dcm_to_euler)
nav_frame = _k.nav_frame
del _k
