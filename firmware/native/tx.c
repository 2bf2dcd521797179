/* The DMA transmitter of drivers/uart_dma.py: a write copies its bytes into the queue buffer
 * and starts the stream on what is queued when it is idle, in one call (the same register
 * writes in Python, stm.mem32 stores of addresses above 2**30, cost ~13,000 instructions a
 * tick on the board: docs/image.md). The addresses come from the caller's state buffer
 * (TX_*), so nothing here knows the board; only the stm32 port's build pokes registers. */
#include <stdint.h>

#include "layout.h"
#include "navk.h"

#define REG(a) (*(volatile uint32_t *)(uintptr_t)(uint32_t)(a))

/* The queued bytes go out when the stream is idle: the flags cleared, the addresses and the
 * count set, the stream enabled (RM0383 9.3.18: configure with EN clear, then set EN), and
 * the other buffer takes the next writes. The DMA clock is switched on first: the port may
 * switch it off when SPI is idle (ports/stm32/dma.c, dma_idle_handler). */
static void tx_start(int32_t *tx, uint8_t *bufs) {
    int32_t n = tx[TX_N];
    if (n == 0) {
        return;
    }
#if defined(__arm__)
    uint32_t cr = (uint32_t)tx[TX_CR];
    if (REG(cr) & 1u) {
        return;
    }
    REG(tx[TX_RCC]) = REG(tx[TX_RCC]) | (uint32_t)tx[TX_RCC_EN];
    REG(tx[TX_IFCR]) = (uint32_t)tx[TX_FLAGS];
    REG(cr + 8) = (uint32_t)tx[TX_DR];
    REG(cr + 12) = (uint32_t)(uintptr_t)(bufs + tx[TX_FILL] * tx[TX_SIZE]);
    REG(cr + 4) = (uint32_t)n;
    REG(cr + 20) = 0;
    REG(cr) = (uint32_t)tx[TX_CR_VALUE];
    REG(cr) = (uint32_t)tx[TX_CR_VALUE] | 1u;
#else
    (void)bufs;
    return; /* no stream to start off the board: the bytes stay queued */
#endif
    tx[TX_FILL] ^= 1;
    tx[TX_N] = 0;
    tx[TX_SENT] = (tx[TX_SENT] + n) & 0x3FFFFFFF;
}

/* DmaTx.write_n: src's first n bytes queued after what is queued (bufs holds the two buffers
 * of TX_SIZE bytes back to back), the stream started if idle; n, or 0 when they do not fit
 * (dropped whole, counted in TX_DROPPED). */
int32_t navk_tx_write(int32_t *tx, uint8_t *bufs, const uint8_t *src, int32_t n) {
    int32_t k = tx[TX_N];
    if (n < 0 || k + n > tx[TX_SIZE]) {
        tx[TX_DROPPED] = (tx[TX_DROPPED] + n) & 0x3FFFFFFF;
        return 0;
    }
    uint8_t *d = bufs + tx[TX_FILL] * tx[TX_SIZE] + k;
    for (int32_t i = 0; i < n; i++) {
        d[i] = src[i];
    }
    tx[TX_N] = k + n;
    tx_start(tx, bufs);
    return n;
}

/* DmaTx.poll: start the stream on the queued bytes if it is idle; the bytes still queued. */
int32_t navk_tx_poll(int32_t *tx, uint8_t *bufs) {
    tx_start(tx, bufs);
    return tx[TX_N];
}
