"""Register model of a Bosch BMI055 (two dies, accel and gyro), as seen over SPI.

Each die is an SPI device for `board/cpython/spi.FakeSPI` (select / exchange / deselect): the first
byte after chip select is the address, bit 7 set for a read; the following bytes are read
from (or written to) auto-incremented addresses. No dummy byte.

    model = Bmi055Model()                      # or Bmi055Model(clock_ms=clock) for timing
    model.attach(spi, cs_accel, cs_gyro)
    model.set_sample(gyro_counts, accel_counts)   # every tick, before the firmware reads
    model.set_temperature_raw(4)               # int8, 0.5 K per LSB, 0 = 23 degC

What is modelled (facts: DESIGN.md 7, Bosch datasheet figures as public drivers use them):
- chip ID at 0x00 (accel 0xFA, gyro 0x0F); read-only registers 0x00..0x0E ignore writes.
- data 0x02..0x07 (X, Y, Z; LSB first): gyro int16 counts; accel 12-bit counts
  left-justified (`counts << 4`), bit 0 of each LSB = new_data, set by a new sample and
  cleared when either byte of that axis is read. INT_STATUS 0x0A bit 7 (data_int) is set by
  a new sample and cleared when any data register is read (a simplification of the chip's
  interrupt logic, enough for polling).
- temperature 0x08 on both dies (int8, 0.5 K per LSB, 0 = 23 degC).
- range 0x0F and bandwidth 0x10 with their reset values (accel 0x03 / 0x0F: +-2 g, 1000 Hz;
  gyro 0x00 / 0x80: +-2000 deg/s, unfiltered) and reserved bits (accel range keeps bits
  3:0, accel bandwidth 4:0, gyro range 2:0, gyro bandwidth 3:0 with bit 7 reading 1).
  Other registers are plain storage that resets to 0x00.
- soft reset: writing 0xB6 to 0x14 (write-only, reads 0x00) resets the die when its chip
  select rises: registers to their reset values, data and new-data bits cleared. With a
  clock (`clock_ms`, a function returning milliseconds) the die then stays silent for its
  start-up time (gyro 30 ms, accel 1.8 ms): MISO floats and writes are lost, so a driver
  that does not wait fails as it would on the board. Without a clock the reset is instant.

Faults (attributes of each die, or constructor options of the model):
- `responds = False`: the die is dead or not selected (MISO floats: the bus reads its idle
  level, 0xFF with a pull-up or 0x00; FakeSPI(miso_idle=...)); `Bmi055Model(present=False)`
  sets it on both dies (no chip, no power).
- `chip_id = 0x..`: a wrong part answers (`Bmi055Model(accel_chip_id=..., gyro_chip_id=...)`).
- `ignore_writes = True`: reads work but writes never arrive (broken MOSI).
"""

GYRO_COUNT_MIN, GYRO_COUNT_MAX = -32768, 32767
ACCEL_COUNT_MIN, ACCEL_COUNT_MAX = -2048, 2047

REG_CHIP_ID = 0x00
REG_DATA = 0x02
REG_TEMP = 0x08
REG_INT_STATUS = 0x0A
REG_RANGE = 0x0F
REG_BW = 0x10
REG_SOFTRESET = 0x14
SOFTRESET_CMD = 0xB6
_READ = 0x80
_N_REGS = 0x80  # 7-bit address space
_READ_ONLY_END = 0x0F  # 0x00..0x0E: ID, data, temperature, status

GYRO_RANGE_DPS = {0: 2000, 1: 1000, 2: 500, 3: 250, 4: 125}  # code -> deg/s
ACCEL_RANGE_G = {0x03: 2, 0x05: 4, 0x08: 8, 0x0C: 16}  # code -> g
GYRO_BW = {  # code -> (ODR Hz, filter bandwidth Hz)
    0: (2000, 523),
    1: (2000, 230),
    2: (1000, 116),
    3: (400, 47),
    4: (200, 23),
    5: (100, 12),
    6: (200, 64),
    7: (100, 32),
}
ACCEL_BW_HZ = {  # code -> filter bandwidth Hz (data update rate = 2x)
    0x08: 7.81,
    0x09: 15.63,
    0x0A: 31.25,
    0x0B: 62.5,
    0x0C: 125.0,
    0x0D: 250.0,
    0x0E: 500.0,
    0x0F: 1000.0,
}


class _Die:
    """One die: register file, SPI protocol, soft reset, faults."""

    name = "die"
    CHIP_ID = 0
    STARTUP_MS = 0.0
    DEFAULTS = {}  # reg -> reset value (others 0x00)
    MASKS = {}  # reg -> (writable bits, bits that always read 1)

    def __init__(self, clock_ms=None, chip_id=None):
        self.clock_ms = clock_ms
        self.chip_id = self.CHIP_ID if chip_id is None else chip_id
        self.responds = True
        self.ignore_writes = False
        self.regs = bytearray(_N_REGS)
        self.counts = (0, 0, 0)
        self.resets = 0  # soft resets performed
        self.writes = []  # (reg, value) of every accepted write, for tests
        self.reads = 0  # register bytes read
        self._ready_at = None
        self._reset_pending = False
        self._selected = False
        self._addr = None
        self._is_read = False
        self._load_defaults()

    # -- register file --

    def _load_defaults(self):
        self.regs[:] = bytes(_N_REGS)
        for reg, value in self.DEFAULTS.items():
            self.regs[reg] = value
        self.regs[REG_CHIP_ID] = self.chip_id
        self.counts = (0, 0, 0)

    def busy(self):
        """True while the die is starting up after a soft reset (needs a clock)."""
        if self._ready_at is None or self.clock_ms is None:
            return False
        if self.clock_ms() >= self._ready_at:
            self._ready_at = None
            return False
        return True

    def read_reg(self, reg):
        """A register as the SPI master reads it (with read side effects)."""
        reg &= 0x7F
        if reg == REG_CHIP_ID:
            return self.chip_id & 0xFF
        value = self.regs[reg]
        if REG_DATA <= reg < REG_DATA + 6:
            self._data_read(reg)
        self.reads += 1
        return value

    def _data_read(self, reg):
        self.regs[REG_INT_STATUS] &= 0x7F

    def write_reg(self, reg, value):
        """A register write from the SPI master."""
        reg &= 0x7F
        value &= 0xFF
        if self.ignore_writes or reg < _READ_ONLY_END:
            return
        self.writes.append((reg, value))
        if reg == REG_SOFTRESET:
            if value == SOFTRESET_CMD:
                self._reset_pending = True
            return
        mask, ones = self.MASKS.get(reg, (0xFF, 0x00))
        self.regs[reg] = (value & mask) | ones

    def soft_reset(self):
        """What writing 0xB6 to 0x14 does (when the chip select rises)."""
        self.resets += 1
        self._load_defaults()
        if self.clock_ms is not None and self.STARTUP_MS > 0:
            self._ready_at = self.clock_ms() + self.STARTUP_MS

    # -- samples --

    def set_temperature_raw(self, raw):
        if not -128 <= raw <= 127:
            raise ValueError(f"temperature register is int8, got {raw}")
        self.regs[REG_TEMP] = raw & 0xFF

    def set_counts(self, counts):
        lo, hi = self.COUNT_RANGE
        xyz = tuple(int(c) for c in counts)
        if len(xyz) != 3 or not all(lo <= c <= hi for c in xyz):
            raise ValueError(f"{self.name} counts must be 3 ints in {lo}..{hi}, got {counts!r}")
        self.counts = xyz
        for i, c in enumerate(xyz):
            lsb, msb = self._encode(c)
            self.regs[REG_DATA + 2 * i] = lsb
            self.regs[REG_DATA + 2 * i + 1] = msb
        self.regs[REG_INT_STATUS] |= 0x80

    def set_registers(self, data6):
        """The data registers 0x02..0x07 exactly as given (a recorded or simulated sample,
        new_data bits included); sets data_int. `counts` is then None (not decoded here: this
        runs every tick of an emulation)."""
        self.regs[REG_DATA : REG_DATA + 6] = data6
        self.counts = None
        self.regs[REG_INT_STATUS] |= 0x80

    # -- SPI device --

    def select(self):
        self._selected = True
        self._addr = None

    def deselect(self):
        self._selected = False
        self._addr = None
        if self._reset_pending:
            self._reset_pending = False
            self.soft_reset()

    def exchange(self, mosi):
        """One byte clocked while selected: returns MISO, or None (floating)."""
        if not self.responds or self.busy():
            return None
        if self._addr is None:  # the address byte; MISO undefined meanwhile
            self._is_read = bool(mosi & _READ)
            self._addr = mosi & 0x7F
            return None
        reg = self._addr
        self._addr = (reg + 1) & 0x7F
        if self._is_read:
            return self.read_reg(reg)
        self.write_reg(reg, mosi)
        return None


class GyroDie(_Die):
    name = "bmi055-gyro"
    CHIP_ID = 0x0F
    STARTUP_MS = 30.0
    DEFAULTS = {REG_RANGE: 0x00, REG_BW: 0x80}
    MASKS = {REG_RANGE: (0x07, 0x00), REG_BW: (0x0F, 0x80)}
    COUNT_RANGE = (GYRO_COUNT_MIN, GYRO_COUNT_MAX)

    @staticmethod
    def _encode(c):
        w = c & 0xFFFF
        return w & 0xFF, w >> 8

    @property
    def range_dps(self):
        """Configured range in deg/s (None for a reserved code)."""
        return GYRO_RANGE_DPS.get(self.regs[REG_RANGE] & 0x07)

    @property
    def bw(self):
        """(ODR Hz, filter bandwidth Hz) configured (None for a reserved code)."""
        return GYRO_BW.get(self.regs[REG_BW] & 0x0F)


class AccelDie(_Die):
    name = "bmi055-accel"
    CHIP_ID = 0xFA
    STARTUP_MS = 1.8
    DEFAULTS = {REG_RANGE: 0x03, REG_BW: 0x0F}
    MASKS = {REG_RANGE: (0x0F, 0x00), REG_BW: (0x1F, 0x00)}
    COUNT_RANGE = (ACCEL_COUNT_MIN, ACCEL_COUNT_MAX)

    @staticmethod
    def _encode(c):
        w = (c & 0xFFF) << 4 | 0x01  # new_data
        return w & 0xFF, w >> 8

    def _data_read(self, reg):
        super()._data_read(reg)
        self.regs[REG_DATA + ((reg - REG_DATA) & ~1)] &= 0xFE  # the axis' new_data bit

    @property
    def range_g(self):
        """Configured range in g (None for a reserved code)."""
        return ACCEL_RANGE_G.get(self.regs[REG_RANGE] & 0x0F)

    @property
    def bw_hz(self):
        """Configured filter bandwidth, Hz (codes below 0x08 mean 7.81, above 0x0F 1000)."""
        code = self.regs[REG_BW] & 0x1F
        return ACCEL_BW_HZ[min(max(code, 0x08), 0x0F)]


class Bmi055Model:
    """Both dies of one BMI055.

    clock_ms: None (soft reset is instant) or a function returning the time in ms, to model
        the start-up time after a soft reset.
    present: False for no chip at all (neither die answers).
    accel_chip_id, gyro_chip_id: what register 0x00 reads (a wrong part).
    """

    def __init__(self, clock_ms=None, present=True, accel_chip_id=None, gyro_chip_id=None):
        self.accel = AccelDie(clock_ms, accel_chip_id)
        self.gyro = GyroDie(clock_ms, gyro_chip_id)
        if not present:
            self.accel.responds = False
            self.gyro.responds = False

    def attach(self, spi, cs_accel, cs_gyro):
        """Put both dies on a FakeSPI bus behind their chip-select FakePins."""
        spi.attach(self.accel, cs_accel)
        spi.attach(self.gyro, cs_gyro)

    def set_sample(self, gyro_counts, accel_counts):
        """The next sample: gyro int16 counts and accel 12-bit counts (x, y, z), as
        host_emulator.sim.imu produces them; sets the new-data bits."""
        self.gyro.set_counts(gyro_counts)
        self.accel.set_counts(accel_counts)

    def set_registers(self, gyro6, accel6):
        """The next sample as data-register bytes (a stimulus record: host_emulator.stimulus)."""
        self.gyro.set_registers(gyro6)
        self.accel.set_registers(accel6)

    def set_temperature_raw(self, raw):
        """int8: 0.5 K per LSB, 0 = 23 degC (both dies)."""
        self.accel.set_temperature_raw(raw)
        self.gyro.set_temperature_raw(raw)

    def set_temperature_c(self, deg_c):
        """Nearest raw value to deg_c, clipped to the register."""
        self.set_temperature_raw(max(-128, min(127, round((deg_c - 23) * 2))))
