"""The float32 seam: the one module that decides what a float is.

Every float that outlives a function call lives in a buffer made by `zeros(n)`.

- On the board (MicroPython, stm32 port, single-precision build) a float *is* an IEEE
  float32, every `+ - * /` is one correctly rounded float32 operation, and `sqrt` is the
  FPU's `vsqrt.f32` (correctly rounded). Buffers are `array('f')`.
- On CPython the same names come from the host's NumPy backend (module `f32_host`, put in
  place by `common.firmware_env.install()`): buffers are `numpy.float32` arrays, an
  element read is a `numpy.float32` scalar, and every operation on it rounds to float32
  exactly as the board does. This is the desktop's bit-exact model of the board.
- On the desktop MicroPython VM (double-precision build) buffers still store float32 but
  arithmetic runs in double: that VM proves the code *runs* on MicroPython, not its bits.

Rules for code on top of this seam (docs/requirements.md, float32 contract): no decimal float
literals other than 0.0, 1.0, 2.0, 0.5 (build constants with `ratio` or `from_bits`); convert ints
with `f32()`, never `float()`; no `math` module outside this file; never divide by zero (the
board raises ZeroDivisionError) nor take `sqrt` of a negative (the board raises ValueError).
"""

import sys

if sys.implementation.name == "micropython":
    import struct
    from array import array
    from math import sqrt  # noqa: F401  (re-exported: vsqrt.f32 on the board)

    f32 = float

    def zeros(n):
        """A new float32 buffer of n zeros (allocate at start-up only). Filled from n zero
        bytes through an iterator, not copied from 4n raw ones: the temporary is a quarter
        of the buffer instead of as large (Navigator.mem, 6 kB, failed to find the room for
        twice its size in a fuller heap)."""
        return array("f", memoryview(bytes(n)))

    def view(buf, start, n):
        """Elements start .. start+n-1 of a float32 buffer as a buffer of their own, sharing
        its memory (a kernel's state is one buffer; its parts are views, made at start-up)."""
        return memoryview(buf)[start : start + n]

    def from_bits(u):
        """The float32 whose IEEE-754 bit pattern is the integer u."""
        return struct.unpack("<f", struct.pack("<I", u))[0]

else:
    try:
        from f32_host import f32, from_bits, sqrt, view, zeros  # noqa: F401
    except ImportError:
        raise ImportError(
            "f32: on CPython the firmware needs the NumPy float32 backend; "
            "call common.firmware_env.install() before importing firmware modules"
        ) from None


def ratio(num, den):
    """num / den as one float32 division of two integers exact in float32 (|x| < 2**24)."""
    return f32(num) / f32(den)
