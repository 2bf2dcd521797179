"""Transmission on a UART by DMA, so that a tick never waits for the line (STM32F411 only).

The stm32 port's `UART.write` puts each byte into the data register itself and spins until the
last one has left (ports/stm32/uart.c, uart_tx_data): at 460800 baud the 52-byte frame holds the
CPU 1.13 ms every tick, the extended frame 2.95 ms (measured on the emulated STM32F411:
docs/image.md). Here the DMA moves the bytes while the loop goes on: `write(buf)` (or
`write_n(buf, n)`, its first n bytes) copies them into one of two buffers and, when the stream
is idle, starts it on what is queued; what comes
while it sends waits in the other buffer, started by the next `write` or `poll` (board.idle
polls before every sleep, and the core wakes at least every millisecond). A write that does not
fit the buffer is dropped whole (never half a frame) and counted in `dropped`.

Registers (RM0383): the UART's CR3.DMAT lets TXE request the DMA; DMA2 stream 7 channel 4
serves USART1_TX, stream 6 channel 5 USART6_TX (table 28). The stream reads memory byte by
byte (MINC, MSIZE = PSIZE = 8 bit, direct mode) into the UART's DR; EN drops when it is done.
The port keeps DMA2's clock for SPI1 and may switch it off after 64 ms without SPI
transfers (ports/stm32/dma.c, dma_idle_handler): the clock is switched on again before every
start. Nothing here allocates: the addresses above 2**30 are module-level ints made once,
everything else is a small int (stm.mem32 reads and writes, uctypes.addressof).
"""

import stm
import uctypes
from micropython import const

import frame

_RCC_AHB1ENR = 0x40023830
_DMA2EN = const(1 << 22)
_DMA2 = 0x40026400
_HISR = _DMA2 + 0x04
_HIFCR = _DMA2 + 0x0C
# per UART: (DR, CR3, stream's CR address, channel select bits, its flags in HISR/HIFCR)
_ROUTES = {
    1: (0x40011004, 0x40011014, _DMA2 + 0x10 + 0x18 * 7, const(4 << 25), const(0x0F400000)),
    6: (0x40011404, 0x40011414, _DMA2 + 0x10 + 0x18 * 6, const(5 << 25), const(0x003D0000)),
}
_DMAT = const(1 << 7)
_EN = const(1)
_CR = const(0x400 | 0x40 | 0x10000)  # MINC, memory to peripheral, medium priority
BUF_BYTES = 512  # each of the two buffers: a tick's frame, extended frame and raw record


def supported(uart_id):
    return uart_id in _ROUTES


class DmaTx:
    def __init__(self, uart_id, size=BUF_BYTES):
        dr, cr3, cr, chsel, flags = _ROUTES[uart_id]
        self._dr = dr
        self._cr = cr
        self._ndtr = cr + 4
        self._par = cr + 8
        self._m0ar = cr + 12
        self._fcr = cr + 20
        self._chsel = chsel
        self._flags = flags
        self._bufs = (bytearray(size), bytearray(size))
        self._addr = (uctypes.addressof(self._bufs[0]), uctypes.addressof(self._bufs[1]))
        self._fill = 0  # the buffer writes go to
        self._n = 0  # bytes queued in it
        self._size = size
        self.dropped = 0  # bytes of writes that did not fit
        self.sent = 0  # bytes handed to the DMA
        m = stm.mem32
        m[_RCC_AHB1ENR] = m[_RCC_AHB1ENR] | _DMA2EN
        m[self._cr] = 0  # the stream stopped
        m[cr3] = m[cr3] | _DMAT

    def write(self, buf):
        """Queue buf, sent in order after what is queued; the bytes queued, or 0 if it did
        not fit (dropped)."""
        return self.write_n(buf, len(buf))

    def write_n(self, buf, n):
        """Queue buf's first n bytes (write)."""
        k = self._n
        if k + n > self._size:
            self.dropped += n
            return 0
        if n == len(buf):
            self._bufs[self._fill][k : k + n] = buf  # a stack slice: no heap object
        else:
            frame.bytes_copy(self._bufs[self._fill], k, buf, n)
        self._n = k + n
        self.poll()
        return n

    def busy(self):
        return stm.mem32[self._cr] & _EN

    def poll(self):
        """Start the stream on the queued bytes if it is idle."""
        n = self._n
        if not n:
            return
        m = stm.mem32
        if m[self._cr] & _EN:
            return
        f = self._fill
        m[_RCC_AHB1ENR] = m[_RCC_AHB1ENR] | _DMA2EN
        m[_HIFCR] = self._flags
        m[self._par] = self._dr
        m[self._m0ar] = self._addr[f]
        m[self._ndtr] = n
        m[self._fcr] = 0
        m[self._cr] = self._chsel | _CR
        m[self._cr] = self._chsel | _CR | _EN
        self._fill = 1 - f
        self._n = 0
        self.sent += n
