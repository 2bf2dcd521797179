"""The embedded flash's interface (RM0383 section 3) and the flash memory it programs.

The F411's 512 KB: sectors 0-3 of 16 KB, 4 of 64 KB, 5-7 of 128 KB from 0x08000000 (the
port keeps its filesystem in sectors 1-3). FLASH_KEYR unlocks FLASH_CR with its two keys (a
wrong key locks it until reset); a sector erase (SER, SNB, STRT) fills the sector with 0xFF, a
program (PG set, then a store into flash of PSIZE bytes) clears bits. Each takes the
datasheet's typical time (DS10314 "Flash memory characteristics", x32 parallelism: a word
16 us, a 16 KB sector 250 ms, 64 KB 550 ms, 128 KB 1.1 s), BSY set meanwhile. The core fetches
its instructions from this flash, so it stalls until the operation ends: the twin's clock jumps
over it (counted as waiting), as the board's does. Strict where the board fails silently or
sets an error flag: a store into flash without PG, programming bits that are not erased, a
program or erase while locked, stop the run with what was wrong.

ACR: LATENCY (the wait states; rcc.py refuses a clock faster than they allow), the prefetch
and caches (stored: the CPI includes their effect).
"""

from host_emulator.f411.bus import Peripheral, TwinError

FLASH_BASE = 0x08000000
FLASH_SIZE = 512 * 1024
SECTORS = tuple(
    (FLASH_BASE + off, size)
    for off, size in zip(
        (0x0000, 0x4000, 0x8000, 0xC000, 0x10000, 0x20000, 0x40000, 0x60000),
        (16384,) * 4 + (65536,) + (131072,) * 3,
        strict=True,
    )
)
KEY1, KEY2 = 0x45670123, 0xCDEF89AB
WORD_US = 16
ERASE_MS = {16384: 250, 65536: 550, 131072: 1100}
SR_BSY = 1 << 16
SR_EOP = 1
CR_PG, CR_SER, CR_MER, CR_STRT, CR_LOCK = 1, 2, 4, 1 << 16, 1 << 31


class FlashIf(Peripheral):
    NAME = "FLASH"
    BASE = 0x40023C00
    REGISTERS = (
        ("ACR", 0x00, 0x00000000, 0x00001F0F),
        ("KEYR", 0x04, 0, 0),
        ("OPTKEYR", 0x08, 0, 0),
        ("SR", 0x0C, 0x00000000, 0),
        ("CR", 0x10, 0x80000000, 0x030103FF),
        ("OPTCR", 0x14, 0x0FFFAAED, 0),
    )

    def __init__(self, chip):
        super().__init__(chip)
        self._key_step = 0
        self._busy_until = 0
        self.erases = 0
        self.words_programmed = 0
        self.stall_cycles = 0

    def reset(self):
        super().reset()
        self._key_step = 0
        self._busy_until = 0

    def latency(self):
        return self.v[0x00] & 0xF

    def busy(self):
        return self.clock.now() < self._busy_until

    def next_change(self, off):
        return self._busy_until if off == 0x0C and self.busy() else None

    def read_SR(self):
        return self.v[0x0C] | (SR_BSY if self.busy() else 0)

    def write_SR(self, value):
        self.v[0x0C] &= ~(value & 0xF3)  # EOP and the error flags: write 1 to clear

    def write_KEYR(self, value):
        cr = self.v[0x10]
        if not cr & CR_LOCK:
            return
        if self._key_step == 0 and value == KEY1:
            self._key_step = 1
        elif self._key_step == 1 and value == KEY2:
            self.v[0x10] = cr & ~CR_LOCK
            self._key_step = 0
        else:
            self._key_step = 2  # a wrong sequence locks FLASH_CR until the next reset

    def write_OPTKEYR(self, value):
        self.chip.unsupported("option bytes programming (FLASH_OPTKEYR)")

    def write_CR(self, value):
        cr = self.v[0x10]
        if cr & CR_LOCK:
            if value & CR_LOCK:
                return
            raise TwinError(f"write of FLASH_CR while it is locked in {self.chip.where()}")
        if value & CR_MER:
            self.chip.unsupported("flash mass erase")
        self.v[0x10] = (value & 0x030103FF) | (value & CR_LOCK)
        if value & CR_STRT and value & CR_SER:
            self._erase((value >> 3) & 0xF)
            self.v[0x10] &= ~CR_STRT

    def _operation(self, us):
        """An operation of `us` microseconds from now: BSY until it ends; the core, which
        fetches from flash, stalls until then."""
        end = self.clock.now() + self.clock.cycles_for_us(us)
        self._busy_until = end
        if FLASH_BASE <= self.chip.cpu.pc() < FLASH_BASE + FLASH_SIZE:
            before = self.clock.now()
            self.clock.wait_until(end)
            self.stall_cycles += self.clock.now() - before
        self.v[0x0C] |= SR_EOP if self.v[0x10] & (1 << 24) else 0

    def _erase(self, snb):
        if snb >= len(SECTORS):
            raise TwinError(f"erase of flash sector {snb} (the F411 has 0-7) in "
                            f"{self.chip.where()}")  # fmt: skip
        if self.busy():
            raise TwinError(f"flash erase started while busy in {self.chip.where()}")
        base, size = SECTORS[snb]
        self.chip.flash_fill(base, size, 0xFF)
        self.erases += 1
        self._operation(ERASE_MS[size] * 1000)

    def program(self, address, size, value):
        """A store into flash memory (the chip's write hook calls this before the store)."""
        cr = self.v[0x10]
        where = self.chip.where
        if not cr & CR_PG or cr & CR_LOCK:
            raise TwinError(f"store of {size} byte(s) into flash at 0x{address:08X} without "
                            f"programming enabled (FLASH_CR.PG) in {where()}")  # fmt: skip
        psize = 1 << ((cr >> 8) & 3)
        if size != psize:
            raise TwinError(f"flash programmed {size} byte(s) at a time with PSIZE "
                            f"{psize} (FLASH_CR) at 0x{address:08X} in {where()}")  # fmt: skip
        old = self.chip.flash_read(address, size)
        if old != b"\xff" * size:
            raise TwinError(f"flash programmed at 0x{address:08X} over bits that are not "
                            f"erased (holds {old.hex()}) in {where()}")  # fmt: skip
        if self.busy():
            self.clock.wait_until(self._busy_until)  # the store waits for the last one
        self.words_programmed += 1
        self._operation(WORD_US * max(1, size // 4))
