"""Run a piece of MicroPython on the emulated Cortex-M4F and get what it printed: for tests and
measurements (instruction counts of one function, float32 behaviour), as runtimes/mpy_unix/vm.py
does for the unix VM.

The code runs through the raw REPL with the frozen modules importable (the firmware's, the
emulated board's, `m4f`); `m4f.init()` has run, so `m4f.icount()` counts from 0. Host files are
reachable through semihosting paths relative to `cwd`. `gc_heap_bytes` runs it on a build that
differs only in the size of its GC heap (build.build_dir).
"""

import subprocess

from host_emulator.runtimes.m4f import build as m4f_build


def run(code, timeout_s=120, cwd=None, gc_heap_bytes=None, kernels=None):
    """stdout of `code` (a str) run on the emulated board; AssertionError with the output if it
    raised or QEMU failed. kernels="native": /flash is mounted first (FAT on the RAM disk, as
    the m4f runtime does) with the armv7emsp navk.mpy in /flash/lib, on sys.path, so that `import
    navk` loads the native module as on a board; "python": /flash without it; None (default):
    no /flash at all (nothing runs before `code` but m4f.init())."""
    from host_emulator import runtimes
    from host_emulator.runtimes.m4f import qemu_command

    elf = m4f_build.build(progress=None, gc_heap_bytes=gc_heap_bytes)
    body = "import m4f\r\nm4f.init()\r\n"
    if kernels is not None:
        runtimes.check_kernels(kernels)
        navk = str(runtimes.native_module("armv7emsp")) if kernels == "native" else None
        body += f"import emulate_m4f\r\nemulate_m4f.mount_flash(None, {navk!r})\r\n"
    body += code.replace("\n", "\r\n") + "\r\nm4f.exit(0)\r\n"
    stdin = b"\x01" + body.encode() + b"\x04" + b"\x01import m4f\r\nm4f.exit(4)\r\n\x04"
    proc = subprocess.run(
        qemu_command(elf), input=stdin, capture_output=True, timeout=timeout_s, cwd=cwd
    )
    text = proc.stdout.decode("utf-8", "replace")
    i = text.find(">OK")
    out = text[i + 3 :] if i >= 0 else text
    if proc.returncode != 0:
        raise AssertionError(f"the emulated Cortex-M4F failed ({proc.returncode}):\n{out}")
    return out.replace("\r\n", "\n")
