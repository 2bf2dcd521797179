"""The board's FAT volume, on the host: its boot sector read, an empty volume written, its files
read (docs/deploy.md, "The filesystem").

The stm32 port formats its internal filesystem with FatFs's f_mkfs (lib/oofatfs/ff.c), whose
FAT12 root directory is fixed at 512 entries: 32 of the 96 blocks (512 bytes) of the F411's
48 KB, leaving 62 clusters = 31 KB for files, fewer than main.py, lib/navk.mpy and ins.cfg need
(the native module alone is 60 clusters). FatFs reads any root-directory size, so deploy
formats the volume as f_mkfs does but with a root directory of ROOT_ENTRIES entries:
`empty_volume(blocks)` is its first blocks (boot sector, FAT, root directory), 92 clusters =
46 KB for files on 96 blocks. `boot_sector` reads a volume's layout; `read_files` its files
(8.3 and long names, subdirectories), as flash-image saves them from an older image's volume;
`stamped` gives its entries one time, as a board with its RTC at that time would write them.
"""

import struct

BLOCK = 512
ROOT_ENTRIES = 32  # 2 blocks: the volume label, boot.py, main.py, ins.cfg, lib/, a few more
PORT_ROOT_ENTRIES = 512  # FatFs f_mkfs's, as the port formats
MAX_FAT12 = 4085
VOLUME_ID = 0x494E5331  # "INS1": our volumes' serial number (f_mkfs takes the time)
HIDDEN = 0x100  # the volume's offset in the port's storage: its fake MBR's partition start


class FatError(ValueError):
    """Not a FAT volume this module reads; the message says why."""


def layout(blocks, root_entries=ROOT_ENTRIES):
    """f_mkfs's FAT12/16 layout of a volume of `blocks` 512-byte blocks with `root_entries`
    root-directory entries: {"cluster_blocks", "fat_blocks", "root_blocks", "data_start",
    "clusters", "fat16"}."""
    if blocks < 50:  # f_mkfs refuses smaller volumes
        raise FatError(f"a volume of {blocks} blocks is too small for FAT")
    n, pau = blocks // 0x1000, 1
    for bound in (1, 4, 16, 64, 256, 512):  # f_mkfs's table: volume size -> sectors per cluster
        if bound > n:
            break
        pau <<= 1
    root = root_entries * 32 // BLOCK
    while True:
        n_clst = blocks // pau
        fat16 = n_clst > MAX_FAT12
        fat_bytes = n_clst * 2 + 4 if fat16 else (n_clst * 3 + 1) // 2 + 3
        fat = -(-fat_bytes // BLOCK)
        n_clst = (blocks - 1 - fat - root) // pau
        if fat16 and n_clst <= MAX_FAT12 and pau > 1:
            pau //= 2  # too few clusters for FAT16: f_mkfs halves the cluster and retries
            continue
        break
    return {"cluster_blocks": pau, "fat_blocks": fat, "root_blocks": root,
            "data_start": 1 + fat + root, "clusters": n_clst, "fat16": fat16}  # fmt: skip


COMPACT_MAX_BLOCKS = 128  # internal-flash filesystems this small get the compact root directory


def format_reason(boot, device_blocks):
    """Why deploy formats the volume anew (None: it does not), from its boot sector's layout
    (boot_sector) and the blocks of its block device: a volume larger than its device (an
    earlier image's, formatted over more flash than this image gives it: what lay beyond is
    gone and writing there fails), or the port's 512-entry root directory on a small one (too
    little room for main.py and lib/navk.mpy)."""
    if boot is None:
        return None
    n = device_blocks
    if boot["blocks"] > n:
        return (
            f"its FAT volume is {boot['blocks']} blocks ({boot['blocks'] * BLOCK // 1024} KB), "
            f"larger than this image's {n}-block ({n * BLOCK // 1024} KB) filesystem: an earlier "
            "image formatted it over more flash, which this image's code now takes, so the "
            "files there are gone and writing there would fail"
        )
    if n <= COMPACT_MAX_BLOCKS and boot["root_entries"] > ROOT_ENTRIES:
        now = boot["clusters"] * boot["cluster_blocks"] * BLOCK // 1024
        geo = layout(n)
        then = geo["clusters"] * geo["cluster_blocks"] * BLOCK // 1024
        return (
            f"it has the port's layout, whose {boot['root_entries']}-entry root directory "
            f"leaves {boot['clusters']} clusters ({now} KB) for files; with a {ROOT_ENTRIES}-"
            f"entry one its {n} blocks hold {geo['clusters']} ({then} KB)"
        )
    return None


def empty_volume(blocks, root_entries=ROOT_ENTRIES):
    """The first blocks of an empty FAT volume of `blocks` blocks, as f_mkfs writes them (one
    FAT, media 0xF8, OEM MSDOS5.0) but with `root_entries` root-directory entries: the boot
    sector, the FAT (entries 0 and 1 set), the root directory (zeros). The data area after
    them is left as it is."""
    geo = layout(blocks, root_entries)
    bs = bytearray(BLOCK)
    bs[0:11] = b"\xeb\xfe\x90MSDOS5.0"
    struct.pack_into("<HBHBHHBH", bs, 11, BLOCK, geo["cluster_blocks"], 1, 1, root_entries,
                     blocks if blocks < 0x10000 else 0, 0xF8, geo["fat_blocks"])  # fmt: skip
    struct.pack_into("<HHI", bs, 24, 63, 255, HIDDEN)  # sectors per track, heads, hidden
    if blocks >= 0x10000:
        struct.pack_into("<I", bs, 32, blocks)
    bs[36], bs[38] = 0x80, 0x29  # drive number, extended boot signature
    struct.pack_into("<I", bs, 39, VOLUME_ID)
    bs[43:62] = b"NO NAME    " + (b"FAT16   " if geo["fat16"] else b"FAT     ")
    bs[510:512] = b"\x55\xaa"
    fat = bytearray(geo["fat_blocks"] * BLOCK)
    fat[0:4] = b"\xf8\xff\xff\xff" if geo["fat16"] else b"\xf8\xff\xff\x00"
    return bytes(bs) + bytes(fat) + bytes(geo["root_blocks"] * BLOCK)


def boot_sector(data):
    """The layout a FAT boot sector (the volume's first 512 bytes) gives, or None when it is
    not one: {"blocks", "root_entries", "cluster_blocks", "fat_blocks", "data_start",
    "clusters"}."""
    bs = bytes(data[:BLOCK])
    if len(bs) < BLOCK or bs[510:512] != b"\x55\xaa":
        return None
    (sector, spc, rsv, nfats, root, tot16, _media, fatsz) = struct.unpack_from("<HBHBHHBH", bs, 11)
    blocks = tot16 or struct.unpack_from("<I", bs, 32)[0]
    if sector != BLOCK or not spc or spc & (spc - 1) or not rsv or nfats not in (1, 2) \
            or not fatsz or not blocks:  # fmt: skip
        return None
    start = rsv + nfats * fatsz + root * 32 // BLOCK
    return {"blocks": blocks, "root_entries": root, "cluster_blocks": spc, "fat_blocks": fatsz,
            "fats": nfats, "reserved": rsv, "data_start": start,
            "clusters": (blocks - start) // spc}  # fmt: skip


def read_files(data):
    """{path: bytes} of the files of the FAT12/16 volume in `data` (its bytes from block 0; a
    volume cut short reads as far as it goes: a file whose clusters lie beyond is left out and
    its path listed in the second result). Returns (files, unreadable paths)."""
    vol = Volume(data)
    files, lost = {}, []
    for path, _at, e in vol.entries(lost):
        if e[11] & 0x18 or path.rsplit("/", 1)[-1] in (".", ".."):
            continue  # directories (walked), the volume label, dot entries
        size = struct.unpack_from("<I", e, 28)[0]
        spans = vol.spans(struct.unpack_from("<H", e, 26)[0])
        body = b"".join(data[a:b] for a, b in spans) if spans is not None else None
        if body is None or len(body) < size:
            lost.append(path)
        else:
            files[path] = body[:size]
    return files, lost


def stamped(data, fattime):
    """A copy of the volume in `data` whose directory entries (files, directories, their dot
    entries, the label) say they were created, written and read at `fattime` (FatFs's
    get_fattime word: year-1980 << 25 | month << 21 | day << 16 | h << 11 | min << 5 | s / 2).
    The port stamps what it writes with its RTC; a host's FAT driver stamps it with the host's
    clock, which would make two otherwise equal volumes differ."""
    out = bytearray(data)
    date, time = fattime >> 16, fattime & 0xFFFF
    for _path, at, _e in Volume(data).entries([]):
        struct.pack_into("<BHHH", out, at + 13, 0, time, date, date)  # created (10 ms, time,
        struct.pack_into("<HH", out, at + 22, time, date)  # date), read; written
    return bytes(out)


class Volume:
    """A FAT12/16 volume's layout over its bytes: cluster chains and directory entries."""

    def __init__(self, data):
        geo = boot_sector(data)
        if geo is None:
            raise FatError("no FAT boot sector")
        self.data, self.geo = data, geo
        fat_at = geo["reserved"] * BLOCK
        self.fat = bytes(data[fat_at : fat_at + geo["fat_blocks"] * BLOCK])
        self.fat16 = geo["clusters"] > MAX_FAT12
        self.csize = geo["cluster_blocks"] * BLOCK
        self.data_at = geo["data_start"] * BLOCK

    def _next(self, c):
        if self.fat16:
            return struct.unpack_from("<H", self.fat, 2 * c)[0]
        v = struct.unpack_from("<H", self.fat, c + c // 2)[0]
        return v >> 4 if c & 1 else v & 0xFFF

    def spans(self, first):
        """[(start, end)] byte ranges in the data of the chain from cluster `first`; None when
        one lies beyond the data."""
        out, end, c = [], 0xFFF8 if self.fat16 else 0xFF8, first
        while 2 <= c < end and len(out) <= self.geo["clusters"]:
            at = self.data_at + (c - 2) * self.csize
            if at + self.csize > len(self.data):
                return None
            out.append((at, at + self.csize))
            c = self._next(c)
        return out

    def entries(self, lost):
        """(path, offset, entry) of every short directory entry in use (files, directories,
        dot entries, the label; long-name entries give the path), subdirectories walked; a
        directory whose clusters lie beyond the data goes to `lost` as "path/"."""
        geo = self.geo
        root_at = (geo["reserved"] + geo["fats"] * geo["fat_blocks"]) * BLOCK
        yield from self._walk([(root_at, root_at + geo["root_entries"] * 32)], "", lost)

    def _walk(self, spans, prefix, lost):
        lfn = {}
        for at in (i for a, b in spans for i in range(a, b - 31, 32)):
            e = bytes(self.data[at : at + 32])
            if len(e) < 32 or e[0] == 0:
                return
            if e[0] == 0xE5:
                lfn = {}
                continue
            if e[11] == 0x0F:  # a long-name entry: 13 UCS-2 characters, in reverse order
                part = e[1:11] + e[14:26] + e[28:32]
                lfn[e[0] & 0x1F] = part.decode("utf-16-le", "replace").split("\x00")[0]
                continue
            name = "".join(lfn[k] for k in sorted(lfn)) if lfn else _short_name(e)
            lfn = {}
            yield prefix + name, at, e
            first = struct.unpack_from("<H", e, 26)[0]
            if e[11] & 0x10 and name not in (".", "..") and first:
                sub = self.spans(first)
                if sub is None:
                    lost.append(prefix + name + "/")
                else:
                    yield from self._walk(sub, prefix + name + "/", lost)


def _short_name(e):
    """An 8.3 entry's name, with the case flags of byte 12 (base 0x08, extension 0x10)."""
    base = e[0:8].decode("latin-1").rstrip()
    ext = e[8:11].decode("latin-1").rstrip()
    if e[0] == 0x05:
        base = "\xe5" + base[1:]
    if e[12] & 0x08:
        base = base.lower()
    if e[12] & 0x10:
        ext = ext.lower()
    return base + ("." + ext if ext else "")
