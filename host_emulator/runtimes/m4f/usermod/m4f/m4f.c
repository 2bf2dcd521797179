// The `m4f` module: what the emulated Cortex-M4F board (QEMU mps2-an386, -icount shift=0)
// gives the guest side of host_emulator/runtimes/m4f besides MicroPython itself.
//
// - An instruction counter. Under -icount shift=0 QEMU advances virtual time by exactly 1 ns
//   per guest instruction; the CMSDK APB timer 0 of the MPS2 board counts down at its 25 MHz
//   PCLK of virtual time, i.e. once per 40 instructions. icount() returns the instructions
//   executed since init(), modulo 2**30 so that it stays a small int (no heap allocation);
//   differences are taken modulo 2**30 as time.ticks_diff does.
// - Time spent in emulation, not firmware: emu_in()/emu_out() bracket the emulated
//   peripherals' Python code (host_emulator/emulated_board/mpy/machine.py); the instructions
//   between them are summed here, emu_total() returns the sum modulo 2**30. Brackets nest: only
//   the outermost one counts. So are the bytes the emulation asks the heap for (emu_alloc():
//   MicroPython's allocation count inside the brackets, modulo 2**30), which a board's C
//   drivers never take: the firmware's view of micropython.mem_total leaves them out
//   (emulated_board/mpy/feed.py).
// - Periph(obj): the firmware's handle on an emulated peripheral or clock function. On a board
//   machine.Pin/SPI/UART/WDT methods and time.ticks_us are C: calling one costs a C method call.
//   A Periph's methods (PERIPH_METHODS) and its call are C as well: the firmware's call costs
//   what it costs on the board, and the Python code behind it runs inside a bracket. Other
//   attributes are the object's own (read and written through).
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

static uint32_t emu_start;  // timer value at the outermost emu_in()
static uint32_t emu_sum;  // timer counts spent in emulation
static uint32_t emu_depth;  // brackets open
static size_t emu_alloc_start;  // MicroPython's allocation count at the outermost emu_in()
static size_t emu_alloc_sum;  // bytes allocated in emulation
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
    // board's clock is its own, emulated_board/mpy/time.py; interrupts are not counted, as
    // documented).
    SYSTICK_CSR = 0;
    TIMER_CTRL = 0;
    TIMER_RELOAD = 0xffffffffu;
    TIMER_VALUE = 0xffffffffu;
    TIMER_CTRL = 1;  // enable, no interrupt
    emu_sum = 0;
    emu_depth = 0;
    emu_alloc_sum = 0;
    return mp_const_none;
}
static MP_DEFINE_CONST_FUN_OBJ_0(m4f_init_obj, m4f_init);

static mp_obj_t m4f_icount(void) {
    return MP_OBJ_NEW_SMALL_INT((counts() * INSTR_PER_COUNT) & COUNT_MASK);
}
static MP_DEFINE_CONST_FUN_OBJ_0(m4f_icount_obj, m4f_icount);

static void emu_enter(void) {
    if (emu_depth++ == 0) {
        emu_start = counts();
        emu_alloc_start = m_get_total_bytes_allocated();
    }
}

static void emu_leave(void) {
    if (emu_depth > 0 && --emu_depth == 0) {
        emu_sum += counts() - emu_start;
        emu_alloc_sum += m_get_total_bytes_allocated() - emu_alloc_start;
    }
}

static mp_obj_t m4f_emu_in(void) {
    emu_enter();
    return mp_const_none;
}
static MP_DEFINE_CONST_FUN_OBJ_0(m4f_emu_in_obj, m4f_emu_in);

static mp_obj_t m4f_emu_out(void) {
    emu_leave();
    return mp_const_none;
}
static MP_DEFINE_CONST_FUN_OBJ_0(m4f_emu_out_obj, m4f_emu_out);

static mp_obj_t m4f_emu_total(void) {
    return MP_OBJ_NEW_SMALL_INT((emu_sum * INSTR_PER_COUNT) & COUNT_MASK);
}
static MP_DEFINE_CONST_FUN_OBJ_0(m4f_emu_total_obj, m4f_emu_total);

static mp_obj_t m4f_emu_alloc(void) {
    return MP_OBJ_NEW_SMALL_INT(emu_alloc_sum & COUNT_MASK);
}
static MP_DEFINE_CONST_FUN_OBJ_0(m4f_emu_alloc_obj, m4f_emu_alloc);

// ---- Periph --------------------------------------------------------------------------------

typedef struct {
    mp_obj_base_t base;
    mp_obj_t obj;  // the emulated peripheral (or function), Python
} periph_obj_t;

#define PERIPH_MAX_ARGS (6)  // positional arguments plus two per keyword argument

// obj.name(*args, **kw) (or obj(...) when name is MP_QSTRnull) inside an emulation bracket,
// which an exception also closes; args holds n_args positional arguments then n_kw key/value
// pairs.
static mp_obj_t periph_forward(mp_obj_t obj, qstr name, size_t n_args, size_t n_kw,
    const mp_obj_t *args) {
    emu_enter();
    nlr_buf_t nlr;
    if (nlr_push(&nlr) == 0) {
        mp_obj_t r;
        if (name == MP_QSTRnull) {
            r = mp_call_function_n_kw(obj, n_args, n_kw, args);
        } else {
            mp_obj_t dest[2 + PERIPH_MAX_ARGS];
            mp_load_method(obj, name, dest);
            for (size_t i = 0; i < n_args + 2 * n_kw; i++) {
                dest[2 + i] = args[i];
            }
            r = mp_call_method_n_kw(n_args, n_kw, dest);
        }
        nlr_pop();
        emu_leave();
        return r;
    }
    emu_leave();
    nlr_jump(nlr.ret_val);
}

static mp_obj_t periph_make_new(const mp_obj_type_t *type, size_t n_args, size_t n_kw,
    const mp_obj_t *args) {
    mp_arg_check_num(n_args, n_kw, 1, 1, false);
    periph_obj_t *self = mp_obj_malloc(periph_obj_t, type);
    self->obj = args[0];
    return MP_OBJ_FROM_PTR(self);
}

static mp_obj_t periph_call(mp_obj_t self_in, size_t n_args, size_t n_kw, const mp_obj_t *args) {
    if (n_args + 2 * n_kw > PERIPH_MAX_ARGS) {
        mp_raise_TypeError(MP_ERROR_TEXT("Periph: too many arguments"));
    }
    periph_obj_t *self = MP_OBJ_TO_PTR(self_in);
    return periph_forward(self->obj, MP_QSTRnull, n_args, n_kw, args);
}

// The methods a board's machine classes have in C and the firmware calls per tick (UART
// writechar: the status page's transmitter without DMA, firmware/board.py _Chars, which holds
// the bound method; without it here the firmware would call machine.py's Python method itself,
// its call counted as firmware).
static mp_obj_t periph_method(qstr name, size_t n_args, const mp_obj_t *args, mp_map_t *kw) {
    periph_obj_t *self = MP_OBJ_TO_PTR(args[0]);
    size_t n_kw = kw->used;
    if (n_kw == 0) {
        return periph_forward(self->obj, name, n_args - 1, 0, args + 1);
    }
    mp_obj_t all[PERIPH_MAX_ARGS];
    if (n_args - 1 + 2 * n_kw > PERIPH_MAX_ARGS) {
        mp_raise_TypeError(MP_ERROR_TEXT("Periph: too many arguments"));
    }
    size_t k = 0;
    for (size_t i = 1; i < n_args; i++) {
        all[k++] = args[i];
    }
    for (size_t i = 0; i < kw->alloc; i++) {
        if (mp_map_slot_is_filled(kw, i)) {
            all[k++] = kw->table[i].key;
            all[k++] = kw->table[i].value;
        }
    }
    return periph_forward(self->obj, name, n_args - 1, n_kw, all);
}

#define PERIPH_METHOD(name) \
    static mp_obj_t periph_##name(size_t n_args, const mp_obj_t *args, mp_map_t *kw) { \
        return periph_method(MP_QSTR_##name, n_args, args, kw); \
    } \
    static MP_DEFINE_CONST_FUN_OBJ_KW(periph_##name##_obj, 1, periph_##name);
PERIPH_METHOD(value)
PERIPH_METHOD(on)
PERIPH_METHOD(off)
PERIPH_METHOD(irq)
PERIPH_METHOD(write)
PERIPH_METHOD(writechar)
PERIPH_METHOD(read)
PERIPH_METHOD(readinto)
PERIPH_METHOD(write_readinto)
PERIPH_METHOD(any)
PERIPH_METHOD(feed)
PERIPH_METHOD(deinit)

static const mp_rom_map_elem_t periph_locals_table[] = {
    { MP_ROM_QSTR(MP_QSTR_value), MP_ROM_PTR(&periph_value_obj) },
    { MP_ROM_QSTR(MP_QSTR_on), MP_ROM_PTR(&periph_on_obj) },
    { MP_ROM_QSTR(MP_QSTR_off), MP_ROM_PTR(&periph_off_obj) },
    { MP_ROM_QSTR(MP_QSTR_irq), MP_ROM_PTR(&periph_irq_obj) },
    { MP_ROM_QSTR(MP_QSTR_write), MP_ROM_PTR(&periph_write_obj) },
    { MP_ROM_QSTR(MP_QSTR_writechar), MP_ROM_PTR(&periph_writechar_obj) },
    { MP_ROM_QSTR(MP_QSTR_read), MP_ROM_PTR(&periph_read_obj) },
    { MP_ROM_QSTR(MP_QSTR_readinto), MP_ROM_PTR(&periph_readinto_obj) },
    { MP_ROM_QSTR(MP_QSTR_write_readinto), MP_ROM_PTR(&periph_write_readinto_obj) },
    { MP_ROM_QSTR(MP_QSTR_any), MP_ROM_PTR(&periph_any_obj) },
    { MP_ROM_QSTR(MP_QSTR_feed), MP_ROM_PTR(&periph_feed_obj) },
    { MP_ROM_QSTR(MP_QSTR_deinit), MP_ROM_PTR(&periph_deinit_obj) },
};
static MP_DEFINE_CONST_DICT(periph_locals_dict, periph_locals_table);

// Any other attribute is the object's own: loaded (a method as a bound method) or stored.
static void periph_attr(mp_obj_t self_in, qstr attr, mp_obj_t *dest) {
    periph_obj_t *self = MP_OBJ_TO_PTR(self_in);
    if (dest[0] == MP_OBJ_NULL) {
        mp_map_elem_t *elem = mp_map_lookup((mp_map_t *)&periph_locals_dict.map,
            MP_OBJ_NEW_QSTR(attr), MP_MAP_LOOKUP);
        if (elem != NULL) {
            dest[0] = elem->value;
            dest[1] = self_in;
            return;
        }
        mp_load_method_maybe(self->obj, attr, dest);
    } else if (dest[1] != MP_OBJ_NULL) {
        mp_store_attr(self->obj, attr, dest[1]);
        dest[0] = MP_OBJ_NULL;
    }
}

static MP_DEFINE_CONST_OBJ_TYPE(
    periph_type,
    MP_QSTR_Periph,
    MP_TYPE_FLAG_NONE,
    make_new, periph_make_new,
    call, periph_call,
    attr, periph_attr
    );

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
    { MP_ROM_QSTR(MP_QSTR_emu_alloc), MP_ROM_PTR(&m4f_emu_alloc_obj) },
    { MP_ROM_QSTR(MP_QSTR_Periph), MP_ROM_PTR(&periph_type) },
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
