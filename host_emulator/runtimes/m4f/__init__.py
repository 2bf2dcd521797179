"""The m4f runtime: the unmodified firmware loop on an emulated Cortex-M4F, the board's CPU and
arithmetic, counting the instructions of every tick.

MicroPython v1.28.0 (common.toolchain's source tree) is built with its qemu port for our board
definition (boards/M4F_INS: QEMU's mps2-an386, Cortex-M4 with the single-precision FPU, hard
float, `MICROPY_FLOAT_IMPL = float`, object representation A: the stm32 port's choices for the
STM32F411), with the firmware frozen exactly as the board image freezes it (firmware/manifest.py)
and the emulated board beside it (emulated_board/mpy: machine.py, bmi055_model.py, time.py, feed.py
and the guest driver emulate_m4f.py; manifest.py). See build.py.

QEMU runs it with `-icount shift=0`: one guest instruction is one ns of virtual time, and the
`m4f` module (usermod/m4f/m4f.c) reads the MPS2's 25 MHz timer, so the guest counts its own
instructions to 40. The host starts the driver through the raw REPL on the UART; the stimulus,
the configuration and the output pass through semihosting files.

What it gives besides the frames:
- floats are float32 as on the board (the unix VM's are doubles), so the frames equal the
  NumPy model's byte for byte (`parity --runtime m4f`);
- per tick (`FirmwareRun.per_tick`, a NumPy record array): instructions executed, of which in
  the emulated peripherals (machine.py, time.py: emulation, not firmware; subtract it), bytes
  allocated, the navigation state after it, and whether the app's own gc.collect() ran in it;
- the heap is the board's (what a board with the image's BOARD_HEAP_BYTES heap would have free
  when the firmware starts; emulated_board/mpy/emulate_m4f.py says how) and the app collects garbage
  itself, as on the board;
- with the display setting on, what the firmware's status page wrote to the screen's UART
  (`FirmwareRun.display` and `display_marks`, as the cpython runtime gives them; each tick's
  bytes also in per_tick["display_bytes"]): the guest takes them after start-up and after every
  tick and empties the UART's transmit buffer. No screen answers in the guest: no `OK` is fed
  back (the cpython runtime feeds the emulated UsartGPU's), so the page takes the screen as
  absent, which is no fault; the bytes it sends do not depend on the answers, and they equal
  the model's byte for byte (model/display.py; `parity --runtime m4f` compares them).

What it cannot give: cycles. A Cortex-M4 at 0 wait states would run about one instruction per
cycle; the F411's flash wait states and MicroPython's branchy interpreter make it ~2
(docs/benchmarks/cpi.md gives the calibration: `python -m host_emulator cpi`). Interrupt
entry/exit and the real peripherals' C drivers are not counted; the firmware's calls into them
are, at a C method call's cost (the firmware holds each emulated part through m4f.Periph, a C
handle: emulated_board/mpy/machine.py).
"""

import os
import pathlib
import shutil
import struct

import numpy as np

from common.errors import EmulatorError
from common.proto import config as board_config
from common.proto import stimulus as stim_mod
from common.proto.mpy.feed_protocol import EXIT_FIRMWARE_ERROR
from host_emulator import runtimes
from host_emulator.runtimes import FirmwareRun
from host_emulator.runtimes.guest_output import (
    GuestOutput,
    display_marks,
    firmware_error,
    run_guest,
)
from host_emulator.runtimes.m4f import build as m4f_build

QEMU = "qemu-system-arm"
QEMU_MACHINE = "mps2-an386"
EXIT_DRIVER_ERROR = 4  # the guest driver itself raised (a bug of the emulator)
PER_TICK = np.dtype(
    [("instr", "<i4"), ("emu_instr", "<i4"), ("alloc_bytes", "<i4"), ("state", "u1"),
     ("collected", "u1"), ("display_bytes", "<u2")]
)  # fmt: skip
AFTER_ERROR = b"import m4f\r\nm4f.exit(4)\r\n\x04"  # runs if the driver's command raised


def qemu_command(elf):
    return [
        QEMU, "-machine", QEMU_MACHINE, "-display", "none", "-monitor", "none",
        "-serial", "stdio", "-semihosting", "-icount", "shift=0", "-kernel", str(elf),
    ]  # fmt: skip


def _default_timeout_s(stim):
    """Generous: the emulated board runs about 3-5x faster than real time here (measured)."""
    return 120.0 + 2.0 * stim.duration_s


def _in_workdir(workdir, path, name):
    """`path` as a name relative to workdir: its own if it is in workdir, else a symbolic link
    `name` to it (semihosting opens it through the link)."""
    path = pathlib.Path(path).resolve()
    if path.parent == workdir:
        return path.name
    link = workdir / name
    link.unlink(missing_ok=True)
    link.symlink_to(path)
    return name


def _data_offset(path):
    with open(path, "rb") as f:
        head = f.read(12)
    if len(head) < 12 or head[:8] != stim_mod.MAGIC:
        raise EmulatorError(f"{path} is not a stimulus file")
    return 12 + struct.unpack_from("<I", head, 8)[0]


def run(
    stim,
    workdir,
    config_overrides=None,
    progress=None,
    timeout_s=None,
    kernels=None,
    guest_setup=None,
    gc_heap_bytes=None,
):
    """Run the firmware on the emulated Cortex-M4F over a whole stimulus; a FirmwareRun.

    stim: a `stimulus.Stimulus` (written to workdir/stimulus.bin) or a stimulus file's path.
    workdir: workdir/flash/ins.cfg (the configuration: the stimulus header's "config" plus
        `config_overrides`, as every runtime) and the guest's output files (workdir/m4f/).
    progress(k, n): called as the guest reports ticks done (every 1000 ticks and at the end).
    kernels: "native" (the armv7emsp navk.mpy, built on demand, in the guest's /flash/lib as on
        a board), "python" (none: the firmware's Python kernels) or None (the default: native
        unless $INS_KERNELS says python).
    guest_setup: (MicroPython source, an expression of a callable), the source run in the
        guest and the callable called before the firmware starts; it returns (report,
        firmware_bytes): report is called at the end for (name, value) pairs, which
        stats["report"] lists; firmware_bytes, the heap the firmware's modules it imported
        hold, is taken from the firmware's start (bench/profile.py).
    gc_heap_bytes: a build whose GC heap is this large instead of build.GC_HEAP_BYTES (room
        for a guest_setup's objects: the firmware still gets the board's heap, the rest is a
        ballast the collector scans).

    The FirmwareRun has `per_tick` (PER_TICK records) and stats from the guest (heap,
    start-up instructions, counters). FirmwareError if the firmware raises; EmulatorError if
    the board cannot be built or run, or times out."""
    workdir = pathlib.Path(workdir).resolve()
    workdir.mkdir(parents=True, exist_ok=True)
    if isinstance(stim, (str, os.PathLike)):
        stim_path = pathlib.Path(stim).resolve()
        stim = stim_mod.read(stim_path)
    else:
        stim_path = workdir / "stimulus.bin"
        stim.write(stim_path)
    if shutil.which(QEMU) is None:
        raise EmulatorError(
            f"{QEMU} not found: run `make toolchain` (installs Debian's qemu-system-arm)"
        )
    kind = runtimes.check_kernels(kernels or runtimes.default_kernels())
    navk = str(runtimes.native_module("armv7emsp")) if kind == "native" else None
    elf = m4f_build.build(
        progress=(lambda msg: print(msg, flush=True)) if progress else None,
        gc_heap_bytes=gc_heap_bytes,
    )
    build_heap = m4f_build.GC_HEAP_BYTES if gc_heap_bytes is None else int(gc_heap_bytes)
    cfg_path = board_config.write_flash(workdir, board_config.run_values(stim, config_overrides))
    out_dir = workdir / "m4f"
    out_dir.mkdir(exist_ok=True)
    for name in ("out.bin", "ticks.bin", "display.bin"):
        (out_dir / name).unlink(missing_ok=True)
    n = len(stim)
    call = _guest_call(workdir, stim, stim_path, navk, cfg_path, out_dir, build_heap,
                       guest_setup)  # fmt: skip
    timeout_s = _default_timeout_s(stim) if timeout_s is None else timeout_s
    out, rc, wall = _execute(elf, call, workdir, progress, timeout_s, n)
    if out.error_tick is not None and rc == EXIT_FIRMWARE_ERROR:
        raise firmware_error(out, stim, "the emulated Cortex-M4F")
    if rc != 0 or out.stats is None:
        tail = "\n".join(out.other[-20:]) or "(no output)"
        raise EmulatorError(f"the emulated Cortex-M4F failed (exit status {rc}):\n{tail}")
    per_tick = np.fromfile(out_dir / "ticks.bin", dtype=PER_TICK)
    if len(per_tick) != n or out.stats.get("ticks") != n:
        raise EmulatorError(
            f"the emulated Cortex-M4F reported {len(per_tick)} ticks of {n}: its output is "
            "incomplete"
        )
    stats = _stats(out, stim.duration_s / wall if wall > 0 else None, kind, guest_setup)
    result = FirmwareRun("m4f", (out_dir / "out.bin").read_bytes(), out.console, n, wall, None,
                         stats)  # fmt: skip
    result.per_tick = per_tick
    result.display = (out_dir / "display.bin").read_bytes()
    result.display_marks = display_marks(
        result.display, per_tick["display_bytes"], stats.get("display_start_bytes", 0),
        "the emulated Cortex-M4F",
    )  # fmt: skip
    return result


def _guest_call(workdir, stim, stim_path, navk, cfg_path, out_dir, build_heap, guest_setup):
    """The MicroPython source the guest runs: guest_setup's, then emulate_m4f.main(...).
    The guest opens its files relative to QEMU's working directory (workdir), by names that
    do not depend on where the host keeps them: the command it compiles, and so its heap, are
    the same for the same stimulus wherever the run happens (counts are comparable)."""
    source, setup = guest_setup or ("", "None")
    stim_rel = _in_workdir(workdir, stim_path, "stim.bin")
    navk_rel = _in_workdir(workdir, navk, "navk.mpy") if navk else None
    # a driver that raises ends QEMU from here: the handler needs no heap (its names are bound
    # before the call), where the REPL's next command (AFTER_ERROR) must be compiled, and a
    # heap the run left full refuses that (measured: 512 bytes), leaving QEMU at the prompt
    return (
        f"{source}import emulate_m4f, m4f, sys\r\n_exit, _pe = m4f.exit, sys.print_exception\r\n"
        f"try:\r\n emulate_m4f.main({stim_rel!r}, "
        f"{_data_offset(stim_path)}, {len(stim)}, {stim.tick_us}, "
        f"{cfg_path.resolve().relative_to(workdir).as_posix()!r}, {out_dir.name!r}, "
        f"{m4f_build.BOARD_HEAP_BYTES}, {build_heap}, {navk_rel!r}, {setup})\r\n"
        f"except BaseException as e:\r\n _pe(e)\r\n _exit({EXIT_DRIVER_ERROR})\r\n"
    )


def _stats(out, realtime_factor, kind, guest_setup):
    """The guest's statistics with the run's; EmulatorError for a run whose counts cannot be
    the board's (a UART that dropped bytes, a driver that allocated, floats not float32)."""
    stats = dict(out.stats)
    stats["realtime_factor"] = realtime_factor
    stats["kernels"] = kind
    if guest_setup:
        stats["report"] = out.reports
    for problem, what in (
        ("tx_overflow", "the emulated output UART dropped bytes (a tick wrote more than it holds)"),
        ("display_tx_overflow", "the emulated display UART dropped bytes (it is emptied after "
                                "every tick: a tick wrote more than it holds)"),
        ("driver_alloc_bytes", "the guest driver allocated between ticks (the app's heap is "
                               "not the board's)"),
    ):  # fmt: skip
        if stats.get(problem):
            raise EmulatorError(f"{what}: {problem} = {stats[problem]}")
    if not stats.get("float32"):
        raise EmulatorError("the emulated Cortex-M4F's floats are not float32: wrong build")
    return stats


def _execute(elf, call, workdir, progress, timeout_s, n):
    """Boot the emulated board, run `call` (MicroPython source) through its raw REPL; (the
    parsed GuestOutput, QEMU's exit status, wall seconds). If `call` raises, the REPL runs
    AFTER_ERROR next, which ends QEMU with EXIT_DRIVER_ERROR (the traceback is in .other)."""
    stdin = b"\x01" + call.encode() + b"\x04" + b"\x01" + AFTER_ERROR
    out = GuestOutput(progress)
    rc, wall = run_guest(
        qemu_command(elf), out, timeout_s, "the emulated Cortex-M4F", n, stdin,
        workdir, start_marker=">OK",
    )  # fmt: skip
    return out, rc, wall
