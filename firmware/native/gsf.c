/* The yaw estimator's bank: the native gsf_accum and gsf_step, the mirrors of
 * firmware/lib/yaw_gsf.py (its docstrings say what and why), operation for operation. */
#include <stdint.h>

#include "fmath32.h"
#include "layout.h"
#include "navk.h"
#include "tuning.h"

static float exp_neg(float y) {
    if (!(y < GSF_EXP_CUT)) {
        return 0.0f;
    }
    float t = y * GSF_SIXTYFOURTH;
    float p = 1.0f + t * (1.0f + t * (0.5f + t * (GSF_SIXTH + t * GSF_TWENTYFOURTH)));
    float r = 1.0f / p;
    for (int i = 0; i < 6; i++) {
        r = r * r;
    }
    return r;
}

void navk_gsf_accum(float *m) {
    float *g = m + M_GSF;
    const float *x = m + M_X;
    const float *f = m + M_F;
    const float *c = x + X_C;
    float dt = x[X_DT];
    float fx = f[0] - x[X_BA];
    float fy = f[1] - x[X_BA + 1];
    float fz = f[2] - x[X_BA + 2];
    float de = (c[0] * fx + c[1] * fy + c[2] * fz) * dt;
    float dn = (c[3] * fx + c[4] * fy + c[5] * fz) * dt;
    g[G_A1] = g[G_A1] + de;
    g[G_A1 + 1] = g[G_A1 + 1] + dn;
    g[G_A2] = g[G_A2] + g[G_A1] * dt;
    g[G_A2 + 1] = g[G_A2 + 1] + g[G_A1 + 1] * dt;
    g[G_T] = g[G_T] + dt;
}

static float sigma_h(const float *m) {
    float s = m[M_FX + FX_SIG_H];
    if (!(s > 0.0f)) {
        s = m[M_FX + FX_HDOP] * m[M_AID + AID_UERE];
    }
    if (s < m[M_AID + AID_FLOOR]) {
        s = m[M_AID + AID_FLOOR];
    }
    return s;
}

static void spread(float *m, float pp, float vv) {
    float *g = m + M_GSF;
    float dy = FM_TWO_PI / (float)GSF_N;
    float yv = dy * 0.5f;
    yv = yv * yv;
    float w = 1.0f / (float)GSF_N;
    for (int k = 0; k < GSF_N; k++) {
        float *h = g + G_HYP + k * NH;
        for (int i = 0; i < NH; i++) {
            h[i] = 0.0f;
        }
        h[0] = m[M_GP];
        h[1] = m[M_GP + 1];
        h[4] = ((float)k + 0.5f) * dy - FM_PI;
        float *p = h + H_P;
        p[0] = pp;
        p[8] = pp;
        p[16] = vv;
        p[24] = vv;
        p[32] = yv;
        p[40] = GSF_B0_VAR;
        p[48] = GSF_B0_VAR;
        h[H_W] = w;
    }
}

static void init(float *m, float sh) {
    float sp = m[M_FX + FX_SPEED];
    float vv = GSF_V0_VAR;
    if (sp > 0.0f) {
        vv = vv + sp * sp;
    }
    spread(m, sh * sh, vv);
}

static void init_chord(float *m, float sh) {
    float *g = m + M_GSF;
    float t = g[G_T];
    float *h0 = g + G_HYP;
    float ve = (m[M_GP] - h0[0]) / t;
    float vn = (m[M_GP + 1] - h0[1]) / t;
    float de = g[G_A1] - g[G_A2] / t;
    float dn = g[G_A1 + 1] - g[G_A2 + 1] / t;
    float r = sh * sh;
    spread(m, r, 0.0f);
    float yv = h0[H_P + 32];
    float vv = (r + r) / (t * t) + (de * de + dn * dn) * yv + GSF_B0_VAR * (t * t) * 0.5f +
        GSF_V0_CHORD_VAR;
    float pv = r / t;
    for (int k = 0; k < GSF_N; k++) {
        float *h = g + G_HYP + k * NH;
        float s = f32_sin(h[4]);
        float c = f32_cos(h[4]);
        h[2] = ve + (c * de - s * dn);
        h[3] = vn + (s * de + c * dn);
        float *p = h + H_P;
        p[2] = pv;
        p[14] = pv;
        p[10] = pv;
        p[22] = pv;
        p[16] = vv;
        p[24] = vv;
    }
}

static void predict(float *g, float *h, float t, float dyaw) {
    float y = f32_wrap(h[4] - dyaw);
    h[4] = y;
    float s = f32_sin(y);
    float c = f32_cos(y);
    float h2 = t * t * 0.5f;
    float u1e = g[G_A1] - h[5] * t;
    float u1n = g[G_A1 + 1] - h[6] * t;
    float u2e = g[G_A2] - h[5] * h2;
    float u2n = g[G_A2 + 1] - h[6] * h2;
    float r1e = c * u1e - s * u1n;
    float r1n = s * u1e + c * u1n;
    float r2e = c * u2e - s * u2n;
    float r2n = s * u2e + c * u2n;
    h[0] = h[0] + h[2] * t + r2e;
    h[1] = h[1] + h[3] * t + r2n;
    h[2] = h[2] + r1e;
    h[3] = h[3] + r1n;
    float ch = c * h2;
    float sh = s * h2;
    float ct = c * t;
    float st = s * t;
    float *fp = g + G_FP;
    float *p = h + H_P;
    for (int j = 0; j < NST; j++) {
        float b5 = p[35 + j];
        float b6 = p[42 + j];
        fp[j] = p[j] + t * p[14 + j] - r2n * p[28 + j] - ch * b5 + sh * b6;
        fp[7 + j] = p[7 + j] + t * p[21 + j] + r2e * p[28 + j] - sh * b5 - ch * b6;
        fp[14 + j] = p[14 + j] - r1n * p[28 + j] - ct * b5 + st * b6;
        fp[21 + j] = p[21 + j] + r1e * p[28 + j] - st * b5 - ct * b6;
        fp[28 + j] = p[28 + j];
        fp[35 + j] = b5;
        fp[42 + j] = b6;
    }
    for (int i = 0; i < NST; i++) {
        const float *r = fp + 7 * i;
        float *o = p + 7 * i;
        float b5 = r[5];
        float b6 = r[6];
        o[0] = r[0] + t * r[2] - r2n * r[4] - ch * b5 + sh * b6;
        o[1] = r[1] + t * r[3] + r2e * r[4] - sh * b5 - ch * b6;
        o[2] = r[2] - r1n * r[4] - ct * b5 + st * b6;
        o[3] = r[3] + r1e * r[4] - st * b5 - ct * b6;
        o[4] = r[4];
        o[5] = b5;
        o[6] = b6;
    }
    float qa = g[G_QA];
    float t2 = t * t;
    float qp = qa * (t2 * t) * GSF_THIRD;
    float qx = qa * t2 * 0.5f;
    float qv = qa * t;
    for (int i = 0; i < 2; i++) {
        float *d = p + 8 * i;
        d[0] = d[0] + qp;
        d[2] = d[2] + qx;
        d[14] = d[14] + qx;
        d[16] = d[16] + qv;
    }
    p[32] = p[32] + g[G_QW] * t;
    float qb = g[G_QB] * t;
    p[40] = p[40] + qb;
    p[48] = p[48] + qb;
}

static float update(float *g, float *h, int32_t i, float a, float z, float r) {
    float *p = h + H_P;
    float *ph = g + G_PH;
    int32_t i2 = i < 2 ? i + 2 : i;
    for (int j = 0; j < NST; j++) {
        ph[j] = p[7 * j + i] + a * p[7 * j + i2];
    }
    float s = ph[i] + a * ph[i2] + r;
    float y = z - (h[i] + a * h[i2]);
    for (int j = 0; j < NST; j++) {
        float k = ph[j] / s;
        h[j] = h[j] + k * y;
        for (int q = j; q < NST; q++) {
            float v = p[7 * j + q] - k * ph[q];
            p[7 * j + q] = v;
            p[7 * q + j] = v;
        }
    }
    g[G_FP] = s;
    return y * y / s;
}

static void bank(const int32_t *c, float *m, float rp) {
    float *g = m + M_GSF;
    float t = g[G_T];
    float dyaw = f32_wrap(g[G_DYAW]);
    float age = (float)(c[C_TICK] - c[C_FIX_TICK]) * m[M_X + X_DT];
    if (age < 0.0f) {
        age = 0.0f;
    }
    float sp = m[M_FX + FX_SPEED];
    float co = m[M_FX + FX_COURSE];
    float rv = g[G_RV];
    for (int k = 0; k < GSF_N; k++) {
        float *h = g + G_HYP + k * NH;
        predict(g, h, t, dyaw);
        float d = update(g, h, 0, -age, m[M_GP], rp);
        float sp2 = g[G_FP];
        d = d + update(g, h, 1, -age, m[M_GP + 1], rp);
        sp2 = sp2 * g[G_FP];
        if (sp >= 0.0f && co >= 0.0f) {
            d = d + update(g, h, 2, 0.0f, sp * f32_sin(co), rv);
            sp2 = sp2 * g[G_FP];
            d = d + update(g, h, 3, 0.0f, sp * f32_cos(co), rv);
            sp2 = sp2 * g[G_FP];
        }
        h[4] = f32_wrap(h[4]);
        g[G_D + k] = d;
        g[G_S + k] = sp2;
    }
    float dmin = g[G_D];
    for (int k = 1; k < GSF_N; k++) {
        if (g[G_D + k] < dmin) {
            dmin = g[G_D + k];
        }
    }
    float total = 0.0f;
    for (int k = 0; k < GSF_N; k++) {
        float *h = g + G_HYP + k * NH;
        float w = h[H_W] * exp_neg((g[G_D + k] - dmin) * 0.5f) / __builtin_sqrtf(g[G_S + k]);
        h[H_W] = w;
        total = total + w;
    }
    for (int k = 0; k < GSF_N; k++) {
        float *h = g + G_HYP + k * NH;
        float w = total > 0.0f ? h[H_W] / total : 1.0f / (float)GSF_N;
        if (w < GSF_W_MIN) {
            w = GSF_W_MIN;
        }
        h[H_W] = w;
    }
}

static int32_t result(const int32_t *c, float *m) {
    float *g = m + M_GSF;
    float se = 0.0f;
    float ce = 0.0f;
    float ve = 0.0f;
    float vn = 0.0f;
    float be = 0.0f;
    float bn = 0.0f;
    for (int k = 0; k < GSF_N; k++) {
        const float *h = g + G_HYP + k * NH;
        float w = h[H_W];
        se = se + w * f32_sin(h[4]);
        ce = ce + w * f32_cos(h[4]);
        ve = ve + w * h[2];
        vn = vn + w * h[3];
        be = be + w * h[5];
        bn = bn + w * h[6];
    }
    float y = f32_atan2(se, ce);
    float var = 0.0f;
    for (int k = 0; k < GSF_N; k++) {
        const float *h = g + G_HYP + k * NH;
        float d = f32_wrap(h[4] - y);
        var = var + h[H_W] * (d * d + h[H_P + 32]);
    }
    g[G_YAW] = y;
    g[G_VAR] = var;
    g[G_V] = ve;
    g[G_V + 1] = vn;
    g[G_B] = be;
    g[G_B + 1] = bn;
    if (!(var < g[G_READY])) {
        return 0;
    }
    if (!(m[M_FX + FX_SPEED] >= 0.0f && m[M_FX + FX_COURSE] >= 0.0f)) {
        if (c[C_STATE] == NAVIGATING || !(var * GSF_FOUR < g[G_READY])) {
            return 0;
        }
    }
    int32_t r = GSF_READY;
    if (c[C_STATE] == NAVIGATING) {
        float y2 = y * y;
        if (y2 > GSF_NINE * (var + m[P_YAW]) && y2 > g[G_RMIN]) {
            r = r | GSF_DISAGREES;
            if (m[M_CN + CN_MH] > GSF_INNOV_BAD) {
                r = r | GSF_NAV_BAD;
            }
        }
    }
    return r;
}

int32_t navk_gsf_step(int32_t *c, float *m) {
    float *g = m + M_GSF;
    float sh = sigma_h(m);
    int32_t st = c[C_GSF];
    if (st == GSF_HELD && g[G_T] > 0.0f) {
        init_chord(m, sh);
        c[C_GSF] = GSF_ON;
    } else if (st == GSF_ON) {
        bank(c, m, sh * sh);
    } else if (m[M_FX + FX_SPEED] >= 0.0f) {
        init(m, sh);
        c[C_GSF] = GSF_ON;
    } else {
        g[G_HYP] = m[M_GP];
        g[G_HYP + 1] = m[M_GP + 1];
        c[C_GSF] = GSF_HELD;
    }
    for (int i = 0; i < 6; i++) {
        g[i] = 0.0f;
    }
    if (c[C_GSF] != GSF_ON) {
        return 0;
    }
    return result(c, m);
}
