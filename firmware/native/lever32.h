/* The antenna's velocity from the lever arm: the C version of nav_aid.lever_vel, the same
 * operation order. */
#ifndef NAVK_LEVER32_H
#define NAVK_LEVER32_H

#include "layout.h"

/* v[0], v[1] = east, north of C_bn ((w - bg) x l): x the INS state (X_C, X_BG), w the body
 * rate, lv the lever arm in body axes */
static inline void lever_vel_en(float *v, const float *x, const float *w, const float *lv) {
    const float *c = x + X_C;
    float wx = w[0] - x[X_BG];
    float wy = w[1] - x[X_BG + 1];
    float wz = w[2] - x[X_BG + 2];
    float ax = wy * lv[2] - wz * lv[1];
    float ay = wz * lv[0] - wx * lv[2];
    float az = wx * lv[1] - wy * lv[0];
    v[0] = c[0] * ax + c[1] * ay + c[2] * az;
    v[1] = c[3] * ax + c[4] * ay + c[5] * az;
}

#endif
