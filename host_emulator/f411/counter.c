/* The twin's instruction counter: a Unicorn code hook in C (one Python call per instruction
 * would be a hundred times slower). Built with cffi by counter.py; the fields are described
 * there. */
#include <stdint.h>

#define N_CATEGORIES 8
#define FRAME_WORDS 26 /* R0-R3, R12, LR, return address, xPSR, S0-S15, FPSCR, reserved */
#define N_SAVED 24     /* R0-R3, R12, LR, xPSR, S0-S15 and FPSCR as read from the core */

typedef int (*reg_batch_fn)(void *uc, const int *regs, void **vals, int count);
typedef int (*mem_fn)(void *uc, uint64_t address, void *bytes, uint64_t size);

typedef struct {
    uint64_t icount;          /* instructions executed */
    uint64_t stop_at;         /* stop before the instruction that would exceed this count */
    uint64_t handler_icount;  /* of which in handler mode (an exception active) */
    uint32_t in_handler;
    uint32_t irq_pending;     /* an interrupt waits for PRIMASK/BASEPRI to drop */
    uint32_t stopped;
    uint32_t flash_base, flash_len;
    int (*stop)(void *);
    const uint8_t *sync;      /* per flash halfword, a bit: check interrupts after it */
    const uint8_t *category;  /* per flash halfword, its category */
    uint64_t category_count[N_CATEGORIES];
    /* exception entry and return (cpu.py): Unicorn's API, and the register ids */
    reg_batch_fn reg_read, reg_write;
    mem_fn mem_read, mem_write;
    int saved_ids[N_SAVED];  /* R0-R3, R12, LR, XPSR, S0-S15, FPSCR */
    int sp_id, lr_id, ipsr_id, xpsr_id;
} twin_counter;

void twin_code_hook(void *uc, uint64_t addr, uint32_t size, void *user) {
    twin_counter *s = (twin_counter *)user;
    (void)size;
    if (s->icount >= s->stop_at) {
        /* every time: a stop requested while Unicorn was inside a memory callback can be
           lost, and the next instruction must not run */
        s->stopped = 1;
        s->stop(uc);
        return;
    }
    s->icount++;
    if (s->in_handler) {
        s->handler_icount++;
    }
    uint32_t off = (uint32_t)addr - s->flash_base;
    if (off < s->flash_len) {
        uint32_t h = off >> 1;
        s->category_count[s->category[h]]++;
        if (s->irq_pending && ((s->sync[h >> 3] >> (h & 7)) & 1)) {
            s->stop_at = s->icount;  /* stop after this instruction: an interrupt may be due */
        }
    } else {
        s->category_count[N_CATEGORIES - 1]++;  /* code outside flash: native modules in RAM */
    }
}


/* Exception entry (ARMv7-M B1.5.6, the extended frame): stacks the frame below SP (8-byte
 * aligned, xPSR bit 9 when realigned), sets SP, LR = exc_return and IPSR = number. Returns 0,
 * or Unicorn's error. */
int twin_enter(twin_counter *s, void *uc, uint32_t return_pc, uint32_t number,
               uint32_t exc_return) {
    uint32_t v[N_SAVED], frame[FRAME_WORDS], sp;
    void *pv[N_SAVED];
    int i, err;
    for (i = 0; i < N_SAVED; i++) {
        pv[i] = &v[i];
    }
    void *psp = &sp;
    if ((err = s->reg_read(uc, &s->sp_id, &psp, 1)) || (err = s->reg_read(uc, s->saved_ids, pv, N_SAVED))) {
        return err;
    }
    uint32_t realign = sp & 4;
    sp = (sp - 4 * FRAME_WORDS) & ~7u;
    for (i = 0; i < 6; i++) {
        frame[i] = v[i];
    }
    frame[6] = return_pc;
    frame[7] = (v[6] & ~(1u << 9)) | (1u << 24) | (realign ? (1u << 9) : 0);
    for (i = 0; i < 17; i++) {
        frame[8 + i] = v[7 + i];
    }
    frame[25] = 0;
    if ((err = s->mem_write(uc, sp, frame, sizeof frame))) {
        return err;
    }
    int ids[3] = {s->sp_id, s->lr_id, s->ipsr_id};
    uint32_t w[3] = {sp, exc_return, number};
    void *pw[3] = {&w[0], &w[1], &w[2]};
    return s->reg_write(uc, ids, pw, 3);
}

/* Exception return: unstacks the frame at SP; *return_pc gets the address to resume at,
 * IPSR becomes `ipsr` (the exception still active beneath, or 0). */
int twin_return(twin_counter *s, void *uc, uint32_t ipsr, uint32_t *return_pc) {
    uint32_t frame[FRAME_WORDS], sp, v[N_SAVED];
    void *pv[N_SAVED];
    int i, err;
    void *psp = &sp;
    if ((err = s->reg_read(uc, &s->sp_id, &psp, 1)) || (err = s->mem_read(uc, sp, frame, sizeof frame))) {
        return err;
    }
    for (i = 0; i < 6; i++) {
        v[i] = frame[i];
    }
    v[6] = frame[7] & ~(1u << 9);
    for (i = 0; i < 17; i++) {
        v[7 + i] = frame[8 + i];
    }
    for (i = 0; i < N_SAVED; i++) {
        pv[i] = &v[i];
    }
    if ((err = s->reg_write(uc, s->saved_ids, pv, N_SAVED))) {
        return err;
    }
    sp += 4 * FRAME_WORDS + ((frame[7] & (1u << 9)) ? 4 : 0);
    int ids[2] = {s->sp_id, s->ipsr_id};
    uint32_t w[2] = {sp, ipsr};
    void *pw[2] = {&w[0], &w[1]};
    *return_pc = frame[6];
    return s->reg_write(uc, ids, pw, 2);
}
