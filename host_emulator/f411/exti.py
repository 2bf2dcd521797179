"""EXTI, the external interrupt controller (RM0383 section 10): 23 lines, 0-15 from the GPIO
pins (the port SYSCFG_EXTICR selects), 16-22 from PVD, the RTC and USB wakeup. An edge
(rising with RTSR, falling with FTSR) on a line sets PR; PR & IMR holds the line's interrupt
(EXTI0-4: IRQ 6-10, EXTI9_5: 23, EXTI15_10: 40, PVD 1, RTC alarm 41, USB wakeup 42, RTC tamper
2, RTC wakeup 3) until software writes 1 to PR. SWIER sets PR by software. Events (EMR) are
stored only: nothing here waits for an event (WFE is not modelled)."""

from host_emulator.f411.bus import Peripheral

_IRQ = {0: 6, 1: 7, 2: 8, 3: 9, 4: 10, 16: 1, 17: 41, 18: 42, 21: 2, 22: 3}
for _line in range(5, 10):
    _IRQ[_line] = 23
for _line in range(10, 16):
    _IRQ[_line] = 40
IMR, RTSR, FTSR, SWIER, PR = 0x00, 0x08, 0x0C, 0x10, 0x14
_LINES = 0x7FFFFF


class Exti(Peripheral):
    NAME = "EXTI"
    BASE = 0x40013C00
    REGISTERS = (
        ("IMR", 0x00, 0, _LINES),
        ("EMR", 0x04, 0, _LINES),
        ("RTSR", 0x08, 0, _LINES),
        ("FTSR", 0x0C, 0, _LINES),
        ("SWIER", 0x10, 0, _LINES),
        ("PR", 0x14, 0, 0),
    )

    def __init__(self, chip):
        super().__init__(chip)
        self.edges = 0

    def irq_level(self, irq):
        active = self.v[PR] & self.v[IMR]
        return any(active >> line & 1 for line, i in _IRQ.items() if i == irq)

    def _raise(self, line):
        self.v[PR] |= 1 << line
        if self.v[IMR] >> line & 1:
            self.chip.scs.irq(_IRQ[line])

    def edge(self, port_index, pin, level):
        """A GPIO input changed level."""
        if self.chip.syscfg.port_of_line(pin) != port_index:
            return
        trig = self.v[RTSR] if level else self.v[FTSR]
        if trig >> pin & 1:
            self.edges += 1
            self._raise(pin)

    def write_SWIER(self, value):
        for line in range(23):
            if value >> line & 1 and not self.v[SWIER] >> line & 1:
                self._raise(line)
        self.v[SWIER] = value & _LINES

    def write_PR(self, value):
        self.v[PR] &= ~value
        self.v[SWIER] &= ~value

    def write_IMR(self, value):
        self.v[IMR] = value & _LINES
        for line, irq in _IRQ.items():
            if value >> line & 1 and self.v[PR] >> line & 1:
                self.chip.scs.irq(irq)
