"""Make the firmware importable on CPython exactly as the board sees it.

On the board `firmware/` is the filesystem root and `firmware/lib/` is on `sys.path`, so the
portable core is imported as flat modules (`import f32, mat, rot`). `install()` reproduces that
layout on the desktop and plugs the NumPy float32 backend into the seam.
"""

import pathlib
import sys

import numpy as np

REPO_DIR = pathlib.Path(__file__).resolve().parents[2]
FIRMWARE_DIR = REPO_DIR / "firmware"
LIB_DIR = FIRMWARE_DIR / "lib"


def install():
    """Idempotent: seam backend, `micropython` stand-in, search path, and the board's float
    error behaviour."""
    from host_emulator.firmware_env import f32_host
    from host_emulator.firmware_env import micropython as fake_micropython

    sys.modules.setdefault("f32_host", f32_host)
    sys.modules.setdefault("micropython", fake_micropython)
    for path in (str(LIB_DIR), str(FIRMWARE_DIR)):
        if path not in sys.path:
            sys.path.insert(0, path)
    # The board raises on x / 0.0 and silently produces inf/nan otherwise: mirror that.
    np.seterr(divide="raise", over="ignore", under="ignore", invalid="ignore")


def install_machine(hw):
    """Install the emulated `machine` module (board/cpython/machine.py) backed by the emulated
    board hw, and MicroPython's time functions on its virtual clock."""
    from host_emulator.board.cpython import machine

    install()
    machine.use(hw)
    sys.modules["machine"] = machine
    import time

    for name in ("ticks_us", "ticks_ms", "ticks_diff", "sleep_ms"):  # not in CPython's time
        setattr(time, name, getattr(machine, name))
    import gc

    if not hasattr(gc, "mem_free"):  # CPython's heap is not the board's: report plenty free
        gc.mem_free = lambda: 1 << 20


def import_module(name):
    """A firmware module by its board name ("app", "drivers.bmi055", ...), for reading its
    constants on CPython. MicroPython's time functions are put in place first (on a fresh
    emulated board if none is installed yet): the BMI055 driver binds time.sleep_ms when it is
    first imported, and bound to anything else it would wait in real time on every emulated
    board after (whose BMI055 then never leaves its reset: no frames at all)."""
    import importlib
    import time

    if "drivers.bmi055" not in sys.modules and not hasattr(time, "sleep_ms"):
        from host_emulator.board.cpython import machine

        install_machine(machine.Hardware())
    install()
    return importlib.import_module(name)
