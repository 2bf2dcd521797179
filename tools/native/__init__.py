"""The firmware's native float32 kernels (firmware/native, DESIGN.md 3 rule 7): one C source,
three builds, all out of tree under build/native/ (docs/native.md):

    natmod("armv7emsp")  build/native/armv7emsp/navk.mpy   the board (Cortex-M4F) and the
                                                           emulated one (runtimes/m4f)
    natmod("x64")        build/native/x64/navk.mpy         the PyPI unix VM (runtimes/mpy_unix)
    cffi_module()        build/native/cffi/<key>/          CPython (firmware_env.navk_host)

The two natmods are MicroPython dynamic native modules: the binding C is generated from navk.h
(bindings.py) and compiled with every firmware/native/*.c by the tree's py/dynruntime.mk, then
linked by its tools/mpy_ld.py (pyelftools). The CPython module is cffi's API mode from the same
header. Every build compiles with FLOAT_FLAGS: no contraction into fused multiply-adds, and
sqrtf as the one square-root instruction with no errno call (vsqrt.f32, sqrtss); never
-ffast-math. No runtime library is linked into the natmods: a kernel that needs a libm
function fails to link, on purpose (the board's libm is not the model's).

`python -m tools.native` builds all three (make native).
"""

import contextlib
import fcntl
import hashlib
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

from tools import toolchain
from tools.native import bindings

NATIVE_DIR = toolchain.REPO / "firmware" / "native"
HEADER = NATIVE_DIR / "navk.h"
BUILD_DIR = toolchain.BUILD_ROOT / "native"
ARCHS = ("armv7emsp", "x64")
MODULE = bindings.MODULE
# What every build of the kernels compiles with, besides its optimisation level (dynruntime.mk
# passes -Os; the cffi build -O2: neither changes a float result).
# -Werror=double-promotion: a float promoted to double (`x * 0.1`) is an error, not a silent
# double-precision operation the float32 model does not make.
FLOAT_FLAGS = (toolchain.C_FLOAT_FLAGS, "-fno-math-errno", "-Werror=double-promotion")
CFFI_MODULE = "_navk_cffi"
CFFI_OPT = "-O2"


class NativeError(toolchain.ToolchainError):
    """A build of the kernels is impossible or failed; the message says what to do."""


def sources(src_dir=NATIVE_DIR):
    """The C files of the kernels (every firmware/native/*.c), sorted."""
    return sorted(pathlib.Path(src_dir).glob("*.c"))


def inputs(src_dir=NATIVE_DIR):
    """Every file a build depends on (the C and header files of firmware/native)."""
    d = pathlib.Path(src_dir)
    return sorted([*d.glob("*.c"), *d.glob("*.h")])


def prototypes(src_dir=NATIVE_DIR):
    return bindings.prototypes((pathlib.Path(src_dir) / HEADER.name).read_text())


@contextlib.contextmanager
def _locked(path):
    """An exclusive lock on `path` (created) for the block: one make per build directory."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _write_if_changed(path, text):
    """Write text unless the file already holds it (make then sees nothing new)."""
    path = pathlib.Path(path)
    if path.exists() and path.read_text() == text:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _need(tool, package):
    if shutil.which(tool) is None:
        raise NativeError(
            f"{tool} not found: install Debian's {package} (`make toolchain` does, as root)"
        )


def _need_module(name, package):
    try:
        __import__(name)
    except ImportError:
        raise NativeError(
            f"the Python package {package} is missing: `make` installs requirements.txt"
        ) from None


def natmod_dir(arch, build_root=BUILD_DIR):
    return pathlib.Path(build_root) / arch


def natmod(arch, src_dir=NATIVE_DIR, build_root=BUILD_DIR):
    """Build (or bring up to date: make decides) the native module for `arch` (ARCHS) from
    src_dir (navk.h and every *.c), in build_root/arch; the path of its navk.mpy. NativeError
    saying what to install or what failed; bindings.HeaderError (a ValueError) naming a
    prototype it cannot bind."""
    if arch not in ARCHS:
        raise NativeError(f"unknown architecture {arch!r}: one of {', '.join(ARCHS)}")
    if arch == "x64":
        _need("gcc", "gcc")
    else:
        _need("arm-none-eabi-gcc", "gcc-arm-none-eabi")
    _need("make", "make")
    _need_module("elftools", "pyelftools")
    src = toolchain.micropython_dir()
    toolchain.check_version(src)
    src_dir = pathlib.Path(src_dir).resolve()
    out = natmod_dir(arch, build_root)
    protos = prototypes(src_dir)
    with _locked(out / ".lock"):
        _write_if_changed(out / "navk_bindings.c", bindings.micropython_module(protos))
        srcs = " ".join(["navk_bindings.c", *(str(p) for p in sources(src_dir))])
        flags = " ".join([f"-I{src_dir}", *FLOAT_FLAGS, "-MMD"])
        _write_if_changed(
            out / "Makefile",
            "# Generated by tools/native: the navk native module for one architecture.\n"
            f"MPY_DIR = {src}\nMOD = {MODULE}\nARCH = {arch}\nSRC = {srcs}\n"
            f"CFLAGS_EXTRA = {flags}\n"
            "include $(MPY_DIR)/py/dynruntime.mk\n"
            "-include $(SRC_O:.o=.d)\n"
            "# libgcc only (the integer helpers: 64-bit division), never libm\n"
            "ifneq ($(CROSS),)\n"
            "MPY_LD_FLAGS += -l$(realpath $(shell $(CROSS)gcc $(CFLAGS_ARCH) "
            "--print-libgcc-file-name))\n"
            "endif\n",
        )
        _clean_if_configuration_changed(out, f"{src}\n{src_dir}")
        _share_ld_cache(out)
        args = ["-C", str(out), f"PYTHON={sys.executable}"]
        try:
            toolchain.make(args, f"the {arch} native module", out / "build.log")
        except toolchain.ToolchainError as e:
            raise NativeError(str(e)) from None
    return out / f"{MODULE}.mpy"


def _share_ld_cache(out):
    """mpy_ld.py caches what it read of libgcc.a in ./.mpy_ld_cache (8 s to make, for the
    armv7emsp one): one cache for every build directory."""
    link = out / ".mpy_ld_cache"
    shared = BUILD_DIR / ".mpy_ld_cache"
    shared.mkdir(parents=True, exist_ok=True)
    if link.is_symlink() and link.resolve() == shared.resolve():
        return
    if link.is_symlink() or link.is_file():
        link.unlink()
    elif link.exists():
        shutil.rmtree(link)
    link.symlink_to(shared)


def _clean_if_configuration_changed(out, src):
    """make tracks files, not the tree or the compiler: another one starts afresh."""
    key = hashlib.sha256(f"{src}\n{sys.executable}\n{FLOAT_FLAGS}".encode()).hexdigest()
    stamp = out / "configuration.sha256"
    if stamp.exists() and stamp.read_text() == key:
        return
    shutil.rmtree(out / "build", ignore_errors=True)
    (out / f"{MODULE}.mpy").unlink(missing_ok=True)
    stamp.write_text(key)


# ---------------------------------------------------------------------------------------------
# CPython: cffi, API mode


def _cffi_key(src_dir=NATIVE_DIR):
    """What the CPython module is built from: sources, flags, generator, interpreter, cffi."""
    import cffi

    h = hashlib.sha256()
    for p in inputs(src_dir):
        h.update(p.name.encode() + b"\0" + p.read_bytes() + b"\0")
    h.update(pathlib.Path(bindings.__file__).read_bytes())
    h.update(pathlib.Path(__file__).read_bytes())
    h.update(f"{FLOAT_FLAGS}{CFFI_OPT}{sys.version}{sys.platform}{cffi.__version__}".encode())
    return h.hexdigest()[:16]


def cffi_dir(src_dir=NATIVE_DIR, build_root=BUILD_DIR):
    return pathlib.Path(build_root) / "cffi" / _cffi_key(src_dir)


def _extension(d):
    found = sorted(pathlib.Path(d).glob(CFFI_MODULE + ".*.so")) + sorted(
        pathlib.Path(d).glob(CFFI_MODULE + ".so")
    )
    return found[0] if found else None


def cffi_module(src_dir=NATIVE_DIR, build_root=BUILD_DIR):
    """Build the CPython extension of the kernels in src_dir unless an up-to-date one is
    cached; its path. Cached under build_root/cffi/<key> (key: a hash of the sources, flags,
    generator and interpreter): built in a temporary directory beside it and renamed into
    place, so two processes building at once each get a whole module. NativeError if it cannot
    be built (bindings.HeaderError, a ValueError, for a prototype it cannot bind)."""
    _need_module("cffi", "cffi")
    src_dir = pathlib.Path(src_dir).resolve()
    final = cffi_dir(src_dir, build_root)
    ext = _extension(final)
    if ext is not None:
        return ext
    _need("gcc", "gcc")
    import cffi

    protos = prototypes(src_dir)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = pathlib.Path(tempfile.mkdtemp(prefix=".build-", dir=final.parent))
    try:
        ffi = cffi.FFI()
        ffi.cdef(bindings.cdef(protos))
        ffi.set_source(
            CFFI_MODULE,
            f'#include "{HEADER.name}"\n',
            sources=[str(p) for p in sources(src_dir)],
            include_dirs=[str(src_dir)],
            extra_compile_args=[CFFI_OPT, *FLOAT_FLAGS],
        )
        log = tmp / "build.log"
        try:
            _compile_quietly(ffi, tmp, log)
        except Exception as e:  # distutils' CompileError, LinkError, ...
            tail = log.read_text(errors="replace")[-3000:] if log.exists() else ""
            raise NativeError(f"building the CPython (cffi) module failed: {e}\n{tail}") from None
        built = _extension(tmp)
        if built is None:
            raise NativeError(f"cffi built no {CFFI_MODULE} extension in {tmp}")
        for p in list(tmp.iterdir()):  # keep the extension (and the log) only
            if p != built and p != log:
                shutil.rmtree(p) if p.is_dir() else p.unlink()
        tmp.chmod(0o755)
        try:
            os.rename(tmp, final)
        except OSError:  # another process put its build there first: use that one
            if _extension(final) is None:
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    _prune(final)
    return _extension(final)


def _prune(keep):
    """Remove the other cached builds (a process that loaded one keeps its mapping) and
    temporary directories left over an hour ago by builds that died."""
    for d in keep.parent.iterdir():
        if d == keep:
            continue
        if d.name.startswith(".build-") and time.time() - d.stat().st_mtime < 3600:
            continue
        shutil.rmtree(d, ignore_errors=True)


def _compile_quietly(ffi, tmpdir, log):
    """ffi.compile with the compiler's output in `log` rather than on the terminal."""
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    saved = os.dup(1), os.dup(2)
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        ffi.compile(tmpdir=str(tmpdir), verbose=False)
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for f in (fd, *saved):
            os.close(f)


def build_all(log=print):
    """All three builds; {name: (path, seconds)}."""
    done = {}
    for arch in ARCHS:
        t = time.perf_counter()
        done[arch] = (natmod(arch), time.perf_counter() - t)
    t = time.perf_counter()
    done["cffi"] = (cffi_module(), time.perf_counter() - t)
    if log:
        for name, (path, s) in done.items():
            log(f"{name:10} {s:6.2f} s  {path.relative_to(toolchain.REPO)}")
    return done


def run_checked(cmd):
    """stdout of a command; NativeError with its output if it fails."""
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode:
        raise NativeError(f"{' '.join(map(str, cmd))} failed:\n{proc.stdout}{proc.stderr}")
    return proc.stdout
