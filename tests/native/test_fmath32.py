"""fmath32.h: the C port of firmware/lib/fmath.py gives the same bits for every input.

(a) navk_sin_n, navk_cos_n, navk_asin_n and navk_atan2_n (navk.c over fmath32.h) equal the
    vectorised model host_emulator/model/fmath.py bit for bit, NaN included (both return the one
    quiet NaN 0x7FC00000), on 36 million inputs (sin, cos 10.0 million each, asin 10.2 million,
    atan2 6.2 million pairs): dense sweeps around the places where a branch or the quadrant
    changes, every float32 in [9/16, 1] for asin, random bit patterns over the whole float32
    range, and specials;
(b) they equal fmath.py itself, run on numpy.float32 scalars, on a few thousand inputs;
(c) the FM_ constants (tuning.h, which common/native/layout.py generates) are fmath.py's;
(d) fmath32.h compiles without a warning about double or float conversions, and the code GCC
    makes of it holds no fused multiply-add, no x87 and no double arithmetic (x86-64, also with
    FMA available, and the Cortex-M4F when arm-none-eabi-gcc is installed).

The C under test is the CPython build of the kernels (common.native.cffi_module: cffi over every
firmware/native/*.c with the float flags of all the native builds).
"""

import math
import re
import shutil
import subprocess

import numpy as np
import pytest

import fmath
from common import native
from host_emulator.model import fmath as model

NATIVE = native.NATIVE_DIR
HEADER = NATIVE / "fmath32.h"
# docs/requirements.md, float32 contract rule 7: each + - * / rounded on its own, sqrtf one
# instruction, no fast-math
FLOAT_FLAGS = [native.CFFI_OPT, *native.FLOAT_FLAGS]
WARNINGS = ["-Wall", "-Wextra", "-Wdouble-promotion", "-Wfloat-conversion", "-Wconversion"]

F32 = np.float32
U32 = np.uint32
CHUNK = 1 << 20  # the model's temporaries stay small
RNG_SEED = 20240611


# ---- the library ----


@pytest.fixture(scope="module")
def navk():
    """The CPython build of the kernels (firmware_env.navk_host: built unless cached)."""
    from common.firmware_env import navk_host

    return navk_host.load()


def run_c(navk, name, *args):
    args = [np.ascontiguousarray(a, dtype=F32) for a in args]
    out = np.empty(args[0].shape, dtype=F32)
    from common.firmware_env import navk_host

    getattr(navk, f"{name}_n")(out, *args, out.size)
    navk_host.clear_cache()  # the wrapper's pointer cache would keep these big arrays alive
    return out


def run_model(name, *args):
    fn = getattr(model, name)
    n = args[0].size
    return np.concatenate([fn(*(a[i : i + CHUNK] for a in args)) for i in range(0, n, CHUNK)])


def bits(a):
    return np.asarray(a, dtype=F32).view(U32)


def assert_same_bits(name, got, want, *args):
    bad = np.flatnonzero(bits(got) != bits(want))
    if bad.size:
        rows = [
            " ".join(f"{int(bits(a[i])):08x}" for a in args)
            + f" -> C {int(bits(got[i])):08x} model {int(bits(want[i])):08x}"
            for i in bad[:12]
        ]
        head = f"{name}: {bad.size} of {got.size} differ, e.g. (input bits):"
        pytest.fail("\n".join([head, *rows]))


# ---- inputs ----


def from_bits(*u):
    return np.array(u, dtype=U32).view(F32)


def ordered(x):
    """float32 -> integer in the order of the floats (+-0 both 0, one step = one ulp)."""
    b = bits(x).astype(np.int64)
    return np.where(b >= 0x80000000, -(b & 0x7FFFFFFF), b)


def unordered(o):
    """Inverse of `ordered`, clipped to +-inf."""
    o = np.clip(o, -0x7F800000, 0x7F800000)
    return np.where(o < 0, (-o) | 0x80000000, o).astype(U32).view(F32)


def sweep(centers, width):
    """Every float32 within `width` ulps of each center."""
    o = ordered(np.asarray(centers, dtype=F32))[:, None] + np.arange(-width, width + 1)
    return unordered(o.ravel())


def span(lo, hi):
    """Every float32 from lo to hi."""
    return unordered(np.arange(ordered(F32(lo)).item(), ordered(F32(hi)).item() + 1))


def both_signs(v):
    v = np.asarray(v, dtype=F32)
    return np.concatenate([v, -v])


def random_bits(rng, n):
    return rng.integers(0, 1 << 32, n, dtype=np.uint64).astype(U32).view(F32)


def log_uniform(rng, n, lo_exp, hi_exp):
    """Random signs and magnitudes spread evenly over the exponents lo_exp .. hi_exp (< 128)."""
    mag = np.exp2(rng.uniform(lo_exp, hi_exp, n))
    return (mag * rng.choice([-1.0, 1.0], n)).astype(F32)


NAN_BITS = (0x7FC00000, 0xFFC00000, 0x7F800001, 0x7FFFFFFF, 0xFFBFFFFF)
SPECIALS = np.concatenate([
    both_signs(from_bits(0x0, 0x1, 0x2, 0x7FFFFF, 0x800000, 0x800001, 0x7F7FFFFF, 0x7F800000,
                         0x7E800000, 0x7E800001, 0x7E7FFFFF, 0x46000000, 0x46000001, 0x45FFFFFF)),
    both_signs(np.array([0.5, 1.0, 2.0, 3.0, 1e-30, 1e30, math.pi / 4, math.pi / 2, math.pi],
                        dtype=F32)),
    from_bits(*NAN_BITS),
])  # fmt: skip


def sincos_inputs(rng):
    k = np.arange(-5215, 5216)  # every multiple of pi/2 within +-8192
    multiples = (k * (math.pi / 2)).astype(F32)
    half_steps = ((np.arange(-5216, 5216) + 0.5) * (math.pi / 2)).astype(F32)  # k changes
    fine = float(fmath.FINE)
    return np.concatenate([
        SPECIALS,
        sweep(multiples, 128),  # the exact and the fine reduction near sin, cos = 0
        sweep(np.concatenate([multiples - fine, multiples + fine]), 32),  # where it switches
        sweep(half_steps, 64),
        sweep(both_signs([fmath.QUARTER_PI, fmath.SINCOS_MAX]), 1 << 16),  # branch edges
        span(0, from_bits(0xFFFF)[0]),  # subnormals
        -span(0, from_bits(0xFFFF)[0]),
        random_bits(rng, 1_000_000),
        rng.uniform(-8192, 8192, 1_500_000).astype(F32),
        rng.uniform(-math.pi, math.pi, 1_000_000).astype(F32),
        log_uniform(rng, 500_000, -40, 13),
    ])  # fmt: skip


def asin_inputs(rng):
    return np.concatenate([
        SPECIALS,
        span(fmath.ASIN_SPLIT, np.nextafter(F32(1.0), F32(2.0))),  # every float32 above 9/16
        -sweep([fmath.ASIN_SPLIT, F32(1.0)], 1 << 16),
        sweep(both_signs([F32(1.0), fmath.ASIN_SPLIT]), 1 << 10),
        span(0, from_bits(0xFFFF)[0]),
        -span(0, from_bits(0xFFFF)[0]),
        random_bits(rng, 1_000_000),
        rng.uniform(-1, 1, 1_000_000).astype(F32),
        log_uniform(rng, 500_000, -40, 1),
    ])  # fmt: skip


def atan2_inputs(rng):
    """(y, x) pairs."""
    s = SPECIALS
    ys, xs = [np.repeat(s, s.size)], [np.tile(s, s.size)]  # every pair of specials

    def signs(a):
        return a * rng.choice(np.array([-1, 1], dtype=F32), a.size)

    def add(y, x):
        ys.append(signs(y))
        xs.append(signs(x))

    w = 32
    base = np.abs(log_uniform(rng, 20_000, -149, 127.99))
    swept = sweep(base * F32(0.5), w)  # t = 1/2 exactly (and its neighbours)
    add(swept, np.repeat(base, 2 * w + 1))  # zone 0 | zone 1
    add(np.repeat(base, 2 * w + 1), swept)  # zone 2 | zone 1
    base = np.abs(log_uniform(rng, 10_000, -149, 127.99))
    add(sweep(base, w), np.repeat(base, 2 * w + 1))  # ay = ax: below | above the diagonal
    huge = sweep([fmath.HUGE], 1000)  # the scaling by 1/2 and what it does to the other one
    other = np.abs(log_uniform(rng, huge.size * 100, -149, 127.99))
    add(np.repeat(huge, 100), other)
    add(other, np.repeat(huge, 100))
    n = 1_000_000
    add(random_bits(rng, n), random_bits(rng, n))
    add(log_uniform(rng, n, -149, 127.99), log_uniform(rng, n, -149, 127.99))
    t = np.abs(log_uniform(rng, 500_000, -8, 8))  # the range fmath.py's table states
    add(t, np.ones_like(t))
    return np.concatenate(ys), np.concatenate(xs)


# ---- (a) C = model ----


@pytest.fixture(scope="module")
def sincos_x():
    return sincos_inputs(np.random.default_rng(RNG_SEED))


@pytest.mark.parametrize("name", ["sin", "cos"])
def test_sincos_equals_model(navk, sincos_x, name):
    x = sincos_x
    assert x.size > 10_000_000
    assert_same_bits(name, run_c(navk, name, x), run_model(name, x), x)


def test_asin_equals_model(navk):
    x = asin_inputs(np.random.default_rng(RNG_SEED))
    assert x.size > 10_000_000
    assert_same_bits("asin", run_c(navk, "asin", x), run_model("asin", x), x)


def test_atan2_equals_model(navk):
    y, x = atan2_inputs(np.random.default_rng(RNG_SEED))
    assert y.size > 6_000_000
    assert_same_bits("atan2", run_c(navk, "atan2", y, x), run_model("atan2", y, x), y, x)


def test_nan_is_the_one_quiet_nan(navk):
    """No NaN payload or sign passes through: the C returns fmath.NAN like the Python."""
    nan = from_bits(*NAN_BITS)
    for name in ("sin", "cos", "asin"):
        assert set(bits(run_c(navk, name, nan)).tolist()) == {0x7FC00000}
    one = np.ones_like(nan)
    assert set(bits(run_c(navk, "atan2", nan, one)).tolist()) == {0x7FC00000}
    assert set(bits(run_c(navk, "atan2", one, nan)).tolist()) == {0x7FC00000}


# ---- (b) C = fmath.py ----


def test_equals_firmware_module(navk):
    rng = np.random.default_rng(RNG_SEED + 1)
    x = np.concatenate([SPECIALS, random_bits(rng, 1000), rng.uniform(-8192, 8192, 1000)])
    x = np.concatenate([x, sweep([fmath.HALF_PI, fmath.ASIN_SPLIT], 100)]).astype(F32)
    for name in ("sin", "cos", "asin"):
        fn = getattr(fmath, name)
        want = np.array([fn(v) for v in x], dtype=F32)
        assert_same_bits(name, run_c(navk, name, x), want, x)
    y = np.concatenate([np.repeat(SPECIALS, SPECIALS.size), random_bits(rng, 1000)])
    x = np.concatenate([np.tile(SPECIALS, SPECIALS.size), random_bits(rng, 1000)])
    want = np.array([fmath.atan2(b, a) for b, a in zip(y, x, strict=True)], dtype=F32)
    assert_same_bits("atan2", run_c(navk, "atan2", y, x), want, y, x)


# ---- (c) constants ----


def test_constants_are_fmath_constants():
    text = (NATIVE / "tuning.h").read_text()
    defined = dict(re.findall(r"#define FM_(\w+) F32_BITS\((0x[0-9A-F]{8})\)", text))
    python = {
        name: int(bits(value))
        for name, value in vars(fmath).items()
        if name.isupper() and isinstance(value, F32)
    }
    assert sorted(defined) == sorted(python)
    assert {name: int(u, 16) for name, u in defined.items()} == python


# ---- (d) code generation ----

TU = """#include "fmath32.h"
float c_sin(float x) { return f32_sin(x); }
float c_cos(float x) { return f32_cos(x); }
float c_atan2(float y, float x) { return f32_atan2(y, x); }
float c_asin(float x) { return f32_asin(x); }
"""


def assembly(tmp_path, gcc, *flags, float_flags=FLOAT_FLAGS):
    src = tmp_path / "tu.c"
    src.write_text(TU)
    cmd = [gcc, *float_flags, *WARNINGS, "-Werror", *flags, f"-I{NATIVE}", "-S", "-o", "-"]
    return subprocess.run([*cmd, str(src)], check=True, capture_output=True, text=True).stdout


def instructions(asm):
    return [line.split()[0] for line in asm.splitlines() if line.startswith("\t") and
            not line.lstrip().startswith(".")]  # fmt: skip


def outside_calls(asm, call):
    """Calls to anything but fmath32.h's own functions (at -Os f32__reduced stays one)."""
    targets = re.findall(rf"^\t{call}\t(\S+)", asm, re.M)
    return [t for t in targets if not t.startswith("f32_")]


def x86_fused(ops):
    return [op for op in ops if re.match(r"vfn?m(add|sub)", op)]


@pytest.mark.parametrize("march", [None, "-march=haswell"])
def test_x86_64_code_is_float32_sse(tmp_path, march):
    """With FMA available (haswell) too: -ffp-contract=off keeps every product rounded."""
    asm = assembly(tmp_path, "gcc", *([march] if march else []))
    ops = instructions(asm)
    x87 = [op for op in ops if re.match(r"f[a-z]", op)]
    double = [op for op in ops if re.search(r"(sd|pd)[lq]?$|ss2sd|sd2ss", op)]
    calls = outside_calls(asm, r"call\w*")  # sqrtf
    assert not x86_fused(ops) and not x87 and not double and not calls, (x87, double, calls)
    assert {"sqrtss", "vsqrtss"} & set(ops)
    assert {"cvttss2sil", "vcvttss2sil"} & set(ops)  # int() truncates toward zero


def test_x86_64_fma_check_finds_contraction(tmp_path):
    """The check above would see them: without -ffp-contract=off GCC fuses a*b + c."""
    asm = assembly(tmp_path, "gcc", "-march=haswell", float_flags=["-O2", "-fno-math-errno"])
    assert x86_fused(instructions(asm))


def arm_fused(ops):
    return [op for op in ops if re.match(r"vfn?m[as]", op)]


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None, reason="no arm-none-eabi-gcc")
@pytest.mark.parametrize("opt", ["-O2", "-Os"])  # the natmods' dynruntime.mk passes -Os
def test_cortex_m4f_code_is_float32_without_fma(tmp_path, opt):
    m4f = ["-mthumb", "-mcpu=cortex-m4", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard"]
    flags = [opt, *native.FLOAT_FLAGS]
    asm = assembly(tmp_path, "arm-none-eabi-gcc", *m4f, float_flags=flags)
    ops = instructions(asm)
    double = [op for op in ops if ".f64" in op]
    calls = outside_calls(asm, r"blx?")  # sqrtf, soft-float helpers
    assert not arm_fused(ops) and not double and not calls, (double, calls)
    assert "vsqrt.f32" in ops
    assert {"vcvt.s32.f32"} & set(ops)  # int() truncates toward zero


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None, reason="no arm-none-eabi-gcc")
def test_cortex_m4f_fma_check_finds_contraction(tmp_path):
    m4f = ["-mthumb", "-mcpu=cortex-m4", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard"]
    asm = assembly(tmp_path, "arm-none-eabi-gcc", *m4f, float_flags=["-Os", "-fno-math-errno"])
    assert arm_fused(instructions(asm))
