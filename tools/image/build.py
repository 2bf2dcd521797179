"""Build a MicroPython image with the firmware frozen in (docs/image.md).

    build(board) -> report dict; the image files in out/image/<board>/

Steps: the toolchain (common.toolchain.ensure: Debian's arm-none-eabi-gcc), the MicroPython
tree (micropython_dir(), v1.28.0) and its own mpy-cross; then, in build/image/<board>/:

    gen/fwid.py       the firmware id module (tools/image/fwid.py), rewritten only when its
                      text changes, so an unchanged firmware leaves make nothing to do
    gen/manifest.py   include()s firmware/manifest.py and adds gen/fwid.py: the FROZEN_MANIFEST
    obj/              make -C <tree>/ports/stm32 BUILD=obj ...: every object, firmware.elf/.map
    key.json          what obj/ was built from (tree, version, board, the board definition's
                      files, compiler); a change empties obj/ first, since make alone would
                      not notice another tree, nor remake the module table when only the
                      board's mpconfigboard.h changed
    build.log         make's output

The source tree is checked before and after make (every file's size and mtime): a build that
wrote into it fails. The outputs (firmware.dfu, firmware.hex, firmware.bin: sector 0 and the
code at 0x08010000 in one file, the gap over the filesystem's sectors 1-3 filled with 0xFF)
and budget.json go to the output folder; over budget (less than 32 KB of the code region left,
tools/image/budget.py), only budget.json goes there and the build fails saying why.
"""

import json
import os
import pathlib
import re
import shutil
import subprocess
import time

from common import toolchain
from tools.image import budget, fwid
from tools.image.boards import BOARDS, DEFAULT_BOARD

BUILD_ROOT = toolchain.BUILD_ROOT / "image"
OUT_ROOT = toolchain.REPO / "out" / "image"
IMAGE_FILES = ("firmware.dfu", "firmware.hex", "firmware.bin")
REPORT = "budget.json"
FLASH_BASE = 0x08000000  # sector 0: the vector table (TEXT0_ADDR)
CC_STEP = 100  # print a progress line every this many compiled C files
TAIL_LINES = 20  # lines of make's log quoted when it fails
CLIP = 240  # characters of one quoted line (make prints whole command lines)
SHARED_SUFFIXES = (".h", ".ld")  # files beside the board folders that the definitions include


class ImageError(Exception):
    """The image could not be built or is over budget; the message says what to do."""


def snapshot(tree):
    """{relative path: (size, mtime_ns)} of every file under tree, plus its directories."""
    out = {}
    for root, _dirs, files in os.walk(tree):
        rel = os.path.relpath(root, tree)
        out[rel + "/"] = None
        for name in files:
            st = os.lstat(os.path.join(root, name))
            out[os.path.join(rel, name)] = (st.st_size, st.st_mtime_ns)
    return out


def tree_changes(before, after):
    """Paths created, changed or removed between two snapshots, sorted."""
    return sorted(p for p in before.keys() | after.keys() if before.get(p) != after.get(p))


def write_if_changed(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.is_file() and path.read_text() == text:
        return False
    path.write_text(text)
    return True


def _gcc_version():
    try:
        proc = subprocess.run(["arm-none-eabi-gcc", "--version"], capture_output=True, text=True)
    except OSError:
        return "missing"
    return proc.stdout.splitlines()[0] if proc.stdout else "unknown"


def _progress(log, t0):
    """A callback for make's output lines that prints what the build is doing."""
    state = {"cc": 0, "mpy": 0, "said": set()}

    def say(key, text):
        if key not in state["said"]:
            state["said"].add(key)
            log(f"  {text} ({time.monotonic() - t0:.0f} s)")

    def on_line(line):
        if line.startswith("CC "):
            state["cc"] += 1
            if state["cc"] == 1:
                say("cc", "compiling MicroPython's C sources")
            elif state["cc"] % CC_STEP == 0:
                log(f"  compiled {state['cc']} C files ({time.monotonic() - t0:.0f} s)")
        elif line.startswith("GEN ") and "/genhdr/" in line:
            say("gen", "generating MicroPython's headers (pins, qstrs, version)")
        elif line.startswith("MPY "):
            state["mpy"] += 1
            say("mpy", "compiling the frozen modules with mpy-cross")
        elif line.startswith("GEN ") and line.rstrip().endswith("frozen_content.c"):
            say("freeze", "freezing the firmware into frozen_content.c")
        elif line.startswith("LINK "):
            say("link", "linking firmware.elf")
        elif line.startswith("GEN ") and line.rstrip().endswith("firmware.dfu"):
            say("dfu", "writing firmware.dfu and firmware.hex")

    return on_line, state


def run_make(args, log_path, on_line):
    """make with args, its output to log_path and, line by line, to on_line."""
    log_path.parent.mkdir(parents=True, exist_ok=True)
    try:
        with open(log_path, "w") as logf:
            proc = subprocess.Popen(
                ["make", "-j", toolchain.jobs(), *args],
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                text=True,
                errors="replace",
                env=toolchain.version_env(),
            )
            for line in proc.stdout:
                logf.write(line)
                on_line(line)
            return proc.wait()
    except OSError as e:
        raise ImageError(f"cannot run make: {e.strerror}. Install it (Debian: apt-get install "
                         "make).") from None  # fmt: skip


def explain_failure(log_text, log_path, board):
    """The ImageError for a failed make, from its log."""
    over = re.findall(r"region [`'](\w+)' overflowed by (\d+) bytes", log_text)
    if over:
        what = ", ".join(f"{name} by {int(n):,} bytes" for name, n in over)
        return ImageError(
            f"the image for {board} is over budget: the linker says {what} (FLASH_TEXT is the "
            "448 KB code region, sectors 4-7; FLASH_START the 16 KB vector sector; RAM the 112 KB "
            "of RAM). "
            "Freeze less (firmware/manifest.py) or turn MicroPython features off in the board "
            f"definition, then build again. Full log: {log_path}"
        )
    lines = [_clip(line) for line in log_text.rstrip().splitlines()]
    tail = lines[-TAIL_LINES:]
    first_error = next((line for line in lines if "error:" in line.lower()), None)
    if first_error and first_error not in tail:
        tail = [first_error, "..."] + tail
    tail = "\n".join(tail)
    return ImageError(
        f"building the image for {board} failed (full log: {log_path}); its last lines:\n{tail}"
    )


def _clip(line):
    return line if len(line) <= CLIP else line[:CLIP] + f" ... ({len(line)} characters)"


def combined_bin(part0, addr0, part1, addr1):
    """One flat image from 0x08000000: part0 at addr0, part1 at addr1, gaps of 0xFF."""
    if addr1 < addr0 + len(part0):
        raise ImageError("firmware0.bin overlaps firmware1.bin")
    return part0 + b"\xff" * (addr1 - addr0 - len(part0)) + part1


def _board(name):
    if name not in BOARDS:
        raise ImageError(f"unknown board {name!r}; the boards are: {', '.join(BOARDS)}")
    return BOARDS[name]


def build(board=DEFAULT_BOARD, out_dir=None, log=print, build_root=BUILD_ROOT, board_dir=None):
    """Build the image for `board` into build_root/<board>, copy it to out_dir (default
    out/image/<board>) and return the report (also out_dir/budget.json). board_dir overrides
    the board definition's folder (tests use it). ImageError when it fails or is over budget;
    toolchain.ToolchainError when the toolchain or the MicroPython tree is missing. One build
    of a board's tree at a time (toolchain.locked)."""
    _board(board)
    with toolchain.locked(pathlib.Path(build_root) / f"{board}.lock"):
        return _build(board, out_dir, log, build_root, board_dir)


def _build(board, out_dir, log, build_root, board_dir):
    spec = _board(board)
    t0 = time.monotonic()
    build_dir = pathlib.Path(build_root) / board
    out_dir = pathlib.Path(out_dir) if out_dir else OUT_ROOT / board
    board_dir = pathlib.Path(board_dir) if board_dir else spec.board_dir

    src, version, port, mpy_cross = _micropython_tree(board, board_dir, log)
    ident = fwid.host_id(src=src)
    gen = build_dir / "gen"
    _write_generated(gen, ident, board, version)
    if spec.pins_from and board_dir is not None:
        pins_board = port / "boards" / spec.pins_from
        board_dir = _assemble_board_dir(board_dir, build_dir / "boarddef" / board, pins_board)
    obj = build_dir / "obj"
    _check_build_key(build_dir, obj, src, version, board, board_dir, log)

    args = ["-C", str(port), f"BUILD={obj}"]
    args += [f"BOARD_DIR={board_dir}"] if board_dir else [f"BOARD={board}"]
    args += [f"MICROPY_MPYCROSS={mpy_cross}", f"FROZEN_MANIFEST={gen / 'manifest.py'}"]
    args += [f"CFLAGS_EXTRA={toolchain.C_FLOAT_FLAGS}"]
    log_path = build_dir / "build.log"
    cold = not (obj / "firmware.elf").exists()
    log(
        f"image {board}: make in {obj} (log: {log_path}); firmware {ident['version']} "
        f"id {ident['crc32']}, {ident['files']} modules + fwid frozen"
        + ("; a first build takes 70-90 s on 2 cores" if cold else "")
    )
    state = _make_checked(src, args, log_path, board, log, t0)
    rebuilt = state["cc"] > 0 or "link" in state["said"]
    if not rebuilt:
        log(f"  up to date: nothing to rebuild ({time.monotonic() - t0:.1f} s)")

    figures = budget.measure(obj / "firmware.elf", obj / "firmware.map")
    report = {
        "board": board,
        "description": spec.description,
        "micropython": version,
        "firmware": {**ident, "module": fwid.MODULE},
        "figures": figures,
        "min_heap_bytes": budget.MIN_HEAP_BYTES,
        "problems": budget.problems(figures),
        "build_dir": str(build_dir),
        "elf": str(obj / "firmware.elf"),
        "rebuilt": rebuilt,
        "seconds": round(time.monotonic() - t0, 1),
    }
    out_dir.mkdir(parents=True, exist_ok=True)
    log(f"image {board}: budget")
    for line in budget.report_lines(figures):
        log("  " + line)
    if report["problems"]:
        _refuse_over_budget(out_dir, report, board)
    _write_image(obj, out_dir, figures["code_region_origin"])
    report["outputs"] = {name: str(out_dir / name) for name in IMAGE_FILES}
    report["seconds"] = round(time.monotonic() - t0, 1)
    (out_dir / REPORT).write_text(json.dumps(report, indent=1) + "\n")
    log(f"image {board}: {out_dir}/firmware.dfu, .hex, .bin and {REPORT} "
        f"({report['seconds']:.1f} s)")  # fmt: skip
    return report


def _micropython_tree(board, board_dir, log):
    """(tree, its version, its ports/stm32, its mpy-cross): the toolchain ensured, the tree
    checked for the port and the board; ImageError when it lacks them."""
    log(f"image {board}: checking the toolchain (arm-none-eabi-gcc, MicroPython tree)")
    toolchain.ensure()
    src = toolchain.micropython_dir()
    version = ".".join(map(str, toolchain.check_version(src)))
    port = src / "ports" / "stm32"
    if not (port / "Makefile").is_file():
        raise ImageError(f"the MicroPython tree {src} has no ports/stm32: set MICROPY_DIR to a "
                         "full MicroPython v1.28.0 tree")  # fmt: skip
    if board_dir is None and not (port / "boards" / board).is_dir():
        raise ImageError(f"the MicroPython tree {src} has no board folder {board}")
    log(f"image {board}: MicroPython {version} from {src}; building its mpy-cross")
    mpy_cross = toolchain.mpy_cross()
    return src, version, port, mpy_cross


def _write_generated(gen, ident, board, version):
    """gen/fwid.py and gen/manifest.py (the FROZEN_MANIFEST), each rewritten only when its
    text changes."""
    write_if_changed(gen / "fwid.py", fwid.module_source(ident, board, version))
    write_if_changed(
        gen / "manifest.py",
        "# Generated by python -m tools.image build: the firmware's freeze list and the module\n"
        "# that says which firmware the image carries (tools/image/fwid.py).\n"
        f"include({str(fwid.FIRMWARE_MANIFEST)!r})\n"
        f"module('fwid.py', base_path={str(gen)!r})\n",
    )


def shared_board_files(board_dir):
    """The files beside the board folders that their definitions include (tools/image/boards/
    *.h: the features left out; *.ld: the linker script with our flash layout)."""
    parent = pathlib.Path(board_dir).parent
    return sorted(f for f in parent.iterdir() if f.is_file() and f.suffix in SHARED_SUFFIXES)


def _assemble_board_dir(board_dir, assembled, pins_board):
    """The board folder `assembled`: ours with pins_board's pins.csv, and beside it the files
    the board folders share (shared_board_files); returns it."""
    # the port wants pins.csv inside BOARD_DIR: the board folder is assembled in the build
    # tree from ours and the MicroPython tree's pins.csv (named as the board: BOARD)
    for f in sorted(board_dir.iterdir()):
        if f.is_file():
            write_if_changed(assembled / f.name, f.read_text())
    write_if_changed(assembled / "pins.csv", (pins_board / "pins.csv").read_text())
    for f in shared_board_files(board_dir):
        write_if_changed(assembled.parent / f.name, f.read_text())
    return assembled


def board_files_digest(board_dir):
    """{name: sha256} of the board definition's files: those of its folder and the shared ones
    beside it (shared_board_files: its mpconfigboard.h and .mk name them). A
    feature turned off in mpconfigboard.h or .mk needs a clean build: make remakes the qstrs
    when the header changes, but not the module table, and the link then fails on the missing
    modules; a changed linker script relinks nothing either."""
    import hashlib

    if board_dir is None:
        return {}
    board_dir = pathlib.Path(board_dir)
    files = [f for f in sorted(board_dir.iterdir()) if f.is_file()]
    files += shared_board_files(board_dir)
    return {
        (f.name if f.parent == board_dir else "../" + f.name):
            hashlib.sha256(f.read_bytes()).hexdigest()[:16]
        for f in files
    }  # fmt: skip


def _check_build_key(build_dir, obj, src, version, board, board_dir, log):
    """Write key.json (what obj/ is built from); empty obj/ first when that changed."""
    key = {
        "micropython_dir": str(src),
        "micropython": version,
        "board": board,
        "board_dir": str(board_dir) if board_dir else None,
        "board_files": board_files_digest(board_dir),
        "compiler": _gcc_version(),
        "cflags_extra": toolchain.C_FLOAT_FLAGS,
    }
    key_path = build_dir / "key.json"
    if obj.exists() and (not key_path.is_file() or json.loads(key_path.read_text()) != key):
        log(f"image {board}: the tree, the board definition or the compiler changed since the "
            "last build: starting afresh")  # fmt: skip
        shutil.rmtree(obj)
    key_path.write_text(json.dumps(key, indent=1) + "\n")


def _make_checked(src, args, log_path, board, log, t0):
    """Run make with its progress logged; the progress state. ImageError when make wrote into
    the source tree or failed."""
    before = snapshot(src)
    on_line, state = _progress(log, t0)
    rc = run_make(args, log_path, on_line)
    changed = tree_changes(before, snapshot(src))
    if changed:
        more = f" and {len(changed) - 5} more" if len(changed) > 5 else ""
        shown = ", ".join(changed[:5]) + more
        raise ImageError(
            f"the build wrote into the MicroPython source tree {src} ({shown}); it must stay "
            "untouched (builds go to build/image). Restore the tree (e.g. from its VENDOR.md "
            "commit) and report this."
        )
    if rc != 0:
        raise explain_failure(log_path.read_text(errors="replace"), log_path, board)
    return state


def _refuse_over_budget(out_dir, report, board):
    """Remove the image files from out_dir, write the report and raise ImageError."""
    for name in IMAGE_FILES:
        (out_dir / name).unlink(missing_ok=True)  # never leave an older image to flash
    (out_dir / REPORT).write_text(json.dumps(report, indent=1) + "\n")
    raise ImageError(
        f"the image for {board} is over budget: " + "; ".join(report["problems"]) + ". "
        f"No image was written (figures: {out_dir / REPORT}). Freeze less "
        "(firmware/manifest.py) or turn MicroPython features off in the board definition."
    )


def _write_image(obj, out_dir, code_origin):
    """firmware.dfu, firmware.hex and the flat firmware.bin from obj/ into out_dir (the code,
    firmware1.bin, at code_origin: the code region's, TEXT1_ADDR)."""
    # each written whole or not at all: another process (a parallel test worker, the twin)
    # may be reading the image that a build of the same tree rewrites
    from common.errors import write_atomic

    write_atomic(out_dir / "firmware.dfu", (obj / "firmware.dfu").read_bytes())
    write_atomic(out_dir / "firmware.hex", (obj / "firmware.hex").read_bytes())
    flat = combined_bin(
        (obj / "firmware0.bin").read_bytes(), FLASH_BASE, (obj / "firmware1.bin").read_bytes(),
        code_origin,
    )  # fmt: skip
    write_atomic(out_dir / "firmware.bin", flat)
