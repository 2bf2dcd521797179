"""Where the unmodified firmware runs on a PC: the runtimes, side by side.

Each one takes the same input, a stimulus (proto/stimulus.py: what the board's peripherals see,
tick by tick) and the board's configuration, and returns a `FirmwareRun`: everything the board
sent on its output UART, its console lines and its counters.

    fw = runtimes.get("cpython").run(stim, workdir, config_overrides=None, progress=None)

    cpython   the firmware on CPython, over the emulated board of emulated_board/mpy (cpython.py);
              float32 bit for bit through the seam's NumPy backend; the fastest, and the
              firmware's own tracebacks
    mpy_unix  the firmware in the MicroPython 1.29 unix VM from PyPI, over emulated_board/mpy
              (mpy_unix/); its floats are doubles, so float output agrees to a tolerance;
              proves the firmware runs on MicroPython and counts the GC blocks of every tick
    m4f       the firmware on an emulated Cortex-M4F (QEMU mps2-an386, MicroPython v1.28.0
              built as for the F411 with the firmware frozen; m4f/): the board's float32
              arithmetic, heap and garbage collection; counts the instructions of every tick;
              about real time
    f411      the image `make image` builds, executed on an emulated STM32F411 (Unicorn, one
              model per peripheral: host_emulator/f411), fed as a board is (f411/): the
              port's drivers, interrupts, DMA and flash as they are; float32 bit for bit;
              cycles per tick at the image's 96 MHz; about real time. `board`: the image
              (WEACT_F411_BLACKPILL, the default, or NUCLEO_F411RE)
    model     no firmware: the NumPy float32 model of it (model/app.py through model.py);
              float32 bit for bit; the parity oracle

`micropython`, the old name of mpy_unix, still works; mpy_unix is named for what it is, a
double-precision build of the unix port, not the board's single-precision MicroPython.
A runtime is imported only when it is used.

Every firmware runtime runs with the firmware's native kernels (navk, firmware/native: a cffi
build on CPython, the x64 native module in the VM, the armv7emsp one in /flash/lib on the
Cortex-M4F) unless `kernels="python"` (or INS_KERNELS=python) leaves navk out, so that the
firmware falls back to its Python kernels (docs/native.md).
"""

import importlib
from dataclasses import dataclass, field

import numpy as np

from common.errors import EmulatorError


@dataclass(eq=False)
class FirmwareRun:
    """What a firmware run produced, whatever the runtime."""

    runtime: str  # the runtime's name
    out: bytes  # everything written to the output UART
    console: list  # lines the firmware printed on its console
    ticks: int
    wall_s: float
    blocks_per_tick: np.ndarray | None = None  # GC blocks allocated by each tick (mpy_unix)
    stats: dict = field(default_factory=dict)  # runtime-specific counters
    display: bytes = b""  # everything written to the screen's UART (the display setting on)
    # (tick, end offset in `display`) after each tick that wrote to it: when the screen got what
    display_marks: list = field(default_factory=list)


@dataclass(frozen=True)
class Runtime:
    name: str
    summary: str
    bit_exact: bool  # float32 results equal to the board's, bit for bit
    counts_allocations: bool  # FirmwareRun.blocks_per_tick
    counts_instructions: bool
    module: str  # the module whose run(stim, workdir, config_overrides, progress) it is
    # its extended frames carry run-time counters of its own (garbage collections as on the
    # board), which the model cannot know: parity compares them with those counters zeroed
    own_run_time: bool = False
    # its raw-input records carry a clock of its own (the board's ticks_us from its reset):
    # parity compares them with those times zeroed
    own_clock: bool = False

    def run(self, stim, workdir, config_overrides=None, progress=None, kernels=None,
            board=None):  # fmt: skip
        """A FirmwareRun of the stimulus; FirmwareError if the firmware raises, EmulatorError
        if the runtime cannot run it. kernels: the firmware's float32 kernels, "native" (navk
        built for this runtime) or "python" (no navk); None: the default, native unless
        $INS_KERNELS says python. The model has no kernels: it takes None only. board: the
        image the f411 runtime runs (None: its default); the others run no image."""
        mod = importlib.import_module(self.module)
        extra = {}
        if board is not None:
            if self.name not in BOARD_RUNTIMES:
                raise EmulatorError(f"--board is for the {', '.join(BOARD_RUNTIMES)} runtime: "
                                    f"{self.name} runs no image")  # fmt: skip
            extra["board"] = board
        if kernels is None:
            return mod.run(stim, workdir, config_overrides=config_overrides, progress=progress,
                           **extra)  # fmt: skip
        if self.name == "model":
            raise EmulatorError("the model runtime has no kernels to choose (it is NumPy)")
        check_kernels(kernels)
        return mod.run(stim, workdir, config_overrides=config_overrides, progress=progress,
                       kernels=kernels, **extra)  # fmt: skip


RUNTIMES = {
    r.name: r
    for r in (
        Runtime("cpython", "the firmware on CPython, float32 bit for bit", True, False, False,
                "host_emulator.runtimes.cpython"),
        Runtime("mpy_unix", "the firmware in the MicroPython unix VM (double precision); counts "
                "GC blocks per tick", False, True, False, "host_emulator.runtimes.mpy_unix"),
        Runtime("m4f", "the firmware on an emulated Cortex-M4F (QEMU), float32 as on the board; "
                "counts instructions per tick", True, True, True, "host_emulator.runtimes.m4f",
                own_run_time=True),
        Runtime("f411", "the image itself on an emulated STM32F411 (Unicorn), its peripherals "
                "timed; cycles per tick", True, False, True, "host_emulator.runtimes.f411",
                own_run_time=True, own_clock=True),
        Runtime("model", "the NumPy float32 model of the firmware (the parity oracle)", True,
                False, False, "host_emulator.runtimes.model"),
    )
}  # fmt: skip
ALIASES = {"micropython": "mpy_unix"}
BOARD_RUNTIMES = ("f411",)  # the runtimes that run a board's image (--board)
KERNELS = ("native", "python")  # the firmware's kernels (firmware_env.KERNELS)


def check_kernels(kernels):
    if kernels not in KERNELS:
        raise EmulatorError(f"unknown kernels {kernels!r}: choose {' or '.join(KERNELS)}")
    return kernels


_built = {}


def native_module(arch):
    """The path of navk.mpy built for `arch` (common.native.ARCHS), brought up to date when a
    file of firmware/native changed since this process last built it; EmulatorError saying
    what to install when it cannot be built."""
    from common import native

    key = tuple((p.name, p.stat().st_mtime_ns) for p in native.inputs())
    if _built.get(arch, (None,))[0] != key:
        try:
            _built[arch] = (key, native.natmod(arch))
        except (native.NativeError, ValueError) as e:  # ValueError: bindings.HeaderError
            raise EmulatorError(f"cannot build the native kernels ({arch}): {e}") from None
    return _built[arch][1]


def default_kernels():
    """What a run gets when it names no kernels: $INS_KERNELS, else native."""
    import os

    kind = os.environ.get("INS_KERNELS") or "native"
    if kind not in KERNELS:
        raise EmulatorError(f"INS_KERNELS={kind!r}: choose {' or '.join(KERNELS)}")
    return kind


def names(aliases=True):
    """The names `get` accepts (for a command line's choices)."""
    return (*RUNTIMES, *ALIASES) if aliases else tuple(RUNTIMES)


def get(name):
    """The Runtime called `name` (or an alias of it); EmulatorError naming the choices."""
    r = RUNTIMES.get(ALIASES.get(name, name))
    if r is None:
        raise EmulatorError(f"unknown runtime {name!r}: choose one of {', '.join(RUNTIMES)}")
    return r
