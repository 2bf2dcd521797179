"""The three builds of the native kernels (common/native) give the same float32 bits everywhere.

A sample navk.h/navk.c (tests/native/sample: every argument and result type, 0 to 12
arguments, sqrtf and a*b+c) is built the three ways into a temporary directory: the cffi
extension on CPython (firmware_env.navk_host's wrappers), the x64 native module in the PyPI unix
VM and the armv7emsp one on the emulated Cortex-M4F (loaded from /flash/lib as on a board). All
three give the NumPy float32 results bit for bit (the VM's floats are doubles, its buffers
float32), refuse wrong buffers with TypeError/ValueError, and the object code holds no fused
multiply-add and takes sqrtf as the one instruction (vsqrt.f32, sqrtss), calling no C library.
Then the firmware's own build: abi() and add() on the three runtimes, the heap the loaded
module takes on the Cortex-M4F and the instructions of one navk.add call there.
"""

import json
import os
import pathlib
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

from common import native, toolchain
from common.firmware_env import navk_host
from common.native import bindings
from host_emulator.runtimes.m4f import guest
from host_emulator.runtimes.mpy_unix import vm

SAMPLE = pathlib.Path(__file__).with_name("sample")
F32 = np.float32
N = 37


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The sample built the three ways: {"cffi": .so, "x64": navk.mpy, "armv7emsp": navk.mpy}."""
    root = tmp_path_factory.mktemp("native")
    return {
        "root": root,
        "cffi": native.cffi_module(SAMPLE, root),
        "x64": native.natmod("x64", SAMPLE, root),
        "armv7emsp": native.natmod("armv7emsp", SAMPLE, root),
    }


def inputs():
    rng = np.random.default_rng(11)

    def floats():
        return (rng.standard_normal(N) * 10.0 ** rng.uniform(-4, 4, N)).astype(F32)

    a, b, c = floats(), floats(), floats()
    return {
        "a": a, "b": b, "c": c, "s": np.abs(floats()),
        "h": rng.integers(-3000, 3000, N).astype(np.int16),
        "u": rng.integers(0, 256, N).astype(np.uint8),
        "i": rng.integers(-(2**20), 2**20, N).astype(np.int32),
        "x": F32(3.25e-3), "y": F32(-7.5e2),
    }  # fmt: skip


def expected(d):
    """What every build must give: NumPy float32, one rounding per operation, in C's order."""
    a, b, c, h, u, i = d["a"], d["b"], d["c"], d["h"], d["u"], d["i"]
    dot = F32(0.0)
    for k in range(N):
        dot = dot + a[k] * b[k]
    xor = u ^ np.uint8(0x5A)
    return {
        "abi": 7, "neg": -123,
        "hypot": np.sqrt(d["x"] * d["x"] + d["y"] * d["y"]).tobytes().hex(),
        "sqrt_n": np.sqrt(d["s"]).tobytes().hex(),
        "add": (a + b).tobytes().hex(),
        "add_view": (a[1:] + b[1:]).tobytes().hex(),
        "madd": (a * b + c).tobytes().hex(),
        "dot": F32(dot).tobytes().hex(),
        "sum16": int(h.astype(np.int64).sum()),
        "scale16": (h.astype(np.int32) * 3).astype(np.int16).tobytes().hex(),
        "xor": [xor.tobytes().hex(), int(xor.astype(np.int64).sum())],
        "icum": np.cumsum(i, dtype=np.int32).tobytes().hex(),
        "args12": [(a[:1] + d["x"]).tobytes().hex(), int(i[0] + 5), int(h[0] - 2),
                   int((int(u[0]) + 1) & 255), 5 - 2 + int(d["y"])],
    }  # fmt: skip


# The same checks in MicroPython (unix VM and Cortex-M4F): inputs as float32 bytes in hex.
MP_CHECKS = """
import array, binascii, json, struct
import navk

def F(h):
    return array.array('f', binascii.unhexlify(h))
def A(t, h):
    return array.array(t, binascii.unhexlify(h))
def H(b):
    return binascii.hexlify(bytes(b)).decode()
def f32(h):
    return struct.unpack('<f', binascii.unhexlify(h))[0]
def fh(x):
    return H(struct.pack('<f', x))
def err(fn, *args):
    try:
        fn(*args)
    except Exception as e:
        return type(e).__name__
    return 'none'

a, b, c, s = F(IN['a']), F(IN['b']), F(IN['c']), F(IN['s'])
h, u, i = A('h', IN['h']), bytearray(binascii.unhexlify(IN['u'])), A('i', IN['i'])
x, y = f32(IN['x']), f32(IN['y'])
n = len(a)
r = {'abi': navk.abi(), 'neg': navk.neg(123), 'hypot': fh(navk.hypot(x, y))}
o = F('00' * 4 * n)
navk.sqrt_n(o, s, n); r['sqrt_n'] = H(o)
navk.add(o, a, b, n); r['add'] = H(o)
ov = F('00' * 4 * (n - 1))
navk.add(memoryview(ov)[0:], memoryview(a)[1:], memoryview(b)[1:], n - 1); r['add_view'] = H(ov)
navk.madd(o, a, b, c, n); r['madd'] = H(o)
r['dot'] = fh(navk.dot(a, b, n))
r['sum16'] = navk.sum16(h, n)
h2 = A('h', '00' * 2 * n)
navk.scale16(h2, h, 3, n); r['scale16'] = H(h2)
u2 = bytearray(n)
r['xor'] = [None, navk.xor(u2, u, n)]; r['xor'][0] = H(u2)
i2 = A('i', '00' * 4 * n)
navk.icum(i2, i, n); r['icum'] = H(i2)
b1, d1, f1, g1 = F('00' * 4), A('i', '00' * 4), A('h', '00' * 2), bytearray(1)
ret = navk.args12(a, b1, i, d1, h, f1, u, g1, 5, x, -2, y)
r['args12'] = [H(b1), d1[0], f1[0], g1[0], ret]
r['errors'] = [
    err(navk.add, o, A('i', IN['i']), b, n),
    err(navk.add, o, bytearray(4 * n), b, n),
    err(navk.add, array.array('f'), a, b, 0),
    err(navk.add, None, a, b, n),
    err(navk.add, o, a, b, 1.0),
    err(navk.add, o, a, b),
    err(navk.xor, bytes(n), bytes(n), n),
    err(navk.xor, bytearray(n), bytes(n), n),
    err(navk.sum16, A('H', IN['h']), n),
    err(navk.icum, A('I', IN['i']), i, n),
    err(navk.neg, 2 ** 40),
]
print(json.dumps(r))
"""
MP_ERRORS = ["TypeError", "TypeError", "ValueError", "TypeError", "TypeError", "TypeError",
             "TypeError", "none", "TypeError", "TypeError"]  # fmt: skip


def mp_script(d):
    hexed = {k: v.tobytes().hex() for k, v in d.items()}
    return f"IN = {hexed!r}\n" + MP_CHECKS


def check_results(r, d):
    want = expected(d)
    errors = r.pop("errors")
    assert errors[:10] == MP_ERRORS
    assert errors[10] in ("ValueError", "OverflowError")  # beyond int32: never truncated
    assert r == want


def test_fused_and_unfused_differ_on_these_inputs():
    """The madd check can tell: one rounding (fused) differs from two in some elements."""
    d = inputs()
    fused = (d["a"].astype(np.float64) * d["b"] + d["c"]).astype(F32)  # a*b exact in double
    assert np.count_nonzero(fused != d["a"] * d["b"] + d["c"]) >= 3


def test_cpython_cffi_build(built):
    d = inputs()
    navk = navk_host.make_module(built["cffi"], native.prototypes(SAMPLE))
    n = N
    a, b, c, s, h, u, i = (d[k] for k in "abcshui")
    o = np.zeros(n, F32)
    r = {"abi": navk.abi(), "neg": navk.neg(123)}
    hy = navk.hypot(d["x"], d["y"])
    assert type(hy) is np.float32  # the seam's float: the firmware's next operation rounds
    r["hypot"] = hy.tobytes().hex()
    navk.sqrt_n(o, s, n)
    r["sqrt_n"] = o.tobytes().hex()
    navk.add(o, a, b, n)
    r["add"] = o.tobytes().hex()
    ov = np.zeros(n - 1, F32)
    navk.add(ov, a[1:], b[1:], n - 1)
    r["add_view"] = ov.tobytes().hex()
    navk.madd(o, a, b, c, n)
    r["madd"] = o.tobytes().hex()
    r["dot"] = navk.dot(a, b, n).tobytes().hex()
    r["sum16"] = navk.sum16(h, n)
    h2 = np.zeros(n, np.int16)
    navk.scale16(h2, h, 3, n)
    r["scale16"] = h2.tobytes().hex()
    u2 = bytearray(n)
    r["xor"] = [None, navk.xor(u2, u, n)]
    r["xor"][0] = u2.hex()
    u3 = np.zeros(n, np.uint8)
    assert navk.xor(u3, bytes(u), n) == r["xor"][1] and u3.tobytes() == bytes(u2)
    i2 = np.zeros(n, np.int32)
    navk.icum(i2, i, n)
    r["icum"] = i2.tobytes().hex()
    b1, d1, f1, g1 = np.zeros(1, F32), np.zeros(1, np.int32), np.zeros(1, np.int16), bytearray(1)
    ret = navk.args12(a, b1, i, d1, h, f1, u, g1, 5, d["x"], -2, d["y"])
    r["args12"] = [b1.tobytes().hex(), int(d1[0]), int(f1[0]), g1[0], ret]
    assert r == expected(d)


def test_cpython_refuses_wrong_buffers(built):
    navk = navk_host.make_module(built["cffi"], native.prototypes(SAMPLE))
    o, a = np.zeros(4, F32), np.ones(4, F32)
    bad = [
        ((o, a.astype(np.float64), a, 4), TypeError, "expected a numpy float32 array"),
        ((o, a.astype(">f4"), a, 4), TypeError, "float32"),
        ((o, np.ones(4, np.int32), a, 4), TypeError, "got a int32 array"),
        ((o, bytearray(16), a, 4), TypeError, "got bytearray"),
        ((np.zeros(0, F32), a, a, 0), ValueError, "empty"),
        ((None, a, a, 4), TypeError, "NoneType"),
        ((o, np.ones(8, F32)[::2], a, 4), ValueError, "not contiguous"),
        ((a.copy(), a, a, 4.0), TypeError, "integer"),
    ]
    ro = np.zeros(4, F32)
    ro.flags.writeable = False
    bad.append(((ro, a, a, 4), TypeError, "read-only"))
    for args, exc, says in bad:
        with pytest.raises(exc, match=says):
            navk.add(*args)
    with pytest.raises(TypeError, match="argument 'out'"):
        navk.add(a.astype(np.float64), a, a, 4)  # the message names the kernel's argument
    with pytest.raises(TypeError):
        navk.add(o, a, a)
    with pytest.raises(TypeError, match="bytearray"):
        navk.xor(bytes(4), bytes(4), 4)  # bytes are read-only
    with pytest.raises(TypeError):
        navk.sum16(np.zeros(4, np.uint16), 4)
    with pytest.raises(OverflowError):
        navk.neg(2**40)
    ro8 = np.zeros(4, np.uint8)
    ro8.flags.writeable = False
    assert navk.xor(bytearray(4), ro8, 4) == 4 * 0x5A  # read-only is fine for const


def test_cpython_pointer_cache(built, monkeypatch):
    """A buffer's pointer is made once and found by identity; the cache is bounded."""
    navk = navk_host.make_module(built["cffi"], native.prototypes(SAMPLE))
    cache = navk.add.__globals__["_k0"]
    o, a = np.zeros(4, F32), np.full(4, F32(2))
    navk.add(o, a, a, 4)
    assert id(o) in cache
    p = cache[id(o)]
    navk.add(o, a, a, 4)
    assert cache[id(o)] is p and o[0] == 4
    monkeypatch.setattr(navk_host, "CACHE_MAX", 3)
    navk2 = navk_host.make_module(built["cffi"], native.prototypes(SAMPLE))
    cache2 = navk2.add.__globals__["_k0"]
    outs = [np.zeros(4, F32) for _ in range(10)]
    for x in outs:
        navk2.add(x, a, a, 4)
        assert len(cache2) <= 3
    assert all(x[3] == 4 for x in outs)


def run_vm(script, path):
    env = {**os.environ, "MICROPYPATH": f"{path}:.frozen"}
    proc = subprocess.run(
        [vm.micropython_exe(), "-c", script], capture_output=True, text=True, env=env, timeout=60
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc.stdout


def test_unix_vm_x64_build(built):
    d = inputs()
    out = run_vm(mp_script(d), built["x64"].parent)
    check_results(json.loads(out.strip().splitlines()[-1]), d)


def test_m4f_armv7emsp_build(built):
    d = inputs()
    code = (
        f"import emulate_m4f\nemulate_m4f.mount_flash(None, {str(built['armv7emsp'])!r})\n"
        + mp_script(d)
    )
    out = guest.run(code)
    check_results(json.loads(out.strip().splitlines()[-1]), d)


def objects(root, arch):
    return sorted((pathlib.Path(root) / arch / "build").rglob("*.o"))


def test_no_fused_multiply_add_and_sqrt_is_one_instruction(built):
    """armv7emsp: no vfma/vfms/vfnma/vfnms anywhere (the sample's a*b+c is the chained vmla),
    sqrtf is vsqrt.f32 with no call; x64 (the natmod and the cffi extension): no vfmadd, sqrtss."""
    objs = objects(built["root"], "armv7emsp")
    assert objs
    for o in objs:
        assert toolchain.fused_multiply_adds(o) == [], o
    # the sample's navk.o by name: its path under build/ mirrors the checkout's absolute path,
    # so its place in a sorted list depends on where the clone lives
    (sample_o,) = [o for o in objs if o.name == "navk.o"]
    dis = native.run_checked(["arm-none-eabi-objdump", "-d", str(sample_o)])
    madd = dis[dis.index("<navk_madd>:") :].split("\n\n")[0]
    # vmla.f32 is the FPv4's chained multiply-accumulate: the product is rounded before the
    # sum (two roundings, as vmul + vadd); only vfma & co. fuse (the sample's bits prove it)
    assert "vmla.f32" in madd or ("vmul.f32" in madd and "vadd.f32" in madd)
    sq = dis[dis.index("<navk_sqrt_n>:") :].split("\n\n")[0]
    assert "vsqrt.f32" in sq and "\tbl\t" not in sq and "\tb.w\t" not in sq
    for obj in (*objects(built["root"], "x64"), built["cffi"]):
        dis = native.run_checked(["objdump", "-d", str(obj)])
        assert not re.search(r"\bv?fn?m(add|sub)\d", dis), obj
    dis = native.run_checked(["objdump", "-d", str(built["cffi"])])
    sq = dis[dis.index("<navk_sqrt_n>:") :].split("\n\n")[0]
    assert "sqrtss" in sq and "call" not in sq


# What a native module may call: the runtime (mp_*), its own kernels, the memory functions the
# bindings define, and libgcc's integer helpers; never libm, never soft float or double.
ALLOWED_UNDEFINED = re.compile(
    r"^(mp_\w+|navk_\w+|memset|memcpy|memmove|_GLOBAL_OFFSET_TABLE_|"
    r"__aeabi_(u?ldivmod|u?idiv(mod)?|llsl|llsr|lasr|lmul))$"
)


def test_the_firmware_build_holds_no_fma_and_calls_no_libm():
    native.natmod("armv7emsp")
    objs = objects(native.BUILD_DIR, "armv7emsp")
    assert any(o.name == "navk.o" for o in objs)
    for o in objs:
        assert toolchain.fused_multiply_adds(o) == [], o
        undefined = native.run_checked(["arm-none-eabi-nm", "-u", str(o)]).split()
        bad = [s for s in undefined if s != "U" and not ALLOWED_UNDEFINED.match(s)]
        assert bad == [], f"{o.name} calls {bad}"


def test_double_promotion_is_an_error(tmp_path):
    """-Werror=double-promotion: `x * 0.1` (a double operation the float32 model does not make)
    does not build."""
    src = tmp_path / "src"
    shutil.copytree(SAMPLE, src)
    c = src / "navk.c"
    c.write_text(c.read_text().replace("return __builtin_sqrtf(x * x + y * y);", "return x * 0.1;"))
    with pytest.raises(native.NativeError, match="double-promotion"):
        native.cffi_module(src, tmp_path / "build")


def test_the_cffi_build_is_cached_by_content_and_safe_to_share(tmp_path):
    """Built once per content (a changed source, another key); two processes building at once
    into an empty cache both get a whole module."""
    src = tmp_path / "src"
    shutil.copytree(SAMPLE, src)
    root = tmp_path / "build"
    code = (
        f"import sys; sys.path.insert(0, {str(toolchain.REPO)!r}); from common import native; "
        f"print(native.cffi_module({str(src)!r}, {str(root)!r}))"
    )
    procs = [
        subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    paths = [p.communicate(timeout=120)[0].strip() for p in procs]
    assert all(p.returncode == 0 for p in procs)
    assert paths[0] == paths[1] and pathlib.Path(paths[0]).is_file()
    assert [d.name for d in (root / "cffi").iterdir()] == [pathlib.Path(paths[0]).parent.name]
    mtime = pathlib.Path(paths[0]).stat().st_mtime_ns
    assert native.cffi_module(src, root) == pathlib.Path(paths[0])  # cached: not rebuilt
    assert pathlib.Path(paths[0]).stat().st_mtime_ns == mtime
    c = src / "navk.c"
    c.write_text(c.read_text().replace("SAMPLE_ABI; }", "SAMPLE_ABI + 1; }"))
    again = native.cffi_module(src, root)
    assert again.parent.name != pathlib.Path(paths[0]).parent.name
    navk = navk_host.make_module(again, native.prototypes(src))
    assert navk.abi() == 8
    assert [d.name for d in (root / "cffi").iterdir()] == [again.parent.name]  # old one pruned


# ---------------------------------------------------------------------------------------------
# The firmware's build: abi() and add() on the three runtimes


def firmware_inputs():
    rng = np.random.default_rng(5)
    a = (rng.standard_normal(64) * 10.0 ** rng.uniform(-6, 6, 64)).astype(F32)
    b = (rng.standard_normal(64) * 10.0 ** rng.uniform(-6, 6, 64)).astype(F32)
    return a, b


ADD_SCRIPT = """
import array, binascii
import navk
a = array.array('f', binascii.unhexlify({a!r}))
b = array.array('f', binascii.unhexlify({b!r}))
o = array.array('f', bytes(len(a) * 4))
navk.add(o, a, b, len(a))
print('R', navk.abi(), binascii.hexlify(bytes(o)).decode())
"""


def test_firmware_kernels_abi_and_add_are_the_same_on_all_three():
    import kern

    a, b = firmware_inputs()
    want = (a + b).tobytes().hex()
    navk = navk_host.load()
    o = np.zeros_like(a)
    navk.add(o, a, b, len(a))
    assert navk.abi() == kern.ABI and o.tobytes().hex() == want
    script = ADD_SCRIPT.format(a=a.tobytes().hex(), b=b.tobytes().hex())
    for out in (vm.run(script, kernels="native"), guest.run(script, kernels="native")):
        line = [x for x in out.splitlines() if x.startswith("R ")][-1].split()
        assert int(line[1]) == kern.ABI and line[2] == want


HEAP_AND_COST = """
import gc, array
gc.collect()
f0 = gc.mem_free()
import navk
gc.collect()
print('HEAP', f0 - gc.mem_free())
a = array.array('f', [1.5, 2.25, 3.0])
b = array.array('f', [0.1, 0.2, 0.3])
o = array.array('f', bytes(12))
add = navk.add
def with_add(k):
    for i in range(k):
        add(o, a, b, 3)
def empty(k):
    for i in range(k):
        pass
def count(fn, k):
    c0 = m4f.icount()
    fn(k)
    return (m4f.icount() - c0) & 0x3FFFFFFF
m0 = gc.mem_alloc()
add(o, a, b, 3)
print('ALLOC', gc.mem_alloc() - m0)
print('ADD', (count(with_add, 2000) - count(empty, 2000)) / 2000)
"""


def test_m4f_heap_and_cost_of_one_call():
    """The figures docs/native.md quotes: the heap the loaded module takes, and the
    instructions one navk.add(out, a, b, 3) adds to a loop (allocation-free)."""
    out = guest.run(HEAP_AND_COST, kernels="native")
    got = {line.split()[0]: float(line.split()[1]) for line in out.splitlines() if " " in line}
    print(f"navk on the M4F: heap {got['HEAP']:.0f} B, navk.add {got['ADD']:.0f} instructions")
    assert got["ALLOC"] == 0
    assert 0 < got["HEAP"] < 64 * 1024
    assert got["ADD"] < 800  # 470 measured; an unwanted slow path would show here


def test_bindings_module_name():
    assert bindings.MODULE == "navk" and native.MODULE == "navk"


@pytest.mark.parametrize("flag", ["-ffast-math", "-Ofast"])
def test_a_fast_math_build_of_the_kernels_stops(flag):
    """navk.c refuses to compile when the compiler may reorder float operations."""
    cc = shutil.which("gcc")
    assert cc, "gcc not found: make toolchain installs it"
    src = native.NATIVE_DIR / "navk.c"
    args = [cc, "-fsyntax-only", f"-I{native.NATIVE_DIR}", *native.FLOAT_FLAGS, str(src)]
    assert subprocess.run(args, capture_output=True).returncode == 0
    proc = subprocess.run([*args, flag], capture_output=True, text=True)
    assert proc.returncode != 0 and "must not be compiled with -ffast-math" in proc.stderr
