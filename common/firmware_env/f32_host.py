"""NumPy backend of the firmware's float32 seam (`firmware/lib/f32.py`) on CPython.

Buffers are `numpy.float32` arrays, so reading an element yields a `numpy.float32` scalar and
every Python operator on it is one float32 operation rounded exactly as on the board (NumPy 2
scalar promotion: a Python int or float operand is converted to float32, as on the board).
`sqrt` is IEEE correctly rounded on both sides. Failures the board raises are raised here too:
`sqrt` of a negative raises ValueError like MicroPython's math.sqrt, and `install()` in
`firmware_env` makes float division by zero raise (FloatingPointError here, ZeroDivisionError
on the board).
"""

import numpy as np

f32 = np.float32


def zeros(n):
    """A new float32 buffer of n zeros."""
    return np.zeros(n, dtype=np.float32)


def view(buf, start, n):
    """Elements start .. start+n-1 of a float32 buffer, sharing its memory."""
    return buf[start : start + n]


def from_bits(u):
    """The float32 whose IEEE-754 bit pattern is the integer u."""
    return np.array(u, dtype=np.uint32).view(np.float32)[()]


def sqrt(x):
    """Correctly rounded float32 square root; ValueError below zero as on the board."""
    x = np.float32(x)
    if x < 0:
        raise ValueError("math domain error")
    return np.sqrt(x)
