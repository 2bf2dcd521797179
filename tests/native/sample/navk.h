/* A sample of navk.h (tests/native): one kernel of every argument and result type the
 * bindings generator takes, every wrapper shape (0 to 3 arguments, and more), a square root
 * and a multiply-add (the two things the float flags decide). Built by the tests into their
 * own directories, never into build/native's real module. */
#include <stdint.h>

#define SAMPLE_ABI 7

int32_t navk_abi(void);
int32_t navk_neg(int32_t x);
float navk_hypot(float x, float y);
void navk_sqrt_n(float *out, const float *x, int32_t n);
void navk_add(float *out, const float *a, const float *b, int32_t n);
void navk_madd(float *out, const float *a, const float *b, const float *c, int32_t n);
float navk_dot(const float *a, const float *b, int32_t n);
int32_t navk_sum16(const int16_t *h, int32_t n);
void navk_scale16(int16_t *out, const int16_t *h, int32_t k, int32_t n);
int32_t navk_xor(uint8_t *out, const uint8_t *in, int32_t n);
void navk_icum(int32_t *acc, const int32_t *x, int32_t n);
int32_t navk_args12(const float *a, float *b, const int32_t *c, int32_t *d, const int16_t *e,
                    int16_t *f, const uint8_t *g, uint8_t *h, int32_t i, float j, int32_t k,
                    float l);

/* not exported: static */
static inline int32_t navk_private(int32_t x) { return x + 1; }
