"""Make the firmware importable on CPython exactly as the board sees it.

On the board `firmware/` is the filesystem root and `firmware/lib/` is on `sys.path`, so the
portable core is imported as flat modules (`import f32, mat, rot`). `install()` reproduces that
layout on the desktop and plugs the NumPy float32 backend into the seam; `install_machine()`
adds the emulated board (board/mpy's `machine`, its BMI055 register model `bmi055_model`, and
`time`) beneath it. `bmi055_model()` gives the register model alone, for an emulator with a
clock of its own.

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
    first use: a failed build raises tools.native.NativeError, not ImportError, so the
    firmware cannot silently fall back to its Python kernels)."""

    @classmethod
    def find_spec(cls, name, path=None, target=None):
        if name != "navk" or kernels() != "native":
            return None
        import importlib.util

        return importlib.util.spec_from_loader(name, cls)

    @staticmethod
    def create_module(spec):
        from host_emulator.firmware_env import navk_host

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
    from host_emulator.firmware_env import f32_host
    from host_emulator.firmware_env import micropython as fake_micropython

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


# MicroPython's time functions the board's time.py adds to CPython's `time` (whose own time(),
# sleep() and perf_counter() the host keeps using)
TIME_FUNCTIONS = ("ticks_us", "ticks_ms", "ticks_cpu", "ticks_diff", "ticks_add", "sleep_ms",
                  "sleep_us", "now_us", "set_us", "advance_us")  # fmt: skip


def _load(name, path):
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def bmi055_model():
    """board/mpy/bmi055_model.py, the BMI055 register model, as the module `bmi055_model`
    (loaded once per process; machine.py imports it under that name). Its dies take a clock
    (`Bmi055(now_us=...)`); without one they read board/mpy/time.py's, which only
    install_machine() puts on CPython's `time`."""
    from host_emulator.board import MPY_DIR

    model = sys.modules.get("bmi055_model")
    if model is None:
        model = _load("bmi055_model", MPY_DIR / "bmi055_model.py")
        sys.modules["bmi055_model"] = model
    return model


def install_machine():
    """The emulated board (board/mpy) on CPython; returns its `machine` module.

    Idempotent: the first call loads board/mpy/time.py (its MicroPython-only functions go onto
    CPython's `time`), board/mpy/bmi055_model.py as the module `bmi055_model` and
    board/mpy/machine.py (which imports it) as the module `machine`, once per process; the
    firmware's modules keep the first ones they import (the BMI055 driver binds
    time.sleep_ms). A run starts a fresh board with `machine.power_on()`."""
    import time

    from host_emulator.board import MPY_DIR

    install()
    machine = sys.modules.get("machine")
    if machine is None or not hasattr(machine, "power_on"):
        if not hasattr(time, "now_us"):
            board_time = _load("host_emulator.board.mpy.time", MPY_DIR / "time.py")
            for name in TIME_FUNCTIONS:  # not in CPython's time
                setattr(time, name, getattr(board_time, name))
        bmi055_model()
        machine = _load("machine", MPY_DIR / "machine.py")
        sys.modules["machine"] = machine
    import gc

    if not hasattr(gc, "mem_free"):  # CPython's heap is not the board's: report plenty free
        gc.mem_free = lambda: 1 << 20
    return machine


def import_module(name):
    """A firmware module by its board name ("app", "drivers.bmi055", ...), for reading its
    constants on CPython. The emulated board is installed first: the BMI055 driver binds
    time.sleep_ms when it is first imported, and bound to anything else it would wait in real
    time on every emulated board after (whose BMI055 then never leaves its reset: no frames at
    all)."""
    import importlib

    install_machine()
    return importlib.import_module(name)
