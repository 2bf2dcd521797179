"""The virtual board's backup domain: a stand-in for the stm32 port's `stm.mem32` over the
registers the firmware's maintenance start uses (firmware/board.py, tools/flash/
maintenance.py), for the virtual board's two MicroPython VMs (host_emulator/virtual_board):
the REPL's, where the board tools write the marker and reset the board, and the firmware's,
where main.py's check (board.maintenance_start) reads it at the next start.

    RTC_BKP0R-19R   in a file of 80 bytes (20 words, little-endian) both VMs open: it outlives
                    a VM as the chip's backup domain outlives a reset; zeros at power-on
    PWR_CR          the VM's own (a reset, a new VM, clears it): DBP, bit 8, and the rest
                    stored; reads 0 and ignores writes while RCC_APB1ENR.PWREN is clear
    RCC_APB1ENR     the VM's own, PWREN set (the port's start-up enables the PWR clock)

As on the chip, a backup register written while PWR_CR.DBP is clear keeps its value (the
port itself sets DBP at start-up when its RTC runs; here it starts clear, so that code which
does not set it fails here too). An address that is not 4-aligned raises the port's
ValueError; any other address raises ValueError (the virtual board has no other hardware to
reach), never reads 0 as a register would. Values are unsigned 32-bit, as mem32 gives them.
"""

RTC_BKP0R = 0x40002850
N_BKP = 20
PWR_CR = 0x40007000
DBP = 0x100
RCC_APB1ENR = 0x40023840
PWREN = 0x10000000


class Mem32:
    def __init__(self, path):
        self.path = path
        self.pwr_cr = 0x8000  # reset value (VOS)
        self.apb1enr = PWREN

    def _check(self, addr):
        if addr & 3:
            raise ValueError(f"address {addr:08x} is not aligned to 4 bytes")
        if RTC_BKP0R <= addr < RTC_BKP0R + 4 * N_BKP:
            return addr - RTC_BKP0R
        if addr == PWR_CR or addr == RCC_APB1ENR:
            return -1
        raise ValueError(
            f"the virtual board's stm.mem32 has no register at {addr:08x} (it has the RTC "
            "backup registers, PWR_CR and RCC_APB1ENR)"
        )

    def __getitem__(self, addr):
        off = self._check(addr)
        if off >= 0:
            f = open(self.path, "rb")
            f.seek(off)
            b = f.read(4)
            f.close()
            return int.from_bytes(b, "little")
        if addr == RCC_APB1ENR:
            return self.apb1enr
        return self.pwr_cr if self.apb1enr & PWREN else 0

    def __setitem__(self, addr, value):
        off = self._check(addr)
        value &= 0xFFFFFFFF
        if off >= 0:
            if self.pwr_cr & DBP:
                f = open(self.path, "r+b")
                f.seek(off)
                f.write(value.to_bytes(4, "little"))
                f.close()
        elif addr == RCC_APB1ENR:
            self.apb1enr = value
        elif self.apb1enr & PWREN:
            self.pwr_cr = value & 0xCFFF


def power_on(path):
    """The backup domain at power-on (no battery): every register 0."""
    f = open(path, "wb")
    f.write(bytes(4 * N_BKP))
    f.close()


class Stm:
    """The `stm` module the virtual board's REPL VM imports: mem32 over the registers above,
    and the constants of theirs the port's module has (addresses of blocks, offsets)."""

    RTC = 0x40002800
    PWR = 0x40007000
    PWR_CR = 0x00
    RCC = 0x40023800
    RCC_APB1ENR = 0x40

    def __init__(self, path):
        self.mem32 = Mem32(path)
        for i in range(N_BKP):
            setattr(self, f"RTC_BKP{i}R", 0x50 + 4 * i)


def maintenance_start(path):
    """main.py's first step, the firmware's board.maintenance_start, on the backup domain in
    file `path` (the virtual board's firmware VM): True for a maintenance start (its console
    line printed by it, which the virtual board passes on). A firmware without the check
    (older than it) starts normally."""
    import board

    check = getattr(board, "maintenance_start", None)
    return check is not None and check(Mem32(path))
