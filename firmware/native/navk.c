/* navk kernels: float32 work of the firmware over caller buffers, in the operation order of
 * the Python reference kernels (firmware/lib) and the NumPy model. Compiled with
 * -ffp-contract=off and without fast-math: every + - * / is one rounded float32 operation. */
#include <stdint.h>

#include "layout.h"
#include "navk.h"

/* Every build keeps each float operation as written (docs/requirements.md, float32 contract rule 7): -ffast-math or
 * -Ofast (also when slipped in through CFLAGS) would let the compiler reorder them, so they stop
 * the build here. Fused multiply-adds are checked in the objects (tests/native). */
#ifdef __FAST_MATH__
#error "navk must not be compiled with -ffast-math or -Ofast"
#endif

/* kern.ABI (layout.h NAVK_ABI), bumped whenever a kernel's signature or a buffer layout
 * changes: firmware/lib/kern.py refuses a module built from another version. */
int32_t navk_abi(void) { return NAVK_ABI; }

void navk_add(float *out, const float *a, const float *b, int32_t n) {
    for (int32_t i = 0; i < n; i++) {
        out[i] = a[i] + b[i];
    }
}

/* ---- fmath32 (vectorised, for the exhaustive tests) ---- */
/* firmware/lib/fmath.py's functions over buffers, bit for bit (tests/native/test_fmath32.py);
 * the host's only (navk.h) */
#ifndef NAVK_NATMOD
#include "fmath32.h"

void navk_sin_n(float *out, const float *x, int32_t n) {
    for (int32_t i = 0; i < n; i++) {
        out[i] = f32_sin(x[i]);
    }
}

void navk_cos_n(float *out, const float *x, int32_t n) {
    for (int32_t i = 0; i < n; i++) {
        out[i] = f32_cos(x[i]);
    }
}

void navk_asin_n(float *out, const float *x, int32_t n) {
    for (int32_t i = 0; i < n; i++) {
        out[i] = f32_asin(x[i]);
    }
}

void navk_atan2_n(float *out, const float *y, const float *x, int32_t n) {
    for (int32_t i = 0; i < n; i++) {
        out[i] = f32_atan2(y[i], x[i]);
    }
}
#endif
