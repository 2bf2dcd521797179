/* The filter's time-distributed work of firmware/lib/eskf.py (the methods _phi_apply,
 * _propagation_slice, _update_slice, _clamp_diagonal, work and diagonal_ok are the reference,
 * line by line). e: the float buffer Eskf.e, ii: the int buffer Eskf.i (layout.h). */
#include <stdint.h>

#include "layout.h"
#include "navk.h"

/* u = Phi x for x = src[0:15] (F's five non-zero blocks, see eskf.py). */
static void phi_apply(float *e, const int32_t *ii, const float *x) {
    const float *s = e + E_S;
    float t = s[S_T];
    const float *f = e + E_FN;
    const float *c = e + E_C;
    float f0 = f[0], f1 = f[1], f2 = f[2];
    float dv0 = (f1 * x[8] - f2 * x[7]) + (c[0] * x[12] + c[1] * x[13] + c[2] * x[14]);
    float dv1 = (f2 * x[6] - f0 * x[8]) + (c[3] * x[12] + c[4] * x[13] + c[5] * x[14]);
    float dv2 = (f0 * x[7] - f1 * x[6]) + (c[6] * x[12] + c[7] * x[13] + c[8] * x[14]);
    float da0 = c[0] * x[9] + c[1] * x[10] + c[2] * x[11];
    float da1 = c[3] * x[9] + c[4] * x[10] + c[5] * x[11];
    float da2 = c[6] * x[9] + c[7] * x[10] + c[8] * x[11];
    if (ii[I_EARTH]) {
        float w1 = e[E_W + 1], w2 = e[E_W + 2];
        dv0 = dv0 - 2.0f * (w1 * x[5] - w2 * x[4]);
        dv1 = dv1 - 2.0f * (w2 * x[3]);
        dv2 = dv2 + 2.0f * (w1 * x[3]);
        da0 = da0 + (w1 * x[8] - w2 * x[7]);
        da1 = da1 + w2 * x[6];
        da2 = da2 - w1 * x[6];
    }
    float *u = e + E_U;
    u[0] = x[0] + t * x[3];
    u[1] = x[1] + t * x[4];
    u[2] = x[2] + t * x[5];
    u[3] = x[3] + t * dv0;
    u[4] = x[4] + t * dv1;
    u[5] = x[5] + t * dv2;
    u[6] = x[6] - t * da0;
    u[7] = x[7] - t * da1;
    u[8] = x[8] - t * da2;
    float g = s[S_DECAY_G];
    float a = s[S_DECAY_A];
    u[9] = g * x[9];
    u[10] = g * x[10];
    u[11] = g * x[11];
    u[12] = a * x[12];
    u[13] = a * x[13];
    u[14] = a * x[14];
}

static void clamp_diagonal(float *e) {
    float *p = e + E_P;
    const float *lo = e + E_LO;
    const float *hi = e + E_HI;
    for (int i = 0; i < N; i++) {
        float d = p[i * (N + 1)];
        if (d < lo[i]) {
            p[i * (N + 1)] = lo[i];
        } else if (d > hi[i]) {
            float g = __builtin_sqrtf(hi[i] / d);
            for (int j = 0; j < N; j++) {
                p[i * N + j] = p[i * N + j] * g;
                p[j * N + i] = p[j * N + i] * g;
            }
        }
    }
}

static void propagation_slice(float *e, int32_t *ii) {
    int32_t st = ii[I_STEP];
    const float *u = e + E_U;
    if (st < N) {
        phi_apply(e, ii, e + E_P + st * N);
        float *a = e + E_A;
        for (int k = 0; k < N; k++) {
            a[k * N + st] = u[k];
        }
    } else if (st < 2 * N) {
        int i = st - N;
        phi_apply(e, ii, e + E_A + i * N);
        float *p = e + E_P;
        for (int j = i; j < N; j++) {
            float x = u[j];
            p[i * N + j] = x;
            p[j * N + i] = x;
        }
    } else {
        float t = e[E_S + S_T];
        float *p = e + E_P;
        const float *q = e + E_Q;
        for (int i = 0; i < N; i++) {
            int d = i * (N + 1);
            p[d] = p[d] + q[i] * t;
        }
        clamp_diagonal(e);
        ii[I_JOB] = IDLE;
    }
    ii[I_STEP] = st + 1;
}

static void update_slice(float *e, int32_t *ii) {
    int32_t m = ii[I_M];
    if (m >= ii[I_NSCAL]) {
        clamp_diagonal(e);
        ii[I_NSCAL] = 0;
        ii[I_JOB] = IDLE;
        ii[I_READY] = 1;
        return;
    }
    int32_t st = ii[I_STEP];
    const float *h = e + E_H + m * N;
    const int32_t *nz = ii + I_NZ + m * MAX_NZ;
    int32_t nnz = ii[I_NNZ + m];
    float *p = e + E_P;
    float *v = e + E_V;
    if (st < 3) {
        for (int i = 5 * st; i < 5 * st + 5; i++) {
            float acc = 0.0f;
            for (int t = 0; t < nnz; t++) {
                int k = nz[t];
                acc = acc + p[i * N + k] * h[k];
            }
            v[i] = acc;
        }
        ii[I_STEP] = st + 1;
        return;
    }
    float *s = e + E_S;
    float *kg = e + E_K;
    if (st == 3) {
        float hv = 0.0f;
        float hx = 0.0f;
        float *dx = e + E_DX;
        for (int t = 0; t < nnz; t++) {
            int k = nz[t];
            float hk = h[k];
            hv = hv + hk * v[k];
            hx = hx + hk * dx[k];
        }
        float sv = hv + e[E_R + m];
        float y = e[E_Z + m] - hx;
        e[E_Z + m] = y; /* from here on: the innovation and its variance (nav's bias watch) */
        e[E_R + m] = sv;
        if (!(sv > 0.0f) || y * y > s[S_GATE2] * sv) {
            ii[I_REJECTED] += 1;
            ii[I_GATE_MASK] |= 1 << m;
            ii[I_M] = m + 1;
            ii[I_STEP] = 0;
            return;
        }
        s[S_S] = sv;
        s[S_Y] = y;
        for (int i = 0; i < N; i++) {
            float ki = v[i] / sv;
            kg[i] = ki;
            dx[i] = dx[i] + ki * y;
        }
        ii[I_ACCEPTED] += 1;
        ii[I_STEP] = 4;
        return;
    }
    /* Joseph form, row i, upper triangle: P - K v^T - v K^T + S K K^T */
    int i = st - 4;
    float ki = kg[i];
    float vi = v[i];
    float ski = s[S_S] * ki;
    for (int j = i; j < N; j++) {
        float kj = kg[j];
        float x = ((p[i * N + j] - ki * v[j]) - vi * kj) + ski * kj;
        p[i * N + j] = x;
        p[j * N + i] = x;
    }
    if (i == N - 1) {
        ii[I_M] = m + 1;
        ii[I_STEP] = 0;
    } else {
        ii[I_STEP] = st + 1;
    }
}

void navk_eskf_work(float *e, int32_t *ii, int32_t n) {
    while (n > 0 && ii[I_JOB] != IDLE) {
        if (ii[I_JOB] == PROPAGATING) {
            propagation_slice(e, ii);
        } else {
            update_slice(e, ii);
        }
        n -= 1;
    }
}

int32_t navk_eskf_diagonal_ok(const float *e) {
    for (int i = 0; i < N; i++) {
        float d = e[E_P + i * (N + 1)];
        if (!(d > 0.0f) || d - d != 0.0f) {
            return 0;
        }
    }
    return 1;
}
