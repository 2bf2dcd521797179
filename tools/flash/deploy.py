"""Deploy a build to a board over its raw REPL: stop the firmware and reset the board into a
maintenance start (tools/flash/maintenance.py: neither its loop nor its 50 ms watchdog, which
a flash write would outlast), compare CRC-32s, copy only what changed (each file verified by
the board's own CRC-32), delete stale firmware files, upload the configuration, soft-reset and
confirm the firmware started. A board whose MicroPython image
carries this firmware frozen (tools/image: its `fwid` module) gets main.py only, and the native
kernels lib/navk.mpy (a native module cannot be frozen): built for the architecture the board
reports (sys.implementation._mpy: armv7emsp on the board, x64 on the virtual board's VM)."""

import pathlib
import time

from common.proto import serial_port, stream
from common.proto.crc import crc32
from tools.flash import build as build_mod
from tools.flash import maintenance as maint
from tools.flash.errors import (
    BoardError,
    FirmwareNotRunning,
    FlashError,
    FlashFull,
    FrozenMismatch,
    TransferCorrupted,
)
from tools.flash.repl import BoardRepl

ROOT = "/flash"
CONFIG_NAME = "ins.cfg"
CHUNK = 2048  # file bytes per raw-REPL run (up to 8 KB of source; the firmware is not running)
ATTEMPTS = 3

# Helpers defined once per session in the board's raw-REPL globals.
BOARD_HELPERS = """
import os
from binascii import crc32 as _c
_buf = bytearray(512)
def _crc(p):
    c = 0
    mv = memoryview(_buf)
    with open(p, 'rb') as f:
        while True:
            n = f.readinto(_buf)
            if not n:
                break
            c = _c(mv[:n], c)
    return c & 0xffffffff
def _ls(d, rel, want):
    for e in os.ilistdir(d):
        n, t = e[0], e[1]
        p = d + '/' + n
        r = rel + n
        if t & 0x4000:
            print('D', r)
            _ls(p, r + '/', want)
        else:
            s = os.stat(p)[6]
            print('F', r, s, _crc(p) if r in want else -1)
def _mk(p):
    try:
        os.mkdir(p)
    except OSError:
        pass
"""


def open_port(port, baud):
    """The board's serial port; FlashError with the ports that exist, or who holds it."""
    try:
        return serial_port.open_port(port, baud, 0.05, write_timeout=10)
    except serial_port.PortError as e:
        if e.kind == serial_port.MISSING:
            raise FlashError(
                f"no serial port {port}. Ports on this machine: {_ports()}. Plug the board in "
                "(its USB port, not the ST-Link) and pass its port with --port, e.g. "
                "--port /dev/ttyACM0 on Linux or --port COM5 on Windows."
            ) from None
        raise FlashError(f"{e}.") from None


def _ports():
    return ", ".join(serial_port.list_ports()) or "none"


class Board:
    """The board's filesystem seen through the raw REPL."""

    def __init__(self, repl):
        self.repl = repl
        self.helpers = False

    def _exec(self, code, what, timeout=None):
        if not self.helpers:
            self.repl.exec(BOARD_HELPERS, what="defining the deploy helpers")
            self.helpers = True
        return self.repl.exec(code, timeout=timeout, what=what).decode(errors="replace")

    def listing(self, want_crc):
        """({path: (size, crc or None)}, set of directories) under /flash."""
        out = self._exec(
            f"_ls({ROOT!r}, '', {sorted(want_crc)!r})", "listing its files", timeout=30
        )
        files, dirs = {}, set()
        for line in out.splitlines():
            parts = line.split()
            if len(parts) == 2 and parts[0] == "D":
                dirs.add(parts[1])
            elif len(parts) == 4 and parts[0] == "F":
                crc = int(parts[3])
                files[parts[1]] = (int(parts[2]), None if crc < 0 else crc)
        return files, dirs

    def statvfs(self):
        out = self._exec(f"print(*os.statvfs({ROOT!r})[:4])", "reading its free space")
        bsize, frsize, blocks, bfree = (int(x) for x in out.split())
        return {
            "cluster": frsize or bsize,
            "total": blocks * (frsize or bsize),
            "free": bfree * (frsize or bsize),
        }

    def native_arch(self):
        """The native architecture of the board's MicroPython (MP_NATIVE_ARCH_*, 0: none), -1
        when it does not say (not MicroPython)."""
        out = self._exec(ARCH_QUERY, "asking its native architecture")
        for line in out.splitlines():
            parts = line.split()
            if len(parts) == 2 and parts[0] == "ARCH":
                return int(parts[1])
        return -1

    def frozen_firmware(self):
        """What the image's frozen `fwid` module says ({"crc32", "version", "micropython",
        "board"}), or None when the image carries no frozen firmware."""
        from tools.image import fwid

        out = self._exec(fwid.BOARD_QUERY, "asking which firmware its image carries")
        return fwid.parse_board_answer(out)

    def volume(self):
        """The internal filesystem's volume: {"device_blocks", "boot": fatfs.boot_sector(...)
        (None: no FAT boot sector)}; None where the board has no pyb.Flash (not the stm32
        port, the virtual board)."""
        from tools.flash import fatfs

        out = self._exec(VOLUME_QUERY, "reading its filesystem's boot sector")
        for line in out.splitlines():
            parts = line.split()
            if parts[:1] == ["VOL"] and len(parts) == 3:
                boot = bytes.fromhex(parts[2])
                return {"device_blocks": int(parts[1]), "boot": fatfs.boot_sector(boot)}
        return None

    def walk(self):
        """(files {path: size}, dirs, unreadable dirs) under /flash, going on past errors."""
        if not getattr(self, "walker", False):
            self._exec(WALK_HELPER, "defining the listing helper")
            self.walker = True
        out = self._exec(f"_walk({ROOT!r}, '')", "listing its files", timeout=30)
        files, dirs, bad = {}, [], []
        for line in out.splitlines():
            parts = line.split()
            if len(parts) == 3 and parts[0] == "F":
                files[parts[1]] = int(parts[2])
            elif len(parts) == 2 and parts[0] in ("D", "X"):
                (dirs if parts[0] == "D" else bad).append(parts[1])
        return files, dirs, bad

    def format(self, blocks):
        """Format the internal filesystem anew (tools/flash/fatfs.empty_volume: f_mkfs's layout
        with a compact root directory): unmount /flash, write the volume's first blocks
        through pyb.Flash, sync, mount it again. Returns its statvfs."""
        from tools.flash import fatfs

        head = fatfs.empty_volume(blocks)
        code = ["import os, vfs, pyb", "_f = pyb.Flash(start=0)", f"_h = bytearray({len(head)})"]
        i = 0
        while i < len(head):  # the non-zero runs: the boot sector's fields, the FAT's first bytes
            if head[i]:
                j = i
                while j < len(head) and any(head[j : j + 8]):
                    j += 1
                code.append(f"_h[{i}:{j}] = {bytes(head[i:j])!r}")
                i = j
            i += 1
        code += [
            "os.chdir('/')",
            "try:\n vfs.umount('/flash')\nexcept OSError:\n pass",
            "_f.writeblocks(0, _h)",
            "_f.ioctl(3, 0)",
            "vfs.mount(vfs.VfsFat(_f), '/flash')",
            "os.chdir('/flash')",
        ]
        self._exec("\n".join(code), "formatting its filesystem", timeout=30)
        return self.statvfs()

    def rmdir(self, rel):
        """Remove an empty directory; False if it is not empty (or not there)."""
        out = self._exec(
            f"try:\n os.rmdir({ROOT + '/' + rel!r})\n print('Y')\nexcept OSError:\n print('N')",
            f"removing {rel}/",
        )
        return out.strip() == "Y"

    def mkdir(self, rel):
        self._exec(f"_mk({ROOT + '/' + rel!r})", f"creating {rel}")

    def remove(self, rel):
        self._exec(f"os.remove({ROOT + '/' + rel!r})", f"deleting {rel}")

    def crc(self, rel):
        return int(self._exec(f"print(_crc({ROOT + '/' + rel!r}))", f"checking {rel}"))

    def read(self, rel):
        """The file's bytes, or None if it does not exist (mpremote's fs_readfile)."""
        data = self.repl.fs("fs_readfile", ROOT + "/" + rel, what=f"reading {rel}", missing=True)
        return None if data is None else bytes(data)

    def write(self, rel, data):
        """Write data to /flash/rel as mpremote's fs_writefile does (`f=open(...)`, then a run
        `w(b'...')` per CHUNK bytes, `f.close()`), each run ending with `os.sync()`; the
        board's CRC-32 of what it wrote. The sync: a write leaves the port's flash cache dirty,
        and its storage interrupt erases the cached sector within 512 ms, the core stalled
        250 ms; a UART REPL (the NUCLEO's) loses what arrives meanwhile, the next run's
        characters, and the raw-paste flow control stops (measured on the twin: 159-373
        characters lost, 3 deploys of lib/navk.mpy in 3 failed). Synced within the run (the
        block device's cache only: FatFs keeps its FAT sector until the close), the cache is
        clean when the host sends again: one sector erase per run."""
        path = ROOT + "/" + rel
        self.repl.exec(f"import os\n_s = getattr(os, 'sync', None) or (lambda: 0)\n"
                       f"f=open({path!r},'wb')\nw=f.write", what=f"opening {rel}")  # fmt: skip
        for i in range(0, len(data), CHUNK):
            self.repl.exec("w(" + repr(bytes(data[i : i + CHUNK])) + ")\n_s()",
                           what=f"writing {rel}")  # fmt: skip
        self.repl.exec("f.close()", what=f"writing {rel}")
        return self.crc(rel)

    def write_verified(self, rel, data, log):
        """Write and check the board's CRC-32, up to ATTEMPTS times. Code that reaches the
        board as a SyntaxError (ours is valid: characters were lost on the way, as a UART REPL
        loses those that come while a flash erase stalls the CPU) is a corrupted attempt too."""
        want = crc32(data)
        for attempt in range(1, ATTEMPTS + 1):
            try:
                got = self.write(rel, data)
            except BoardError as e:
                if "SyntaxError" not in str(e):
                    raise
                log(f"  {rel}: the code sent arrived corrupted (attempt {attempt})")
                got = None
                continue
            if got == want:
                return attempt
            log(f"  {rel}: CRC-32 {got:08x} on the board, {want:08x} sent (attempt {attempt})")
        seen = "its code arrived corrupted" if got is None else f"the board's CRC-32 of the file " \
            f"({got:08x}) still differs from the host's ({want:08x})"  # fmt: skip
        raise TransferCorrupted(
            f"the transfer of {rel} was corrupted: after {ATTEMPTS} attempts {seen}. Check the "
            "USB cable and hub (connect the board directly), try a lower --baud, and run "
            "deploy again: only the files that differ are sent."
        )


# The board's internal filesystem (the stm32 port's pyb.Flash, from the volume's first block):
# the blocks of its block device and its boot sector, in hex; "VOL -" where there is none
# (another port, the virtual board, a stand-in)
VOLUME_QUERY = (
    "try:\n import pyb, binascii\n _f = pyb.Flash(start=0)\n _b = bytearray(512)\n"
    " _f.readblocks(0, _b)\n print('VOL', _f.ioctl(4, 0), binascii.hexlify(_b).decode())\n"
    "except (ImportError, AttributeError, ValueError, OSError):\n print('VOL -')\n"
)
# A listing that goes on past what cannot be read (a directory of a volume larger than its
# device, whose clusters lie beyond it): "D dir", "F file size", "X dir" for unreadable
WALK_HELPER = """
def _walk(d, rel):
    try:
        es = list(os.ilistdir(d))
    except OSError:
        print('X', rel or '/')
        return
    for e in es:
        if e[1] & 0x4000:
            print('D', rel + e[0])
            _walk(d + '/' + e[0], rel + e[0] + '/')
        else:
            print('F', rel + e[0], e[3] if len(e) > 3 else -1)
"""
KEEP_LIMIT = 64 * 1024  # bytes of user files a reformat keeps (read, then written back)
SAVE_ROOT = None  # where their copies go (None: out/board-files of this checkout)


# The native architecture of the board's MicroPython (-1: not MicroPython, e.g. a stand-in)
ARCH_QUERY = (
    "import sys\n_m = getattr(sys.implementation, '_mpy', None)\n"
    "print('ARCH', -1 if _m is None else (_m >> 10) & 0x2F)"
)
NATIVE_ARCHS = {2: "x64", 7: "armv7emsp"}  # MP_NATIVE_ARCH_* (py/persistentcode.h) we build


def native_plan(manifest, arch, log):
    """The manifest with lib/navk.mpy for the board's native architecture `arch`: the built one
    (armv7emsp) as it is; for another architecture we build (x64: the virtual board's VM) that
    build instead; none when the board cannot load native code (the firmware then runs its
    Python kernels)."""
    from tools.flash import build as build_mod

    nat = manifest.get("native")
    if not nat or arch < 0 or NATIVE_ARCHS.get(arch) == nat["arch"]:
        return manifest
    files = [f for f in manifest["files"] if f["path"] != nat["path"]]
    name = NATIVE_ARCHS.get(arch)
    if name is None:
        log(
            f"the board's MicroPython loads no native module we build (arch {arch}): "
            f"{nat['path']} is not sent, the firmware runs its Python kernels"
        )
    else:
        src = build_mod.native_module(name)
        data = src.read_bytes()
        files.append({"path": nat["path"], "size": len(data), "crc32": f"{crc32(data):08x}",
                      "src": str(src)})  # fmt: skip
        log(f"the board's MicroPython is {name}: {nat['path']} built for it")
    return {**manifest, "files": files, "total_bytes": sum(f["size"] for f in files)}


def is_firmware_file(rel):
    """Files deploy owns (and may delete): .py/.mpy under lib/ and drivers/, and the top-level
    app, board and main modules. Never ins.cfg or other user data."""
    if not rel.endswith((".py", ".mpy")):
        return False
    if rel.startswith(("lib/", "drivers/")) and rel.count("/") == 1:
        return True
    return rel.rsplit(".", 1)[0] in ("app", "board", "main")


def plan(manifest, board_files, board_dirs):
    """(files to write in order, stale files, directories to create)."""
    want = {f["path"]: f for f in manifest["files"]}
    stale = sorted(p for p in board_files if is_firmware_file(p) and p not in want)
    writes = [
        f
        for f in manifest["files"]
        if board_files.get(f["path"], (None, None))[1] != int(f["crc32"], 16)
    ]
    # shrinking files first so the filesystem never holds more than at the end; main.py last
    writes.sort(
        key=lambda f: (
            f["path"] == "main.py",
            f["size"] - board_files.get(f["path"], (0, None))[0],
            f["path"],
        )
    )
    new_dirs = [d for d in manifest.get("dirs", []) if d not in board_dirs]
    return writes, stale, new_dirs


def space_needed(writes, stale, new_dirs, board_files, cluster, extra=()):
    """Net bytes (in whole clusters) the filesystem must find for this deploy."""
    c = build_mod.clusters
    grow = sum(
        c(f["size"], cluster) - c(board_files.get(f["path"], (0,))[0], cluster) for f in writes
    )
    for rel, size in extra:
        grow += c(size, cluster) - c(board_files.get(rel, (0,))[0], cluster)
    grow -= sum(c(board_files[p][0], cluster) for p in stale)
    grow += len(new_dirs)
    return grow * cluster


FROZEN_PACKAGES = ("drivers",)  # firmware packages a frozen image carries: on /flash, even an
# empty directory of that name would come first on sys.path ('' is /flash) and hide them


def host_firmware_id():
    """The id of this checkout's firmware (tools/image/fwid.py); FlashError if unreadable."""
    from common import toolchain
    from tools.image import fwid

    try:
        return fwid.host_id()
    except (toolchain.ToolchainError, fwid.FirmwareIdError) as e:
        raise FlashError(
            f"the board's image carries frozen firmware, and telling whether it is this "
            f"checkout's needs MicroPython's manifest runner: {e}."
        ) from None


def frozen_plan(manifest, board_id, log, with_config):
    """The manifest to deploy next to an image that carries the firmware frozen: main.py and
    the native kernels (lib/navk.mpy: a native module cannot be frozen) when the image's
    firmware is this checkout's; FrozenMismatch otherwise."""
    host = host_firmware_id()
    if board_id["crc32"] != host["crc32"]:
        raise FrozenMismatch(
            f"the board's MicroPython image carries another firmware frozen (id "
            f"{board_id['crc32']}, version {board_id['version']}, built for {board_id['board']}) "
            f"than this checkout's firmware/ (id {host['crc32']}, version {host['version']}). "
            "Frozen modules come before /flash/lib on the board's sys.path, so files deployed "
            "next to them would mix two versions. Flash an image of this firmware: `make image "
            f"BOARD={board_id['board']}`, then `make flash-image BOARD={board_id['board']}` with "
            "the board in DFU mode (its filesystem and ins.cfg are kept), and run deploy again. "
            "To deploy the firmware as files instead, flash a MicroPython image without it "
            "frozen onto a board whose filesystem holds them (SPI flash). Nothing was written."
        )
    keep = ("main.py", (manifest.get("native") or {}).get("path"))
    names = [p for p in keep if p and any(f["path"] == p for f in manifest["files"])]
    names += ["ins.cfg"] if with_config else []
    goes = " and ".join((", ".join(names[:-1]), names[-1])) + " go" if names[1:] else "main.py goes"
    log(
        f"the board's image carries this firmware frozen (id {host['crc32']}, version "
        f"{board_id['version']}, {board_id['board']}, MicroPython {board_id['micropython']}): "
        f"only {goes} to /flash; with the firmware frozen the F411's 46 KB of files are no "
        "longer a limit"
    )
    files = [f for f in manifest["files"] if f["path"] in keep]
    dirs = sorted({f["path"].rsplit("/", 1)[0] for f in files if "/" in f["path"]})
    return {**manifest, "files": files, "dirs": dirs,
            "total_bytes": sum(f["size"] for f in files)}  # fmt: skip


def _quiet(_line):
    pass


def _stderr(line):
    import sys

    print(line, file=sys.stderr)


def connect(port, baud, timeout=5.0, log=_quiet, maintenance=True):
    """(ser, repl): the board's raw REPL, its firmware stopped (Ctrl-C) and, with maintenance,
    the board reset into a maintenance start (maintenance.start: repl.maintenance says how it
    went, repl.console keeps what the board said when stopped)."""
    ser = open_port(port, baud)
    repl = BoardRepl(ser, timeout=timeout, port=port)
    try:
        repl.enter()
        if maintenance:
            return maint.start(repl, lambda: open_port(port, baud), log)
    except BaseException:
        ser.close()
        raise
    return ser, repl


def deploy(
    build_dir,
    port,
    baud=115200,
    config_bytes=None,
    frames_port=None,
    frames_baud=460800,
    dry_run=False,
    log=print,
    config_merge=None,
    watch_s=15.0,
    check_budget=None,
):
    """Deploy the build in build_dir; returns a summary dict. When the board's image carries
    this firmware frozen, only main.py (and the configuration) are written and the firmware
    files on /flash are deleted; check_budget() is called only when all files are deployed."""
    manifest = build_mod.load_manifest(build_dir)
    ser, repl = connect(port, baud, log=log)
    try:
        board = Board(repl)
        _log_board_said(repl, log)
        formatted = format_if_needed(board, log, dry_run)
        if formatted is not None and dry_run:
            manifest, board_id = _board_manifest(board, manifest, config_bytes, log, check_budget)
            return _dry_run(repl, manifest["files"], [], [], config_bytes, board_id, watch_s,
                            log)  # fmt: skip
        if config_merge is not None:  # --set: the changes on --config's or the board's file
            base = config_bytes if config_bytes is not None else board.read(CONFIG_NAME)
            config_bytes = config_merge(base)
        manifest, board_id = _board_manifest(board, manifest, config_bytes, log, check_budget)
        want = [f["path"] for f in manifest["files"]] + [CONFIG_NAME]
        board_files, board_dirs = board.listing(want)
        fs = board.statvfs()
        writes, stale, new_dirs = plan(manifest, board_files, board_dirs)
        extra = _config_write(board, board_files, config_bytes)
        _check_space(manifest, fs, writes, stale, new_dirs, board_files, extra, log)
        if dry_run:
            return _dry_run(repl, writes, stale, extra, config_bytes, board_id, watch_s, log)
        _clear_stale(board, stale, board_dirs, board_id, log)
        for d in new_dirs:
            board.mkdir(d)
        _write_files(board, build_dir, manifest, writes, stale, extra, config_bytes, log)
        console = restart(repl, watch_s)
        result = {
            "written": [f["path"] for f in writes],
            "stale": stale,
            "console": console,
            "frozen": board_id,
            "formatted": formatted,
        }
        log("firmware: " + console.strip().replace("\r\n", "\n").replace("\n", "\n  "))
        if frames_port:
            result["frames"] = _confirm_frames(frames_port, frames_baud, log)
        return result
    finally:
        ser.close()


def format_if_needed(board, log, dry_run=False):
    """Format the board's internal filesystem anew when fatfs.format_reason says so (a volume
    an earlier image formatted larger than this image's filesystem; the port's 512-entry root
    directory, which leaves too little room), keeping its files but the firmware's: each is
    read first (and saved on the host, out/board-files/), then written back. None when nothing
    was done, else {"reason", "kept", "lost", "saved"}; with dry_run it only says so."""
    from tools.flash import fatfs

    vol = board.volume()
    reason = fatfs.format_reason(vol["boot"], vol["device_blocks"]) if vol else None
    if reason is None:
        return None
    blocks = vol["device_blocks"]
    log(f"the board's filesystem needs formatting anew: {reason}")
    files, _dirs, bad = board.walk()
    keep, lost = {}, [d + "/ (a directory)" for d in bad]
    for rel in sorted(files):
        if is_firmware_file(rel):
            continue  # main.py, lib/navk.mpy: written again from this checkout
        if sum(len(v) for v in keep.values()) + max(files[rel], 0) > KEEP_LIMIT:
            lost.append(rel + " (beyond the 64 KB kept)")
            continue
        try:
            keep[rel] = board.read(rel)
        except FlashError:
            lost.append(rel)
    keep = {k: v for k, v in keep.items() if v is not None}
    said = f"keeping {', '.join(keep)} (read now, written back)" if keep else "no files to keep"
    said += f"; unreadable, lost: {', '.join(lost)}" if lost else ""
    done = {"reason": reason, "kept": sorted(keep), "lost": lost, "saved": None}
    if dry_run:
        log(f"would format it anew ({blocks} blocks, a {fatfs.ROOT_ENTRIES}-entry root "
            f"directory), {said}; main.py and the native kernels would go again")  # fmt: skip
        return done
    if keep:
        done["saved"] = str(_save_on_host(keep))
        log(f"copies of the files kept: {done['saved']}")
    fs = board.format(blocks)
    log(f"formatted /flash anew: {fs['total']} bytes, {fs['free']} free "
        f"({fs['cluster']}-byte clusters); {said}")  # fmt: skip
    for rel in sorted(keep):
        parent = rel.rsplit("/", 1)[0] if "/" in rel else None
        if parent:
            for i, _c in enumerate(parent.split("/")):
                board.mkdir("/".join(parent.split("/")[: i + 1]))
        board.write_verified(rel, keep[rel], log)
        log(f"  {rel}: {len(keep[rel])} bytes written back")
    return done


def _save_on_host(files):
    """The files in a new folder SAVE_ROOT/<time>/ (out/board-files by default); its path."""
    from common.firmware_env import REPO_DIR

    root = pathlib.Path(SAVE_ROOT) if SAVE_ROOT else REPO_DIR / "out" / "board-files"
    out = root / time.strftime("%Y%m%d-%H%M%S")
    for rel, data in files.items():
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_bytes(data)
    return out


def _log_board_said(repl, log):
    """Log what the board printed when it was stopped (its prompts left out)."""
    said = [
        line.strip()
        for line in repl.console.decode(errors="replace").splitlines()
        if line.strip() and not line.strip().startswith(">>>")
    ]
    if said:
        log("board said: " + " / ".join(said))


def _board_manifest(board, manifest, config_bytes, log, check_budget):
    """(manifest, board_id): the manifest for the board's native architecture and, when its
    image carries the firmware frozen (board_id: what its `fwid` says, else None), only what
    goes next to it; check_budget() is called only when all files are deployed."""
    manifest = native_plan(manifest, board.native_arch(), log)
    board_id = board.frozen_firmware()
    if board_id is not None:
        manifest = frozen_plan(manifest, board_id, log, config_bytes is not None)
    else:
        log(
            f"the board's image has no frozen firmware: deploying all "
            f"{len(manifest['files'])} files ({manifest['total_bytes'] / 1024:.1f} KB). An "
            "image with the firmware frozen (make image, make flash-image) needs only "
            "main.py, lib/navk.mpy and ins.cfg on the filesystem: the F411's 46 KB of files are "
            "then no limit"
        )
        if check_budget is not None:
            check_budget()
    return manifest, board_id


def _config_write(board, board_files, config_bytes):
    """[(CONFIG_NAME, size)] when the configuration must be written, else []."""
    extra = []
    if config_bytes is not None:
        # compared whole: the file ends with its own CRC-32, so the CRC-32 of any intact
        # configuration file is the same residue (0x2144df1c) and cannot tell two apart
        cur = board.read(CONFIG_NAME) if CONFIG_NAME in board_files else None
        if cur != config_bytes:
            extra.append((CONFIG_NAME, len(config_bytes)))
    return extra


def _check_space(manifest, fs, writes, stale, new_dirs, board_files, extra, log):
    """Log the board's filesystem and the plan; FlashFull when the deploy would not fit."""
    need = space_needed(writes, stale, new_dirs, board_files, fs["cluster"], extra)
    total_fw = sum(build_mod.clusters(f["size"], fs["cluster"]) for f in manifest["files"])
    log(
        f"board filesystem: {fs['total']} bytes, {fs['free']} free "
        f"({fs['cluster']}-byte clusters); {len(writes)} of {len(manifest['files'])} "
        f"files differ, {len(stale)} stale"
    )
    if need > fs["free"]:
        raise FlashFull(
            f"flash full: the board's filesystem ({fs['total']} bytes, {fs['free']} free) "
            f"cannot take this deploy: it needs {need} more bytes ({len(writes)} files to "
            f"write; the whole firmware occupies {total_fw * fs['cluster']} bytes in "
            f"{fs['cluster']}-byte clusters). Nothing was written. "
            + (
                "The firmware is larger than this whole filesystem (the STM32F411's "
                "internal one holds 46 KB of files): flash an image with the "
                "firmware frozen (`make image`, then `make flash-image` in DFU mode; "
                "docs/image.md), after which deploy sends only main.py and ins.cfg; or use "
                "a board with SPI flash (e.g. a WeAct BlackPill with a W25Q chip)."
                if total_fw * fs["cluster"] > fs["total"]
                else "Delete files you no longer need from the board (e.g. old logs), then "
                "run deploy again."
            )
        )


def _dry_run(repl, writes, stale, extra, config_bytes, board_id, watch_s, log):
    """Log what a deploy would do, restart a firmware that was running; the summary dict."""
    for f in writes:
        log(f"would write {f['path']} ({f['size']} bytes)")
    for p in stale:
        log(f"would delete {p}")
    if extra:
        log(f"would write {CONFIG_NAME} ({len(config_bytes)} bytes)")
    # Ctrl-C stopped a running firmware to read the board: it runs again as before
    running = b"ins: stopped" in repl.console
    if running:
        restart(repl, watch_s)
        log("the firmware, stopped to read the board, runs again (a soft reset)")
    elif repl.maintenance:
        log("the board stays in maintenance (its firmware was not running): Ctrl-D or "
            "a reset starts it")  # fmt: skip
    return {
        "written": [],
        "stale": stale,
        "dry_run": True,
        "planned": writes,
        "frozen": board_id,
        "restarted": running,
    }


def _clear_stale(board, stale, board_dirs, board_id, log):
    """Delete the stale firmware files and, next to a frozen image, the package directories
    that would hide its frozen packages; FlashError when one holds other files."""
    why = " (frozen in the image)" if board_id is not None else ""
    for p in stale:
        board.remove(p)
        log(f"deleted stale {p}{why}")
    if board_id is not None:
        for d in FROZEN_PACKAGES:
            if d in board_dirs and not board.rmdir(d):
                raise FlashError(
                    f"/flash/{d} holds files that are not firmware modules; as a directory "
                    f"on /flash it hides the frozen {d} package (sys.path puts /flash "
                    f"first). Move those files elsewhere and run deploy again."
                )
            if d in board_dirs:
                log(f"removed /flash/{d}/ (it would hide the frozen {d} package)")


def _write_files(board, build_dir, manifest, writes, stale, extra, config_bytes, log):
    """Write the files that differ (and the configuration), each verified by the board's
    CRC-32, and log what was sent."""
    sent = 0
    t0 = time.monotonic()
    for f in writes:
        data = pathlib.Path(f.get("src") or pathlib.Path(build_dir) / f["path"]).read_bytes()
        attempts = board.write_verified(f["path"], data, log)
        sent += len(data) * attempts
        note = "" if attempts == 1 else f" after {attempts} attempts"
        log(f"  {f['path']}: {len(data)} bytes, CRC-32 {f['crc32']} OK{note}")
    if extra:
        board.write_verified(CONFIG_NAME, config_bytes, log)
        log(f"  {CONFIG_NAME}: {len(config_bytes)} bytes, CRC-32 OK")
    dt = time.monotonic() - t0
    log(
        f"{len(writes)} files written ({sent} bytes in {dt:.1f} s), "
        f"{len(manifest['files']) - len(writes)} unchanged, {len(stale)} stale deleted"
    )


def _confirm_frames(frames_port, frames_baud, log):
    """The valid frames counted on frames_port; FirmwareNotRunning when fewer than 3."""
    n = count_frames(frames_port, frames_baud)
    if n < 3:
        raise FirmwareNotRunning(
            f"the firmware says it runs but no valid 52-byte frames arrived on "
            f"{frames_port} within 3 s ({n}). Check the RS485 adapter's wiring and "
            f"that {frames_port} is its port, and the output baud ({frames_baud})."
        )
    log(f"{n} valid frames on {frames_port}")
    return n


def soft_reset(repl, quiet=0.1, overall=0.5):
    """Leave the raw REPL (Ctrl-B), let the board finish printing, and soft-reset (Ctrl-D):
    the firmware starts again, and aligns again."""
    repl.exit()
    repl.drain(quiet=quiet, overall=overall)
    repl.ser.write(b"\x04")


def restart(repl, watch_s=15.0):
    """Soft-reset into the firmware from the friendly REPL; the console text once it reports
    running. FirmwareNotRunning quoting the console otherwise."""
    soft_reset(repl, quiet=0.2, overall=1.0)
    text = b""
    t0 = time.monotonic()
    done = None
    while time.monotonic() - t0 < watch_s:
        data = repl.drain(quiet=0.1, overall=0.3)
        text += data
        if b"ins: running" in text:
            line_end = text.find(b"\n", text.find(b"ins: running"))
            if line_end < 0:
                text += repl.drain(quiet=0.2, overall=1.0)
            done = "ok"
            break
        if b"Traceback" in text or b"IMU not ready" in text or b"ins: cannot start" in text:
            text += repl.drain(quiet=0.5, overall=3.0)
            done = "failed"
            break
    console = text.decode(errors="replace")
    if done == "ok":
        return console
    quoted = console.strip() or "(nothing)"
    if done is None:
        why = f"did not print 'ins: running' within {watch_s:.0f} s"
    else:
        why = "reported a problem"
    raise FirmwareNotRunning(
        f"the files were written and verified, but after the soft reset the firmware {why}. "
        f"The console said:\n{quoted}\nFix what it names (e.g. the IMU wiring, or the "
        "configuration with `config set`) and reset the board; run deploy again after changing "
        "firmware files."
    )


def count_frames(port, baud, seconds=3.0):
    """Valid 52-byte frames (header EB 90, checksum) read from port within seconds."""
    ser = open_port(port, baud)
    try:
        data = bytearray()
        t0 = time.monotonic()
        n = 0
        while time.monotonic() - t0 < seconds and n < 10:
            data += ser.read(4096)
            n = valid_frames(bytes(data))
        return n
    finally:
        ser.close()


def valid_frames(data):
    """52-byte frames with a good checksum in data (stream.decode resynchronises on garbage)."""
    return len(stream.decode(data).frames)


def read_config(port, baud, log=_stderr):
    """The board's /flash/ins.cfg bytes (None if it has none), read in a maintenance start;
    restarts the firmware after (a soft reset: the firmware starts again, and aligns again)."""
    ser, repl = connect(port, baud, log=log)
    try:
        board = Board(repl)
        _refuse_oversized(board, "reading ins.cfg")
        data = board.read(CONFIG_NAME)
        soft_reset(repl)
        return data
    finally:
        ser.close()


def _refuse_oversized(board, doing):
    """FlashError, before `doing`, when the board's volume is larger than its filesystem (an
    earlier image's): what lay beyond is gone and a write there fails; deploy formats it."""
    vol = board.volume()
    if vol and vol["boot"] and vol["boot"]["blocks"] > vol["device_blocks"]:
        from tools.flash import fatfs

        raise FlashError(
            f"the board's filesystem needs formatting anew before {doing}: "
            f"{fatfs.format_reason(vol['boot'], vol['device_blocks'])}. Run `make deploy "
            "PORT=...` (python -m tools.flash deploy): it formats it, keeping ins.cfg and the "
            "other files it can still read, and writes main.py and lib/navk.mpy again. Nothing "
            "was written."
        )


# What a recording needs to know of the board besides its configuration: the platform, and
# whether its floats are float32 (the board) or double (a MicroPython VM: the virtual board)
FACTS_QUERY = (
    "import sys\nprint(repr(getattr(sys.implementation, '_machine', sys.platform)))\n"
    "print(1.0 + 1e-10 != 1.0)\n"
)


class BoardSession:
    """The board, stopped (in a maintenance start), for what a recording keeps of it: `config`
    (its /flash/ins.cfg bytes, None without one) and `facts` ({"machine", "floats": "float32" |
    "double"}); `restart()` soft-resets it, so that a recording begun before holds the
    firmware's start."""

    def __init__(self, port, baud, log=_quiet):
        self.ser, self.repl = connect(port, baud, log=log)
        try:
            board = Board(self.repl)
            self.config = board.read(CONFIG_NAME)
            out = self.repl.exec(FACTS_QUERY, what="asking which board it is").decode()
            lines = out.split("\n")
            machine = lines[0].strip().strip("'")
            self.facts = {
                "machine": machine,
                "floats": "double" if lines[1].strip() == "True" else "float32",
            }
        except BaseException:
            self.ser.close()
            raise

    def restart(self):
        """Ctrl-B, Ctrl-D: the firmware starts again (it aligns again)."""
        try:
            soft_reset(self.repl)
        finally:
            self.ser.close()


def write_config(port, baud, data, log=print):
    """Write ins.cfg with CRC verification in a maintenance start, then soft-reset so the
    firmware loads it."""
    ser, repl = connect(port, baud, log=log)
    try:
        board = Board(repl)
        _refuse_oversized(board, "writing ins.cfg")
        board.write_verified(CONFIG_NAME, data, log)
        # the file's own CRC-32 (of what precedes it): that of the whole file is a constant
        log(f"{ROOT}/{CONFIG_NAME}: {len(data)} bytes, CRC-32 {crc32(data[:-4]):08x} OK")
        soft_reset(repl)
    finally:
        ser.close()


__all__ = ["deploy", "read_config", "write_config", "FlashError"]
