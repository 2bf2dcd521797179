"""Peripherals the image only switches off: SPI2-5 and I2C1-3, which the NUCLEO image's board
definition declares (tools/image/boards) and the port's soft reset de-initialises whether or
not they were used (ports/stm32/main.c: spi_deinit_all, and the I2C buses' HAL_I2C_DeInit):
HAL_SPI_DeInit and HAL_I2C_DeInit read CR1 and write it back with the enable bit clear, then
reset the block through RCC, all with the peripheral's clock off (nothing ever enabled it).

On the chip a register of a peripheral whose clock is off reads 0 and ignores writes; here
every register reads 0, a write of 0 is taken, and anything else stops the run (nothing of
these peripherals is modelled: a firmware that uses one needs a model first).
"""

from host_emulator.f411.bus import Peripheral


class Inert(Peripheral):
    """A peripheral that may only be read (0) and written 0."""

    def __init__(self, chip, name, base, size):
        self.NAME = name
        self.BASE = base
        self.REGISTERS = tuple((f"R{o:02X}", o, 0, 0) for o in range(0, size, 4))
        super().__init__(chip)

    def bus_read(self, off, size):
        if (off & ~3) not in self.regs:
            return super().bus_read(off, size)
        return 0

    def bus_write(self, off, size, value):
        if (off & ~3) not in self.regs:
            super().bus_write(off, size, value)
        elif value:
            self.chip.unsupported(f"{self.NAME} (a write of 0x{value:X} at +0x{off:02X}; "
                                  "only its switching off at a soft reset is)")  # fmt: skip


# (name, base, register bytes) of RM0383's memory map
BLOCKS = (
    ("SPI2", 0x40003800, 0x24), ("SPI3", 0x40003C00, 0x24), ("SPI4", 0x40013400, 0x24),
    ("SPI5", 0x40015000, 0x24), ("I2C1", 0x40005400, 0x28), ("I2C2", 0x40005800, 0x28),
    ("I2C3", 0x40005C00, 0x28),
)  # fmt: skip
