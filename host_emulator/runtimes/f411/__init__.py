"""The f411 runtime: the image `make image` builds, executed instruction by instruction on the
emulated STM32F411 (host_emulator/f411), fed as a board is, its frames taken off the RS485 UART.

    fw = runtimes.get("f411").run(stim, workdir)        # WEACT_F411_BLACKPILL by default

What runs is what a user flashes: out/image/<BOARD>/firmware.bin (built or brought up to date
first, tools/image), the firmware frozen in it, and on its filesystem what deploy writes next
to such an image: main.py, ins.cfg (the stimulus header's configuration plus any overrides)
and lib/navk.mpy (the armv7emsp native kernels; with kernels="python" none, and the Python
reference kernels, which the image does not freeze, in /flash/lib instead), in a FAT volume
the port formatted itself (flashfs.py). The image boots from reset, runs main.py, and the firmware
starts its loop as on a board.

The world around the chip (world.py): the BMI055's two dies on SPI1 behind their chip selects,
the GNSS receiver's bytes on the GNSS UART at the baud rate, its PPS on the EXTI line of PB0,
the RS485 transceiver on USART1, and with the display setting on the UsartGPU screen on the
Black Pill's USART6 (FirmwareRun.display and display_marks, as the cpython runtime gives them;
the screen's OKs come back, and its counters are in stats["display_*"]). Stimulus record k
belongs to the firmware's tick k, the k-th expiry of its 5 ms timer (found when the image
inserts the soft timer); the runtime measures every tick on the twin's clock (CPI from
docs/benchmarks/cpi.md, 2.4106 by default: the slowest measured MicroPython code).

FirmwareRun.stats carries the run's figures; FirmwareRun.per_tick (PER_TICK records) what each
tick cost: busy time from the tick's timer to the loop's return to WFI, instructions, of which
in interrupt handlers and in the port's UART and SPI/DMA code, cycles waited in polled
peripheral flags, whether it ran past the next tick's moment (late).
"""

import os
import pathlib
import time

import numpy as np

from common.errors import EmulatorError, FirmwareError
from common.proto import config as board_config
from common.proto import stimulus as stim_mod
from host_emulator import runtimes
from host_emulator.runtimes import FirmwareRun

DEFAULT_BOARD = "WEACT_F411_BLACKPILL"
DEFAULT_CPI = (24106, 10000)  # cpi.md's highest: bm_* code at 3 wait states
START_LIMIT_S = 20.0  # board seconds from reset for the firmware to start its tick timer
PER_TICK = np.dtype(
    [("busy_cycles", "<u4"), ("instr", "<u4"), ("handler_instr", "<u4"), ("uart_instr", "<u4"),
     ("spi_dma_instr", "<u4"), ("gc_instr", "<u4"), ("poll_wait_cycles", "<u4"),
     ("exceptions", "<u2"), ("late", "u1"), ("pad", "u1")]
)  # fmt: skip


def image_files(board_name, log=None):
    """(firmware.bin, firmware.elf) of the board's image, built or brought up to date."""
    from tools.image import build as image_build

    quiet = log or (lambda msg: None)
    try:
        image_build.build(board_name, log=quiet)
    except Exception as e:  # noqa: BLE001  (ImageError, ToolchainError: both say what to do)
        raise EmulatorError(f"cannot build the {board_name} image: {e}") from None
    out = image_build.OUT_ROOT / board_name
    return out / "firmware.bin", image_build.BUILD_ROOT / board_name / "obj" / "firmware.elf"


# The Python reference kernels, which the image does not freeze (firmware/manifest.py): with
# kernels="python" they go to /flash/lib as .mpy, where the firmware finds them (a /flash/drivers
# directory would hide the frozen drivers package: gnss_kern is a top-level module there)
REFERENCE_KERNELS = {"lib/nav_kern.mpy": "lib/nav_kern.py", "lib/yaw_gsf.mpy": "lib/yaw_gsf.py",
                     "lib/gnss_kern.mpy": "drivers/gnss_kern.py"}  # fmt: skip


def deployed_files(stim, config_overrides, kernels, workdir):
    """What deploy writes to /flash next to an image with the firmware frozen: main.py,
    ins.cfg and lib/navk.mpy; with kernels="python" no navk, and the reference kernels
    instead (REFERENCE_KERNELS, compiled by the tree's mpy-cross for the board)."""
    from common.firmware_env import FIRMWARE_DIR

    cfg_path = board_config.write_flash(workdir, board_config.run_values(stim, config_overrides))
    files = {
        "main.py": (FIRMWARE_DIR / "main.py").read_bytes(),
        "ins.cfg": cfg_path.read_bytes(),
    }
    if kernels == "native":
        files["lib/navk.mpy"] = pathlib.Path(runtimes.native_module("armv7emsp")).read_bytes()
    else:
        for dest, src in REFERENCE_KERNELS.items():
            files[dest] = _compiled(FIRMWARE_DIR / src, dest[:-4] + ".py", workdir)
    return files


def _compiled(src, name, workdir):
    """src compiled to .mpy for the board (mpy-cross -march=armv7emsp; `name`, its board path,
    names it in tracebacks)."""
    import subprocess

    from common import toolchain

    out = pathlib.Path(workdir) / (pathlib.Path(name).stem + ".mpy")
    try:
        cmd = [str(toolchain.mpy_cross()), "-march=armv7emsp", "-s", name, "-o", str(out),
               str(src)]  # fmt: skip
        proc = subprocess.run(cmd, capture_output=True, text=True)
    except (OSError, toolchain.ToolchainError) as e:
        raise EmulatorError(f"cannot compile {name} for the board's /flash/lib: {e}") from None
    if proc.returncode != 0:
        raise EmulatorError(f"mpy-cross could not compile {name}: {proc.stderr.strip()}")
    return out.read_bytes()


def run(stim, workdir, config_overrides=None, progress=None, kernels=None, board=None,
        cpi=None, log=None):  # fmt: skip
    """Run the image over a whole stimulus on the emulated STM32F411; a FirmwareRun.

    board: WEACT_F411_BLACKPILL (default) or NUCLEO_F411RE. cpi: (numerator, denominator) of
    the cycles per instruction. FirmwareError if the firmware raises (its traceback reaches
    the console) or never starts; EmulatorError if the twin meets something it does not
    model (the message names the register and the C function)."""
    from host_emulator.f411 import boards
    from host_emulator.f411.chip import F411
    from host_emulator.f411.image import Image
    from host_emulator.runtimes.f411 import flashfs
    from host_emulator.runtimes.f411.world import World

    workdir = pathlib.Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    if isinstance(stim, (str, os.PathLike)):
        stim = stim_mod.read(stim)
    if stim.stalled.any():
        raise EmulatorError("the f411 runtime cannot inject stalls (FLAG_STALL): the twin's "
                            "loop runs as the image makes it run")  # fmt: skip
    kind = runtimes.check_kernels(kernels or runtimes.default_kernels())
    bd = boards.get(board or DEFAULT_BOARD)
    bin_path, elf_path = image_files(bd.name, log)
    image = Image(bin_path, elf_path)
    files = deployed_files(stim, config_overrides, kind, workdir)
    part = flashfs.with_files(flashfs.formatted(bd, image, log), files)

    t_wall = time.perf_counter()
    chip = F411(bd, image, cpi=cpi or DEFAULT_CPI)
    chip.flash_write_raw(flashfs.PART_BASE, part)
    values = board_config.run_values(stim, config_overrides)
    world = World(chip, bd, stim, gnss_baud=int(values.get("gnss_baud", 9600)),
                  display=screen(values))  # fmt: skip
    if not world.wait_for_start(START_LIMIT_S):
        raise FirmwareError(
            f"the firmware on the {bd.name} image did not start its 5 ms tick within "
            f"{START_LIMIT_S:g} s of board time; its console:\n" + world.console_text()
        )
    n = len(stim)
    world.feed(progress)
    wall = time.perf_counter() - t_wall
    if world.error:
        raise FirmwareError(f"the firmware on the {bd.name} image stopped: {world.error}; its "
                            f"console:\n{world.console_text()}")  # fmt: skip
    stats = world.stats()
    stats.update({"kernels": kind, "board": bd.name, "image": str(bin_path),
                  "cpi": (cpi or DEFAULT_CPI)[0] / (cpi or DEFAULT_CPI)[1],
                  "realtime_factor": stim.duration_s / wall if wall > 0 else None})  # fmt: skip
    fw = FirmwareRun("f411", world.output(), world.console_lines(), n, wall, None, stats)
    fw.per_tick = world.per_tick
    fw.display, fw.display_marks = world.display()
    return fw


def screen(values):
    """((width, height), baud) of the screen the firmware drives with these configuration
    values (its display setting on), or None: off, or a configuration the firmware refuses
    (it then runs on its defaults, the display off)."""
    try:
        cfg = board_config.from_values(values)
    except board_config.ConfigError:
        return None
    if not cfg.display:
        return None
    return (cfg.display_w, cfg.display_h), cfg.display_baud
