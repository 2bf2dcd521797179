/* The navigator's per-tick float work (firmware/lib/nav.py, the reference: _calibrate with
 * _apply_cal, _still_update, the delay ring and finiteness check of _navigate, _inject). */
#include <stdint.h>

#include "layout.h"
#include "navk.h"
#include "rot32.h"

/* nav._apply_cal: out = m (x - b0), or x - b0 without a matrix. */
static void apply_cal(float *out, const float *x, const float *b0, const float *m) {
    float x0 = x[0] - b0[0];
    float x1 = x[1] - b0[1];
    float x2 = x[2] - b0[2];
    if (m == 0) {
        out[0] = x0;
        out[1] = x1;
        out[2] = x2;
    } else {
        out[0] = m[0] * x0 + m[1] * x1 + m[2] * x2;
        out[1] = m[3] * x0 + m[4] * x1 + m[5] * x2;
        out[2] = m[6] * x0 + m[7] * x1 + m[8] * x2;
    }
}

int32_t navk_imu_cal(float *w, float *f, const int16_t *gyro, const int16_t *accel,
    const float *cal, int32_t flags) {
    float wr[3], fr[3];
    for (int i = 0; i < 3; i++) {
        wr[i] = (float)gyro[i] / cal[CAL_G];
        fr[i] = (float)accel[i] / cal[CAL_A];
    }
    apply_cal(w, wr, cal + CAL_GB, (flags & CAL_HAS_GM) ? cal + CAL_GM : 0);
    apply_cal(f, fr, cal + CAL_AB, (flags & CAL_HAS_AM) ? cal + CAL_AM : 0);
    float s = w[0] + w[1] + w[2] + f[0] + f[1] + f[2];
    return s - s == 0.0f;
}

int32_t navk_still(float *st, const float *f, const float *w, const float *x, const float *prm,
    int32_t flags) {
    float alpha = prm[STP_ALPHA];
    if (flags & STILL_FIRST) {
        for (int i = 0; i < 3; i++) {
            st[ST_FX + i] = f[i];
        }
    }
    float var = 0.0f;
    for (int i = 0; i < 3; i++) {
        float lp = st[ST_FX + i];
        float d = f[i] - lp;
        st[ST_FX + i] = lp + alpha * d;
        var = var + d * d;
    }
    st[ST_VAR] = st[ST_VAR] + alpha * (var - st[ST_VAR]);
    float wx = w[0] - x[X_BG];
    float wy = w[1] - x[X_BG + 1];
    float wz = w[2] - x[X_BG + 2];
    st[ST_GYRO] = st[ST_GYRO] + alpha * ((wx * wx + wy * wy + wz * wz) - st[ST_GYRO]);
    float ga = prm[STP_GYRO];
    float aa = prm[STP_ACCEL];
    int32_t quiet = st[ST_VAR] < aa * aa && st[ST_GYRO] < ga * ga;
    if (quiet) {
        if (flags & STILL_GNSS_SPEED) {
            if (st[ST_SPEED] > prm[STP_GNSS_SPEED]) {
                quiet = 0;
            }
        } else if (flags & STILL_NAVIGATING) {
            float lim = prm[STP_MAX_SPEED];
            if (x[X_V] * x[X_V] + x[X_V + 1] * x[X_V + 1] > lim * lim) {
                quiet = 0;
            }
        }
    }
    return quiet;
}

void navk_ring_put(float *ring_p, float *ring_v, const float *x, const float *corr, int32_t b) {
    for (int i = 0; i < 3; i++) {
        ring_p[b + i] = x[X_P + i] - corr[i];
        ring_v[b + i] = x[X_V + i] - corr[3 + i];
    }
}

int32_t navk_ins_finite(const float *x) {
    float s = x[X_P] + x[X_P + 1] + x[X_P + 2] + x[X_V] + x[X_V + 1] + x[X_V + 2] + x[X_Q];
    return s - s == 0.0f;
}

void navk_inject(float *x, float *e, float *corr) {
    float *dx = e + E_DX;
    float att[3];
    for (int i = 0; i < 3; i++) {
        float d = dx[IX_POS + i];
        x[X_P + i] = x[X_P + i] - d;
        corr[i] = corr[i] - d;
        d = dx[IX_VEL + i];
        x[X_V + i] = x[X_V + i] - d;
        corr[3 + i] = corr[3 + i] - d;
        x[X_BG + i] = x[X_BG + i] + dx[IX_BG + i];
        x[X_BA + i] = x[X_BA + i] + dx[IX_BA + i];
        att[i] = dx[IX_ATT + i];
    }
    float dq[4], q[4];
    rot_q_from_rotvec(dq, att);
    for (int i = 0; i < 4; i++) {
        q[i] = x[X_Q + i];
    }
    rot_q_mul(x + X_Q, dq, q);
    rot_q_normalize(x + X_Q);
    rot_q_to_dcm(x + X_C, x + X_Q);
    for (int i = 0; i < N; i++) {
        dx[i] = 0.0f;
    }
}

void navk_euler(float *ypr, const float *c_bn) {
    rot_dcm_to_euler(ypr, c_bn);
}
