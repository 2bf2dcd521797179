"""NumPy float32 model of `firmware/lib/mat.py`, vectorised over leading (batch) axes.

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


def zero(shape):
    return np.zeros(shape, dtype=F32)


def identity(n, batch=()):
    return np.broadcast_to(np.eye(n, dtype=F32), (*batch, n, n)).copy()


def copy(a):
    return _f32(a).copy()


def add(a, b):
    return _f32(a) + _f32(b)


def sub(a, b):
    return _f32(a) - _f32(b)


def scale(a, s):
    """a * s; s is a float32 scalar or one per batch element (shape a.shape[:-2])."""
    a, s = _f32(a), _f32(s)
    return a * s[..., None, None]


def add_scaled(a, s, b):
    """a + s * b; s as in `scale`."""
    a, s, b = _f32(a), _f32(s), _f32(b)
    return a + s[..., None, None] * b


def add_diag(a, d):
    """a (..., n, n) with d (..., n) added to the diagonal."""
    a, d = _f32(a), _f32(d)
    n = a.shape[-1]
    out = np.array(np.broadcast_to(a, np.broadcast_shapes(a.shape, d.shape[:-1] + (n, n))))
    i = np.arange(n)
    out[..., i, i] = out[..., i, i] + d
    return out


def dot(a, b):
    """Sum over the last axis: s = 0; s = s + a[..., i] * b[..., i]."""
    a, b = _f32(a), _f32(b)
    s = np.zeros(np.broadcast_shapes(a.shape[:-1], b.shape[:-1]), dtype=F32)
    for i in range(a.shape[-1]):
        s = s + a[..., i] * b[..., i]
    return s


def transpose(a):
    return np.swapaxes(_f32(a), -1, -2).copy()


def mul(a, b):
    """a (..., m, n) times b (..., n, p), summed over k in order."""
    a, b = _f32(a), _f32(b)
    out = np.zeros(np.broadcast_shapes(a.shape[:-1], b.shape[:-2] + (1,)) + b.shape[-1:], F32)
    for k in range(a.shape[-1]):
        out = out + a[..., :, k, None] * b[..., None, k, :]
    return out


def mul_at(a, b):
    """a^T b with a (..., n, m), b (..., n, p): out[i, j] = sum_k a[k, i] * b[k, j]."""
    a, b = _f32(a), _f32(b)
    out = np.zeros(
        np.broadcast_shapes(a.shape[:-2], b.shape[:-2]) + a.shape[-1:] + b.shape[-1:], F32
    )
    for k in range(a.shape[-2]):
        out = out + a[..., k, :, None] * b[..., None, k, :]
    return out


def mul_bt(a, b):
    """a b^T with a (..., m, n), b (..., p, n): out[i, j] = sum_k a[i, k] * b[j, k]."""
    a, b = _f32(a), _f32(b)
    out = np.zeros(
        np.broadcast_shapes(a.shape[:-2], b.shape[:-2]) + a.shape[-2:-1] + b.shape[-2:-1], F32
    )
    for k in range(a.shape[-1]):
        out = out + a[..., :, k, None] * b[..., None, :, k]
    return out


def symmetrize(a):
    """For i > j: a[i, j] = a[j, i] = (a[i, j] + a[j, i]) * 0.5 (lower + upper); diagonal kept."""
    a = _f32(a)
    n = a.shape[-1]
    at = np.swapaxes(a, -1, -2)
    low = (a + at) * F32(0.5)  # at (i, j) with i > j: a[i, j] + a[j, i], the firmware's order
    i, j = np.indices((n, n))
    return np.where(i > j, low, np.where(i < j, np.swapaxes(low, -1, -2), a))


def cholesky(a):
    """(L, ok): the firmware's lower factor and success flag per batch element.

    Column by column here, row by row in the firmware: every element sees the same sequence
    of operations (s = a[i, j]; s = s - L[i, k] * L[j, k] for k < j; then / L[j, j] or sqrt),
    so the values agree bit for bit. The firmware stops at the first pivot that is not > 0;
    every earlier pivot is the same here, so `ok` (all pivots > 0, NaN failing) agrees too.
    Only the lower triangle of a is read. L of a failed batch element is NaN (the firmware
    leaves its buffer partly written).
    """
    a = _f32(a)
    n = a.shape[-1]
    L = np.zeros(a.shape, dtype=F32)
    ok = np.ones(a.shape[:-2], dtype=bool)
    with np.errstate(all="ignore"):
        for j in range(n):
            s = a[..., j, j]
            for k in range(j):
                s = s - L[..., j, k] * L[..., j, k]
            ok &= s > 0
            d = np.sqrt(np.where(ok, s, F32(1.0)))
            L[..., j, j] = d
            s = a[..., j + 1 :, j]
            for k in range(j):
                s = s - L[..., j + 1 :, k] * L[..., j, k, None]
            L[..., j + 1 :, j] = s / d[..., None]
    L[~ok] = np.nan
    return L, ok


def chol_solve(L, b):
    """X with (L L^T) X = B; L (..., n, n) lower, B (..., n, k); the firmware's substitutions."""
    L, b = _f32(L), _f32(b)
    n = L.shape[-1]
    x = np.array(np.broadcast_to(b, np.broadcast_shapes(L.shape[:-2], b.shape[:-2]) + b.shape[-2:]))
    for i in range(n):
        s = x[..., i, :]
        for j in range(i):
            s = s - L[..., i, j, None] * x[..., j, :]
        x[..., i, :] = s / L[..., i, i, None]
    for i in range(n - 1, -1, -1):
        s = x[..., i, :]
        for j in range(i + 1, n):
            s = s - L[..., j, i, None] * x[..., j, :]
        x[..., i, :] = s / L[..., i, i, None]
    return x


def inv_spd(a):
    """(a^-1, ok) via cholesky and chol_solve on the identity; NaN where not ok."""
    a = _f32(a)
    L, ok = cholesky(a)
    with np.errstate(all="ignore"):
        x = chol_solve(L, identity(a.shape[-1], a.shape[:-2]))
    x[~ok] = np.nan
    return x, ok
