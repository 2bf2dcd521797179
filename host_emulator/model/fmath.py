"""NumPy float32 model of `firmware/lib/fmath.py`: sin, cos, atan2, asin, elementwise.

Inputs are anything `np.asarray(..., float32)` accepts (atan2 broadcasts y against x); outputs
are float32 arrays of that shape. Every expression repeats the firmware's operations in the
firmware's order, so results are bit-identical. A firmware branch becomes a mask: both sides
are computed for every element and `np.where` keeps the one the firmware would have taken
(the side not taken may divide by zero or see NaN, hence the local `np.errstate`). The
constants and coefficients are the firmware module's own objects.
"""

import functools

import numpy as np

from common import firmware_env

firmware_env.install()
import fmath as fw  # noqa: E402  (the firmware module: one table of constants)

F32 = np.float32
_ONE = F32(1.0)
_HALF = F32(0.5)


def _all_branches(fn):
    """Both sides of every branch are evaluated: silence what the side not taken does."""

    @functools.wraps(fn)
    def wrapper(*args):
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            return fn(*args)

    return wrapper


def _f32(a):
    return np.asarray(a, dtype=F32)


def _sin_poly(z):
    return (fw.S3 * z + fw.S2) * z + fw.S1


def _cos_poly(z):
    return (fw.C3 * z + fw.C2) * z + fw.C1


def _atan_poly(z):
    return (((fw.A5 * z + fw.A4) * z + fw.A3) * z + fw.A2) * z + fw.A1


def _asin_poly(z):
    return ((((fw.B6 * z + fw.B5) * z + fw.B4) * z + fw.B3) * z + fw.B2) * z + fw.B1


def _near_zero(x):
    return (fw.MINUS_QUARTER_PI <= x) & (x <= fw.QUARTER_PI)


@_all_branches
def sin(x):
    x = _f32(x)
    z = x * x
    y_near = _sin_poly(z) * z * x + x
    y_near = np.where(x == 0, x, y_near)  # sin(+-0) = +-0: the firmware returns x itself
    return np.where(_near_zero(x), y_near, _reduced(x, 0))


@_all_branches
def cos(x):
    x = _f32(x)
    z = x * x
    h = _HALF * z
    w = _ONE - h
    y_near = w + (((_ONE - w) - h) + _cos_poly(z) * z * z)
    return np.where(_near_zero(x), y_near, _reduced(x, 1))


def _reduced(x, shift):
    """sin (shift 0) or cos (shift 1) through x = k pi/2 + r + rl; NaN outside |x| <= 8192."""
    inside = (fw.MINUS_SINCOS_MAX <= x) & (x <= fw.SINCOS_MAX)
    x = np.where(inside, x, F32(0.0))  # keep NaN and inf away from the integer conversion
    t = x * fw.TWO_OVER_PI
    k = np.where(x > 0, np.trunc(t + _HALF), np.trunc(t - _HALF)).astype(np.int64)
    fk = k.astype(F32)
    r2 = (x - fk * fw.PIO2_1) - fk * fw.PIO2_2
    tail = fk * fw.PIO2_3
    r_coarse = r2 - tail
    fine = (fw.MINUS_FINE < r_coarse) & (r_coarse < fw.FINE)
    r_fine = ((r2 - fk * fw.PIO2_3A) - fk * fw.PIO2_3B) - fk * fw.PIO2_4
    r = np.where(fine, r_fine, r_coarse)
    rl = np.where(fine, F32(0.0), (r2 - r_coarse) - tail)
    z = r * r
    q = (k + shift) & 3
    h = _HALF * z
    w = _ONE - h
    cos_r = w + ((((_ONE - w) - h) + _cos_poly(z) * z * z) - r * rl)
    sin_r = r + (_sin_poly(z) * z * r + rl)
    y = np.where(q & 1, cos_r, sin_r)
    y = np.where(q & 2, -y, y)
    return np.where(inside, y, fw.NAN)


@_all_branches
def atan2(y, x):
    y, x = np.broadcast_arrays(_f32(y), _f32(x))
    ax = np.where(x < 0, -x, x)  # not np.abs: a -0.0 stays -0.0 as in the firmware
    ay = np.where(y < 0, -y, y)
    finite = (ax <= fw.FLT_MAX) & (ay <= fw.FLT_MAX)
    huge = (ax > fw.HUGE) | (ay > fw.HUGE)
    ax = np.where(huge, ax * _HALF, ax)
    ay = np.where(huge, ay * _HALF, ay)
    below = ay <= ax  # angle within pi/4 of the x axis
    t = np.where(below, ay / ax, ax / ay)
    middle = ~(t <= _HALF)
    v = np.where(middle, (ay - ax) / (ay + ax), t)
    z = v * v
    p = _atan_poly(z) * z * v + v
    zone0 = below & ~middle
    zone2 = ~below & ~middle
    left = x < 0
    a = np.select(
        [left & zone0, left & middle, left & zone2, zone0, middle],
        [
            (fw.PI_LO - p) + fw.PI,
            (fw.THREE_QUARTER_PI_LO - p) + fw.THREE_QUARTER_PI,
            (fw.HALF_PI_LO + p) + fw.HALF_PI,
            p,
            (fw.QUARTER_PI_LO + p) + fw.QUARTER_PI,
        ],
        (fw.HALF_PI_LO - p) + fw.HALF_PI,
    )
    a = np.where(y < 0, -a, a)
    a = np.where(below & (y == 0), np.where(x < 0, fw.PI, y), a)
    return np.where(finite, a, fw.NAN)


@_all_branches
def asin(x):
    x = _f32(x)
    z = x * x
    y_near = _asin_poly(z) * z * x + x
    a = np.where(x < 0, -x, x)
    inside = a <= _ONE
    zf = _HALF * (_ONE - a)
    s = np.sqrt(np.where(inside, zf, F32(0.0)))  # the firmware never takes sqrt(negative)
    p = _asin_poly(zf) * zf * s + s
    r = (fw.HALF_PI_LO - (p + p)) + fw.HALF_PI
    r = np.where(x < 0, -r, r)
    clamped = np.where(x < 0, fw.MINUS_HALF_PI, fw.HALF_PI)
    outside = np.where(a <= fw.FLT_MAX, clamped, fw.NAN)
    y_far = np.where(inside, r, outside)
    split = (fw.MINUS_ASIN_SPLIT <= x) & (x <= fw.ASIN_SPLIT)
    return np.where(split, y_near, y_far)
