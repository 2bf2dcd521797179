"""DMA1 and DMA2 (RM0383 section 9): 8 streams each, a channel (CHSEL) picks the request.

A stream is programmed as on the chip (PAR, M0AR, NDTR, CR with DIR, MINC, PSIZE/MSIZE,
the interrupt enables) and started by setting CR.EN. The transfers modelled are the ones the
image and the firmware make, found by the peripheral register PAR points at and the channel:
SPI1 (DMA2 channel 3: RX on streams 0 or 2, TX on 3 or 5) and USART1/USART6 transmission
(DMA2 channel 4 stream 7 / channel 5 streams 6 and 7); any other stream started stops the
run, naming it. The peripheral decides when each byte moves (spi.py, usart.py); the stream
then sets HTIF at half and TCIF at the end of its transfer (NDTR 0, EN cleared: normal mode),
with their interrupts if HTIE/TCIE (DMA2 streams 0-4: IRQ 56-60, 5-7: 68-70; DMA1 0-6: 11-17,
7: 47). Reads from memory happen when the stream starts, writes when it completes.

Strict: clearing a controller's clock (RCC_AHB1ENR) while one of its streams transfers stops
the run (on the chip the transfer freezes).
"""

from host_emulator.f411.bus import Peripheral, TwinError

_FLAG_SHIFT = (0, 6, 16, 22)  # in LISR/HISR, per stream % 4
TCIF, HTIF, TEIF, DMEIF, FEIF = 0x20, 0x10, 0x08, 0x04, 0x01
EN, DMEIE, TEIE, HTIE, TCIE = 1, 2, 4, 8, 16
_IRQS = {1: (11, 12, 13, 14, 15, 16, 17, 47), 2: (56, 57, 58, 59, 60, 68, 69, 70)}


def _regs():
    r = [("LISR", 0x00, 0, 0), ("HISR", 0x04, 0, 0), ("LIFCR", 0x08, 0, 0),
         ("HIFCR", 0x0C, 0, 0)]  # fmt: skip
    for s in range(8):
        b = 0x10 + 0x18 * s
        r += [(f"S{s}CR", b, 0, 0x0FEFFFFF), (f"S{s}NDTR", b + 4, 0, 0xFFFF),
              (f"S{s}PAR", b + 8, 0), (f"S{s}M0AR", b + 12, 0), (f"S{s}M1AR", b + 16, 0),
              (f"S{s}FCR", b + 20, 0x21, 0x87)]  # fmt: skip
    return tuple(r)


class Stream:
    def __init__(self, dma, n):
        self.dma = dma
        self.n = n
        self.base = 0x10 + 0x18 * n
        self.active = False
        self._events = []
        self.transfers = 0

    @property
    def cr(self):
        return self.dma.v[self.base]

    @property
    def ndtr(self):
        return self.dma.v[self.base + 4]

    @property
    def par(self):
        return self.dma.v[self.base + 8]

    @property
    def m0ar(self):
        return self.dma.v[self.base + 12]

    def channel(self):
        return (self.cr >> 25) & 7

    def direction(self):
        return (self.cr >> 6) & 3  # 0 periph->mem, 1 mem->periph, 2 mem->mem

    def _step(self):
        cr = self.cr
        msize = 1 << ((cr >> 13) & 3)
        return msize if cr & (1 << 10) else 0

    def read_block(self, n):
        """n items (bytes) from memory as the stream reads them (MINC, MSIZE 8-bit)."""
        if (self.cr >> 13) & 3:
            raise TwinError(f"DMA{self.dma.number} stream {self.n}: only byte transfers are "
                            "modelled")  # fmt: skip
        step = self._step()
        chip = self.dma.chip
        if step:
            return chip.read_memory(self.m0ar, n)
        return chip.read_memory(self.m0ar, 1) * n

    def write_block(self, data):
        self._pending_write = bytes(data)

    def start_transfer(self, end_cycle, half_cycle=None):
        """The peripheral moves the block; flags and interrupts at these cycles."""
        self.active = True
        self.transfers += 1
        clock = self.dma.clock
        if half_cycle is not None:
            self._events.append(clock.at(half_cycle, lambda: self._flag(HTIF, HTIE)))
        self._events.append(clock.at(end_cycle, self._complete))

    def _flag(self, flag, enable):
        self.dma.set_flag(self.n, flag)
        if self.cr & enable:
            self.dma.chip.scs.irq(_IRQS[self.dma.number][self.n])

    def _complete(self):
        self._events = []
        w = getattr(self, "_pending_write", None)
        if w is not None:
            self.dma.chip.write_memory(self.m0ar, w)
            self._pending_write = None
        self.dma.v[self.base + 4] = 0
        self.dma.v[self.base] &= ~EN
        self.active = False
        self._flag(TCIF, TCIE)

    def abort(self):
        for e in self._events:
            e.cancel()
        self._events = []
        self.active = False


class Dma(Peripheral):
    REGISTERS = _regs()

    def __init__(self, chip, number):
        self.number = number
        self.NAME = f"DMA{number}"
        self.BASE = 0x40026000 if number == 1 else 0x40026400
        self.CLOCK = ("AHB1ENR", 20 + number)
        self.streams = [Stream(self, s) for s in range(8)]
        super().__init__(chip)
        for s in range(8):
            chip.irq_sources[_IRQS[number][s]] = lambda s=s: self.irq_level_of(s)
        for s in range(8):
            setattr(self, f"write_S{s}CR", self._cr_writer(s))
        self._writers.update({0x10 + 0x18 * s: getattr(self, f"write_S{s}CR") for s in range(8)})

    def reset(self):
        super().reset()
        for st in getattr(self, "streams", ()):
            st.abort()

    def set_flag(self, n, flag):
        reg = 0x00 if n < 4 else 0x04
        self.v[reg] |= flag << _FLAG_SHIFT[n % 4]

    def irq_level_of(self, n):
        flags = (self.v[0x00 if n < 4 else 0x04] >> _FLAG_SHIFT[n % 4]) & 0x3D
        cr = self.streams[n].cr
        return bool((flags & TCIF and cr & TCIE) or (flags & HTIF and cr & HTIE) or
                    (flags & TEIF and cr & TEIE) or (flags & DMEIF and cr & DMEIE))  # fmt: skip

    def write_LIFCR(self, value):
        self.v[0x00] &= ~value

    def write_HIFCR(self, value):
        self.v[0x04] &= ~value

    def clock_changed(self, on):
        if not on:
            busy = [s.n for s in self.streams if s.active]
            if busy:
                raise TwinError(
                    f"DMA{self.number}'s clock turned off (RCC_AHB1ENR) while stream(s) "
                    f"{busy} transfer, in {self.chip.where()}: on the board they freeze"
                )

    def _cr_writer(self, s):
        def write(value, s=s):
            st = self.streams[s]
            base = st.base
            if st.active and not value & EN:
                st.abort()  # software disable: the stream stops after the current item
                self.v[base] = value & 0x0FEFFFFE
                self.set_flag(s, TCIF)
                return
            if st.active:
                # only the interrupt enables may change while EN is set (RM0383 9.5.5)
                if (value ^ self.v[base]) & ~0x1F & 0x0FEFFFFF:
                    raise TwinError(
                        f"DMA{self.number} stream {s} reconfigured while it transfers in "
                        f"{self.chip.where()}: the chip ignores it"
                    )
                self.v[base] = (self.v[base] & ~0x1E) | (value & 0x1E)
                return
            self.v[base] = value & 0x0FEFFFFF
            if value & EN:
                self._started(st)

        return write

    def _started(self, st):
        if st.cr & ((1 << 8) | (1 << 18)):  # CIRC, DBM
            self.chip.unsupported(f"DMA{self.number} stream {st.n} circular/double-buffer mode")
        if st.direction() == 2:
            self.chip.unsupported(f"DMA{self.number} memory-to-memory transfer")
        self.kick()

    def kick(self):
        """Start what the enabled streams and their peripherals' requests allow."""
        chip = self.chip
        v = self.v
        waiting = [s for s in self.streams if v[s.base] & EN and not s.active]
        for st in waiting:
            target = chip.dma_target(self.number, st.channel(), st.par, st.direction())
            if target is None:
                raise TwinError(
                    f"DMA{self.number} stream {st.n} started (channel {st.channel()}, PAR "
                    f"0x{st.par:08X}, direction {st.direction()}) for a transfer the twin does "
                    f"not model, in {chip.where()}"
                )
            kind, periph = target
            if kind == "spi_rx":
                continue  # moves with its TX stream
            if kind == "spi_tx":
                rx = next((r for r in self.streams if r.cr & EN and not r.active and
                           chip.dma_target(self.number, r.channel(), r.par, r.direction()) ==
                           ("spi_rx", periph)), None)  # fmt: skip
                times = periph.dma_block(st, rx)
                if times is None:
                    continue
                tx_end, rx_end = times
                n = st.ndtr
                bc = periph.byte_cycles()
                now = self.clock.now()
                st.start_transfer(tx_end, now + max(n // 2 - 1, 0) * bc if n > 1 else None)
                if rx is not None:
                    rx.start_transfer(rx_end, now + (n // 2) * bc if n > 1 else None)
            elif kind == "usart_tx":
                data = st.read_block(st.ndtr)
                end = periph.dma_tx(st, data)
                if end is None:
                    continue
                half = periph.char_cycles() * (len(data) // 2)
                st.start_transfer(end, self.clock.now() + half if len(data) > 1 else None)
