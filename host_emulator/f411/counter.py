"""The instruction counter of the twin's CPU: a Unicorn code hook written in C (counter.c),
built with cffi on first use and cached in build/f411/ (keyed by its source, the compiler
flags and the interpreter).

One `twin_counter` struct is shared between C and Python:
    icount          instructions executed since reset (the clock's base)
    stop_at         the hook stops emulation before the instruction that would exceed it:
                    the CPU stops exactly at the cycle of the next event
    handler_icount  of which executed in handler mode (in_handler, set by the CPU's exception
                    entry and return)
    irq_pending     set while an interrupt is pending but masked: after an instruction marked
                    in `sync` (CPSIE, MSR PRIMASK/BASEPRI) the hook stops so that the CPU can
                    take it at once, as the core would
    on_due          called (cpu.py) instead of stopping when the next event is due before an
                    instruction in flash outside an IT block; on_wfi: before a WFI in flash;
                    on_watch: before an instruction marked in `watch` runs (chip.hook)
    category_count  instructions per category of the code they belong to (`category` maps
                    each flash halfword to one; the last one is code outside flash: native
                    modules the image loaded into RAM)
Why C: Unicorn calls a code hook before every instruction; in Python that is ~1 us each, in C
a few ns, so the twin runs at tens of millions of instructions a second.
"""

import ctypes
import hashlib
import importlib.util
import pathlib
import sys
import tempfile

from common.errors import EmulatorError

SOURCE = pathlib.Path(__file__).with_name("counter.c")
# compiled into the same module: the peripheral accesses of plain registers (bus.py)
SOURCES = (SOURCE, SOURCE.with_name("mmio.c"))
ROOT = pathlib.Path(__file__).resolve().parents[2]
BUILD = ROOT / "build" / "f411"
MODULE = "_f411_counter"
N_CATEGORIES = 8
CFLAGS = ["-O2"]
CDEF = """
typedef struct {
    uint64_t icount;
    uint64_t stop_at;
    uint64_t handler_icount;
    uint32_t in_handler;
    uint32_t irq_pending;
    uint32_t stopped;
    uint32_t flash_base, flash_len;
    int (*stop)(void *);
    const uint8_t *sync;
    const uint8_t *category;
    uint64_t category_count[8];
    void *reg_read, *reg_write, *mem_read, *mem_write;
    int saved_ids[24];
    int sp_id, lr_id, ipsr_id, xpsr_id;
    int pc_id, primask_id, basepri_id;
    void *reg_read1, *reg_write1;
    const uint16_t *flash_code;
    void (*on_wfi)(void *uc, uint32_t addr);
    int (*on_due)(void *uc, uint32_t addr);
    const uint8_t *watch;
    void (*on_watch)(void *uc, uint32_t addr);
} twin_counter;
void twin_code_hook(void *uc, uint64_t addr, uint32_t size, void *user);
int twin_enter(twin_counter *s, void *uc, uint32_t return_pc, uint32_t number,
               uint32_t exc_return);
int twin_return(twin_counter *s, void *uc, uint32_t ipsr, uint32_t *return_pc);
uint32_t twin_pc(twin_counter *s, void *uc);
uint32_t twin_masks(twin_counter *s, void *uc);
void twin_set_pc(twin_counter *s, void *uc, uint32_t pc);
int twin_read_word(twin_counter *s, void *uc, uint32_t addr, uint32_t *out);
int twin_maybe_in_it(const uint16_t *code, uint32_t h);
typedef struct {
    uint32_t *v;
    const uint8_t *plain;
    const uint32_t *writable;
    uint32_t words;
    const uint32_t *gate;
    uint32_t gate_bit;
    uint32_t *served;
    uint64_t (*py_read)(void *, uint64_t, unsigned, void *);
    void (*py_write)(void *, uint64_t, unsigned, uint64_t, void *);
} twin_periph;
int twin_mmio_map(void *map_fn, void *uc, uint64_t base, uint64_t size, twin_periph *p);
"""

_loaded = None


def _key():
    import cffi

    h = hashlib.sha256(b"".join(f.read_bytes() for f in SOURCES))
    h.update(f"{CDEF}{CFLAGS}{sys.version}{cffi.__version__}".encode())
    return h.hexdigest()[:16]


def load():
    """The compiled module (ffi, lib), built if needed."""
    global _loaded
    if _loaded is not None:
        return _loaded
    import cffi

    out = BUILD / _key()
    so = next(out.glob(MODULE + "*.so"), None) if out.is_dir() else None
    if so is None:
        out.mkdir(parents=True, exist_ok=True)
        ffi = cffi.FFI()
        ffi.cdef(CDEF)
        ffi.set_source(MODULE, "\n".join(f.read_text() for f in SOURCES), extra_compile_args=CFLAGS)
        with tempfile.TemporaryDirectory(dir=out) as tmp:
            try:
                built = pathlib.Path(ffi.compile(tmpdir=tmp, verbose=False))
            except Exception as e:  # noqa: BLE001  (cffi raises several kinds)
                raise EmulatorError(f"cannot build the twin's instruction counter: {e}") from None
            so = out / built.name
            built.replace(so)
    spec = importlib.util.spec_from_file_location(MODULE, so)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    _loaded = (mod.ffi, mod.lib)
    return _loaded


def _fn(uclib, name):
    return ctypes.cast(getattr(uclib, name), ctypes.c_void_p).value


def uc_function(name):
    """The address of one of Unicorn's C functions."""
    from unicorn.unicorn_py3 import unicorn as ucmod

    return _fn(ucmod.uclib, name)


def attach(uc, uclib, hook_handle_type, code_hook_type, frame_ids=None):
    """A new twin_counter hooked on every instruction of `uc`; returns (counter, keep), where
    keep holds what must stay alive as long as the hook."""
    ffi, lib = load()
    c = ffi.new("twin_counter *")
    c.stop = ffi.cast("int(*)(void *)", _fn(uclib, "uc_emu_stop"))
    c.stop_at = 0
    for field, name in (("reg_read", "uc_reg_read_batch"), ("reg_write", "uc_reg_write_batch"),
                        ("mem_read", "uc_mem_read"), ("mem_write", "uc_mem_write"),
                        ("reg_read1", "uc_reg_read"), ("reg_write1", "uc_reg_write")):  # fmt: skip
        setattr(c, field, ffi.cast("void *", _fn(uclib, name)))
    if frame_ids is not None:
        saved, sp, lr, ipsr, xpsr, c.pc_id, c.primask_id, c.basepri_id = frame_ids
        for i, r in enumerate(saved):
            c.saved_ids[i] = r
        c.sp_id, c.lr_id, c.ipsr_id, c.xpsr_id = sp, lr, ipsr, xpsr
    handle = hook_handle_type()
    fn = int(ffi.cast("uintptr_t", ffi.addressof(lib, "twin_code_hook")))
    err = uclib.uc_hook_add(
        uc._uch, ctypes.byref(handle), code_hook_type, ctypes.c_void_p(fn),
        ctypes.c_void_p(int(ffi.cast("uintptr_t", c))), ctypes.c_uint64(1), ctypes.c_uint64(0),
    )  # fmt: skip
    if err:
        raise EmulatorError(f"unicorn refused the instruction counter hook (error {err})")
    return c, (handle, ffi, lib, uc._uch.value)
