"""SYSCFG (RM0383 section 7): which port drives each EXTI line (EXTICR1-4), the memory
remap (MEMRMP: only main flash at 0, the reset state, is modelled), PMC, the compensation
cell (CMPCR.READY follows CMP_PD at once)."""

from host_emulator.f411.bus import Peripheral


class Syscfg(Peripheral):
    NAME = "SYSCFG"
    BASE = 0x40013800
    CLOCK = ("APB2ENR", 14)
    REGISTERS = (
        ("MEMRMP", 0x00, 0, 0x3),
        ("PMC", 0x04, 0, 0x00010000),
        ("EXTICR1", 0x08, 0, 0xFFFF),
        ("EXTICR2", 0x0C, 0, 0xFFFF),
        ("EXTICR3", 0x10, 0, 0xFFFF),
        ("EXTICR4", 0x14, 0, 0xFFFF),
        ("CMPCR", 0x20, 0, 0x1),
    )

    def port_of_line(self, line):
        return (self.v[0x08 + 4 * (line // 4)] >> (4 * (line % 4))) & 0xF

    def write_MEMRMP(self, value):
        if value & 3:
            self.chip.unsupported(f"memory remap SYSCFG_MEMRMP = {value & 3}")

    def read_CMPCR(self):
        v = self.v[0x20]
        return v | ((v & 1) << 8)
