"""The emulated board the runtimes run the firmware on: what `machine` and `time` give the
firmware's own board.py and drivers, backed by emulated peripherals on a virtual clock.

    mpy/  machine.py (the stm32 port's API, as strict as the port about arguments: pins, SPI,
          UARTs, timer, watchdog; allocation-free per tick), bmi055_model.py (the BMI055
          register model machine.py puts on the SPI bus and re-exports, on a clock given to
          it) and time.py (the virtual clock and MicroPython's tick functions), plain Python
          that runs unchanged in a MicroPython VM and on CPython; emulate.py and
          emulate_m4f.py, the harnesses that replay a stimulus through the firmware inside the
          unix VM (mpy_unix) and on the emulated Cortex-M4F (m4f), with feed.py;
          backup_domain.py, the virtual board's stand-in for `stm.mem32` over the RTC backup
          registers (the firmware's maintenance marker), shared by its two VMs through a file

One board for every runtime: the VM finds machine.py, bmi055_model.py and time.py on its
sys.path, the emulated Cortex-M4F has them frozen (runtimes/m4f/manifest.py); the cpython
runtime, the model's virtual clock and the tests load them with
host_emulator.emulated_board.install_machine() (machine.py as `machine`, bmi055_model.py as
`bmi055_model`, time.py's functions on CPython's `time`); bmi055_model() loads
the register model alone and feed() the feed loop. mpy/ is not a host package: it is loaded
by file.
"""

import pathlib
import sys

from common import firmware_env

MPY_DIR = pathlib.Path(__file__).resolve().parent / "mpy"
EMULATE = MPY_DIR / "emulate.py"  # the VM's harness: micropython emulate.py FW STIM CFG OUT


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
    """emulated_board/mpy/bmi055_model.py, the BMI055 register model, as the module `bmi055_model`
    (loaded once per process; machine.py imports it under that name). Its dies take a clock
    (`Bmi055(now_us=...)`); without one they read emulated_board/mpy/time.py's, which only
    install_machine() puts on CPython's `time`."""
    model = sys.modules.get("bmi055_model")
    if model is None:
        model = _load("bmi055_model", MPY_DIR / "bmi055_model.py")
        sys.modules["bmi055_model"] = model
    return model


def feed():
    """emulated_board/mpy/feed.py, the feed loop every runtime runs, as the module `feed` on
    CPython (loaded once per process, after install_machine(): it imports `machine` and the
    stimulus record's constants, common/proto/mpy/feed_protocol.py, as `feed_protocol`, the
    names the VMs know them by)."""
    module = sys.modules.get("feed")
    if module is None:
        from common.proto.mpy import feed_protocol

        sys.modules.setdefault("feed_protocol", feed_protocol)
        module = _load("feed", MPY_DIR / "feed.py")
        sys.modules["feed"] = module
    return module


def install_machine():
    """The emulated board (emulated_board/mpy) on CPython; returns its `machine` module.

    Idempotent: the first call loads emulated_board/mpy/time.py (its MicroPython-only functions go
    onto CPython's `time`), emulated_board/mpy/bmi055_model.py as the module `bmi055_model` and
    emulated_board/mpy/machine.py (which imports it) as the module `machine`, once per process; the
    firmware's modules keep the first ones they import (the BMI055 driver binds
    time.sleep_ms). A run starts a fresh board with `machine.power_on()`."""
    import time

    firmware_env.install()
    machine = sys.modules.get("machine")
    if machine is None or not hasattr(machine, "power_on"):
        if not hasattr(time, "now_us"):
            board_time = _load("host_emulator.emulated_board.mpy.time", MPY_DIR / "time.py")
            for name in TIME_FUNCTIONS:  # not in CPython's time
                setattr(time, name, getattr(board_time, name))
        bmi055_model()
        machine = _load("machine", MPY_DIR / "machine.py")
        sys.modules["machine"] = machine
    import gc

    if not hasattr(gc, "mem_free"):  # CPython's heap is not the board's: report plenty free
        gc.mem_free = lambda: 1 << 20
    return machine
