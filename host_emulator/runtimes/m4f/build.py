"""Build the emulated Cortex-M4F: MicroPython's qemu port for our board definition
(boards/M4F_INS: QEMU mps2-an386, Cortex-M4 with fpv4-sp-d16, hard float, float32 MicroPython),
with the `m4f` module (usermod/) and, frozen, the firmware exactly as the board image freezes
it plus the emulated board and its driver (manifest.py).

Out of tree, from common.toolchain's MicroPython source (MICROPY_DIR) with its own mpy-cross,
into build/m4f/ (build/m4f-heap<N>/ for another GC heap size); make decides what is stale, so
a second build with nothing changed takes a second.
"""

import hashlib
import pathlib
import shutil
import time

from common import progress as progress_lines
from common import toolchain
from common.errors import EmulatorError

HERE = pathlib.Path(__file__).resolve().parent
BOARD_DIR = HERE / "boards" / "M4F_INS"
MANIFEST = HERE / "manifest.py"
USER_C_MODULES = HERE / "usermod"
VM_OPTIONS = HERE.parents[2] / "tools" / "image" / "boards" / "ins_vm.h"
BUILD_DIR = toolchain.BUILD_ROOT / "m4f"

# The firmware's heap is the board's: 91,664 bytes on the WEACT_F411_BLACKPILL image (`make
# image` reports it; tests/tools/test_image_build.py keeps the two equal). The build's heap adds
# a reserve for the emulated board's objects (its modules, peripherals, C handles, the driver's
# buffers, the UARTs' transmit buffers and the stimulus record's module: 10,656 bytes
# measured), sized so that the ballast the driver sets aside for the rest
# (emulated_board/mpy/emulate_m4f.py) stays under a few hundred bytes: the collector scans a
# ballast like any object, which would inflate every gc.collect().
BOARD_HEAP_BYTES = 91_664
EMULATOR_RESERVE_BYTES = 11_040
GC_HEAP_BYTES = BOARD_HEAP_BYTES + EMULATOR_RESERVE_BYTES  # MICROPY_HEAP_SIZE of the build


def build_dir(gc_heap_bytes=None):
    """build/m4f; build/m4f-heap<N> for a build that differs from it only in the size of its GC
    heap (MICROPY_HEAP_SIZE = N bytes; e.g. bench/cpi.py's, sized as the NUCLEO-F401RE's)."""
    if gc_heap_bytes is None or gc_heap_bytes == GC_HEAP_BYTES:
        return BUILD_DIR
    return toolchain.BUILD_ROOT / f"m4f-heap{int(gc_heap_bytes)}"


def firmware_elf(gc_heap_bytes=None):
    return build_dir(gc_heap_bytes) / "firmware.elf"


def build(progress=print, gc_heap_bytes=None):
    """Build (or bring up to date) the emulated board's firmware; returns the ELF's path.
    gc_heap_bytes: another size of the GC heap than GC_HEAP_BYTES (a build of its own).
    EmulatorError with what to do when the toolchain or the build fails."""
    heap = GC_HEAP_BYTES if gc_heap_bytes is None else int(gc_heap_bytes)
    if not 16 * 1024 <= heap <= 1024 * 1024 or heap % 4:
        raise EmulatorError(f"a GC heap of {heap} bytes: give a multiple of 4, 16 KB to 1 MB")
    out = build_dir(heap)
    try:
        toolchain.ensure()
        mpy_cross = toolchain.mpy_cross()
        src = toolchain.micropython_dir()
    except toolchain.ToolchainError as e:
        raise EmulatorError(f"cannot build the emulated Cortex-M4F: {e}") from None
    args = [
        "-C", str(src / "ports" / "qemu"),
        "BOARD=M4F_INS",
        f"BOARD_DIR={BOARD_DIR}",
        f"BUILD={out}",
        f"MICROPY_MPYCROSS={mpy_cross}",
        f"FROZEN_MANIFEST={MANIFEST}",
        f"USER_C_MODULES={USER_C_MODULES}",
        f"MICROPY_HEAP_SIZE={heap}",
        # the VM options the board images are built with (tools/image/boards/ins_vm.h)
        f"CFLAGS_EXTRA={toolchain.C_FLOAT_FLAGS} -include {VM_OPTIONS}",
    ]  # fmt: skip
    elf = out / "firmware.elf"
    t = time.perf_counter()
    with toolchain.locked(toolchain.BUILD_ROOT / "locks" / f"{out.name}.lock"):
        _clean_if_configuration_changed(args, out)
        if progress and not elf.exists():
            progress(ANNOUNCE.format(jobs=toolchain.jobs()))
        on_line, counter = _compile_counter(bool(progress))
        try:
            toolchain.make(
                args,
                "the emulated Cortex-M4F (qemu port)",
                toolchain.BUILD_ROOT / "logs" / f"{out.name}.log",
                on_line,
            )
        except toolchain.ToolchainError as e:
            raise EmulatorError(str(e)) from None
        finally:
            counter.end()
    if progress and time.perf_counter() - t > 5:
        progress(f"built {elf} in {time.perf_counter() - t:.0f} s")
    return elf


# A build from scratch takes about 45 s of CPU (measured: 43 s; 58 s of wall time with
# make -j2 on two cores that other jobs shared): its wall time depends on the cores and their
# load, so the announcement gives the CPU time and the counter shows how far make got.
ANNOUNCE = "building the emulated Cortex-M4F once: about 45 s of CPU, make -j{jobs}"
STEPS = ("CC", "MPY", "GEN", "LINK")  # make's lines worth a redraw


def _compile_counter(enabled):
    """(on_line for make's output, its Counter): what make has compiled so far."""
    counter = progress_lines.Counter("m4f build", enabled=enabled)
    n = {"CC": 0, "MPY": 0}

    def on_line(line):
        step, _, what = line.strip().partition(" ")
        if step not in STEPS:  # an up-to-date build says nothing worth a line
            return
        if step in n:
            n[step] += 1
        counter(_step_text(step, what, n))

    return on_line, counter


def _step_text(step, what, n):
    if step == "GEN":  # the headers: qstr.i.last preprocesses every source (~10 s)
        return f"generating {pathlib.Path(what).name}"
    if step == "LINK":
        return "linking firmware.elf"
    return f"{n['CC']} C files, {n['MPY']} frozen modules compiled"


def _clean_if_configuration_changed(args, out):
    """make tracks sources, not flags: a changed make command line or board definition starts
    the build afresh."""
    h = hashlib.sha256("\n".join(args).encode())
    for p in sorted(BOARD_DIR.iterdir()):
        h.update(p.read_bytes())
    stamp = out / "configuration.sha256"
    if stamp.exists() and stamp.read_text() == h.hexdigest():
        return
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    stamp.write_text(h.hexdigest())
