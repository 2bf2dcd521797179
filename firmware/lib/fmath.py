"""Deterministic float32 sin, cos, atan2 and asin: the same bits on the board and the desktop.

The board's libm (newlib/musl, compiled with fused multiply-add) and the desktop's differ in
the last bit, so the navigation core never calls `math`. These functions use only float32
`+ - * /` and the correctly rounded `sqrt` of the seam, in a fixed order, so the board, the
desktop's NumPy float32 backend and the vectorised model `host_emulator/model/fmath.py`
(which repeats every operation below) agree bit for bit.

Method
- sin, cos: x = k pi/2 + r with k the integer nearest to x 2/pi and |r| <= ~pi/4
  (Cody-Waite reduction). pi/2 is split into parts of 8 and 11 significant bits, whose
  products with any |k| < 2**13 are exact, and a rounded tail; the rounding error of the last
  subtraction is carried on as `rl`. When |r| < 2**-11 the tail is redone with two more exact
  11-bit parts, so results next to a multiple of pi/2 keep their relative accuracy. Then an
  odd (sin) or even (cos) polynomial in r, chosen by the quadrant k mod 4. |x| <= pi/4 skips
  the reduction.
- atan2: with t = min(|y|, |x|) / max(|y|, |x|) <= 1, t <= 1/2 uses atan t, t > 1/2 uses
  pi/4 + atan((|y| - |x|) / (|y| + |x|)) (that difference is exact); then pi/2 - a, pi - a
  and the sign of y place the angle. The constant added last is split hi + lo.
- asin: |x| <= 9/16 is an odd polynomial; above, asin|x| = pi/2 - 2 asin(sqrt((1 - |x|) / 2)).
- Polynomials: minimax fits of the relative error on the interval used (Lawson's algorithm;
  `python -m host_emulator.bench.float32 --fit` re-derives them), rounded to float32.

Accuracy: the largest error seen, in float32 ulps of the exact value (ulp = float32 spacing
at the exact result, 2**-149 at the least, so near zero the error is still relative),
measured on the model by `python -m host_emulator.bench.float32`. sin, cos and asin:
every float32 input in the domain. atan2: every float32 t in [2**-8, 2**8] as (t, +-1), and
40 million random (y, x) with magnitudes from 2**-149 to 2**128 in all four quadrants (the
largest seen, 1.853, is stated with a small margin since atan2 was sampled). sin and cos are
faithful (< 1 ulp: the result is one of the two float32 around the exact value).

| function | domain | max error (ulp) |
|---|---|---|
| sin | [-pi, pi] | 0.826 |
| sin | [-8192, 8192] | 0.999 |
| cos | [-pi, pi] | 0.837 |
| cos | [-8192, 8192] | 0.993 |
| atan2 | all finite (y, x) | 1.86 |
| asin | [-1, 1] | 1.391 |

Outside the domain nothing raises and nothing divides by zero. sin and cos give NaN for
|x| > 8192 and for non-finite x. atan2 gives NaN if either argument is non-finite;
atan2(+-0, x >= 0) = +-0 (y itself, also for x = -0) and atan2(+-0, x < 0) = +pi (the sign
of a zero y cannot be read without dividing by it). asin clamps a finite |x| > 1 to +-pi/2
(rounding can push a direction-cosine entry just past 1) and gives NaN for NaN and +-inf.
Symmetries hold bit for bit: sin(-x) = -sin x (so sin(-0) = -0), cos(-x) = cos x,
asin(-x) = -asin x, atan2(-y, x) = -atan2(y, x) for y != 0.

Cost: float boxes allocated per call, one per float operation on the path (nothing else is
allocated; the tests count them in the MicroPython VM). sin 8 and cos 13 for |x| <= pi/4;
otherwise 20 (sin polynomial) or 26 (cos polynomial), +1 if negated, +4 within 2**-11 of a
multiple of pi/2. atan2 13 to 18 for x, y >= 0 (18 when t > 1/2), up to 3 more otherwise.
asin 14 for |x| <= 9/16, else 19 (+2 if x < 0).
"""

from f32 import f32, from_bits, ratio, sqrt  # noqa: F401  (sqrt is re-exported)

PI = from_bits(0x40490FDB)  # 3.14159274, pi rounded to nearest
HALF_PI = from_bits(0x3FC90FDB)  # 1.57079637
TWO_PI = from_bits(0x40C90FDB)  # 6.28318548
QUARTER_PI = from_bits(0x3F490FDB)  # 0.785398185

# Negative bounds are constants too: a unary minus would allocate a float at every call.
MINUS_QUARTER_PI = from_bits(0xBF490FDB)  # -0.785398185
MINUS_HALF_PI = from_bits(0xBFC90FDB)  # -1.57079637

# Low parts: value = hi + lo to ~2**-48 relative.
PI_LO = from_bits(0xB3BBBD2E)  # -8.74227766e-08
HALF_PI_LO = from_bits(0xB33BBD2E)  # -4.37113883e-08
QUARTER_PI_LO = from_bits(0xB2BBBD2E)  # -2.18556941e-08
THREE_QUARTER_PI = from_bits(0x4016CBE4)  # 2.3561945
THREE_QUARTER_PI_LO = from_bits(0xB1CCDE2E)  # -5.96244032e-09

NAN = from_bits(0x7FC00000)  # quiet NaN
FLT_MAX = from_bits(0x7F7FFFFF)  # 3.40282347e+38
HUGE = from_bits(0x7E800000)  # 2**126 = 8.50705917e+37

# sin/cos range reduction: pi/2 = PIO2_1 + PIO2_2 + PIO2_3, and more finely
# pi/2 = PIO2_1 + PIO2_2 + PIO2_3A + PIO2_3B + PIO2_4. Parts 1 (8 significant bits),
# 2, 3A and 3B (11 bits each) times any integer |k| < 2**13 are exact float32 products.
SINCOS_MAX = from_bits(0x46000000)  # 8192.0: |k| <= 5215
MINUS_SINCOS_MAX = from_bits(0xC6000000)  # -8192.0
TWO_OVER_PI = from_bits(0x3F22F983)  # 0.636619747
PIO2_1 = from_bits(0x3FC90000)  # 1.5703125
PIO2_2 = from_bits(0x39FDA000)  # 0.000483751297
PIO2_3 = from_bits(0x33A22169)  # 7.54979013e-08 (rounded tail)
PIO2_3A = from_bits(0x33A22000)  # 7.54953362e-08
PIO2_3B = from_bits(0x2C346000)  # 2.56328292e-12
PIO2_4 = from_bits(0x248D3132)  # 6.12323426e-17 (rounded tail)
FINE = from_bits(0x3A000000)  # 2**-11 = 0.00048828125: below, redo the tail finely
MINUS_FINE = from_bits(0xBA000000)  # -0.00048828125

# sin r = r + r z (S1 + z (S2 + z S3)), z = r*r, |r| <= 0.7875
S1 = from_bits(0xBE2AAAA2)  # -0.166666538
S2 = from_bits(0x3C088390)  # 0.00833214819
S3 = from_bits(0xB94C9D40)  # -0.000195135362
# cos r = 1 - z/2 + z z (C1 + z (C2 + z C3)), |r| <= 0.7875
C1 = from_bits(0x3D2AAAA5)  # 0.0416666456
C2 = from_bits(0xBAB6060B)  # -0.0013887299
C3 = from_bits(0x37CCF185)  # 2.44311614e-05
# atan v = v + v z (A1 + z (A2 + ... + z A5)), |v| <= 1/2
A1 = from_bits(0xBEAAAA89)  # -0.33333233
A2 = from_bits(0x3E4CBDAA)  # 0.199942261
A3 = from_bits(0xBE1126F0)  # -0.141750097
A4 = from_bits(0x3DD013B8)  # 0.101600111
A5 = from_bits(0xBD523B1B)  # -0.0513258986
# asin v = v + v z (B1 + z (B2 + ... + z B6)), |v| <= 9/16
B1 = from_bits(0x3E2AAA93)  # 0.166666314
B2 = from_bits(0x3D99A4AE)  # 0.0750211328
B3 = from_bits(0x3D352AD1)  # 0.044230286
B4 = from_bits(0x3D0B5A0F)  # 0.0340214334
B5 = from_bits(0x3BDC06A5)  # 0.00671465928
B6 = from_bits(0x3D429B89)  # 0.0475116111
ASIN_SPLIT = ratio(9, 16)  # 0.5625
MINUS_ASIN_SPLIT = ratio(-9, 16)  # -0.5625


def isfinite(x):
    """True unless x is NaN or +-inf."""
    return x - x == 0.0


def sin(x):
    """sin x for |x| <= 8192 (NaN beyond and for non-finite x)."""
    if MINUS_QUARTER_PI <= x <= QUARTER_PI:
        if x == 0.0:
            return x  # the polynomial would turn -0 into +0
        z = x * x
        return ((S3 * z + S2) * z + S1) * z * x + x
    return _reduced(x, 0)


def cos(x):
    """cos x for |x| <= 8192 (NaN beyond and for non-finite x)."""
    if MINUS_QUARTER_PI <= x <= QUARTER_PI:
        z = x * x
        h = 0.5 * z
        w = 1.0 - h
        # w + ((1 - w) - h) is 1 - z/2 with w's rounding error put back
        return w + (((1.0 - w) - h) + ((C3 * z + C2) * z + C1) * z * z)
    return _reduced(x, 1)


def _reduced(x, shift):
    """sin x (shift 0) or cos x = sin(x + pi/2) (shift 1) through x = k pi/2 + r + rl."""
    if not MINUS_SINCOS_MAX <= x <= SINCOS_MAX:
        return NAN
    t = x * TWO_OVER_PI
    if x > 0.0:
        k = int(t + 0.5)
    else:
        k = int(t - 0.5)
    fk = f32(k)
    r2 = (x - fk * PIO2_1) - fk * PIO2_2  # exact
    tail = fk * PIO2_3
    r = r2 - tail
    if MINUS_FINE < r < FINE:
        # r has lost its leading bits: continue with exact parts, round once at the end
        r = ((r2 - fk * PIO2_3A) - fk * PIO2_3B) - fk * PIO2_4
        rl = 0.0
    else:
        rl = (r2 - r) - tail  # what the rounding of r2 - tail lost
    z = r * r
    q = (k + shift) & 3
    if q & 1:
        # cos(r + rl) = cos r - r rl
        h = 0.5 * z
        w = 1.0 - h
        y = w + ((((1.0 - w) - h) + ((C3 * z + C2) * z + C1) * z * z) - r * rl)
    else:
        # sin(r + rl) = sin r + rl
        y = r + (((S3 * z + S2) * z + S1) * z * r + rl)
    if q & 2:
        return -y
    return y


def atan2(y, x):
    """Angle of the vector (x, y) in [-pi, pi] (see the module notes for zeros and NaN)."""
    ax = x
    if x < 0.0:
        ax = -x
    ay = y
    if y < 0.0:
        ay = -y
    if not (ax <= FLT_MAX and ay <= FLT_MAX):
        return NAN
    if ax > HUGE or ay > HUGE:
        # keeps ay + ax <= FLT_MAX. Halving is exact unless the smaller one is denormal,
        # and then the quotient is below 2**-250: its angle rounds to 0 (or pi) anyway.
        ax = ax * 0.5
        ay = ay * 0.5
    if ay <= ax:
        if y == 0.0:
            # y is +-0 (so is x if ax is 0): +-0 ahead, pi behind; no division by zero.
            # (Not ay: after the scaling above a tiny y may have become 0 but keeps its sign.)
            if x < 0.0:
                return PI
            return y
        t = ay / ax
        if t <= 0.5:
            zone = 0  # angle = atan t
            v = t
        else:
            zone = 1  # angle = pi/4 + atan v
            v = (ay - ax) / (ay + ax)
    else:
        t = ax / ay
        if t <= 0.5:
            zone = 2  # angle = pi/2 - atan t
            v = t
        else:
            zone = 1
            v = (ay - ax) / (ay + ax)
    z = v * v
    p = ((((A5 * z + A4) * z + A3) * z + A2) * z + A1) * z * v + v
    if x < 0.0:
        # second quadrant: pi - angle
        if zone == 0:
            a = (PI_LO - p) + PI
        elif zone == 1:
            a = (THREE_QUARTER_PI_LO - p) + THREE_QUARTER_PI
        else:
            a = (HALF_PI_LO + p) + HALF_PI
    elif zone == 0:
        a = p
    elif zone == 1:
        a = (QUARTER_PI_LO + p) + QUARTER_PI
    else:
        a = (HALF_PI_LO - p) + HALF_PI
    if y < 0.0:
        return -a
    return a


def asin(x):
    """asin x for |x| <= 1; finite |x| > 1 is clamped to +-pi/2, NaN and +-inf give NaN."""
    if MINUS_ASIN_SPLIT <= x <= ASIN_SPLIT:
        z = x * x
        return (((((B6 * z + B5) * z + B4) * z + B3) * z + B2) * z + B1) * z * x + x
    a = x
    if x < 0.0:
        a = -x
    if not a <= 1.0:
        if a <= FLT_MAX:
            if x < 0.0:
                return MINUS_HALF_PI
            return HALF_PI
        return NAN
    z = 0.5 * (1.0 - a)  # exact
    s = sqrt(z)
    p = (((((B6 * z + B5) * z + B4) * z + B3) * z + B2) * z + B1) * z * s + s
    r = (HALF_PI_LO - (p + p)) + HALF_PI
    if x < 0.0:
        return -r
    return r


def wrap(a):
    """a (within 3 pi of 0) into -pi..pi by one turn: the angle differences the heading code
    forms (nav_align, yaw_gsf; fmath32.h's f32_wrap is its native twin)."""
    if a > PI:
        return a - TWO_PI
    if a < -PI:
        return a + TWO_PI
    return a
