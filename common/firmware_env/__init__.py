"""Make the firmware importable on CPython exactly as the board sees it.

On the board `firmware/` is the filesystem root and `firmware/lib/` is on `sys.path`, so the
portable core is imported as flat modules (`import f32, mat, rot`). `install()` reproduces that
layout on the desktop and plugs the NumPy float32 backend into the seam; the emulator adds
its emulated board beneath it (host_emulator.emulated_board.install_machine: `machine`, the BMI055
register model, `time`).

Kernels: the firmware does `import navk` (firmware/lib/kern.py) and falls back to its Python
kernels on ImportError. `use_kernels("native")` (the default; INS_KERNELS=python in the
environment changes it for the whole process) makes `import navk` give the cffi build of
firmware/native (navk_host.py; built on the first import, NativeError if it cannot be);
`use_kernels("python")` makes it raise ImportError even when built. A switch drops the
firmware's modules from sys.modules, so the next `import app` (or any firmware module) is made
afresh under the new choice; modules imported before keep the kernels they picked. The cpython
runtime calls it at the start of every run (`run(..., kernels=...)`).
"""

import os
import pathlib
import sys

import numpy as np

REPO_DIR = pathlib.Path(__file__).resolve().parents[2]
FIRMWARE_DIR = REPO_DIR / "firmware"
LIB_DIR = FIRMWARE_DIR / "lib"
KERNELS = ("native", "python")
KERNELS_ENV = "INS_KERNELS"  # the process's default choice (native when unset)
_kernels = None  # the choice in force (None: not made yet, the default applies)


def default_kernels():
    """$INS_KERNELS, else "native"; ValueError for anything but KERNELS."""
    kind = os.environ.get(KERNELS_ENV) or "native"
    if kind not in KERNELS:
        raise ValueError(f"{KERNELS_ENV}={kind!r}: choose {' or '.join(KERNELS)}")
    return kind


def kernels():
    """The kernels `import navk` gives the firmware now: "native" or "python"."""
    return _kernels or default_kernels()


class _NavkFinder:
    """`import navk` -> the cffi build's module, while the native kernels are chosen (built on
    first use: a failed build raises common.native.NativeError, not ImportError, so the
    firmware cannot silently fall back to its Python kernels)."""

    @classmethod
    def find_spec(cls, name, path=None, target=None):
        if name != "navk" or kernels() != "native":
            return None
        import importlib.util

        return importlib.util.spec_from_loader(name, cls)

    @staticmethod
    def create_module(spec):
        from common.firmware_env import navk_host

        return navk_host.load()

    @staticmethod
    def exec_module(module):
        pass


def _firmware_modules():
    fw = str(FIRMWARE_DIR) + os.sep
    return [
        name for name, m in list(sys.modules.items())
        if (getattr(m, "__file__", None) or "").startswith(fw)
    ]  # fmt: skip


def use_kernels(kind=None):
    """Choose the firmware's kernels: "native" (navk, the cffi build), "python" (`import navk`
    raises ImportError), None (the default: $INS_KERNELS or native). A change drops the
    firmware's modules from sys.modules (they are imported afresh, picking the new kernels).
    Returns the choice in force."""
    global _kernels
    install()
    kind = default_kernels() if kind is None else kind
    if kind not in KERNELS:
        raise ValueError(f"kernels {kind!r}: choose {' or '.join(KERNELS)}")
    if kind == kernels() and _kernels is not None:
        return kind
    changed = kind != kernels()
    _kernels = kind
    if kind == "python":
        sys.modules["navk"] = None  # import navk -> ImportError (ModuleNotFoundError)
    elif sys.modules.get("navk", 0) is None:
        del sys.modules["navk"]
    if changed:
        for name in _firmware_modules():
            del sys.modules[name]
    return kind


def install():
    """Idempotent: seam backend, `micropython` stand-in, search path, the board's float
    error behaviour, and `import navk` as use_kernels() says (native unless chosen else)."""
    from common.firmware_env import f32_host
    from common.firmware_env import micropython as fake_micropython

    sys.modules.setdefault("f32_host", f32_host)
    sys.modules.setdefault("micropython", fake_micropython)
    for path in (str(LIB_DIR), str(FIRMWARE_DIR)):
        if path not in sys.path:
            sys.path.insert(0, path)
    # The board raises on x / 0.0 and silently produces inf/nan otherwise: mirror that.
    np.seterr(divide="raise", over="ignore", under="ignore", invalid="ignore")
    if not any(f is _NavkFinder for f in sys.meta_path):
        sys.meta_path.insert(0, _NavkFinder)
    if _kernels is None and default_kernels() == "python":
        sys.modules["navk"] = None


def import_module(name):
    """A firmware module by its board name ("app", "drivers.bmi055", ...), for reading its
    constants on CPython (install() first). The firmware's modules find MicroPython's `time`
    functions when they call them, so the emulated board may come later
    (host_emulator.emulated_board.install_machine)."""
    import importlib

    install()
    return importlib.import_module(name)
