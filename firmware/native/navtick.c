/* A whole navigator tick in one call: Navigator._tick and its callees (firmware/lib/nav.py,
 * the reference: _imu_counts_py, _tick, _still_update, _navigate, _schedule, _inject,
 * _update_health), with the control state in the int buffer c (C_*), the floats in m
 * (Navigator.mem, M_*) and the float work in the other kernels. Few arguments on purpose: see
 * nav.py's self.mem.
 *
 * What stays in Python returns an event (EV_*) with c[C_PHASE] saying where the tick resumes:
 * the app runs the event's method (a fix's screening, with re-anchoring or the start of
 * navigation, a reset: once a second at most) and calls again with the same arguments. The
 * filter's jobs start here, their rows included (aid.c). The order of every step is the
 * reference's, so a tick's results are the same bit for bit. */
#include <stdint.h>

#include "fmath32.h"
#include "layout.h"
#include "lever32.h"
#include "navk.h"
#include "rot32.h"
#include "tuning.h"


#define PH_START 0 /* a new tick */
#define PH_SCHEDULE 1 /* after a fix was screened (EV_FIX) */
#define PH_CHECK 2 /* after a reset to GNSS (EV_RESET, EV_VRESET) */
#define PH_HEALTH 3 /* after alignment or a fault reset (EV_ALIGN, EV_FAULT) */

/* _update_health: the causes (CAUSE_*) and the health code they make */
static void update_health(int32_t *c) {
    int32_t t = c[C_TICK];
    int32_t k = 0;
    if (t < c[C_SAT_UNTIL]) {
        k |= CAUSE_IMU_SAT;
    }
    if (t < c[C_HELD_UNTIL]) {
        k |= CAUSE_IMU_HELD;
    }
    if (t < c[C_DEAD_UNTIL]) {
        k |= CAUSE_IMU_DEAD;
    }
    if (t < c[C_FAULT_UNTIL]) {
        k |= CAUSE_NUMERIC;
    }
    if (t < c[C_GATED_UNTIL]) {
        k |= CAUSE_GNSS_GATED;
    }
    if (t < c[C_DATA_UNTIL]) {
        k |= CAUSE_GNSS_DATA;
    }
    if (t < c[C_RESET_UNTIL]) {
        k |= CAUSE_RESET;
    }
    if (t < c[C_DRIFT_UNTIL]) {
        k |= CAUSE_DRIFT;
    }
    if (t < c[C_IMPLAUSIBLE_UNTIL]) {
        k |= CAUSE_GNSS_IMPLAUSIBLE;
    }
    if (c[C_STATE] == NAVIGATING) {
        if (t - c[C_ACCEPT_TICK] > c[C_T_TIMEOUT]) {
            k |= CAUSE_GNSS_LOST;
        }
        if (c[C_REJECTS] >= 2 || c[C_V_REJECTS] >= 2) {
            k |= CAUSE_GNSS_REJECTS;
        }
        if (c[C_UNCERTAIN]) {
            k |= CAUSE_UNCERTAIN;
        }
    } else {
        k |= CAUSE_NOT_NAVIGATING;
    }
    c[C_CAUSES] = k;
    c[C_HEALTH] = (k & CAUSE_FAULTS) ? 2 : (k ? 1 : 0);
}

/* nav_kern.imu_check: 1 if the counts cannot be a working BMI055's sample; keeps the last counts
 * and the runs of unchanged ones (not for a repeat of the same read) */
static int32_t imu_check(int32_t *c, const int16_t *g, const int16_t *a) {
    int32_t st = c[C_IMU_STATUS];
    if (!(st & IMU_REPEAT)) {
        if (g[0] == c[C_PREV_G] && g[1] == c[C_PREV_G + 1] && g[2] == c[C_PREV_G + 2]) {
            if (c[C_N_SAME_G] < c[C_T_STUCK]) {
                c[C_N_SAME_G] += 1;
            }
        } else {
            c[C_N_SAME_G] = 0;
        }
        if (a[0] == c[C_PREV_A] && a[1] == c[C_PREV_A + 1] && a[2] == c[C_PREV_A + 2]) {
            if (c[C_N_SAME_A] < c[C_T_STUCK]) {
                c[C_N_SAME_A] += 1;
            }
        } else {
            c[C_N_SAME_A] = 0;
        }
        for (int i = 0; i < 3; i++) {
            c[C_PREV_G + i] = g[i];
            c[C_PREV_A + i] = a[i];
        }
    }
    if ((st & IMU_OVER_RANGE) || !(st & IMU_FRESH)) {
        return 1;
    }
    int32_t v = a[0];
    if ((v == 0 || v == -1) && a[1] == v && a[2] == v && g[0] == v && g[1] == v && g[2] == v) {
        return 1;
    }
    return c[C_N_SAME_G] >= c[C_T_STUCK] || c[C_N_SAME_A] >= c[C_T_STUCK];
}

/* nav_kern.finite6 */
static int32_t finite6(const float *w, const float *f) {
    float s = w[0] + w[1] + w[2] + f[0] + f[1] + f[2];
    return s - s == 0.0f;
}

/* nav_kern.uncertain */
static int32_t uncertain(const float *e, const float *aid, const float *m) {
    float lim = aid[AID_FAULT_SIGMA];
    float lim2 = lim * lim;
    const float *p = e + E_P;
    if (p[0] > lim2 || p[N + 1] > lim2) {
        return 1;
    }
    lim = aid[AID_FAULT_SIGMA_V];
    return p[2 * (N + 1)] > lim * lim && m[M_FX + FX_SIG_V] >= 0.0f ? 1 : 0;
}

/* nav_align._level: roll and pitch from the mean specific force, the gyro bias from the
 * mean rate when standing still; the heading is kept */
static void level(int32_t *c, float *m) {
    float *x = m + M_X;
    float *lv = m + M_LVL;
    float *ypr = m + M_YPR;
    float n = (float)c[C_N_LEVEL];
    float fx = lv[0] / n;
    float fy = lv[1] / n;
    float fz = lv[2] / n;
    float g = __builtin_sqrtf(fx * fx + fy * fy + fz * fz);
    if (!(g > MIN_LEVEL_F)) { /* a dead accelerometer or free fall */
        for (int i = 0; i < 6; i++) {
            lv[i] = 0.0f;
        }
        c[C_N_LEVEL] = 0;
        return;
    }
    rot_dcm_to_euler(ypr, x + X_C);
    ypr[1] = f32_asin(fy / g);
    ypr[2] = f32_atan2(-fx, fz);
    rot_euler_to_q(x + X_Q, ypr);
    rot_q_to_dcm(x + X_C, x + X_Q);
    if (c[C_STILL]) {
        for (int i = 0; i < 3; i++) {
            x[X_BG + i] = lv[3 + i] / n;
        }
    }
    for (int i = 0; i < 6; i++) {
        lv[i] = 0.0f;
    }
    c[C_N_LEVEL] = 0;
    c[C_LEVELED] = 1;
}

/* nav_align._align up to the pending fix: the levelling sums, levelling, and roll and pitch
 * kept current with the gyros once levelled */
static void align_step(int32_t *c, float *m) {
    float *x = m + M_X;
    const float *w = m + M_W;
    const float *f = m + M_F;
    float *lv = m + M_LVL;
    int32_t still = c[C_STILL];
    if (still || !c[C_LEVELED]) {
        for (int i = 0; i < 3; i++) {
            lv[i] = lv[i] + f[i];
            lv[3 + i] = lv[3 + i] + w[i];
        }
        c[C_N_LEVEL] += 1;
        if (c[C_N_LEVEL] >= c[C_T_LEVEL]) {
            level(c, m);
        }
    }
    if (c[C_LEVELED] && !still) {
        float th[3];
        float dt = x[X_DT];
        for (int i = 0; i < 3; i++) {
            th[i] = (w[i] - x[X_BG + i]) * dt;
        }
        rot_q_update(x + X_Q, th);
        rot_q_to_dcm(x + X_C, x + X_Q);
    }
    if (c[C_GSF]) {
        navk_gsf_accum(m);
    }
}

/* _still_update */
static void still_update(int32_t *c, float *st, const float *f, const float *w, const float *x,
    const float *stp) {
    int32_t flags = 0;
    if (c[C_TICK] == 4) {
        flags = STILL_FIRST;
    }
    if (c[C_TICK] - c[C_SPEED_TICK] < c[C_T_SECOND]) {
        flags |= STILL_GNSS_SPEED;
    }
    if (c[C_STATE] == NAVIGATING) {
        flags |= STILL_NAVIGATING;
    }
    if (navk_still(st, f, w, x, stp, flags)) {
        c[C_N_STILL] += 4;
    } else {
        c[C_N_STILL] = 0;
    }
    c[C_STILL] = c[C_N_STILL] >= c[C_T_STILL] ? 1 : 0;
}

/* nav_kern.lag_search: per candidate lag, the change of the velocity residual against the
 * ring's track between consecutive fixes, its running mean of squares, and the lag applied
 * (the least, shrunk by the evidence against no lag) */
static void lag_search(int32_t *c, float *m, int32_t age) {
    const float *x = m + M_X;
    float *cn = m + M_CN;
    float *ls = m + M_LS;
    int32_t t = c[C_FIX_TICK] - c[C_LAG_TICK];
    if (c[C_LAG_TICK] != 0 && t >= 0 && t < c[C_T_SECOND] - c[C_T_SECOND] / 4) {
        return; /* pairs about a second apart at any rate */
    }
    c[C_LAG_TICK] = c[C_FIX_TICK];
    float course = m[M_FX + FX_COURSE];
    float sp = m[M_FX + FX_SPEED];
    if (!(c[C_OPTS] & OPT_LAG) || course < 0.0f || !(sp * sp > LAG_V2) || age < 0
        || age + LS_STEP * (LS_C - 1) > RING - 1 || c[C_TICK] < c[C_DRIFT_UNTIL]
        || c[C_TICK] < c[C_GATED_UNTIL]) {
        c[C_LAG_TICK] = 0; /* no velocity, too slow, too old for the ring, or the INS drifting */
        return;
    }
    float ve = sp * f32_sin(course);
    float vn = sp * f32_cos(course);
    float lev[2];
    lever_vel_en(lev, x, m + M_W, m + M_AID + AID_LEVER);
    int32_t pair = t >= 1 && t <= 2 * c[C_T_SECOND];
    float k = cn[CN_KL];
    if (pair) {
        k = k + 1.0f;
        if (k > CN_N) {
            k = CN_N;
        }
        cn[CN_KL] = k;
    }
    float a = pair ? 1.0f / k : 0.0f;
    const float *rv = m + M_RING_V;
    int32_t best = 0;
    for (int32_t j = 0; j < LS_C; j++) {
        int32_t b = ((c[C_TICK] - (age + j * LS_STEP)) % RING) * 3;
        float ye = (rv[b] + lev[0]) - ve;
        float yn = (rv[b + 1] + lev[1]) - vn;
        if (pair) {
            float de = ye - ls[LS_E + j];
            float dn = yn - ls[LS_N + j];
            ls[LS_M + j] = ls[LS_M + j] + a * ((de * de + dn * dn) - ls[LS_M + j]);
            if (ls[LS_M + j] < ls[LS_M + best]) {
                best = j;
            }
        }
        ls[LS_E + j] = ye;
        ls[LS_N + j] = yn;
    }
    if (!pair) {
        return;
    }
    float dt = x[X_DT];
    float lag = (float)(best * LS_STEP) * dt;
    cn[CN_LAG] = lag;
    cn[CN_LAGT] = 0.0f;
    if (best == 0 || k < LAG_K0) {
        return;
    }
    float mb = ls[LS_M + best];
    if (!(mb > 0.0f)) {
        return;
    }
    float q = k * (ls[LS_M] - mb) / mb;
    if (q < 1.0f) {
        return; /* not a sigma from no lag */
    }
    lag = lag * q / (1.0f + q);
    cn[CN_LAGT] = (float)(int32_t)(lag / dt + 0.5f);
}

/* _start_queued_fix and nav_aid._start_gnss_update: the GNSS update of the queued fix,
 * against the state at its measurement time (the delay ring holds the last RING ticks) */
static void start_queued_fix(int32_t *c, int32_t *ki, float *m) {
    c[C_FIX_QUEUED] = 0;
    int32_t age = c[C_TICK] - c[C_FIX_TICK];
    lag_search(c, m, age);
    age = age + (int32_t)m[M_CN + CN_LAGT];
    if (age < 0) {
        age = 0;
    } else if (age > RING - 1) {
        age = RING - 1;
    }
    c[C_JOB] = JOB_GNSS;
    c[C_UPDATES] += 1;
    /* nav_kern.rate_r: the factor on the position variances, the fixes a second taken (1 to 10) */
    float rk = 1.0f;
    int32_t d = c[C_FIX_TICK] - c[C_LAST_TICK];
    if (!(c[C_LAST_TICK] == 0 || d <= 0 || d >= c[C_T_SECOND])) {
        if (d < c[C_T_SECOND] / 10) {
            d = c[C_T_SECOND] / 10;
        }
        rk = (float)c[C_T_SECOND] / (float)d;
    }
    m[M_CN + CN_RK] = rk;
    c[C_USED_TICK] = c[C_FIX_TICK];
    navk_gnss_rows(m + M_E, ki, m + M_X, m + M_RING_P, m + M_RING_V, m + M_CORR, m + M_GP,
        m + M_FX, m + M_US, m + M_W, m + M_AID, ((c[C_TICK] - age) % RING) * 3, rk,
        m[M_CN + CN_RVEL]);
}

/* Eskf.widen: P's variances i0 + j at least var[j] */
static void widen(float *e, const float *var, int32_t i0, int32_t n) {
    float *p = e + E_P;
    for (int32_t j = 0; j < n; j++) {
        int32_t k = (i0 + j) * (N + 1);
        if (p[k] < var[j]) {
            p[k] = var[j];
        }
    }
}

/* _schedule (the filter is idle): start the next job, if one is due */
static void schedule(int32_t *c, int32_t *ki, float *m) {
    float *x = m + M_X;
    float *e = m + M_E;
    if (c[C_INFLATE] & INFLATE_MOTION) { /* the IMU is back after a dead spell */
        widen(e, m + M_INIT + IX_VEL, IX_VEL, 6);
    }
    if (c[C_INFLATE] & INFLATE_VERTICAL) { /* a vertical accelerometer step (aid_watch) */
        widen(e, m + M_INIT + IX_VEL + 2, IX_VEL + 2, 1);
        widen(e, m + M_INIT + IX_BA + 2, IX_BA + 2, 1);
    }
    c[C_INFLATE] = 0;
    int32_t overdue = c[C_SINCE_PROP] >= 2 * c[C_T_PROP];
    if ((c[C_OPTS] & OPT_ZUPT) && c[C_STILL] && c[C_SINCE_ZUPT] >= 2 * c[C_T_ZUPT]) {
        overdue = 1;
    } else if ((c[C_OPTS] & OPT_NHC) && !c[C_STILL] && c[C_SINCE_NHC] >= 2 * c[C_T_NHC]) {
        overdue = 1;
    }
    if (c[C_FIX_QUEUED] && !overdue) {
        start_queued_fix(c, ki, m);
    } else if (c[C_SINCE_PROP] >= c[C_T_PROP]) {
        navk_prop_start(x, e, ki, c[C_SINCE_PROP]);
        c[C_SINCE_PROP] = 0;
    } else if ((c[C_OPTS] & OPT_ZUPT) && c[C_STILL] && c[C_SINCE_ZUPT] >= c[C_T_ZUPT]) {
        c[C_SINCE_ZUPT] = 0;
        c[C_JOB] = JOB_AID;
        navk_zupt_rows(e, ki, x, m + M_AID); /* nav_aid._start_zupt */
    } else if ((c[C_OPTS] & OPT_NHC) && !c[C_STILL] && c[C_SINCE_NHC] >= c[C_T_NHC]) {
        c[C_SINCE_NHC] = 0;
        c[C_JOB] = JOB_AID;
        navk_nhc_rows(e, ki, x, m + M_AID); /* nav_aid._start_nhc */
    }
}

/* nav_kern.drift_watch: 2 when a running mean of normalised innovations passes the limit, else 1
   when one of the suspicion's (M_BS, each ratio clipped at BS_CLIP) passes BS_LIMIT (the
   height's while a drift is held: BS_LEAVE), else 0; plus DRIFT_H when a mean beyond its limit
   is a horizontal one */
static int32_t drift_watch(const float *e, float *m, int32_t n, int32_t held) {
    const float *z = e + E_Z;
    const float *r = e + E_R;
    float *bw = m + M_BW;
    float *bs = m + M_BS;
    float a = BW_ALPHA / m[M_CN + CN_RK]; /* a fix weighs 1 / rk of a second's */
    int32_t hit = 0;
    int32_t hz = 0;
    for (int k = 0; k < BW_N; k++) {
        if (k < n && r[k] > 0.0f) {
            float q = z[k] / __builtin_sqrtf(r[k]);
            if (q > BW_CLIP) {
                q = BW_CLIP;
            } else if (q < -BW_CLIP) {
                q = -BW_CLIP;
            }
            bw[k] = bw[k] + a * (q - bw[k]);
            int beyond = bw[k] > BW_LIMIT || bw[k] < -BW_LIMIT;
            if (beyond) {
                hit = 2;
            }
            if (q > BS_CLIP) {
                q = BS_CLIP;
            } else if (q < -BS_CLIP) {
                q = -BS_CLIP;
            }
            bs[k] = bs[k] + a * (q - bs[k]);
            if (bs[k] > BS_LIMIT || bs[k] < -BS_LIMIT) {
                beyond = 1;
                if (hit == 0) {
                    hit = 1;
                }
            } else if (held && k == 2 && hit == 0 && (bs[k] > BS_LEAVE || bs[k] < -BS_LEAVE)) {
                hit = 1;
            }
            if (beyond && k != 2) { /* not the height's */
                hz = DRIFT_H;
            }
        }
    }
    if (hit == 2) {
        for (int j = 0; j < BW_N; j++) {
            bs[j] = 0.0f;
            bw[j] = 0.0f;
        }
    }
    return hit | hz;
}

/* nav_kern.aid_watch: after the non-holonomic constraint (n = 2: rows lateral, vertical) or the
   zero-velocity update (n = 3: its row 2, up, into the vertical mean), the running means of
   y / sqrt(S) clipped at BW_CLIP as drift_watch's; AW_HIT_LAT, AW_HIT_UP for those beyond their
   limits */
static int32_t aid_watch(const float *e, float *m, int32_t n) {
    const float *z = e + E_Z;
    const float *r = e + E_R;
    float *aw = m + M_AW;
    int32_t k0;
    if (n == 2) {
        k0 = AW_LAT; /* rows 0, 1: the means AW_LAT, AW_UP */
    } else if (n == 3) {
        k0 = AW_UP; /* row 2: the mean AW_UP */
    } else {
        return 0;
    }
    int32_t hit = 0;
    for (int32_t k = k0; k < 2; k++) {
        int32_t j = n == 2 ? k : 2;
        if (r[j] > 0.0f) {
            float q = z[j] / __builtin_sqrtf(r[j]);
            if (q > BW_CLIP) {
                q = BW_CLIP;
            } else if (q < -BW_CLIP) {
                q = -BW_CLIP;
            }
            aw[k] = aw[k] + BW_ALPHA * (q - aw[k]);
            float lim = k == AW_LAT ? AW_LIMIT_LAT : AW_LIMIT_UP;
            if (aw[k] > lim || aw[k] < -lim) {
                hit |= 1 << k;
            }
        }
    }
    return hit;
}

/* nav_kern.consistency: after a GNSS update whose position rows were all accepted, the running
 * means of y^2/S and from them the position's error variance the filter cannot see */
static void consistency(const float *e, float *m, int32_t n, int32_t mask) {
    if (n < 3 || (mask & 7)) {
        return;
    }
    const float *z = e + E_Z;
    const float *r = e + E_R;
    if (!(r[0] > 0.0f && r[1] > 0.0f && r[2] > 0.0f)) {
        return;
    }
    float *cn = m + M_CN;
    float k = cn[CN_K] + 1.0f / cn[CN_RK]; /* a window of CN_N seconds at any rate */
    if (k > CN_N) {
        k = CN_N;
    }
    cn[CN_K] = k;
    float a = 1.0f / k;
    float qe = z[0] * z[0] / r[0];
    if (qe > CN_CLIP) {
        qe = CN_CLIP;
    }
    float qn = z[1] * z[1] / r[1];
    if (qn > CN_CLIP) {
        qn = CN_CLIP;
    }
    float qu = z[2] * z[2] / r[2];
    if (qu > CN_CLIP) {
        qu = CN_CLIP;
    }
    float qh = (qe + qn) * 0.5f;
    cn[CN_MH] = cn[CN_MH] + a * (qh - cn[CN_MH]);
    float s = m[M_US + US_SIG_H];
    const float *p = e + E_P;
    if (cn[CN_MH] < 1.0f) {
        cn[CN_VH] = (1.0f - cn[CN_MH]) * (s * s);
    } else { /* fixes that miss the state more than S says: an error P does not hold */
        cn[CN_VH] = (cn[CN_MH] - 1.0f) * ((p[0] + p[N + 1]) * 0.5f);
    }
    s = m[M_US + US_SIG_V]; /* < 0: the fix had no height, and the state's is unknown */
    cn[CN_VV] = NO_HEIGHT_VAR;
    if (s > 0.0f) {
        cn[CN_MV] = cn[CN_MV] + a * (qu - cn[CN_MV]);
        if (cn[CN_MV] < 1.0f) {
            cn[CN_VV] = (1.0f - cn[CN_MV]) * (s * s);
        } else {
            cn[CN_VV] = (cn[CN_MV] - 1.0f) * p[2 * (N + 1)];
        }
    }
}

/* nav_kern.vel_noise: after a GNSS update whose velocity rows (n = 5: rows 3, 4 east, north)
 * were accepted, the running mean of the change of y since the last fix squared over 2 less
 * S - R: the receiver's velocity variance per axis the rows take next */
static void vel_noise(const float *e, float *m, int32_t n, int32_t mask) {
    float *cn = m + M_CN;
    const float *z = e + E_Z;
    const float *r = e + E_R;
    float rv = cn[CN_RVEL];
    if (n < 5 || (mask & 0x18) || !(r[3] > 0.0f && r[4] > 0.0f) || r[3] - rv > VR_MAX ||
        r[4] - rv > VR_MAX) {
        cn[CN_VOK] = 0.0f;
        return;
    }
    float ye = z[3];
    float yn = z[4];
    float de = ye - cn[CN_VE];
    float dn = yn - cn[CN_VN];
    float ok = cn[CN_VOK];
    cn[CN_VE] = ye;
    cn[CN_VN] = yn;
    cn[CN_VOK] = 1.0f;
    if (!(ok > 0.0f)) { /* no previous fix to compare with */
        return;
    }
    float k = cn[CN_KR] + 1.0f / cn[CN_RK];
    if (k > VR_N) {
        k = VR_N;
    }
    cn[CN_KR] = k;
    if (k < 1.0f) { /* a fast receiver's first pair */
        k = 1.0f;
    }
    float a = 1.0f / k;
    float q = ((de * de + dn * dn) * 0.5f - ((r[3] - rv) + (r[4] - rv))) * 0.5f;
    cn[CN_V2] = cn[CN_V2] + a * (q - cn[CN_V2]);
    float lo = m[M_AID + AID_VEL_SIGMA];
    lo = lo * lo;
    rv = lo;
    if (k >= VR_K0) {
        rv = cn[CN_V2];
        if (rv < lo) {
            rv = lo;
        } else if (rv > VR_MAX) {
            rv = VR_MAX;
        }
    }
    cn[CN_RVEL] = rv;
}

/* nav_aid._jumped: the fix just used farther from the last fix the filter took than the
   board can have moved between them at the INS's speed, plus JUMP_M and STEP_HALF_A t^2; or,
   with a course and t up to JUMP_VEL_S, farther than that margin from it moved by the fix's
   own velocity */
static int32_t jumped(const int32_t *c, const float *m) {
    if (c[C_LAST_TICK] == 0) {
        return 0;
    }
    float t = (float)(c[C_USED_TICK] - c[C_LAST_TICK]) * m[M_X + X_DT];
    float de = m[M_US] - m[M_LAST];
    float dn = m[M_US + 1] - m[M_LAST + 1];
    float ve = m[M_X + X_V];
    float vn = m[M_X + X_V + 1];
    float margin = JUMP_M + STEP_HALF_A * (t * t);
    float reach = __builtin_sqrtf(ve * ve + vn * vn) * t + margin;
    if (de * de + dn * dn > reach * reach) {
        return 1;
    }
    float course = m[M_US + US_COURSE];
    if (course < 0.0f || t > JUMP_VEL_S) {
        return 0;
    }
    float sp = m[M_US + US_SPEED];
    de = de - sp * f32_sin(course) * t;
    dn = dn - sp * f32_cos(course) * t;
    return de * de + dn * dn > margin * margin;
}

/* nav_aid._beyond_drift: an east/north innovation (ye, yn) beyond what the INS can have
   drifted since the last accepted fix */
static int32_t beyond_drift(const int32_t *c, const float *m, float ye, float yn) {
    float t = (float)(c[C_TICK] - c[C_ACCEPT_TICK]) * m[M_X + X_DT];
    float lim = STEP_M + STEP_HALF_A * (t * t);
    return ye * ye + yn * yn > lim * lim;
}

/* nav_aid.refused: the reset to the fix of a jumped run's GNSS update just done refused */
static int32_t refused(const int32_t *c, const float *e, const float *m) {
    float de = m[M_JUMP] - m[M_RESET_D];
    float dn = m[M_JUMP + 1] - m[M_RESET_D + 1];
    if (de * de + dn * dn < STEP_M * STEP_M) {
        return 0; /* the jump undoes the last reset */
    }
    float ye = e[E_Z];
    float yn = e[E_Z + 1];
    if (beyond_drift(c, m, ye, yn)) {
        return 1;
    }
    if (c[C_TICK] - c[C_ACCEPT_TICK] >= STEP_HOLD_S * c[C_T_SECOND]) {
        return 0;
    }
    return !beyond_drift(c, m, ye - m[M_JUMP], yn - m[M_JUMP + 1]);
}

/* nav_aid._last_fix: the fix just used becomes the last one the filter took */
static void last_fix(int32_t *c, float *m) {
    m[M_LAST] = m[M_US];
    m[M_LAST + 1] = m[M_US + 1];
    c[C_LAST_TICK] = c[C_USED_TICK];
}

/* nav._drift_reset: a reset to GNSS that a drift calls for holds the drift DRIFT_HOLD_S */
static void drift_reset(int32_t *c) {
    int32_t t = c[C_TICK] + DRIFT_HOLD_S * c[C_T_SECOND];
    if (t > c[C_DRIFT_UNTIL]) {
        c[C_DRIFT_UNTIL] = t;
    }
}

/* _inject (dx is ready): the reset the rejects or a drift call for (EV_RESET, EV_VRESET),
   else 0 */
static int32_t inject(int32_t *c, int32_t *ki, float *m) {
    float *x = m + M_X;
    float *e = m + M_E;
    /* the yaw correction turns the navigator, not the truth: the bank's offsets less it */
    m[M_GSF + G_DYAW] = m[M_GSF + G_DYAW] + e[E_DX + IX_ATT + 2];
    navk_inject(x, e, m + M_CORR);
    ki[I_READY] = 0;
    int32_t job = c[C_JOB];
    c[C_JOB] = JOB_NONE;
    if (job == JOB_AID) {
        int32_t hit = aid_watch(e, m, ki[I_ACCEPTED] + ki[I_REJECTED]);
        if (hit) { /* a constraint the INS keeps breaking: a sensor step, for 5 s */
            int32_t w = c[C_TICK] + 5 * c[C_T_SECOND];
            if (w > c[C_DRIFT_UNTIL]) {
                c[C_DRIFT_UNTIL] = w;
            }
            c[C_STEP_UNTIL] = w;
            if (hit & AW_HIT_UP) {
                c[C_INFLATE] |= INFLATE_VERTICAL;
            }
        }
    }
    if (job != JOB_GNSS) {
        return 0;
    }
    int32_t mask = ki[I_GATE_MASK];
    int32_t n = ki[I_ACCEPTED] + ki[I_REJECTED];
    int32_t w = drift_watch(e, m, n, c[C_TICK] < c[C_DRIFT_UNTIL]);
    if (w & 3) { /* a drift: for 5 s; a suspected one: for 1.5 s after the fix that shows it */
        int32_t t = c[C_TICK] + ((w & 3) == 2 ? 5 * c[C_T_SECOND] : 3 * c[C_T_SECOND] / 2);
        if (t > c[C_DRIFT_UNTIL]) {
            c[C_DRIFT_UNTIL] = t;
        }
    }
    /* a sensor step the constraints show, the yaw estimator agreeing with the heading: a
       rejected fix, or a horizontal drift, resets now (nav._drift_reset) */
    int32_t step = c[C_TICK] < c[C_STEP_UNTIL] && !c[C_GSF_DIS];
    consistency(e, m, n, mask);
    vel_noise(e, m, n, mask);
    if (mask & 4) {
        c[C_V_REJECTS] += 1;
    } else {
        c[C_V_REJECTS] = 0;
    }
    if (mask & 0x1B) { /* east, north: position or velocity */
        c[C_REJECTS] += 1;
        if (c[C_REJECTS] == 1) {
            c[C_JUMPED] = jumped(c, m);
            m[M_JUMP] = e[E_Z];
            m[M_JUMP + 1] = e[E_Z + 1];
        }
        c[C_GATED_UNTIL] = c[C_TICK] + c[C_T_SECOND];
        last_fix(c, m);
        if (c[C_REJECTS] < c[C_RESET_AFTER] && !step) {
            return 0;
        }
        if (c[C_JUMPED] && refused(c, e, m)) { /* the receiver jumped: no reset to it */
            int32_t u = c[C_TICK] + c[C_T_SECOND]; /* not shortening a reset's hold */
            if (u > c[C_IMPLAUSIBLE_UNTIL]) {
                c[C_IMPLAUSIBLE_UNTIL] = u;
            }
            return 0;
        }
        if (c[C_REJECTS] < c[C_RESET_AFTER]) {
            drift_reset(c);
        }
        return EV_RESET;
    }
    last_fix(c, m);
    c[C_REJECTS] = 0;
    c[C_ACCEPT_TICK] = c[C_TICK];
    if (mask) {
        c[C_GATED_UNTIL] = c[C_TICK] + c[C_T_SECOND];
    } else if (c[C_RESET_UNTIL] > c[C_TICK]) {
        c[C_RESET_UNTIL] = c[C_TICK]; /* a whole fix agrees with the reset state */
    }
    if (c[C_V_REJECTS] >= c[C_RESET_AFTER]) {
        return EV_VRESET;
    }
    if (step && (w & DRIFT_H)) {
        drift_reset(c);
        return EV_RESET;
    }
    return 0;
}

static int32_t stop(int32_t *c, int32_t phase, int32_t ev) {
    c[C_PHASE] = phase;
    return ev;
}

int32_t navk_nav_tick(int32_t *c, int32_t *ki, float *m, const int16_t *gyro,
    const int16_t *accel) {
    float *x = m + M_X;
    float *e = m + M_E;
    float *w = m + M_W;
    float *f = m + M_F;
    float *st = m + M_ST;
    float *corr = m + M_CORR;
    switch (c[C_PHASE]) {
        case PH_START: {
            /* _imu_counts_py and _tick: an unusable sample is replaced by the previous one */
            int32_t held = imu_check(c, gyro, accel);
            int32_t finite = held ? finite6(w, f)
                                  : navk_imu_cal(w, f, gyro, accel, m + M_CAL, c[C_CAL_FLAGS]);
            c[C_TICK] += 1;
            int32_t t = c[C_TICK];
            if (c[C_IMU_STATUS] & IMU_OVER_RANGE) {
                c[C_SAT_UNTIL] = t + c[C_T_SECOND];
            }
            if (held) {
                c[C_HELD_UNTIL] = t + c[C_T_SECOND];
                if (c[C_N_HELD] < c[C_T_STUCK]) {
                    c[C_N_HELD] += 1;
                }
                if (c[C_N_HELD] >= c[C_T_STUCK]) {
                    c[C_DEAD_UNTIL] = t + c[C_T_SECOND];
                }
            } else {
                if (c[C_N_HELD] >= c[C_T_STUCK]) {
                    c[C_INFLATE] |= INFLATE_MOTION; /* the IMU is back after a dead spell */
                }
                c[C_N_HELD] = 0;
            }
            if (!finite) {
                c[C_FAULT_UNTIL] = t + c[C_T_SECOND];
                update_health(c);
                return 0;
            }
            if ((t & 3) == 0 && !held) {
                still_update(c, st, f, w, x, m + M_STP);
            }
            if (c[C_STATE] != NAVIGATING) {
                align_step(c, m);
                if (c[C_FIX_PENDING]) {
                    c[C_FIX_PENDING] = 0;
                    return stop(c, PH_HEALTH, EV_ALIGN);
                }
                update_health(c);
                return 0;
            }
            navk_ins_step(x, w, f, (c[C_OPTS] & OPT_CONING) ? 1 : 0);
            navk_ring_put(m + M_RING_P, m + M_RING_V, x, corr, (c[C_TICK] % RING) * 3);
            if (c[C_GSF]) {
                navk_gsf_accum(m);
            }
            c[C_SINCE_PROP] += 1;
            c[C_SINCE_ZUPT] += 1;
            c[C_SINCE_NHC] += 1;
            if (c[C_FIX_PENDING]) {
                c[C_FIX_PENDING] = 0;
                return stop(c, PH_SCHEDULE, EV_FIX);
            }
        }
        /* fall through */
        case PH_SCHEDULE:
            if (ki[I_JOB] == IDLE && !ki[I_READY]) {
                schedule(c, ki, m);
            }
            c[C_BUSY] = ki[I_JOB] != IDLE;
            navk_eskf_work(e, ki, c[C_SLICES]);
            if (ki[I_READY]) {
                int32_t ev = inject(c, ki, m);
                if (ev) {
                    return stop(c, PH_CHECK, ev);
                }
            }
        /* fall through */
        case PH_CHECK:
            /* P changes only when a job finishes: check it then, not every tick */
            if (c[C_BUSY] && ki[I_JOB] == IDLE) {
                if (!navk_eskf_diagonal_ok(e)) {
                    return stop(c, PH_HEALTH, EV_FAULT);
                }
                c[C_UNCERTAIN] = uncertain(e, m + M_AID, m);
            }
            if (!navk_ins_finite(x)) {
                return stop(c, PH_HEALTH, EV_FAULT);
            }
        /* fall through */
        default: /* PH_HEALTH */
            update_health(c);
            c[C_PHASE] = PH_START;
            return 0;
    }
}
