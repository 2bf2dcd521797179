/* The strapdown step of firmware/lib/ins.py (its `_step_py` is the reference, line by line). */
#include <stdint.h>

#include "layout.h"
#include "navk.h"
#include "rot32.h"
#include "tuning.h"


/* v[i] += dv + a[i] dt; p[i] += (v_old + v_new) dt/2, Kahan-compensated. */
static inline void advance(float *x, int i, float dv) {
    float v0 = x[X_V + i];
    float v1 = v0 + dv + x[X_AN + i] * x[X_DT];
    x[X_V + i] = v1;
    float y = (v0 + v1) * x[X_HDT] - x[X_PK + i];
    float p0 = x[X_P + i];
    float t = p0 + y;
    x[X_PK + i] = (t - p0) - y;
    x[X_P + i] = t;
}

void navk_ins_step(float *x, const float *w_b, const float *f_b, int32_t coning) {
    float dt = x[X_DT];
    float tx = (w_b[0] - x[X_BG]) * dt;
    float ty = (w_b[1] - x[X_BG + 1]) * dt;
    float tz = (w_b[2] - x[X_BG + 2]) * dt;
    float dx = (f_b[0] - x[X_BA]) * dt;
    float dy = (f_b[1] - x[X_BA + 1]) * dt;
    float dz = (f_b[2] - x[X_BA + 2]) * dt;
    if (coning) {
        float px = x[X_THP], py = x[X_THP + 1], pz = x[X_THP + 2];
        float qx = x[X_DVP], qy = x[X_DVP + 1], qz = x[X_DVP + 2];
        x[X_THP] = tx;
        x[X_THP + 1] = ty;
        x[X_THP + 2] = tz;
        x[X_DVP] = dx;
        x[X_DVP + 1] = dy;
        x[X_DVP + 2] = dz;
        float sx = ((py * dz - pz * dy) + (qy * tz - qz * ty)) * TWELFTH;
        float sy = ((pz * dx - px * dz) + (qz * tx - qx * tz)) * TWELFTH;
        float sz = ((px * dy - py * dx) + (qx * ty - qy * tx)) * TWELFTH;
        float cx = (py * tz - pz * ty) * TWELFTH;
        float cy = (pz * tx - px * tz) * TWELFTH;
        float cz = (px * ty - py * tx) * TWELFTH;
        tx = tx + cx;
        ty = ty + cy;
        tz = tz + cz;
        dx = dx + sx;
        dy = dy + sy;
        dz = dz + sz;
    }
    float ux = dx + (ty * dz - tz * dy) * 0.5f;
    float uy = dy + (tz * dx - tx * dz) * 0.5f;
    float uz = dz + (tx * dy - ty * dx) * 0.5f;
    const float *c = x + X_C;
    float ex = c[0] * ux + c[1] * uy + c[2] * uz;
    float ey = c[3] * ux + c[4] * uy + c[5] * uz;
    float ez = c[6] * ux + c[7] * uy + c[8] * uz;
    x[X_DVS] = x[X_DVS] + ex;
    x[X_DVS + 1] = x[X_DVS + 1] + ey;
    x[X_DVS + 2] = x[X_DVS + 2] + ez;
    x[X_TH] = tx;
    x[X_TH + 1] = ty;
    x[X_TH + 2] = tz;
    rot_q_update(x + X_Q, x + X_TH);
    rot_q_to_dcm(x + X_C, x + X_Q);
    advance(x, 0, ex);
    advance(x, 1, ey);
    advance(x, 2, ez);
}
