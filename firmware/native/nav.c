/* The navigator's per-tick float work (firmware/lib/nav.py, the reference: _calibrate with
 * _apply_cal, _still_update, the delay ring and finiteness check of _navigate, _inject). */
#include <stdint.h>

#include "layout.h"
#include "navk.h"
#include "rot32.h"
#include "tuning.h"


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

/* nav_kern.fix_in: the receiver's integers as the fix's floats. */
void navk_fix_in(float *fx, const int32_t *fi, const float *aid) {
    fx[FX_SIG_V] = 0.0f;
    if (fi[FI_ALT_MM] == FI_NO_HEIGHT) { /* no height: gnss_rows holds v_U instead */
        fx[FX_H] = 0.0f;
        fx[FX_SIG_V] = -1.0f;
    } else {
        fx[FX_H] = (float)fi[FI_ALT_MM] / 1000.0f;
    }
    fx[FX_HDOP] = fi[FI_HDOP_X100] >= 0 ? (float)fi[FI_HDOP_X100] / 100.0f : aid[AID_HDOP_MAX];
    fx[FX_SPEED] = -1.0f;
    fx[FX_COURSE] = -1.0f;
    if (fi[FI_SPEED_MM_S] >= 0) {
        fx[FX_SPEED] = (float)fi[FI_SPEED_MM_S] / 1000.0f;
        if (fi[FI_COURSE_CDEG] >= 0) {
            fx[FX_COURSE] = (float)fi[FI_COURSE_CDEG] * RAD_PER_CDEG;
        }
    }
    fx[FX_SIG_H] = 0.0f;
}

/* Navigator._fix_usable: fix_check's bits when the quality is acceptable (any HDOP while a
 * drift is held), and the tick of a usable fix's speed */
int32_t navk_fix_usable(int32_t *c, float *m) {
    if (c[C_FIX_QUALITY] < c[C_MIN_QUALITY]) {
        return 0;
    }
    int32_t any_hdop = c[C_TICK] < c[C_DRIFT_UNTIL];
    int32_t r = navk_fix_check(m + M_ST, m + M_FX, m + M_X, m + M_AID, m + M_E + E_P, any_hdop);
    if (r & FC_SPEED) {
        c[C_SPEED_TICK] = c[C_TICK];
    }
    return r;
}

/* Navigator.gnss_fix: the fix in fi (FI_*) into the pending fix (m[M_FX], c[C_FIX_*]), its
 * measurement tick from fi or, when unknown (< 0), the arrival less the latency, less the
 * lag of the position behind its stamp (_take_fix) */
void navk_gnss_fix(int32_t *c, float *m, const int32_t *fi) {
    navk_fix_in(m + M_FX, fi, m + M_AID);
    c[C_FIX_LAT] = fi[FI_LAT_E7];
    c[C_FIX_LON_DEG] = fi[FI_LON_DEG];
    c[C_FIX_LON_FRAC] = fi[FI_LON_FRAC];
    c[C_FIX_QUALITY] = fi[FI_QUALITY];
    if (fi[FI_QUALITY] < 0) { /* the app dropped an epoch with an impossible field */
        c[C_DATA_UNTIL] = c[C_TICK] + c[C_T_SECOND];
    }
    int32_t fix_tick = fi[FI_TICK];
    if (fix_tick < 0) {
        fix_tick = c[C_TICK] - c[C_T_LATENCY];
    }
    c[C_FIX_TICK] = fix_tick - c[C_T_STAMP_LAG];
    c[C_FIX_PENDING] = 1;
}

/* nav_kern.fix_check: FC_* bits of a fix whose quality is acceptable (any HDOP: any_hdop). */
int32_t navk_fix_check(float *st, const float *fx, const float *x, const float *aid,
                       const float *p, int32_t any_hdop) {
    if (!any_hdop && !(fx[FX_HDOP] <= aid[AID_HDOP_MAX])) {
        return 0;
    }
    int32_t r = FC_USABLE;
    float sp = fx[FX_SPEED];
    if (sp >= 0.0f) {
        st[ST_SPEED] = sp;
        r |= FC_SPEED;
        if (sp >= aid[AID_HEADING_V]) {
            r |= FC_FAST;
        }
    }
    if (fx[FX_COURSE] >= 0.0f) {
        r |= FC_COURSE;
    }
    float lim = aid[AID_REANCHOR];
    if (x[X_P] > lim || x[X_P] < -lim || x[X_P + 1] > lim || x[X_P + 1] < -lim) {
        r |= FC_REANCHOR;
    }
    /* moving: beyond 1 m/s and 3 sigma of the horizontal velocity (P's diagonal); a receiver
     * that says it stands (a known speed, a NaN is not) is not frozen */
    float v2 = x[X_V] * x[X_V] + x[X_V + 1] * x[X_V + 1];
    int k = (N + 1) * IX_VEL;
    if (v2 > FROZEN_V2 && v2 > FROZEN_K2 * (p[k] + p[k + N + 1])) {
        if (!(sp >= 0.0f && sp * sp <= FROZEN_V2)) {
            r |= FC_MOVING;
        }
    }
    return r;
}

/* geo._enu_py: ENU metres of an integer offset d_e7 (lat, lon) from the origin, at the height
 * h[0]. */
void navk_geo_enu(float *enu, const float *coef, const float *h, const int32_t *d_e7) {
    const float *c = coef;
    float dh = h[0] - c[GEO_H0];
    float n1 = (float)d_e7[0] * c[GEO_KN];
    float e1 = (float)d_e7[1] * c[GEO_KE];
    float ee = e1 * e1;
    float nn = n1 * n1;
    enu[0] = e1 + e1 * (dh * c[GEO_INV_RN] - n1 * c[GEO_GE_N]);
    enu[1] = n1 + (n1 * (n1 * c[GEO_GN_N] + dh * c[GEO_INV_RM]) + ee * c[GEO_GN_E]);
    enu[2] = dh - (nn * c[GEO_GU_N] + ee * c[GEO_GU_E]);
}

/* geo._coef_py: the coefficients of the origin at lat0_e7 and the height c[GEO_H0] */
void navk_geo_coef(float *c, int32_t lat0_e7) {
    const float a_m = 6378137.0f; /* geo.A_M */
    const float e2 = F32_BITS(0x3BDB5C88); /* geo.E2 */
    const float rad_per_e7 = F32_BITS(0x30EFE050); /* geo.RAD_PER_E7 */
    float phi0 = (float)lat0_e7 * rad_per_e7;
    float s = f32_sin(phi0);
    float co = f32_cos(phi0);
    float w2 = 1.0f - e2 * s * s;
    float rn = a_m / __builtin_sqrtf(w2);
    float rm = rn * (1.0f - e2) / w2;
    float drm = 3.0f * rm * e2 * s * co / w2;
    float h0 = c[GEO_H0];
    float rn_h = rn + h0;
    float rm_h = rm + h0;
    float tan = s / co;
    c[GEO_KE] = rad_per_e7 * rn_h * co;
    c[GEO_KN] = rad_per_e7 * rm_h;
    c[GEO_GE_N] = rm * tan / (rm_h * rn_h);
    c[GEO_INV_RN] = 1.0f / rn_h;
    c[GEO_GN_N] = 0.5f * drm / (rm_h * rm_h);
    c[GEO_INV_RM] = 1.0f / rm_h;
    c[GEO_GN_E] = 0.5f * tan / rn_h;
    c[GEO_GU_N] = 0.5f / rm_h;
    c[GEO_GU_E] = 0.5f / rn_h;
    c[GEO_SIN_LAT] = s;
    c[GEO_COS_LAT] = co;
}

/* drivers/bmi055._decode_py: both dies' data registers into int16 counts; the over-range
 * mask (bits 0-2 gyro, 3-5 accel) and the accel new_data bits (6-8). */
int32_t navk_bmi055_decode(int16_t *gyro, int16_t *accel, const uint8_t *raw_gyro,
    const uint8_t *raw_accel) {
    int32_t m = 0;
    for (int i = 0; i < 3; i++) {
        int32_t v = raw_gyro[2 * i] | (raw_gyro[2 * i + 1] << 8);
        if (v >= 0x8000) {
            v -= 0x10000;
        }
        gyro[i] = (int16_t)v;
        if (v >= BMI055_GYRO_SAT_HI || v <= BMI055_GYRO_SAT_LO) {
            m |= 1 << i;
        }
        int32_t lsb = raw_accel[2 * i];
        int32_t a = ((raw_accel[2 * i + 1] << 8) | lsb) >> 4;
        if (a >= 0x800) {
            a -= 0x1000;
        }
        accel[i] = (int16_t)a;
        if (a >= BMI055_ACCEL_SAT_HI || a <= BMI055_ACCEL_SAT_LO) {
            m |= 1 << (i + 3);
        }
        m |= (lsb & 1) << (i + 6);
    }
    return m;
}
