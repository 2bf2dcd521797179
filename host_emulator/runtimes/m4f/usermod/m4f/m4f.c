// The `m4f` module: what the emulated Cortex-M4F board (QEMU mps2-an386, -icount shift=0)
// gives the guest side of host_emulator/runtimes/m4f besides MicroPython itself.
//
// - An instruction counter. Under -icount shift=0 QEMU advances virtual time by exactly 1 ns
//   per guest instruction; the CMSDK APB timer 0 of the MPS2 board counts down at its 25 MHz
//   PCLK of virtual time, i.e. once per 40 instructions. icount() returns the instructions
//   executed since init(), modulo 2**30 so that it stays a small int (no heap allocation);
//   differences are taken modulo 2**30 as time.ticks_diff does.
// - Time spent in emulation, not firmware: emu_in()/emu_out() bracket the emulated
//   peripherals' Python code (host_emulator/board/mpy/machine.py); the instructions between
//   them are summed here, emu_total() returns the sum modulo 2**30.
// - Host files through ARM semihosting (QEMU -semihosting): open/readinto/write/close, paths
//   relative to QEMU's working directory. The stimulus comes in and the output goes out here.
// - A RAM disk outside the MicroPython heap, so that a FAT /flash can hold ins.cfg as on the
//   board without taking heap from the firmware; get_fattime() for FatFs.
// - exit(code): ends QEMU with that status (semihosting SYS_EXIT_EXTENDED).
// - init() also stops the port's SysTick interrupt (see there).
//
// Nothing here allocates on the heap except ramdisk() (once) and the errors.

#include <stdint.h>
#include <string.h>

#include "py/runtime.h"
#include "py/objarray.h"

#define TIMER0_BASE (0x40000000u)  // CMSDK APB timer 0 on MPS2
#define TIMER_CTRL (*(volatile uint32_t *)(TIMER0_BASE + 0x00))
#define TIMER_VALUE (*(volatile uint32_t *)(TIMER0_BASE + 0x04))
#define TIMER_RELOAD (*(volatile uint32_t *)(TIMER0_BASE + 0x08))
#define SYSTICK_CSR (*(volatile uint32_t *)0xE000E010)
#define INSTR_PER_COUNT (40u)  // 1 ns per instruction, 25 MHz timer
#define COUNT_MASK (0x3fffffffu)

#define SYS_OPEN (0x01)
#define SYS_CLOSE (0x02)
#define SYS_WRITE (0x05)
#define SYS_READ (0x06)
#define SYS_SEEK (0x0a)
#define SYS_FLEN (0x0c)
#define SYS_EXIT (0x18)
#define SYS_EXIT_EXTENDED (0x20)

#ifndef M4F_RAMDISK_BYTES
#define M4F_RAMDISK_BYTES (64 * 1024)
#endif

static uint32_t emu_start;  // timer value at emu_in()
static uint32_t emu_sum;  // timer counts spent in emulation
static uint8_t ramdisk_buf[M4F_RAMDISK_BYTES] __attribute__((aligned(4)));

static uint32_t semihost(uint32_t op, const void *arg) {
    register uint32_t r0 __asm__ ("r0") = op;
    register const void *r1 __asm__ ("r1") = arg;
    __asm__ __volatile__ ("bkpt 0xAB" : "+r" (r0) : "r" (r1) : "memory");
    return r0;
}

// Timer counts since init() (the timer counts down from 0xffffffff).
static inline uint32_t counts(void) {
    return 0xffffffffu - TIMER_VALUE;
}

static mp_obj_t m4f_init(void) {
    // The port's 1 ms SysTick interrupt would land in the counted code at a phase that depends
    // on when the host's REPL input arrived: off, so that counts repeat exactly (the emulated
    // board's clock is its own, board/mpy/time.py; interrupts are not counted, as documented).
    SYSTICK_CSR = 0;
    TIMER_CTRL = 0;
    TIMER_RELOAD = 0xffffffffu;
    TIMER_VALUE = 0xffffffffu;
    TIMER_CTRL = 1;  // enable, no interrupt
    emu_sum = 0;
    return mp_const_none;
}
static MP_DEFINE_CONST_FUN_OBJ_0(m4f_init_obj, m4f_init);

static mp_obj_t m4f_icount(void) {
    return MP_OBJ_NEW_SMALL_INT((counts() * INSTR_PER_COUNT) & COUNT_MASK);
}
static MP_DEFINE_CONST_FUN_OBJ_0(m4f_icount_obj, m4f_icount);

static mp_obj_t m4f_emu_in(void) {
    emu_start = counts();
    return mp_const_none;
}
static MP_DEFINE_CONST_FUN_OBJ_0(m4f_emu_in_obj, m4f_emu_in);

static mp_obj_t m4f_emu_out(void) {
    emu_sum += counts() - emu_start;
    return mp_const_none;
}
static MP_DEFINE_CONST_FUN_OBJ_0(m4f_emu_out_obj, m4f_emu_out);

static mp_obj_t m4f_emu_total(void) {
    return MP_OBJ_NEW_SMALL_INT((emu_sum * INSTR_PER_COUNT) & COUNT_MASK);
}
static MP_DEFINE_CONST_FUN_OBJ_0(m4f_emu_total_obj, m4f_emu_total);

// open(path, mode): mode as ARM semihosting's (0 "r", 1 "rb", 4 "w", 5 "wb", 8 "a").
static mp_obj_t m4f_open(mp_obj_t path_in, mp_obj_t mode_in) {
    size_t len;
    const char *path = mp_obj_str_get_data(path_in, &len);
    uint32_t args[3] = {(uint32_t)path, (uint32_t)mp_obj_get_int(mode_in), len};
    int32_t h = (int32_t)semihost(SYS_OPEN, args);
    if (h < 0) {
        mp_raise_msg_varg(&mp_type_OSError, MP_ERROR_TEXT("semihosting cannot open %s"), path);
    }
    return MP_OBJ_NEW_SMALL_INT(h);
}
static MP_DEFINE_CONST_FUN_OBJ_2(m4f_open_obj, m4f_open);

static mp_obj_t m4f_close(mp_obj_t h_in) {
    uint32_t args[1] = {(uint32_t)mp_obj_get_int(h_in)};
    semihost(SYS_CLOSE, args);
    return mp_const_none;
}
static MP_DEFINE_CONST_FUN_OBJ_1(m4f_close_obj, m4f_close);

// readinto(h, buf, n): bytes read (fewer at the end of the file).
static mp_obj_t m4f_readinto(mp_obj_t h_in, mp_obj_t buf_in, mp_obj_t n_in) {
    mp_buffer_info_t bufinfo;
    mp_get_buffer_raise(buf_in, &bufinfo, MP_BUFFER_WRITE);
    uint32_t n = (uint32_t)mp_obj_get_int(n_in);
    if (n > bufinfo.len) {
        mp_raise_ValueError(MP_ERROR_TEXT("n exceeds the buffer"));
    }
    uint32_t args[3] = {(uint32_t)mp_obj_get_int(h_in), (uint32_t)bufinfo.buf, n};
    uint32_t not_read = semihost(SYS_READ, args);
    return MP_OBJ_NEW_SMALL_INT(n - not_read);
}
static MP_DEFINE_CONST_FUN_OBJ_3(m4f_readinto_obj, m4f_readinto);

// write(h, buf, n): writes the first n bytes of buf; OSError if the host wrote fewer.
static mp_obj_t m4f_write(mp_obj_t h_in, mp_obj_t buf_in, mp_obj_t n_in) {
    mp_buffer_info_t bufinfo;
    mp_get_buffer_raise(buf_in, &bufinfo, MP_BUFFER_READ);
    uint32_t n = (uint32_t)mp_obj_get_int(n_in);
    if (n > bufinfo.len) {
        mp_raise_ValueError(MP_ERROR_TEXT("n exceeds the buffer"));
    }
    uint32_t args[3] = {(uint32_t)mp_obj_get_int(h_in), (uint32_t)bufinfo.buf, n};
    if (semihost(SYS_WRITE, args) != 0) {
        mp_raise_msg(&mp_type_OSError, MP_ERROR_TEXT("semihosting write failed"));
    }
    return mp_const_none;
}
static MP_DEFINE_CONST_FUN_OBJ_3(m4f_write_obj, m4f_write);

static mp_obj_t m4f_seek(mp_obj_t h_in, mp_obj_t pos_in) {
    uint32_t args[2] = {(uint32_t)mp_obj_get_int(h_in), (uint32_t)mp_obj_get_int(pos_in)};
    if (semihost(SYS_SEEK, args) != 0) {
        mp_raise_msg(&mp_type_OSError, MP_ERROR_TEXT("semihosting seek failed"));
    }
    return mp_const_none;
}
static MP_DEFINE_CONST_FUN_OBJ_2(m4f_seek_obj, m4f_seek);

static mp_obj_t m4f_flen(mp_obj_t h_in) {
    uint32_t args[1] = {(uint32_t)mp_obj_get_int(h_in)};
    return mp_obj_new_int((int32_t)semihost(SYS_FLEN, args));
}
static MP_DEFINE_CONST_FUN_OBJ_1(m4f_flen_obj, m4f_flen);

static mp_obj_t m4f_ramdisk(void) {
    return mp_obj_new_bytearray_by_ref(sizeof(ramdisk_buf), ramdisk_buf);
}
static MP_DEFINE_CONST_FUN_OBJ_0(m4f_ramdisk_obj, m4f_ramdisk);

static mp_obj_t m4f_exit(mp_obj_t code_in) {
    // ADP_Stopped_ApplicationExit with a status (semihosting v2, as QEMU implements it)
    uint32_t args[2] = {0x20026, (uint32_t)mp_obj_get_int(code_in)};
    semihost(SYS_EXIT_EXTENDED, args);
    semihost(SYS_EXIT, (const void *)0x20026);  // older hosts: status 0
    for (;;) {
    }
    return mp_const_none;
}
static MP_DEFINE_CONST_FUN_OBJ_1(m4f_exit_obj, m4f_exit);

// FatFs's timestamp for files written on the RAM disk: 2026-01-01 00:00.
uint32_t get_fattime(void) {
    return ((2026u - 1980u) << 25) | (1u << 21) | (1u << 16);
}

static const mp_rom_map_elem_t m4f_globals_table[] = {
    { MP_ROM_QSTR(MP_QSTR___name__), MP_ROM_QSTR(MP_QSTR_m4f) },
    { MP_ROM_QSTR(MP_QSTR_init), MP_ROM_PTR(&m4f_init_obj) },
    { MP_ROM_QSTR(MP_QSTR_icount), MP_ROM_PTR(&m4f_icount_obj) },
    { MP_ROM_QSTR(MP_QSTR_emu_in), MP_ROM_PTR(&m4f_emu_in_obj) },
    { MP_ROM_QSTR(MP_QSTR_emu_out), MP_ROM_PTR(&m4f_emu_out_obj) },
    { MP_ROM_QSTR(MP_QSTR_emu_total), MP_ROM_PTR(&m4f_emu_total_obj) },
    { MP_ROM_QSTR(MP_QSTR_open), MP_ROM_PTR(&m4f_open_obj) },
    { MP_ROM_QSTR(MP_QSTR_close), MP_ROM_PTR(&m4f_close_obj) },
    { MP_ROM_QSTR(MP_QSTR_readinto), MP_ROM_PTR(&m4f_readinto_obj) },
    { MP_ROM_QSTR(MP_QSTR_write), MP_ROM_PTR(&m4f_write_obj) },
    { MP_ROM_QSTR(MP_QSTR_seek), MP_ROM_PTR(&m4f_seek_obj) },
    { MP_ROM_QSTR(MP_QSTR_flen), MP_ROM_PTR(&m4f_flen_obj) },
    { MP_ROM_QSTR(MP_QSTR_ramdisk), MP_ROM_PTR(&m4f_ramdisk_obj) },
    { MP_ROM_QSTR(MP_QSTR_exit), MP_ROM_PTR(&m4f_exit_obj) },
    { MP_ROM_QSTR(MP_QSTR_INSTR_PER_COUNT), MP_ROM_INT(INSTR_PER_COUNT) },
};
static MP_DEFINE_CONST_DICT(m4f_globals, m4f_globals_table);

const mp_obj_module_t m4f_module = {
    .base = { &mp_type_module },
    .globals = (mp_obj_dict_t *)&m4f_globals,
};

MP_REGISTER_MODULE(MP_QSTR_m4f, m4f_module);
