/* The twin's peripheral accesses (bus.py): Unicorn calls these for every load and store in a
 * peripheral's window. A register without behaviour (no read_/write_ method in its model) is
 * read and written here, in the model's own register array; any other goes to the model's
 * Python method. Most of the image's accesses are of plain registers (a DMA stream's CR,
 * NDTR, PAR, M0AR; SPI's CR2; RCC's enables), and a call into Python costs microseconds. */
#include <stdint.h>

#define TWIN_PLAIN_READ 1
#define TWIN_PLAIN_WRITE 2

typedef uint64_t (*twin_mmio_read_fn)(void *uc, uint64_t off, unsigned size, void *user);
typedef void (*twin_mmio_write_fn)(void *uc, uint64_t off, unsigned size, uint64_t value,
                                   void *user);
typedef int (*twin_mmio_map_fn)(void *uc, uint64_t address, size_t size, twin_mmio_read_fn rd,
                                void *user_rd, twin_mmio_write_fn wr, void *user_wr);

typedef struct {
    uint32_t *v;               /* the model's registers, indexed by byte offset (words used) */
    const uint8_t *plain;      /* per word (offset / 4): TWIN_PLAIN_READ | TWIN_PLAIN_WRITE */
    const uint32_t *writable;  /* per word: the bits a plain write changes */
    uint32_t words;
    const uint32_t *gate;      /* RCC's enable register gating the clock, or NULL */
    uint32_t gate_bit;
    uint32_t *served;          /* set on every access served here (the bus's polling watch) */
    twin_mmio_read_fn py_read;     /* the model, for every other access */
    twin_mmio_write_fn py_write;
} twin_periph;

static int twin_gated_off(const twin_periph *p) {
    return p->gate && !((*p->gate >> p->gate_bit) & 1);
}

uint64_t twin_mmio_read(void *uc, uint64_t off, unsigned size, void *user) {
    twin_periph *p = (twin_periph *)user;
    uint32_t w = (uint32_t)off >> 2;
    if (w < p->words && (p->plain[w] & TWIN_PLAIN_READ) && !twin_gated_off(p)) {
        *p->served = 1;
        uint32_t v = p->v[w << 2];
        if (size >= 4) {
            return v;
        }
        return (v >> ((off & 3) * 8)) & ((1u << (size * 8)) - 1);
    }
    return p->py_read(uc, off, size, user);
}

void twin_mmio_write(void *uc, uint64_t off, unsigned size, uint64_t value, void *user) {
    twin_periph *p = (twin_periph *)user;
    uint32_t w = (uint32_t)off >> 2;
    if (w < p->words && (p->plain[w] & TWIN_PLAIN_WRITE) && !twin_gated_off(p)) {
        *p->served = 1;
        uint32_t old = p->v[w << 2], val = (uint32_t)value;
        if (size < 4) {
            uint32_t sh = (off & 3) * 8, m = ((1u << (size * 8)) - 1) << sh;
            val = (old & ~m) | ((val << sh) & m);
        }
        p->v[w << 2] = (old & ~p->writable[w]) | (val & p->writable[w]);
        return;
    }
    p->py_write(uc, off, size, value, user);
}

/* uc_mmio_map with the two functions above, for one model */
int twin_mmio_map(void *map_fn, void *uc, uint64_t base, uint64_t size, twin_periph *p) {
    return ((twin_mmio_map_fn)map_fn)(uc, base, (size_t)size, twin_mmio_read, p,
                                      twin_mmio_write, p);
}
