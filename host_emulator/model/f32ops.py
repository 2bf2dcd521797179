"""Float32 helpers shared by the NumPy models of ins.py, eskf.py, nav.py and its mixins.

How those models stay bit-exact with the firmware:
- every value is a `numpy.float32` scalar or array; Python floats only meet float32 operands
  (NumPy 2 turns `0.5 * x` into one float32 operation, like the board);
- elementwise array operations round each element exactly as the firmware's scalar statement,
  so a statement repeated over i = 0, 1, 2 becomes one vector expression; sums keep the
  firmware's left-to-right grouping, written out term by term (`mat_vec`, `cross`), never `@`
  (BLAS sums in blocks and may fuse multiply-adds);
- sums that start from `0.0` in the firmware start from a float32 zero here (0.0 + -0.0 = +0.0);
- sin, cos, atan2, asin, quaternions and the geodetic series come from the bit-exact models
  fmath.py, rot.py and geo.py; constants are the firmware modules' own objects.
"""

import numpy as np

F32 = np.float32
ZERO = F32(0.0)
HALF = F32(0.5)
ONE = F32(1.0)
TWO = F32(2.0)


def ratio(num, den):
    """num / den as one float32 division (the firmware's f32.ratio)."""
    return F32(num) / F32(den)


def vec(*xs):
    return np.array(xs, dtype=F32)


def cross(a, b):
    """a x b, component k = a_i b_j - a_j b_i as the firmware writes each cross product."""
    return vec(a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def mat_vec(c, x):
    """C x for a 3x3 C, every row summed left to right: (c_i0 x0 + c_i1 x1) + c_i2 x2."""
    return (c[:, 0] * x[0] + c[:, 1] * x[1]) + c[:, 2] * x[2]


def sum_left(xs):
    """x0 + x1 + ... evaluated left to right."""
    s = xs[0]
    for x in xs[1:]:
        s = s + x
    return s
