"""The system control space of the Cortex-M4 (0xE000E000-0xE000EFFF): NVIC, SCB, SysTick's
registers (systick.py has its model), the software trigger, the FPU's control registers.

Exception priorities as ARMv7-M (B1.5.4): exception numbers 1-3 fixed (reset -3, NMI -2,
HardFault -1), the rest from SHPR1-3 (system handlers) and NVIC_IPR (interrupts, IRQ n =
exception 16 + n); the STM32F411 implements the top 4 bits of each priority byte and 86
interrupts (RM0383 table 37). AIRCR.PRIGROUP splits a priority into group (preemption) and
subpriority. The execution priority is the group priority of the highest-priority active
exception, lowered to 0 by PRIMASK and to BASEPRI's group priority when that is higher; a
pending exception is taken when its group priority is higher (numerically lower) than the
execution priority; among several, the lowest priority value, then the lowest number.
"""

from host_emulator.f411.bus import Peripheral

N_IRQ = 86
PENDSV = 14
SYSTICK = 15
_IMPL = 0xF0  # implemented priority bits
ICSR_PENDSVSET = 1 << 28
ICSR_PENDSVCLR = 1 << 27
ICSR_PENDSTSET = 1 << 26
ICSR_PENDSTCLR = 1 << 25


def _regs():
    r = [
        ("ICTR", 0x004, 0x2, 0),
        ("ACTLR", 0x008, 0),
        ("STK_CTRL", 0x010, 0x4),  # CLKSOURCE resets to 1 on the STM32 (HCLK)
        ("STK_LOAD", 0x014, 0, 0x00FFFFFF),
        ("STK_VAL", 0x018, 0),
        ("STK_CALIB", 0x01C, 0x40002EDF, 0),  # RM0383 / PM0214: TENMS for 12 MHz / 8
        ("CPUID", 0xD00, 0x410FC241, 0),
        ("ICSR", 0xD04, 0),
        ("VTOR", 0xD08, 0, 0xFFFFFF80),
        ("AIRCR", 0xD0C, 0xFA050000),
        ("SCR", 0xD10, 0, 0x16),
        ("CCR", 0xD14, 0x200, 0x31B),
        ("SHPR1", 0xD18, 0, 0x00F0F0F0),
        ("SHPR2", 0xD1C, 0, 0xF0000000),
        ("SHPR3", 0xD20, 0, 0xF0F00000),
        ("SHCSR", 0xD24, 0, 0x70000),
        ("CFSR", 0xD28, 0),
        ("HFSR", 0xD2C, 0),
        ("DFSR", 0xD30, 0),
        ("MMFAR", 0xD34, 0),
        ("BFAR", 0xD38, 0),
        ("AFSR", 0xD3C, 0),
        ("CPACR", 0xD88, 0, 0x00F00000),
        ("DEMCR", 0xDFC, 0, 0x010F07F1),
        ("STIR", 0xF00, 0),
        ("FPCCR", 0xF34, 0xC0000000, 0xC0000000),
        ("FPCAR", 0xF38, 0, 0xFFFFFFF8),
        ("FPDSCR", 0xF3C, 0, 0x07C00000),
    ]
    for i in range(3):  # 86 interrupts: three words of enable/pending/active bits
        r += [(f"ISER{i}", 0x100 + 4 * i, 0), (f"ICER{i}", 0x180 + 4 * i, 0),
              (f"ISPR{i}", 0x200 + 4 * i, 0), (f"ICPR{i}", 0x280 + 4 * i, 0),
              (f"IABR{i}", 0x300 + 4 * i, 0, 0)]  # fmt: skip
    for i in range((N_IRQ + 3) // 4):
        r.append((f"IPR{i}", 0x400 + 4 * i, 0, 0xF0F0F0F0))
    return tuple(r)


class Scs(Peripheral):
    NAME = "SCS"
    BASE = 0xE000E000
    SIZE = 0x1000
    REGISTERS = _regs()

    def __init__(self, chip):
        self.pending = set()  # exception numbers
        self.enabled = set()  # IRQ numbers (exceptions 16+)
        self.active = set()
        super().__init__(chip)
        self.bus = chip.bus
        self.systick = None

    def reset(self):
        super().reset()
        self.pending.clear()
        self.enabled.clear()
        self.active.clear()

    # -- the CPU asks -------------------------------------------------------------------

    def priority(self, n):
        if n <= 3:
            return (-3, -2, -1)[n - 1]
        if n < 16:
            reg = 0xD18 + ((n - 4) // 4) * 4
            return (self.v[reg] >> (8 * ((n - 4) % 4))) & 0xFF
        irq = n - 16
        return (self.v[0x400 + (irq // 4) * 4] >> (8 * (irq % 4))) & 0xFF

    def group(self, prio):
        if prio < 0:
            return prio
        prigroup = (self.v[0xD0C] >> 8) & 7
        return prio & ~((2 << prigroup) - 1) & 0xFF

    def _candidate(self):
        """The pending exception that would be taken first (enabled), or None."""
        best = None
        for n in self.pending:
            if n >= 16 and (n - 16) not in self.enabled:
                continue
            key = (self.priority(n), n)
            if best is None or key < best[0]:
                best = (key, n)
        return best

    def execution_priority(self, primask, basepri, with_primask=True):
        ep = 256
        for n in self.chip.cpu.active:
            ep = min(ep, self.group(self.priority(n)))
        if basepri & _IMPL:
            ep = min(ep, self.group(basepri & _IMPL))
        if primask and with_primask:
            ep = min(ep, 0)
        return ep

    def take(self):
        """The exception to take now, or None; updates the counter's irq_pending flag."""
        cpu = self.chip.cpu
        best = self._candidate() if self.pending else None  # most stops: nothing pending
        if best is None:
            cpu.counter.irq_pending = 0
            return None
        primask, basepri = cpu.masks()
        (prio, n) = best[0][0], best[1]
        if self.group(prio) < self.execution_priority(primask, basepri):
            cpu.counter.irq_pending = 0
            return n
        cpu.counter.irq_pending = 1  # masked: the counter stops after CPSIE / MSR
        return None

    def wakes(self):
        """WFI ends: a pending exception would preempt if PRIMASK were clear."""
        best = self._candidate()
        if best is None:
            return False
        primask, basepri = self.chip.cpu.masks()
        return self.group(best[0][0]) < self.execution_priority(primask, basepri, False)

    def activate(self, n):
        self.pending.discard(n)
        self.active.add(n)

    def deactivate(self, n):
        self.active.discard(n)

    def vector(self, n):
        return self.chip.read_word(self.v[0xD08] + 4 * n)

    def set_pending(self, n):
        """Exception n pending (a peripheral's interrupt line, SysTick, PendSV)."""
        if n not in self.pending:
            self.pending.add(n)
            if n < 16 or (n - 16) in self.enabled:
                self.chip.cpu.stop_soon()

    def irq(self, irq):
        self.set_pending(16 + irq)

    # -- registers ----------------------------------------------------------------------

    def _bits(self, base_exc, word):
        return {base_exc + 32 * word + b for b in range(32)}

    def _word_of(self, numbers, word, offset=16):
        v = 0
        for b in range(32):
            if offset + 32 * word + b in numbers:
                v |= 1 << b
        return v

    def read_STK_CTRL(self):
        return self.systick.read_ctrl()

    def write_STK_CTRL(self, value):
        self.systick.write_ctrl(value)

    def read_STK_VAL(self):
        return self.systick.read_val()

    def write_STK_VAL(self, value):
        self.systick.write_val()

    def write_STK_LOAD(self, value):
        self.v[0x014] = value & 0x00FFFFFF
        self.systick.reload_changed()

    def read_ICSR(self):
        v = 0
        cpu = self.chip.cpu
        if cpu.active:
            v |= cpu.active[-1] & 0x1FF
        if len(cpu.active) <= 1:
            v |= 1 << 11  # RETTOBASE
        best = self._candidate()
        if best is not None:
            v |= (best[1] & 0x1FF) << 12
            if best[1] >= 16:
                v |= 1 << 22  # ISRPENDING
        if PENDSV in self.pending:
            v |= ICSR_PENDSVSET
        if SYSTICK in self.pending:
            v |= ICSR_PENDSTSET
        return v

    def write_ICSR(self, value):
        if value & ICSR_PENDSVSET:
            self.set_pending(PENDSV)
        if value & ICSR_PENDSVCLR:
            self.pending.discard(PENDSV)
        if value & ICSR_PENDSTSET:
            self.set_pending(SYSTICK)
        if value & ICSR_PENDSTCLR:
            self.pending.discard(SYSTICK)
        if value & (1 << 31):
            self.chip.unsupported("SCB_ICSR.NMIPENDSET")

    def write_AIRCR(self, value):
        if (value >> 16) != 0x05FA:
            return  # without the key the write is ignored
        if value & (1 << 2):  # SYSRESETREQ
            self.chip.request_reset("SYSRESETREQ (NVIC_SystemReset)")
            return
        self.v[0xD0C] = 0xFA050000 | (value & 0x0700)

    def write_SCR(self, value):
        if value & 0x6:  # SLEEPDEEP, SLEEPONEXIT
            self.chip.unsupported(f"deep sleep / sleep-on-exit (SCB_SCR 0x{value:X})")
        self.v[0xD10] = value & 0x16

    def write_STIR(self, value):
        self.irq(value & 0x1FF)

    def write_CPACR(self, value):
        self.v[0xD88] = value & 0x00F00000  # CP10/CP11: Unicorn's FPU is always on

    def write_FPCCR(self, value):
        self.v[0xF34] = value & 0xC0000000  # ASPEN/LSPEN: the twin stacks the FP frame always


def _make_irq_accessors():
    def iser_read(i):
        return lambda self: self._word_of({16 + n for n in self.enabled}, i)

    def iser_write(i):
        def w(self, value):
            for b in range(32):
                if value >> b & 1:
                    irq = 32 * i + b
                    if irq < N_IRQ:
                        self.enabled.add(irq)
                        if 16 + irq in self.pending:
                            self.chip.cpu.stop_soon()

        return w

    def icer_write(i):
        def w(self, value):
            for b in range(32):
                if value >> b & 1:
                    self.enabled.discard(32 * i + b)

        return w

    def ispr_read(i):
        return lambda self: self._word_of(self.pending, i)

    def ispr_write(i):
        def w(self, value):
            for b in range(32):
                if value >> b & 1 and 32 * i + b < N_IRQ:
                    self.irq(32 * i + b)

        return w

    def icpr_write(i):
        def w(self, value):
            for b in range(32):
                if value >> b & 1:
                    self.pending.discard(16 + 32 * i + b)

        return w

    def iabr_read(i):
        return lambda self: self._word_of(self.active, i)

    for i in range(3):
        setattr(Scs, f"read_ISER{i}", iser_read(i))
        setattr(Scs, f"read_ICER{i}", iser_read(i))
        setattr(Scs, f"write_ISER{i}", iser_write(i))
        setattr(Scs, f"write_ICER{i}", icer_write(i))
        setattr(Scs, f"read_ISPR{i}", ispr_read(i))
        setattr(Scs, f"read_ICPR{i}", ispr_read(i))
        setattr(Scs, f"write_ISPR{i}", ispr_write(i))
        setattr(Scs, f"write_ICPR{i}", icpr_write(i))
        setattr(Scs, f"read_IABR{i}", iabr_read(i))


_make_irq_accessors()
