"""The emulated board's `machine`: the stm32 port's API subset that firmware/board.py and the
drivers use, backed by emulated peripherals on a virtual clock. Plain Python that runs in the
MicroPython VM and on CPython alike, the one emulated board of every runtime:

- in the VM, host_emulator/board/mpy/emulate.py puts this directory first on sys.path, so the
  firmware's `import machine` (and `import time`) find these files instead of the built-ins;
- on CPython, host_emulator/firmware_env.install_machine() loads this file as `machine` and
  puts board/mpy/time.py's MicroPython-only functions on CPython's `time`; several boards run
  one after another in one process, each starting with `power_on()`.

The parts:

- `Pin(name, ...)`: one object per pin name (the constructor returns the existing pin and
  re-initialises it); value()/on()/off()/irq(); `fire()` runs the interrupt handler like an
  ISR (the emulator calls it for a PPS edge). A chip-select pin tells the die wired to it
  when it falls (select) and rises (deselect).
- `SPI(id, ...)`: one bus per id; write/readinto/write_readinto/read clock bytes through the
  device whose chip select is low (`spi_bus(id).attach(die, pin(name))`). A floating MISO
  reads `miso_idle` (0xFF); two chip selects low, or none, raises RuntimeError (a driver
  bug); an SPI mode other than 0/3 or LSB-first shifts every byte by one bit, as a real bus
  mangles it. `log`: None, or a list that gets [device name, MOSI bytearray, MISO bytearray]
  for every chip-select assertion on the bus (tests; it allocates).
- `Bmi055` (both dies, `GyroDie`/`AccelDie`): the register model: chip IDs 0xFA (accel) /
  0x0F (gyro); range 0x0F and bandwidth 0x10 reset values and writable masks; read-only
  0x00..0x0E; soft reset (0xB6 to 0x14) when the chip select rises, then silent for the
  start-up time on the virtual clock (gyro 30 ms, accel 1.8 ms); data 0x02..0x07 set by the
  emulator exactly as given (new_data bits included), INT_STATUS 0x0A bit 7 set by a new
  sample and cleared by a data read, the accel axis' new_data bit cleared when either of its
  bytes is read; temperature 0x08. Faults: `responds`, `chip_id`, `ignore_writes`. `writes`
  lists the accepted register writes as (reg, value) (start-up only; tests).
- `UART(id, ...)`: one port per id; a receive ring of `rxbuf` bytes (default 64, as the
  port); bytes that arrive (`feed`) when it is full are dropped and counted in `overflow`;
  any()/readinto(buf, n) (None when nothing has arrived); write() appends to a preallocated
  transmit buffer the emulator empties (`tx`, `tx_n`, `tx_clear()`); what does not fit is
  counted in `tx_overflow`.
- `Timer(-1, mode, freq, callback)`: fired by `fire_timers()` (every tick, whatever freq).
- `WDT(timeout=ms)`: counts feeds; `idle()`.

Emulation is not firmware: on the emulated Cortex-M4F (runtimes/m4f) every method the firmware
calls per tick runs between `_emu_in()` and `_emu_out()`, the `m4f` module's counter of the
instructions spent emulating (subtracted from the firmware's count); an interrupt handler the
emulator fires runs outside such a bracket, since it is the firmware's code. Elsewhere (no `m4f`
module) the two are empty functions. What the firmware holds on the emulated Cortex-M4F is not
the part but its `m4f.Periph` (`_handle`): calling a method then costs a C method call, as the
board's machine classes have, and the Python method runs inside a bracket opened in C, so that
its call (a frame of more than 11 words is allocated on the heap: py/objfun.c) is emulation too.

Time: `time.now_us()` of board/mpy/time.py (us since power-on). Allocation: everything the
firmware calls per tick (Pin.value, SPI write/readinto, UART any/readinto/write, WDT.feed)
allocates nothing: integer work on preallocated buffers, index loops, no slices (but the
stack-allocated slice of a whole-buffer store, and on CPython, where it costs nothing that
matters, the BMI055's burst read), tuples or bound methods; tests prove it under
micropython.heap_lock(). Construction allocates.
"""

import sys
import time

# Slices allocate on MicroPython (the firmware's ticks there must not), not on CPython, where
# they are the faster way to move bytes
_SLICES = sys.implementation.name != "micropython"

try:
    from m4f import Periph as _Periph
    from m4f import emu_in as _emu_in
    from m4f import emu_out as _emu_out
except ImportError:
    _Periph = None

    def _emu_in():
        pass

    def _emu_out():
        pass


_pins = {}
_buses = {}
_uarts = {}
_timers = []
watchdog = None  # the WDT the firmware created, if any


def _part(table, cls, key):
    """The emulated part `key` of class cls (made on first use with cls._setup, not through
    its constructor, so that it is not re-initialised)."""
    part = table.get(key)
    if part is None:
        part = object.__new__(cls)
        part._setup(key)
        table[key] = part
    return part


def power_on(t_us=0):
    """The board as at power-on: no pins, buses, UARTs, timers or watchdog yet, the clock at
    t_us. A new VM starts so; on CPython the runtime calls it before every run (the firmware's
    modules keep this module, so its tables are emptied rather than the module reloaded)."""
    global _pins, _buses, _uarts, _timers, watchdog
    _pins = {}
    _buses = {}
    _uarts = {}
    _timers = []
    watchdog = None
    time.set_us(t_us)


def _handle(part, args, kwargs):
    """What the firmware's constructor call returns: the emulated part itself or, on the emulated
    Cortex-M4F, its C handle (`m4f.Periph`: its methods are C, as the board's are); the part is
    then initialised here, since Python calls __init__ only for an instance of the class."""
    if _Periph is None:
        return part
    part.__init__(*args, **kwargs)
    return _Periph(part)


def pin(name):
    """The emulated pin `name` (level 1 when new)."""
    return _part(_pins, Pin, name)


def spi_bus(id):
    """The emulated SPI bus `id`."""
    return _part(_buses, SPI, id)


def uart(id):
    """The emulated UART `id`."""
    return _part(_uarts, UART, id)


def fire_timers():
    """Every running timer's callback, as its interrupt would call it (one period elapsed)."""
    for i in range(len(_timers)):
        t = _timers[i]
        if t.callback is not None:
            _emu_out()
            t.callback(t)
            _emu_in()


def idle():
    """Wait for an interrupt: nothing to wait for on the virtual board."""


def disable_irq():
    return 0


def enable_irq(state=0):
    pass


# ---- pins ---------------------------------------------------------------------------------


class Pin:
    """machine.Pin: one object per name; `fire()` is a rising edge for the emulator."""

    IN = 0
    OUT = 1
    OPEN_DRAIN = 2
    ALT = 3
    ANALOG = 4
    PULL_NONE = 0
    PULL_UP = 1
    PULL_DOWN = 2
    IRQ_RISING = 1
    IRQ_FALLING = 2

    def __new__(cls, id, *args, **kwargs):
        return _handle(pin(id), (id,) + args, kwargs)

    def __init__(self, id, mode=-1, pull=-1, value=None, **kwargs):
        self.init(mode, pull, value)

    def _setup(self, name):
        self.id = name
        self.mode = -1
        self.pull = -1
        self._v = 1
        self._dev = None  # a die whose chip select this is
        self._bus = None  # the SPI bus of that die
        self.edges = 0  # level changes (tests)
        self.irq_handler = None
        self.irq_trigger = 0
        self.fired = 0  # interrupts delivered by fire()

    def init(self, mode=-1, pull=-1, value=None, **kwargs):
        if mode != -1:
            self.mode = mode
        if pull != -1:
            self.pull = pull
        if value is not None:
            self.value(value)

    def value(self, v=None):
        """The level (0/1), or set it; a chip select's edge selects/deselects its die."""
        if v is None:
            return self._v
        _emu_in()
        v = 1 if v else 0
        if v != self._v:
            self._v = v
            self.edges += 1
            dev = self._dev
            if dev is not None:
                if v:
                    dev.deselect()
                else:
                    log = self._bus.log
                    if log is not None:
                        log.append([dev.name, bytearray(), bytearray()])
                    dev.select()
        _emu_out()
        return None

    def __call__(self, v=None):
        return self.value(v)

    def on(self):
        self.value(1)

    def off(self):
        self.value(0)

    def high(self):
        self.value(1)

    def low(self):
        self.value(0)

    def irq(self, handler=None, trigger=3, hard=False, **kwargs):
        """Keep the handler for `fire()` (a rising edge)."""
        self.irq_handler = handler
        self.irq_trigger = trigger
        return None

    def fire(self):
        """A rising edge on the pin (e.g. PPS): runs the handler like an ISR, if one is set
        for rising edges."""
        h = self.irq_handler
        if h is not None and self.irq_trigger & 1:
            self.fired += 1
            _emu_out()
            h(self)
            _emu_in()


# ---- SPI and the BMI055 ------------------------------------------------------------------


class SPI:
    """machine.SPI(id, ...): the emulated bus `id`, set up as asked."""

    MSB = 0
    LSB = 1

    def __new__(cls, id, *args, **kwargs):
        return _handle(spi_bus(id), (id,) + args, kwargs)

    def __init__(self, id, baudrate=1000000, polarity=0, phase=0, bits=8, firstbit=0, **kw):
        self.init(baudrate, polarity, phase, bits, firstbit)

    def _setup(self, id):
        self.id = id
        self.miso_idle = 0xFF  # a floating MISO with the usual pull-up
        self.bytes_clocked = 0
        self.log = None  # or a list: [device name, MOSI bytearray, MISO bytearray] per selection
        self._devs = []
        self.init()

    def init(self, baudrate=1000000, polarity=0, phase=0, bits=8, firstbit=0, **kw):
        if bits != 8:
            raise ValueError("the emulated SPI supports 8-bit transfers only")
        self.baudrate = baudrate
        self.polarity = polarity
        self.phase = phase
        self.bits = bits
        self.firstbit = firstbit
        mode = (polarity << 1) | phase
        self._wrong_edge = firstbit != 0 or not (mode == 0 or mode == 3)

    def deinit(self):
        pass

    def attach(self, dev, cs):
        """Route bytes to `dev` (select(), exchange(mosi) -> int, -1 floating, deselect())
        while the Pin `cs` is low."""
        cs._dev = dev
        cs._bus = self
        self._devs.append(dev)
        dev.cs = cs
        if cs._v == 0:
            if self.log is not None:
                self.log.append([dev.name, bytearray(), bytearray()])
            dev.select()

    def _device(self):
        """The one device whose chip select is low."""
        found = None
        devs = self._devs
        for i in range(len(devs)):
            d = devs[i]
            if d.cs._v == 0:
                if found is not None:
                    raise RuntimeError("SPI bus contention: several chip selects low")
                found = d
        if found is None:
            raise RuntimeError("SPI transfer with no chip select low")
        return found

    def _x(self, dev, mosi):
        """One byte clocked: MOSI to the device, MISO back."""
        self.bytes_clocked += 1
        if self._wrong_edge:
            miso = dev.exchange((mosi << 1) & 0xFF)
            if miso < 0:
                miso = self.miso_idle
            miso = ((miso & 0xFF) >> 1) | (self.miso_idle & 0x80)
        else:
            miso = dev.exchange(mosi)
            if miso < 0:
                miso = self.miso_idle
            miso &= 0xFF
        log = self.log
        if log is not None:
            t = log[-1]
            t[1].append(mosi)
            t[2].append(miso)
        return miso

    def _fast(self, dev):
        """The transfer can go to the device's `transfer` (its exchange for each byte, in one
        call: the emulator's hot path): right clock edge, no log."""
        return not self._wrong_edge and self.log is None and hasattr(dev, "transfer")

    def write(self, buf):
        _emu_in()
        dev = self._device()
        if self._fast(dev):
            dev.transfer(buf, None, 0, len(buf), self.miso_idle)
            self.bytes_clocked += len(buf)
        else:
            for i in range(len(buf)):
                self._x(dev, buf[i])
        _emu_out()

    def readinto(self, buf, write=0):
        _emu_in()
        dev = self._device()
        if self._fast(dev):
            dev.transfer(None, buf, write, len(buf), self.miso_idle)
            self.bytes_clocked += len(buf)
        else:
            for i in range(len(buf)):
                buf[i] = self._x(dev, write)
        _emu_out()

    def write_readinto(self, write_buf, read_buf):
        n = len(write_buf)
        if n != len(read_buf):
            raise ValueError("buffers must be the same length")
        _emu_in()
        dev = self._device()
        if self._fast(dev):
            dev.transfer(write_buf, read_buf, 0, n, self.miso_idle)
            self.bytes_clocked += n
        else:
            for i in range(n):
                read_buf[i] = self._x(dev, write_buf[i])
        _emu_out()

    def read(self, nbytes, write=0):
        buf = bytearray(nbytes)
        self.readinto(buf, write)
        return bytes(buf)


REG_CHIP_ID = 0x00
REG_DATA = 0x02
REG_TEMP = 0x08
REG_INT_STATUS = 0x0A
REG_RANGE = 0x0F
REG_BW = 0x10
REG_SOFTRESET = 0x14
SOFTRESET_CMD = 0xB6
_N_REGS = 0x80
_READ_ONLY_END = 0x0F  # 0x00..0x0E ignore writes


class _Die:
    """One BMI055 die: register file, SPI protocol (address byte, bit 7 = read, then
    auto-incremented registers, no dummy byte), soft reset and start-up time, faults
    (`responds`, `chip_id`, `ignore_writes` as in bmi055_model)."""

    name = "die"
    CHIP_ID = 0
    STARTUP_US = 0
    RANGE_RESET = 0
    BW_RESET = 0
    RANGE_MASK = 0xFF
    BW_MASK = 0xFF
    BW_ONES = 0x00
    IS_ACCEL = False

    def __init__(self, chip_id=None):
        self.chip_id = self.CHIP_ID if chip_id is None else chip_id
        self.responds = True
        self.ignore_writes = False
        self.regs = bytearray(_N_REGS)
        self.resets = 0  # soft resets performed
        self.writes = []  # (reg, value) of every accepted write (the driver writes at start-up)
        self.reads = 0  # register bytes read (not counting the chip ID)
        self.cs = None
        self._ready_at = -1  # virtual us when the start-up after a reset ends; -1 ready
        self._reset_pending = False
        self._selected = False
        self._addr = -1  # -1: the next byte is the address
        self._is_read = False
        self._load_defaults()

    def _load_defaults(self):
        regs = self.regs
        for i in range(_N_REGS):
            regs[i] = 0
        regs[REG_RANGE] = self.RANGE_RESET
        regs[REG_BW] = self.BW_RESET
        regs[REG_CHIP_ID] = self.chip_id & 0xFF

    def busy(self):
        """True while the die is starting up after a soft reset."""
        if self._ready_at < 0:
            return False
        if time.now_us() >= self._ready_at:
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
        if self.ignore_writes or reg < _READ_ONLY_END:
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
            self._ready_at = time.now_us() + self.STARTUP_US

    def set_registers(self, buf, off=0):
        """Data registers 0x02..0x07 = buf[off:off + 6] exactly (new_data bits included);
        sets INT_STATUS bit 7 (data_int)."""
        regs = self.regs  # written out: the emulator's hot path
        d = REG_DATA
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
    """Both dies of one BMI055 (present=False: neither answers)."""

    def __init__(self, present=True, accel_chip_id=None, gyro_chip_id=None):
        self.accel = AccelDie(accel_chip_id)
        self.gyro = GyroDie(gyro_chip_id)
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
        """int8, 0.5 K per LSB, 0 = 23 degC (both dies)."""
        self.accel.set_temperature_raw(raw)
        self.gyro.set_temperature_raw(raw)


# ---- UART -------------------------------------------------------------------------------

# Transmit buffer bytes of a UART made from now on; the emulator empties it between ticks. The
# emulated Cortex-M4F, whose heap is the board's, sets it smaller before the firmware starts.
TX_CAPACITY = 16384


class UART:
    """machine.UART(id, baudrate, rxbuf=..., ...): the emulated port `id`."""

    def __new__(cls, id, *args, **kwargs):
        return _handle(uart(id), (id,) + args, kwargs)

    def __init__(self, id, baudrate=9600, bits=8, parity=None, stop=1, **kwargs):
        self.init(baudrate, bits, parity, stop, **kwargs)

    def _setup(self, id):
        self.id = id
        self.overflow = 0  # received bytes dropped because the ring was full
        self.tx_overflow = 0  # written bytes that did not fit the transmit buffer
        self.tx = bytearray(TX_CAPACITY)
        self.tx_n = 0
        self.init()

    def init(self, baudrate=9600, bits=8, parity=None, stop=1, rxbuf=64, txbuf=0, **kwargs):
        """(Re)configure: a new, empty receive ring of rxbuf bytes."""
        self.baudrate = baudrate
        self.rxbuf = rxbuf
        self.txbuf = txbuf
        self.timeout = kwargs.get("timeout", 0)
        self._ring = bytearray(rxbuf if rxbuf > 0 else 1)
        self._head = 0  # next byte to read
        self._count = 0

    def deinit(self):
        pass

    # -- emulator side --

    def feed(self, buf, n=-1):
        """Bytes buf[0:n] arrived (all of buf if n < 0); what does not fit the receive ring
        is lost and counted in `overflow`, as on the board."""
        if n < 0:
            n = len(buf)
        ring = self._ring
        size = self.rxbuf
        room = size - self._count
        if n > room:
            self.overflow += n - room
            n = room
        w = self._head + self._count
        for i in range(n):
            if w >= size:
                w -= size
            ring[w] = buf[i]
            w += 1
        self._count += n

    def tx_clear(self):
        """Forget the transmitted bytes (after the emulator saved tx[0:tx_n])."""
        self.tx_n = 0

    # -- the machine.UART API the firmware uses --

    def any(self):
        _emu_in()
        n = self._count
        _emu_out()
        return n

    def readinto(self, buf, nbytes=-1):
        """Up to nbytes (default len(buf)) received bytes into buf; the count, or None when
        nothing has arrived (the stm32 port with timeout=0)."""
        _emu_in()
        n = len(buf)
        if 0 <= nbytes < n:
            n = nbytes
        if n > self._count:
            n = self._count
        if n <= 0:
            _emu_out()
            return None
        ring = self._ring
        size = self.rxbuf
        r = self._head
        for i in range(n):
            buf[i] = ring[r]
            r += 1
            if r >= size:
                r = 0
        self._head = r
        self._count -= n
        _emu_out()
        return n

    def read(self, nbytes=-1):
        """Received bytes as a new bytes object (allocates), or None."""
        n = self._count if nbytes < 0 or nbytes > self._count else nbytes
        if n <= 0:
            return None
        buf = bytearray(n)
        self.readinto(buf, n)
        return bytes(buf)

    def write(self, buf):
        """Append buf to the transmit buffer; returns the bytes accepted."""
        _emu_in()
        m = len(buf)
        tx = self.tx
        n = self.tx_n
        room = len(tx) - n
        if m > room:
            self.tx_overflow += m - room
            m = room
            for i in range(m):
                tx[n + i] = buf[i]
        else:
            tx[n : n + m] = buf  # no allocation on MicroPython either (a stack slice)
        self.tx_n = n + m
        _emu_out()
        return m


# ---- timer, watchdog ----------------------------------------------------------------------


class Timer:
    """machine.Timer(-1, mode=PERIODIC, freq=..., callback=...): fired by fire_timers()."""

    ONE_SHOT = 0
    PERIODIC = 1

    def __init__(self, id=-1, mode=PERIODIC, freq=None, period=None, callback=None, **kw):
        self.id = id
        self.callback = None
        self.init(mode=mode, freq=freq, period=period, callback=callback)

    def init(self, mode=PERIODIC, freq=None, period=None, callback=None, **kw):
        self.mode = mode
        self.freq = freq
        self.period = period
        self.callback = callback
        if self not in _timers:
            _timers.append(self)

    def deinit(self):
        if self in _timers:
            _timers.remove(self)


class WDT:
    """machine.WDT(timeout=ms): counts feeds and remembers the last one (virtual us)."""

    def __new__(cls, *args, **kwargs):
        return _handle(object.__new__(cls), args, kwargs)

    def __init__(self, id=0, timeout=5000):
        global watchdog
        self.timeout_ms = timeout
        self.feeds = 0
        self.last_feed_us = time.now_us()
        watchdog = self

    def feed(self):
        _emu_in()
        self.feeds += 1
        self.last_feed_us = time.now_us()
        _emu_out()
