"""Measure the accuracy of the deterministic float32 math functions (`firmware/lib/fmath.py`),
then the rotation and lat/lon kernels (core_figures.py): the figures of docs/float32.md.

    python -m host_emulator float32          # exhaustive, a few minutes on 2 cores (make accuracy)
    python -m host_emulator float32 --quick  # random samples, seconds
    python -m host_emulator float32 --fit    # re-derive the polynomial coefficients

The functions measured are the NumPy model (`host_emulator/model/fmath.py`), which the tests
prove bit-identical to the firmware. For a float32 input x the exact value is the float64
function of x (its own error, ~1e-16 relative, is negligible here), and the error is

    |y - exact| / ulp(exact),  ulp(e) = float32 spacing at |e| = 2**(floor(log2|e|) - 23),

with the spacing of the denormals, 2**-149, as the floor (so a zero exact value, e.g.
sin(0) or atan2(0, 1), must be met exactly). Results near zero are therefore judged
relatively: there is no absolute-error allowance. "Correctly rounded" counts errors <= 1/2.

Full mode tries every positive float32 up to 8192 for sin and cos and up to 1 for asin (the
negative half follows by the exact odd/even symmetry that the tests check), every float32
ratio in [2**-8, 2**8] for atan2(t, +-1), plus random (y, x) pairs with log-spread
magnitudes in all four quadrants.
"""

import argparse
import math
import multiprocessing
import sys
import time

import numpy as np

from host_emulator.model import fmath

F32 = np.float32
_CHUNK = 1 << 16  # small enough to stay in cache


def ulp32(exact):
    """float32 spacing at |exact| (float64 array), floored at the denormal spacing 2**-149."""
    _, e = np.frexp(np.abs(exact))
    spacing = np.ldexp(1.0, np.maximum(e - 24, -149))
    return np.where(exact == 0.0, math.ldexp(1.0, -149), spacing)


def ulp_error(y, exact):
    return np.abs(y.astype(np.float64) - exact) / ulp32(exact)


class Stat:
    """Running maximum error, where it occurred, and the share correctly rounded."""

    def __init__(self):
        self.max, self.arg, self.n, self.n_cr = 0.0, None, 0, 0

    def add(self, err, args):
        if err.size == 0:
            return
        i = int(np.argmax(err))
        if err[i] > self.max:
            self.max, self.arg = float(err[i]), tuple(float(a[i]) for a in args)
        self.n += err.size
        self.n_cr += int(np.count_nonzero(err <= 0.5))

    def merge(self, other):
        if other.max > self.max:
            self.max, self.arg = other.max, other.arg
        self.n += other.n
        self.n_cr += other.n_cr


def _bits_range(lo, hi):
    """uint32 patterns of the positive float32 values in [lo, hi]."""
    a = int(np.float32(lo).view(np.uint32))
    b = int(np.float32(hi).view(np.uint32))
    return a, b + 1


def _sweep_one(job):
    """Worker: every float32 x with bit pattern in [a, b); stats split at x <= split."""
    name, a, b, split = job
    model = getattr(fmath, name)
    exact_fn = {"sin": np.sin, "cos": np.cos, "asin": np.arcsin}[name]
    inner, outer = Stat(), Stat()
    for s in range(a, b, _CHUNK):
        x = np.arange(s, min(s + _CHUNK, b), dtype=np.uint32).view(F32)
        err = ulp_error(model(x), exact_fn(x.astype(np.float64)))
        low = x <= split
        inner.add(err[low], (x[low],))
        outer.add(err, (x,))
    return inner, outer


def sweep(name, hi, split, pool, step=None, rng=None):
    """(stat over (0, split], stat over (0, hi]); step=None means every float32."""
    a, b = _bits_range(math.ldexp(1.0, -149), hi)
    if step is None:
        n_jobs = 256
        edges = np.linspace(a, b, n_jobs + 1).astype(np.int64)
        jobs = [(name, int(edges[i]), int(edges[i + 1]), split) for i in range(n_jobs)]
        results = pool.map(_sweep_one, jobs)
        inner, outer = Stat(), Stat()
        for i_stat, o_stat in results:
            inner.merge(i_stat)
            outer.merge(o_stat)
        return inner, outer
    # quick: a random sample of bit patterns, plus a uniform sample in value
    x = np.concatenate(
        [
            rng.integers(a, b, step, dtype=np.uint32).view(F32),
            rng.uniform(0.0, hi, step).astype(F32),
            rng.uniform(0.0, split, step).astype(F32),
        ]
    )
    model = getattr(fmath, name)
    exact_fn = {"sin": np.sin, "cos": np.cos, "asin": np.arcsin}[name]
    err = ulp_error(model(x), exact_fn(x.astype(np.float64)))
    inner, outer = Stat(), Stat()
    low = x <= split
    inner.add(err[low], (x[low],))
    outer.add(err, (x,))
    return inner, outer


def _atan2_ratio_one(job):
    sign, a, b = job
    st = Stat()
    for s in range(a, b, _CHUNK):
        t = np.arange(s, min(s + _CHUNK, b), dtype=np.uint32).view(F32)
        x = np.full_like(t, sign)
        err = ulp_error(fmath.atan2(t, x), np.arctan2(t.astype(np.float64), float(sign)))
        st.add(err, (t, x))
    return st


def atan2_ratios(pool, quick, rng):
    """atan2(t, +-1) for every float32 t in [2**-8, 2**8] (a sample in quick mode)."""
    a, b = _bits_range(math.ldexp(1.0, -8), math.ldexp(1.0, 8))
    st = Stat()
    if quick:
        t = rng.integers(a, b, 2_000_000, dtype=np.uint32).view(F32)
        for sign in (1.0, -1.0):
            x = np.full_like(t, sign)
            st.add(ulp_error(fmath.atan2(t, x), np.arctan2(t.astype(np.float64), sign)), (t, x))
        return st
    edges = np.linspace(a, b, 65).astype(np.int64)
    jobs = [(s, int(edges[i]), int(edges[i + 1])) for s in (1.0, -1.0) for i in range(64)]
    for r in pool.map(_atan2_ratio_one, jobs):
        st.merge(r)
    return st


def atan2_random(n, rng):
    """Random (y, x) of both signs: |y|, |x| log-uniform over 2**-149 .. 2**127.9, or of one
    scale with ratios within 2**+-3."""
    st = Stat()
    block = 1_000_000
    for i in range(0, n, block):
        m = min(block, n - i)
        sy = rng.choice([-1.0, 1.0], m)
        sx = rng.choice([-1.0, 1.0], m)
        if (i // block) % 2 == 0:
            y = sy * np.exp2(rng.uniform(-149, 127.9, m))
            x = sx * np.exp2(rng.uniform(-149, 127.9, m))
        else:  # the same magnitude scale for both: every octant boundary gets crowded
            scale = np.exp2(rng.uniform(-120, 120, m))
            y = sy * scale * np.exp2(rng.uniform(-3, 3, m))
            x = sx * scale
        y, x = y.astype(F32), x.astype(F32)
        ok = np.isfinite(y) & np.isfinite(x)
        y, x = y[ok], x[ok]
        err = ulp_error(fmath.atan2(y, x), np.arctan2(y.astype(np.float64), x.astype(np.float64)))
        st.add(err, (y, x))
    return st


def measure(quick=False, seed=1):
    """Rows (function, domain, inputs, max ulp, share correctly rounded, worst argument)."""
    rng = np.random.default_rng(seed)
    rows = []
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool() as pool:
        step = 1_000_000 if quick else None
        how = "random sample" if quick else "every float32"
        for name in ("sin", "cos"):
            inner, outer = sweep(name, 8192.0, math.pi, pool, step, rng)
            rows.append((name, "[-pi, pi]", how, inner))
            rows.append((name, "[-8192, 8192]", how, outer))
        inner, outer = sweep("asin", 1.0, 1.0, pool, step, rng)
        rows.append(("asin", "[-1, 1]", how, outer))
        ratios = atan2_ratios(pool, quick, rng)
        how = "random sample" if quick else "every float32 t"
        rows.append(("atan2", "(t, +-1), t in [2^-8, 2^8]", how, ratios))
        n = 2_000_000 if quick else 40_000_000
        pairs = atan2_random(n, rng)
        rows.append(("atan2", "random (y, x), 4 quadrants", "log-spread pairs", pairs))
    return rows


def table(rows):
    lines = [
        "| function | domain | inputs | max error (ulp) | correctly rounded | worst at |",
        "|---|---|---|---|---|---|",
    ]
    for name, domain, how, st in rows:
        arg = ", ".join(f"{a:.9g}" for a in st.arg) if st.arg else "-"
        lines.append(
            f"| {name} | {domain} | {how} ({st.n:,}) | {st.max:.4f} | "
            f"{100.0 * st.n_cr / st.n:.2f} % | {arg} |"
        )
    return "\n".join(lines)


# ---- where the coefficients come from -------------------------------------------------------


def _series(name, z):
    """The function's tail as a power series in z = v*v, summed to float64 accuracy.

    sin v = v + v^3 g, cos v = 1 - z/2 + z^2 g, atan v = v + v^3 g, asin v = v + v^3 g.
    """
    g = np.zeros_like(z)
    if name == "sin":
        for n in range(1, 20):
            g += (-1) ** n * z ** (n - 1) / math.factorial(2 * n + 1)
    elif name == "cos":
        for n in range(2, 20):
            g += (-1) ** n * z ** (n - 2) / math.factorial(2 * n)
    elif name == "atan":
        for n in range(1, 80):
            g += (-1) ** n * z ** (n - 1) / (2 * n + 1)
    else:
        c = 1.0
        for n in range(1, 120):
            c = c * (2 * n - 1) / (2 * n)
            g += c * z ** (n - 1) / (2 * n + 1)
    return g


def fit(name, n_coef, v_max, iterations=2000):
    """Minimax (Lawson's iteratively reweighted least squares) fit of g(z) on v in (0, v_max],
    weighted so that the relative error of the whole function is minimised; float64 result."""
    v = np.linspace(1e-4, v_max, 6000)
    z = v * v
    g = _series(name, z)
    value = {"sin": np.sin, "cos": np.cos, "atan": np.arctan, "asin": np.arcsin}[name](v)
    weight = (z * z if name == "cos" else v**3) / value
    basis = np.vander(z, n_coef, increasing=True)
    lw = np.full(z.size, 1.0 / z.size)
    for _ in range(iterations):
        sw = np.sqrt(lw) * weight
        coef = np.linalg.lstsq(basis * sw[:, None], sw * g, rcond=None)[0]
        err = np.abs(weight * (basis @ coef - g))
        lw = lw * err + 1e-300
        lw /= lw.sum()
    return coef, float(err.max())


FITS = (
    ("sin", ("S1", "S2", "S3"), 0.7875),
    ("cos", ("C1", "C2", "C3"), 0.7875),
    ("atan", ("A1", "A2", "A3", "A4", "A5"), 0.5),
    ("asin", ("B1", "B2", "B3", "B4", "B5", "B6"), 0.5625),
)


def print_fits():
    fw = fmath.fw
    for name, names, v_max in FITS:
        coef, rel = fit(name, len(names), v_max)
        print(f"{name}: |v| <= {v_max}, relative error of the float64 fit {rel:.2e}")
        for cname, c in zip(names, coef, strict=True):
            bits = int(np.float32(c).view(np.uint32))
            have = int(np.float32(getattr(fw, cname)).view(np.uint32))
            mark = "same" if bits == have else f"firmware has 0x{have:08X}"
            print(f"  {cname} = from_bits(0x{bits:08X})  # {np.float32(c):.9g}  ({mark})")


def main(argv=None):
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator float32", description=__doc__.split("\n\n")[0]
    )
    ap.add_argument("--quick", action="store_true", help="random samples instead of sweeps")
    ap.add_argument("--fit", action="store_true", help="re-derive the polynomial coefficients")
    args = ap.parse_args(argv)
    if args.fit:
        print_fits()
        return 0
    from host_emulator.bench import core_figures

    t0 = time.time()
    print(table(measure(quick=args.quick)))
    print()
    core_figures.main()
    print(f"\n({time.time() - t0:.0f} s)", file=sys.stderr)
    return 0
