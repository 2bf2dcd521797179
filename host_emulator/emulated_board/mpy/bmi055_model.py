"""The BMI055 register model: both dies of the IMU as its SPI master sees them, the emulated
part every runtime puts on the board's SPI bus (machine.py re-exports it: `machine.Bmi055`,
`machine.GyroDie`, `machine.AccelDie`). Plain Python that runs in the MicroPython VM, frozen on
the emulated Cortex-M4F, and on CPython (firmware_env loads it by file as `bmi055_model`).

- `Bmi055` (both dies, `GyroDie`/`AccelDie`): chip IDs 0xFA (accel) / 0x0F (gyro); range 0x0F
  and bandwidth 0x10 reset values and writable masks; read-only 0x00..0x0E; soft reset (0xB6
  to 0x14) when the chip select rises, then silent for the start-up time (gyro 30 ms, accel
  1.8 ms); data 0x02..0x07 set by the emulator exactly as given (new_data bits included),
  INT_STATUS 0x0A bit 7 set by a new sample and cleared by a data read, the accel axis'
  new_data bit cleared when either of its bytes is read; temperature 0x08. Faults:
  `responds`, `chip_id`, `ignore_writes`. `writes` lists the accepted register writes as
  (reg, value) (start-up only; tests).
- The SPI protocol: an address byte (bit 7 = read), then auto-incremented registers, no dummy
  byte; MISO floats (-1) for the address byte, while the die starts up and when it does not
  respond. A bus drives a die through select(), exchange(mosi) (one byte) or transfer(...)
  (n bytes in one call) and deselect(); machine.SPI routes bytes to the die whose chip select
  is low (`attach`).

The clock: a die times its start-up on `now_us`, a function returning microseconds, given at
construction (`Bmi055(now_us=...)`, `GyroDie(now_us=...)`); by default emulated_board/mpy/time.py's
`time.now_us`, the virtual clock of the board the runtimes emulate. Another emulator with a
clock of its own (a cycle-level STM32F411 model on CPython) passes its own and reuses the
model unchanged. The clock is read only while a die is starting up.

Allocation: what the emulator calls every tick (`set_registers`, `exchange`, `transfer`,
select/deselect) allocates nothing in the MicroPython VM: integer work on the preallocated
register file, index loops (on CPython, where it costs nothing that matters, the burst read of
the data registers goes by slices). Construction allocates.
"""

import sys
import time  # emulated_board/mpy/time.py in the VM and frozen on the emulated Cortex-M4F

# Slices allocate on MicroPython (the firmware's ticks there must not), not on CPython, where
# they are the faster way to move bytes
_SLICES = sys.implementation.name != "micropython"

REG_CHIP_ID = 0x00
REG_DATA = 0x02
REG_TEMP = 0x08
REG_INT_STATUS = 0x0A
REG_RANGE = 0x0F
REG_BW = 0x10
REG_SOFTRESET = 0x14
SOFTRESET_CMD = 0xB6
# (the register file is 0x00..0x7F and 0x00..0x0E ignore writes: literals below, not globals,
# which would grow this module's dict on the emulated Cortex-M4F's heap)


class _Die:
    """One BMI055 die: register file, SPI protocol (address byte, bit 7 = read, then
    auto-incremented registers, no dummy byte), soft reset and start-up time on the clock
    `now_us` (a function returning us; None: emulated_board/mpy/time.py's), faults (`responds`,
    `chip_id`, `ignore_writes`)."""

    name = "die"
    CHIP_ID = 0
    STARTUP_US = 0
    RANGE_RESET = 0
    BW_RESET = 0
    RANGE_MASK = 0xFF
    BW_MASK = 0xFF
    BW_ONES = 0x00
    IS_ACCEL = False

    def __init__(self, chip_id=None, now_us=None):
        self.chip_id = self.CHIP_ID if chip_id is None else chip_id
        self.now_us = time.now_us if now_us is None else now_us  # the clock of the start-up
        self.responds = True
        self.ignore_writes = False
        self.regs = bytearray(0x80)  # registers 0x00..0x7F
        self.resets = 0  # soft resets performed
        self.writes = []  # (reg, value) of every accepted write (the driver writes at start-up)
        self.reads = 0  # register bytes read (not counting the chip ID)
        self.cs = None
        self._ready_at = -1  # now_us() when the start-up after a reset ends; -1 ready
        self._reset_pending = False
        self._selected = False
        self._addr = -1  # -1: the next byte is the address
        self._is_read = False
        self._load_defaults()

    def _load_defaults(self):
        regs = self.regs
        for i in range(0x80):
            regs[i] = 0
        regs[REG_RANGE] = self.RANGE_RESET
        regs[REG_BW] = self.BW_RESET
        regs[REG_CHIP_ID] = self.chip_id & 0xFF

    def busy(self):
        """True while the die is starting up after a soft reset."""
        if self._ready_at < 0:
            return False
        if self.now_us() >= self._ready_at:
            self._ready_at = -1
            return False
        return True

    def read_reg(self, reg):
        """A register as the SPI master reads it (with the read side effects)."""
        reg &= 0x7F
        if reg == REG_CHIP_ID:
            return self.chip_id & 0xFF
        regs = self.regs
        value = regs[reg]
        if REG_DATA <= reg < REG_DATA + 6:
            regs[REG_INT_STATUS] &= 0x7F
            if self.IS_ACCEL:
                regs[REG_DATA + ((reg - REG_DATA) & 0x7E)] &= 0xFE  # the axis' new_data
        self.reads += 1
        return value

    def write_reg(self, reg, value):
        """A register write from the SPI master (masks, read-only registers, soft reset)."""
        reg &= 0x7F
        value &= 0xFF
        if self.ignore_writes or reg < 0x0F:  # 0x00..0x0E: read-only
            return
        self.writes.append((reg, value))
        if reg == REG_SOFTRESET:
            if value == SOFTRESET_CMD:
                self._reset_pending = True
            return
        if reg == REG_RANGE:
            value &= self.RANGE_MASK
        elif reg == REG_BW:
            value = (value & self.BW_MASK) | self.BW_ONES
        self.regs[reg] = value

    def soft_reset(self):
        """What 0xB6 written to 0x14 does when the chip select rises."""
        self.resets += 1
        self._load_defaults()
        if self.STARTUP_US > 0:
            self._ready_at = self.now_us() + self.STARTUP_US

    def set_registers(self, buf, off=0):
        """Data registers 0x02..0x07 = buf[off:off + 6] exactly (new_data bits included);
        sets INT_STATUS bit 7 (data_int)."""
        regs = self.regs  # written out: the emulator's hot path
        d = REG_DATA
        if _SLICES:  # a slice is a heap object on MicroPython; on CPython the cheaper copy
            regs[d : d + 6] = buf[off : off + 6]
            regs[REG_INT_STATUS] |= 0x80
            return
        regs[d] = buf[off]
        regs[d + 1] = buf[off + 1]
        regs[d + 2] = buf[off + 2]
        regs[d + 3] = buf[off + 3]
        regs[d + 4] = buf[off + 4]
        regs[d + 5] = buf[off + 5]
        regs[REG_INT_STATUS] |= 0x80

    def set_temperature_raw(self, raw):
        """Temperature register: int8, 0.5 K per LSB, 0 = 23 degC."""
        if raw < -128 or raw > 127:
            raise ValueError("temperature register is int8")
        self.regs[REG_TEMP] = raw & 0xFF

    # -- SPI device --

    def select(self):
        self._selected = True
        self._addr = -1

    def deselect(self):
        self._selected = False
        self._addr = -1
        if self._reset_pending:
            self._reset_pending = False
            self.soft_reset()

    def exchange(self, mosi):
        """One byte clocked while selected: the MISO byte, or -1 (floating)."""
        if not self.responds or self.busy():
            return -1
        reg = self._addr
        if reg < 0:  # the address byte; MISO undefined meanwhile
            self._is_read = (mosi & 0x80) != 0
            self._addr = mosi & 0x7F
            return -1
        self._addr = (reg + 1) & 0x7F
        if self._is_read:
            return self.read_reg(reg)
        self.write_reg(reg, mosi)
        return -1

    def transfer(self, wbuf, rbuf, fill, n, idle):
        """n bytes clocked while selected, exactly as n calls of `exchange`: MOSI from wbuf
        (None: the byte fill), MISO into rbuf (None: dropped; idle where the die leaves MISO
        floating). No time passes within a transfer, so whether the die answers is decided
        once; the state lives in locals meanwhile (the emulator's hot path)."""
        if not self.responds or (self._ready_at >= 0 and self.busy()):
            if rbuf is not None:
                for i in range(n):
                    rbuf[i] = idle
            return
        reg = self._addr
        is_read = self._is_read
        if _SLICES and reg < 0 and n > 1 and wbuf is not None and rbuf is not None:
            r0 = wbuf[0] & 0x7F
            if wbuf[0] & 0x80 and REG_DATA <= r0 and r0 + n - 1 <= REG_DATA + 6:
                # a burst read of data registers (the driver's every tick) by slices, with
                # read_reg's side effects for them: the byte loop gives the same
                regs = self.regs
                rbuf[0] = idle
                rbuf[1:n] = regs[r0 : r0 + n - 1]
                regs[REG_INT_STATUS] &= 0x7F
                if self.IS_ACCEL:
                    for r in range(r0, r0 + n - 1):
                        regs[REG_DATA + ((r - REG_DATA) & 0x7E)] &= 0xFE
                self.reads += n - 1
                self._addr = (r0 + n - 1) & 0x7F
                self._is_read = True
                return
        for i in range(n):
            mosi = fill if wbuf is None else wbuf[i]
            v = idle
            if reg < 0:  # the address byte
                is_read = (mosi & 0x80) != 0
                reg = mosi & 0x7F
            else:
                if is_read:
                    v = self.read_reg(reg)
                else:
                    self.write_reg(reg, mosi)
                reg = (reg + 1) & 0x7F
            if rbuf is not None:
                rbuf[i] = v
        self._addr = reg
        self._is_read = is_read


class GyroDie(_Die):
    """The gyro die: ID 0x0F, range 0x0F resets to 0x00 (+-2000 deg/s, bits 2:0),
    bandwidth 0x10 to 0x80 (bits 3:0, bit 7 reads 1); 30 ms start-up."""

    name = "bmi055-gyro"
    CHIP_ID = 0x0F
    STARTUP_US = 30000
    RANGE_RESET = 0x00
    BW_RESET = 0x80
    RANGE_MASK = 0x07
    BW_MASK = 0x0F
    BW_ONES = 0x80


class AccelDie(_Die):
    """The accel die: ID 0xFA, range 0x0F resets to 0x03 (+-2 g, bits 3:0), bandwidth 0x10
    to 0x0F (bits 4:0); 1.8 ms start-up."""

    name = "bmi055-accel"
    CHIP_ID = 0xFA
    STARTUP_US = 1800
    RANGE_RESET = 0x03
    BW_RESET = 0x0F
    RANGE_MASK = 0x0F
    BW_MASK = 0x1F
    IS_ACCEL = True


class Bmi055:
    """Both dies of one BMI055 (present=False: neither answers), on the clock `now_us` (a
    function returning us; None: emulated_board/mpy/time.py's `time.now_us`)."""

    def __init__(self, present=True, accel_chip_id=None, gyro_chip_id=None, now_us=None):
        self.accel = AccelDie(accel_chip_id, now_us)
        self.gyro = GyroDie(gyro_chip_id, now_us)
        if not present:
            self.accel.responds = False
            self.gyro.responds = False

    def attach(self, spi, cs_accel, cs_gyro):
        """Put both dies on an SPI bus behind their chip-select pins."""
        spi.attach(self.accel, cs_accel)
        spi.attach(self.gyro, cs_gyro)

    def set_registers(self, buf, gyro_off, accel_off):
        """The next sample: gyro and accel data registers from buf (6 bytes each at the
        offsets, LSB first, as a stimulus record holds them)."""
        self.gyro.set_registers(buf, gyro_off)
        self.accel.set_registers(buf, accel_off)

    def set_temperature_raw(self, raw):
        """int8, 0.5 K per LSB, 0 = 23 degC (both dies). The feed sets it every tick and it
        changes every few seconds at most: unchanged, the dies are not called."""
        if (
            -128 <= raw <= 127
            and self.accel.regs[REG_TEMP] == raw & 0xFF == self.gyro.regs[REG_TEMP]
        ):
            return
        self.accel.set_temperature_raw(raw)
        self.gyro.set_temperature_raw(raw)
