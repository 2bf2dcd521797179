"""Bosch BMI055 IMU over SPI: register-level driver for its two dies (accel and gyro).

The BMI055 is two chips in one package, each with its own chip select (active low) on a
shared SPI bus (mode 0 or 3, up to 10 MHz). The driver never imports `machine`: the board
builds the bus and pins and passes them in (`board.py`), and the host emulator passes its
emulated board's (`host_emulator/emulated_board/mpy/machine.py`). It uses only `spi.write(buf)`,
`spi.readinto(buf, 0)` (configuration), `spi.write_readinto(tx, rx)` (the data bursts) and
`pin.value(v)`.

Protocol (both dies): the first byte is the register address, bit 7 set for a read; the
following bytes are read (or written) at auto-incremented addresses. No dummy byte.

Units and scales (datasheet figures, docs/requirements.md, BMI055 facts):
    gyro counts: int16 at registers 0x02..0x07 (LSB first). Sensitivity per range, in
        LSB per (deg/s) x 10 (integers: no float literal in firmware/):
        2000 -> 164, 1000 -> 328, 500 -> 656, 250 -> 1312, 125 -> 2624.
    accel counts: 12-bit two's complement, left-justified in 0x02..0x07 (LSB first; bit 0
        of each LSB is new_data), returned after the 4-bit shift (-2048..2047). Sensitivity
        in LSB per g: 2 g -> 1024, 4 g -> 512, 8 g -> 256, 16 g -> 128.
    temperature: accel register 0x08, int8, 0.5 K per LSB, 0 = 23 degC.
Counts are in the sensor's own axes; mounting rotation is the application's business.

Bandwidth defaults for the 5 ms (200 Hz) loop, which reads the free-running sensor:
    gyro  0x10 = 3: ODR 400 Hz, filter 47 Hz.
    accel 0x10 = 0x0C: filter 125 Hz, data update 250 Hz.
Both dies update faster than the loop reads, so every read returns a sample at most
2.5 ms (gyro) / 4 ms (accel) old and the sensor clock never beats against the loop timer
(at ODR 200 Hz = loop rate, drift between the two clocks periodically repeats or skips a
sample; the accel's next lower setting, 62.5 Hz, updates at 125 Hz, so 3 reads in 8 would
be stale). The filters sit at or near the loop's 100 Hz Nyquist frequency, so vibration
above it is attenuated before the loop samples it, while vehicle dynamics (a few Hz) pass
with a few ms of delay. Both are constructor arguments (the `GYRO_BW_*`, `ACCEL_BW_*`
register codes below).

Saturation: the datasheet's accuracy collapses once the measured quantity exceeds the
range, and the chip then clips at full scale. `read()` sets `saturated` when any axis is
at full scale or within one count of it: gyro >= 32766 or <= -32767, accel >= 2046 or
<= -2047. `status` tells which axes (bits 0-2 gyro x,y,z; bits 3-5 accel x,y,z).

Allocation: `read()` and `read_temperature()` allocate nothing (no heap block, not even a
transient call frame: each method's state stays within the VM's on-stack frame limit);
the tests prove it on the MicroPython VM under `micropython.heap_lock()`.
"""

from array import array

from micropython import const

import kern

try:
    from time import sleep_ms as _sleep_ms
except ImportError:  # CPython: the emulator may add sleep_ms (its virtual clock) later

    def _sleep_ms(ms):
        import time

        if hasattr(time, "sleep_ms"):
            time.sleep_ms(ms)
        else:
            time.sleep(ms / 1000)


# Registers common to both dies
_REG_CHIP_ID = const(0x00)
_REG_DATA = const(0x02)  # X LSB; 6 bytes X, Y, Z (LSB first)
_REG_RANGE = const(0x0F)
_REG_BW = const(0x10)
_REG_SOFTRESET = const(0x14)
_ACC_REG_TEMP = const(0x08)  # accel die only
_READ = const(0x80)
_SOFTRESET_CMD = const(0xB6)

ACCEL_CHIP_ID = const(0xFA)
GYRO_CHIP_ID = const(0x0F)

# Start-up time after a soft reset (datasheet: gyro 30 ms, accel 1.8 ms).
GYRO_RESET_MS = const(30)
ACCEL_RESET_MS = const(2)

# Bits the range and bandwidth registers keep (the rest is reserved; gyro 0x10 bit 7
# reads as 1 on the real part).
_ACC_RANGE_MASK = const(0x0F)
_ACC_BW_MASK = const(0x1F)
_GYR_RANGE_MASK = const(0x07)
_GYR_BW_MASK = const(0x0F)

# Gyro bandwidth register codes: ODR / filter bandwidth.
GYRO_BW_2000HZ_523HZ = const(0)  # unfiltered
GYRO_BW_2000HZ_230HZ = const(1)
GYRO_BW_1000HZ_116HZ = const(2)
GYRO_BW_400HZ_47HZ = const(3)  # default
GYRO_BW_200HZ_23HZ = const(4)
GYRO_BW_100HZ_12HZ = const(5)
GYRO_BW_200HZ_64HZ = const(6)
GYRO_BW_100HZ_32HZ = const(7)

# Accel bandwidth register codes: filter bandwidth (data update rate = 2 x bandwidth).
ACCEL_BW_7HZ8 = const(0x08)
ACCEL_BW_15HZ6 = const(0x09)
ACCEL_BW_31HZ = const(0x0A)
ACCEL_BW_62HZ = const(0x0B)
ACCEL_BW_125HZ = const(0x0C)  # default
ACCEL_BW_250HZ = const(0x0D)
ACCEL_BW_500HZ = const(0x0E)
ACCEL_BW_1000HZ = const(0x0F)

# Range (deg/s or g) -> register code, and sensitivity (gyro in LSB per deg/s x 10).
GYRO_RANGE_CODE = {2000: 0, 1000: 1, 500: 2, 250: 3, 125: 4}
GYRO_LSB_PER_DPS_X10 = {2000: 164, 1000: 328, 500: 656, 250: 1312, 125: 2624}
ACCEL_RANGE_CODE = {2: 0x03, 4: 0x05, 8: 0x08, 16: 0x0C}
ACCEL_LSB_PER_G = {2: 1024, 4: 512, 8: 256, 16: 128}

# Over-range thresholds: full scale or within one count of it.
GYRO_SAT_HI = const(32766)
GYRO_SAT_LO = const(-32767)
ACCEL_SAT_HI = const(2046)
ACCEL_SAT_LO = const(-2047)


class Bmi055Error(Exception):
    """The BMI055 does not answer as it should (chip ID, or configuration read-back)."""


def temperature_half_c(raw):
    """Raw temperature register value (int8) -> half degrees Celsius (0 = 23 degC)."""
    return raw + 46


def _hex(v):
    return f"0x{v:02X}"


def _chip_id_message(accel_id, gyro_id):
    """Why the chip IDs are wrong, in words a person at the bench can act on."""
    if accel_id == GYRO_CHIP_ID and gyro_id == ACCEL_CHIP_ID:
        return (
            "BMI055 chip selects swapped: the accel CS reads chip ID 0x0F (the gyro's) and "
            "the gyro CS reads 0xFA (the accel's); exchange cs_accel and cs_gyro"
        )
    parts = []
    for die, want, got, other_ok in (
        ("accel", ACCEL_CHIP_ID, accel_id, gyro_id == GYRO_CHIP_ID),
        ("gyro", GYRO_CHIP_ID, gyro_id, accel_id == ACCEL_CHIP_ID),
    ):
        if got == want:
            continue
        msg = f"BMI055 {die} die: expected chip ID {_hex(want)} at register 0x00, read {_hex(got)}"
        if got in (0x00, 0xFF):
            msg += (
                " (nothing answers: no power, SPI wiring SCK/MOSI/MISO, wrong chip-select "
                "pin, SPI mode not 0/3, or no chip)"
            )
            if other_ok:
                msg += (
                    "; the other die answers, so power and the bus are fine: check the "
                    f"{die} chip-select pin and its wiring"
                )
        else:
            msg += " (another device answers on this chip select: wrong part or wrong CS pin)"
        parts.append(msg)
    return "; ".join(parts)


class BMI055:
    """Both dies of one BMI055.

    spi: a machine.SPI already set up (mode 0 or 3, <= 10 MHz, MSB first).
    cs_accel, cs_gyro: machine.Pin outputs, chip selects (active low); driven high here.
    gyro_range_dps: 125, 250, 500, 1000 or 2000 (default 250, the output frame's scale).
    accel_range_g: 2, 4, 8 or 16 (default 2, the output frame's scale).
    gyro_bw, accel_bw: bandwidth register codes (GYRO_BW_*, ACCEL_BW_*; module docstring).
    sleep_ms: the delay function (default time.sleep_ms); tests inject a recorder.
    init: False to build without touching the bus (call init() later).

    After `read()`:
    gyro: array('h', 3), gyro counts x, y, z (int16; divide by gyro_lsb_per_dps_x10 / 10
        for deg/s).
    accel: array('h', 3), accel counts x, y, z (-2048..2047; divide by accel_lsb_per_g).
    saturated: True if an axis is at (or within one count of) full scale.
    status: bits 0-5 the axes at full scale (gyro x, y, z, accel x, y, z), bits 6-8 the
        new_data bits of accel x, y, z (1: not read before); the navigator's input
        (nav.IMU_OVER_RANGE, nav.IMU_FRESH).
    raw_gyro, raw_accel: 6 bytes (memoryviews), the data registers as read (for raw
        logging/replay).
    """

    def __init__(
        self,
        spi,
        cs_accel,
        cs_gyro,
        gyro_range_dps=250,
        accel_range_g=2,
        gyro_bw=GYRO_BW_400HZ_47HZ,
        accel_bw=ACCEL_BW_125HZ,
        sleep_ms=None,
        init=True,
    ):
        if gyro_range_dps not in GYRO_RANGE_CODE:
            raise ValueError(
                f"BMI055 gyro range must be 125, 250, 500, 1000 or 2000 deg/s, got {gyro_range_dps}"
            )
        if accel_range_g not in ACCEL_RANGE_CODE:
            raise ValueError(f"BMI055 accel range must be 2, 4, 8 or 16 g, got {accel_range_g}")
        if not (isinstance(gyro_bw, int) and 0 <= gyro_bw <= 7):
            raise ValueError(f"BMI055 gyro bandwidth code must be 0..7, got {gyro_bw}")
        if not (isinstance(accel_bw, int) and 0x08 <= accel_bw <= 0x0F):
            raise ValueError(f"BMI055 accel bandwidth code must be 0x08..0x0F, got {accel_bw}")
        self._spi = spi
        self._cs_a = cs_accel
        self._cs_g = cs_gyro
        self._sleep_ms = sleep_ms if sleep_ms is not None else _sleep_ms
        self.gyro_range_dps = gyro_range_dps
        self.accel_range_g = accel_range_g
        self.gyro_bw = gyro_bw
        self.accel_bw = accel_bw
        self.gyro_lsb_per_dps_x10 = GYRO_LSB_PER_DPS_X10[gyro_range_dps]
        self.accel_lsb_per_g = ACCEL_LSB_PER_G[accel_range_g]
        # Everything read() touches is allocated here, once.
        self._tx1 = bytearray(1)
        self._rx1 = bytearray(1)
        self._tx2 = bytearray(2)
        # a burst is one full-duplex transfer of 7 bytes: the address out, then 6 data bytes in
        # (what comes back while the address goes out is not data)
        self._burst_tx = bytearray(7)
        self._burst_tx[0] = _REG_DATA | _READ
        self._burst_g = bytearray(7)
        self._burst_a = bytearray(7)
        self.raw_gyro = memoryview(self._burst_g)[1:]
        self.raw_accel = memoryview(self._burst_a)[1:]
        self.gyro = array("h", (0, 0, 0))
        self.accel = array("h", (0, 0, 0))
        self.saturated = False
        self.status = 0
        cs_accel.value(1)
        cs_gyro.value(1)
        if init:
            self.init()

    # -- register access (used at start-up; allocation-free as well) --

    def _read_reg(self, cs, reg):
        tx = self._tx1
        tx[0] = reg | _READ
        cs.value(0)
        self._spi.write(tx)
        self._spi.readinto(self._rx1, 0)
        cs.value(1)
        return self._rx1[0]

    def _write_reg(self, cs, reg, value):
        tx = self._tx2
        tx[0] = reg & 0x7F
        tx[1] = value
        cs.value(0)
        self._spi.write(tx)
        cs.value(1)

    def read_accel_reg(self, reg):
        """One accel-die register (diagnostics)."""
        return self._read_reg(self._cs_a, reg)

    def read_gyro_reg(self, reg):
        """One gyro-die register (diagnostics)."""
        return self._read_reg(self._cs_g, reg)

    def release(self):
        """Deselect both dies (after an SPI error left a transaction open)."""
        self._cs_a.value(1)
        self._cs_g.value(1)

    # -- start-up --

    def check_ids(self):
        """Raise Bmi055Error unless both dies answer with their chip IDs."""
        a = self._read_reg(self._cs_a, _REG_CHIP_ID)
        g = self._read_reg(self._cs_g, _REG_CHIP_ID)
        if a != ACCEL_CHIP_ID or g != GYRO_CHIP_ID:
            raise Bmi055Error(_chip_id_message(a, g))

    def init(self):
        """Chip IDs, soft reset of both dies, range and bandwidth, then read-back check."""
        self.release()
        self.check_ids()
        self._write_reg(self._cs_g, _REG_SOFTRESET, _SOFTRESET_CMD)
        self._sleep_ms(GYRO_RESET_MS)
        self._write_reg(self._cs_a, _REG_SOFTRESET, _SOFTRESET_CMD)
        self._sleep_ms(ACCEL_RESET_MS)
        self.check_ids()  # both dies came back from the reset
        ga = GYRO_RANGE_CODE[self.gyro_range_dps]
        ac = ACCEL_RANGE_CODE[self.accel_range_g]
        self._write_reg(self._cs_g, _REG_RANGE, ga)
        self._write_reg(self._cs_g, _REG_BW, self.gyro_bw)
        self._write_reg(self._cs_a, _REG_RANGE, ac)
        self._write_reg(self._cs_a, _REG_BW, self.accel_bw)
        self._verify(self._cs_g, "gyro", _REG_RANGE, "range", ga, _GYR_RANGE_MASK)
        self._verify(self._cs_g, "gyro", _REG_BW, "bandwidth", self.gyro_bw, _GYR_BW_MASK)
        self._verify(self._cs_a, "accel", _REG_RANGE, "range", ac, _ACC_RANGE_MASK)
        self._verify(self._cs_a, "accel", _REG_BW, "bandwidth", self.accel_bw, _ACC_BW_MASK)

    def _verify(self, cs, die, reg, name, want, mask):
        got = self._read_reg(cs, reg)
        if got & mask != want:
            raise Bmi055Error(
                f"BMI055 {die} die: {name} register {_hex(reg)} reads {_hex(got)} after writing "
                f"{_hex(want)} (writes do not reach the chip: MOSI wiring or SPI mode?)"
            )

    # -- per tick --

    def read(self):
        """Burst-read both dies' data registers and decode them into `gyro` and `accel`.

        Returns `saturated`. Two SPI transactions of 1 + 6 bytes each, one full-duplex call
        each (per call the board's SPI driver costs more than its bytes); allocates nothing.
        The chip selects are set by calling the pin (Pin.__call__, the port's pin_call), which
        spares the method look-up of Pin.value on every edge.
        """
        spi = self._spi
        tx = self._burst_tx
        cs = self._cs_g
        cs(0)
        spi.write_readinto(tx, self._burst_g)
        cs(1)
        cs = self._cs_a
        cs(0)
        spi.write_readinto(tx, self._burst_a)
        cs(1)
        m = _decode(self.gyro, self.accel, self.raw_gyro, self.raw_accel)
        self.status = m
        self.saturated = (m & 0x3F) != 0
        return self.saturated

    def read_temperature(self):
        """Raw temperature (int8: 0.5 K per LSB, 0 = 23 degC); allocates nothing.

        temperature_half_c(raw) gives half degrees Celsius.
        """
        t = self._read_reg(self._cs_a, _ACC_REG_TEMP)
        if t >= 0x80:
            t -= 0x100
        return t


def _decode_gyro(b, out):
    """int16 LSB-first words -> out[0..2]; returns the over-range mask (bits 0-2)."""
    m = 0
    for i in range(3):
        v = b[2 * i] | (b[2 * i + 1] << 8)
        if v >= 0x8000:
            v -= 0x10000
        out[i] = v
        if v >= GYRO_SAT_HI or v <= GYRO_SAT_LO:
            m |= 1 << i
    return m


def _decode_accel(b, out):
    """12-bit left-justified words -> out[0..2]; returns the over-range mask (bits 0-2)
    and the new_data bits (bits 3-5)."""
    m = 0
    for i in range(3):
        lsb = b[2 * i]
        v = ((b[2 * i + 1] << 8) | lsb) >> 4
        if v >= 0x800:
            v -= 0x1000
        out[i] = v
        if v >= ACCEL_SAT_HI or v <= ACCEL_SAT_LO:
            m |= 1 << i
        m |= (lsb & 1) << (i + 3)
    return m


def _decode_py(gyro, accel, raw_gyro, raw_accel):
    """Both dies' data registers into gyro and accel (int16 counts); returns the over-range
    mask (bits 0-2 gyro, 3-5 accel) and the accel new_data bits (6-8). The reference of the
    native kernel `bmi055_decode`."""
    return _decode_gyro(raw_gyro, gyro) | (_decode_accel(raw_accel, accel) << 3)


_decode = kern.pick("bmi055_decode", _decode_py)
