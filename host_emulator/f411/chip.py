"""The emulated STM32F411: the core (cpu.py), its memory, one model per peripheral, the image.

    chip = F411(boards.get("NUCLEO_F411RE"), Image(bin, elf), cpi=(241, 100))
    chip.run(until_cycle)          # also: run_for_ms(ms)

Memory (RM0383 section 2.3): flash 512 KB at 0x08000000 and aliased at 0 (BOOT0 low), SRAM
128 KB at 0x20000000, system memory with the 96-bit unique ID (0x1FFF7A10) and the flash size
(0x1FFF7A22, 512 KB). Stores into flash go to the flash interface's programming model
(flash_if.py). Peripherals: SCS (NVIC, SCB, SysTick), RCC, PWR, FLASH, GPIOA-E/H, SYSCFG,
EXTI, DMA1/2, SPI1, USART1/2/6, IWDG, RTC, USB OTG FS, and SPI2-5 and I2C1-3 only as the soft
reset switches them off (inert.py); everything else of RM0383's map is left unmapped so that an
access to it stops the run, naming it.

Resets: the watchdog (IWDG) or software (SCB_AIRCR.SYSRESETREQ) reset the chip as the board
does: peripherals to their reset values except the backup domain (RTC, RCC_BDCR), the flash and
SRAM kept, RCC_CSR's flags saying why, the core restarting from the vector table.
`on_reset` is told (a run may treat a watchdog reset as a failure).

Observing the image without changing it: `hook(function, fn)` calls fn(chip) when the core is
about to execute that C function (the counter watches its first instruction): the console
(mp_hal_stdout_tx_strn: what MicroPython prints, whichever port it goes to) and the soft
timers' insertion (the firmware's tick timer) are observed so.
"""

import ctypes

from unicorn import UC_HOOK_MEM_WRITE_PROT, UcError
from unicorn import arm_const as A

from host_emulator.f411.bus import Bus, TwinError, block_name
from host_emulator.f411.cpu import Cpu
from host_emulator.f411.dma import Dma
from host_emulator.f411.exti import Exti
from host_emulator.f411.flash_if import FLASH_BASE, FLASH_SIZE, FlashIf
from host_emulator.f411.gpio import Gpio
from host_emulator.f411.inert import BLOCKS as INERT_BLOCKS
from host_emulator.f411.inert import Inert
from host_emulator.f411.iwdg import Iwdg
from host_emulator.f411.nvic import Scs
from host_emulator.f411.pwr import Pwr
from host_emulator.f411.rcc import CSR_IWDGRST, CSR_PINRST, CSR_SFTRST, Rcc
from host_emulator.f411.rtc import Rtc
from host_emulator.f411.spi import Spi
from host_emulator.f411.syscfg import Syscfg
from host_emulator.f411.systick import SysTick
from host_emulator.f411.usart import Usart
from host_emulator.f411.usb_otg import UsbOtgFs

SRAM_BASE, SRAM_SIZE = 0x20000000, 128 * 1024
SYSMEM_BASE, SYSMEM_SIZE = 0x1FFF0000, 0x8000
UID_ADDR = 0x1FFF7A10
FLASH_SIZE_ADDR = 0x1FFF7A22
DEFAULT_UID = bytes.fromhex("3a0035000f51353338363636")  # the twin's unique ID


class F411:
    def __init__(self, board, image, cpi=(241, 100), uid=DEFAULT_UID):
        self.board = board
        self.image = image
        self.cpu = Cpu(cpi)
        self.clock = self.cpu.clock
        self.cpu.where = self.where
        self.irq_sources = {}  # IRQ number -> fn() -> bool, the level of its line
        self.on_reset = []  # fn(reason) after a reset
        self.resets = []  # (cycle, reason)
        self._reset_request = None
        uc = self.cpu.uc
        self.cpu.map_flash(FLASH_BASE, FLASH_SIZE)
        uc.mem_map(SRAM_BASE, SRAM_SIZE)
        uc.mem_map(SYSMEM_BASE, SYSMEM_SIZE, 1)  # read only
        uc.mem_write(UID_ADDR, uid)
        uc.mem_write(FLASH_SIZE_ADDR, (FLASH_SIZE // 1024).to_bytes(2, "little"))
        uc.hook_add(UC_HOOK_MEM_WRITE_PROT, self.cpu.guarded(self._flash_store))

        self.bus = Bus(self)
        add = self.bus.add
        self.scs = add(Scs(self))
        self.scs.systick = SysTick(self.scs)
        self.cpu.nvic = self.scs
        self.rcc = add(Rcc(self))
        self.pwr = add(Pwr(self))
        self.flash_if = add(FlashIf(self))
        self.gpio = {p: add(Gpio(self, p)) for p in "ABCDEH"}
        self.syscfg = add(Syscfg(self))
        self.exti = add(Exti(self))
        self.dma1 = add(Dma(self, 1))
        self.dma2 = add(Dma(self, 2))
        self.spi1 = add(Spi(self))
        self.usart = {n: add(Usart(self, n)) for n in (1, 2, 6)}
        self.iwdg = add(Iwdg(self))
        self.rtc = add(Rtc(self))
        self.usb = add(UsbOtgFs(self))
        for name, base, size in INERT_BLOCKS:
            add(Inert(self, name, base, size))
        self.bus.map_bitband()
        self.rcc.resets.update({
            (0x10, 0): self.gpio["A"], (0x10, 1): self.gpio["B"], (0x10, 2): self.gpio["C"],
            (0x10, 21): self.dma1, (0x10, 22): self.dma2, (0x14, 7): self.usb,
            (0x20, 17): self.usart[2], (0x24, 4): self.usart[1], (0x24, 5): self.usart[6],
            (0x24, 12): self.spi1, (0x24, 14): self.syscfg,
        })  # fmt: skip
        self._usart_dma = {(2, 4, self.usart[1].BASE + 4): self.usart[1],
                           (2, 5, self.usart[6].BASE + 4): self.usart[6],
                           (1, 4, self.usart[2].BASE + 4): self.usart[2]}  # fmt: skip
        for irq in (6, 7, 8, 9, 10, 23, 40):
            self.irq_sources[irq] = lambda irq=irq: self.exti.irq_level(irq)
        self._wire_board()

        self._load(image)
        self.cpu.reset(0)

    # -- set-up -------------------------------------------------------------------------

    def _wire_board(self):
        port, pin = self.board.button
        self.gpio[port].drive(pin, 1)  # released

    def pin(self, name):
        """(gpio model, pin number) of "B6"."""
        return self.gpio[name[0]], int(name[1:])

    def _load(self, image):
        ctypes.memmove(self.cpu._flash_buf, image.data, len(image.data))
        self.cpu.set_code_map(FLASH_BASE, image.category_map(), image.sync_map())

    def hook(self, function, fn):
        """fn(chip) each time the core is about to execute C function `function`."""
        self.cpu.watch(self.image.address(function) & ~1, lambda: fn(self))

    def reg(self, n):
        return self.cpu.uc.reg_read(A.UC_ARM_REG_R0 + n)

    # -- memory -------------------------------------------------------------------------

    def read_word(self, addr):
        return self.cpu.read_word(addr)

    def read_memory(self, addr, n):
        try:
            return bytes(self.cpu.uc.mem_read(addr, n))
        except UcError:
            raise TwinError(f"DMA read of {n} bytes at 0x{addr:08X}: no memory there") from None

    def write_memory(self, addr, data):
        if not SRAM_BASE <= addr and addr + len(data) <= SRAM_BASE + SRAM_SIZE:
            raise TwinError(f"DMA write of {len(data)} bytes at 0x{addr:08X}: not in SRAM")
        self.cpu.uc.mem_write(addr, bytes(data))

    def flash_read(self, address, size):
        off = address - FLASH_BASE if address >= FLASH_BASE else address
        return bytes(self.cpu._flash_buf[off : off + size])

    def flash_fill(self, base, size, value):
        off = base - FLASH_BASE
        ctypes.memset(ctypes.addressof(self.cpu._flash_buf) + off, value, size)
        for a in (base, off):
            self.cpu.uc.ctl_remove_cache(a, a + size)

    def flash_bytes(self, base, size):
        return self.flash_read(base, size)

    def flash_write_raw(self, base, data):
        """Put bytes into flash as a programmer would (before the run: the filesystem)."""
        off = base - FLASH_BASE
        ctypes.memmove(ctypes.addressof(self.cpu._flash_buf) + off, bytes(data), len(data))

    def _flash_store(self, uc, access, address, size, value, _data):
        if FLASH_BASE <= address < FLASH_BASE + FLASH_SIZE or address < FLASH_SIZE:
            a = address if address >= FLASH_BASE else address + FLASH_BASE
            self.flash_if.program(a, size, value)
            off = a - FLASH_BASE
            for i in range(size):
                self.cpu._flash_buf[off + i] = (value >> (8 * i)) & 0xFF
            return True
        return False

    # -- DMA routing (dma.py) -----------------------------------------------------------

    def dma_target(self, dma, channel, par, direction):
        """(kind, peripheral) of a stream's transfer, or None: SPI1 on DMA2 channel 3, a
        USART's transmission on DMA2 channel 4 (USART1), 5 (USART6), DMA1 channel 4
        (USART2)."""
        if dma == 2 and channel == 3 and par == self.spi1.BASE + 0x0C:
            return ("spi_rx", self.spi1) if direction == 0 else ("spi_tx", self.spi1)
        u = self._usart_dma.get((dma, channel, par))
        return ("usart_tx", u) if u is not None and direction == 1 else None

    def clocks_changed(self):
        pass

    # -- errors -------------------------------------------------------------------------

    def where(self, pc=None):
        return self.image.where(self.cpu.pc() if pc is None else pc)

    def unmodelled(self, kind, address, name):
        raise TwinError(f"{kind} of {name} (0x{address:08X}), a register the twin does not "
                        f"model, in {self.where()}")  # fmt: skip

    def unmapped_error(self, kind, address, pc):
        block = block_name(address)
        what = f"{block} (not modelled by the twin)" if block else "nothing on the F411"
        return TwinError(f"{kind} at 0x{address:08X}: {what}, in {self.where(pc)}")

    def unsupported(self, what):
        raise TwinError(f"{what}: not modelled by the twin, in {self.where()}")

    # -- resets -------------------------------------------------------------------------

    def request_reset(self, reason, watchdog=False):
        self._reset_request = (reason, watchdog)
        self.cpu.stop_soon()

    def _do_reset(self):
        reason, watchdog = self._reset_request
        self._reset_request = None
        self.resets.append((self.clock.now(), reason))
        flags = CSR_PINRST | (CSR_IWDGRST if watchdog else CSR_SFTRST)
        for p in self.bus.peripherals:
            for e in getattr(p, "streams", ()):
                e.abort()
            p.reset()
        self.scs.systick.reset()
        self.rcc.reset_flags |= flags
        self.clock.set_hz(16_000_000)
        self._wire_board()
        self.cpu.reset(0)
        for fn in self.on_reset:
            fn(reason)

    # -- running ------------------------------------------------------------------------

    def run(self, until_cycle, halted=lambda: False):
        """Run until the clock reaches until_cycle or halted(); "cycle", "halted" or
        "asleep"."""
        while True:
            r = self.cpu.run(until_cycle, lambda: self._reset_request is not None or halted())
            if self._reset_request is not None:
                self._do_reset()
                continue
            return r

    def run_for_ms(self, ms, halted=lambda: False):
        return self.run(self.clock.now() + self.clock.cycles_for_us(int(ms * 1000)), halted)
