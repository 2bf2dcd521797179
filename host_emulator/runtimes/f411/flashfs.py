"""The board's filesystem in the twin: the flash sectors the port keeps it in, as a board
holds it after `deploy`.

The stm32 port keeps /flash in internal flash where the image's linker script puts it (the
symbols _micropy_hw_internal_flash_storage_start/end, which ports/stm32/flashbdev.c reads):
with our layout (tools/image/boards/stm32f411_fs48.ld) sectors 1-3 of the F411, 48 KB from
0x08004000, 96 blocks of 512 bytes (the port's own boards/stm32f411.ld gives it 64 KB, into
sector 4). `partition(image)` reads them from the image's ELF. The port formats the volume
on its first boot when it finds no filesystem there (a FAT volume of exactly that many blocks,
FatFs's f_mkfs, holding the port's factory boot.py and main.py; `volume_blocks` reads its
size back from the boot sector, and `formatted` checks it) and writes through its own FAT
driver.

So the twin makes it the same way: `formatted(image)` boots the image on an erased flash until
it prints its REPL prompt and is quiet, and keeps the sectors as the port wrote them (cached in
build/f411/fs/ by the image's hash: formatting takes the twin ~10 s of board time, two of them
flash erases); `with_files(partition, files)` writes the files deploy writes (main.py, ins.cfg,
lib/navk.mpy) into that volume with MicroPython's own FAT driver (VfsFat of the unix VM from
PyPI: the same oofatfs code as the board's), as deploy's writes through the board's REPL would,
after giving the volume the compact root directory deploy gives it (tools/flash/fatfs.py: the
port's 512-entry one leaves 31 KB, less than lib/navk.mpy and main.py need), every entry
stamped with the time a board's RTC gives them after a cold start (BOARD_FATTIME): the host's
clock in the entries would change what the image does by an instruction here and there.
"""

import hashlib
import pathlib
import subprocess
import tempfile

from common.errors import EmulatorError

PART_BASE = 0x08004000  # sector 1: where the filesystem starts (ours and the port's layout)
PART_SIZE = 48 * 1024  # sectors 1-3 (tools/image/boards/stm32f411_fs48.ld); partition() reads it
BLOCK = 512
ROOT = pathlib.Path(__file__).resolve().parents[3]
CACHE = ROOT / "build" / "f411" / "fs"
# the time a board stamps deploy's files with: its RTC from a cold start, which the port sets
# to 1 January 2015 00:00 (ports/stm32/rtc.c); the unix VM would stamp the host's clock
BOARD_FATTIME = (2015 - 1980) << 25 | 1 << 21 | 1 << 16
FORMAT_LIMIT_S = 30  # board seconds to wait for the first boot's prompt

_VM_SCRIPT = """
import vfs, os
class Dev:
    def __init__(self, path):
        f = open(path, 'rb')
        self.data = bytearray(f.read())
        f.close()
    def readblocks(self, n, buf):
        buf[:] = self.data[n * 512 : n * 512 + len(buf)]
    def writeblocks(self, n, buf):
        self.data[n * 512 : n * 512 + len(buf)] = buf
    def ioctl(self, op, arg):
        if op == 4:
            return len(self.data) // 512
        if op == 5:
            return 512
        return 0
d = Dev(PART)
vfs.mount(vfs.VfsFat(d), '/fl')
if HEAD:  # deploy formats the volume anew (tools/flash/fatfs.py), keeping the other files
    kept = []
    def walk(p, rel):
        for e in os.ilistdir(p):
            if e[1] & 0x4000:
                walk(p + '/' + e[0], rel + e[0] + '/')
            elif rel + e[0] not in [r for r, _s in FILES]:
                f = open(p + '/' + e[0], 'rb')
                kept.append((rel + e[0], f.read()))
                f.close()
    walk('/fl', '')
    vfs.umount('/fl')
    f = open(HEAD, 'rb')
    d.writeblocks(0, f.read())
    f.close()
    vfs.mount(vfs.VfsFat(d), '/fl')
    for rel, data in kept:
        p = '/fl'
        for name in rel.split('/')[:-1]:
            p += '/' + name
            try:
                os.mkdir(p)
            except OSError:
                pass
        g = open('/fl/' + rel, 'wb')
        g.write(data)
        g.close()
for rel, src in FILES:
    parts = rel.split('/')
    p = '/fl'
    for name in parts[:-1]:
        p += '/' + name
        try:
            os.mkdir(p)
        except OSError:
            pass
    f = open(src, 'rb')
    data = f.read()
    f.close()
    g = open('/fl/' + rel, 'wb')
    g.write(data)
    g.close()
vfs.umount('/fl')
f = open(OUT, 'wb')
f.write(d.data)
f.close()
print('OK', len(FILES))
"""


def partition(image):
    """(start, size) of the image's filesystem in flash: its ELF's linker symbols."""
    from elftools.elf.elffile import ELFFile

    want = ("_micropy_hw_internal_flash_storage_start", "_micropy_hw_internal_flash_storage_end")
    found = {}
    with open(image.elf_path, "rb") as f:
        for sym in ELFFile(f).get_section_by_name(".symtab").iter_symbols():
            if sym.name in want:
                found[sym.name] = sym["st_value"]
    if len(found) != 2:
        raise EmulatorError(f"{image.elf_path} does not say where its filesystem is (no "
                            f"{' / '.join(want)}): not an stm32 port image?")  # fmt: skip
    start, end = found[want[0]], found[want[1]]
    if start != PART_BASE or end <= start or (end - start) % BLOCK:
        raise EmulatorError(f"the image's filesystem is 0x{start:08X}-0x{end:08X}: the twin "
                            f"expects it from 0x{PART_BASE:08X}, whole blocks")  # fmt: skip
    return start, end - start


def volume_blocks(part):
    """The blocks the FAT volume at the start of `part` says it has (its boot sector's total
    sectors), or None when there is no FAT boot sector."""
    bs = bytes(part[:BLOCK])
    if len(bs) < BLOCK or bs[510:512] != b"\x55\xaa" or bs[11:13] != b"\x00\x02":
        return None
    n = int.from_bytes(bs[19:21], "little")
    return n or int.from_bytes(bs[32:36], "little")


def with_files(partition, files, fresh=None):
    """The partition's bytes with `files` ({board path: bytes}) written into its volume, as
    deploy writes them: first, if deploy would format the volume anew (tools/flash/fatfs.py
    format_reason: the port's 512-entry root directory leaves too little room for lib/navk.mpy,
    or the volume is larger than the partition), its compact layout, keeping the other files
    (the port's factory boot.py). fresh: True or False decides that instead (False: the files
    go into the volume as it is, e.g. to make an earlier image's)."""
    from host_emulator.runtimes.mpy_unix.vm import micropython_exe
    from tools.flash import fatfs

    if not partition or len(partition) % BLOCK:
        raise EmulatorError(f"a filesystem partition of {len(partition)} bytes, not whole blocks")
    blocks = len(partition) // BLOCK
    if fresh is None:
        fresh = fatfs.format_reason(fatfs.boot_sector(partition), blocks) is not None
    with tempfile.TemporaryDirectory(prefix="f411fs-") as d:
        d = pathlib.Path(d)
        (d / "part.img").write_bytes(partition)
        head = ""
        if fresh:
            (d / "head.img").write_bytes(fatfs.empty_volume(blocks))
            head = str(d / "head.img")
        listed = []
        for i, (rel, data) in enumerate(sorted(files.items())):
            src = d / f"file{i}"
            src.write_bytes(data)
            listed.append((rel, str(src)))
        script = (f"PART = {str(d / 'part.img')!r}\nOUT = {str(d / 'out.img')!r}\n"
                  f"HEAD = {head!r}\nFILES = {listed!r}\n" + _VM_SCRIPT)  # fmt: skip
        (d / "fs.py").write_text(script)
        proc = subprocess.run([str(micropython_exe()), str(d / "fs.py")], capture_output=True,
                              text=True, timeout=60)  # fmt: skip
        if proc.returncode != 0 or not proc.stdout.startswith("OK"):
            raise EmulatorError(
                "writing the board's files into its filesystem failed (MicroPython's VfsFat): "
                + (proc.stdout + proc.stderr).strip()[-400:]
            )
        return fatfs.stamped((d / "out.img").read_bytes(), BOARD_FATTIME)


def _image_key(image):
    return hashlib.sha256(image.data).hexdigest()[:16]


def formatted(board, image, log=None):
    """The partition as the image formats it on its first boot (cached, with what the image
    printed meanwhile beside it: `first_boot_console`)."""
    from host_emulator.f411.chip import F411

    base, size = partition(image)
    path = _cache_path(board, image)
    if path.is_file() and path.stat().st_size == size and path.with_suffix(".txt").is_file():
        return path.read_bytes()
    if log:
        log(f"f411: first boot of the {board.name} image on an erased flash (the port formats "
            "its filesystem; cached)")  # fmt: skip
    chip = F411(board, image)
    out = bytearray()

    def stdout(c):
        out.extend(c.cpu.uc.mem_read(c.reg(0), c.reg(1)))

    chip.hook("mp_hal_stdout_tx_strn", stdout)
    prompt_at = None
    while True:
        chip.run_for_ms(50)
        if prompt_at is None and out.endswith(b">>> "):
            prompt_at = chip.clock.us()
        if prompt_at is not None and chip.clock.us() - prompt_at > 6_000_000:
            break  # the port writes its cached flash sector back after 5 s without writes
        if chip.clock.us() > FORMAT_LIMIT_S * 1e6:
            raise EmulatorError(f"the {board.name} image did not reach its REPL prompt within "
                                f"{FORMAT_LIMIT_S} s of board time; it printed: "
                                f"{out.decode(errors='replace')[-300:]!r}")  # fmt: skip
    part = chip.flash_bytes(base, size)
    if volume_blocks(part) != size // BLOCK:
        raise EmulatorError(f"the {board.name} image formatted a volume of "
                            f"{volume_blocks(part)} blocks on its {size // BLOCK}-block "
                            "filesystem")  # fmt: skip
    path.parent.mkdir(parents=True, exist_ok=True)
    path.with_suffix(".txt").write_bytes(bytes(out))
    tmp = path.with_suffix(".tmp")
    tmp.write_bytes(part)
    tmp.replace(path)
    return part


def _cache_path(board, image):
    return CACHE / f"{board.name}-{_image_key(image)}.img"


def first_boot_console(board, image):
    """What the image printed on its first boot (its banner and REPL prompt), formatting."""
    formatted(board, image)
    return _cache_path(board, image).with_suffix(".txt").read_text(errors="replace")
