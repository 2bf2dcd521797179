/* fmath32: firmware/lib/fmath.py in C, bit for bit (sin, cos, atan2, asin).
 *
 * The method, the accuracy and the handling of NaN, inf, +-0 and |x| > 8192 are documented in
 * fmath.py; this is a line-by-line port. Each constant is built from the same bit pattern as
 * there (F32_BITS; tuning.h, generated from fmath.py), each operation is the same float32
 * operation in the same order, and every intermediate is a float: literals carry the f suffix
 * (an unsuffixed 0.5 is a double and would promote the whole expression). The build must keep
 * that: -ffp-contract=off (no fused multiply-add), no fast-math, no x87 (FLT_EVAL_METHOD 0;
 * x86-64 SSE and the Cortex-M4F's FPU both qualify), no flush-to-zero. sqrt is the correctly rounded __builtin_sqrtf, one
 * instruction with -fno-math-errno.
 *
 * tests/native/test_fmath32.py compares every function with the NumPy model
 * host_emulator/model/fmath.py and with fmath.py itself.
 */
#ifndef FMATH32_H
#define FMATH32_H

#include <stdint.h>

/* The float32 whose IEEE-754 bit pattern is u (fmath.py's from_bits); folded at compile time. */
static inline float f32_from_bits(uint32_t u) {
    union {
        uint32_t u;
        float f;
    } v;
    v.u = u;
    return v.f;
}
#define F32_BITS(u) f32_from_bits(UINT32_C(u))

/* fmath.py's constants, same names with the prefix FM_, and the kernels' other float32
 * constants: generated from the Python (common/native/layout.py) */
#include "tuning.h"

/* Comparisons are written as in fmath.py: a NaN fails every one of them, so it takes the
 * same branch as there (the "not a <= b" forms stay negations). */

/* fmath._reduced: sin x (shift 0) or cos x (shift 1) through x = k pi/2 + r + rl */
static inline float f32__reduced(float x, int32_t shift) {
    if (!(FM_MINUS_SINCOS_MAX <= x && x <= FM_SINCOS_MAX)) {
        return FM_NAN;
    }
    float t = x * FM_TWO_OVER_PI;
    /* Python's int() truncates toward zero, as the C conversion does; |k| <= 5215 */
    int32_t k;
    if (x > 0.0f) {
        k = (int32_t)(t + 0.5f);
    } else {
        k = (int32_t)(t - 0.5f);
    }
    float fk = (float)k; /* exact */
    float r2 = (x - fk * FM_PIO2_1) - fk * FM_PIO2_2;
    float tail = fk * FM_PIO2_3;
    float r = r2 - tail;
    float rl;
    if (FM_MINUS_FINE < r && r < FM_FINE) {
        r = ((r2 - fk * FM_PIO2_3A) - fk * FM_PIO2_3B) - fk * FM_PIO2_4;
        rl = 0.0f;
    } else {
        rl = (r2 - r) - tail;
    }
    float z = r * r;
    /* Python's & on a negative int acts on its two's complement (-1 & 3 == 3): the unsigned
     * conversion (modulo 2**32) gives the same low bits, without C's signed corner cases. */
    uint32_t q = ((uint32_t)k + (uint32_t)shift) & 3u;
    float y;
    if (q & 1u) {
        float h = 0.5f * z;
        float w = 1.0f - h;
        y = w + ((((1.0f - w) - h) + ((FM_C3 * z + FM_C2) * z + FM_C1) * z * z) - r * rl);
    } else {
        y = r + (((FM_S3 * z + FM_S2) * z + FM_S1) * z * r + rl);
    }
    if (q & 2u) {
        return -y;
    }
    return y;
}

/* sin x for |x| <= 8192, NaN beyond and for non-finite x */
static inline float f32_sin(float x) {
    if (FM_MINUS_QUARTER_PI <= x && x <= FM_QUARTER_PI) {
        if (x == 0.0f) {
            return x; /* keeps -0 */
        }
        float z = x * x;
        return ((FM_S3 * z + FM_S2) * z + FM_S1) * z * x + x;
    }
    return f32__reduced(x, 0);
}

/* cos x for |x| <= 8192, NaN beyond and for non-finite x */
static inline float f32_cos(float x) {
    if (FM_MINUS_QUARTER_PI <= x && x <= FM_QUARTER_PI) {
        float z = x * x;
        float h = 0.5f * z;
        float w = 1.0f - h;
        return w + (((1.0f - w) - h) + ((FM_C3 * z + FM_C2) * z + FM_C1) * z * z);
    }
    return f32__reduced(x, 1);
}

/* Angle of the vector (x, y) in [-pi, pi]; zeros and NaN as in fmath.atan2 */
static inline float f32_atan2(float y, float x) {
    /* not fabsf, as in fmath.py: a -0 stays -0 (the result would be the same, but the port
     * keeps fmath.py's intermediate values) */
    float ax = x;
    if (x < 0.0f) {
        ax = -x;
    }
    float ay = y;
    if (y < 0.0f) {
        ay = -y;
    }
    if (!(ax <= FM_FLT_MAX && ay <= FM_FLT_MAX)) {
        return FM_NAN;
    }
    if (ax > FM_HUGE || ay > FM_HUGE) {
        ax = ax * 0.5f;
        ay = ay * 0.5f;
    }
    int32_t zone;
    float v;
    if (ay <= ax) {
        if (y == 0.0f) {
            if (x < 0.0f) {
                return FM_PI;
            }
            return y;
        }
        float t = ay / ax;
        if (t <= 0.5f) {
            zone = 0; /* atan t */
            v = t;
        } else {
            zone = 1; /* pi/4 + atan v */
            v = (ay - ax) / (ay + ax);
        }
    } else {
        float t = ax / ay;
        if (t <= 0.5f) {
            zone = 2; /* pi/2 - atan t */
            v = t;
        } else {
            zone = 1;
            v = (ay - ax) / (ay + ax);
        }
    }
    float z = v * v;
    float p = ((((FM_A5 * z + FM_A4) * z + FM_A3) * z + FM_A2) * z + FM_A1) * z * v + v;
    float a;
    if (x < 0.0f) {
        if (zone == 0) {
            a = (FM_PI_LO - p) + FM_PI;
        } else if (zone == 1) {
            a = (FM_THREE_QUARTER_PI_LO - p) + FM_THREE_QUARTER_PI;
        } else {
            a = (FM_HALF_PI_LO + p) + FM_HALF_PI;
        }
    } else if (zone == 0) {
        a = p;
    } else if (zone == 1) {
        a = (FM_QUARTER_PI_LO + p) + FM_QUARTER_PI;
    } else {
        a = (FM_HALF_PI_LO - p) + FM_HALF_PI;
    }
    if (y < 0.0f) {
        return -a;
    }
    return a;
}

/* asin x for |x| <= 1; finite |x| > 1 clamps to +-pi/2, NaN and +-inf give NaN */
static inline float f32_asin(float x) {
    if (FM_MINUS_ASIN_SPLIT <= x && x <= FM_ASIN_SPLIT) {
        float z = x * x;
        return (((((FM_B6 * z + FM_B5) * z + FM_B4) * z + FM_B3) * z + FM_B2) * z + FM_B1) * z * x
            + x;
    }
    float a = x;
    if (x < 0.0f) {
        a = -x;
    }
    if (!(a <= 1.0f)) {
        if (a <= FM_FLT_MAX) {
            if (x < 0.0f) {
                return FM_MINUS_HALF_PI;
            }
            return FM_HALF_PI;
        }
        return FM_NAN;
    }
    float z = 0.5f * (1.0f - a); /* exact */
    float s = __builtin_sqrtf(z);
    float p = (((((FM_B6 * z + FM_B5) * z + FM_B4) * z + FM_B3) * z + FM_B2) * z + FM_B1) * z * s
        + s;
    float r = (FM_HALF_PI_LO - (p + p)) + FM_HALF_PI;
    if (x < 0.0f) {
        return -r;
    }
    return r;
}

/* fmath.wrap: a (within 3 pi of 0) into -pi..pi by one turn */
static inline float f32_wrap(float a) {
    if (a > FM_PI) {
        return a - FM_TWO_PI;
    }
    if (a < -FM_PI) {
        return a + FM_TWO_PI;
    }
    return a;
}

#endif /* FMATH32_H */
