/* Starting the filter's jobs: propagation (nav._schedule with ins.take_dvn, ins.slow_update
 * and eskf.start_propagation) and the measurement rows of nav_aid.py (_start_gnss_update,
 * _start_zupt, _start_nhc with eskf.add_scalar and start_update). Those are the reference. */
#include <stdint.h>

#include "fmath32.h"
#include "layout.h"
#include "lever32.h"
#include "navk.h"
#include "rot32.h"
#include "tuning.h"


/* eskf.add_scalar: queue z = h dx + noise (variance r), h with nnz <= 3 non-zeros. */
static int32_t add_scalar(float *e, int32_t *ii, float z, float r, int32_t nnz, int32_t i0,
    float h0, int32_t i1, float h1, int32_t i2, float h2) {
    int32_t m = ii[I_NSCAL];
    ii[I_NSCAL] = m + 1;
    float *h = e + E_H + m * N;
    for (int k = 0; k < N; k++) {
        h[k] = 0.0f;
    }
    e[E_Z + m] = z;
    e[E_R + m] = r;
    int32_t *nz = ii + I_NZ + m * MAX_NZ;
    nz[0] = i0;
    h[i0] = h0;
    if (nnz > 1) {
        nz[1] = i1;
        h[i1] = h1;
    }
    if (nnz > 2) {
        nz[2] = i2;
        h[i2] = h2;
    }
    ii[I_NNZ + m] = nnz;
    return m;
}

/* eskf.add_scalar_terms: three more non-zeros for scalar m. */
static void add_scalar_terms(float *e, int32_t *ii, int32_t m, int32_t i0, float h0, int32_t i1,
    float h1, int32_t i2, float h2) {
    float *h = e + E_H + m * N;
    int32_t *nz = ii + I_NZ + m * MAX_NZ + ii[I_NNZ + m];
    nz[0] = i0;
    nz[1] = i1;
    nz[2] = i2;
    h[i0] = h0;
    h[i1] = h1;
    h[i2] = h2;
    ii[I_NNZ + m] = ii[I_NNZ + m] + 3;
}

static void start_update(int32_t *ii) {
    ii[I_JOB] = UPDATING;
    ii[I_STEP] = 0;
    ii[I_M] = 0;
    ii[I_ACCEPTED] = 0;
    ii[I_REJECTED] = 0;
    ii[I_GATE_MASK] = 0;
}

/* ins.slow_update(t): Earth rate on the attitude over t, then a_n = g_n - 2 w x v. */
static void slow_update(float *x, float t, int32_t earth) {
    const float *p = x + X_P;
    const float *v = x + X_V;
    float g = x[X_G0] - FREE_AIR * (x[X_H0] + p[2]);
    float *a = x + X_AN;
    if (!earth) {
        a[0] = 0.0f;
        a[1] = 0.0f;
        a[2] = -g;
        return;
    }
    const float *w = x + X_WIE;
    if (t > 0.0f) {
        float r[4], q[4];
        r[0] = 1.0f;
        r[1] = 0.0f;
        r[2] = -(w[1] * t) * 0.5f;
        r[3] = -(w[2] * t) * 0.5f;
        for (int i = 0; i < 4; i++) {
            q[i] = x[X_Q + i];
        }
        rot_q_mul(x + X_Q, r, q);
        rot_q_normalize(x + X_Q);
        rot_q_to_dcm(x + X_C, x + X_Q);
    }
    float wy2 = w[1] + w[1];
    float wz2 = w[2] + w[2];
    a[0] = -(g * p[0] * x[X_INV_RN]) - (wy2 * v[2] - wz2 * v[1]);
    a[1] = -(g * p[1] * x[X_INV_RM]) - wz2 * v[0];
    a[2] = wy2 * v[0] - g;
}

void navk_prop_start(float *x, float *e, int32_t *ii, int32_t ticks) {
    float t = (float)ticks * x[X_DT];
    float dvn[3];
    for (int i = 0; i < 3; i++) { /* ins.take_dvn */
        dvn[i] = x[X_DVS + i];
        x[X_DVS + i] = 0.0f;
    }
    slow_update(x, t, ii[I_EARTH]);
    float *s = e + E_S; /* eskf.start_propagation */
    s[S_T] = t;
    s[S_DECAY_G] = 1.0f - t * s[S_INV_TAU_G];
    s[S_DECAY_A] = 1.0f - t * s[S_INV_TAU_A];
    for (int i = 0; i < 3; i++) {
        e[E_FN + i] = dvn[i] / t;
        e[E_W + i] = x[X_WIE + i];
    }
    for (int i = 0; i < 9; i++) {
        e[E_C + i] = x[X_C + i];
    }
    ii[I_JOB] = PROPAGATING;
    ii[I_STEP] = 0;
}

void navk_zupt_rows(float *e, int32_t *ii, const float *x, const float *aid) {
    float r = aid[AID_ZUPT_SIGMA] * aid[AID_ZUPT_SIGMA];
    for (int i = 0; i < 3; i++) {
        add_scalar(e, ii, x[X_V + i], r, 1, IX_VEL + i, 1.0f, 0, 0.0f, 0, 0.0f);
    }
    start_update(ii);
}

void navk_nhc_rows(float *e, int32_t *ii, const float *x, const float *aid) {
    const float *c = x + X_C;
    float v0 = x[X_V], v1 = x[X_V + 1], v2 = x[X_V + 2];
    float r = aid[AID_NHC_SIGMA] * aid[AID_NHC_SIGMA];
    for (int k = 0; k < 3; k += 2) {
        float c0 = c[k], c1 = c[3 + k], c2 = c[6 + k];
        float z = c0 * v0 + c1 * v1 + c2 * v2;
        int32_t m = add_scalar(e, ii, z, r, 3, IX_VEL, c0, IX_VEL + 1, c1, IX_VEL + 2, c2);
        add_scalar_terms(e, ii, m, IX_ATT, v1 * c2 - v2 * c1, IX_ATT + 1, v2 * c0 - v0 * c2,
            IX_ATT + 2, v0 * c1 - v1 * c0);
    }
    start_update(ii);
}

/* nav_aid._sigma_h and _sigma_v */
static float sigma_h(const float *fx, const float *aid) {
    float s = fx[FX_SIG_H];
    if (!(s > 0.0f)) {
        s = fx[FX_HDOP] * aid[AID_UERE];
    }
    if (s < aid[AID_FLOOR]) {
        s = aid[AID_FLOOR];
    }
    return s;
}

static float sigma_v(const float *fx, const float *aid, float sh) {
    float s = fx[FX_SIG_V];
    if (!(s > 0.0f)) {
        s = sh * aid[AID_VERT];
    }
    if (s < aid[AID_FLOOR]) {
        s = aid[AID_FLOOR];
    }
    return s;
}

void navk_gnss_rows(float *e, int32_t *ii, const float *x, const float *ring_p,
    const float *ring_v, const float *corr, float *gp, const float *fx, float *used,
    const float *w, const float *aid, int32_t b, float rk, float rvel) {
    const float *c = x + X_C;
    const float *lv = aid + AID_LEVER;
    float lx = c[0] * lv[0] + c[1] * lv[1] + c[2] * lv[2]; /* nav_aid._lever_n */
    float ly = c[3] * lv[0] + c[4] * lv[1] + c[5] * lv[2];
    float lz = c[6] * lv[0] + c[7] * lv[1] + c[8] * lv[2];
    float sh = sigma_h(fx, aid);
    float sv = sigma_v(fx, aid, sh);
    float rh = sh * sh * rk;
    float rv = sv * sv * rk;
    used[US_SIG_V] = sv;
    if (fx[FX_SIG_V] < 0.0f) { /* no height: the state's own, and v_U held at 0 instead */
        gp[2] = ring_p[b + 2] + corr[2] + lz;
        used[US_SIG_V] = -sv;
    }
    for (int i = 0; i < 3; i++) {
        used[US_P + i] = gp[i];
    }
    used[US_SPEED] = fx[FX_SPEED];
    used[US_COURSE] = fx[FX_COURSE];
    used[US_SIG_H] = sh;
    float z = (ring_p[b] + corr[0] + lx) - gp[0];
    add_scalar(e, ii, z, rh, 3, 0, 1.0f, IX_ATT + 1, -lz, IX_ATT + 2, ly);
    z = (ring_p[b + 1] + corr[1] + ly) - gp[1];
    add_scalar(e, ii, z, rh, 3, 1, 1.0f, IX_ATT, lz, IX_ATT + 2, -lx);
    if (used[US_SIG_V] > 0.0f) {
        z = (ring_p[b + 2] + corr[2] + lz) - gp[2];
        add_scalar(e, ii, z, rv, 3, 2, 1.0f, IX_ATT, -ly, IX_ATT + 1, lx);
    } else {
        add_scalar(e, ii, ring_v[b + 2] + corr[5], 1.0f, 1, IX_VEL + 2, 1.0f, 0, 0.0f, 0, 0.0f);
    }
    float course = fx[FX_COURSE];
    float sp = fx[FX_SPEED];
    if (course >= 0.0f) {
        float ve = sp * f32_sin(course);
        float vn = sp * f32_cos(course);
        float lev[2];
        lever_vel_en(lev, x, w, lv);
        z = (ring_v[b] + corr[3] + lev[0]) - ve;
        add_scalar(e, ii, z, rvel, 1, IX_VEL, 1.0f, 0, 0.0f, 0, 0.0f);
        z = (ring_v[b + 1] + corr[4] + lev[1]) - vn;
        add_scalar(e, ii, z, rvel, 1, IX_VEL + 1, 1.0f, 0, 0.0f, 0, 0.0f);
    }
    start_update(ii);
}

/* Navigator._restart: position and velocity v from the fix gp (antenna) taken `age` ticks
 * ago, the covariance from the initial diagonal m[M_INIT..] with the fix's sigmas sh, sv and
 * the horizontal velocity's sigma_vel; the step in position east, north into m[M_RESET_D].
 * keep_height: the height, and the variances of the height, the vertical velocity and the
 * vertical accelerometer bias, stay (their covariances with the rest restart at 0). */
static void restart(int32_t *c, int32_t *ii, float *m, const float *gp, const float *v,
                    int32_t age, float sh, float sv, float sigma_vel, int32_t keep_height) {
    float *x = m + M_X;
    float *pk = m + M_E + E_P;
    const float *cb = x + X_C;
    const float *lv = m + M_AID + AID_LEVER;
    float p[3];
    p[0] = cb[0] * lv[0] + cb[1] * lv[1] + cb[2] * lv[2]; /* nav_aid._lever_n */
    p[1] = cb[3] * lv[0] + cb[4] * lv[1] + cb[5] * lv[2];
    p[2] = cb[6] * lv[0] + cb[7] * lv[1] + cb[8] * lv[2];
    if (age < 0) {
        age = 0;
    }
    float t = (float)age * x[X_DT];
    for (int i = 0; i < 3; i++) {
        p[i] = (gp[i] - p[i]) + v[i] * t;
    }
    const int32_t kh = N + 1;
    float k_h = 0.0f;
    float k_v = 0.0f;
    float k_b = 0.0f;
    if (keep_height) {
        p[2] = x[X_P + 2];
        k_h = pk[2 * kh];
        k_v = pk[(IX_VEL + 2) * kh];
        k_b = pk[(IX_BA + 2) * kh];
    }
    m[M_RESET_D] = p[0] - x[X_P];
    m[M_RESET_D + 1] = p[1] - x[X_P + 1];
    for (int i = 0; i < 3; i++) { /* ins.reset_kinematics */
        x[X_P + i] = p[i];
        x[X_V + i] = v[i];
        x[X_PK + i] = 0.0f;
        x[X_THP + i] = 0.0f;
        x[X_DVP + i] = 0.0f;
    }
    float *ini = m + M_INIT;
    ini[0] = sh * sh;
    ini[1] = sh * sh;
    ini[2] = sv * sv;
    float vv = sigma_vel * sigma_vel;
    ini[IX_VEL] = vv;
    ini[IX_VEL + 1] = vv;
    float *dx = m + M_E + E_DX;
    for (int i = 0; i < N * N; i++) { /* eskf.reset_p */
        pk[i] = 0.0f;
    }
    for (int i = 0; i < N; i++) {
        pk[i * kh] = ini[i];
        dx[i] = 0.0f;
    }
    ii[I_JOB] = IDLE;
    ii[I_READY] = 0;
    ii[I_NSCAL] = 0;
    if (keep_height) {
        pk[2 * kh] = k_h;
        pk[(IX_VEL + 2) * kh] = k_v;
        pk[(IX_BA + 2) * kh] = k_b;
    }
    for (int i = 0; i < 6; i++) {
        m[M_CORR + i] = 0.0f;
    }
    c[C_LAG_TICK] = 0; /* the velocity track jumps: no pair for the lag search */
}

/* nav_align._start_navigation and Navigator._restart: navigation starts at the fix in m
 * (M_GP, M_FX): heading from the course m[M_NS] (rad clockwise from north), horizontal
 * velocity m[M_NS + 1] along it with the 1-sigma m[M_NS + 2], position carried over the
 * fix's age, the covariance reset to the initial diagonal m[M_INIT..] with the fix's sigmas. */
void navk_nav_start(int32_t *c, int32_t *ii, float *m) {
    float *x = m + M_X;
    float *ypr = m + M_YPR;
    float *cb = x + X_C;
    const float *aid = m + M_AID;
    float course = m[M_NS];
    float sp = m[M_NS + 1];
    float sigma_vel = m[M_NS + 2];
    rot_dcm_to_euler(ypr, cb);
    ypr[0] = -course;
    rot_euler_to_q(x + X_Q, ypr);
    rot_q_to_dcm(cb, x + X_Q);
    float v[3];
    v[0] = sp * f32_sin(course);
    v[1] = sp * f32_cos(course);
    v[2] = 0.0f;
    float sh = sigma_h(m + M_FX, aid);
    float sv = sigma_v(m + M_FX, aid, sh);
    restart(c, ii, m, m + M_GP, v, c[C_TICK] - c[C_FIX_TICK], sh, sv, sigma_vel, 0);
    for (int i = 0; i < 3; i++) { /* ins.take_dvn */
        x[X_DVS + i] = 0.0f;
    }
    slow_update(x, 0.0f, ii[I_EARTH]);
    c[C_SINCE_PROP] = 0;
    c[C_ACCEPT_TICK] = c[C_TICK];
    c[C_STATE] = NAVIGATING;
}

/* nav_aid._hold: CAUSE_GNSS_IMPLAUSIBLE held after a reset to GNSS whose step m[M_RESET_D]
 * the horizontal variance var_h did not allow; (pe, pn) the step before this reset. */
static void hold(int32_t *c, const float *m, float var_h, float pe, float pn) {
    int32_t t = c[C_TICK];
    float de = m[M_RESET_D];
    float dn = m[M_RESET_D + 1];
    if (t < c[C_IMPLAUSIBLE_UNTIL]) {
        float ue = de + pe;
        float un = dn + pn;
        if (ue * ue + un * un < STEP_M * STEP_M) {
            c[C_IMPLAUSIBLE_UNTIL] = t;
            return;
        }
    }
    if (de * de + dn * dn > HOLD_K2 * var_h) {
        int32_t u = c[C_ACCEPT_TICK] + STEP_HOLD_S * c[C_T_SECOND];
        if (u > c[C_IMPLAUSIBLE_UNTIL]) {
            c[C_IMPLAUSIBLE_UNTIL] = u;
        }
    }
}

/* nav_aid._reset_to_gnss: position and horizontal velocity from the fix the filter last
 * rejected (m[M_US..]), a fresh covariance, the biases back to the calibration; a sensor
 * step's reset (fewer rejects than C_RESET_AFTER) keeps the vertical channel. */
static void reset_to_gnss(int32_t *c, int32_t *ii, float *m) {
    float *x = m + M_X;
    const float *used = m + M_US;
    const float *pk = m + M_E + E_P;
    float sh = used[US_SIG_H];
    float var_h = pk[0] + pk[N + 1] + 2.0f * (sh * sh);
    float pe = m[M_RESET_D];
    float pn = m[M_RESET_D + 1];
    float course = used[US_COURSE];
    float sp = used[US_SPEED];
    int32_t drift = c[C_REJECTS] < c[C_RESET_AFTER];
    float v[3];
    v[2] = drift ? x[X_V + 2] : 0.0f;
    if (course >= 0.0f) {
        v[0] = sp * f32_sin(course);
        v[1] = sp * f32_cos(course);
    } else {
        v[0] = x[X_V];
        v[1] = x[X_V + 1];
        if (sp >= 0.0f) {
            float v2 = v[0] * v[0] + v[1] * v[1];
            if (v2 > sp * sp) {
                float k = sp / __builtin_sqrtf(v2);
                v[0] = v[0] * k;
                v[1] = v[1] * k;
            }
        }
    }
    float sigma_vel = m[M_NS]; /* init_vel_sigma */
    if (course < 0.0f) {       /* the velocity is the navigator's own, and it has drifted */
        sigma_vel = m[M_NS + 1]; /* track_vel_sigma */
    }
    restart(c, ii, m, used + US_P, v, c[C_TICK] - c[C_USED_TICK], sh, used[US_SIG_V],
            sigma_vel, drift);
    for (int i = 0; i < 3; i++) {
        x[X_BG + i] = 0.0f;
        if (i < 2 || !drift) {
            x[X_BA + i] = 0.0f;
        }
    }
    c[C_REJECTS] = 0;
    c[C_V_REJECTS] = 0;
    c[C_RESET_UNTIL] = UNCONFIRMED;
    hold(c, m, var_h, pe, pn);
}

/* nav_align._gsf_turn: after a start or a reset (no filter job, dx 0) the attitude turned by
 * the bank, about the vertical by d and in roll and pitch by its weighted specific force error
 * (injected as a correction is), the bank's offsets less d and its force errors less it. */
static void gsf_turn(float *m, float d) {
    float *g = m + M_GSF;
    float *e = m + M_E;
    float be = g[G_B];
    float bn = g[G_B + 1];
    d = f32_wrap(d);
    e[E_DX + IX_ATT] = bn / G0_M_S2;
    e[E_DX + IX_ATT + 1] = -be / G0_M_S2;
    e[E_DX + IX_ATT + 2] = d;
    navk_inject(m + M_X, e, m + M_CORR);
    g[G_DYAW] = g[G_DYAW] + f32_wrap(d); /* _turned */
    for (int k = 0; k < GSF_N; k++) {
        float *h = g + G_HYP + k * NH;
        h[5] = h[5] - be;
        h[6] = h[6] - bn;
    }
}

/* nav_align._yaw_var: the heading's initial variance into m[M_INIT + yaw], the larger of
 * init_yaw_sigma^2 (m[M_NS + 2]) and var. */
static void yaw_var(float *m, float var) {
    float y = m[M_NS + 2];
    y = y * y;
    if (var > y) {
        y = var;
    }
    m[M_INIT + IX_ATT + 2] = y;
}

/* nav_align._start_navigation: navigation starts with the heading from course (rad clockwise
 * from north), horizontal velocity sp along it (1-sigma sigma_vel), the heading's variance the
 * larger of var_course and init_yaw_sigma^2. */
static void start(int32_t *c, int32_t *ii, float *m, float course, float sp, float sigma_vel,
                  float var_course) {
    yaw_var(m, var_course);
    float ypr[3];
    rot_dcm_to_euler(ypr, m + M_X + X_C); /* _yaw_now */
    m[M_GSF + G_DYAW] = m[M_GSF + G_DYAW] + f32_wrap(-course - ypr[0]); /* _turned */
    if (m[M_FX + FX_SIG_V] < 0.0f) { /* a receiver without height: the height is unknown */
        m[M_CN + CN_VV] = NO_HEIGHT_VAR;
    }
    m[M_NS] = course;
    m[M_NS + 1] = sp;
    m[M_NS + 2] = sigma_vel;
    navk_nav_start(c, ii, m);
}

/* nav_align._gsf_reset: heading, horizontal velocity and covariance from the yaw estimator's
 * bank (m[M_GSF..]), the position from the fix, the biases kept. */
static void gsf_reset(int32_t *c, int32_t *ii, float *m) {
    float *g = m + M_GSF;
    const float *aid = m + M_AID;
    yaw_var(m, g[G_VAR]);
    float v[3];
    v[0] = g[G_V];
    v[1] = g[G_V + 1];
    v[2] = 0.0f;
    float sh = sigma_h(m + M_FX, aid);
    float sv = sigma_v(m + M_FX, aid, sh);
    restart(c, ii, m, m + M_GP, v, c[C_TICK] - c[C_FIX_TICK], sh, sv, m[M_NS], 0);
    gsf_turn(m, g[G_YAW]);
    c[C_REJECTS] = 0;
    c[C_V_REJECTS] = 0;
    c[C_GSF_DIS] = 0;
    c[C_RESET_UNTIL] = UNCONFIRMED;
}

/* nav_align._gsf_start: navigation starts from the yaw estimator's heading and velocity. */
static void gsf_start(int32_t *c, int32_t *ii, float *m) {
    const float *g = m + M_GSF;
    float ypr[3];
    rot_dcm_to_euler(ypr, m + M_X + X_C); /* _yaw_now */
    float yaw = ypr[0] + g[G_YAW];
    float course = f32_atan2(g[G_V], g[G_V + 1]);
    float sp = __builtin_sqrtf(g[G_V] * g[G_V] + g[G_V + 1] * g[G_V + 1]); /* _gsf_speed */
    start(c, ii, m, course, sp, m[M_NS], g[G_VAR]);
    gsf_turn(m, yaw + course); /* the start set the yaw to -course */
}

/* nav_align._course_start: navigation starts from the fix's course and speed, the course's
 * 1-sigma gnss_vel_sigma / speed. */
static void course_start(int32_t *c, int32_t *ii, float *m) {
    const float *fx = m + M_FX;
    float sp = fx[FX_SPEED];
    float s = m[M_AID + AID_VEL_SIGMA] / sp;
    start(c, ii, m, fx[FX_COURSE], sp, m[M_NS], s * s);
}

/* The navigator's starts and resets from the fix's course, the yaw estimator or the fix the
 * filter kept rejecting, without Python floats (on the board those are heap objects: a reset's
 * ~2 KB of them brought collections while a walk navigated, the start's Python made the
 * heaviest tick of a drive). kind RESTART_*; m[M_NS..] holds init_vel_sigma, track_vel_sigma
 * and init_yaw_sigma (Navigator._restart_native); a start's own inputs replace them. */
void navk_nav_restart(int32_t *c, int32_t *ii, float *m, int32_t kind) {
    if (kind == RESTART_GNSS) {
        reset_to_gnss(c, ii, m);
    } else if (kind == RESTART_GSF) {
        gsf_reset(c, ii, m);
    } else if (kind == RESTART_GSF_START) {
        gsf_start(c, ii, m);
    } else {
        course_start(c, ii, m);
    }
}
