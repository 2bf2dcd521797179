"""The mpy_unix runtime: the unmodified firmware loop in the real MicroPython VM (the unix port
from PyPI, a double-precision build), fed from a stimulus, counting the GC blocks every tick
allocates.

The VM (`micropython`, MicroPython 1.29's unix port, see vm.py) runs emulated_board/mpy/emulate.py,
which imports the firmware's own `board.py`, drivers and `app.py` on top of the emulated
`machine` and `time` beside it (emulated_board/mpy/machine.py, emulated_board/mpy/time.py: pins, SPI
with the BMI055 register model of emulated_board/mpy/bmi055_model.py, UARTs, the timer, the
watchdog, a virtual clock in us since power-on).
Each stimulus record is replayed exactly as the cpython runtime replays it, so both runtimes
see the same input at the same virtual times.

What differs from the CPython runtime: the VM's floats are doubles (the board's are float32,
which the CPython runtime reproduces bit for bit), so integer output (counters, raw sensor
fields, flags, GNSS fix fields, navigation state) is the same and float output agrees to a
tolerance. What it adds: `blocks_per_tick`, the GC blocks each `App.service()` allocated
(gc.mem_alloc() difference with the collector off; one block = one boxed float on the board
and in the VM, docs/requirements.md, time budget), with the navigation state per tick to split them
by phase.

The screen: with the display setting on, what the firmware's status page writes to the display
UART (board.PINS["display_uart"]) is taken by the VM's driver after start-up and after every
tick and emptied there (so its transmit buffer never fills), and comes back as
`FirmwareRun.display` and `display_marks`, as the cpython runtime gives them. No screen answers
in the VM: no `OK` is fed back into the UART (the cpython runtime feeds the emulated UsartGPU's),
so the page takes the screen as absent, which is no fault; the bytes it sends do not depend on
the answers (its `oks` stay 0 in stats["display_oks"]). The VM's doubles can change a digit
of a field computed in floating point (attitude, speed, position, the 1-sigma from the
covariance) where the frames differ by a step (below); the page's own work is in integers.

Heap: the VM heap also holds the firmware's compiled bytecode (~85 KB on this 64-bit VM) and
the emulator's buffers (~200 KB live in all). gc.mem_alloc() scans the whole heap twice a
tick, so the heap size sets the speed: 512 KB (default) runs 90 s of urban_drive in ~10 s,
2 MB in ~26 s. Garbage is collected between ticks, never during one.
"""

import os
import pathlib

import numpy as np

from common.errors import EmulatorError
from common.firmware_env import FIRMWARE_DIR
from common.proto import config as board_config
from common.proto import stimulus as stim_mod
from common.proto.mpy.feed_protocol import EXIT_FIRMWARE_ERROR
from host_emulator import runtimes
from host_emulator.emulated_board import EMULATE
from host_emulator.runtimes import FirmwareRun
from host_emulator.runtimes.guest_output import (
    GuestOutput,
    display_marks,
    firmware_error,
    run_guest,
)
from host_emulator.runtimes.mpy_unix import vm

HEAP_KB = 512
# With the Python reference kernels every float is boxed: the yaw estimator's step at a fix
# alone boxes about 300 KB in one tick (gc.mem_alloc around yaw_gsf.gsf_step in this VM)
PYTHON_KERNELS_HEAP_KB = 2048


def _default_timeout_s(stim):
    """Generous: the VM runs ~8x faster than real time on a desktop (measured)."""
    return 60.0 + 1.0 * stim.duration_s


def _block_stats(blocks):
    if not len(blocks):
        return {"blocks_mean": None, "blocks_p99": None, "blocks_max": None}
    return {
        "blocks_mean": float(np.mean(blocks)),
        "blocks_p99": float(np.percentile(blocks, 99)),
        "blocks_max": int(np.max(blocks)),
    }


def _memory_hint(heap_kb):
    return (
        f"(the VM heap is {heap_kb} KB and the collector is off during a tick: a tick that "
        "allocates more than is free runs out; a larger heap_kb tells whether the "
        "firmware or the heap size is at fault)"
    )


def run(stim, workdir, config_overrides=None, progress=None, heap_kb=None, timeout_s=None,
        kernels=None):  # fmt: skip
    """Run the firmware in the MicroPython VM over a whole stimulus; returns a FirmwareRun.

    stim: a `stimulus.Stimulus` (written to workdir/stimulus.bin for the VM) or the path of a
        stimulus file (read here, which checks its CRC, and given to the VM as it is).
    workdir: the emulated board's flash (workdir/flash/ins.cfg: the configuration, the
        stimulus header's "config" plus `config_overrides`, as the cpython runtime) and the
        VM's output files (workdir/vm/).
    progress(k, n): called as the VM reports ticks done (every 1000 ticks and at the end).
    heap_kb: the VM's heap (default HEAP_KB, PYTHON_KERNELS_HEAP_KB with the Python kernels);
    timeout_s: wall-time limit (default 60 s + the stimulus duration).
    kernels: "native" (the x64 navk.mpy on the VM's path, built on demand), "python" (no
        navk) or None (the default: native unless $INS_KERNELS says python).

    The FirmwareRun's stats hold the blocks' mean/p99/max, overall and by navigation state
    ("blocks_by_state"), and the run's counters; its extra attribute `nav_state` is the
    navigation state after each tick (uint8, 1 aligning, 2 navigating).

    FirmwareError (with .tick, .t_s, .vm_traceback) if the firmware raises in the VM;
    EmulatorError if the VM cannot start, fails otherwise, or times out."""
    if heap_kb is None:
        kind = runtimes.check_kernels(kernels or runtimes.default_kernels())
        heap_kb = HEAP_KB if kind == "native" else PYTHON_KERNELS_HEAP_KB
    workdir = pathlib.Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    stim, stim_path = _stimulus_file(stim, workdir)
    cfg_path = board_config.write_flash(workdir, board_config.run_values(stim, config_overrides))
    out_dir = workdir / "vm"
    out_dir.mkdir(exist_ok=True)
    for name in ("out.bin", "blocks.bin", "state.bin", "display.bin", "display_n.bin"):
        (out_dir / name).unlink(missing_ok=True)
    try:
        exe = vm.micropython_exe()
    except RuntimeError as e:
        raise EmulatorError(f"cannot run the MicroPython VM: {e}") from None
    kind = runtimes.check_kernels(kernels or runtimes.default_kernels())
    cmd = [exe, "-X", f"heapsize={int(heap_kb)}K", str(EMULATE), str(FIRMWARE_DIR),
           str(stim_path.resolve()), str(cfg_path.resolve()), str(out_dir.resolve())]  # fmt: skip
    timeout_s = _default_timeout_s(stim) if timeout_s is None else timeout_s
    out = GuestOutput(progress)
    n = len(stim)
    rc, wall = run_guest(cmd, out, timeout_s, "the MicroPython VM", n, env=vm.env(kind))
    if out.error_tick is not None and rc == EXIT_FIRMWARE_ERROR:
        raise firmware_error(out, stim, "the MicroPython VM", _memory_hint(heap_kb))
    if rc != 0 or out.stats is None:
        tail = "\n".join(out.other[-20:]) or "(no output)"
        raise EmulatorError(f"the MicroPython VM failed (exit status {rc}):\n{tail}")
    blocks = np.fromfile(out_dir / "blocks.bin", dtype="<i4").astype(np.int64)
    state = np.fromfile(out_dir / "state.bin", dtype=np.uint8)
    if len(blocks) != n or len(state) != n or out.stats.get("ticks") != n:
        raise EmulatorError(
            f"the MicroPython VM reported {len(blocks)} ticks of {n}: its output is incomplete"
        )
    stats = _stats(out.stats, blocks, state, stim.duration_s / wall if wall > 0 else None, kind)
    display, marks = _display(out_dir, stats, n)
    result = FirmwareRun(
        "mpy_unix", (out_dir / "out.bin").read_bytes(), out.console, n, wall, blocks, stats
    )
    result.nav_state = state  # per tick, after it (1 aligning, 2 navigating)
    result.display, result.display_marks = display, marks
    return result


def _stimulus_file(stim, workdir):
    """(the Stimulus, the path of its file for the VM): a path is read here, which checks its
    CRC, and given to the VM as it is; a Stimulus is written to workdir/stimulus.bin."""
    if isinstance(stim, (str, os.PathLike)):
        return stim_mod.read(stim), pathlib.Path(stim)
    path = workdir / "stimulus.bin"
    stim.write(path)
    return stim, path


def _stats(reported, blocks, state, realtime_factor, kind):
    """The FirmwareRun's stats from the VM's S line and the per-tick blocks; EmulatorError if
    a UART's transmit buffer overflowed (the counts would be wrong)."""
    stats = {
        "overruns": reported["overruns"],
        "gnss_rx_overflow": reported["gnss_rx_overflow"],
        "nmea_rejected": reported["nmea_rejected"],
        "wdt_feeds": reported["wdt_feeds"],
        "imu_error": reported["imu_error"],
        "config_status": reported["config_status"],
        **_block_stats(blocks),
        "blocks_by_state": block_stats(blocks, state),
        "ticks_navigating": int(np.sum(state == 2)),
        "app_gc_runs": reported["app_gc_runs"],  # collections inside a tick: 0, else counts are off
        "negative_ticks": reported["negative_ticks"],
        "vm_gc_collects": reported["gc_collects"],
        "bytes_per_block": reported["bytes_per_block"],
        "heap_bytes": reported["heap_bytes"],
        "live_bytes_at_start": reported["live_bytes_at_start"],
        "tx_overflow": reported["tx_overflow"],
        **{k: v for k, v in reported.items() if k.startswith("display_")},
        "realtime_factor": realtime_factor,
        "kernels": kind,
    }
    if stats["tx_overflow"]:
        raise EmulatorError(
            f"the emulated output UART dropped {stats['tx_overflow']} bytes (its buffer is "
            "emptied between ticks): a tick wrote more than it holds"
        )
    if stats.get("display_tx_overflow"):
        raise EmulatorError(
            f"the emulated display UART dropped {stats['display_tx_overflow']} bytes (its "
            "buffer is emptied after every tick): a tick wrote more than it holds"
        )
    return stats


def _display(out_dir, stats, n):
    """(what the firmware sent to the screen, its per-tick marks) from display.bin and
    display_n.bin."""
    display = (out_dir / "display.bin").read_bytes()
    per_tick = np.fromfile(out_dir / "display_n.bin", dtype="<u2")
    if "display_batches" not in stats:
        per_tick = np.zeros(n, np.uint16)  # the page off: nothing written
    elif len(per_tick) != n:
        raise EmulatorError(
            f"the MicroPython VM reported the display bytes of {len(per_tick)} ticks of {n}"
        )
    start = stats.get("display_start_bytes", 0)
    return display, display_marks(display, per_tick, start, "the MicroPython VM")


def block_stats(blocks, state):
    """Minimum, mean, 99th percentile and maximum blocks per tick, aligning and navigating."""
    res = {}
    for name, s in (("aligning", 1), ("navigating", 2)):
        b = blocks[state == s]
        if len(b):
            res[name] = {
                "ticks": int(len(b)),
                "min": int(np.min(b)),
                "mean": float(np.mean(b)),
                "p99": float(np.percentile(b, 99)),
                "max": int(np.max(b)),
            }
    return res
