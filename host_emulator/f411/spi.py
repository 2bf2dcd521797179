"""SPI1 in master mode (RM0383 section 20), wired to the devices on its bus.

A byte takes 8 x 2^(BR+1) bus-clock cycles (PCLK2 / 2^(BR+1): the port's 4 MHz request gives
3 MHz at 96 MHz). Polled: a write to DR starts a byte at once if the shift register is idle
(else it waits in DR, TXE clear); when a byte ends, the device's answer lands in DR with RXNE
(OVR if RXNE was still set: the byte is lost); BSY while bytes are shifting. With CR2.TXDMAEN
and RXDMAEN, the DMA streams (dma.py) move a whole block: `dma_block` exchanges every byte with
the device at the start, writes the answers to memory and sets the streams' flags at the
times the bytes end.

The devices: each has a chip-select pin (GPIO output, active low) and `select()`,
`exchange(mosi) -> miso (or -1: MISO floats)`, `deselect()`; `attach(device, port, pin)`.
A byte clocked with no chip select low, or with two, stops the run (a driver bug), as do the
modes the BMI055 cannot talk (CPOL/CPHA other than 0/0 or 1/1, LSB first, 16-bit frames) and
those not modelled (slave mode, bidirectional, CRC, TI frames, RXNE/TXE interrupts). The error
interrupt (CR2.ERRIE: OVR, MODF; SPI1 is IRQ 35) is modelled: ST's HAL enables it for DMA
transfers, and a transmit-only DMA transfer overruns the receive side on every other byte.
OVR clears by a read of DR followed by a read of SR.
"""

from host_emulator.f411.bus import Peripheral, TwinError

CR1, CR2, SR, DR = 0x00, 0x04, 0x08, 0x0C
RXNE, TXE, OVR, BSY = 1, 2, 1 << 6, 1 << 7
SPE, MSTR = 1 << 6, 1 << 2
RXDMAEN, TXDMAEN, ERRIE = 1, 2, 1 << 5
IRQ = 35
MISO_FLOAT = 0xFF  # a floating MISO with the usual pull-up


class Spi(Peripheral):
    NAME = "SPI1"
    BASE = 0x40013000
    CLOCK = ("APB2ENR", 12)
    REGISTERS = (
        ("CR1", 0x00, 0, 0xFFFF),
        ("CR2", 0x04, 0, 0x00F7),
        ("SR", 0x08, 0x0002, 0),
        ("DR", 0x0C, 0, 0xFFFF),
        ("CRCPR", 0x10, 0x0007, 0xFFFF),
        ("RXCRCR", 0x14, 0, 0),
        ("TXCRCR", 0x18, 0, 0),
        ("I2SCFGR", 0x1C, 0, 0x0FBF),
        ("I2SPR", 0x20, 0x0002, 0x03FF),
    )

    def __init__(self, chip):
        self.devices = []  # (device, gpio port, pin)
        self.bytes = 0
        super().__init__(chip)
        chip.irq_sources[IRQ] = self.irq_level

    def reset(self):
        super().reset()
        self._queue = []  # (end cycle, miso) of bytes shifting, in order
        self._rx = 0
        self._flags = 0  # RXNE, OVR
        self._busy_until = 0
        self._waiting = None  # a byte written while the shift register was busy
        self._dr_read = False  # DR read since OVR was set (the first half of clearing it)

    # A soft reset de-initialises every SPI the board defines, used or not (ports/stm32/main.c,
    # spi_deinit_all): HAL_SPI_DeInit reads CR1 and writes it back with SPE clear, with SPI1's
    # clock off after a start that never used it (a maintenance start). On the chip such a
    # register reads 0 and ignores writes: so here, for that access only; any other access
    # with the clock off still stops the run.
    OVERRIDES = (CR1,)  # bus_read and bus_write below: CR1 only

    def _clocked(self):
        return self.chip.rcc.enabled(*self.CLOCK)

    def bus_read(self, off, size):
        if off & ~3 == CR1 and not self._clocked():
            return 0
        return super().bus_read(off, size)

    def bus_write(self, off, size, value):
        if off & ~3 == CR1 and not self._clocked() and not value & SPE:
            return
        super().bus_write(off, size, value)

    def attach(self, device, gpio, pin):
        self.devices.append((device, gpio, pin))

        def cs(level, device=device):
            if level:
                device.deselect()
            else:
                device.select()

        gpio.watch(pin, cs)

    def byte_cycles(self):
        br = (self.v[CR1] >> 3) & 7
        rcc = self.chip.rcc
        return 8 * (2 << br) * rcc.hclk() // rcc.pclk2()

    def _device(self):
        low = [d for d, g, p in self.devices if g.level(p) == 0]
        if len(low) != 1:
            raise TwinError(
                f"SPI1 byte clocked with {len(low)} chip selects low in {self.chip.where()}"
            )
        return low[0]

    def _exchange(self, mosi):
        self.bytes += 1
        miso = self._device().exchange(mosi)
        return MISO_FLOAT if miso < 0 else miso & 0xFF

    def _check_mode(self):
        cr1 = self.v[CR1]
        if not cr1 & SPE:
            raise TwinError(f"SPI1 used while disabled (CR1.SPE) in {self.chip.where()}")
        if not cr1 & MSTR:
            self.chip.unsupported("SPI1 slave mode")
        mode = cr1 & 3
        if mode not in (0, 3) or cr1 & (1 << 7) or cr1 & (1 << 11):
            raise TwinError(f"SPI1 in a mode the BMI055 does not talk (CR1 = 0x{cr1:04X}: "
                            f"CPOL/CPHA {mode >> 1}/{mode & 1}, LSB first or 16-bit) in "
                            f"{self.chip.where()}")  # fmt: skip

    # -- polled transfers ----------------------------------------------------------------

    def _advance(self, now):
        q = self._queue
        while q and q[0][0] <= now:
            end, miso = q.pop(0)
            if self._flags & RXNE:
                self._set_ovr()
            else:
                self._rx = miso
                self._flags |= RXNE
            if self._waiting is not None:
                b, self._waiting = self._waiting, None
                self._queue.append((end + self.byte_cycles(), self._exchange(b)))
                self._busy_until = end + self.byte_cycles()

    def next_change(self, off):
        """When RXNE, TXE or BSY will change: the next byte's end, or the end of a block."""
        if off != SR:
            return None
        times = [self._queue[0][0]] if self._queue else []
        if self.clock.now() < self._busy_until:
            times.append(self._busy_until)
        return min(times) if times else None

    def _set_ovr(self):
        if not self._flags & OVR:
            self._flags |= OVR
            self._dr_read = False
            if self.v[CR2] & ERRIE:
                self.chip.scs.irq(IRQ)

    def irq_level(self):
        return bool(self.v[CR2] & ERRIE and self._flags & OVR)

    def read_SR(self):
        now = self.clock.now()
        self._advance(now)
        v = self._flags
        if self._flags & OVR and self._dr_read:
            self._flags &= ~OVR  # DR then SR read: OVR cleared (this read still shows it)
        if self._waiting is None:
            v |= TXE
        if now < self._busy_until:
            v |= BSY
        return v

    def read_DR(self):
        self._advance(self.clock.now())
        self._flags &= ~RXNE
        if self._flags & OVR:
            self._dr_read = True
        return self._rx

    def write_DR(self, value):
        self._check_mode()
        now = self.clock.now()
        self._advance(now)
        if now >= self._busy_until:
            end = now + self.byte_cycles()
            self._queue.append((end, self._exchange(value & 0xFF)))
            self._busy_until = end
        elif self._waiting is None:
            self._waiting = value & 0xFF
        else:
            raise TwinError(f"write to SPI1_DR while TXE is clear in {self.chip.where()}")

    def write_CR1(self, value):
        if value & ((1 << 15) | (1 << 13) | (1 << 10)):  # BIDIMODE, CRCEN, RXONLY
            self.chip.unsupported(f"SPI1 CR1 = 0x{value:04X} (bidirectional, CRC or RX-only)")
        self.v[CR1] = value & 0xFFFF

    def write_CR2(self, value):
        if value & 0xD0:  # FRF (TI mode), RXNEIE, TXEIE
            self.chip.unsupported(f"SPI1 CR2 = 0x{value:02X} (TI frames or RXNE/TXE interrupts)")
        self.v[CR2] = value & 0xF7
        if self.irq_level():
            self.chip.scs.irq(IRQ)
        self.chip.dma2.kick()

    def write_SR(self, value):
        if not value & (1 << 4):
            pass  # CRCERR: write 0 clears it; nothing else is writable

    def write_I2SCFGR(self, value):
        if value & (1 << 11):
            self.chip.unsupported("SPI1 in I2S mode")
        self.v[0x1C] = value & 0x0FBF

    # -- DMA ------------------------------------------------------------------------------

    def dma_block(self, tx, rx):
        """Both streams enabled and the requests on (dma.py calls this): the block of
        tx.ndtr bytes is exchanged; returns (tx end cycle, rx end cycle) or None if the SPI
        does not request yet."""
        cr2 = self.v[CR2]
        if not (cr2 & TXDMAEN and self.v[CR1] & SPE):
            return None
        if rx is not None and not cr2 & RXDMAEN:
            rx = None
        self._check_mode()
        now = self.clock.now()
        self._advance(now)
        if self._queue or self._waiting is not None:
            raise TwinError(f"SPI1 DMA started while a polled byte is shifting in "
                            f"{self.chip.where()}")  # fmt: skip
        n = tx.ndtr
        bc = self.byte_cycles()
        answers = bytearray(self._exchange(b) for b in tx.read_block(n))
        end = now + n * bc
        self._busy_until = end
        if rx is not None:
            if rx.ndtr != n:
                raise TwinError(f"SPI1 DMA with {n} bytes out and {rx.ndtr} in")
            rx.write_block(answers)
        else:
            # no RX DMA: each answer lands in DR as its byte ends (overrunning an unread one)
            self._queue = [(now + (i + 1) * bc, answers[i]) for i in range(n)]
            for i in range(n):
                self.chip.clock.at(now + (i + 1) * bc, self._byte_ends)
        return now + max(n - 1, 0) * bc, end

    def _byte_ends(self):
        self._advance(self.clock.now())
