"""firmware/lib/mat.py (the two kernels the firmware calls, `copy` and `mul`): bit for bit
against the NumPy model, against float64 within the proven float32 rounding-error bound,
inside the MicroPython VM, and what they allocate there.

Error bound (u = 2**-24, gamma_k = k u / (1 - k u); Higham, "Accuracy and Stability of
Numerical Algorithms", 2nd ed., eq. 3.5): a sum of n rounded products accumulated in any order
has |fl(A B) - A B| <= gamma_n |A| |B|, elementwise. Underflow adds at most 2**-150 absolute
per rounded operation (half the denormal spacing); the float64 reference adds its own (much
smaller) error, included as slack.
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

# Float32 values that exercise signed zeros, the denormal boundary, overflow and NaN.
SMALL = [0.0, -0.0, 1e-30, -1e-30, 1e-38, -1e-38, 1.2e-38, 1e-45, -1e-45]
LARGE = [1e30, -1e30, 3e38, -3e38, np.inf, -np.inf, np.nan]
SPECIALS = np.array(SMALL + LARGE, dtype=F32)
KINDS = ["normal", "normal", "mixed", "special", "special", "tiny", "huge", "negzero", "zeros"]
SHAPES = [(3, 3, 3), (3, 3, 1), (1, 3, 3), (6, 15, 6), (15, 15, 15)]  # 3 x 3: config.py's


def gamma(k, u=U32):
    return k * u / (1 - k * u)


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


def fw_mul(a, b, m, n, p):
    out = garbage(m * p)
    mat.mul(out, fbuf(a), fbuf(b), m, n, p)
    return out.reshape(m, p)


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
    """(m, n, p, kind) draws, sizes 1..15, plus SHAPES in every kind."""
    cases = [(*s, k) for s in SHAPES for k in KINDS]
    while len(cases) < count:
        m, n, p = (int(v) for v in rng.integers(1, 16, 3))
        cases.append((m, n, p, KINDS[int(rng.integers(len(KINDS)))]))
    return cases


def test_the_firmware_calls_only_copy_and_mul():
    """The module is what the firmware calls (config.py's mounting); the rest had no caller."""
    public = sorted(n for n in vars(mat) if not n.startswith("_") and callable(vars(mat)[n]))
    assert public == ["copy", "mul"]
    assert sorted(n for n in vars(model) if not n.startswith("_") and callable(vars(model)[n])
                  and n != "F32") == ["copy", "mul"]  # fmt: skip


def test_mul_and_copy_bit_exact():
    rng = np.random.default_rng([SEED, 3])
    batch = 4
    count = 0
    for m, n, p, kind in shape_cases(rng, 120):
        a = draw(rng, (batch, m, n), kind)
        b = draw(rng, (batch, n, p), kind)
        want = model.mul(a, b)
        assert want.shape == (batch, m, p)
        for t in range(batch):
            assert_bits(fw_mul(a[t], b[t], m, n, p), want[t], f"mul {m}x{n}x{p} {kind}")
            out = garbage(m * n)
            mat.copy(out, fbuf(a[t]), m * n)
            assert_bits(out, model.copy(a[t]), f"copy {m}x{n} {kind}")
            out = fbuf(a[t])
            mat.copy(out, out, m * n)  # copy may write over its input
            assert_bits(out, a[t], "copy aliased")
            count += 1
    assert count >= 400


def check_product(got, a64, b64):
    """|got - A B| <= gamma_n |A||B| elementwise (plus underflow and float64 slack)."""
    n = a64.shape[-1]
    exact = a64 @ b64
    mag = np.abs(a64) @ np.abs(b64)
    bound = (gamma(n) + 2 * gamma(n, U64)) * mag + n * 2.0**-149
    err = np.abs(got.astype(np.float64) - exact)
    assert (err <= bound).all(), f"worst err/bound {np.max(err / bound):.3g}"
    return np.max(err / bound)


def test_mul_within_float32_bound():
    rng = np.random.default_rng([SEED, 4])
    worst = 0.0
    for m, n, p, _ in shape_cases(rng, 60):
        kind = "spread" if rng.random() < 0.3 else "normal"
        a = draw(rng, (m, n), kind)
        b = draw(rng, (n, p), kind)
        worst = max(worst, check_product(fw_mul(a, b, m, n, p), a.astype(float), b.astype(float)))
    # The bound is not vacuous: rounding errors reach a visible part of it ...
    assert worst > 0.02
    # ... and it rejects a result that is only float16-accurate.
    a = draw(rng, (15, 15), "normal")
    b = draw(rng, (15, 15), "normal")
    c16 = (a.astype(np.float64) @ b).astype(np.float16)
    with pytest.raises(AssertionError):
        check_product(c16, a.astype(np.float64), b.astype(np.float64))


def test_kernels_in_micropython_vm():
    """The double-precision VM: mul within twice the float32 bound of the model's (each sum
    rounds in double there), copy bit for bit."""
    rng = np.random.default_rng([SEED, 7])
    cases = []
    lines = ["import mat, json", "R = []"]
    for m, n, p in SHAPES:
        a, b = draw(rng, (m, n), "normal"), draw(rng, (n, p), "normal")
        cases.append((a, b, model.mul(a, b)))
        lines.append(
            f"o = _buf({mpvm.hex_of(np.zeros(m * p))!r}); mat.mul(o, "
            f"_buf({mpvm.hex_of(a)!r}), _buf({mpvm.hex_of(b)!r}), {m}, {n}, {p}); "
            "R.append(_hex(o))"
        )
    a = draw(rng, (5, 7), "mixed")
    lines.append(f"o = _buf({mpvm.hex_of(np.zeros(35))!r}); mat.copy(o, "
                 f"_buf({mpvm.hex_of(a)!r}), 35); R.append(_hex(o))")  # fmt: skip
    lines.append("print(json.dumps(R))")
    res = mpvm.run_json("\n".join(lines))
    for (a_, b_, want), got_hex in zip(cases, res, strict=False):
        got = mpvm.from_hex(got_hex).reshape(want.shape)
        a64, b64 = a_.astype(float), b_.astype(float)
        n = a64.shape[1]
        bound = 2 * ((gamma(n) + 2 * gamma(n, U64)) * (np.abs(a64) @ np.abs(b64)))
        assert (np.abs(got.astype(float) - want) <= bound).all()
    assert_bits(mpvm.from_hex(res[-1]).reshape(5, 7), a, "VM copy")


def test_allocation_in_vm():
    """The module docstring's costs, counted in GC blocks in the VM."""
    rng = np.random.default_rng([SEED, 8])
    formulas = {}
    for m, n, p in [(1, 1, 1), (3, 3, 3), (3, 7, 2), (15, 15, 15)]:
        formulas[f"mul {m}x{n}x{p}"] = (f"mat.mul(O, A, B, {m}, {n}, {p})", 4 * m * n * p)
    for n in (1, 2, 9, 225):
        formulas[f"copy {n}"] = (f"mat.copy(O, A, {n})", n)
    body = (
        "import mat, json\n"
        f"A = _buf({mpvm.hex_of(draw(rng, 256, 'normal'))!r})\n"
        f"B = _buf({mpvm.hex_of(draw(rng, 256, 'normal'))!r})\n"
        "O = _buf(_hex(A))\nR = {}\n"
        + "\n".join(f"R[{k!r}] = _blocks(lambda: {call})" for k, (call, _) in formulas.items())
        + "\nR['copy locked'] = _locked(lambda: mat.copy(O, A, 1))\nprint(json.dumps(R))\n"
    )
    res = mpvm.run_json(body)
    assert res.pop("copy locked") is False  # the lock really catches one float box
    assert res == {k: v for k, (_, v) in formulas.items()}
