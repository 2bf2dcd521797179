"""Fixed-size matrix kernels on flat float32 buffers (the board's MAT library, docs/requirements.md,
matrix library).

Conventions
-----------
- A matrix is a flat row-major buffer from `f32.zeros`: element (i, j) of an m x n matrix is
  `a[i * n + j]`. Dimensions are passed as ints; nothing checks them, so a buffer may be
  larger than the matrix it holds (only the leading elements are used).
- Results go into a caller-provided `out` buffer; no kernel creates a container, slice, tuple
  or object. Elementwise kernels take the element count (`m * n` for a matrix) as `n`.
- Aliasing: `copy`, `add`, `sub`, `scale`, `add_scaled` may write `out` over any input (each
  element is read before it is written). `symmetrize` and `add_diag` work in place.
  `cholesky` reads only the lower triangle of `a`, so `l_out` may be `a` (then `a` is
  destroyed, even on failure). `chol_solve` may write `x_out` over `b`. `inv_spd` may write
  `out` over `a` (its `work` must be neither). `mul`, `mul_at`, `mul_bt` and `transpose` must
  not write `out` over an input.
- Arithmetic: every `+ - * /` is one correctly rounded float32 operation on the board and on
  the desktop model; `f32.sqrt` is correctly rounded. The order is part of the contract
  (`host_emulator/model/mat.py` repeats it bit for bit; an asm_thumb replacement must
  keep it). Every sum starts from `s = 0.0` (or from the first element where stated) and
  adds terms one at a time in increasing index order, exactly like `op_AB`:
  `s = s + a[i][k] * b[k][j]` for k = 0 .. n-1. So `0.0 + (-0.0)` gives +0.0, as on the board.
- Failures: nothing divides by zero or takes `sqrt` of a negative. `cholesky` (and so
  `inv_spd`) returns False at the first pivot that is not > 0 in float32 (this includes NaN).

Cost (float boxes per call = GC blocks: a float read from a buffer is one box, every
arithmetic result is one box; stores, ints and the constants 0.0/1.0/0.5 cost nothing):

    zero, identity          0           (integer-only: safe under micropython.heap_lock)
    copy                    n
    transpose               m n
    scale                   2 n         (read, mul)
    add, sub, add_diag      3 n         (2 reads, op)
    add_scaled, dot         4 n         (2 reads, mul, add)
    symmetrize              2 n (n - 1) (per off-diagonal pair: 2 reads, add, mul)
    mul, mul_at, mul_bt     4 m n p     (per term: 2 reads, mul, add)
    cholesky                n (n + 1) (2 n + 1) / 3    when it succeeds
    chol_solve              k (4 n^2 + 2 n)
    inv_spd                 n (14 n^2 + 9 n + 1) / 3   when it succeeds

Examples: a 15 x 15 product is 13500 blocks; a 6 x 6 `inv_spd` is 1118. Solving S K^T = H P
with `chol_solve` (n = 6, k = 15: 2340) is cheaper and more accurate than forming S^-1 and
multiplying (1118 + 2160). Big kernels must be spread over ticks by the caller
(docs/requirements.md, time budget).
"""

import f32


def zero(out, n):
    """out[0:n] = 0."""
    for i in range(n):
        out[i] = 0.0


def identity(out, n):
    """out (n x n) = I."""
    for i in range(n * n):
        out[i] = 0.0
    step = n + 1
    for i in range(n):
        out[i * step] = 1.0


def copy(out, a, n):
    """out = a (n elements)."""
    for i in range(n):
        out[i] = a[i]


def add(out, a, b, n):
    """out = a + b (n elements)."""
    for i in range(n):
        out[i] = a[i] + b[i]


def sub(out, a, b, n):
    """out = a - b (n elements)."""
    for i in range(n):
        out[i] = a[i] - b[i]


def scale(out, a, s, n):
    """out = a * s (n elements, s a float)."""
    for i in range(n):
        out[i] = a[i] * s


def add_scaled(out, a, s, b, n):
    """out = a + s * b (n elements; the product is rounded, then the sum)."""
    for i in range(n):
        out[i] = a[i] + s * b[i]


def add_diag(a, d, n):
    """In place: a (n x n) += diag(d), i.e. a[i][i] = a[i][i] + d[i] (e.g. P + Q)."""
    step = n + 1
    for i in range(n):
        k = i * step
        a[k] = a[k] + d[i]


def dot(a, b, n):
    """Return s = 0.0; s = s + a[i] * b[i] for i = 0 .. n-1."""
    s = 0.0
    for i in range(n):
        s = s + a[i] * b[i]
    return s


def transpose(out, a, m, n):
    """out (n x m) = a^T, a being m x n."""
    for i in range(m):
        ia = i * n
        for j in range(n):
            out[j * m + i] = a[ia + j]


def mul(out, a, b, m, n, p):
    """out (m x p) = a (m x n) @ b (n x p), summed over k in order as op_AB does."""
    io = 0
    for i in range(m):
        ia = i * n
        for j in range(p):
            s = 0.0
            kb = j
            for k in range(ia, ia + n):
                s = s + a[k] * b[kb]
                kb += p
            out[io] = s
            io += 1


def mul_at(out, a, b, m, n, p):
    """out (m x p) = a^T @ b, a stored n x m, b n x p; s = s + a[k][i] * b[k][j] over k."""
    io = 0
    for i in range(m):
        for j in range(p):
            s = 0.0
            ka = i
            kb = j
            for _ in range(n):
                s = s + a[ka] * b[kb]
                ka += m
                kb += p
            out[io] = s
            io += 1


def mul_bt(out, a, b, m, n, p):
    """out (m x p) = a @ b^T, a m x n, b stored p x n; s = s + a[i][k] * b[j][k] over k."""
    io = 0
    for i in range(m):
        ia = i * n
        for j in range(p):
            s = 0.0
            kb = j * n
            for k in range(ia, ia + n):
                s = s + a[k] * b[kb]
                kb += 1
            out[io] = s
            io += 1


def symmetrize(a, n):
    """In place, for i > j: a[i][j] = a[j][i] = (a[i][j] + a[j][i]) * 0.5 (lower + upper).

    The diagonal is not touched (it would be unchanged except where a + a overflows).
    """
    for i in range(1, n):
        ia = i * n
        for j in range(i):
            x = (a[ia + j] + a[j * n + i]) * 0.5
            a[ia + j] = x
            a[j * n + i] = x


def cholesky(l_out, a, n):
    """Lower factor L of a (n x n, SPD) with L L^T = a; return True, or False if not PD.

    Row by row (Cholesky-Banachiewicz). For j < i:
        s = a[i][j]; s = s - L[i][k] * L[j][k] for k = 0 .. j-1; L[i][j] = s / L[j][j]
    then the pivot s = a[i][i]; s = s - L[i][k] * L[i][k] for k = 0 .. i-1; and
    L[i][i] = sqrt(s) if s > 0, else return False at once (l_out is then partly written).
    Only the lower triangle of a is read; the upper triangle of l_out is set to 0.0.
    """
    for i in range(n):
        ia = i * n
        for j in range(i):
            ja = j * n
            s = a[ia + j]
            for k in range(j):
                s = s - l_out[ia + k] * l_out[ja + k]
            l_out[ia + j] = s / l_out[ja + j]
        s = a[ia + i]
        for k in range(ia, ia + i):
            x = l_out[k]
            s = s - x * x
        if not s > 0.0:
            return False
        l_out[ia + i] = f32.sqrt(s)
        for j in range(ia + i + 1, ia + n):
            l_out[j] = 0.0
    return True


def chol_solve(x_out, low, b, n, k):
    """Solve (L L^T) X = B for X (n x k), L from a successful `cholesky`. x_out may be b.

    Column by column: forward substitution L Y = B,
        s = b[i][c]; s = s - L[i][j] * y[j][c] for j = 0 .. i-1; y[i][c] = s / L[i][i]
    for i = 0 .. n-1, then back substitution L^T X = Y,
        s = y[i][c]; s = s - L[j][i] * x[j][c] for j = i+1 .. n-1; x[i][c] = s / L[i][i]
    for i = n-1 .. 0.
    """
    for c in range(k):
        for i in range(n):
            ia = i * n
            s = b[i * k + c]
            jx = c
            for j in range(ia, ia + i):
                s = s - low[j] * x_out[jx]
                jx += k
            x_out[i * k + c] = s / low[ia + i]
        for r in range(n):
            i = n - 1 - r
            s = x_out[i * k + c]
            jl = (i + 1) * n + i
            jx = (i + 1) * k + c
            for _ in range(r):
                s = s - low[jl] * x_out[jx]
                jl += n
                jx += k
            x_out[i * k + c] = s / low[i * n + i]


def inv_spd(out, a, n, work):
    """out = a^-1 for a symmetric positive definite a (n x n); return True, or False if not PD.

    `cholesky(work, a, n)` (work: n * n elements, not a or out), then `identity(out, n)` and
    `chol_solve(out, work, out, n, n)`. On False, out is not written. The result is not
    exactly symmetric; `symmetrize` it if that matters.
    """
    if not cholesky(work, a, n):
        return False
    identity(out, n)
    chol_solve(out, work, out, n, n)
    return True
