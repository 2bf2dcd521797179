"""Transmission on a UART by DMA, so that a tick never waits for the line (STM32F411 only).

The stm32 port's `UART.write` puts each byte into the data register itself and spins until the
last one has left (ports/stm32/uart.c, uart_tx_data): at 460800 baud the 52-byte frame holds the
CPU 1.13 ms every tick, the extended frame 2.95 ms (measured on the emulated STM32F411:
docs/image.md). Here the DMA moves the bytes while the loop goes on: `write(buf)` (or
`write_n(buf, n)`, its first n bytes) copies them into one of two buffers and, when the stream
is idle, starts it on what is queued; what comes while it sends waits in the other buffer,
started by the next `write` or `poll` (board.idle polls before every sleep, and the core wakes
at least every millisecond). A write that does not fit the buffer is dropped whole (never half
a frame) and counted (`dropped`).

Registers (RM0383): the UART's CR3.DMAT lets TXE request the DMA; DMA2 stream 7 channel 4
serves USART1_TX, stream 6 channel 5 USART6_TX (table 28). The stream reads memory byte by
byte (MINC, MSIZE = PSIZE = 8 bit, direct mode) into the UART's DR; EN drops when it is done.
The port keeps DMA2's clock for SPI1 and may switch it off after 64 ms without SPI
transfers (ports/stm32/dma.c, dma_idle_handler): the clock is switched on again before every
start. The copy and the start are one native kernel (`tx_write`, `tx_poll`: firmware/native/
tx.c) over the state buffer `_tx` (TX_*, the addresses as int32: the stm.mem32 stores of
addresses above 2**30 cost the board ~13,000 instructions a tick in Python). Nothing here
allocates per call.
"""

from array import array

from micropython import const

import kern

try:
    import stm
except ImportError:  # not the stm32 port: no DMA transmitter (board.py uses the UART itself)
    stm = None

_RCC_AHB1ENR = 0x40023830
_DMA2EN = const(1 << 22)
_DMA2 = 0x40026400
_HIFCR = _DMA2 + 0x0C
# per UART: (DR, CR3, stream's CR address, channel select bits, its flags in HISR/HIFCR)
_ROUTES = {
    1: (0x40011004, 0x40011014, _DMA2 + 0x10 + 0x18 * 7, const(4 << 25), const(0x0F400000)),
    6: (0x40011404, 0x40011414, _DMA2 + 0x10 + 0x18 * 6, const(5 << 25), const(0x003D0000)),
}
_DMAT = const(1 << 7)
_CR = const(0x400 | 0x40 | 0x10000)  # MINC, memory to peripheral, medium priority
BUF_BYTES = 512  # each of the two buffers: a tick's frame, extended frame and raw record
# The transmitter's state (DmaTx._tx, int32; tx.c): the stream's CR, the UART's DR, HIFCR
# and RCC_AHB1ENR addresses, the CR value without EN, the stream's flags in HIFCR, DMA2EN;
# the buffer being filled (0, 1), the bytes queued in it, its size, bytes handed to the DMA
# and bytes dropped (both wrap at 2**30)
TX_CR = const(0)
TX_DR = const(1)
TX_IFCR = const(2)
TX_RCC = const(3)
TX_CR_VALUE = const(4)
TX_FLAGS = const(5)
TX_RCC_EN = const(6)
TX_FILL = const(7)
TX_N = const(8)
TX_SIZE = const(9)
TX_SENT = const(10)
TX_DROPPED = const(11)
NTX = const(12)

_tx_write = kern.pick("tx_write", None)
_tx_poll = kern.pick("tx_poll", None)


def supported(uart_id):
    """Whether this port and UART have the DMA transmitter (the stm32 port, with navk)."""
    return stm is not None and _tx_write is not None and uart_id in _ROUTES


class DmaTx:
    def __init__(self, uart_id, size=BUF_BYTES):
        dr, cr3, cr, chsel, flags = _ROUTES[uart_id]
        t = array("i", bytes(4 * NTX))
        t[TX_CR] = cr
        t[TX_DR] = dr
        t[TX_IFCR] = _HIFCR
        t[TX_RCC] = _RCC_AHB1ENR
        t[TX_CR_VALUE] = chsel | _CR
        t[TX_FLAGS] = flags
        t[TX_RCC_EN] = _DMA2EN
        t[TX_SIZE] = size
        self._tx = t
        self._bufs = bytearray(2 * size)  # the two buffers, back to back
        m = stm.mem32
        m[_RCC_AHB1ENR] = m[_RCC_AHB1ENR] | _DMA2EN
        m[cr] = 0  # the stream stopped
        m[cr3] = m[cr3] | _DMAT

    def write(self, buf):
        """Queue buf, sent in order after what is queued; the bytes queued, or 0 if it did
        not fit (dropped)."""
        return _tx_write(self._tx, self._bufs, buf, len(buf))

    def write_n(self, buf, n):
        """Queue buf's first n bytes (write)."""
        return _tx_write(self._tx, self._bufs, buf, n)

    def poll(self):
        """Start the stream on the queued bytes if it is idle."""
        _tx_poll(self._tx, self._bufs)

    @property
    def dropped(self):
        return self._tx[TX_DROPPED]
