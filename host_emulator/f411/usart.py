"""USART1, USART2, USART6 (RM0383 section 19), timed by their baud rate.

A character takes (start + data + parity + stop bits) x BRR cycles of the bus clock (16x
oversampling: baud = PCLK / BRR; 8x: PCLK x 2 / BRR'), converted to HCLK cycles.

Transmit: a write to DR moves the byte into the shift register at once if it is idle, else it
waits in DR (TXE clear) until the shift register empties; a write while DR is still full
stops the run (on the board the waiting byte is lost). TC is set when the shift register and
DR are empty, cleared by writing 0 to it or by a new byte. Every character is given to the
line's listeners (`on_tx`: the RS485 capture, the console) with the cycle it starts at. With
CR3.DMAT, a DMA stream feeds DR as TXE asks (dma.py hands the whole block over: `dma_tx`).

Receive: `receive(byte, cycle)` schedules a character that completes at `cycle`: DR takes it
and RXNE is set, or, if RXNE is still set, the character is lost and ORE set (the port's
interrupt handler reads DR for every RXNE; at 9600 baud it has a millisecond). RXNE or ORE with
RXNEIE, and IDLE (the line quiet for one character after a reception) with IDLEIE, hold the
interrupt line. ORE, IDLE, NF, FE, PE clear by a read of SR followed by a read of DR.

Not modelled (a register write asking for them stops the run): 9-bit characters with parity
off, TXE and TC interrupts, LIN, smartcard, IrDA, half-duplex, hardware flow control, DMA
reception.
"""

from host_emulator.f411.bus import Peripheral, TwinError

SR, DR, BRR, CR1, CR2, CR3 = 0x00, 0x04, 0x08, 0x0C, 0x10, 0x14
PE, FE, NF, ORE, IDLE, RXNE, TC, TXE = 1, 2, 4, 8, 16, 32, 64, 128
UE, M, PCE, TXEIE, TCIE, RXNEIE, IDLEIE, TE, RE = (
    1 << 13,
    1 << 12,
    1 << 10,
    1 << 7,
    1 << 6,
    1 << 5,
    1 << 4,
    1 << 3,
    1 << 2,
)
OVER8 = 1 << 15
DMAT, DMAR = 1 << 7, 1 << 6
_UNITS = {1: ("APB2ENR", 4, 0x40011000, 37), 2: ("APB1ENR", 17, 0x40004400, 38),
          6: ("APB2ENR", 5, 0x40011400, 71)}  # fmt: skip


class Usart(Peripheral):
    REGISTERS = (
        ("SR", 0x00, 0x00C0, 0),
        ("DR", 0x04, 0, 0),
        ("BRR", 0x08, 0, 0xFFFF),
        ("CR1", 0x0C, 0, 0xBFFF),
        ("CR2", 0x10, 0, 0x7F7F),
        ("CR3", 0x14, 0, 0x0FFF),
        ("GTPR", 0x18, 0, 0xFFFF),
    )

    def __init__(self, chip, number):
        reg, bit, base, irq = _UNITS[number]
        self.number = number
        self.NAME = f"USART{number}"
        self.BASE = base
        self.CLOCK = (reg, bit)
        self.irq = irq
        self.on_tx = []  # fn(byte, start_cycle)
        self.tx_bytes = 0
        self.rx_bytes = 0
        self.rx_lost = 0  # characters lost to overrun (ORE)
        super().__init__(chip)
        chip.irq_sources[irq] = self.irq_level

    def reset(self):
        super().reset()
        self._shift_end = 0  # the cycle the character in the shift register ends
        self._dr_byte = None  # a character waiting in DR
        self._tc_cleared = False
        self._rx = 0  # DR's received character
        self._flags = 0  # RXNE, ORE, IDLE latched
        self._sr_seen = 0  # flags the last SR read saw (cleared by the DR read after it)
        self._last_rx_end = None
        self._idle_event = None
        self._cc_key = self._cc = None

    # -- timing -------------------------------------------------------------------------

    def char_cycles(self):
        """HCLK cycles of one character (start, data, parity, stop bits), kept while the
        registers and clocks it comes from stay: every character asks."""
        v = self.v
        key = (v[CR1] & (M | OVER8), v[CR2] & 0x3000, v[BRR], self.chip.rcc.clock_tree())
        if key != self._cc_key:
            self._cc = self._char_cycles()
            self._cc_key = key
        return self._cc

    def _char_cycles(self):
        cr1, cr2 = self.v[CR1], self.v[CR2]
        brr = self.v[BRR]
        if brr == 0:
            raise TwinError(f"{self.NAME} used with BRR = 0 in {self.chip.where()}")
        stop = {0: 2, 1: 1, 2: 4, 3: 3}[(cr2 >> 12) & 3]  # in half bits
        half_bits = 2 * (1 + (9 if cr1 & M else 8)) + stop
        rcc = self.chip.rcc
        pclk = rcc.pclk2() if self.number in (1, 6) else rcc.pclk1()
        hclk = rcc.hclk()
        per_bit = brr if not cr1 & OVER8 else 8 * (brr >> 4) + (brr & 7)
        per_bit_hclk = per_bit * hclk / pclk / (1 if not cr1 & OVER8 else 2)
        return round(half_bits * per_bit_hclk / 2)

    def baud(self):
        return self.chip.clock.hz * 10 / self.char_cycles()

    def _advance(self, now):
        if self._dr_byte is not None and now >= self._shift_end:
            b, self._dr_byte = self._dr_byte, None
            self._start(b, self._shift_end)

    def _start(self, b, at):
        self._shift_end = at + self.char_cycles()
        self.tx_bytes += 1
        for fn in self.on_tx:
            fn(b, at)

    def next_change(self, off):
        """When TXE or TC will be set (a transmission in progress): what a polling sender
        waits for. Reception flags change at arrivals (events), IDLE nobody polls."""
        if off == SR:
            now = self.clock.now()
            if self._dr_byte is not None or now < self._shift_end:
                return self._shift_end
        return None

    # -- registers ----------------------------------------------------------------------

    def _sr(self):
        now = self.clock.now()
        self._advance(now)
        v = self._flags
        if self._last_rx_end is not None and now >= self._last_rx_end + self.char_cycles():
            v |= IDLE
        if self._dr_byte is None:
            v |= TXE
            if now >= self._shift_end and not self._tc_cleared:
                v |= TC
        return v

    def read_SR(self):
        v = self._sr()
        self._sr_seen = v & (ORE | IDLE | NF | FE | PE)
        return v

    def write_SR(self, value):
        if not value & TC:
            self._tc_cleared = True
        if not value & RXNE:
            self._flags &= ~RXNE
        self._update_irq()

    def read_DR(self):
        v = self._rx
        self._flags &= ~(RXNE | self._sr_seen)
        if self._sr_seen & IDLE:
            self._last_rx_end = None
        self._sr_seen = 0
        self._update_irq()
        return v

    def write_DR(self, value):
        cr1 = self.v[CR1]
        if not (cr1 & UE and cr1 & TE):
            raise TwinError(f"write to {self.NAME}_DR with the transmitter off (CR1 UE/TE) in "
                            f"{self.chip.where()}")  # fmt: skip
        now = self.clock.now()
        self._advance(now)
        self._tc_cleared = False
        b = value & 0xFF
        if now >= self._shift_end:
            self._start(b, now)
        elif self._dr_byte is None:
            self._dr_byte = b
        else:
            raise TwinError(
                f"write to {self.NAME}_DR while TXE is clear in {self.chip.where()}: the "
                "character waiting there is lost"
            )

    def write_CR1(self, value):
        if value & (TXEIE | TCIE):
            self.chip.unsupported(f"{self.NAME} TXE/TC interrupts (CR1 = 0x{value:04X})")
        if value & M and not value & PCE:
            self.chip.unsupported(f"{self.NAME} 9-bit characters")
        self.v[CR1] = value & 0xBFFF
        self._update_irq()

    def write_CR2(self, value):
        if value & ((1 << 14) | (1 << 11)):  # LINEN, CLKEN
            self.chip.unsupported(f"{self.NAME} LIN or synchronous mode (CR2 = 0x{value:04X})")
        self.v[CR2] = value & 0x7F7F

    def write_CR3(self, value):
        if value & 0x33E:  # IREN..SCEN, RTSE, CTSE, ONEBIT aside: what the model lacks
            self.chip.unsupported(f"{self.NAME} CR3 = 0x{value:04X} (flow control, IrDA, "
                                  "smartcard or half-duplex)")  # fmt: skip
        if value & DMAR:
            self.chip.unsupported(f"{self.NAME} DMA reception")
        self.v[CR3] = value & 0x0FFF
        if value & DMAT:
            self.chip.dma2.kick()

    # -- the line -----------------------------------------------------------------------

    def receive(self, byte, cycle):
        """A character that completes at `cycle` (scheduled; the twin's world calls this)."""
        self.chip.clock.at(cycle, lambda: self._arrive(byte))

    def _arrive(self, byte):
        cr1 = self.v[CR1]
        if not (cr1 & UE and cr1 & RE):
            self.rx_lost += 1
            return
        self.rx_bytes += 1
        if self._flags & RXNE:
            self._flags |= ORE
            self.rx_lost += 1
        else:
            self._rx = byte
            self._flags |= RXNE
        self._flags &= ~IDLE
        self._last_rx_end = self.clock.now()
        if self.v[CR1] & IDLEIE:
            if self._idle_event is not None:
                self._idle_event.cancel()
            self._idle_event = self.clock.after(self.char_cycles(), self._update_irq)
        self._update_irq()

    def irq_level(self):
        cr1 = self.v[CR1]
        f = self._sr()
        return bool((cr1 & RXNEIE and f & (RXNE | ORE)) or (cr1 & IDLEIE and f & IDLE))

    def _update_irq(self):
        if self.irq_level():
            self.chip.scs.irq(self.irq)

    # -- DMA transmission ---------------------------------------------------------------

    def dma_tx(self, stream, data):
        """A DMA stream feeds `data` into DR as TXE asks; returns the cycle at which the stream
        has moved its last byte (its transfer complete)."""
        if not self.v[CR3] & DMAT:
            return None
        now = self.clock.now()
        self._advance(now)
        t = max(now, self._shift_end)
        if self._dr_byte is not None:
            raise TwinError(f"{self.NAME} DMA started with a character waiting in DR")
        ch = self.char_cycles()
        n = len(data)
        for fn in self.on_tx:  # byte i starts at t + i x ch, back to back
            for i, b in enumerate(data):
                fn(b, t + i * ch)
        self.tx_bytes += n
        # DR takes byte i when byte i-1 starts: the last load is when byte n-2 starts
        last_load = t if n <= 1 else t + (n - 2) * ch
        self._shift_end = t + n * ch
        self._tc_cleared = False
        return last_load
