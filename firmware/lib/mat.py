"""Fixed-size matrix kernels on flat float32 buffers (the board's MAT library, docs/requirements.md,
matrix library): the two the firmware calls (config.py composes the sensor mounting into the
calibration matrices with them). The filter and the navigator work on their own buffers
(eskf.py, ins.py, nav_kern.py, and navk on the board); the other kernels this module had
(add, scale, transpose, the transposed products, Cholesky and its solves, ...) had no caller
and left the image (docs/image.md).

Conventions
-----------
- A matrix is a flat row-major buffer from `f32.zeros`: element (i, j) of an m x n matrix is
  `a[i * n + j]`. Dimensions are passed as ints; nothing checks them, so a buffer may be
  larger than the matrix it holds (only the leading elements are used).
- Results go into a caller-provided `out` buffer; no kernel creates a container, slice, tuple
  or object. `copy` may write `out` over `a`; `mul` must not write `out` over an input.
- Arithmetic: every `+ - *` is one correctly rounded float32 operation on the board and on
  the desktop model. The order is part of the contract (`host_emulator/model/mat.py` repeats
  it bit for bit): the product's sums start from `s = 0.0` and add terms one at a time in
  increasing index order, exactly like `op_AB`: `s = s + a[i][k] * b[k][j]` for k = 0 .. n-1.
  So `0.0 + (-0.0)` gives +0.0, as on the board.

Cost (float boxes per call = GC blocks: a float read from a buffer is one box, every
arithmetic result is one box; stores and ints cost nothing):

    copy                    n
    mul                     4 m n p     (per term: 2 reads, mul, add)

A 3 x 3 product is 108 blocks; a 15 x 15 one would be 13500, which a caller must spread over
ticks (docs/requirements.md, time budget).
"""


def copy(out, a, n):
    """out = a (n elements)."""
    for i in range(n):
        out[i] = a[i]


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
