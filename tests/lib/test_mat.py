"""firmware/lib/mat.py: bit for bit against the NumPy model, against float64 linear algebra
within proven float32 rounding-error bounds, inside the MicroPython VM, and what it allocates
there.

Error bounds used below (u = 2**-24, gamma_k = k u / (1 - k u); Higham, "Accuracy and
Stability of Numerical Algorithms", 2nd ed.):
- a sum of n rounded products accumulated in any order (eq. 3.5):
  |fl(A B) - A B| <= gamma_n |A| |B|, elementwise;
- Cholesky (Thm 10.3): L^ L^T = A + dA with |dA| <= gamma_{n+1} |L^| |L^T|;
- Cholesky solve (Thm 10.4): (A + dA) x^ = b with |dA| <= gamma_{3n+1} |L^| |L^T|, hence,
  exactly, x - x^ = A^-1 dA x^ and |x - x^| <= gamma_{3n+1} |A^-1| |L^| |L^T| |x^|. This is
  the condition-number bound made componentwise: since || |L^| |L^T| ||_2 <= ~n ||A||_2, its
  norm is of order n^2 u kappa_2(A) ||x^||. The inverse is n such solves, one per column.
Underflow adds at most 2**-150 absolute per rounded operation (half the denormal spacing);
the float64 references add their own (much smaller) error, included as slack.
"""

import numpy as np
import pytest

import f32
import mat
from host_emulator.model import mat as model
from host_emulator.runtimes.mpy_unix import vm as mpvm

F32 = np.float32
U32 = 2.0**-24
U64 = 2.0**-53
SEED = 20261122

# Kalman-update shapes (m, n, p) of a 15-state filter with up to 6 measurements:
# F P, H P, P H^T, H P H^T, K S^-1, K H, (I - K H) P.
KALMAN_SHAPES = [(15, 15, 15), (6, 15, 15), (15, 15, 6), (6, 15, 6), (15, 6, 6), (15, 6, 15)]

# Float32 values that exercise signed zeros, the denormal boundary, overflow and NaN.
SMALL = [0.0, -0.0, 1e-30, -1e-30, 1e-38, -1e-38, 1.2e-38, 1e-45, -1e-45]
LARGE = [1e30, -1e30, 3e38, -3e38, np.inf, -np.inf, np.nan]
SPECIALS = np.array(SMALL + LARGE, dtype=F32)
KINDS = ["normal", "normal", "mixed", "special", "special", "tiny", "huge", "negzero", "zeros"]


def gamma(k, u=U32):
    return k * u / (1 - k * u)


# ---- inputs ---------------------------------------------------------------------------------


def draw(rng, shape, kind):
    """Random float32 values of one kind (see KINDS)."""
    x = rng.standard_normal(shape)
    if kind == "mixed":  # magnitudes 1e-20 .. 1e20 side by side
        x = x * 10.0 ** rng.integers(-20, 21, shape)
    elif kind == "spread":  # 1e-8 .. 1e8: mixed, but products neither overflow nor underflow
        x = x * 10.0 ** rng.integers(-8, 9, shape)
    elif kind == "tiny":  # products land in the denormals or flush to zero
        x = x * 10.0 ** rng.integers(-24, -18, shape)
    elif kind == "huge":  # products and sums overflow to inf (then inf - inf = NaN)
        x = x * 10.0 ** rng.integers(17, 21, shape)
    elif kind == "negzero":
        x = np.full(shape, -0.0)
    elif kind == "zeros":
        x = np.zeros(shape)
    x = x.astype(F32)
    if kind == "special":
        mask = rng.random(shape) < 0.3
        x[mask] = rng.choice(SPECIALS, int(mask.sum()))
    return x


def spd(rng, n, batch, rank=None, eps_exp=(-3, 0)):
    """Symmetric positive definite float32 matrices B B^T + eps I, built with float32 kernels
    (exactly symmetric: each product pair is the same). rank < n makes them ill-conditioned,
    kappa ~ n rank / eps."""
    r = n if rank is None else rank
    b = rng.standard_normal((batch, n, r)).astype(F32)
    eps = (10.0 ** rng.uniform(*eps_exp, batch)).astype(F32)
    return model.add_diag(model.mul_bt(b, b), np.repeat(eps[:, None], n, axis=1))


def not_pd(rng, n, batch):
    """Symmetric matrices that are not positive definite (in exact arithmetic and, by a wide
    margin, in float32), failing at various pivots, plus zero and NaN matrices."""
    out = []
    for t in range(batch):
        kind = t % 4
        if kind == 0:  # indefinite random symmetric
            s = rng.standard_normal((n, n))
            a = s + s.T
            a[-1, -1] = -abs(a[-1, -1]) - n
        elif kind == 1:  # rank n - 1 Gram matrix minus 0.1 I: one eigenvalue is -0.1
            b = rng.standard_normal((n, n - 1))
            a = b @ b.T - 0.1 * np.eye(n)
        elif kind == 2:
            a = np.zeros((n, n))
        else:
            s = rng.standard_normal((n, n))
            a = s @ s.T + np.eye(n)
            a[n // 2, n // 2] = np.nan
        out.append(a)
    return np.array(out, dtype=F32)


# ---- firmware runners: one matrix at a time on f32.zeros buffers (numpy float32) -----------


def fbuf(x):
    x = np.asarray(x, dtype=F32).ravel()
    b = f32.zeros(x.size)
    b[:] = x
    return b


def garbage(size):
    """An out buffer full of NaN, so a kernel that relies on a zeroed out is caught."""
    b = f32.zeros(size)
    b[:] = np.nan
    return b


def fw_mul(kernel, a, b, m, n, p):
    out = garbage(m * p)
    kernel(out, fbuf(a), fbuf(b), m, n, p)
    return out.reshape(m, p)


def fw_cholesky(a, alias=False):
    n = a.shape[-1]
    ab = fbuf(a)
    low = ab if alias else garbage(n * n)
    ok = mat.cholesky(low, ab, n)
    return low.reshape(n, n), ok


def fw_chol_solve(low, b, alias=False):
    n, k = b.shape
    bb = fbuf(b)
    x = bb if alias else garbage(n * k)
    mat.chol_solve(x, fbuf(low), bb, n, k)
    return x.reshape(n, k)


def fw_inv_spd(a, alias=False):
    n = a.shape[-1]
    ab = fbuf(a)
    out = ab if alias else garbage(n * n)
    ok = mat.inv_spd(out, ab, n, garbage(n * n))
    return out.reshape(n, n), ok


def bits(x):
    """The uint32 patterns, NaN made canonical: NaN payloads are not part of the contract (the
    board's FPU returns the default NaN 0x7FC00000, x86 0xFFC00000)."""
    x = np.array(x, dtype=F32)
    u = x.view(np.uint32)
    u[np.isnan(x)] = 0x7FC00000
    return u


def assert_bits(got, want, what=""):
    g, w = bits(got).ravel(), bits(want).ravel()
    assert g.shape == w.shape, what
    bad = np.flatnonzero(g != w)
    if bad.size:
        i = bad[0]
        raise AssertionError(
            f"{what}: {bad.size} of {g.size} elements differ; first [{i}]: "
            f"{np.ravel(got)[i]!r} ({g[i]:#010x}) vs {np.ravel(want)[i]!r} ({w[i]:#010x})"
        )


def shape_cases(rng, count):
    """(m, n, p, kind) draws, sizes 1..15, plus the Kalman shapes in every kind."""
    cases = [(*s, k) for s in KALMAN_SHAPES for k in ("normal", "special", "mixed")]
    cases += [(1, 1, 1, k) for k in KINDS]
    while len(cases) < count:
        m, n, p = (int(v) for v in rng.integers(1, 16, 3))
        cases.append((m, n, p, KINDS[int(rng.integers(len(KINDS)))]))
    return cases


# ---- (a) bit for bit against the model --------------------------------------------------------

MUL_KERNELS = {
    # name: (firmware kernel, model, stored shape of a, stored shape of b) for out m x p
    "mul": (mat.mul, model.mul, lambda m, n: (m, n), lambda n, p: (n, p)),
    "mul_at": (mat.mul_at, model.mul_at, lambda m, n: (n, m), lambda n, p: (n, p)),
    "mul_bt": (mat.mul_bt, model.mul_bt, lambda m, n: (m, n), lambda n, p: (p, n)),
}


@pytest.mark.parametrize("name", MUL_KERNELS)
def test_products_bit_exact(name):
    kernel, ref, sa, sb = MUL_KERNELS[name]
    rng = np.random.default_rng([SEED, len(name)])
    batch = 4
    count = 0
    for m, n, p, kind in shape_cases(rng, 75):
        a = draw(rng, (batch, *sa(m, n)), kind)
        b = draw(rng, (batch, *sb(n, p)), kind)
        want = ref(a, b)
        assert want.shape == (batch, m, p)
        for t in range(batch):
            assert_bits(fw_mul(kernel, a[t], b[t], m, n, p), want[t], f"{name} {m}x{n}x{p} {kind}")
            count += 1
    assert count >= 300


def test_elementwise_bit_exact():
    rng = np.random.default_rng([SEED, 1])
    count = 0
    for m, n, _, kind in shape_cases(rng, 60):
        a = draw(rng, (4, m, n), kind)
        b = draw(rng, (4, m, n), kind)
        s = draw(rng, (4,), kind)
        size = m * n
        for t in range(4):
            fa, fb = fbuf(a[t]), fbuf(b[t])
            for kernel, args, want in (
                (mat.copy, (fa, size), model.copy(a[t])),
                (mat.add, (fa, fb, size), model.add(a[t], b[t])),
                (mat.sub, (fa, fb, size), model.sub(a[t], b[t])),
                (mat.scale, (fa, s[t], size), model.scale(a[t], s[t])),
                (mat.add_scaled, (fa, s[t], fb, size), model.add_scaled(a[t], s[t], b[t])),
                (mat.transpose, (fa, m, n), model.transpose(a[t])),
            ):
                out = garbage(size)
                kernel(out, *args)
                assert_bits(out, want, f"{kernel.__name__} {m}x{n} {kind}")
            # every elementwise kernel may write over its first input
            out = fbuf(a[t])
            mat.add_scaled(out, out, s[t], fb, size)
            assert_bits(out, model.add_scaled(a[t], s[t], b[t]), "add_scaled aliased")
            count += 1
        # vectorised over the batch with a per-matrix scalar
        assert_bits(model.scale(a, s)[1], model.scale(a[1], s[1]), "model broadcast")
    assert count >= 240


def test_square_kernels_bit_exact():
    """symmetrize, add_diag, identity, zero, dot on square matrices / vectors."""
    rng = np.random.default_rng([SEED, 2])
    for n in range(1, 16):
        for kind in KINDS:
            a = draw(rng, (3, n, n), kind)
            d = draw(rng, (3, n), kind)
            sym = model.symmetrize(a)
            dia = model.add_diag(a, d)
            dots = model.dot(a[:, 0, :], d)
            for t in range(3):
                buf = fbuf(a[t])
                mat.symmetrize(buf, n)
                assert_bits(buf, sym[t], f"symmetrize {n} {kind}")
                buf = fbuf(a[t])
                mat.add_diag(buf, fbuf(d[t]), n)
                assert_bits(buf, dia[t], f"add_diag {n} {kind}")
                assert_bits(mat.dot(fbuf(a[t, 0]), fbuf(d[t]), n), dots[t], f"dot {n} {kind}")
        out = garbage(n * n)
        mat.identity(out, n)
        assert_bits(out, model.identity(n), "identity")
        mat.zero(out, n * n)
        assert_bits(out, model.zero(n * n), "zero")
    # symmetrize really is symmetric, keeps the diagonal, and averages lower + upper
    a = draw(rng, (15, 15), "normal")
    s = model.symmetrize(a)
    assert_bits(s, s.T, "symmetric")
    assert_bits(np.diag(s), np.diag(a), "diagonal kept")
    assert_bits(s[3, 1], (a[3, 1] + a[1, 3]) * F32(0.5), "average")


def test_cholesky_and_solves_bit_exact():
    rng = np.random.default_rng([SEED, 3])
    n_ok = n_fail = 0
    for n in range(1, 16):
        mats = [spd(rng, n, 6), spd(rng, n, 4, rank=max(n // 2, 1)), not_pd(rng, n, 8)]
        if n > 1:  # exactly singular in exact arithmetic: float32 rounding decides PD or not
            mats.append(spd(rng, n, 4, rank=n - 1, eps_exp=(-45, -44)))
        for kind in ("special", "huge", "tiny"):
            s = draw(rng, (2, n, n), kind)
            mats.append(model.symmetrize(s))
        a = np.concatenate(mats)
        want_l, want_ok = model.cholesky(a)
        b = draw(rng, (a.shape[0], n, 3), "normal")
        want_x = model.chol_solve(np.where(want_ok[:, None, None], want_l, F32(1.0)), b)
        want_inv, want_inv_ok = model.inv_spd(a)
        assert (want_inv_ok == want_ok).all()
        for t in range(a.shape[0]):
            alias = t % 2 == 1
            low, ok = fw_cholesky(a[t], alias)
            assert ok == want_ok[t], f"cholesky flag n={n} case {t}"
            inv, inv_ok = fw_inv_spd(a[t], alias)
            assert inv_ok == want_ok[t]
            if not ok:
                n_fail += 1
                # inv_spd leaves out untouched on failure (aliased: out is a itself)
                assert_bits(inv, a[t] if alias else np.full((n, n), np.nan), "inv_spd failed")
                continue
            n_ok += 1
            assert_bits(low, want_l[t], f"cholesky n={n} case {t}")
            assert_bits(fw_chol_solve(low, b[t], alias), want_x[t], f"chol_solve n={n} {t}")
            assert_bits(inv, want_inv[t], f"inv_spd n={n} case {t}")
    assert n_ok >= 150 and n_fail >= 120


def test_cholesky_edge_cases():
    cases = {
        "indefinite 2x2": [[1, 2], [2, 1]],
        "negative definite": -np.eye(3),
        "zero": np.zeros((4, 4)),
        "nan": [[np.nan]],
        "second pivot zero": [[1, 1], [1, 1]],
    }
    for what, a in cases.items():
        a = np.array(a, dtype=F32)
        low, ok = fw_cholesky(a)
        assert ok is False, what
        inv, ok = fw_inv_spd(a)
        assert ok is False, what
        assert not model.cholesky(a)[1], what
    low, ok = fw_cholesky(np.array([[4, 2], [2, 5]], dtype=F32))
    assert ok is True
    assert_bits(low, np.array([[2, 0], [1, 2]], dtype=F32), "exact 2x2 factor")
    # only the lower triangle is read: NaN above the diagonal changes nothing
    a = spd(np.random.default_rng([SEED, 9]), 15, 1)[0]
    poisoned = np.where(np.triu(np.ones((15, 15)), 1) > 0, F32(np.nan), a)
    assert_bits(fw_cholesky(poisoned)[0], fw_cholesky(a)[0], "lower triangle only")
    assert_bits(model.cholesky(poisoned)[0], model.cholesky(a)[0], "model: lower triangle only")


# ---- (b) against float64 linear algebra ------------------------------------------------------


def check_product(got, a64, b64):
    """|got - A B| <= gamma_n |A||B| elementwise (plus underflow and float64 slack)."""
    n = a64.shape[-1]
    exact = a64 @ b64
    mag = np.abs(a64) @ np.abs(b64)
    bound = (gamma(n) + 2 * gamma(n, U64)) * mag + n * 2.0**-149
    err = np.abs(got.astype(np.float64) - exact)
    assert (err <= bound).all(), f"worst err/bound {np.max(err / bound):.3g}"
    return np.max(err / bound)


def test_products_within_float32_bound():
    rng = np.random.default_rng([SEED, 4])
    worst = 0.0
    for m, n, p, _ in shape_cases(rng, 60):
        kind = "spread" if rng.random() < 0.3 else "normal"
        a = draw(rng, (m, n), kind)
        b = draw(rng, (n, p), kind)
        a64, b64 = a.astype(np.float64), b.astype(np.float64)
        worst = max(worst, check_product(fw_mul(mat.mul, a, b, m, n, p), a64, b64))
        check_product(fw_mul(mat.mul_at, a.T.copy(), b, m, n, p), a64, b64)
        check_product(fw_mul(mat.mul_bt, a, b.T.copy(), m, n, p), a64, b64)
        got = mat.dot(fbuf(a[0]), fbuf(b[:, 0]), n)
        check_product(np.array([[got]]), a64[:1], b64[:, :1])
    # The bound is not vacuous: rounding errors reach a visible part of it ...
    assert worst > 0.02
    # ... and it rejects a result that is only float16-accurate.
    a = draw(rng, (15, 15), "normal")
    b = draw(rng, (15, 15), "normal")
    c16 = (a.astype(np.float64) @ b).astype(np.float16)
    with pytest.raises(AssertionError):
        check_product(c16, a.astype(np.float64), b.astype(np.float64))


def test_elementwise_correctly_rounded():
    """One rounded float32 op per element: equal to the float64 result rounded to float32
    (double then single rounding is exact for + - * since 53 >= 2 * 24 + 2)."""
    rng = np.random.default_rng([SEED, 5])
    for _ in range(40):
        m, n = (int(v) for v in rng.integers(1, 16, 2))
        a, b = draw(rng, (m, n), "spread"), draw(rng, (m, n), "spread")
        s = draw(rng, (1,), "normal")[0]
        a64, b64, s64 = a.astype(float), b.astype(float), float(s)
        size = m * n
        for kernel, args, want in (
            (mat.add, (fbuf(a), fbuf(b), size), a64 + b64),
            (mat.sub, (fbuf(a), fbuf(b), size), a64 - b64),
            (mat.scale, (fbuf(a), s, size), a64 * s64),
            (
                mat.add_scaled,
                (fbuf(a), s, fbuf(b), size),
                a64 + (s64 * b64).astype(F32).astype(float),
            ),
            (mat.copy, (fbuf(a), size), a64),
        ):
            out = garbage(size)
            kernel(out, *args)
            assert_bits(out, want.astype(F32), kernel.__name__)
        out = garbage(size)
        mat.transpose(out, fbuf(a), m, n)
        assert_bits(out, a.T, "transpose")
        sq = draw(rng, (n, n), "spread")
        buf = fbuf(sq)
        mat.symmetrize(buf, n)
        sq64 = sq.astype(float)
        avg = ((sq64 + sq64.T) * 0.5).astype(F32)  # one rounding: * 0.5 is exact here
        np.fill_diagonal(avg, np.diag(sq))
        assert_bits(buf, avg, "symmetrize")


def solve_bound(a64, low, x_hat):
    """gamma_{3n+1} |A^-1| |L^| |L^T| |x^| (Higham Thm 10.4), with float64 slack."""
    n = a64.shape[-1]
    l64 = np.abs(low.astype(np.float64))
    return (gamma(3 * n + 1) * (1 + 2.0**-20)) * (
        np.abs(np.linalg.inv(a64)) @ (l64 @ (l64.T @ np.abs(x_hat.astype(np.float64))))
    )


def check_solve(got, a64, low, b64, reference=None):
    x = np.linalg.solve(a64, b64) if reference is None else reference
    kappa = np.linalg.cond(a64)
    slack = 64 * a64.shape[-1] * kappa * U64 * np.abs(x).max()  # error of the float64 solve
    bound = solve_bound(a64, low, got) + slack
    err = np.abs(got.astype(np.float64) - x)
    assert (err <= bound).all(), f"worst err/bound {np.max(err / bound):.3g}"
    return np.max(err / bound)


def check_cholesky(low, a64):
    """L^ L^T = A + dA, |dA| <= gamma_{n+1} |L^| |L^T| (Higham Thm 10.3)."""
    n = a64.shape[-1]
    l64 = low.astype(np.float64)
    assert (np.triu(l64, 1) == 0).all()
    err = np.abs(l64 @ l64.T - a64)
    bound = (gamma(n + 1) + 2 * gamma(n, U64)) * (np.abs(l64) @ np.abs(l64).T)
    assert (err <= bound).all(), f"worst err/bound {np.max(err / bound):.3g}"
    return np.max(err / bound)


def test_cholesky_solve_inverse_within_float32_bound():
    rng = np.random.default_rng([SEED, 6])
    worst = {"chol": 0.0, "solve": 0.0, "inv": 0.0}
    kappas = []
    for n in range(1, 16):
        mats = np.concatenate([spd(rng, n, 3), spd(rng, n, 3, rank=max(n // 3, 1))])
        for a in mats:
            a64 = a.astype(np.float64)
            kappas.append(np.linalg.cond(a64))
            low, ok = fw_cholesky(a)
            assert ok
            worst["chol"] = max(worst["chol"], check_cholesky(low, a64))
            b = draw(rng, (n, 4), "normal")
            x = fw_chol_solve(low, b)
            worst["solve"] = max(worst["solve"], check_solve(x, a64, low, b.astype(float)))
            inv, ok = fw_inv_spd(a)
            assert ok
            ref_inv = np.linalg.inv(a64)
            worst["inv"] = max(worst["inv"], check_solve(inv, a64, low, np.eye(n), ref_inv))
    assert max(kappas) > 1e4  # the ill-conditioned cases are really there
    # not vacuous: the observed errors use a visible part of each bound
    assert min(worst.values()) > 1e-3, worst
    # and a float16-accurate solution of a well-conditioned system is rejected
    a = spd(rng, 6, 1, eps_exp=(1, 1.1))[0]
    a64 = a.astype(np.float64)
    low, _ = fw_cholesky(a)
    b = draw(rng, (6, 2), "normal").astype(np.float64)
    x16 = np.linalg.solve(a64, b).astype(np.float16)
    with pytest.raises(AssertionError):
        check_solve(x16, a64, low, b)


# ---- (c) inside the MicroPython VM ----------------------------------------------------------
# The VM is a double-precision MicroPython: array('f') stores float32, but every `+ - * /` and
# sqrt runs in double and is rounded to float32 only when stored. So its results are not the
# board's bits, but they obey the same error bounds as the float32 model, only better: a VM sum
# is one float32 rounding of a double sum (error <= u|AB| + gamma_n(2**-53)|A||B|), a VM
# Cholesky element has one float32 and a few double roundings. Both results are within the
# bound B of the exact value, so they are within 2 B of each other (triangle inequality).
# A single + - * of two float32 values gives the board's bits even in the VM (rounding to
# double, then to float32, equals one float32 rounding since 53 >= 2 * 24 + 2), so add, sub,
# scale and copy must agree with the model bit for bit.


def test_kernels_in_micropython_vm():
    rng = np.random.default_rng([SEED, 7])
    cases = []
    lines = ["import mat, json", "R = []"]
    for name in MUL_KERNELS:
        for m, n, p in [(15, 15, 15), (6, 15, 6), (3, 4, 5)]:
            _, ref, sa, sb = MUL_KERNELS[name]
            a, b = draw(rng, sa(m, n), "normal"), draw(rng, sb(n, p), "normal")
            cases.append((name, a, b, ref(a, b)))
            lines.append(
                f"o = _buf({mpvm.hex_of(np.zeros(m * p))!r}); mat.{name}(o, "
                f"_buf({mpvm.hex_of(a)!r}), _buf({mpvm.hex_of(b)!r}), {m}, {n}, {p}); "
                "R.append(_hex(o))"
            )
    a, b = draw(rng, (5, 7), "mixed"), draw(rng, (5, 7), "mixed")
    s = draw(rng, (1,), "normal")[0]
    h = f"_buf({mpvm.hex_of(a)!r}), _buf({mpvm.hex_of(b)!r})"
    for name, args in (
        ("add", h),
        ("sub", h),
        ("scale", f"_buf({mpvm.hex_of(a)!r}), S"),
        ("copy", f"_buf({mpvm.hex_of(a)!r})"),
    ):
        lines.append(
            f"S = _buf({mpvm.hex_of([s])!r})[0]; o = _buf({mpvm.hex_of(a)!r}); "
            f"mat.{name}(o, {args}, 35); R.append(_hex(o))"
        )
    spds = [spd(rng, 6, 1)[0], spd(rng, 15, 1, rank=5)[0], spd(rng, 3, 1)[0]]
    rhs = [draw(rng, (a_.shape[0], 4), "normal") for a_ in spds]
    for a_, b_ in zip(spds, rhs, strict=True):
        n = a_.shape[0]
        lines.append(
            f"A = _buf({mpvm.hex_of(a_)!r}); L = _buf({mpvm.hex_of(np.zeros(n * n))!r}); "
            f"X = _buf({mpvm.hex_of(b_)!r}); I = _buf({mpvm.hex_of(np.zeros(n * n))!r}); "
            f"W = _buf({mpvm.hex_of(np.zeros(n * n))!r}); "
            f"ok = mat.cholesky(L, A, {n}); mat.chol_solve(X, L, X, {n}, 4); "
            f"ok2 = mat.inv_spd(I, A, {n}, W); R.append([ok, ok2, _hex(L), _hex(X), _hex(I)])"
        )
    lines.append("print(json.dumps(R))")
    res = mpvm.run_json("\n".join(lines))

    for (name, a_, b_, want), got_hex in zip(cases, res, strict=False):
        got = mpvm.from_hex(got_hex).reshape(want.shape)
        a64, b64 = a_.astype(float), b_.astype(float)
        if name == "mul_at":
            a64 = a64.T
        elif name == "mul_bt":
            b64 = b64.T
        n = a64.shape[1]
        bound = 2 * ((gamma(n) + 2 * gamma(n, U64)) * (np.abs(a64) @ np.abs(b64)))
        assert (np.abs(got.astype(float) - want) <= bound).all(), name
    res = res[len(cases) :]
    want_elem = [model.add(a, b), model.sub(a, b), model.scale(a, s), a]
    for got_hex, want in zip(res[:4], want_elem, strict=True):
        assert_bits(mpvm.from_hex(got_hex).reshape(5, 7), want, "VM elementwise")
    for (ok, ok2, lh, xh, ih), a_, b_ in zip(res[4:], spds, rhs, strict=True):
        n = a_.shape[0]
        a64 = a_.astype(float)
        assert ok and ok2
        l_vm = mpvm.from_hex(lh).reshape(n, n)
        l_m, _ = model.cholesky(a_)
        check_cholesky(l_vm, a64)  # the VM factor meets the model's backward bound too
        bound_l = (gamma(n + 1) + 2 * gamma(n, U64)) * (
            np.abs(l_vm.astype(float)) @ np.abs(l_vm.astype(float)).T
            + np.abs(l_m.astype(float)) @ np.abs(l_m.astype(float)).T
        )
        recon = np.abs(
            l_vm.astype(float) @ l_vm.T.astype(float) - l_m.astype(float) @ l_m.T.astype(float)
        )
        assert (recon <= bound_l).all()
        for got_hex, want, rhs64 in (
            (xh, model.chol_solve(l_m, b_), b_.astype(float)),
            (ih, model.inv_spd(a_)[0], np.eye(n)),
        ):
            got = mpvm.from_hex(got_hex).reshape(want.shape)
            bound = solve_bound(a64, l_vm, got) + solve_bound(a64, l_m, want)
            assert (np.abs(got.astype(float) - want) <= bound).all()
            check_solve(got, a64, l_vm, rhs64)


# ---- (d) allocation, in the VM ----------------------------------------------------------------


def block_formulas():
    """name -> (VM call expression, blocks the module docstring promises)."""
    f = {}
    for m, n, p in [(1, 1, 1), (15, 15, 15), (6, 15, 15), (15, 15, 6), (6, 15, 6), (3, 7, 2)]:
        for name in MUL_KERNELS:
            f[f"{name} {m}x{n}x{p}"] = (f"mat.{name}(O, A, B, {m}, {n}, {p})", 4 * m * n * p)
    for n in (1, 2, 35, 225):
        f[f"copy {n}"] = (f"mat.copy(O, A, {n})", n)
        f[f"add {n}"] = (f"mat.add(O, A, B, {n})", 3 * n)
        f[f"sub {n}"] = (f"mat.sub(O, A, B, {n})", 3 * n)
        f[f"scale {n}"] = (f"mat.scale(O, A, S, {n})", 2 * n)
        f[f"add_scaled {n}"] = (f"mat.add_scaled(O, A, S, B, {n})", 4 * n)
        f[f"dot {n}"] = (f"mat.dot(A, B, {n})", 4 * n)
    for n in (1, 2, 6, 15):
        f[f"symmetrize {n}"] = (f"mat.symmetrize(O, {n})", 2 * n * (n - 1))
        f[f"add_diag {n}"] = (f"mat.add_diag(O, A, {n})", 3 * n)
        f[f"transpose {n}x{n + 2}"] = (f"mat.transpose(O, A, {n}, {n + 2})", n * (n + 2))
        f[f"cholesky {n}"] = (f"mat.cholesky(L, P{n}, {n})", n * (n + 1) * (2 * n + 1) // 3)
        f[f"chol_solve {n}x3"] = (f"mat.chol_solve(O, L{n}, B, {n}, 3)", 3 * (4 * n * n + 2 * n))
        f[f"inv_spd {n}"] = (f"mat.inv_spd(O, P{n}, {n}, L)", n * (14 * n * n + 9 * n + 1) // 3)
    return f


def test_allocation_in_vm():
    rng = np.random.default_rng([SEED, 8])
    setup = [
        "import mat, json",
        f"A = _buf({mpvm.hex_of(draw(rng, 256, 'normal'))!r})",
        f"B = _buf({mpvm.hex_of(draw(rng, 256, 'normal'))!r})",
        "O = _buf(_hex(A)); L = _buf(_hex(A)); S = A[3]",
    ]
    for n in (1, 2, 6, 15):
        a = spd(rng, n, 1)[0]
        setup.append(f"P{n} = _buf({mpvm.hex_of(a)!r})")
        setup.append(f"L{n} = _buf({mpvm.hex_of(model.cholesky(a)[0])!r})")
    formulas = block_formulas()
    body = (
        "\n".join(setup)
        + "\nR = {}\n"
        + "\n".join(f"R[{k!r}] = _blocks(lambda: {call})" for k, (call, _) in formulas.items())
    )
    body += """
R['zero locked'] = _locked(lambda: mat.zero(O, 225))
R['identity locked'] = _locked(lambda: mat.identity(O, 15))
R['copy locked'] = _locked(lambda: mat.copy(O, A, 1))
R['cholesky ok'] = mat.cholesky(L, P15, 15)
print(json.dumps(R))
"""
    res = mpvm.run_json(body)
    assert res.pop("zero locked") is True
    assert res.pop("identity locked") is True
    assert res.pop("copy locked") is False  # the lock really catches one float box
    assert res.pop("cholesky ok") is True  # so the counts above are the success path
    assert res == {k: v for k, (_, v) in formulas.items()}
