"""GPIO ports A-E and H (RM0383 section 8).

Registers as on the chip: MODER, OTYPER, OSPEEDR, PUPDR, IDR (read only), ODR, BSRR (write
only: bits 0-15 set, 16-31 reset), LCKR (the lock sequence is not modelled: a write stops the
run), AFRL/AFRH; the reset values of ports A and B carry the debug pins.

A pin's level: an output (MODER 01) drives its ODR bit; otherwise something outside drives it
(`drive(pin, level)`: the board's button, a sensor's line, the GNSS receiver's PPS), else the
pull-up or pull-down (PUPDR), else it floats and reads 0 (documented, not a board fact: a
floating CMOS input reads either). `watch(pin, fn)`: fn(level) on each change of an output,
so devices see their chip selects; EXTI (exti.py) sees every change of an input.
"""

from host_emulator.f411.bus import Peripheral

_PORTS = "ABCDEH"
MODER, PUPDR, IDR, ODR, BSRR = 0x00, 0x0C, 0x10, 0x14, 0x18


class Gpio(Peripheral):
    REGISTERS = (
        ("MODER", 0x00, 0),
        ("OTYPER", 0x04, 0, 0xFFFF),
        ("OSPEEDR", 0x08, 0),
        ("PUPDR", 0x0C, 0),
        ("IDR", 0x10, 0, 0),
        ("ODR", 0x14, 0, 0xFFFF),
        ("BSRR", 0x18, 0, 0),
        ("LCKR", 0x1C, 0, 0),
        ("AFRL", 0x20, 0),
        ("AFRH", 0x24, 0),
    )

    def __init__(self, chip, port):
        self.port = port
        self.index = _PORTS.index(port)
        self.NAME = "GPIO" + port
        self.BASE = 0x40020000 + (0x1C00 if port == "H" else 0x400 * self.index)
        self.CLOCK = ("AHB1ENR", 7 if port == "H" else self.index)
        self.external = {}  # pin -> level driven from outside
        self.watchers = {}  # pin -> [fn(level)]
        super().__init__(chip)
        self._levels = self.levels()

    def reset(self):
        super().reset()
        self._now = None
        if self.port == "A":
            self.v[MODER], self.v[0x08], self.v[PUPDR] = 0xA8000000, 0x0C000000, 0x64000000
        elif self.port == "B":
            self.v[MODER], self.v[0x08], self.v[PUPDR] = 0x00000280, 0x000000C0, 0x00000100

    def mode(self, pin):
        return (self.v[MODER] >> (2 * pin)) & 3

    def _level(self, pin):
        if self.mode(pin) == 1:
            return (self.v[ODR] >> pin) & 1
        ext = self.external.get(pin)
        if ext is not None:
            return ext
        return 1 if (self.v[PUPDR] >> (2 * pin)) & 3 == 1 else 0

    def level(self, pin):
        return (self.levels() >> pin) & 1

    def levels(self):
        """The 16 pins' levels, kept until a write to the port, a reset or drive(): chip
        selects and the RS485 driver enable are asked for every byte."""
        v = self._now
        if v is None:
            v = 0
            for pin in range(16):
                v |= self._level(pin) << pin
            self._now = v
        return v

    def bus_write(self, off, size, value):
        self._now = None
        super().bus_write(off, size, value)

    def drive(self, pin, level):
        """Something outside drives the pin (None: lets go of it)."""
        self.external[pin] = level
        self._now = None
        self._changed()

    def watch(self, pin, fn):
        self.watchers.setdefault(pin, []).append(fn)

    def _changed(self):
        new = self.levels()
        diff = new ^ self._levels
        self._levels = new
        if not diff:
            return
        for pin in range(16):
            if diff >> pin & 1:
                level = (new >> pin) & 1
                for fn in self.watchers.get(pin, ()):
                    fn(level)
                if self.mode(pin) != 1:
                    self.chip.exti.edge(self.index, pin, level)

    def read_IDR(self):
        return self.levels()

    def write_MODER(self, value):
        self.v[MODER] = value
        self._changed()

    def write_PUPDR(self, value):
        self.v[PUPDR] = value
        self._changed()

    def write_ODR(self, value):
        self.v[ODR] = value & 0xFFFF
        self._changed()

    def write_BSRR(self, value):
        self.v[ODR] = (self.v[ODR] | (value & 0xFFFF)) & ~(value >> 16)
        self._changed()

    def write_LCKR(self, value):
        self.chip.unsupported(f"GPIO{self.port} configuration lock (LCKR)")
