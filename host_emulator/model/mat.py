"""NumPy float32 model of `firmware/lib/mat.py` (its `copy` and `mul`), vectorised over leading
(batch) axes.

Matrices are stacked as (..., m, n) and batch axes broadcast; vectors as (..., n). Inputs must
already be float32 (a float64 array would silently change the arithmetic, so it is refused).
Each function returns new arrays instead of writing an `out` buffer, and repeats the
firmware's operation order element by element, so the results are bit-identical:
sums start from 0.0 and add one rounded product per step in increasing index order (never
`@`, whose BLAS kernels sum in blocks and may fuse multiply-adds).
"""

import numpy as np

F32 = np.float32


def _f32(x):
    x = np.asarray(x)
    if x.dtype != F32:
        raise TypeError(f"float32 required, got {x.dtype}")
    return x


def copy(a):
    return _f32(a).copy()


def mul(a, b):
    """a (..., m, n) times b (..., n, p), summed over k in order."""
    a, b = _f32(a), _f32(b)
    out = np.zeros(np.broadcast_shapes(a.shape[:-1], b.shape[:-2] + (1,)) + b.shape[-1:], F32)
    for k in range(a.shape[-1]):
        out = out + a[..., :, k, None] * b[..., None, k, :]
    return out
