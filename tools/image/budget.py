"""The image's budget, measured from what the linker produced.

Figures come from three sources, all written by the stm32 port's own link step:

- the linker map (firmware.map): the memory regions and their sizes ("Memory Configuration",
  from our tools/image/boards/stm32f411_fs48.ld: FLASH 512 KB, FLASH_START 16 KB for the vector
  table, FLASH_FS 48 KB from 0x08004000 for the filesystem, FLASH_TEXT 448 KB from 0x08010000
  for the code, RAM 112 KB), and every input section the link kept from frozen_content.o (the
  frozen firmware: bytecode, constants, qstrs);
- the ELF's symbols (arm-none-eabi-nm): _sidata/_sdata/_edata (.data and where its initial
  values sit in flash), _sbss/_ebss, _heap_start/_heap_end (the GC heap MicroPython's main.c
  hands to gc_init), _sstack/_estack;
- the ELF's section table (arm-none-eabi-size -A) for what sits in the vector-table sector.

The budget the image must meet: its code fits the code region with at least MIN_CODE_FREE_BYTES
of it left (room for what comes next: a build that eats into it fails, so the room is never
used up by accident), its vectors the 16 KB sector 0 (the linker refuses otherwise, and
build.py turns its message into ours), and the heap is at least MIN_HEAP_BYTES: the firmware
keeps ~16 KB live after start-up and collects when fewer than 12 KB are free (app.py's
_GC_LOW_WATER), so a heap much under 64 KB would collect every few ticks (docs/requirements.md,
time budget, measures a collection at ~1.8 ms).
"""

import re
import subprocess

MIN_HEAP_BYTES = 64 * 1024
MIN_CODE_FREE_BYTES = 32 * 1024  # fail when the code region would have less than this left
NM = "arm-none-eabi-nm"
SIZE = "arm-none-eabi-size"


class BudgetError(Exception):
    """The image exceeds its budget, or its figures cannot be read; the message says which."""


def _run(cmd):
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True)
    except OSError as e:
        raise BudgetError(f"cannot run {cmd[0]}: {e.strerror}") from None
    if proc.returncode != 0:
        raise BudgetError(f"{' '.join(cmd)} failed: {proc.stderr.strip()}")
    return proc.stdout


def symbols(elf):
    """{name: address} of the ELF's symbols."""
    out = {}
    for line in _run([NM, str(elf)]).splitlines():
        parts = line.split()
        if len(parts) == 3:
            out[parts[2]] = int(parts[0], 16)
    return out


def sections(elf):
    """{name: (size, address)} of the ELF's sections."""
    out = {}
    for line in _run([SIZE, "-A", str(elf)]).splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0].startswith(".") and parts[1].isdigit():
            out[parts[0]] = (int(parts[1]), int(parts[2]))
    return out


def memory_regions(map_text):
    """{name: (origin, length)} from the map's "Memory Configuration" table."""
    start = map_text.find("Memory Configuration")
    end = map_text.find("Linker script and memory map")
    if start < 0 or end < 0:
        raise BudgetError("the linker map has no Memory Configuration table")
    regions = {}
    for m in re.finditer(
        r"^(\w+)\s+0x([0-9a-fA-F]+)\s+0x([0-9a-fA-F]+)", map_text[start:end], re.MULTILINE
    ):
        regions[m.group(1)] = (int(m.group(2), 16), int(m.group(3), 16))
    return regions


def object_bytes(map_text, obj_name, ranges):
    """Bytes the link placed from input sections of the object file obj_name (its basename)
    at addresses inside `ranges` [(start, end)]: the object's share of the image."""
    start = map_text.find("Linker script and memory map")
    end = map_text.find("Cross Reference Table")
    body = map_text[start : end if end > 0 else None]
    total = 0
    pattern = re.compile(
        r"^\s*(?:\S+\s+)?0x([0-9a-fA-F]+)\s+0x([0-9a-fA-F]+)\s+(\S+)$", re.MULTILINE
    )
    for m in pattern.finditer(body):
        if not m.group(3).endswith("/" + obj_name) and m.group(3) != obj_name:
            continue
        addr, size = int(m.group(1), 16), int(m.group(2), 16)
        if any(lo <= addr < hi for lo, hi in ranges):
            total += size
    return total


def measure(elf, map_path):
    """The image's figures (a dict of ints, bytes) read from its ELF and linker map."""
    map_text = open(map_path, encoding="utf-8", errors="replace").read()
    regions = memory_regions(map_text)
    for name in ("FLASH", "FLASH_START", "FLASH_TEXT", "RAM"):
        if name not in regions:
            raise BudgetError(f"the linker map has no {name} region (not an STM32F4 image?)")
    sym = symbols(elf)
    need = ("_sidata", "_sdata", "_edata", "_sbss", "_ebss", "_heap_start", "_heap_end")
    missing = [s for s in need if s not in sym]
    if missing:
        raise BudgetError(f"{elf} lacks the symbols {', '.join(missing)}")
    sec = sections(elf)
    text_origin, text_len = regions["FLASH_TEXT"]
    isr_origin, isr_len = regions["FLASH_START"]
    flash_origin, flash_len = regions["FLASH"]
    ram_origin, ram_len = regions["RAM"]
    data = sym["_edata"] - sym["_sdata"]
    bss = sym["_ebss"] - sym["_sbss"]
    code = sym["_sidata"] + data - text_origin  # .text, .ARM and .data's initial values
    isr = sum(
        size for size, addr in sec.values() if isr_origin <= addr < isr_origin + isr_len and size
    )
    frozen = object_bytes(
        map_text,
        "frozen_content.o",
        [(flash_origin, flash_origin + flash_len), (ram_origin, ram_origin + ram_len)],
    )
    fs_origin, fs_len = regions.get("FLASH_FS", (0, 0))
    return {
        "code_region_origin": text_origin,
        "code_region_bytes": text_len,
        "code_bytes": code,
        "code_free_bytes": text_len - code,
        "vector_sector_bytes": isr_len,
        "vector_sector_used_bytes": isr,
        "flash_bytes": flash_len,
        "flash_programmed_bytes": code + isr,
        "filesystem_origin": fs_origin,
        "filesystem_bytes": fs_len,
        "ram_bytes": ram_len,
        "data_bytes": data,
        "bss_bytes": bss,
        "static_ram_bytes": data + bss,
        "heap_bytes": sym["_heap_end"] - sym["_heap_start"],
        "stack_bytes": sym.get("_estack", 0) - sym.get("_sstack", 0),
        "frozen_bytes": frozen,
    }


def problems(fig):
    """Why the image is over budget: a list of sentences, empty when it fits."""
    out = []
    if fig["code_bytes"] > fig["code_region_bytes"]:
        out.append(
            f"the code needs {fig['code_bytes']:,} bytes but the code region holds "
            f"{fig['code_region_bytes']:,} ({fig['code_region_bytes'] // 1024} KB)"
        )
    elif fig["code_region_bytes"] - fig["code_bytes"] < MIN_CODE_FREE_BYTES:
        out.append(
            f"only {fig['code_region_bytes'] - fig['code_bytes']:,} bytes of the "
            f"{fig['code_region_bytes'] // 1024} KB code region would be left, under the "
            f"{MIN_CODE_FREE_BYTES // 1024} KB kept free (the code needs {fig['code_bytes']:,})"
        )
    if fig["vector_sector_used_bytes"] > fig["vector_sector_bytes"]:
        out.append(
            f"the vector-table sector needs {fig['vector_sector_used_bytes']:,} bytes of "
            f"{fig['vector_sector_bytes']:,}"
        )
    if fig["heap_bytes"] < MIN_HEAP_BYTES:
        out.append(
            f"the heap is {fig['heap_bytes']:,} bytes, under the {MIN_HEAP_BYTES // 1024} KB the "
            f"firmware needs (static RAM takes {fig['static_ram_bytes']:,} bytes)"
        )
    return out


def _kb(n):
    return f"{n / 1024:.1f} KB"


def _sectors(origin, size):
    """The F411 sectors [origin, origin + size) covers, as text ("1-3", "4-7")."""
    starts = (
        [0x08000000 + k * 0x4000 for k in range(4)]
        + [0x08010000]
        + [0x08020000 + k * 0x20000 for k in range(3)]
    )
    covered = [i for i, a in enumerate(starts) if origin <= a < origin + size]
    if not covered:
        return "?"
    return str(covered[0]) if len(covered) == 1 else f"{covered[0]}-{covered[-1]}"


def report_lines(fig):
    """The budget as printed lines."""
    pct = 100 * fig["code_bytes"] / fig["code_region_bytes"]
    origin = fig.get("code_region_origin", 0x08010000)
    fs = ""
    if fig.get("filesystem_bytes"):
        fs = (f"; sectors {_sectors(fig['filesystem_origin'], fig['filesystem_bytes'])} hold the "
              f"{fig['filesystem_bytes'] // 1024} KB filesystem")  # fmt: skip
    return [
        f"code region   {fig['code_bytes']:>9,} B of {fig['code_region_bytes']:,} "
        f"({fig['code_region_bytes'] // 1024} KB from 0x{origin:08X}, sectors "
        f"{_sectors(origin, fig['code_region_bytes'])}): {pct:.1f} %, "
        f"{fig['code_free_bytes']:,} B ({_kb(fig['code_free_bytes'])}) free, at least "
        f"{MIN_CODE_FREE_BYTES // 1024} KB kept",
        f"vector sector {fig['vector_sector_used_bytes']:>9,} B of "
        f"{fig['vector_sector_bytes']:,} (sector 0)",
        f"flash         {fig['flash_programmed_bytes']:>9,} B of {fig['flash_bytes']:,} "
        f"({fig['flash_bytes'] // 1024} KB) programmed "
        f"({100 * fig['flash_programmed_bytes'] / fig['flash_bytes']:.1f} %{fs})",
        f"static RAM    {fig['static_ram_bytes']:>9,} B (.data {fig['data_bytes']:,} + .bss "
        f"{fig['bss_bytes']:,}) of {fig['ram_bytes']:,} ({fig['ram_bytes'] // 1024} KB)",
        f"heap          {fig['heap_bytes']:>9,} B ({_kb(fig['heap_bytes'])}; at least "
        f"{MIN_HEAP_BYTES // 1024} KB needed), stack {fig['stack_bytes']:,} B",
        f"frozen firmware {fig['frozen_bytes']:>7,} B ({_kb(fig['frozen_bytes'])}, "
        f"{100 * fig['frozen_bytes'] / fig['code_bytes']:.1f} % of the code)",
    ]
