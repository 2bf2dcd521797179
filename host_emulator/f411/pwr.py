"""PWR, the power controller (RM0383 section 5): the regulator's voltage scale (CSR.VOSRDY is
set: the scale is ready at once) and the backup domain's write protection (CR.DBP: writes to
RCC_BDCR and the RTC are ignored while it is clear, as on the chip). Low-power modes are not
modelled (stop and standby would stop the run: cpu.py refuses SLEEPDEEP)."""

from host_emulator.f411.bus import Peripheral

DBP = 1 << 8
VOSRDY = 1 << 14


class Pwr(Peripheral):
    NAME = "PWR"
    BASE = 0x40007000
    CLOCK = ("APB1ENR", 28)
    REGISTERS = (
        ("CR", 0x00, 0x00008000, 0x0000CFFF),
        ("CSR", 0x04, 0x00000000, 0x00000300),
    )

    def backup_writable(self):
        return bool(self.v[0x00] & DBP)

    def read_CSR(self):
        return self.v[0x04] | VOSRDY
