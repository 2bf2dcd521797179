"""Heading from motion alone: a Gaussian-sum bank of yaw hypotheses (docs/navigation.md,
"The yaw estimator").

The board has no magnetometer, and a board in a hand points anywhere, so the receiver's course
is not its heading. Each of GSF_N hypotheses is a small Kalman filter with the state (east,
north position, east, north velocity, yaw offset, east, north specific force error): the
offset is the rotation about the vertical that takes the navigator's attitude to the true
one, so it does not change as the gyros turn the attitude (both turn alike), only when the
navigator corrects or sets its own yaw (`_G_DYAW`, which the navigator adds to: nav._inject,
a start, a reset); the specific force error is what the navigator's tilt and accelerometer
bias leave in the horizontal, which levelling at a standstill cannot see once the board moves
and turns. Between fixes the navigator's specific force, rotated by its attitude into the
frame, is summed once for all hypotheses (`gsf_accum`: once a tick, a dozen float
operations); at a fix each hypothesis turns the sums, less its force error, by its offset,
predicts, and is updated with the fix's position (always) and velocity (when the receiver
reports speed and course; without a speed the bank starts at the second fix, from the chord);
its weight is multiplied by the likelihood of what it predicted
(`gsf_step`). What explains the motion best wins, and the spread of the weighted offsets says
when the heading is known, with the board held at any yaw to the way it moves. In the spirit
of the yaw estimator PX4's EKF2 and ArduPilot run in the air (EKF-GSF: a bank of yaw
hypotheses on the GNSS velocity), here on the ground, with positions too (a receiver without
velocity), one shared attitude and the force error as states.

Approximations, said: the antenna's lever arm is not applied (a few cm on the boards this
serves); a fix's velocity is compared at its arrival, not at its measurement (its latency
later); a navigator correction within an interval turns only the sums after it.

`gsf_accum` and `gsf_step` are the references of the native kernels of the same names
(gsf.c; navtick.c calls gsf_accum every tick the bank runs): the same operation order, bit
for bit (tests/lib/test_yaw_gsf.py), as host_emulator/model/yaw_gsf.py is their NumPy model
(tests/model). They work on the Navigator's buffers (nav.py lays them out; the indices are
repeated below) and allocate (every float result is a heap object): a board with navk runs
the native ones and never imports this module.
"""

from micropython import const

import f32
from fmath import PI, TWO_PI, atan2, cos, sin, sqrt
from fmath import wrap as _wrap

# ---- nav.py's consts used here: `python -m common.native.layout` writes them ----
_NAVIGATING = const(2)
_FX_HDOP = const(1)
_FX_SPEED = const(2)
_FX_COURSE = const(3)
_FX_SIG_H = const(4)
_AID_UERE = const(0)
_AID_FLOOR = const(1)
_C_TICK = const(0)
_C_STATE = const(1)
_C_FIX_TICK = const(19)
_C_GSF = const(75)
_M_X = const(0)
_M_E = const(52)
_M_F = const(772)
_M_GP = const(1586)
_M_FX = const(1589)
_M_AID = const(1602)
_M_CN = const(1645)
_M_GSF = const(1717)
_CN_MH = const(1)
# ---- end of nav.py's consts ----
# ---- ins.py's consts used here: `python -m common.native.layout` writes them ----
_X_C = const(10)
_X_BA = const(22)
_X_DT = const(46)
# ---- end of ins.py's consts ----
# ---- eskf.py's consts used here: `python -m common.native.layout` writes them ----
_N = const(15)
_IX_ATT = const(6)
_E_P = const(0)
# ---- end of eskf.py's consts ----

GSF_N = const(6)  # hypotheses, 60 deg apart at the start
# a hypothesis: its state, its covariance (7 x 7, row-major) and its weight
_H_X = const(0)  # east, north (m), east, north velocity (m/s), yaw offset (rad), and the
# specific force's error east and north in the navigator's frame (m/s^2: its tilt error's
# gravity and the accelerometer's bias, which levelling leaves and turns reveal)
_H_P = const(7)
_H_W = const(56)
_NH = const(57)
_NST = const(7)
# the bank's buffer (Navigator.mem from nav._M_GSF)
_G_A1 = const(0)  # sum of C_bn (f - b_a) dt since the last step, east, north (m/s)
_G_A2 = const(2)  # sum of _G_A1 dt, each tick after its addition (m)
_G_T = const(4)  # time since the last step, s
_G_DYAW = const(5)  # the navigator's yaw changes since the last step not made by its gyros
_G_YAW = const(6)  # the weighted yaw offset, rad: the navigator's yaw plus it is the heading
_G_VAR = const(7)  # its variance, rad^2: the hypotheses' own and their spread
_G_V = const(8)  # the weighted velocity, east, north (m/s)
_G_QA = const(10)  # horizontal acceleration noise the sums miss, (m/s^2)^2 / Hz
_G_QW = const(11)  # yaw offset random walk (the gyros' bias), rad^2 / s
_G_READY = const(12)  # the variance under which the heading is known, rad^2
_G_RMIN = const(13)  # the least offset^2 that disagrees with the navigator, rad^2
_G_QB = const(14)  # the specific force error's random walk, (m/s^2)^2 / s
_G_RV = const(15)  # a velocity's variance, (m/s)^2 (the receiver's, or more: see navcfg)
_G_PH = const(16)  # scratch: P h (7)
_G_FP = const(23)  # scratch: F P (49)
_G_D = const(72)  # each hypothesis's sum of y^2 / S at this step (GSF_N)
_G_S = const(78)  # ... and its product of S (GSF_N)
_G_B = const(84)  # the weighted specific force error, east, north (m/s^2)
_G_HYP = const(86)  # the hypotheses (GSF_N x _NH)
NG = const(428)

# the bank's state in the navigator's _C_GSF (0: off)
GSF_ON = const(1)  # running: the sums are kept, every fix steps it
GSF_HELD = const(2)  # a fix without velocity held for the chord; the sums are kept

# step's result bits
GSF_READY = const(1)  # the offset's variance is under _G_READY (at a fix without velocity,
# only while aligning and under a quarter of it)
GSF_DISAGREES = const(2)  # navigating, ready, and the offset is beyond 3 sigma of the
# navigator's and the bank's yaw variances together, and beyond sqrt(_G_RMIN)
GSF_NAV_BAD = const(4)  # ... and the navigator's positions miss their fixes: the running mean
# of their y^2 / S (nav_kern.consistency) over INNOV_BAD

V0_VAR = f32.f32(4)  # (m/s)^2 at the start, beyond the fix's speed squared
V0_CHORD_VAR = f32.ratio(1, 4)  # (m/s)^2 beyond the chord's: the force error and the fix's
# latency the chord leaves in the end's velocity
B0_VAR = f32.ratio(1, 25)  # (m/s^2)^2: the specific force error at the start (1.2 deg of tilt)
W_MIN = f32.ratio(1, 10000)  # a weight never below: a hypothesis out of favour can come back
EXP_CUT = f32.f32(32)  # exp_neg(y) for y beyond this is 0 (e^-32 = 1.3e-14)
SIXTH = f32.ratio(1, 6)
TWENTYFOURTH = f32.ratio(1, 24)
SIXTYFOURTH = f32.ratio(1, 64)
THIRD = f32.ratio(1, 3)
NINE = f32.f32(9)
FOUR = f32.f32(4)
INNOV_BAD = f32.f32(2)

_P_YAW = const(_M_E + _E_P + (_IX_ATT + 2) * (_N + 1))  # P's yaw variance in mem


def exp_neg(y):
    """e^-y for y >= 0 in float32 arithmetic: e^-(y/64) as the reciprocal of e^(y/64)'s
    Taylor series to 4th order, squared six times (relative error 6e-6 at most for y <= 4,
    4e-4 for y <= 16, 1.1 % below 32, where the weights it makes are 1e-14: the test has
    them); 0 from EXP_CUT on."""
    if not y < EXP_CUT:
        return f32.f32(0)
    t = y * SIXTYFOURTH
    p = 1.0 + t * (1.0 + t * (0.5 + t * (SIXTH + t * TWENTYFOURTH)))
    r = 1.0 / p
    for _ in range(6):
        r = r * r
    return r


def gsf_accum(m):
    """A tick's share (every tick once the bank runs): the specific force less the
    navigator's accelerometer bias, rotated by its attitude, times the tick, summed east and
    north into _G_A1, and _G_A1 times the tick into _G_A2."""
    g = _M_GSF
    x = _M_X
    dt = m[x + _X_DT]
    fx = m[_M_F] - m[x + _X_BA]
    fy = m[_M_F + 1] - m[x + _X_BA + 1]
    fz = m[_M_F + 2] - m[x + _X_BA + 2]
    c = x + _X_C
    de = (m[c] * fx + m[c + 1] * fy + m[c + 2] * fz) * dt
    dn = (m[c + 3] * fx + m[c + 4] * fy + m[c + 5] * fz) * dt
    m[g + _G_A1] = m[g + _G_A1] + de
    m[g + _G_A1 + 1] = m[g + _G_A1 + 1] + dn
    m[g + _G_A2] = m[g + _G_A2] + m[g + _G_A1] * dt
    m[g + _G_A2 + 1] = m[g + _G_A2 + 1] + m[g + _G_A1 + 1] * dt
    m[g + _G_T] = m[g + _G_T] + dt


def _sigma_h(m):
    """nav_aid._sigma_h on mem: the fix's horizontal 1-sigma, m."""
    s = m[_M_FX + _FX_SIG_H]
    if not s > 0.0:
        s = m[_M_FX + _FX_HDOP] * m[_M_AID + _AID_UERE]
    if s < m[_M_AID + _AID_FLOOR]:
        s = m[_M_AID + _AID_FLOOR]
    return s


def _init(m, sh):
    """The bank at its first fix with a speed: every hypothesis at the fix with no velocity
    (its variance V0_VAR plus the fix's speed squared) and no specific force error (B0_VAR),
    its offset one of GSF_N around the circle (the variance of half their spacing), equal
    weights."""
    sp = m[_M_FX + _FX_SPEED]
    vv = V0_VAR
    if sp > 0.0:
        vv = vv + sp * sp
    _spread(m, sh * sh, vv)


def _init_chord(m, sh):
    """The bank at the second fix of a receiver without velocity: the chord from the held
    fix (hypothesis 0's position) over the interval is the mean velocity, and each hypothesis
    turns the sums' part that the end's velocity adds (_G_A1 - _G_A2 / t, the same for every
    yaw but for its rotation) by its offset. Started at rest instead, a car already at 10 m/s
    is 5 sigma from every hypothesis, and the bank grew sure of a wrong heading (50 deg off
    at 13 deg of sigma after the sharp turn of tests/lib/test_nav.py). The velocity's
    variance is the chord's (two fixes' noise over t^2), what the offset's spread turns the
    added part by, and what the force error (B0_VAR) makes of it over the interval (half of
    (b t)^2, for the long interval after an outage); position and velocity share the fix's
    noise (sh^2 / t)."""
    g = _M_GSF
    t = m[g + _G_T]
    h0 = g + _G_HYP
    ve = (m[_M_GP] - m[h0]) / t
    vn = (m[_M_GP + 1] - m[h0 + 1]) / t
    de = m[g + _G_A1] - m[g + _G_A2] / t
    dn = m[g + _G_A1 + 1] - m[g + _G_A2 + 1] / t
    r = sh * sh
    _spread(m, r, 0.0)
    yv = m[h0 + _H_P + 32]
    vv = (r + r) / (t * t) + (de * de + dn * dn) * yv + B0_VAR * (t * t) * 0.5 + V0_CHORD_VAR
    pv = r / t
    for k in range(GSF_N):
        h = g + _G_HYP + k * _NH
        s = sin(m[h + 4])
        c = cos(m[h + 4])
        m[h + 2] = ve + (c * de - s * dn)
        m[h + 3] = vn + (s * de + c * dn)
        p = h + _H_P
        m[p + 2] = pv
        m[p + 14] = pv
        m[p + 10] = pv
        m[p + 22] = pv
        m[p + 16] = vv
        m[p + 24] = vv


def _spread(m, pp, vv):
    """Every hypothesis at the fix (position variance pp, velocity 0 of variance vv), no
    specific force error (B0_VAR), its offset one of GSF_N around the circle (the variance of
    half their spacing), equal weights."""
    g = _M_GSF
    dy = TWO_PI / f32.f32(GSF_N)
    yv = dy * 0.5
    yv = yv * yv
    w = 1.0 / f32.f32(GSF_N)
    for k in range(GSF_N):
        h = g + _G_HYP + k * _NH
        for i in range(_NH):
            m[h + i] = 0.0
        m[h] = m[_M_GP]
        m[h + 1] = m[_M_GP + 1]
        m[h + 4] = (f32.f32(k) + 0.5) * dy - PI
        p = h + _H_P
        m[p] = pp
        m[p + 8] = pp
        m[p + 16] = vv
        m[p + 24] = vv
        m[p + 32] = yv
        m[p + 40] = B0_VAR
        m[p + 48] = B0_VAR
        m[h + _H_W] = w


def _predict(m, h, t, dyaw):
    """Hypothesis h over the interval t (s): its offset less dyaw; the sums less its specific
    force error, turned by its offset, move it."""
    g = _M_GSF
    y = _wrap(m[h + 4] - dyaw)
    m[h + 4] = y
    s = sin(y)
    c = cos(y)
    h2 = t * t * 0.5
    u1e = m[g + _G_A1] - m[h + 5] * t
    u1n = m[g + _G_A1 + 1] - m[h + 6] * t
    u2e = m[g + _G_A2] - m[h + 5] * h2
    u2n = m[g + _G_A2 + 1] - m[h + 6] * h2
    r1e = c * u1e - s * u1n
    r1n = s * u1e + c * u1n
    r2e = c * u2e - s * u2n
    r2n = s * u2e + c * u2n
    m[h] = m[h] + m[h + 2] * t + r2e
    m[h + 1] = m[h + 1] + m[h + 3] * t + r2n
    m[h + 2] = m[h + 2] + r1e
    m[h + 3] = m[h + 3] + r1n
    # F = I but dp/dv = t, dp/dyaw = (-r2n, r2e), dv/dyaw = (-r1n, r1e), dp/db = -R h2,
    # dv/db = -R t (R the offset's rotation): P = F P F^T + Q, F P into the scratch first,
    # then (F P) F^T back
    ch = c * h2
    sh = s * h2
    ct = c * t
    st = s * t
    fp = g + _G_FP
    p = h + _H_P
    for j in range(_NST):
        b5 = m[p + 35 + j]
        b6 = m[p + 42 + j]
        m[fp + j] = m[p + j] + t * m[p + 14 + j] - r2n * m[p + 28 + j] - ch * b5 + sh * b6
        m[fp + 7 + j] = m[p + 7 + j] + t * m[p + 21 + j] + r2e * m[p + 28 + j] - sh * b5 - ch * b6
        m[fp + 14 + j] = m[p + 14 + j] - r1n * m[p + 28 + j] - ct * b5 + st * b6
        m[fp + 21 + j] = m[p + 21 + j] + r1e * m[p + 28 + j] - st * b5 - ct * b6
        m[fp + 28 + j] = m[p + 28 + j]
        m[fp + 35 + j] = b5
        m[fp + 42 + j] = b6
    for i in range(_NST):
        r = fp + 7 * i
        o = p + 7 * i
        b5 = m[r + 5]
        b6 = m[r + 6]
        m[o] = m[r] + t * m[r + 2] - r2n * m[r + 4] - ch * b5 + sh * b6
        m[o + 1] = m[r + 1] + t * m[r + 3] + r2e * m[r + 4] - sh * b5 - ch * b6
        m[o + 2] = m[r + 2] - r1n * m[r + 4] - ct * b5 + st * b6
        m[o + 3] = m[r + 3] + r1e * m[r + 4] - st * b5 - ct * b6
        m[o + 4] = m[r + 4]
        m[o + 5] = b5
        m[o + 6] = b6
    qa = m[g + _G_QA]
    t2 = t * t
    qp = qa * (t2 * t) * THIRD
    qx = qa * t2 * 0.5
    qv = qa * t
    for i in range(2):
        d = p + 8 * i
        m[d] = m[d] + qp
        m[d + 2] = m[d + 2] + qx
        m[d + 14] = m[d + 14] + qx
        m[d + 16] = m[d + 16] + qv
    m[p + 32] = m[p + 32] + m[g + _G_QW] * t
    qb = m[g + _G_QB] * t
    m[p + 40] = m[p + 40] + qb
    m[p + 48] = m[p + 48] + qb


def _update(m, h, i, a, z, r):
    """Hypothesis h with the scalar z = x[i] + a x[i + 2] + noise of variance r (a position,
    i 0 or 1: a is minus the fix's age, the velocity carries the state back to the fix's
    moment; a velocity, i 2 or 3: a = 0): returns y^2 / S and leaves S in the scratch
    _G_FP."""
    g = _M_GSF
    p = h + _H_P
    ph = g + _G_PH
    i2 = i + 2 if i < 2 else i
    for j in range(_NST):
        m[ph + j] = m[p + 7 * j + i] + a * m[p + 7 * j + i2]
    s = m[ph + i] + a * m[ph + i2] + r
    y = z - (m[h + i] + a * m[h + i2])
    for j in range(_NST):
        k = m[ph + j] / s
        m[h + j] = m[h + j] + k * y
        for q in range(j, _NST):
            v = m[p + 7 * j + q] - k * m[ph + q]
            m[p + 7 * j + q] = v
            m[p + 7 * q + j] = v
    m[g + _G_FP] = s
    return y * y / s


def gsf_step(c, m):
    """A usable fix (the navigator's _gp and _fx) once levelled: the bank's first (a fix with
    a speed), its second (a receiver without velocity: the chord from the first, held in
    _C_GSF's state GSF_HELD), or the predict and update of every hypothesis and their new
    weights; the weighted offset, its variance and the weighted velocity (_G_YAW, _G_VAR,
    _G_V); GSF_* bits. The sums and _G_DYAW start again."""
    g = _M_GSF
    sh = _sigma_h(m)
    st = c[_C_GSF]
    if st == GSF_HELD and m[g + _G_T] > 0.0:
        _init_chord(m, sh)
        c[_C_GSF] = GSF_ON
    elif st == GSF_ON:
        _bank(c, m, sh * sh)
    elif m[_M_FX + _FX_SPEED] >= 0.0:
        _init(m, sh)
        c[_C_GSF] = GSF_ON
    else:
        m[g + _G_HYP] = m[_M_GP]
        m[g + _G_HYP + 1] = m[_M_GP + 1]
        c[_C_GSF] = GSF_HELD
    for i in range(6):
        m[g + i] = 0.0
    if c[_C_GSF] != GSF_ON:
        return 0
    return _result(c, m)


def _bank(c, m, rp):
    """Predict and update every hypothesis (the position's variance rp), and weigh them by
    the likelihood of their innovations, relative to the likeliest's."""
    g = _M_GSF
    t = m[g + _G_T]
    dyaw = _wrap(m[g + _G_DYAW])
    age = f32.f32(c[_C_TICK] - c[_C_FIX_TICK]) * m[_M_X + _X_DT]
    if age < 0.0:
        age = f32.f32(0)
    sp = m[_M_FX + _FX_SPEED]
    co = m[_M_FX + _FX_COURSE]
    rv = m[g + _G_RV]
    for k in range(GSF_N):
        h = g + _G_HYP + k * _NH
        _predict(m, h, t, dyaw)
        d = _update(m, h, 0, -age, m[_M_GP], rp)
        sp2 = m[g + _G_FP]
        d = d + _update(m, h, 1, -age, m[_M_GP + 1], rp)
        sp2 = sp2 * m[g + _G_FP]
        if sp >= 0.0 and co >= 0.0:
            d = d + _update(m, h, 2, f32.f32(0), sp * sin(co), rv)
            sp2 = sp2 * m[g + _G_FP]
            d = d + _update(m, h, 3, f32.f32(0), sp * cos(co), rv)
            sp2 = sp2 * m[g + _G_FP]
        m[h + 4] = _wrap(m[h + 4])
        m[g + _G_D + k] = d
        m[g + _G_S + k] = sp2
    dmin = m[g + _G_D]
    for k in range(1, GSF_N):
        if m[g + _G_D + k] < dmin:
            dmin = m[g + _G_D + k]
    total = f32.f32(0)
    for k in range(GSF_N):
        h = g + _G_HYP + k * _NH
        w = m[h + _H_W] * exp_neg((m[g + _G_D + k] - dmin) * 0.5) / sqrt(m[g + _G_S + k])
        m[h + _H_W] = w
        total = total + w
    for k in range(GSF_N):
        h = g + _G_HYP + k * _NH
        w = m[h + _H_W] / total if total > 0.0 else 1.0 / f32.f32(GSF_N)
        if w < W_MIN:
            w = W_MIN
        m[h + _H_W] = w


def _result(c, m):
    """The weighted offset (the circular mean), its variance (each hypothesis's own plus its
    squared distance from the mean, weighted), the weighted velocity and specific force
    error; GSF_* bits."""
    g = _M_GSF
    se = f32.f32(0)
    ce = f32.f32(0)
    ve = f32.f32(0)
    vn = f32.f32(0)
    be = f32.f32(0)
    bn = f32.f32(0)
    for k in range(GSF_N):
        h = g + _G_HYP + k * _NH
        w = m[h + _H_W]
        se = se + w * sin(m[h + 4])
        ce = ce + w * cos(m[h + 4])
        ve = ve + w * m[h + 2]
        vn = vn + w * m[h + 3]
        be = be + w * m[h + 5]
        bn = bn + w * m[h + 6]
    y = atan2(se, ce)
    var = f32.f32(0)
    for k in range(GSF_N):
        h = g + _G_HYP + k * _NH
        d = _wrap(m[h + 4] - y)
        var = var + m[h + _H_W] * (d * d + m[h + _H_P + 32])
    m[g + _G_YAW] = y
    m[g + _G_VAR] = var
    m[g + _G_V] = ve
    m[g + _G_V + 1] = vn
    m[g + _G_B] = be
    m[g + _G_B + 1] = bn
    if not var < m[g + _G_READY]:
        return 0
    if not (m[_M_FX + _FX_SPEED] >= 0.0 and m[_M_FX + _FX_COURSE] >= 0.0):
        # positions alone: a start only, under a quarter of the variance (docs/navigation.md)
        if c[_C_STATE] == _NAVIGATING or not var * FOUR < m[g + _G_READY]:
            return 0
    r = GSF_READY
    if c[_C_STATE] == _NAVIGATING:
        y2 = y * y
        if y2 > NINE * (var + m[_P_YAW]) and y2 > m[g + _G_RMIN]:
            r = r | GSF_DISAGREES
            if m[_M_CN + _CN_MH] > INNOV_BAD:
                r = r | GSF_NAV_BAD
    return r
