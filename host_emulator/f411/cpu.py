"""The twin's Cortex-M4F: Unicorn's ARMv7E-M core with the parts Unicorn leaves to its user.

Unicorn (QEMU's TCG) executes the instructions, the FPv4-SP arithmetic included, and nothing
of the system around them: no NVIC, no exception entry or return, no sleep. Done here:
- counting: a C code hook (counter.c) counts every instruction and stops Unicorn exactly
  before the instruction at which the clock reaches the next event (clock.py);
- exception entry, as ARMv7-M (B1.5.6): the frame (R0-R3, R12, LR, return address, xPSR,
  and S0-S15 and FPSCR: the extended frame, which the core stacks once the interrupted code
  has used the FPU; the image computes in floats, so always), 8-byte alignment with xPSR bit 9,
  LR = EXC_RETURN, IPSR, the handler from the vector table at VTOR; 12 cycles;
- exception return: Unicorn does not treat a branch to EXC_RETURN as one (it does not rebuild
  its handler-mode state when IPSR is written), so the branch fetches from 0xFFFFFFxx; that
  is caught, the frame unstacked here, and the next pending exception taken at once
  (tail-chaining) if it may be;
- which exception is taken: nvic.py (priorities, PRIMASK, BASEPRI, active exceptions);
- WFI: the core sleeps until an interrupt that would preempt (PRIMASK does not keep it
  asleep, B1.5.19), the clock jumping from event to event;
- interrupts unmasked by software (CPSIE, MSR PRIMASK/BASEPRI): the counter stops after such
  an instruction while one is pending, so it is taken before the next instruction, as on the
  core. Interrupts made pending by a peripheral access are taken after that instruction.

Speed: what comes after a stop (the events due, the sleep of a WFI, the interrupt taken, an
exception return) runs inside Unicorn's hooks, and emulation goes on from there without
returning from emu_start (a return and restart costs more than most of what comes between):
the counter calls back at the next event (outside an IT block, where Unicorn cannot stop, it
stops as before) and at a WFI in flash; the interrupt hook does the exception return. The
instructions counted, and so every figure of a tick, are the same as when each of these
returned from emulation (the runs' per-tick records compare equal).

What is not modelled: the MPU, fault escalation (a fault stops the run with what faulted),
lazy FP stacking's timing, the bus matrix's contention, tail-chaining's shorter latency.
"""

import ctypes

from unicorn import (
    UC_ARCH_ARM,
    UC_ERR_EXCEPTION,
    UC_HOOK_CODE,
    UC_HOOK_INTR,
    UC_HOOK_MEM_FETCH_UNMAPPED,
    UC_HOOK_MEM_READ_UNMAPPED,
    UC_HOOK_MEM_WRITE_UNMAPPED,
    UC_MEM_FETCH_UNMAPPED,
    UC_MEM_READ_UNMAPPED,
    UC_MEM_WRITE_UNMAPPED,
    UC_MODE_MCLASS,
    UC_MODE_THUMB,
    Uc,
    UcError,
)
from unicorn import arm_const as A
from unicorn.unicorn_py3 import unicorn as _ucmod

from host_emulator.f411 import counter as counter_mod
from host_emulator.f411.bus import TwinError
from host_emulator.f411.clock import Clock

ENTRY_CYCLES = 12  # Cortex-M4 interrupt latency at zero wait states (TRM 3.3.1)
RETURN_CYCLES = 12
_FRAME_REGS = (A.UC_ARM_REG_R0, A.UC_ARM_REG_R1, A.UC_ARM_REG_R2, A.UC_ARM_REG_R3,
               A.UC_ARM_REG_R12, A.UC_ARM_REG_LR)  # fmt: skip
_FP_REGS = tuple(A.UC_ARM_REG_S0 + i for i in range(16))
FRAME_WORDS = 26  # 8 + S0-S15 + FPSCR + reserved
_WFI = 0xBF30
_EXCP_EXCEPTION_EXIT = 8  # QEMU's: a branch to EXC_RETURN, which Unicorn hands to the hook
_UNTIL = 0xFFFFFFFE  # an address no code runs at: emulation ends by the counter, WFI or a fault


class Cpu:
    def __init__(self, cpi):
        uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        uc.ctl_set_cpu_model(A.UC_CPU_ARM_CORTEX_M4)
        self.uc = uc
        saved = (*_FRAME_REGS, A.UC_ARM_REG_XPSR, *_FP_REGS, A.UC_ARM_REG_FPSCR)
        self.counter, self._keep = counter_mod.attach(
            uc, _ucmod.uclib, _ucmod.uc_hook_h, UC_HOOK_CODE,
            (saved, A.UC_ARM_REG_SP, A.UC_ARM_REG_LR, A.UC_ARM_REG_IPSR, A.UC_ARM_REG_XPSR,
             A.UC_ARM_REG_PC, A.UC_ARM_REG_PRIMASK, A.UC_ARM_REG_BASEPRI),
        )  # fmt: skip
        self._ffi, self._lib, self._uch = self._keep[1], self._keep[2], self._keep[3]
        self._uc_ptr = self._ffi.cast("void *", self._uch)
        self._ret_pc = self._ffi.new("uint32_t *")
        self._word = self._ffi.new("uint32_t *")
        self.clock = Clock(self.counter, cpi)
        self.nvic = None  # nvic.Scs, set by the chip
        self.where = None  # pc -> "function (file)" for messages, set by the chip
        self._pc = 0
        self.active = []  # active exception numbers, the running one last
        self.exceptions_taken = 0
        self.sleeping_cycles = 0  # of clock.waited: in WFI
        self._bad = None  # (kind, address) of the last unmapped access
        self._sync_keep = None
        uc.hook_add(
            UC_HOOK_MEM_READ_UNMAPPED | UC_HOOK_MEM_WRITE_UNMAPPED | UC_HOOK_MEM_FETCH_UNMAPPED,
            self._on_unmapped,
        )
        uc.hook_add(UC_HOOK_INTR, self._on_intr)
        self._intr = None
        self._error = None
        self.on_sleep = None  # fn(pc) when the core executes the WFI at pc
        self._asleep = False
        self._exit = None  # run()'s result, when a hook reached it (_go_on)
        self._until, self._halted = 0, lambda: False
        self._watched = {}  # address -> [fn()] (watch)
        self._watch_cb = self._ffi.callback("void(void *, uint32_t)", self._on_watch)
        self.counter.on_watch = self._watch_cb
        self._wfi_cb = self._ffi.callback("void(void *, uint32_t)", self._on_wfi)
        self._due_cb = self._ffi.callback("int(void *, uint32_t)", self._on_due)
        self.counter.on_wfi = self._wfi_cb
        self.counter.on_due = self._due_cb

    # -- set-up ------------------------------------------------------------------------

    def map_flash(self, base, data_size):
        """Flash at `base` and its boot alias at 0 (BOOT0 low: main flash at 0x00000000), one
        host buffer for both, erased (0xFF)."""
        self._flash_buf = (ctypes.c_ubyte * data_size)()
        ctypes.memset(self._flash_buf, 0xFF, data_size)
        perms = 5  # read, execute: a store faults into the flash interface model (chip.py)
        self.uc.mem_map_ptr(base, data_size, perms, self._flash_buf)
        self.uc.mem_map_ptr(0, data_size, perms, self._flash_buf)

    def set_code_map(self, flash_base, categories, sync):
        """The counter's per-halfword category map and sync bitmap (bytes) over flash."""
        c = self.counter
        self._sync_keep = (bytes(categories), bytes(sync))
        ffi = self._keep[1]
        c.flash_base = flash_base
        c.flash_code = self._ffi.cast("const uint16_t *", ctypes.addressof(self._flash_buf))
        c.flash_len = len(categories) * 2
        c.category = ffi.from_buffer(self._sync_keep[0])
        c.sync = ffi.from_buffer(self._sync_keep[1])
        self._watch_bits = ffi.new("uint8_t[]", len(sync))
        c.watch = self._watch_bits

    def watch(self, addr, fn):
        """fn() each time the core is about to execute the instruction at addr (in flash)."""
        h = (addr - self.counter.flash_base) >> 1
        if not 0 <= h < self.counter.flash_len // 2:
            raise TwinError(f"0x{addr:08X}: only code in flash can be watched")
        self._watch_bits[h >> 3] |= 1 << (h & 7)
        self._watched.setdefault(addr, []).append(fn)

    def _on_watch(self, _uc, addr):
        try:
            for fn in self._watched[addr]:
                fn()
        except BaseException as e:  # noqa: BLE001  (cffi would only print it)
            self.fail(e)

    def reset(self, vector_table):
        """The core's reset (ARMv7-M B1.5.5): the masks and CONTROL cleared (a reset from code
        that had interrupts masked, in the idle loop or a flash erase, must not start the
        image with them masked: its millisecond tick would not run), Thread mode, the stack
        and entry point from the vector table."""
        sp, pc = (int.from_bytes(self.uc.mem_read(vector_table + i, 4), "little") for i in (0, 4))
        uc = self.uc
        for reg in (A.UC_ARM_REG_PRIMASK, A.UC_ARM_REG_BASEPRI, A.UC_ARM_REG_FAULTMASK,
                    A.UC_ARM_REG_CONTROL):  # fmt: skip
            uc.reg_write(reg, 0)
        uc.reg_write(A.UC_ARM_REG_XPSR, 0x01000000)  # T set, IPSR 0 (Thread mode)
        self.uc.reg_write(A.UC_ARM_REG_MSP, sp)
        self.uc.reg_write(A.UC_ARM_REG_SP, sp)
        self._pc = pc & ~1
        self._asleep = False
        self.active = []
        self.counter.in_handler = 0

    # -- state --------------------------------------------------------------------------

    def pc(self):
        return self._lib.twin_pc(self.counter, self._uc_ptr)

    def fail(self, exc):
        """An exception in a callback Unicorn made (it would not pass it on): kept, emulation
        stopped, raised by run()."""
        if self._error is None:
            self._error = exc
        self.uc.emu_stop()

    def guarded(self, fn):
        """fn wrapped for use as a Unicorn hook: an exception goes to fail()."""

        def hook(*args):
            try:
                return fn(*args)
            except BaseException as e:  # noqa: BLE001
                self.fail(e)
                return False

        return hook

    def stop_soon(self):
        """Stop emulation after the instruction being executed (an event or an interrupt is
        due)."""
        c = self.counter
        if c.stop_at > c.icount:
            c.stop_at = c.icount

    def read_word(self, addr):
        """A word of memory, read in C (every exception entry reads its vector); TwinError
        where nothing is mapped."""
        out = self._word
        if self._lib.twin_read_word(self.counter, self._uc_ptr, addr, out):
            raise TwinError(f"read of a word at 0x{addr:08X}: no memory there")
        return out[0]

    def masks(self):
        m = self._lib.twin_masks(self.counter, self._uc_ptr)
        return m & 1, m >> 8

    # -- running -----------------------------------------------------------------------

    def run(self, until_cycle, halted=lambda: False):
        """Execute until the clock reaches until_cycle or halted() becomes true (checked
        after every stop); returns "cycle", "halted" or "asleep" (WFI with no event left that
        could ever wake the core)."""
        c = self.counter
        uc = self.uc
        self._until, self._halted = until_cycle, halted
        while True:
            r = self._resume()
            if r is not None:
                return r
            self._exit = None
            try:
                uc.emu_start(self._pc | 1, _UNTIL)
            except UcError as e:
                if self._error is not None:
                    raise self._take_error() from None
                pc = self.pc()
                if pc >= 0xFFFFFF00 or (self._bad and self._bad[1] >= 0xFFFFFF00):
                    self._exception_return((self._bad[1] if self._bad else pc) | 1)
                    continue
                raise self._fault(e, pc) from None
            if self._error is not None:
                raise self._take_error()
            if self._exit is not None:
                return self._exit  # a hook went on as this loop would have, up to a result
            self._pc = self.pc()
            if self._intr == _EXCP_EXCEPTION_EXIT or self._pc >= 0xFFFFFF00:
                self._exception_return(self._pc | 1)
                continue
            if c.stopped:
                continue
            # Unicorn returned by itself: the core executed a WFI outside flash (the counter
            # sleeps in the hook at those in flash), or a fault hook asked it to
            if self._intr is not None:
                raise TwinError(f"the core raised exception {self._intr} (an SVC, BKPT or "
                                f"undefined instruction) in {self.where(self._pc)}")  # fmt: skip
            if self._halfword(self._pc - 2) != _WFI:
                raise TwinError(f"emulation stopped at 0x{self._pc:08X} in "
                                f"{self.where(self._pc)} for no known reason")  # fmt: skip
            if self.on_sleep is not None:
                self.on_sleep(self._pc - 2)
            self._asleep = True

    def _resume(self):
        """What comes after every stop, before the core goes on at self._pc: the events due,
        halted(), the sleep of a WFI, the interrupts pending; None once the counter is armed
        for the next event, else run()'s result."""
        clock = self.clock
        c = self.counter
        clock.fire_due()
        if self._halted():
            return "halted"
        if self._asleep:
            r = self._woken(self._until, self._halted)
            if r != "awake":
                return r
        self._take_pending()
        now = clock.now()
        if now >= self._until:
            return "cycle"
        nxt = clock.next_event()
        target = self._until if nxt is None or nxt > self._until else nxt
        stop = clock.instructions_for(target)
        c.stop_at = stop if stop > c.icount else c.icount + 1
        c.stopped = 0
        self._bad = None
        self._intr = None
        self.nvic.bus.forget_polling()
        return None

    def _go_on(self, at):
        """In a hook: run()'s loop without leaving Unicorn (a return from emu_start and the
        restart cost more than the loop), from self._pc: the core goes on there, or where an
        exception sends it, or emulation stops with run()'s result. `at`: the instruction
        whose code hook this is (the counter's), or None. True when the core does not go on
        at self._pc as it was."""
        pc, taken = self._pc, self.exceptions_taken
        r = self._resume()
        if r is not None:
            self._exit = r
            self.uc.emu_stop()
            return True
        if at is not None and self.exceptions_taken == taken and self._pc == pc:
            return False  # the instruction at `at` runs now
        self._lib.twin_set_pc(self.counter, self._uc_ptr, self._pc | 1)
        return True

    def _on_due(self, _uc, addr):
        """The counter reached the next event before the instruction at addr."""
        try:
            self._pc = addr
            return 1 if self._go_on(addr) else 0
        except BaseException as e:  # noqa: BLE001  (cffi would only print it)
            self.fail(e)
            return 1

    def _on_wfi(self, _uc, addr):
        """The core is about to execute the WFI at addr (counted): it sleeps (run()'s loop
        in the hook) and goes on after it."""
        try:
            self._pc = addr + 2
            if self.on_sleep is not None:
                self.on_sleep(addr)
            self._asleep = True
            self._go_on(None)  # at None: the core goes on past the WFI, never through it
        except BaseException as e:  # noqa: BLE001
            self.fail(e)

    def _woken(self, until_cycle, halted):
        """While the core sleeps in WFI: "awake" once an interrupt wakes it, else why not."""
        r = self._sleep(until_cycle, halted)
        if r == "awake":
            self._asleep = False
        return r

    def _take_error(self):
        e, self._error = self._error, None
        return e

    def _sleep(self, until_cycle, halted):
        """WFI: the clock moves from event to event until one makes an interrupt pending that
        would preempt (PRIMASK aside)."""
        clock = self.clock
        while not self.nvic.wakes():
            nxt = clock.next_event()
            if nxt is None:
                return "asleep"
            t = min(nxt, until_cycle)
            before = clock.now()
            clock.wait_until(t)
            self.sleeping_cycles += clock.now() - before
            if t >= until_cycle and nxt > until_cycle:
                return "cycle"
            clock.fire_due()
            if halted():
                return "halted"
        return "awake"

    def _halfword(self, addr):
        try:
            return int.from_bytes(self.uc.mem_read(addr, 2), "little")
        except UcError:
            return -1

    def _fault(self, e, pc):
        if self._bad is not None:
            kind, addr = self._bad
            return self.nvic.chip.unmapped_error(kind, addr, pc)
        what = "an undefined or unsupported instruction" if e.errno == UC_ERR_EXCEPTION else e
        return TwinError(f"the core faulted ({what}) at 0x{pc:08X} in {self.where(pc)}")

    def _on_unmapped(self, uc, access, address, size, value, _data):
        kinds = {UC_MEM_READ_UNMAPPED: "read", UC_MEM_WRITE_UNMAPPED: "write",
                 UC_MEM_FETCH_UNMAPPED: "fetch"}  # fmt: skip
        self._bad = (kinds.get(access, "access"), address)
        return False

    def _on_intr(self, uc, intno, _data):
        if intno == _EXCP_EXCEPTION_EXIT:  # unstacked here, and the core goes on
            try:
                self._exception_return(self.pc() | 1)
                self._go_on(None)
            except BaseException as e:  # noqa: BLE001
                self.fail(e)
            return
        self._intr = intno
        uc.emu_stop()

    # -- exceptions ---------------------------------------------------------------------

    def _take_pending(self):
        n = self.nvic.take()
        while n is not None:
            self._enter(n)
            n = self.nvic.take()

    def _enter(self, n):
        """Exception entry (counter.c's twin_enter stacks the frame: in C, it is frequent)."""
        err = self._lib.twin_enter(self.counter, self._uc_ptr, self._pc,
                                   n, 0xFFFFFFE1 if self.active else 0xFFFFFFE9)  # fmt: skip
        if err:
            raise TwinError(f"exception {n} could not be stacked (Unicorn error {err}) below SP "
                            f"0x{self.uc.reg_read(A.UC_ARM_REG_SP):08X}")  # fmt: skip
        self.active.append(n)
        self.counter.in_handler = 1
        self.nvic.activate(n)
        self._pc = self.nvic.vector(n) & ~1
        self.exceptions_taken += 1
        self.clock.exception(ENTRY_CYCLES)

    def _exception_return(self, exc_return):
        if not self.active:
            raise TwinError(
                f"a branch to EXC_RETURN 0x{exc_return:08X} outside any exception, from "
                f"{self.where(self.uc.reg_read(A.UC_ARM_REG_LR))}"
            )
        n = self.active.pop()
        beneath = self.active[-1] if self.active else 0
        err = self._lib.twin_return(self.counter, self._uc_ptr, beneath,
                                    self._ret_pc)  # fmt: skip
        if err:
            raise TwinError(f"the frame of exception {n} could not be unstacked (Unicorn error "
                            f"{err})")  # fmt: skip
        self.nvic.deactivate(n)
        self.counter.in_handler = 1 if self.active else 0
        self._pc = self._ret_pc[0] & ~1
        self.clock.exception(RETURN_CYCLES)
