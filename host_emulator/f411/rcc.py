"""RCC, reset and clock control (RM0383 section 6).

Modelled: the oscillators' ready bits follow their enable bits at once (HSI, HSE, PLL,
PLLI2S in CR; LSE in BDCR; LSI in CSR): the image waits for them, the twin does not make it
wait; the system clock switch (CFGR.SWS follows SW) and the clock tree: SYSCLK from HSI
(16 MHz), HSE (the board's crystal or, bypassed, its clock input) or the main PLL (input / M x
N / P), HCLK = SYSCLK / HPRE, PCLK1/2 = HCLK / PPRE1/2; HCLK feeds the twin's clock (clock.py).
Switching to a clock that the flash's wait states (FLASH_ACR.LATENCY) cannot follow (30 MHz
per wait state at 2.7-3.6 V, RM0383 table 6) stops the run: a board would read garbage.
The enable registers gate the peripherals (bus.py refuses an access to a peripheral whose
clock is off); the reset registers reset the peripheral models; CSR's reset flags say why the
chip last reset (power-on, pin, independent watchdog, software) until RMVF clears them.
"""

from host_emulator.f411.bus import ENABLE_REGISTERS, Peripheral, TwinError

HSI_HZ = 16_000_000
CR, PLLCFGR, CFGR = 0x00, 0x04, 0x08
BDCR, CSR = 0x70, 0x74
_AHB_DIV = {8: 2, 9: 4, 10: 8, 11: 16, 12: 64, 13: 128, 14: 256, 15: 512}
_APB_DIV = {4: 2, 5: 4, 6: 8, 7: 16}
CSR_PORRST = 1 << 27
CSR_PINRST = 1 << 26
CSR_BORRST = 1 << 25
CSR_SFTRST = 1 << 28
CSR_IWDGRST = 1 << 29
CSR_RMVF = 1 << 24


class Rcc(Peripheral):
    NAME = "RCC"
    BASE = 0x40023800
    REGISTERS = (
        ("CR", 0x00, 0x00000083, 0x150D00F9),
        ("PLLCFGR", 0x04, 0x24003010, 0x0F437FFF),
        ("CFGR", 0x08, 0x00000000, 0xFFFFFCF3),
        ("CIR", 0x0C, 0x00000000, 0x00001F00),
        ("AHB1RSTR", 0x10, 0, 0x0060109F),
        ("AHB2RSTR", 0x14, 0, 0x00000080),
        ("APB1RSTR", 0x20, 0, 0x10E2C80F),
        ("APB2RSTR", 0x24, 0, 0x00177931),
        ("AHB1ENR", 0x30, 0, 0x0060109F),
        ("AHB2ENR", 0x34, 0, 0x00000080),
        ("APB1ENR", 0x40, 0, 0x10E2C80F),
        ("APB2ENR", 0x44, 0, 0x00177931),
        ("AHB1LPENR", 0x50, 0x0061900F, 0x0061909F),
        ("AHB2LPENR", 0x54, 0x00000080, 0x00000080),
        ("APB1LPENR", 0x60, 0x10E2C80F, 0x10E2C80F),
        ("APB2LPENR", 0x64, 0x00077930, 0x00177931),
        ("BDCR", 0x70, 0, 0x00018305),
        ("CSR", 0x74, 0x0E000000, 0x00000001),
        ("SSCGR", 0x80, 0, 0xCFFFFFFF),
        ("PLLI2SCFGR", 0x84, 0x24003000, 0x70007FFF),
        ("DCKCFGR", 0x8C, 0, 0x01000000),
    )

    def __init__(self, chip):
        self.resets = {}  # (register, bit) -> peripheral model, filled by the chip
        super().__init__(chip)
        self.reset_flags = CSR_PORRST | CSR_PINRST | CSR_BORRST

    def reset(self):
        backup = self.v[BDCR]  # the backup domain survives a system reset (0 at power-on)
        super().reset()
        self.v[BDCR] = backup
        self._clocks = None

    def bus_write(self, off, size, value):
        self._clocks = None  # (HCLK, PCLK1, PCLK2) computed anew when next asked
        super().bus_write(off, size, value)

    def enabled(self, reg, bit):
        return (self.v[ENABLE_REGISTERS[reg]] >> bit) & 1

    # -- the clock tree -----------------------------------------------------------------

    def sysclk(self):
        sw = self.v[CFGR] & 3
        if sw == 0:
            return HSI_HZ
        if sw == 1:
            return self.chip.board.hse_hz
        p = self.v[PLLCFGR]
        src = self.chip.board.hse_hz if p & (1 << 22) else HSI_HZ
        m, n = p & 0x3F, (p >> 6) & 0x1FF
        pdiv = ((p >> 16) & 3) * 2 + 2
        if not 2 <= m <= 63 or not 50 <= n <= 432:
            raise TwinError(f"PLL configured out of range (M {m}, N {n}) in {self.chip.where()}")
        return src // m * n // pdiv if src % m == 0 else src * n // (m * pdiv)

    def clock_tree(self):
        """(HCLK, PCLK1, PCLK2), kept until the next write to RCC: every UART character
        and SPI byte asks."""
        c = self._clocks
        if c is None:
            cfgr = self.v[CFGR]
            hclk = self.sysclk() // _AHB_DIV.get((cfgr >> 4) & 0xF, 1)
            c = self._clocks = (hclk, hclk // _APB_DIV.get((cfgr >> 10) & 7, 1),
                                hclk // _APB_DIV.get((cfgr >> 13) & 7, 1))  # fmt: skip
        return c

    def hclk(self):
        return self.clock_tree()[0]

    def pclk1(self):
        return self.clock_tree()[1]

    def pclk2(self):
        return self.clock_tree()[2]

    def _clock_changed(self):
        hz = self.hclk()
        ws = self.chip.flash_if.latency()
        if hz > 30_000_000 * (ws + 1):
            raise TwinError(
                f"HCLK {hz / 1e6:g} MHz with {ws} flash wait states (at most "
                f"{30 * (ws + 1)} MHz at 2.7-3.6 V, RM0383 table 6) in {self.chip.where()}"
            )
        self.clock.set_hz(hz)
        self.chip.clocks_changed()

    # -- registers ----------------------------------------------------------------------

    def read_CR(self):
        v = self.v[CR]
        return v | ((v & ((1 << 0) | (1 << 16) | (1 << 24) | (1 << 26))) << 1)

    def write_CR(self, value):
        old = self.v[CR]
        self.v[CR] = value & 0x150D00F9
        if old & (1 << 24) and not value & (1 << 24) and (self.v[CFGR] >> 2) & 3 == 2:
            raise TwinError(f"PLL stopped while it clocks the system in {self.chip.where()}")

    def read_CFGR(self):
        v = self.v[CFGR]
        return (v & ~0xC) | ((v & 3) << 2)

    def write_CFGR(self, value):
        old = self.v[CFGR]
        self.v[CFGR] = value & 0xFFFFFCF3
        if (old ^ value) & 0xFCF3 & ~0x0300:  # SW, HPRE, PPRE1/2 (not the MCO bits)
            if value & 3 == 2 and not self.v[CR] & (1 << 24):
                raise TwinError(f"system clock switched to a PLL that is off in "
                                f"{self.chip.where()}")  # fmt: skip
            self._clock_changed()

    def read_BDCR(self):
        v = self.v[BDCR]
        return v | ((v & 1) << 1)  # LSERDY = LSEON

    def write_BDCR(self, value):
        if not self.chip.pwr.backup_writable():
            return  # the backup domain is write-protected (PWR_CR.DBP clear): ignored
        if value & (1 << 16):  # BDRST
            self.v[BDCR] = 1 << 16
            self.chip.rtc.backup_reset()
            return
        self.v[BDCR] = value & 0x00018305

    def read_CSR(self):
        v = self.v[CSR] & 1
        return v | ((v & 1) << 1) | self.reset_flags

    def write_CSR(self, value):
        if value & CSR_RMVF:
            self.reset_flags = 0
        self.v[CSR] = value & 1

    def write_AHB1ENR(self, value):
        old = self.v[0x30]
        self.v[0x30] = value & self.regs[0x30].writable
        for bit, dma in ((21, self.chip.dma1), (22, self.chip.dma2)):
            if old >> bit & 1 and not value >> bit & 1:
                dma.clock_changed(False)

    def _reset_write(self, off, value):
        self.v[off] = value & self.regs[off].writable
        for b in range(32):
            if value >> b & 1:
                p = self.resets.get((off, b))
                if p is not None:
                    p.reset()

    def write_AHB1RSTR(self, value):
        self._reset_write(0x10, value)

    def write_AHB2RSTR(self, value):
        self._reset_write(0x14, value)

    def write_APB1RSTR(self, value):
        self._reset_write(0x20, value)

    def write_APB2RSTR(self, value):
        self._reset_write(0x24, value)
