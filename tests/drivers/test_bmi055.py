"""firmware/drivers/bmi055.py against the emulated board's BMI055 register model
(host_emulator/emulated_board/mpy/bmi055_model.py, through machine.py, on CPython) and against a
minimal fake bus inside the MicroPython VM: start-up (chip IDs, soft reset and its delays,
range/bandwidth registers and their read-back), clear errors for the usual wiring faults, exact
decoding of every count including the extremes, the over-range flag at its documented
threshold, temperature, and a read() that allocates nothing."""

import json
import time

import numpy as np
import pytest

from common.proto import stimulus
from drivers import bmi055
from host_emulator.emulated_board import bmi055_model, install_machine
from host_emulator.runtimes.mpy_unix import vm as mpvm
from host_emulator.sim import imu as sim_imu

machine = install_machine()  # the emulated board; time.now_us is its clock

# What the range and bandwidth registers mean (Bosch datasheet figures, docs/requirements.md, BMI055
# facts)
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


def gyro_range_dps(die):
    """The configured range in deg/s (None for a reserved code)."""
    return GYRO_RANGE_DPS.get(die.regs[0x0F] & 0x07)


def gyro_bw(die):
    """(ODR Hz, filter bandwidth Hz) configured (None for a reserved code)."""
    return GYRO_BW.get(die.regs[0x10] & 0x0F)


def accel_range_g(die):
    """The configured range in g (None for a reserved code)."""
    return ACCEL_RANGE_G.get(die.regs[0x0F] & 0x0F)


def accel_bw_hz(die):
    """The configured filter bandwidth, Hz (codes below 0x08 mean 7.81, above 0x0F 1000)."""
    return ACCEL_BW_HZ[min(max(die.regs[0x10] & 0x1F, 0x08), 0x0F)]


def set_sample(model, gyro_counts, accel_counts):
    """The next sample from gyro int16 and accel 12-bit counts (x, y, z), encoded into data
    registers as the emulator's stimulus holds them (new_data bits set)."""
    regs = stimulus.gyro_registers([gyro_counts])[0].tobytes()
    regs += stimulus.accel_registers([accel_counts])[0].tobytes()
    model.set_registers(regs, 0, 6)


def temp_raw(deg_c):
    """The temperature register for deg_c, as sim/imu.py computes it (0.5 K per LSB, 0 = 23
    degC, clipped to int8)."""
    return int(np.clip(np.rint((deg_c - 23.0) * 2.0), -128, 127))


class Clock:
    """The board's virtual clock (time.now_us, from 0 at power-on): the driver's injected
    sleep_ms advances it by advance(ms) milliseconds and is recorded."""

    def __init__(self, advance=None):
        self.sleeps = []
        self.advance = advance if advance is not None else (lambda ms: ms)

    def sleep_ms(self, ms):
        self.sleeps.append(ms)
        time.advance_us(1000 * self.advance(ms))


def rig(model=None, miso_idle=0xFF, swap_cs=False, clock=None, polarity=0, phase=0, **drv):
    """A freshly powered board, the model on its SPI bus (every transaction logged) and a
    driver on top: (imu, model, spi, clock)."""
    clock = Clock() if clock is None else clock
    model = machine.Bmi055() if model is None else model
    machine.power_on()
    spi = machine.SPI(1, baudrate=8_000_000, polarity=polarity, phase=phase)
    spi.miso_idle = miso_idle
    spi.log = []
    cs_a = machine.Pin("cs_accel", machine.Pin.OUT, value=1)
    cs_g = machine.Pin("cs_gyro", machine.Pin.OUT, value=1)
    if swap_cs:
        model.attach(spi, cs_g, cs_a)
    else:
        model.attach(spi, cs_a, cs_g)
    imu = bmi055.BMI055(spi, cs_a, cs_g, sleep_ms=clock.sleep_ms, **drv)
    return imu, model, spi, clock


# -- start-up --


def test_init_defaults_configure_the_registers_exactly():
    imu, model, _, clock = rig()
    g, a = model.gyro, model.accel
    assert g.resets == a.resets == 1
    # Every accepted write, in order: reset, range, bandwidth.
    assert g.writes == [(0x14, 0xB6), (0x0F, 0x03), (0x10, 0x03)]
    assert a.writes == [(0x14, 0xB6), (0x0F, 0x03), (0x10, 0x0C)]
    assert g.regs[0x0F] == 0x03 and g.regs[0x10] == 0x83  # gyro bw bit 7 reads 1
    assert a.regs[0x0F] == 0x03 and a.regs[0x10] == 0x0C
    assert gyro_range_dps(g) == 250 and gyro_bw(g) == (400, 47)
    assert accel_range_g(a) == 2 and accel_bw_hz(a) == 125.0
    assert imu.gyro_lsb_per_dps_x10 == 1312 and imu.accel_lsb_per_g == 1024
    assert clock.sleeps == [30, 2]


@pytest.mark.parametrize(
    "gyro_dps, gyro_code, accel_g, accel_code",
    [(125, 4, 16, 0x0C), (500, 2, 4, 0x05), (1000, 1, 8, 0x08), (2000, 0, 2, 0x03)],
)
def test_ranges_set_their_codes_and_sensitivities(gyro_dps, gyro_code, accel_g, accel_code):
    imu, model, _, _ = rig(gyro_range_dps=gyro_dps, accel_range_g=accel_g)
    assert model.gyro.regs[0x0F] == gyro_code and gyro_range_dps(model.gyro) == gyro_dps
    assert model.accel.regs[0x0F] == accel_code and accel_range_g(model.accel) == accel_g
    # The driver's integer sensitivities are the simulation's datasheet figures.
    assert imu.gyro_lsb_per_dps_x10 == round(10 * sim_imu.GYRO_LSB_PER_DPS_BY_RANGE[gyro_dps])
    assert imu.accel_lsb_per_g == sim_imu.ACCEL_LSB_PER_G_BY_RANGE[accel_g]


def test_sensitivity_tables_match_the_datasheet_for_every_range():
    for dps, lsb in sim_imu.GYRO_LSB_PER_DPS_BY_RANGE.items():
        assert bmi055.GYRO_LSB_PER_DPS_X10[dps] == round(10 * lsb)
    assert bmi055.ACCEL_LSB_PER_G == sim_imu.ACCEL_LSB_PER_G_BY_RANGE
    # Full scale in counts covers the nominal range (gyro: 32767 / 131.2 = 249.7 deg/s).
    for dps, x10 in bmi055.GYRO_LSB_PER_DPS_X10.items():
        assert 32768 * 10 / x10 == pytest.approx(dps, rel=0.002)


def test_bandwidths_are_configurable():
    _, model, _, _ = rig(gyro_bw=bmi055.GYRO_BW_200HZ_23HZ, accel_bw=bmi055.ACCEL_BW_62HZ)
    assert model.gyro.regs[0x10] == 0x84 and gyro_bw(model.gyro) == (200, 23)
    assert model.accel.regs[0x10] == 0x0B and accel_bw_hz(model.accel) == 62.5


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"gyro_range_dps": 300}, "gyro range must be 125, 250, 500, 1000 or 2000 deg/s, got 300"),
        ({"accel_range_g": 3}, "accel range must be 2, 4, 8 or 16 g, got 3"),
        ({"gyro_bw": 8}, "gyro bandwidth code must be 0..7, got 8"),
        ({"accel_bw": 0x07}, "accel bandwidth code must be 0x08..0x0F, got 7"),
    ],
)
def test_invalid_configuration_is_a_clear_value_error(kwargs, words):
    machine.power_on()
    spi = machine.SPI(1)
    with pytest.raises(ValueError, match=words):
        bmi055.BMI055(spi, machine.Pin("a"), machine.Pin("g"), **kwargs)
    assert spi.bytes_clocked == 0  # rejected before touching the bus


def test_soft_reset_returns_registers_to_their_defaults():
    model = machine.Bmi055()
    g, a = model.gyro, model.accel
    g.write_reg(0x0F, 0x02)
    g.write_reg(0x11, 0x80)  # suspend
    a.write_reg(0x0F, 0x0C)
    a.write_reg(0x10, 0x08)
    set_sample(model, (1, 2, 3), (4, 5, 6))
    for die in (g, a):
        die.select()
        for byte in (0x14, 0xB6):
            die.exchange(byte)
        assert die.resets == 0  # takes effect when the chip select rises
        die.deselect()
        assert die.resets == 1
    assert (g.regs[0x0F], g.regs[0x10], g.regs[0x11]) == (0x00, 0x80, 0x00)
    assert (a.regs[0x0F], a.regs[0x10]) == (0x03, 0x0F)
    assert bytes(g.regs[2:8]) == bytes(a.regs[2:8]) == bytes(6)
    assert g.read_reg(0x00) == 0x0F and a.read_reg(0x00) == 0xFA


def test_driver_resets_a_die_left_configured_by_a_previous_run():
    model = machine.Bmi055()
    model.gyro.write_reg(0x11, 0x80)  # left in suspend by someone else
    model.accel.write_reg(0x13, 0x40)  # shadowing disabled
    _, model, _, _ = rig(model=model)
    assert model.gyro.regs[0x11] == 0x00 and model.accel.regs[0x13] == 0x00


def test_soft_reset_delays_are_requested_after_each_reset():
    machine.power_on()
    clock = Clock()
    model = machine.Bmi055()
    spi = machine.SPI(1, baudrate=8_000_000)
    spi.log = []
    cs_a = machine.Pin("a", machine.Pin.OUT, value=1)
    cs_g = machine.Pin("g", machine.Pin.OUT, value=1)
    model.attach(spi, cs_a, cs_g)
    log = []  # (time us, die, first MOSI byte) of every transaction, when its chip select rises
    for die, name in ((model.accel, "accel"), (model.gyro, "gyro")):

        def deselect(name=name, real=die.deselect):
            log.append((time.now_us(), name, spi.log[-1][1][0]))
            real()

        die.deselect = deselect
    bmi055.BMI055(spi, cs_a, cs_g, sleep_ms=clock.sleep_ms)
    assert clock.sleeps == [bmi055.GYRO_RESET_MS, bmi055.ACCEL_RESET_MS] == [30, 2]
    for die, wait_us in (("gyro", 30_000), ("accel", 1_800)):  # datasheet start-up times
        mine = [(t, b) for t, d, b in log if d == die]
        k = mine.index(next(e for e in mine if e[1] == 0x14))  # the soft reset write
        assert mine[k + 1][0] - mine[k][0] >= wait_us  # next access only after the start-up
    assert model.gyro.resets == model.accel.resets == 1


def test_without_the_delays_the_dies_do_not_answer():
    # The model keeps each die silent for its start-up time after a soft reset, as the chip
    # is: a driver that did not wait would read a floating bus after the reset.
    with pytest.raises(bmi055.Bmi055Error, match="expected chip ID 0xFA.*read 0xFF"):
        rig(clock=Clock(advance=lambda ms: 0))
    # Gyro short by more than the accel's 2 ms: the gyro is still starting up.
    with pytest.raises(bmi055.Bmi055Error, match="^BMI055 gyro die: .*read 0xFF"):
        rig(clock=Clock(advance=lambda ms: ms - 3 if ms == 30 else ms))


# -- chip ID and wiring faults --


@pytest.mark.parametrize("idle", [0xFF, 0x00])
def test_absent_chip_names_both_dies_and_the_likely_causes(idle):
    with pytest.raises(bmi055.Bmi055Error) as err:
        rig(model=machine.Bmi055(present=False), miso_idle=idle)
    msg = str(err.value)
    got = f"0x{idle:02X}"
    assert f"accel die: expected chip ID 0xFA at register 0x00, read {got}" in msg
    assert f"gyro die: expected chip ID 0x0F at register 0x00, read {got}" in msg
    for cause in ("no power", "wiring", "wrong chip-select pin", "no chip"):
        assert cause in msg


def test_wrong_chip_id_says_another_device_answers():
    with pytest.raises(bmi055.Bmi055Error) as err:
        rig(model=machine.Bmi055(accel_chip_id=0xF8))
    msg = str(err.value)
    assert "accel die: expected chip ID 0xFA at register 0x00, read 0xF8" in msg
    assert "another device answers" in msg
    assert "gyro" not in msg


def test_missing_gyro_with_accel_present_points_at_the_gyro_chip_select():
    model = machine.Bmi055()
    model.gyro.responds = False
    with pytest.raises(bmi055.Bmi055Error) as err:
        rig(model=model)
    msg = str(err.value)
    assert msg.startswith("BMI055 gyro die: expected chip ID 0x0F at register 0x00, read 0xFF")
    assert "the other die answers" in msg and "check the gyro chip-select pin" in msg
    assert "accel die" not in msg
    assert model.accel.resets == model.gyro.resets == 0  # nothing written before the check


def test_swapped_chip_selects_are_recognised():
    with pytest.raises(bmi055.Bmi055Error, match="chip selects swapped"):
        rig(swap_cs=True)


def test_lost_writes_are_caught_by_the_read_back():
    model = machine.Bmi055()
    model.gyro.ignore_writes = model.accel.ignore_writes = True  # MOSI broken: IDs still read
    with pytest.raises(bmi055.Bmi055Error) as err:
        rig(model=model)
    assert "gyro die: range register 0x0F reads 0x00 after writing 0x03" in str(err.value)
    assert "MOSI" in str(err.value)


def test_wrong_spi_mode_fails_the_chip_id_check():
    with pytest.raises(bmi055.Bmi055Error, match="expected chip ID"):
        rig(polarity=0, phase=1)
    rig(polarity=1, phase=1)  # mode 3 is fine


# -- reading --


def test_read_is_two_bursts_of_seven_bytes():
    imu, model, spi, _ = rig()
    set_sample(model, (1, 2, 3), (4, 5, 6))
    n0, t0 = spi.bytes_clocked, len(spi.log)
    imu.read()
    assert spi.bytes_clocked - n0 == 14
    new = spi.log[t0:]
    assert [(name, bytes(mosi)) for name, mosi, _ in new] == [
        ("bmi055-gyro", bytes([0x82, 0, 0, 0, 0, 0, 0])),
        ("bmi055-accel", bytes([0x82, 0, 0, 0, 0, 0, 0])),
    ]


SAMPLES = [
    ((0, 0, 0), (0, 0, 0)),
    ((1, -1, 2), (1, -1, 2)),
    ((-32768, 32767, -1), (-2048, 2047, -1)),
    ((32767, -32768, 0x1234), (2047, -2048, 0x123)),
    ((-300, 4660, -22136), (-1000, 1024, -513)),
]


@pytest.mark.parametrize("gyro, accel", SAMPLES)
def test_read_decodes_counts_exactly(gyro, accel):
    imu, model, _, _ = rig()
    set_sample(model, gyro, accel)
    imu.read()
    assert list(imu.gyro) == list(gyro)
    assert list(imu.accel) == list(accel)
    assert (imu.status >> 6) == 0b111
    # The raw register bytes are kept for logging: gyro int16 LE, accel counts << 4 | new.
    assert bytes(imu.raw_gyro) == np.array(gyro, "<i2").tobytes()
    words = (np.array(accel, np.int32) << 4 | 1).astype("<u2")
    assert bytes(imu.raw_accel) == words.tobytes()


def test_read_decodes_random_counts_exactly():
    imu, model, _, _ = rig()
    rng = np.random.default_rng(55)
    gyro = rng.integers(-32768, 32768, (300, 3))
    accel = rng.integers(-2048, 2048, (300, 3))
    for g, a in zip(gyro, accel, strict=True):
        set_sample(model, g, a)
        imu.read()
        assert list(imu.gyro) == list(g) and list(imu.accel) == list(a)


def test_new_data_bits_clear_once_read():
    imu, model, _, _ = rig()
    set_sample(model, (5, 6, 7), (8, 9, 10))
    imu.read()
    assert (imu.status >> 6) == 0b111
    imu.read()  # no new sample: same counts, new_data cleared by the first read
    assert (imu.status >> 6) == 0 and list(imu.accel) == [8, 9, 10]
    assert model.gyro.regs[0x0A] & 0x80 == 0 and model.accel.regs[0x0A] & 0x80 == 0


def test_sim_counts_go_through_unchanged():
    """The emulator feeds sim.imu counts (numpy int16), encoded as the stimulus's data
    registers, into the model; a count out of range never gets that far."""
    imu, model, _, _ = rig()
    counts = np.array([[100, -200, 300], [-2048, 2047, 1024]], np.int16)
    set_sample(model, counts[0], counts[1])
    imu.read()
    assert list(imu.gyro) == [100, -200, 300] and list(imu.accel) == [-2048, 2047, 1024]
    with pytest.raises(ValueError, match=r"accel counts must be 12-bit \(-2048..2047\)"):
        set_sample(model, (0, 0, 0), (0, 0, 2048))


# Threshold: full scale or within one count of it (gyro 32766 / -32767, accel 2046 / -2047).
SAT = [
    ("gyro", 32767, True),
    ("gyro", 32766, True),
    ("gyro", 32765, False),
    ("gyro", -32768, True),
    ("gyro", -32767, True),
    ("gyro", -32766, False),
    ("accel", 2047, True),
    ("accel", 2046, True),
    ("accel", 2045, False),
    ("accel", -2048, True),
    ("accel", -2047, True),
    ("accel", -2046, False),
]


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("die, count, flagged", SAT)
def test_over_range_flag_at_full_scale_only(die, count, flagged, axis):
    imu, model, _, _ = rig()
    g, a = [10, -10, 0], [0, 5, -5]
    (g if die == "gyro" else a)[axis] = count
    set_sample(model, g, a)
    assert imu.read() is flagged
    assert imu.saturated is flagged
    bit = 1 << (axis + (0 if die == "gyro" else 3))
    assert (imu.status & 0x3F) == (bit if flagged else 0)
    set_sample(model, (0, 0, 0), (0, 0, 0))
    assert imu.read() is False and (imu.status & 0x3F) == 0  # clears on the next good sample


@pytest.mark.parametrize("raw", [-128, -46, -1, 0, 1, 4, 127])
def test_temperature(raw):
    imu, model, _, _ = rig()
    model.set_temperature_raw(raw)
    assert imu.read_temperature() == raw
    assert bmi055.temperature_half_c(raw) == 46 + raw  # 0.5 K per LSB, 0 = 23 degC


def test_temperature_from_celsius():
    imu, model, _, _ = rig()
    model.set_temperature_raw(temp_raw(24.5))
    assert imu.read_temperature() == 3
    assert bmi055.temperature_half_c(3) == 49  # 24.5 degC
    model.set_temperature_raw(temp_raw(-40))
    assert imu.read_temperature() == -126


def test_a_die_runs_on_the_clock_it_is_given():
    """bmi055_model is machine's BMI055 (re-exported), and a die takes another emulator's
    clock (`now_us`): its start-up after a soft reset ends on that clock, whatever the board's
    says; without one it runs on the board's (time.now_us)."""
    model = bmi055_model()
    assert machine.Bmi055 is model.Bmi055 and machine.GyroDie is model.GyroDie
    machine.power_on()
    now = [1000]
    imu = model.Bmi055(now_us=lambda: now[0])
    board = model.Bmi055()
    for b in (imu, board):
        for die in (b.gyro, b.accel):
            die.write_reg(0x14, 0xB6)
            die.deselect()
    time.advance_us(40_000)  # the board's clock: past both start-ups
    assert imu.gyro.busy() and imu.accel.busy()
    assert not board.gyro.busy() and not board.accel.busy()
    now[0] = 1000 + 1800  # the accel's 1.8 ms, not yet the gyro's 30 ms
    assert imu.gyro.busy() and not imu.accel.busy()
    assert imu.gyro.exchange(0x80) == -1  # silent while starting up
    now[0] = 1000 + 30_000
    assert not imu.gyro.busy() and imu.gyro.resets == 1


@pytest.mark.parametrize("die_cls", [machine.GyroDie, machine.AccelDie])
def test_a_transfer_is_its_bytes_exchanged_one_by_one(die_cls):
    """_Die.transfer (the emulator's hot path: state in locals, a burst of data registers by
    slices on CPython) equals exchange() byte by byte: the MISO bytes, the registers with
    their read side effects (data_int, new_data), the read count and the address after it,
    for bursts in and across the data registers, other registers and writes."""
    rng = np.random.default_rng(5)
    cases = [(0x82, 7), (0x82, 2), (0x83, 4), (0x86, 3), (0x87, 2), (0x80, 9), (0x81, 12),
             (0x8A, 3), (0x02, 3), (0x10, 2), (0x82, 1)]  # fmt: skip
    for first, n in cases:
        a, b = die_cls(), die_cls()
        data = rng.integers(0, 256, 6).astype(np.uint8).tobytes()
        for die in (a, b):
            die.set_registers(data, 0)
            die.select()
        wbuf = bytearray([first]) + bytearray(rng.integers(0, 256, n - 1).astype(np.uint8))
        fast = bytearray(n)
        a.transfer(wbuf, fast, 0, n, 0xFF)
        slow = bytearray()
        for i in range(n):
            v = b.exchange(wbuf[i])
            slow.append(0xFF if v < 0 else v & 0xFF)
        assert fast == slow, (hex(first), n)
        assert a.regs == b.regs and a.reads == b.reads and a._addr == b._addr, (hex(first), n)
        assert a.writes == b.writes


def test_bus_is_strict_about_chip_selects():
    machine.power_on()
    spi = machine.SPI(1)
    model = machine.Bmi055()
    a, g = machine.Pin("a"), machine.Pin("g")
    model.attach(spi, a, g)
    with pytest.raises(RuntimeError, match="no chip select low"):
        spi.write(b"\x80")
    a.off()
    g.off()
    with pytest.raises(RuntimeError, match="contention"):
        spi.write(b"\x80")


# -- in the MicroPython VM --

# A minimal bus for the VM: two register files behind two chip selects, the BMI055 read/write
# protocol with auto-increment, soft reset to the reset values. Written to allocate nothing
# itself, and it records the allocator's high-water mark whenever the driver calls it.
_VM_FAKE = """
import json, time
class Bus:
    def __init__(self):
        self.regs = (bytearray(128), bytearray(128))  # 0 accel, 1 gyro
        self.ids = (0xFA, 0x0F)
        self.sel = -1
        self.pos = -1
        self.peak = 0
        self.reset(0)
        self.reset(1)
    def reset(self, d):
        r = self.regs[d]
        for i in range(128):
            r[i] = 0
        r[0] = self.ids[d]
        r[0x0F] = 0x03 if d == 0 else 0x00
        r[0x10] = 0x0F if d == 0 else 0x80
    def probe(self):
        m = gc.mem_alloc()
        if m > self.peak:
            self.peak = m
    def write(self, buf):
        self.probe()
        r = self.regs[self.sel]
        for i in range(len(buf)):
            x = buf[i]
            if self.pos < 0:
                self.pos = x & 0x7F
            else:
                if self.pos == 0x14:
                    if x == 0xB6:
                        self.reset(self.sel)
                elif self.pos == 0x10 and self.sel == 1:
                    r[0x10] = x | 0x80
                else:
                    r[self.pos] = x
                self.pos += 1
    def readinto(self, buf, w=0):
        self.probe()
        r = self.regs[self.sel]
        p = self.pos
        for i in range(len(buf)):
            buf[i] = r[p + i]
        self.pos = p + len(buf)
    def write_readinto(self, wbuf, rbuf):
        self.probe()
        r = self.regs[self.sel]
        self.pos = wbuf[0] & 0x7F
        rbuf[0] = 0xFF
        for i in range(1, len(wbuf)):
            rbuf[i] = r[self.pos + i - 1]
        self.pos += len(wbuf) - 1
class Cs:
    def __init__(self, bus, d):
        self.bus = bus
        self.d = d
    def value(self, v):
        self.bus.sel = self.d if v == 0 else -1
        self.bus.pos = -1
    __call__ = value  # a machine.Pin is callable: pin(v) sets it (the port's pin_call)
from drivers import bmi055
bus = Bus()
sleeps = []
imu = bmi055.BMI055(bus, Cs(bus, 0), Cs(bus, 1), sleep_ms=sleeps.append)
def put(g, a):
    for i in range(3):
        w = g[i] & 0xFFFF
        bus.regs[1][2 + 2 * i] = w & 0xFF
        bus.regs[1][3 + 2 * i] = w >> 8
        w = ((a[i] & 0xFFF) << 4) | 1
        bus.regs[0][2 + 2 * i] = w & 0xFF
        bus.regs[0][3 + 2 * i] = w >> 8
"""


def test_driver_in_the_micropython_vm_decodes_exactly_and_allocates_nothing():
    cases = [list(map(list, s)) for s in SAMPLES] + [
        [[32766, 0, 0], [0, 0, 0]],
        [[32765, -32766, 0], [2045, -2046, 0]],
        [[0, 0, 0], [0, -2047, 0]],
    ]
    out = mpvm.run_json(
        _VM_FAKE
        + f"""
res = {{'regs': [bus.regs[1][0x0F], bus.regs[1][0x10], bus.regs[0][0x0F], bus.regs[0][0x10]],
       'sleeps': sleeps, 'sens': [imu.gyro_lsb_per_dps_x10, imu.accel_lsb_per_g], 'cases': []}}
for g, a in {cases!r}:
    put(g, a)
    sat = imu.read()
    res['cases'].append([list(imu.gyro), list(imu.accel), sat, imu.status & 0x3F,
                         imu.status >> 6])
bus.regs[0][0x08] = 0xFE
res['temp'] = imu.read_temperature()
put([-32768, 32767, 1], [-2048, 2047, 1])
res['locked_read'] = _locked(lambda: imu.read())
res['locked_temp'] = _locked(lambda: imu.read_temperature())
res['blocks'] = _blocks(imu.read)
# mem_total counts every allocation, even a call frame taken from the heap and freed on
# return (which neither mem_alloc deltas nor heap_lock reveal); the bus's probe sees the
# high-water mark of the heap while the driver is inside read().
imu.read()
i = 0  # the loop's global exists before the count starts (a new global may grow the dict)
gc.collect()
gc.disable()
m0 = gc.mem_alloc()
bus.peak = m0
t0 = micropython.mem_total()
for i in range(100):
    imu.read()
    imu.read_temperature()
res['mem_total'] = micropython.mem_total() - t0
res['peak'] = bus.peak - m0
gc.enable()
res['after'] = [list(imu.gyro), list(imu.accel), imu.saturated]
n = 2000
t = time.ticks_us()
for i in range(n):
    imu.read()
res['us_per_read'] = time.ticks_diff(time.ticks_us(), t) / n
errs = []
for ids in ((0xFF, 0xFF), (0x00, 0x0F), (0xFA, 0xFF)):
    bus.ids = ids
    bus.reset(0)
    bus.reset(1)
    try:
        bmi055.BMI055(bus, Cs(bus, 0), Cs(bus, 1), sleep_ms=sleeps.append)
    except bmi055.Bmi055Error as e:
        errs.append(str(e))
try:
    bmi055.BMI055(bus, Cs(bus, 0), Cs(bus, 1), gyro_range_dps=200)
except ValueError as e:
    errs.append(str(e))
res['errs'] = errs
print(json.dumps(res))
"""
    )
    assert out["regs"] == [0x03, 0x83, 0x03, 0x0C]
    assert out["sleeps"] == [30, 2]
    assert out["sens"] == [1312, 1024]
    for (g, a), (vg, va, sat, mask, new) in zip(cases, out["cases"], strict=True):
        assert vg == g and va == a and new == 0b111
        want = [c >= 32766 or c <= -32767 for c in g] + [c >= 2046 or c <= -2047 for c in a]
        assert sat is any(want)
        assert mask == sum(1 << i for i, w in enumerate(want) if w)
    assert out["temp"] == -2
    assert out["locked_read"] is True and out["locked_temp"] is True
    assert out["blocks"] == 0
    assert out["mem_total"] == 0 and out["peak"] == 0
    assert out["after"] == [[-32768, 32767, 1], [-2048, 2047, 1], True]
    errs = out["errs"]
    assert "accel die: expected chip ID 0xFA at register 0x00, read 0xFF" in errs[0]
    assert "gyro die: expected chip ID 0x0F at register 0x00, read 0xFF" in errs[0]
    assert errs[1].startswith("BMI055 accel die: expected chip ID 0xFA at register 0x00, read 0x00")
    assert "check the accel chip-select pin" in errs[1]
    assert errs[2].startswith("BMI055 gyro die: expected chip ID 0x0F at register 0x00, read 0xFF")
    assert errs[3] == "BMI055 gyro range must be 125, 250, 500, 1000 or 2000 deg/s, got 200"
    print(json.dumps({"vm_us_per_read": out["us_per_read"]}))


def test_the_native_decode_equals_the_python_reference():
    """bmi055_decode (navk) against _decode_py on random registers and on every edge the
    decoding has: sign, the over-range counts, the accel new_data bit."""
    from array import array

    import kern

    assert kern.NATIVE and bmi055._decode is not bmi055._decode_py
    rng = np.random.default_rng(5)
    words = ((0xFE, 0x7F), (0xFF, 0x7F), (0x01, 0x80), (0x00, 0x80), (0x00, 0x00), (0xFF, 0xFF),
             (0xE1, 0x7F), (0x10, 0x80), (0xF1, 0x7F))  # fmt: skip
    edges = [bytes(w) for w in words]
    cases = [bytes(rng.integers(0, 256, 6, dtype=np.uint8)) for _ in range(3000)]
    cases += [a + b + c for a in edges for b in edges for c in edges[:3]]
    for g_raw in cases[::7] + cases[-27:]:
        for a_raw in cases[:40]:
            want = [array("h", bytes(6)), array("h", bytes(6))]
            got = [array("h", bytes(6)), array("h", bytes(6))]
            m_want = bmi055._decode_py(*want, g_raw, a_raw)
            m_got = bmi055._decode(*got, g_raw, a_raw)
            assert (m_got, list(got[0]), list(got[1])) == (m_want, list(want[0]), list(want[1]))
