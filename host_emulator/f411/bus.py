"""The twin's address map: which model answers an address, and what happens when none does.

Memory (flash, its alias at 0, SRAM, system memory) is plain Unicorn memory. Every peripheral is
a `Peripheral` (one file per peripheral of RM0383, the STM32F411 reference manual) mapped as
MMIO at its base, so each register access is a call into its model. Addresses of the
peripheral region (0x40000000-0x5FFFFFFF) and the system control space that no model claims
are not mapped: an access there stops the run with the address, the peripheral it belongs to
(if RM0383 has one there) and the C function that made it (from the ELF's symbols). So does an
access to an offset of a modelled peripheral that its model does not declare, or to a
peripheral whose clock the image has not enabled: never a silent zero.

Speed: a register without behaviour (no read_/write_ method) is read and written in C
(mmio.c), in the model's register array `v`, without a call into Python; the models see the
same values there. A model that overrides bus_read or bus_write names the offsets its override
is for in OVERRIDES, and those stay in Python (None, the default: the override sees every
offset, and none of that direction is served in C).

Bit-band: a word access at 0x42000000 + 32 * (a - 0x40000000) + 4 * b reads or writes bit b of
the peripheral byte at a (a read-modify-write of the register, as the core's bus does).

Polling: a busy loop that reads the same register and gets the same value again and again
(uart_wait_flag_set spinning on TXE, flash_wait_for_last_operation on BSY) costs the board the
time until the flag changes. The bus notices the third identical read of a register by the
same instruction within a few dozen instructions of the one before, with no other peripheral
access between them, and moves the clock to the moment the register changes (the
peripheral's `next_change`) or the next event, whichever is first: the wait costs what it
costs on the board, without emulating its iterations. Only flags whose change the model can
date are skipped this way (a UART's TXE and TC, SPI's flags, FLASH_SR.BSY, IWDG_SR); any other
loop runs instruction by instruction.
"""

from common.errors import EmulatorError
from host_emulator.f411 import counter

# RCC's peripheral clock enable registers (rcc.py), by name
ENABLE_REGISTERS = {"AHB1ENR": 0x30, "AHB2ENR": 0x34, "APB1ENR": 0x40, "APB2ENR": 0x44}


class TwinError(EmulatorError):
    """The emulated chip met something it does not model, or the image faulted."""


# Peripherals of RM0383's memory map (table 1), for naming an address nobody models
RM0383_BLOCKS = (
    (0x40000000, "TIM2"), (0x40000400, "TIM3"), (0x40000800, "TIM4"), (0x40000C00, "TIM5"),
    (0x40002800, "RTC_BKP"), (0x40002C00, "WWDG"), (0x40003000, "IWDG"),
    (0x40003400, "I2S2ext"), (0x40003800, "SPI2_I2S2"), (0x40003C00, "SPI3_I2S3"),
    (0x40004000, "I2S3ext"), (0x40004400, "USART2"), (0x40005400, "I2C1"),
    (0x40005800, "I2C2"), (0x40005C00, "I2C3"), (0x40007000, "PWR"), (0x40010000, "TIM1"),
    (0x40011000, "USART1"), (0x40011400, "USART6"), (0x40012000, "ADC1"),
    (0x40012C00, "SDIO"), (0x40013000, "SPI1_I2S1"), (0x40013400, "SPI4_I2S4"),
    (0x40013800, "SYSCFG"), (0x40013C00, "EXTI"), (0x40014000, "TIM9"), (0x40014400, "TIM10"),
    (0x40014800, "TIM11"), (0x40015000, "SPI5_I2S5"), (0x40020000, "GPIOA"),
    (0x40020400, "GPIOB"), (0x40020800, "GPIOC"), (0x40020C00, "GPIOD"), (0x40021000, "GPIOE"),
    (0x40021C00, "GPIOH"), (0x40023000, "CRC"), (0x40023800, "RCC"),
    (0x40023C00, "FLASH_IF"), (0x40026000, "DMA1"), (0x40026400, "DMA2"),
    (0x50000000, "USB_OTG_FS"), (0xE0042000, "DBGMCU"),
)  # fmt: skip


def block_name(address):
    for base, name in RM0383_BLOCKS:
        if base <= address < base + 0x400 or (name == "USB_OTG_FS" and base <= address < base
                                                 + 0x40000):  # fmt: skip
            return name
    return None


class Register:
    __slots__ = ("name", "offset", "reset", "writable")

    def __init__(self, name, offset, reset=0, writable=0xFFFFFFFF):
        self.name = name
        self.offset = offset
        self.reset = reset
        self.writable = writable


class Peripheral:
    """A peripheral: its registers (REGISTERS: (name, offset, reset value, writable bits)),
    stored values in `v` (offset -> u32), and behaviour in methods named after the registers:
    `read_<NAME>(self) -> value` replaces the stored value on a read; `write_<NAME>(self,
    value)` replaces the store on a write (the writable bits are applied first unless it
    is defined: it sees the raw value). `next_change(offset)` says when a lazily computed
    register will read differently (polling, above). CLOCK: (RCC enable register, bit) that
    must be set for the peripheral to answer. OVERRIDES: the offsets a bus_read or bus_write
    override needs to see (None: every one)."""

    NAME = "?"
    BASE = 0
    SIZE = 0x400
    REGISTERS = ()
    CLOCK = None
    OVERRIDES = None

    def __init__(self, chip):
        self.chip = chip
        self.clock = chip.clock
        self.regs = {}
        for spec in self.REGISTERS:
            r = Register(*spec)
            self.regs[r.offset] = r
        ffi, _ = counter.load()
        self.v = ffi.new("uint32_t[]", self.SIZE)  # by byte offset; shared with mmio.c
        self._readers = {}
        self._writers = {}
        for off, r in self.regs.items():
            self._readers[off] = getattr(self, "read_" + r.name, None)
            self._writers[off] = getattr(self, "write_" + r.name, None)
        # the RCC enable register and bit gating it (every access looks)
        c = self.CLOCK
        self._gate = None if c is None else (ENABLE_REGISTERS[c[0]], c[1])
        self.reset()

    def reset(self):
        for off, r in self.regs.items():
            self.v[off] = r.reset

    def plain_words(self):
        """Per word of the window: 1 when C may serve its reads, 2 its writes (both: 3)."""
        kinds = bytearray(self.SIZE // 4)
        base = Peripheral
        for off in self.regs:
            if self.OVERRIDES is not None and off in self.OVERRIDES:
                continue
            read_ok = type(self).bus_read is base.bus_read or self.OVERRIDES is not None
            write_ok = type(self).bus_write is base.bus_write or self.OVERRIDES is not None
            kinds[off >> 2] = ((read_ok and self._readers[off] is None) |
                               (write_ok and self._writers[off] is None) << 1)  # fmt: skip
        return kinds

    def name_of(self, off):
        r = self.regs.get(off & ~3)
        return f"{self.NAME}_{r.name}" if r else f"{self.NAME}+0x{off:03X}"

    def next_change(self, off):
        """The cycle at which register `off` will read differently without an access, or None
        when only an event (on the clock) or an access changes it."""
        return None

    # -- the bus calls these ------------------------------------------------------------

    def bus_read(self, off, size):
        w = off & ~3
        r = self.regs.get(w)
        if r is None:
            self.chip.unmodelled("read", self.BASE + off, self.name_of(off))
        g = self._gate
        if g is not None and not (self.chip.rcc.v[g[0]] >> g[1]) & 1:
            self._clock_off("read", off)
        fn = self._readers[w]
        value = fn() if fn is not None else self.v[w]
        if size == 4:
            return value & 0xFFFFFFFF
        return (value >> ((off & 3) * 8)) & ((1 << (size * 8)) - 1)

    def bus_write(self, off, size, value):
        w = off & ~3
        r = self.regs.get(w)
        if r is None:
            self.chip.unmodelled("write", self.BASE + off, self.name_of(off))
        g = self._gate
        if g is not None and not (self.chip.rcc.v[g[0]] >> g[1]) & 1:
            self._clock_off("write", off)
        if size != 4:
            sh = (off & 3) * 8
            m = ((1 << (size * 8)) - 1) << sh
            value = (self.v[w] & ~m) | ((value << sh) & m)
        fn = self._writers[w]
        if fn is not None:
            fn(value & 0xFFFFFFFF)
        else:
            self.v[w] = (self.v[w] & ~r.writable) | (value & r.writable)

    def _clock_off(self, what, off):
        reg, bit = self.CLOCK
        raise TwinError(
            f"{what} of {self.name_of(off)} with the peripheral's clock off (RCC {reg} bit "
            f"{bit} clear) in {self.chip.where()}: on the board it reads 0 and ignores writes"
        )


class Bus:
    """Maps peripherals into the Unicorn engine and watches for polling loops."""

    POLL_REPEATS = 3  # identical reads in a row that make a polling loop
    POLL_GAP = 64  # at most this many instructions between them

    def __init__(self, chip):
        self.chip = chip
        self.uc = chip.cpu.uc
        self.peripherals = []
        self._last = None  # (address, value, icount, pc) of the last peripheral read
        self._repeats = 0
        self.polls_skipped = 0
        self.poll_wait_cycles = 0  # cycles the clock moved over polling loops
        self.poll_wait_by = {}  # ... per peripheral polled (its NAME)
        ffi, _ = counter.load()
        self._served = ffi.new("uint32_t *")  # mmio.c served an access (not a polling loop)
        self._map_fn = ffi.cast("void *", counter.uc_function("uc_mmio_map"))
        self._keep = []  # what mmio.c's maps point at

    def add(self, p):
        self.peripherals.append(p)
        base, size = p.BASE, p.SIZE
        ffi, lib = counter.load()
        cpu = self.chip.cpu
        fail = cpu.fail

        def read(uc, off, sz, _data, p=p, base=base):
            try:
                value = p.bus_read(off, sz)
                self._watch(base + off, value, p)
                return value
            except BaseException as e:  # noqa: BLE001  (Unicorn would drop it: cpu.fail keeps it)
                fail(e)
                return 0

        def write(uc, off, sz, value, _data, p=p):
            self._last = None
            try:
                p.bus_write(off, sz, value)
            except BaseException as e:  # noqa: BLE001
                fail(e)

        c = ffi.new("twin_periph *")
        plain = ffi.new("uint8_t[]", bytes(p.plain_words()))
        writable = ffi.new("uint32_t[]", size // 4)
        for off, r in p.regs.items():
            writable[off >> 2] = r.writable
        c.v, c.plain, c.writable, c.words, c.served = p.v, plain, writable, size // 4, self._served
        if p._gate is not None:
            c.gate, c.gate_bit = self.chip.rcc.v + p._gate[0], p._gate[1]
        cbs = (
            ffi.callback("uint64_t(void *, uint64_t, unsigned, void *)", read),
            ffi.callback("void(void *, uint64_t, unsigned, uint64_t, void *)", write),
        )
        c.py_read, c.py_write = cbs
        err = lib.twin_mmio_map(self._map_fn, cpu._uc_ptr, base, size, c)
        if err:
            raise TwinError(f"Unicorn refused to map {p.NAME} at 0x{base:08X} (error {err})")
        self._keep.append((c, plain, writable, cbs))
        return p

    def forget_polling(self):
        """An exception or a stop came between two reads: not one polling loop."""
        self._last = None
        self._repeats = 0

    def _watch(self, address, value, p):
        served = self._served
        if served[0]:  # another register, read or written in C, came between
            served[0] = 0
            self._last = None
        n = self.chip.cpu.counter.icount
        last = self._last
        if last is not None and last[0] == address and last[1] == value and \
                n - last[2] <= self.POLL_GAP:  # fmt: skip
            pc = self.chip.cpu.pc()
            if pc == last[3]:
                self._repeats += 1
                self._last = (address, value, n, pc)
                if self._repeats >= self.POLL_REPEATS - 1:
                    self._fast_forward(address, p)
                return
            self._last = (address, value, n, pc)
        else:
            self._last = (address, value, n, None if last is None or last[0] != address
                          else self.chip.cpu.pc())  # fmt: skip
        self._repeats = 0

    def _fast_forward(self, address, p):
        """A polling loop on a flag that changes at a known cycle (the peripheral's
        next_change): the clock moves there, or to the next event if that comes first (its
        interrupt is taken, then the loop reads again). A register whose next change is not
        known is not skipped: the loop is emulated instruction by instruction, which is
        always right (a loop that drains a UART's receive ring reads SR once per byte, from
        one instruction: that is not a wait)."""
        clock = self.chip.clock
        change = p.next_change(address - p.BASE)
        if change is None:
            return
        ev = clock.next_event()
        t = change if ev is None else min(change, ev)
        if t > clock.now():
            self.poll_wait_cycles += t - clock.now()
            self.poll_wait_by[p.NAME] = self.poll_wait_by.get(p.NAME, 0) + t - clock.now()
            clock.wait_until(t)
            self.polls_skipped += 1
        if ev is not None and t >= ev:
            self.chip.cpu.stop_soon()  # the event fires before the next read
        self._repeats = 0
        self._last = None

    # -- bit-band alias of the peripherals ---------------------------------------------

    def map_bitband(self):
        def owner(addr):
            for p in self.peripherals:
                if p.BASE <= addr < p.BASE + p.SIZE:
                    return p
            self.chip.unmodelled("bit-band access", addr, block_name(addr) or "nothing")
            return None

        fail = self.chip.cpu.fail

        def read(uc, off, sz, _data):
            try:
                a = 0x40000000 + off // 32
                bit = (off % 32) // 4 + (a & 3) * 8
                p = owner(a)
                return (p.bus_read((a & ~3) - p.BASE, 4) >> bit) & 1
            except BaseException as e:  # noqa: BLE001
                fail(e)
                return 0

        def write(uc, off, sz, value, _data):
            try:
                a = 0x40000000 + off // 32
                bit = (off % 32) // 4 + (a & 3) * 8
                p = owner(a)
                w = (a & ~3) - p.BASE
                old = p.bus_read(w, 4)
                new = (old | (1 << bit)) if value & 1 else (old & ~(1 << bit))
                self._last = None
                p.bus_write(w, 4, new)
            except BaseException as e:  # noqa: BLE001
                fail(e)

        self.uc.mmio_map(0x42000000, 0x02000000, read, None, write, None)
