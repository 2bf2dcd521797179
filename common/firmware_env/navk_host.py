"""The native kernels on CPython: the module `navk` as the firmware imports it on the board, over
the cffi build of firmware/native (common.native.cffi_module, built on first use and cached).

Same names and calling convention as the MicroPython native module (the `navk_` prefix
dropped, positional arguments in the prototype's order), with NumPy buffers where the board
has arrays:

    float * / const float *         numpy.float32 array
    int32_t * / const int32_t *     numpy.int32 array
    int16_t * / const int16_t *     numpy.int16 array
    uint8_t * / const uint8_t *     numpy.uint8 array, bytearray, byte memoryview (or bytes,
                                    const)
    int32_t, float                  int, float (or NumPy scalars)

A buffer must have exactly that dtype (native byte order), be C-contiguous and not empty, and be
writable unless const: a wrong dtype raises TypeError, never passes other bits. A float result
is returned as numpy.float32 (the seam's float on CPython, so the firmware's next operation on
it still rounds to float32), an int32 result as int, void as None.

Per call, a buffer costs a dict look-up: the cffi pointer of each array is made once (the
checks, ffi.from_buffer) and cached by the array's identity (the cache holds the array, so its
id cannot be reused while cached); the cache is emptied when it reaches CACHE_MAX entries.
Kernel buffers are made at start-up (f32.zeros, f32.view), so a run fills it once.
"""

import array
import keyword
import types

import numpy as np

from common import native
from common.native import bindings

CACHE_MAX = 4096
_module = None


def _load_extension(path):
    import importlib.machinery
    import importlib.util

    loader = importlib.machinery.ExtensionFileLoader(native.CFFI_MODULE, str(path))
    spec = importlib.util.spec_from_file_location(native.CFFI_MODULE, str(path), loader=loader)
    ext = importlib.util.module_from_spec(spec)
    loader.exec_module(ext)
    return ext


def _converter(ffi, base, const, where):
    """(cache, slow): slow(a) checks a buffer argument, makes its cffi pointer and caches it."""
    b = bindings.BUFFERS[base]
    dtype = np.dtype(b.dtype)
    ctype = ffi.typeof(f"{base}[]")
    cache = {}
    raw = (bytearray, bytes) if (base == "uint8_t" and const) else (bytearray,)
    raw = raw if base == "uint8_t" else ()
    views = base == "uint8_t"  # a byte memoryview (the BMI055 driver's raw registers)
    codes = tuple(t for t in b.typecodes if isinstance(t, str))
    want = f"a numpy {b.dtype} array, {b.python}" + (" or bytearray" if raw else "")
    want += ", or a byte memoryview" if views else ""

    def slow(a):
        if isinstance(a, np.ndarray):
            if a.dtype != dtype or not a.dtype.isnative:
                raise TypeError(f"{where}: expected {want}, got a {a.dtype} array")
            if not a.flags.c_contiguous:
                raise ValueError(f"{where}: the array is not contiguous")
            if not const and not a.flags.writeable:
                raise TypeError(f"{where}: the array is read-only")
            if a.size < 1:
                raise ValueError(f"{where}: empty buffer")
        elif isinstance(a, raw):
            if len(a) < 1:
                raise ValueError(f"{where}: empty buffer")
        elif views and isinstance(a, memoryview):
            if a.format != "B" or not a.contiguous or (a.readonly and not const):
                raise TypeError(f"{where}: expected {want}, got a memoryview that is not")
            if len(a) < 1:
                raise ValueError(f"{where}: empty buffer")
        elif isinstance(a, array.array):  # the firmware's int buffers (array('i'), array('h'))
            if a.typecode not in codes or a.itemsize != b.itemsize:
                raise TypeError(f"{where}: expected {want}, got array({a.typecode!r})")
            if len(a) < 1:
                raise ValueError(f"{where}: empty buffer")
        else:
            raise TypeError(f"{where}: expected {want}, got {type(a).__name__}")
        p = ffi.from_buffer(ctype, a, require_writable=not const)
        if len(cache) >= CACHE_MAX:
            cache.clear()
        cache[id(a)] = p  # p holds a (its buffer's exporter): the id stays a's
        return p

    return cache, slow


def _wrapper(ffi, lib, proto):
    """The Python function of one prototype (source generated so that a call is one
    expression: cached pointers, then the C function)."""
    env = {"_c": getattr(lib, proto.cname), "_f32": np.float32}
    args, fast, slow = [], [], []
    for i, p in enumerate(proto.params):
        name = p.name  # the C name, unless Python cannot have it (`in`) or it could clash
        if keyword.iskeyword(name) or name.startswith("_"):
            name = f"a{i}_{name.strip('_')}"
        args.append(name)
        if p.pointer:
            where = f"navk.{proto.name}() argument {p.name!r} ({p.ctype})"
            env[f"_k{i}"], env[f"_s{i}"] = _converter(ffi, p.base, p.const, where)
            fast.append(f"_k{i}[id({name})]")
            slow.append(f"_k{i}.get(id({name})) or _s{i}({name})")
        else:
            fast.append(name)
            slow.append(name)
    sig = ", ".join(args)
    wrap = "_f32({})" if proto.ret == "float" else "{}"
    src = [f"def {proto.name}({sig}):"]
    if any(p.pointer for p in proto.params):
        src += [
            "    try:",
            f"        r = _c({', '.join(fast)})",
            "    except KeyError:",
            f"        r = _c({', '.join(slow)})",
            f"    return {wrap.format('r')}",
        ]
    else:
        src.append(f"    return {wrap.format(f'_c({sig})')}")
    exec("\n".join(src), env)  # noqa: S102  (our own generated source)
    fn = env[proto.name]
    fn.__doc__ = f"navk.{proto.name}: {proto.declaration()}"
    return fn


def make_module(ext_path, protos):
    """A module `navk` with one wrapper per prototype over the cffi extension at ext_path."""
    ext = _load_extension(ext_path)
    mod = types.ModuleType("navk", "The native kernels on CPython (firmware_env.navk_host).")
    mod.__file__ = ext.__file__
    for proto in protos:
        setattr(mod, proto.name, _wrapper(ext.ffi, ext.lib, proto))
    return mod


def load():
    """The module `navk` over the cffi build of firmware/native (built now if missing or
    stale); one per process. common.native.NativeError if it cannot be built."""
    global _module
    if _module is None:
        _module = make_module(native.cffi_module(), native.prototypes())
    return _module


def clear_cache():
    """Forget every cached pointer (the arrays they hold are released)."""
    if _module is None:
        return
    for fn in vars(_module).values():
        for name, value in getattr(fn, "__globals__", {}).items():
            if name.startswith("_k") and isinstance(value, dict):
                value.clear()
