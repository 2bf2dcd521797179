/* The twin's instruction counter: a Unicorn code hook in C (one Python call per instruction
 * would be a hundred times slower). Built with cffi by counter.py; the fields are described
 * there. */
#include <stdint.h>

#define N_CATEGORIES 8
#define FRAME_WORDS 26 /* R0-R3, R12, LR, return address, xPSR, S0-S15, FPSCR, reserved */
#define N_SAVED 24     /* R0-R3, R12, LR, xPSR, S0-S15 and FPSCR as read from the core */

typedef int (*reg_batch_fn)(void *uc, const int *regs, void **vals, int count);
typedef int (*reg_fn)(void *uc, int regid, void *value);
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
    int pc_id, primask_id, basepri_id;
    reg_fn reg_read1, reg_write1;  /* uc_reg_read, uc_reg_write: one register */
    /* WFI: the twin sleeps inside the hook (cpu.py), without Unicorn returning */
    const uint16_t *flash_code;  /* flash's contents, by halfword */
    void (*on_wfi)(void *uc, uint32_t addr);
    /* the next event is due before the instruction at addr (flash, outside an IT block):
       1 when it must not run now (the core went elsewhere, or emulation stops) */
    int (*on_due)(void *uc, uint32_t addr);
    /* per flash halfword, a bit: call on_watch before the instruction there runs (chip.hook:
       one code hook for every instruction, where Unicorn would walk a list of them) */
    const uint8_t *watch;
    void (*on_watch)(void *uc, uint32_t addr);
} twin_counter;

/* Whether the instruction at halfword h may be inside an IT block: an IT instruction
 * (0xBFxy, mask y nonzero) among the 8 halfwords before it whose 1-4 instructions, decoded
 * forward, reach h. Unicorn does not stop inside an IT block (it reverts the request until
 * the block ends); there the counter keeps to the plain stop. A false "maybe" (the second
 * half of a 32-bit instruction that looks like IT) only takes that path too. */
int twin_maybe_in_it(const uint16_t *code, uint32_t h) {
    for (uint32_t k = 1; k <= 8 && k <= h; k++) {
        uint16_t w = code[h - k];
        if ((w & 0xFF00) != 0xBF00 || !(w & 0xF)) {
            continue;
        }
        int n = (w & 1) ? 4 : (w & 2) ? 3 : (w & 4) ? 2 : 1;
        uint32_t p = h - k + 1;
        /* past h: not this IT's block (and no read past the end of flash) */
        for (int i = 0; i < n && p <= h; i++) {
            if (p == h) {
                return 1;
            }
            p += (code[p] >> 11) >= 0x1D ? 2 : 1;  /* 0b11101, 0b11110, 0b11111: 32 bits */
        }
    }
    return 0;
}

void twin_code_hook(void *uc, uint64_t addr, uint32_t size, void *user) {
    twin_counter *s = (twin_counter *)user;
    (void)size;
    if (s->icount >= s->stop_at) {
        uint32_t o = (uint32_t)addr - s->flash_base;
        if (s->on_due && o < s->flash_len && !twin_maybe_in_it(s->flash_code, o >> 1)) {
            if (s->on_due(uc, (uint32_t)addr)) {
                return;
            }  /* else re-armed past this instruction: it runs, counted */
        } else {
            /* every time: a stop requested while Unicorn was inside a memory callback can
               be lost, and the next instruction must not run */
            s->stopped = 1;
            s->stop(uc);
            return;
        }
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
        if (s->flash_code[h] == 0xBF30 && s->on_wfi) {
            s->on_wfi(uc, (uint32_t)addr);  /* counted; it sleeps there, then goes on */
        } else if (s->watch && ((s->watch[h >> 3] >> (h & 7)) & 1)) {
            s->on_watch(uc, (uint32_t)addr);
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

/* The PC, and PRIMASK | BASEPRI << 8: read on every stop and every interrupt decision, where
 * Unicorn's Python binding costs microseconds a register. */
uint32_t twin_pc(twin_counter *s, void *uc) {
    uint32_t v = 0;
    s->reg_read1(uc, s->pc_id, &v);
    return v;
}

/* A word of memory into *out (the vector table, on every exception entry): 0, or Unicorn's
 * error (nothing mapped there). */
int twin_read_word(twin_counter *s, void *uc, uint32_t addr, uint32_t *out) {
    return s->mem_read(uc, addr, out, 4);
}

void twin_set_pc(twin_counter *s, void *uc, uint32_t pc) {
    s->reg_write1(uc, s->pc_id, &pc);
}

uint32_t twin_masks(twin_counter *s, void *uc) {
    uint32_t p = 0, b = 0;
    s->reg_read1(uc, s->primask_id, &p);
    s->reg_read1(uc, s->basepri_id, &b);
    return (p & 1) | (b & 0xFF) << 8;
}
