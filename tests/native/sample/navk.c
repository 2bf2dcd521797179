#include <stdint.h>

#include "navk.h"

int32_t navk_abi(void) { return SAMPLE_ABI; }

int32_t navk_neg(int32_t x) { return navk_private(-x) - 1; }

float navk_hypot(float x, float y) { return __builtin_sqrtf(x * x + y * y); }

void navk_sqrt_n(float *out, const float *x, int32_t n) {
    for (int32_t i = 0; i < n; i++) {
        out[i] = __builtin_sqrtf(x[i]);
    }
}

void navk_add(float *out, const float *a, const float *b, int32_t n) {
    for (int32_t i = 0; i < n; i++) {
        out[i] = a[i] + b[i];
    }
}

/* two roundings: the product, then the sum (a fused multiply-add would round once) */
void navk_madd(float *out, const float *a, const float *b, const float *c, int32_t n) {
    for (int32_t i = 0; i < n; i++) {
        out[i] = a[i] * b[i] + c[i];
    }
}

float navk_dot(const float *a, const float *b, int32_t n) {
    float s = 0.0f;
    for (int32_t i = 0; i < n; i++) {
        s = s + a[i] * b[i];
    }
    return s;
}

int32_t navk_sum16(const int16_t *h, int32_t n) {
    int32_t s = 0;
    for (int32_t i = 0; i < n; i++) {
        s += h[i];
    }
    return s;
}

void navk_scale16(int16_t *out, const int16_t *h, int32_t k, int32_t n) {
    for (int32_t i = 0; i < n; i++) {
        out[i] = (int16_t)(h[i] * k);
    }
}

int32_t navk_xor(uint8_t *out, const uint8_t *in, int32_t n) {
    int32_t s = 0;
    for (int32_t i = 0; i < n; i++) {
        out[i] = (uint8_t)(in[i] ^ 0x5a);
        s += out[i];
    }
    return s;
}

void navk_icum(int32_t *acc, const int32_t *x, int32_t n) {
    int32_t s = 0;
    for (int32_t i = 0; i < n; i++) {
        s += x[i];
        acc[i] = s;
    }
}

int32_t navk_args12(const float *a, float *b, const int32_t *c, int32_t *d, const int16_t *e,
                    int16_t *f, const uint8_t *g, uint8_t *h, int32_t i, float j, int32_t k,
                    float l) {
    b[0] = a[0] + j;
    d[0] = c[0] + i;
    f[0] = (int16_t)(e[0] + k);
    h[0] = (uint8_t)(g[0] + 1);
    return i + k + (int32_t)l;
}
