/* A whole navigator tick in one call: Navigator._tick and its callees (firmware/lib/nav.py,
 * the reference: _still_update, _navigate, _schedule, _inject, _update_health), with the
 * control state in the int buffer c (C_*), the floats in m (Navigator.mem, M_*) and the float
 * work in the other kernels. Few arguments on purpose: see nav.py's self.mem.
 *
 * What stays in Python returns an event (EV_*) with c[C_PHASE] saying where the tick resumes:
 * the app runs the event's method (a fix's screening, with re-anchoring or the start of
 * navigation, a reset: once a second at most) and calls again with the same arguments. The
 * filter's jobs start here, their rows included (aid.c). The order
 * of every step is the reference's, so a tick's results are the same bit for bit. */
#include <stdint.h>

#include "fmath32.h"
#include "layout.h"
#include "navk.h"
#include "rot32.h"

#define MIN_LEVEL_F (49.0f / 10.0f) /* nav_align.MIN_LEVEL_F, m/s^2 */

#define PH_START 0 /* a new tick */
#define PH_SCHEDULE 1 /* after a fix was screened (EV_FIX) */
#define PH_CHECK 2 /* after a reset to GNSS (EV_RESET) */
#define PH_HEALTH 3 /* after alignment or a fault reset (EV_ALIGN, EV_FAULT) */

/* _update_health */
static void update_health(int32_t *c) {
    int32_t t = c[C_TICK];
    if (t < c[C_FAULT_UNTIL]) {
        c[C_HEALTH] = 2;
    } else if (t < c[C_SAT_UNTIL] || t < c[C_GATED_UNTIL]) {
        c[C_HEALTH] = 1;
    } else if (c[C_STATE] == NAVIGATING && t - c[C_ACCEPT_TICK] > c[C_T_TIMEOUT]) {
        c[C_HEALTH] = 1;
    } else {
        c[C_HEALTH] = 0;
    }
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

/* _start_queued_fix and nav_aid._start_gnss_update: the GNSS update of the queued fix,
 * against the state at its measurement time (the delay ring holds the last RING ticks) */
static void start_queued_fix(int32_t *c, int32_t *ki, float *m) {
    c[C_FIX_QUEUED] = 0;
    int32_t age = c[C_TICK] - c[C_FIX_TICK];
    if (age < 0) {
        age = 0;
    } else if (age > RING - 1) {
        age = RING - 1;
    }
    c[C_JOB] = JOB_GNSS;
    c[C_UPDATES] += 1;
    c[C_USED_TICK] = c[C_FIX_TICK];
    navk_gnss_rows(m + M_E, ki, m + M_X, m + M_RING_P, m + M_RING_V, m + M_CORR, m + M_GP,
        m + M_FX, m + M_US, m + M_W, m + M_AID, ((c[C_TICK] - age) % RING) * 3);
}

/* _schedule (the filter is idle): start the next job, if one is due */
static void schedule(int32_t *c, int32_t *ki, float *m) {
    float *x = m + M_X;
    float *e = m + M_E;
    int32_t overdue = c[C_SINCE_PROP] >= 2 * c[C_T_PROP];
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

/* _inject (dx is ready): 1 when the rejects call for a reset to GNSS */
static int32_t inject(int32_t *c, int32_t *ki, float *x, float *e, float *corr) {
    navk_inject(x, e, corr);
    ki[I_READY] = 0;
    int32_t job = c[C_JOB];
    c[C_JOB] = JOB_NONE;
    if (job != JOB_GNSS) {
        return 0;
    }
    int32_t mask = ki[I_GATE_MASK];
    if (mask & 3) {
        c[C_REJECTS] += 1;
        c[C_GATED_UNTIL] = c[C_TICK] + c[C_T_SECOND];
        return c[C_REJECTS] >= c[C_RESET_AFTER];
    }
    c[C_REJECTS] = 0;
    c[C_ACCEPT_TICK] = c[C_TICK];
    if (mask) {
        c[C_GATED_UNTIL] = c[C_TICK] + c[C_T_SECOND];
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
            int32_t finite = navk_imu_cal(w, f, gyro, accel, m + M_CAL, c[C_CAL_FLAGS]);
            c[C_TICK] += 1;
            if (c[C_SAT]) {
                c[C_SAT_UNTIL] = c[C_TICK] + c[C_T_SECOND];
            }
            if (!finite) {
                c[C_FAULT_UNTIL] = c[C_TICK] + c[C_T_SECOND];
                update_health(c);
                return 0;
            }
            if ((c[C_TICK] & 3) == 0) {
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
            if (ki[I_READY] && inject(c, ki, x, e, corr)) {
                return stop(c, PH_CHECK, EV_RESET);
            }
        /* fall through */
        case PH_CHECK:
            /* P changes only when a job finishes: check it then, not every tick */
            if ((c[C_BUSY] && ki[I_JOB] == IDLE && !navk_eskf_diagonal_ok(e))
                || !navk_ins_finite(x)) {
                return stop(c, PH_HEALTH, EV_FAULT);
            }
        /* fall through */
        default: /* PH_HEALTH */
            update_health(c);
            c[C_PHASE] = PH_START;
            return 0;
    }
}
