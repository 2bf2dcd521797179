"""The navigator's Python kernels: the float32 work that navk does natively, in Python.

Each function here is the reference of a native kernel of the same name and signature
(firmware/native/: `still` of still(), `inject` of inject()...) or of the part of `nav_tick`
it mirrors (navtick.c: the sample check `imu_check`, the watches `drift_watch` and `aid_watch`,
the receiver's unseen error `consistency` and velocity noise `vel_noise`, the lag search
`lag_search`, `rate_r`, `uncertain`), with the same operation order, so that both give the
same bits (tests/native).
nav.py picks the native kernel where navk is loaded (kern.py) and calls these otherwise; its
own Python flow (Navigator._tick and what it calls) calls the others, which on a board with
navk run inside nav_tick, so a board with navk never loads this module (nav.py says when).
They work on the Navigator's buffers (nav.py lays them out; the indices are repeated below)
and allocate: every float result is a heap object.
"""

from array import array

from micropython import const

import eskf
import f32
import frame
import ins as ins_mod
import rot
from fmath import cos, sin
from nav_aid import NO_HEIGHT_VAR, lever_vel

# ---- nav.py's consts used here: `python -m common.native.layout` writes them ----
_RING = const(128)
_IMU_OVER_RANGE = const(0x3F)
_IMU_FRESH = const(0x1C0)
_IMU_REPEAT = const(0x200)
_FX_H = const(0)
_FX_HDOP = const(1)
_FX_SPEED = const(2)
_FX_COURSE = const(3)
_FX_SIG_H = const(4)
_FX_SIG_V = const(5)
_ST_FX = const(0)
_ST_VAR = const(3)
_ST_GYRO = const(4)
_ST_SPEED = const(5)
_CAL_G = const(0)
_CAL_A = const(1)
_CAL_GB = const(2)
_CAL_AB = const(5)
_CAL_GM = const(8)
_CAL_AM = const(17)
_CAL_HAS_GM = const(1)
_CAL_HAS_AM = const(2)
_STP_ALPHA = const(0)
_STP_ACCEL = const(1)
_STP_GYRO = const(2)
_STP_GNSS_SPEED = const(3)
_STP_MAX_SPEED = const(4)
_STILL_FIRST = const(1)
_STILL_GNSS_SPEED = const(2)
_STILL_NAVIGATING = const(4)
_AID_VEL_SIGMA = const(3)
_AID_LEVER = const(6)
_AID_HDOP_MAX = const(9)
_AID_REANCHOR = const(10)
_AID_FAULT_SIGMA = const(11)
_AID_FAULT_SIGMA_V = const(12)
_AID_HEADING_V = const(13)
_FI_ALT_MM = const(3)
_FI_HDOP_X100 = const(5)
_FI_SPEED_MM_S = const(6)
_FI_COURSE_CDEG = const(7)
_FI_NO_HEIGHT = const(0x3FFFFFFF)
_FC_USABLE = const(1)
_FC_SPEED = const(2)
_FC_REANCHOR = const(4)
_FC_MOVING = const(8)
_FC_COURSE = const(16)
_FC_FAST = const(32)
_C_TICK = const(0)
_C_GATED_UNTIL = const(7)
_C_FIX_TICK = const(19)
_C_T_SECOND = const(32)
_C_OPTS = const(43)
_C_IMU_STATUS = const(46)
_C_N_SAME_G = const(51)
_C_N_SAME_A = const(52)
_C_PREV_G = const(53)
_C_PREV_A = const(56)
_C_T_STUCK = const(59)
_C_DRIFT_UNTIL = const(65)
_C_LAG_TICK = const(66)
_C_LAST_TICK = const(72)
_OPT_LAG = const(8)
_M_X = const(0)
_M_YPR = const(766)
_M_W = const(769)
_M_RING_V = const(1202)
_M_FX = const(1589)
_M_US = const(1595)
_M_AID = const(1602)
_M_BW = const(1640)
_M_CN = const(1645)
_M_LS = const(1662)
_M_BS = const(1710)
_M_AW = const(1715)
_BW_N = const(5)
_AW_LAT = const(0)
_AW_UP = const(1)
_DRIFT_H = const(4)
_CN_K = const(0)
_CN_MH = const(1)
_CN_MV = const(2)
_CN_VH = const(3)
_CN_VV = const(4)
_CN_KL = const(5)
_CN_LAG = const(6)
_CN_LAGT = const(7)
_CN_RK = const(8)
_CN_KR = const(9)
_CN_VE = const(10)
_CN_VN = const(11)
_CN_VOK = const(12)
_CN_V2 = const(13)
_CN_RVEL = const(14)
_NCN = const(15)
_LS_C = const(16)
_LS_STEP = const(4)
_LS_E = const(0)
_LS_N = const(16)
_LS_M = const(32)
_NLS = const(48)
# ---- end of nav.py's consts ----

RAD_PER_CDEG = f32.from_bits(0x393702D3)  # pi / 18000 = 1.7453292e-4: radians per centidegree
CDEG_PER_RAD = f32.from_bits(0x45B30CA0)  # 18000 / pi = 5729.578: centidegrees per radian


def _apply_cal(out, x, b0, m):
    x0 = x[0] - b0[0]
    x1 = x[1] - b0[1]
    x2 = x[2] - b0[2]
    if m is None:
        out[0] = x0
        out[1] = x1
        out[2] = x2
    else:
        out[0] = m[0] * x0 + m[1] * x1 + m[2] * x2
        out[1] = m[3] * x0 + m[4] * x1 + m[5] * x2
        out[2] = m[6] * x0 + m[7] * x1 + m[8] * x2


def imu_cal(w, f, gyro, accel, cal, flags):
    """BMI055 counts to calibrated SI: w, f = M (counts / scale - b0); False if not finite."""
    g = cal[_CAL_G]
    a = cal[_CAL_A]
    wr = f32.zeros(3)  # the Python kernels allocate anyway (every float result)
    fr = f32.zeros(3)
    for i in range(3):
        wr[i] = f32.f32(gyro[i]) / g
        fr[i] = f32.f32(accel[i]) / a
    return cal_si(w, f, wr, fr, cal, flags)


def cal_si(w, f, w_in, f_in, cal, flags):
    """w, f = M (x - b0) from SI rate and specific force; False if not finite."""
    gm = f32.view(cal, _CAL_GM, 9) if flags & _CAL_HAS_GM else None
    _apply_cal(w, w_in, f32.view(cal, _CAL_GB, 3), gm)
    am = f32.view(cal, _CAL_AM, 9) if flags & _CAL_HAS_AM else None
    _apply_cal(f, f_in, f32.view(cal, _CAL_AB, 3), am)
    return finite6(w, f)


def still(st, f, w, x, prm, flags):
    """One 50 Hz step of the standstill detector's low-passes; returns "quiet": small
    specific-force changes and rotation, and a speed that agrees (the GNSS speed when there is
    a recent usable fix, so that an INS velocity error cannot lock the zero-velocity update
    out; else the navigator's own while navigating: a smooth road is as quiet as a stop)."""
    alpha = prm[_STP_ALPHA]
    if flags & _STILL_FIRST:
        for i in range(3):
            st[_ST_FX + i] = f[i]
    var = 0.0
    for i in range(3):
        lp = st[_ST_FX + i]
        d = f[i] - lp
        st[_ST_FX + i] = lp + alpha * d
        var = var + d * d
    st[_ST_VAR] = st[_ST_VAR] + alpha * (var - st[_ST_VAR])
    wx = w[0] - x[ins_mod.X_BG]
    wy = w[1] - x[ins_mod.X_BG + 1]
    wz = w[2] - x[ins_mod.X_BG + 2]
    st[_ST_GYRO] = st[_ST_GYRO] + alpha * ((wx * wx + wy * wy + wz * wz) - st[_ST_GYRO])
    ga = prm[_STP_GYRO]
    aa = prm[_STP_ACCEL]
    quiet = st[_ST_VAR] < aa * aa and st[_ST_GYRO] < ga * ga
    if quiet:
        if flags & _STILL_GNSS_SPEED:
            if st[_ST_SPEED] > prm[_STP_GNSS_SPEED]:
                quiet = False
        elif flags & _STILL_NAVIGATING:
            v0 = x[ins_mod.X_V]
            v1 = x[ins_mod.X_V + 1]
            lim = prm[_STP_MAX_SPEED]
            if v0 * v0 + v1 * v1 > lim * lim:
                quiet = False
    return quiet


def imu_check(c, g, a):
    """True if this tick's counts (g, a; the driver's status word in c[_C_IMU_STATUS]) cannot
    be a sample of a working BMI055: an axis over range, no new accel sample, all six words
    0x0000 or all 0xFFFF (registers cleared, or the bus' idle level: the chip does not
    answer), or one die's counts unchanged for c[_C_T_STUCK] ticks (a real sensor's noise
    moves them every sample). Keeps the last counts and the runs of unchanged ones in c (not
    for an _IMU_REPEAT: the same read again)."""
    st = c[_C_IMU_STATUS]
    if not st & _IMU_REPEAT:
        if g[0] == c[_C_PREV_G] and g[1] == c[_C_PREV_G + 1] and g[2] == c[_C_PREV_G + 2]:
            if c[_C_N_SAME_G] < c[_C_T_STUCK]:
                c[_C_N_SAME_G] += 1
        else:
            c[_C_N_SAME_G] = 0
        if a[0] == c[_C_PREV_A] and a[1] == c[_C_PREV_A + 1] and a[2] == c[_C_PREV_A + 2]:
            if c[_C_N_SAME_A] < c[_C_T_STUCK]:
                c[_C_N_SAME_A] += 1
        else:
            c[_C_N_SAME_A] = 0
        for i in range(3):
            c[_C_PREV_G + i] = g[i]
            c[_C_PREV_A + i] = a[i]
    if st & _IMU_OVER_RANGE or not st & _IMU_FRESH:
        return True
    v = a[0]
    if (v == 0 or v == -1) and a[1] == v and a[2] == v and g[0] == v and g[1] == v and g[2] == v:
        return True
    return c[_C_N_SAME_G] >= c[_C_T_STUCK] or c[_C_N_SAME_A] >= c[_C_T_STUCK]


def finite6(w, f):
    """False if the rate or specific force is not finite."""
    s = w[0] + w[1] + w[2] + f[0] + f[1] + f[2]
    return s - s == 0.0


def uncertain(e, aid, mem):
    """1 if the covariance (Eskf.e's P) puts the position's east or north 1-sigma beyond
    aid[_AID_FAULT_SIGMA], or its vertical one beyond aid[_AID_FAULT_SIGMA_V] (not while the
    receiver gives no height: the newest fix's _FX_SIG_V < 0)."""
    lim = aid[_AID_FAULT_SIGMA]
    lim2 = lim * lim
    p = f32.view(e, eskf.E_P, eskf.N * eskf.N)
    if p[0] > lim2 or p[eskf.N + 1] > lim2:
        return 1
    lim = aid[_AID_FAULT_SIGMA_V]
    if p[2 * (eskf.N + 1)] > lim * lim and mem[_M_FX + _FX_SIG_V] >= 0.0:
        return 1
    return 0


_FROZEN_V2 = f32.f32(1)  # _frozen: a repeated fix while moving faster than 1 m/s (squared)
_FROZEN_K2 = f32.f32(9)  # ... and faster than 3 sigma of its own horizontal velocity (squared)
_BW_ALPHA = f32.ratio(1, 4)  # weight of a second of fixes in the drift watch's running means
_BW_LIMIT = f32.f32(3)  # a running mean beyond 3 (in innovation sigmas): drift
# A suspected drift, health 2 while it lasts: running means of the same ratios, each clipped
# at 3 (one outlier adds at most 3/4, so that one bad fix alone raises nothing), beyond 3/2.
# The no-fault runs' means stay below it (`make bench-faults`: no health 2 in the 1 Hz runs);
# a bias step passes it fixes before the drift limit, while its errors pass 10 m
_BS_CLIP = f32.f32(3)
_BS_LIMIT = f32.ratio(3, 2)
# ... and while a drift is held, the height's suspicion holds it on while its mean is beyond 1.
# Fixes have no vertical velocity: the height is pulled back to each fix and its mean hovers
# about the limit, which let the health fall to 0 for a second at a time while the height
# stayed 11 m off (`make bench-faults`, gyro-bias@250+30:1 seed 2: 25 such frames). Not the
# horizontal means: on the real walks' speed and bearing they hover about 1 on good solutions
# (`make bench-real` with `m == 2` taken out of the hold's condition: T01_R01's health-2
# share 35 -> 55 %)
_BS_LEAVE = f32.f32(1)
_BW_CLIP = f32.f32(5)  # one innovation counts at most this much (both watches): an outlier
# alone is no jump
# The aiding watch (aid_watch): the same running means of y / sqrt(S) for the constraints a
# drifting INS breaks within seconds, long before GNSS shows it: the non-holonomic
# constraint's lateral and vertical rows, and the zero-velocity update's vertical one. A
# vertical accelerometer step of 0.1 m/s^2 passes the limit in 6-7 s (the height then ~1 m
# off), a yaw-rate step of 0.3 deg/s the lateral one in 5-6 s (`make bench-faults`). The limits
# stay above the real drive's means (drive_0708, logged once while choosing them: 0.89
# lateral, 2.51 vertical, road bumps) and the simulated no-fault runs' (below 0.7).
_AW_LIMIT_LAT = f32.f32(2)
_AW_LIMIT_UP = f32.f32(3)


def aid_watch(e, mem, n):
    """After an aiding update of n scalars (E_Z/E_R: innovation y and variance S): the non-
    holonomic constraint (n = 2: body lateral, vertical velocity) or the zero-velocity update
    (n = 3: east, north, up velocity). Running means of y / sqrt(S) in mem's _M_AW, each ratio
    clipped at _BW_CLIP, weight _BW_ALPHA per update, as the drift watch's: lateral from the
    constraint's row 0, vertical from its row 1 and the update's row 2 (body z and up agree
    while nearly level). The update's horizontal rows are left out: at the real drive's stops
    they reach 10 sigma in one update. Returns _AW_HIT_LAT and _AW_HIT_UP for the means beyond
    their limits. A detector (health 2, docs/health.md), and for the vertical channel the
    trigger of its containment (_INFLATE_VERTICAL)."""
    z = f32.view(e, eskf.E_Z, 3)
    r = f32.view(e, eskf.E_R, 3)
    aw = f32.view(mem, _M_AW, 2)
    if n == 2:
        k0 = _AW_LAT  # rows 0, 1: the means _AW_LAT, _AW_UP
    elif n == 3:
        k0 = _AW_UP  # row 2: the mean _AW_UP
    else:
        return 0
    hit = 0
    for k in range(k0, 2):
        j = k if n == 2 else 2
        if r[j] > 0.0:
            q = z[j] / f32.sqrt(r[j])
            if q > _BW_CLIP:
                q = _BW_CLIP
            elif q < -_BW_CLIP:
                q = -_BW_CLIP
            aw[k] = aw[k] + _BW_ALPHA * (q - aw[k])
            lim = _AW_LIMIT_LAT if k == _AW_LAT else _AW_LIMIT_UP
            if aw[k] > lim or aw[k] < -lim:
                hit |= 1 << k
    return hit


def drift_watch(e, mem, n, held):
    """After a GNSS update of n scalars (eskf.E_Z/E_R hold each one's innovation y and its
    variance S): the running means of y / sqrt(S) of the position east, north, up (scalars
    0-2) and of the velocity east and north (3, 4, when the fix had a course) in mem's _M_BW.
    2, and the means restarted, when one is beyond _BW_LIMIT; else 1 when one of the
    suspicion's means (_M_BS: the ratios clipped at _BS_CLIP) is beyond _BS_LIMIT (a drift
    suspected: a bias step's errors pass 10 m before the drift means reach their limit) or,
    the height's while a drift is `held`, beyond _BS_LEAVE (its suspicion ends when the
    height's innovations are back within a sigma, not when they dip under the limit); else 0;
    plus _DRIFT_H when a mean beyond its limit is a horizontal one (not the height's).
    Innovations that keep one sign for several fixes mean the INS drifts away from GNSS faster
    than the filter allows for (a sensor bias or scale that jumped; or fixes that are late).
    The positions count because a fix without a course (a stop, a slow receiver) has no
    velocity rows. Each ratio is clipped at _BW_CLIP, so it takes four one-sided outliers in a
    row (or more, smaller ones) to pass the limit: one bad fix alone does not. A detector
    (docs/health.md), and with _DRIFT_H the trigger of nav._drift_reset: the height is left to
    its own reset (tried without the bit, a suspected vertical drift reset the drive_0708
    replay to its fixes and took its height RMS from 0.93 to 1.54 m)."""
    z = f32.view(e, eskf.E_Z, eskf.MAX_SCALARS)
    r = f32.view(e, eskf.E_R, eskf.MAX_SCALARS)
    bw = f32.view(mem, _M_BW, _BW_N)
    bs = f32.view(mem, _M_BS, _BW_N)
    # a fix weighs 1 / rk of a second's (rate_r): a faster receiver's fixes share their
    # errors, and ten one-sided ones in a second are no more a drift than one (10 Hz: 40
    # health 2 frames in a no-fault run with a weight per fix)
    a = _BW_ALPHA / mem[_M_CN + _CN_RK]
    hit = 0
    hz = 0
    for m in range(_BW_N):
        if m < n and r[m] > 0.0:
            q = z[m] / f32.sqrt(r[m])
            if q > _BW_CLIP:
                q = _BW_CLIP
            elif q < -_BW_CLIP:
                q = -_BW_CLIP
            bw[m] = bw[m] + a * (q - bw[m])
            beyond = bw[m] > _BW_LIMIT or bw[m] < -_BW_LIMIT
            if beyond:
                hit = 2
            if q > _BS_CLIP:
                q = _BS_CLIP
            elif q < -_BS_CLIP:
                q = -_BS_CLIP
            bs[m] = bs[m] + a * (q - bs[m])
            if bs[m] > _BS_LIMIT or bs[m] < -_BS_LIMIT:
                beyond = True
                if hit == 0:
                    hit = 1
            elif held and m == 2 and hit == 0 and (bs[m] > _BS_LEAVE or bs[m] < -_BS_LEAVE):
                hit = 1
            if beyond and m != 2:
                hz = _DRIFT_H
    if hit == 2:
        for m in range(_BW_N):
            bw[m] = 0.0
            bs[m] = 0.0
    return hit | hz


# The receiver's error that a white-noise filter cannot see (docs/navigation.md, "The reported
# covariance"). The filter takes each fix's error as independent of the last one's, with the
# variance R its sigma gives. A receiver's error is partly slow (multipath, atmosphere: tens of
# seconds); consecutive fixes share that part, the filter follows it as if it were position,
# and P never holds it. The innovations show it by its absence: when fixes scatter about the
# INS prediction less than S = HPH' + R says, the missing share of R is error the estimate
# carries along. So the running mean m of y^2/S over the last fixes estimates what R leaves
# unseen: (1 - m) R, per axis, reported on top of P (nothing changes in the filter itself).
# the running means' length: in seconds of fixes for consistency (a fix counts 1 / rate_r),
# in pairs for lag_search (1/k weights up to it: a true mean)
_CN_N = f32.f32(64)
_CN_CLIP = f32.f32(25)  # one y^2/S counts at most this much (_BW_CLIP squared)
_LAG_V2 = f32.f32(4)  # the lag search takes fixes above 2 m/s (speed squared, m^2/s^2)
_LAG_K0 = f32.f32(4)  # the lag is applied from this many pairs of fixes on
_LEV = f32.zeros(2)  # lag_search's antenna velocity from the lever arm (east, north)


def rate_r(c):
    """The factor on the position variances of the queued fix: the fixes a second the filter
    takes (from the measurement ticks of this fix and of the last one it took), 1 to 10. A
    receiver's error is correlated over seconds (multipath, the atmosphere, its own filter): five
    fixes a second carry little more than one, and taken as independent they pull the state
    onto that error (highway_outage, realistic errors, 10 Hz: 4.03 m against 2.40 at 1 Hz
    before this rule; its commit has the figures). R times the rate gives the filter a 1 Hz
    receiver's information a second. Natively in start_queued_fix."""
    d = c[_C_FIX_TICK] - c[_C_LAST_TICK]
    if c[_C_LAST_TICK] == 0 or d <= 0 or d >= c[_C_T_SECOND]:
        return 1.0
    if d < c[_C_T_SECOND] // 10:
        d = c[_C_T_SECOND] // 10
    return f32.f32(c[_C_T_SECOND]) / f32.f32(d)


def consistency(e, mem, n, mask):
    """After a GNSS update of n scalars (E_Z/E_R: each one's innovation y and variance S)
    whose gate mask is `mask`: when its three position rows were accepted, the running means
    of y^2/S east/north and up in mem's _M_CN, and from them and the fix's sigmas (mem's _M_US)
    the unseen variances _CN_VH, _CN_VV: (1 - mean) sigma^2 when the fixes scatter less than
    S says, else (mean - 1) times P's (the position's posterior variance): fixes that miss the
    state by more than S says show an error of the estimate that P does not hold (an INS
    gone overconfident, or a receiver worse than its sigma, which the filter then follows
    with too much gain: either way the estimate's error is about mean times P). The means
    span _CN_N seconds of fixes at any rate: a fix counts 1 / rk (rate_r). With R times rk,
    a faster receiver's sigma^2 here is not what S holds: the estimate is then conservative
    (the fixes' independent share of R counts as unseen)."""
    if n < 3 or mask & 7:
        return
    z = f32.view(e, eskf.E_Z, 5)
    r = f32.view(e, eskf.E_R, 5)
    if not (r[0] > 0.0 and r[1] > 0.0 and r[2] > 0.0):
        return
    cn = f32.view(mem, _M_CN, _NCN)
    k = cn[_CN_K] + 1.0 / cn[_CN_RK]
    if k > _CN_N:
        k = _CN_N
    cn[_CN_K] = k
    a = 1.0 / k
    qe = z[0] * z[0] / r[0]
    if qe > _CN_CLIP:
        qe = _CN_CLIP
    qn = z[1] * z[1] / r[1]
    if qn > _CN_CLIP:
        qn = _CN_CLIP
    qu = z[2] * z[2] / r[2]
    if qu > _CN_CLIP:
        qu = _CN_CLIP
    qh = (qe + qn) * 0.5
    cn[_CN_MH] = cn[_CN_MH] + a * (qh - cn[_CN_MH])
    s = mem[_M_US + 5]  # nav_aid's _US_SIG_H
    p = f32.view(e, eskf.E_P, eskf.N * eskf.N)
    if cn[_CN_MH] < 1.0:
        cn[_CN_VH] = (1.0 - cn[_CN_MH]) * (s * s)
    else:  # fixes that miss the state more than S says: an error P does not hold
        cn[_CN_VH] = (cn[_CN_MH] - 1.0) * ((p[0] + p[eskf.N + 1]) * 0.5)
    s = mem[_M_US + 6]  # _US_SIG_V; < 0: the fix had no height, and the state's is unknown
    cn[_CN_VV] = NO_HEIGHT_VAR
    if s > 0.0:
        cn[_CN_MV] = cn[_CN_MV] + a * (qu - cn[_CN_MV])
        if cn[_CN_MV] < 1.0:
            cn[_CN_VV] = (1.0 - cn[_CN_MV]) * (s * s)
        else:
            cn[_CN_VV] = (cn[_CN_MV] - 1.0) * p[2 * (eskf.N + 1)]


# The receiver's velocity noise (docs/navigation.md, "The receiver's velocity noise"): the
# setting gnss_vel_sigma says what a good receiver's speed and course are worth (0.05-0.1 m/s);
# a phone's are worth 0.3-0.5 m/s, and taken at 0.08 they pull the state onto their noise. A
# receiver's noise is new at every fix; the state's own error (a heading 40 deg off, a bias)
# changes slowly. So the change of the velocity innovation from one fix to the next, squared
# and halved, less the state's variance H P H' (S less the R it was given), estimates the R
# the receiver has, and its running mean is the variance the rows take, never below the
# setting's (a floor, as gnss_sigma_floor_m is the position's) nor above _VR_MAX. Tried first,
# the mean of y^2 less H P H' (about y's own mean) learned the turns of the Tokyo drive at 1 Hz
# as noise (commit 21f23ad's message has the figures) and, on the board across the car
# (tests/lib/test_yaw_gsf.py), the state's wrong heading. Only consecutive fixes whose velocity
# rows the gate accepted count, while H P H' is below _VR_MAX (after a reset it is tens of
# m^2/s^2, and the estimate then says nothing about a tenth of a m/s).
_VR_N = f32.f32(32)  # the mean's length, seconds of fixes (a fix counts 1 / rate_r)
_VR_K0 = f32.f32(4)  # the setting's variance until this many seconds of fixes are in
_VR_MAX = f32.ratio(1, 4)  # m^2/s^2: the largest velocity variance learned (0.5 m/s)


def vel_noise(e, mem, n, mask):
    """After a GNSS update of n scalars whose last two (n = 5) are the velocity east and north
    (E_Z/E_R: each one's innovation y and variance S), both accepted (gate mask `mask`) and
    their S - R below _VR_MAX (else the next fix has no previous one): y kept (mem's _M_CN +
    _CN_VE, _CN_VN; _CN_VOK set) and, when the last update's was kept too, the running mean
    (weight 1 / k, k the seconds of fixes so far up to _VR_N) of the change of y squared
    over 2 less S - R, R the variance the rows had (_CN_RVEL), both axes' mean: the variance
    the rows take next, between gnss_vel_sigma^2 and _VR_MAX, the setting's until k reaches
    _VR_K0."""
    cn = f32.view(mem, _M_CN, _NCN)
    z = f32.view(e, eskf.E_Z, eskf.MAX_SCALARS)
    r = f32.view(e, eskf.E_R, eskf.MAX_SCALARS)
    rv = cn[_CN_RVEL]
    if (
        n < 5
        or mask & 0x18
        or not (r[3] > 0.0 and r[4] > 0.0)
        or r[3] - rv > _VR_MAX
        or r[4] - rv > _VR_MAX
    ):
        cn[_CN_VOK] = 0.0  # no pair with the next fix
        return
    ye = z[3]
    yn = z[4]
    de = ye - cn[_CN_VE]
    dn = yn - cn[_CN_VN]
    ok = cn[_CN_VOK]
    cn[_CN_VE] = ye
    cn[_CN_VN] = yn
    cn[_CN_VOK] = 1.0
    if not ok > 0.0:
        return
    k = cn[_CN_KR] + 1.0 / cn[_CN_RK]
    if k > _VR_N:
        k = _VR_N
    cn[_CN_KR] = k
    if k < 1.0:  # a fast receiver's first pair (rate_r > 1)
        k = 1.0
    a = 1.0 / k
    q = ((de * de + dn * dn) * 0.5 - ((r[3] - rv) + (r[4] - rv))) * 0.5
    cn[_CN_V2] = cn[_CN_V2] + a * (q - cn[_CN_V2])
    lo = mem[_M_AID + _AID_VEL_SIGMA]
    lo = lo * lo
    rv = lo
    if k >= _VR_K0:
        rv = cn[_CN_V2]
        if rv < lo:
            rv = lo
        elif rv > _VR_MAX:
            rv = _VR_MAX
    cn[_CN_RVEL] = rv


def lag_search(c, mem, age):
    """The fixes' lag behind their stamps (docs/navigation.md, "Fixes late against their
    stamps"), before the update of the queued fix measured `age` ticks ago. A fix measured
    lag_s before its stamp reports the velocity of then. Against the state's velocity at
    candidate lags L (ring slots age + L: the track without the corrections, plus the lever
    arm's velocity), its residual differs from the last fix's by (lag_s - L) times the change
    of acceleration between them, plus noise: the L whose residual changes least (its running
    mean of squares _LS_M, _CN_LAG) is the lag. Applied (_CN_LAGT) shrunk by the evidence
    against no lag, L q / (1 + q) with q = k (M(0) - M(L)) / M(L) (the means in units of
    their own noise), nothing below q = 1, so that a flat search (a straight road) applies
    nothing. The filter's corrections, which absorb part of a lag, are not in the ring's
    track; the attitude and biases it estimates are, so a wrong lag applied early can hold
    itself (docs/navigation.md): hence the gate, and pairs about a second apart."""
    x = f32.view(mem, _M_X, ins_mod.NX)
    cn = f32.view(mem, _M_CN, _NCN)
    ls = f32.view(mem, _M_LS, _NLS)
    fx = f32.view(mem, _M_FX, 6)
    t = c[_C_FIX_TICK] - c[_C_LAG_TICK]
    if c[_C_LAG_TICK] != 0 and 0 <= t < c[_C_T_SECOND] - c[_C_T_SECOND] // 4:
        return  # pairs about a second apart at any rate
    c[_C_LAG_TICK] = c[_C_FIX_TICK]
    course = fx[_FX_COURSE]
    sp = fx[_FX_SPEED]
    if (
        not c[_C_OPTS] & _OPT_LAG
        or course < 0.0
        or not sp * sp > _LAG_V2
        or age < 0
        or age + _LS_STEP * (_LS_C - 1) > _RING - 1
        or c[_C_TICK] < c[_C_DRIFT_UNTIL]
        or c[_C_TICK] < c[_C_GATED_UNTIL]
    ):
        c[_C_LAG_TICK] = 0  # no velocity, too slow, too old for the ring, or the INS drifting
        return
    ve = sp * sin(course)
    vn = sp * cos(course)
    lev = _LEV
    lever_vel(lev, x, f32.view(mem, _M_W, 3), f32.view(mem, _M_AID + _AID_LEVER, 3))
    pair = 1 <= t <= 2 * c[_C_T_SECOND]
    k = cn[_CN_KL]
    if pair:
        k = k + 1.0
        if k > _CN_N:
            k = _CN_N
        cn[_CN_KL] = k
    a = 1.0 / k if pair else 0.0
    rv = f32.view(mem, _M_RING_V, 3 * _RING)
    best = 0
    for j in range(_LS_C):
        b = ((c[_C_TICK] - (age + j * _LS_STEP)) % _RING) * 3
        ye = (rv[b] + lev[0]) - ve
        yn = (rv[b + 1] + lev[1]) - vn
        if pair:
            de = ye - ls[_LS_E + j]
            dn = yn - ls[_LS_N + j]
            ls[_LS_M + j] = ls[_LS_M + j] + a * ((de * de + dn * dn) - ls[_LS_M + j])
            if ls[_LS_M + j] < ls[_LS_M + best]:
                best = j
        ls[_LS_E + j] = ye
        ls[_LS_N + j] = yn
    if not pair:
        return
    dt = x[ins_mod.X_DT]
    lag = f32.f32(best * _LS_STEP) * dt
    cn[_CN_LAG] = lag
    cn[_CN_LAGT] = 0.0
    if best == 0 or k < _LAG_K0:
        return
    m = ls[_LS_M + best]
    if not m > 0.0:
        return
    q = k * (ls[_LS_M] - m) / m
    if q < 1.0:
        return  # not a sigma from no lag
    lag = lag * q / (1.0 + q)
    cn[_CN_LAGT] = f32.f32(int(lag / dt + 0.5))


def ring_put(ring_p, ring_v, x, corr, b):
    """The delay ring's entry at offset b: position and velocity minus the corrections."""
    for i in range(3):
        ring_p[b + i] = x[ins_mod.X_P + i] - corr[i]
        ring_v[b + i] = x[ins_mod.X_V + i] - corr[3 + i]


def ins_finite(x):
    """False if the position, velocity or attitude went NaN or infinite."""
    s = x[0] + x[1] + x[2] + x[3] + x[4] + x[5] + x[ins_mod.X_Q]
    return s - s == 0.0


def inject(x, e, corr):
    """Closed-loop correction (docs/requirements.md, error-state filter formulation) of the state
    buffer x from the filter's dx (in e): p -= dp, v -= dv, q = q(phi) (x) q, b += db (corr keeps
    the sum of p, v corrections); then dx = 0."""
    dx = f32.view(e, eskf.E_DX, eskf.N)
    att = f32.zeros(3)
    for i in range(3):
        d = dx[eskf.IX_POS + i]
        x[ins_mod.X_P + i] = x[ins_mod.X_P + i] - d
        corr[i] = corr[i] - d
        d = dx[eskf.IX_VEL + i]
        x[ins_mod.X_V + i] = x[ins_mod.X_V + i] - d
        corr[3 + i] = corr[3 + i] - d
        x[ins_mod.X_BG + i] = x[ins_mod.X_BG + i] + dx[eskf.IX_BG + i]
        x[ins_mod.X_BA + i] = x[ins_mod.X_BA + i] + dx[eskf.IX_BA + i]
        att[i] = dx[eskf.IX_ATT + i]
    dq = f32.zeros(4)
    rot.q_from_rotvec(dq, att)
    q = f32.zeros(4)
    for i in range(4):
        q[i] = x[ins_mod.X_Q + i]
    q_bn = f32.view(x, ins_mod.X_Q, 4)
    rot.q_mul(q_bn, dq, q)
    rot.q_normalize(q_bn)
    rot.q_to_dcm(f32.view(x, ins_mod.X_C, 9), q_bn)
    for i in range(eskf.N):
        dx[i] = 0.0


def fix_in(fx, fi, aid):
    """The receiver's integers fi (FI_*) as the fix's floats fx (_FX_*): unknown HDOP is the
    worst accepted one, unknown speed or course -1.0."""
    fx[_FX_SIG_V] = 0.0
    if fi[_FI_ALT_MM] == _FI_NO_HEIGHT:  # no height: nav_aid holds the vertical velocity instead
        fx[_FX_H] = 0.0
        fx[_FX_SIG_V] = -1.0
    else:
        fx[_FX_H] = f32.ratio(fi[_FI_ALT_MM], 1000)
    if fi[_FI_HDOP_X100] >= 0:
        fx[_FX_HDOP] = f32.ratio(fi[_FI_HDOP_X100], 100)
    else:
        fx[_FX_HDOP] = aid[_AID_HDOP_MAX]
    fx[_FX_SPEED] = -1.0
    fx[_FX_COURSE] = -1.0
    if fi[_FI_SPEED_MM_S] >= 0:
        fx[_FX_SPEED] = f32.ratio(fi[_FI_SPEED_MM_S], 1000)
        if fi[_FI_COURSE_CDEG] >= 0:
            fx[_FX_COURSE] = f32.f32(fi[_FI_COURSE_CDEG]) * RAD_PER_CDEG
    fx[_FX_SIG_H] = 0.0


def fix_check(st, fx, x, aid, p, any_hdop):
    """_FC_* bits of a fix whose quality is acceptable: HDOP acceptable (then its speed, if
    known, into st), whether it has a course and a speed from heading_speed_m_s on (the
    aligning tick reads these bits, not the floats: a float read from a buffer is boxed, and a
    10 Hz receiver's boxes made the aligning heap checks ten times as often), the position
    (x[0:2], ins.X_P = 0) beyond the re-anchoring distance, and the navigator moving while
    the receiver does not say it stands: faster than _FROZEN_V2 allows and than 3 sigma of
    its horizontal velocity (p: Eskf.e, P from eskf.E_P = 0), a speed it can tell from
    standing; a receiver reporting a speed under the same bound holds its position by its own
    account (a phone standing at a waypoint repeats its fix with speed 0), a frozen one
    repeats the speed it had. any_hdop (0 or 1): every HDOP acceptable (a drift held)."""
    if not any_hdop and not fx[_FX_HDOP] <= aid[_AID_HDOP_MAX]:
        return 0
    r = _FC_USABLE
    sp = fx[_FX_SPEED]
    if sp >= 0.0:
        st[_ST_SPEED] = sp
        r |= _FC_SPEED
        if sp >= aid[_AID_HEADING_V]:
            r |= _FC_FAST
    if fx[_FX_COURSE] >= 0.0:
        r |= _FC_COURSE
    lim = aid[_AID_REANCHOR]
    if x[0] > lim or x[0] < -lim or x[1] > lim or x[1] < -lim:
        r |= _FC_REANCHOR
    v2 = x[ins_mod.X_V] * x[ins_mod.X_V] + x[ins_mod.X_V + 1] * x[ins_mod.X_V + 1]
    k = (eskf.N + 1) * eskf.IX_VEL
    if v2 > _FROZEN_V2 and v2 > _FROZEN_K2 * (p[k] + p[k + eskf.N + 1]):
        if not (sp >= 0.0 and sp * sp <= _FROZEN_V2):  # a NaN speed is unknown too
            r |= _FC_MOVING
    return r


def nav_frame(buf, fields, gyro, accel, mem):
    """The output frame (frame.pack_fields) of the navigator's state in mem (Navigator.mem):
    the attitude as yaw, pitch, roll into mem's ypr, the velocity and position; the fix's
    latitude and longitude are in fields (frame.F_LAT_DEG ... F_LON_FRAC)."""
    ypr = f32.view(mem, _M_YPR, 3)
    rot.dcm_to_euler(ypr, f32.view(mem, _M_X + ins_mod.X_C, 9))
    lat = array("i", (fields[frame.F_LAT_DEG], fields[frame.F_LAT_FRAC]))
    lon = array("i", (fields[frame.F_LON_DEG], fields[frame.F_LON_FRAC]))
    frame.pack_fields(buf, fields, gyro, accel, lat, lon, ypr, f32.view(mem, _M_X + ins_mod.X_V, 3),
                      f32.view(mem, _M_X + ins_mod.X_P, 3), CDEG_PER_RAD)  # fmt: skip
