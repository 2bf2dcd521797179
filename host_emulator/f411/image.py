"""The image file the twin executes, and its symbols.

`Image(bin_path, elf_path)`: the bytes `make image` writes for the flash (firmware.bin: one flat
file from 0x08000000; the ST-LINK drive takes it as it is) and, from the ELF the same build
linked (obj/firmware.elf), the symbols that name the code (functions and their sizes) for
messages and for the counter's categories. The ELF's loadable contents must equal the .bin's
bytes where both have them: the twin runs the file a user flashes, and a stale ELF beside it
would name the wrong functions.
"""

import bisect
import pathlib

from common.errors import EmulatorError

FLASH_BASE = 0x08000000
FLASH_SIZE = 512 * 1024

# Categories of code for the counter (counter.py): by the C function's name
CATEGORIES = ("other", "uart", "spi_dma", "gc", "flash", "timers", "vm_runtime", "ram")
_PREFIXES = (
    ("uart", ("uart_", "machine_uart", "mp_machine_uart", "USART")),
    ("spi_dma", ("spi_", "machine_spi", "machine_hard_spi", "mp_machine_spi", "dma_", "HAL_SPI",
                 "HAL_DMA", "SPI_", "DMA_")),
    ("gc", ("gc_",)),
    ("flash", ("flash_", "storage_", "HAL_FLASH", "FLASH_", "f_", "ff_", "disk_")),
    ("timers", ("soft_timer", "SysTick", "systick", "PendSV", "pendsv", "mp_irq", "HAL_IncTick",
                "mp_sched", "mp_handle_pending", "extint", "EXTI")),
    ("vm_runtime", ("mp_execute_bytecode", "mp_obj_", "mp_call", "mp_load", "mp_store",
                    "mp_binary_op", "mp_unary_op", "fun_", "mp_map", "qstr_", "m_malloc",
                    "m_realloc", "m_free", "mp_arg", "mp_setup", "mp_native", "mp_convert",
                    "mp_small_int", "mpz_", "mp_obj_int", "array_", "bytearray", "mp_seq")),
)  # fmt: skip


class Image:
    def __init__(self, bin_path, elf_path):
        from elftools.elf.elffile import ELFFile

        self.bin_path = pathlib.Path(bin_path)
        self.elf_path = pathlib.Path(elf_path)
        for p in (self.bin_path, self.elf_path):
            if not p.is_file():
                raise EmulatorError(f"no image file {p}: build it with `make image`")
        self.data = self.bin_path.read_bytes()
        if len(self.data) > FLASH_SIZE:
            raise EmulatorError(f"{self.bin_path} is {len(self.data)} bytes: more than the "
                                "F411's 512 KB of flash")  # fmt: skip
        funcs = []
        self.objects = {}
        with open(self.elf_path, "rb") as f:
            elf = ELFFile(f)
            for seg in elf.iter_segments():
                if seg["p_type"] != "PT_LOAD" or not seg["p_filesz"]:
                    continue
                a = seg["p_paddr"]
                if FLASH_BASE <= a < FLASH_BASE + FLASH_SIZE:
                    chunk = seg.data()
                    off = a - FLASH_BASE
                    if self.data[off : off + len(chunk)] != chunk:
                        raise EmulatorError(
                            f"{self.elf_path} does not match {self.bin_path} at 0x{a:08X}: "
                            "the ELF is not the one this image was linked from (make image)"
                        )
            for s in elf.get_section_by_name(".symtab").iter_symbols():
                t = s["st_info"]["type"]
                if t == "STT_FUNC" and s["st_value"]:
                    funcs.append((s["st_value"] & ~1, s["st_size"], s.name))
                elif t == "STT_OBJECT":
                    self.objects[s.name] = (s["st_value"], s["st_size"])
        funcs.sort()
        self._starts = [f[0] for f in funcs]
        self._funcs = funcs
        self.functions = {name: addr for addr, _size, name in funcs}

    def function_at(self, pc):
        """(name, offset) of the function holding pc, or None."""
        i = bisect.bisect_right(self._starts, pc) - 1
        if i < 0:
            return None
        addr, size, name = self._funcs[i]
        if pc < addr + max(size, 2):
            return name, pc - addr
        return None

    def where(self, pc):
        if FLASH_BASE <= pc < FLASH_BASE + FLASH_SIZE or pc < FLASH_SIZE:
            f = self.function_at(pc if pc >= FLASH_BASE else pc + FLASH_BASE)
            if f:
                return f"{f[0]}+0x{f[1]:x} (0x{pc:08X})"
            return f"0x{pc:08X} (no symbol)"
        if 0x20000000 <= pc < 0x20020000:
            return f"code in RAM at 0x{pc:08X} (a native module)"
        return f"0x{pc:08X}"

    def address(self, name):
        a = self.functions.get(name)
        if a is None:
            a = self.objects.get(name, (None,))[0]
        if a is None:
            raise EmulatorError(f"the image has no symbol {name!r}")
        return a

    def size(self, name):
        for _addr, size, n in self._funcs:
            if n == name:
                return max(size, 2)
        raise EmulatorError(f"the image has no function {name!r}")

    def category_map(self):
        """Per flash halfword, the index of its code's category (CATEGORIES)."""
        m = bytearray(FLASH_SIZE // 2)
        index = {c: i for i, c in enumerate(CATEGORIES)}
        for addr, size, name in self._funcs:
            cat = next((c for c, prefixes in _PREFIXES if name.startswith(prefixes)), "other")
            i = index[cat]
            if i and FLASH_BASE <= addr < FLASH_BASE + FLASH_SIZE:
                h0 = (addr - FLASH_BASE) // 2
                m[h0 : h0 + (size + 1) // 2] = bytes([i]) * ((size + 1) // 2)
        return m

    def sync_map(self):
        """A bit per flash halfword at the instructions that may unmask a pending interrupt:
        CPSIE i (0xB662) and MSR PRIMASK/BASEPRI/BASEPRI_MAX, Rn (0xF38n 0x881x)."""
        d = self.data
        bits = bytearray(FLASH_SIZE // 16)
        for h in range(0, len(d) - 3, 2):
            w = d[h] | (d[h + 1] << 8)
            if w == 0xB662 or ((w & 0xFFF0) == 0xF380 and d[h + 3] == 0x88 and d[h + 2] in
                                (0x10, 0x11, 0x12)):  # fmt: skip
                i = h // 2
                bits[i >> 3] |= 1 << (i & 7)
        return bits
