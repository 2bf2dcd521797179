"""The emulated board's `machine`: the stm32 port's API subset that firmware/board.py and the
drivers use, backed by emulated peripherals on a virtual clock. Plain Python that runs in the
MicroPython VM and on CPython alike, the one emulated board of every runtime:

- in the VM, host_emulator/emulated_board/mpy/emulate.py puts this directory first on
  sys.path, so the firmware's `import machine` (and `import time`) find these files instead of
  the built-ins;
- on CPython, host_emulator.emulated_board.install_machine() loads bmi055_model.py and this file
  as the modules `bmi055_model` and `machine`, and puts emulated_board/mpy/time.py's
  MicroPython-only functions on CPython's `time`; several boards run one after another in one
  process, each starting with `power_on()`.

The API is the stm32 port's (MicroPython v1.28.0, ports/stm32 and extmod/machine_*.c: the
spec): a constructor or method takes the arguments its C takes, positional where the C allows
them positionally, and refuses the rest as the port does (`_parse`, py/argcheck.c's
mp_arg_parse_all: TypeError "extra keyword arguments given", "extra positional arguments
given", "'x' argument required"; `txbuf`, which the port has not, is refused). Values the
port refuses raise its ValueError (pin modes, pulls and alternate functions, UART bits with
parity, Timer ids, WDT ids and timeouts, SPI pins); constants are the port's (the F4 HAL's).
tests/firmware/test_machine_api.py derives the port's argument tables from its C source and
checks these against them, and the firmware's calls too.

One module, as the port's `machine` is one module (the firmware imports it whole), and the
only one of its size here on purpose: split into files, its parts would become modules the
firmware does not know, and on the emulated Cortex-M4F each module's globals come out of the
reserve the emulated board has beside the board's heap (runtimes/m4f/build.py).

The parts:

- `Pin(name, ...)`: one object per pin name (the constructor returns the existing pin and, given
  more than the name, re-initialises it: `init(mode, pull=None, af=-1, *, value, alt)`);
  value()/on()/off()/irq(handler=None, trigger=IRQ_RISING | IRQ_FALLING, hard=False); `fire()`
  runs the interrupt handler like an ISR (the emulator calls it for a PPS edge). A chip-select
  pin tells the die wired to it when it falls (select) and rises (deselect).
- `SPI(id, baudrate=500000, *, polarity, phase, bits, firstbit)`: one bus per id;
  write/readinto/write_readinto/read clock bytes through the device whose chip select is low
  (`spi_bus(id).attach(die, pin(name))`). A floating MISO reads `miso_idle` (0xFF); two chip
  selects low, or none, raises RuntimeError (a driver bug); an SPI mode other than 0/3 or
  LSB-first shifts every byte by one bit, as a real bus mangles it; 16-bit frames are not
  emulated (ValueError). `log`: None, or a list that gets [device name, MOSI bytearray, MISO
  bytearray] for every chip-select assertion on the bus (tests; it allocates).
- `Bmi055` (both dies, `GyroDie`/`AccelDie`): the BMI055 register model, bmi055_model.py beside
  this file, re-exported here; its dies run on this board's clock (`time.now_us`).
- `UART(id, baudrate, bits=8, parity=None, stop=1, *, flow, timeout, timeout_char, rxbuf,
  read_buf_len)`: one port per id; UART(id) alone returns it unchanged, as the port. A receive
  ring of `rxbuf` bytes (default 64, as the port); bytes that arrive (`feed`) when it is full
  are dropped and counted in `overflow`; any()/readinto(buf, n) (None when nothing has
  arrived); write() and writechar() append to a preallocated transmit buffer the emulator
  empties (`tx`, `tx_n`, `tx_clear()`); what does not fit is counted in `tx_overflow`.
- `Timer(-1, *, mode, callback, period, tick_hz, freq, hard)` (the port's soft timer, the only
  id it has): fired by `fire_timers()` (every tick, whatever its period).
- `WDT(id=0, timeout=5000)`: counts feeds; `idle()`, `disable_irq()`, `enable_irq(state)`.

Emulation is not firmware: on the emulated Cortex-M4F (runtimes/m4f) every method the firmware
calls per tick runs between `_emu_in()` and `_emu_out()`, the `m4f` module's counter of the
instructions spent emulating (subtracted from the firmware's count); an interrupt handler the
emulator fires runs outside such a bracket, since it is the firmware's code. Elsewhere (no `m4f`
module) the two are empty functions. What the firmware holds on the emulated Cortex-M4F is not
the part but its `m4f.Periph` (`_handle`): calling a method then costs a C method call, as the
board's machine classes have, and the Python method runs inside a bracket opened in C, so that
its call (a frame of more than 11 words is allocated on the heap: py/objfun.c) is emulation too.

Time: `time.now_us()` of emulated_board/mpy/time.py (us since power-on). Allocation: everything the
firmware calls per tick (Pin.value, SPI write/readinto, UART any/readinto/write, WDT.feed)
allocates nothing: integer work on preallocated buffers, index loops, no slices (but the
stack-allocated slice of a whole-buffer store), tuples or bound methods; tests prove it under
micropython.heap_lock(). Construction allocates (its argument parsing too).
"""

import time

from bmi055_model import (  # noqa: F401 (machine.Bmi055 and the rest, as before the split)
    REG_BW,
    REG_CHIP_ID,
    REG_DATA,
    REG_INT_STATUS,
    REG_RANGE,
    REG_SOFTRESET,
    REG_TEMP,
    SOFTRESET_CMD,
    AccelDie,
    Bmi055,
    GyroDie,
    _Die,
)
from micropython import const

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
    """Wait for an interrupt (WFI): nothing to wait for on the virtual board."""


def disable_irq():
    """Mask interrupts; the state to give enable_irq: whether they were enabled, a bool as
    the stm32 port's (ports/stm32/irq.c; interrupts are never held off here)."""
    return True


def enable_irq(state):
    """Interrupts enabled if state is true, masked if false: the port's takes a bool, not a
    PRIMASK value (`enable_irq(0)` masks them). Nothing to do here."""


# ---- arguments as the port parses them ----------------------------------------------------

# Flags of an argument, py/runtime.h's MP_ARG_*: its kind, required, keyword-only. The argument
# tables (the classes' _INIT, _NEW, _IRQ and SPI's beside it: (name, flags, default) as the
# C's `allowed_args[]`, `...` for MP_OBJ_NULL, not given) are literals: frozen on the emulated
# Cortex-M4F they are ROM objects, not the board's heap, whose free bytes when the firmware
# starts must be the board's (build.py's EMULATOR_RESERVE_BYTES); hence consts, and few globals.
_BOOL = const(0x001)
_INT = const(0x002)
_OBJ = const(0x003)
_REQUIRED = const(0x100)
_KW_ONLY = const(0x200)


def _int(v):
    """mp_obj_get_int: an int (a bool is one), else TypeError."""
    if isinstance(v, int):
        return int(v)
    raise TypeError("can't convert to int")


def _parse(allowed, args, kwargs):
    """The values of the arguments `allowed` ((name, flags, default) in the C's order, as its
    `mp_arg_t allowed_args[]`) from a call's positional args and keyword kwargs, exactly as
    py/argcheck.c's mp_arg_parse_all takes them, with its TypeErrors: a keyword-only argument
    given positionally or too many positionals ("extra positional arguments given"), a missing
    required one ("'name' argument required"), a keyword nobody takes or one that repeats a
    positional ("extra keyword arguments given"); an int argument must be an int, a bool one
    is taken for its truth."""
    n_pos = len(args)
    values = []
    taken = 0  # keywords used
    for i in range(len(allowed)):
        name, flags, default = allowed[i]
        if i < n_pos:
            if flags & _KW_ONLY:
                raise TypeError("extra positional arguments given")
            v = args[i]
        elif name in kwargs:
            taken += 1
            v = kwargs[name]
        elif flags & _REQUIRED:
            raise TypeError(f"'{name}' argument required")
        else:
            values.append(default)
            continue
        kind = flags & 0xFF
        if kind == _INT:
            v = _int(v)
        elif kind == _BOOL:
            v = bool(v)
        values.append(v)
    if n_pos > len(allowed):
        raise TypeError("extra positional arguments given")
    if taken < len(kwargs):
        raise TypeError("extra keyword arguments given")
    return values


# GPIO modes as the F4 HAL defines them (stm32f4xx_hal_gpio.h)
_GPIO_IN = const(0x00)
_GPIO_OUT = const(0x01)
_GPIO_OPEN_DRAIN = const(0x11)
_GPIO_ALT = const(0x02)
_GPIO_ALT_OPEN_DRAIN = const(0x12)
_GPIO_ANALOG = const(0x03)
_IRQ_RISING = const(0x10110000)  # GPIO_MODE_IT_RISING
_IRQ_FALLING = const(0x10210000)  # GPIO_MODE_IT_FALLING
# ---- pins ---------------------------------------------------------------------------------


class Pin:
    """machine.Pin: one object per name; `fire()` is a rising edge for the emulator."""

    IN = _GPIO_IN
    OUT = _GPIO_OUT
    OPEN_DRAIN = _GPIO_OPEN_DRAIN
    ALT = _GPIO_ALT
    ALT_OPEN_DRAIN = _GPIO_ALT_OPEN_DRAIN
    ANALOG = _GPIO_ANALOG
    PULL_NONE = 0  # a legacy name the port still has (MICROPY_PY_MACHINE_PIN_LEGACY)
    PULL_UP = 1
    PULL_DOWN = 2
    IRQ_RISING = _IRQ_RISING
    IRQ_FALLING = _IRQ_FALLING

    _INIT = (  # ports/stm32/pin.c pin_obj_init_helper: (mode, pull=None, af=-1, *, value, alt)
        ("mode", _REQUIRED | _INT, ...),
        ("pull", _OBJ, None),
        ("af", _INT, -1),  # legacy
        ("value", _KW_ONLY | _OBJ, ...),
        ("alt", _KW_ONLY | _INT, -1),
    )
    _IRQ = (  # ports/stm32/pin.c pin_irq
        ("handler", _OBJ, None),
        ("trigger", _INT, _IRQ_RISING | _IRQ_FALLING),
        ("hard", _BOOL, False),
    )

    def __new__(cls, *args, **kwargs):
        if not args:  # mp_arg_check_num(n_args, n_kw, 1, ...): the name, positionally
            raise TypeError("function missing 1 required positional arguments")
        return _handle(pin(args[0]), args, kwargs)

    def __init__(self, *args, **kwargs):
        if len(args) > 1 or kwargs:  # Pin(name) alone leaves the pin as it is
            self.init(*args[1:], **kwargs)

    def _setup(self, name):
        self.id = name
        self.mode = -1  # not configured yet
        self.pull = -1
        self.alt = -1
        self._v = 1
        self._dev = None  # a die whose chip select this is
        self._bus = None  # the SPI bus of that die
        self.edges = 0  # level changes (tests)
        self.irq_handler = None
        self.irq_trigger = 0
        self.irq_hard = False
        self.fired = 0  # interrupts delivered by fire()

    def init(self, *args, **kwargs):
        """init(mode, pull=None, af=-1, *, value, alt): the port's checks (the F4 HAL's
        IS_GPIO_MODE, IS_GPIO_PULL and, for an alternate function, the STM32F411's IS_GPIO_AF:
        no AF3, 11, 13 or 14), then the level (value, if given) and the configuration."""
        mode, pull, af, value, alt = _parse(Pin._INIT, args, kwargs)
        # IS_GPIO_MODE: these, interrupt on both edges, event on rising, falling or both
        if mode not in (_GPIO_IN, _GPIO_OUT, _GPIO_OPEN_DRAIN, _GPIO_ALT, _GPIO_ALT_OPEN_DRAIN,
                        _GPIO_ANALOG, _IRQ_RISING, _IRQ_FALLING,
                        0x10310000, 0x10120000, 0x10220000, 0x10320000):  # fmt: skip
            raise ValueError(f"invalid pin mode: {mode}")
        pull = 0 if pull is None else _int(pull)
        if pull not in (0, 1, 2):  # GPIO_NOPULL, GPIO_PULLUP, GPIO_PULLDOWN
            raise ValueError(f"invalid pin pull: {pull}")
        if alt == -1:
            alt = af
        f411_afs = (0, 1, 2, 4, 5, 6, 7, 8, 9, 10, 12, 15)  # IS_GPIO_AF for STM32F411xE
        if (mode == _GPIO_ALT or mode == _GPIO_ALT_OPEN_DRAIN) and alt not in f411_afs:
            raise ValueError(f"invalid pin af: {alt}")
        if value is not ...:
            self.value(1 if value else 0)  # value=None is low, as the port takes it
        self.mode = mode
        self.pull = pull
        self.alt = alt

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

    def irq(self, *args, **kwargs):
        """irq(handler=None, trigger=IRQ_RISING | IRQ_FALLING, hard=False): keep the handler
        for `fire()` (a rising edge); irq() with no arguments changes nothing (the port's)."""
        handler, trigger, hard = _parse(Pin._IRQ, args, kwargs)
        if args or kwargs:
            self.irq_handler = handler
            self.irq_trigger = trigger
            self.irq_hard = hard
        return None

    def fire(self):
        """A rising edge on the pin (e.g. PPS): runs the handler like an ISR, if one is set
        for rising edges."""
        h = self.irq_handler
        if h is not None and (self.irq_trigger & _IRQ_RISING) == _IRQ_RISING:
            self.fired += 1
            _emu_out()
            h(self)
            _emu_in()


# ---- SPI ----------------------------------------------------------------------------------


# SPI's tables sit beside its class: its dict (17 entries) is full, one more would grow it
_SPI_NEW = (  # ports/stm32/machine_spi.c machine_hard_spi_make_new
    ("id", _REQUIRED | _OBJ, ...),
    ("baudrate", _INT, 500000),
    ("polarity", _KW_ONLY | _INT, 0),
    ("phase", _KW_ONLY | _INT, 0),
    ("bits", _KW_ONLY | _INT, 8),
    ("firstbit", _KW_ONLY | _INT, 0),
    ("sck", _KW_ONLY | _OBJ, ...),
    ("mosi", _KW_ONLY | _OBJ, ...),
    ("miso", _KW_ONLY | _OBJ, ...),
)
_SPI_INIT = (  # ports/stm32/machine_spi.c machine_hard_spi_init: -1 leaves it as it is
    ("baudrate", _KW_ONLY | _INT, -1),
    ("polarity", _KW_ONLY | _INT, -1),
    ("phase", _KW_ONLY | _INT, -1),
    ("bits", _KW_ONLY | _INT, -1),
    ("firstbit", _KW_ONLY | _INT, -1),
)


class SPI:
    """machine.SPI(id, baudrate=500000, *, polarity=0, phase=0, bits=8, firstbit=MSB): the
    emulated bus `id`, set up as asked (the port's hardware SPI, ports/stm32/machine_spi.c)."""

    MSB = 0  # SPI_FIRSTBIT_MSB
    LSB = 0x80  # SPI_FIRSTBIT_LSB (SPI_CR1_LSBFIRST)

    def __new__(cls, *args, **kwargs):
        if not args or args[0] == -1:
            # SPI() and SPI(-1, ...) are the port's legacy SoftSPI construction
            # (MP_MACHINE_SPI_CHECK_FOR_LEGACY_SOFTSPI_CONSTRUCTION), whose table has no id:
            # SPI(id=1) is refused there. SoftSPI is not emulated.
            if "id" in kwargs:
                raise TypeError("extra keyword arguments given")
            raise NotImplementedError("SoftSPI (SPI() or SPI(-1, ...)) is not emulated")
        return _handle(spi_bus(args[0]), args, kwargs)

    def __init__(self, *args, **kwargs):
        _, baudrate, polarity, phase, bits, firstbit, sck, mosi, miso = _parse(
            _SPI_NEW, args, kwargs
        )
        if sck is not ... or mosi is not ... or miso is not ...:
            raise ValueError("explicit choice of sck/mosi/miso is not implemented")
        self.init(baudrate=baudrate, polarity=polarity, phase=phase, bits=bits, firstbit=firstbit)

    def _setup(self, id):
        self.id = id
        self.miso_idle = 0xFF  # a floating MISO with the usual pull-up
        self.bytes_clocked = 0
        self.log = None  # or a list: [device name, MOSI bytearray, MISO bytearray] per selection
        self._devs = []
        self.baudrate = 500000
        self.polarity = 0
        self.phase = 0
        self.bits = 8
        self.firstbit = SPI.MSB
        self._wrong_edge = False

    def init(self, *args, **kwargs):
        """init(*, baudrate, polarity, phase, bits, firstbit), as spi_set_params
        (ports/stm32/spi.c) takes them: what is given changes (-1 leaves a setting as it is);
        a polarity or phase other than 0 is 1, bits other than 16 are 8."""
        baudrate, polarity, phase, bits, firstbit = _parse(_SPI_INIT, args, kwargs)
        if bits == 16:
            raise ValueError("the emulated SPI supports 8-bit transfers only")
        if baudrate != -1:
            self.baudrate = baudrate
        if polarity != -1:
            self.polarity = 0 if polarity == 0 else 1
        if phase != -1:
            self.phase = 0 if phase == 0 else 1
        if bits != -1:
            self.bits = 8
        if firstbit != -1:
            self.firstbit = firstbit
        mode = (self.polarity << 1) | self.phase
        self._wrong_edge = self.firstbit != SPI.MSB or not (mode == 0 or mode == 3)

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


# ---- UART -------------------------------------------------------------------------------

# Transmit buffer bytes of a UART made from now on; the emulator empties it between ticks. The
# emulated Cortex-M4F, whose heap is the board's, sets it smaller before the firmware starts,
# and makes the buffers then (reserve_tx): a board's UART has none, so they are not the
# firmware's heap (made as the firmware opened its UARTs, they took 3 KB of it)
TX_CAPACITY = 16384
_tx_pool = []


def reserve_tx(n):
    """n transmit buffers of TX_CAPACITY bytes made now, for the next n UARTs made."""
    for _ in range(n):
        _tx_pool.append(bytearray(TX_CAPACITY))


class UART:
    """machine.UART(id, baudrate, bits=8, parity=None, stop=1, *, flow=0, timeout=0,
    timeout_char=0, rxbuf, read_buf_len=64): the emulated port `id` (ports/stm32/machine_uart.c;
    UART(id) alone returns it as it is)."""

    _INIT = (  # ports/stm32/machine_uart.c mp_machine_uart_init_helper (no txbuf)
        ("baudrate", _REQUIRED | _INT, 9600),
        ("bits", _INT, 8),
        ("parity", _OBJ, None),
        ("stop", _INT, 1),
        ("flow", _KW_ONLY | _INT, 0),
        ("timeout", _KW_ONLY | _INT, 0),
        ("timeout_char", _KW_ONLY | _INT, 0),
        ("rxbuf", _KW_ONLY | _INT, -1),
        ("read_buf_len", _KW_ONLY | _INT, 64),  # legacy
    )

    def __new__(cls, *args, **kwargs):
        if not args:  # mp_arg_check_num(n_args, n_kw, 1, ...): the id, positionally
            raise TypeError("function missing 1 required positional arguments")
        return _handle(uart(args[0]), args, kwargs)

    def __init__(self, *args, **kwargs):
        if len(args) > 1 or kwargs:
            self.init(*args[1:], **kwargs)

    def _setup(self, id):
        self.id = id
        self.overflow = 0  # received bytes dropped because the ring was full
        self.rx_waits = 0  # reads that would have waited timeout_char (readinto)
        self.tx_overflow = 0  # written bytes that did not fit the transmit buffer
        self.tx = _tx_pool.pop() if _tx_pool else bytearray(TX_CAPACITY)
        self.tx_n = 0
        self.init(9600)

    def init(self, *args, **kwargs):
        """(Re)configure as the port's init helper: baudrate is required; bits counts the data
        bits (8 or 9, or 7 or 8 with parity: the F4 has no 7-bit word); stop 1, anything else
        is 2; rxbuf (else read_buf_len, the legacy name) the receive ring's bytes, 0 none. A
        new, empty receive ring."""
        baudrate, bits, parity, stop, flow, timeout, timeout_char, rxbuf, read_buf_len = _parse(
            UART._INIT, args, kwargs
        )
        word = bits
        if parity is not None:
            parity = _int(parity) & 1  # odd when bit 0 is set, else even
            word += 1  # ST's word length counts the parity bit
        if word != 8 and word != 9:
            raise ValueError("unsupported combination of bits and parity")
        if rxbuf < 0:
            rxbuf = read_buf_len
        if rxbuf < 0:
            rxbuf = 0
        self.baudrate = baudrate
        self.bits = bits
        self.parity = parity
        self.stop = 1 if stop == 1 else 2
        self.flow = flow
        self.timeout = timeout
        # at least a character's time (13 bits) and 2 ms (the port's SysTick resolution)
        self.timeout_char = max(timeout_char, (13000 // baudrate if baudrate > 0 else 0) + 2)
        self.rxbuf = rxbuf
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
        nothing has arrived (the stm32 port with timeout=0). Asking for more than has arrived
        makes the port wait timeout_char ms after the last byte (mp_machine_uart_read): such a
        read is counted in `rx_waits` (the emulated loop takes no time for it)."""
        _emu_in()
        n = len(buf)
        if 0 <= nbytes < n:
            n = nbytes
        if n > self._count:
            if self._count:
                self.rx_waits += 1
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

    def writechar(self, char):
        """One character (an int; 9 bits at most, as the port's) to the transmit buffer."""
        _emu_in()
        n = self.tx_n
        if n < len(self.tx):
            self.tx[n] = char & 0xFF
            self.tx_n = n + 1
        else:
            self.tx_overflow += 1
        _emu_out()

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
    """machine.Timer(-1, *, mode=PERIODIC, callback, period, tick_hz=1000, freq, hard=False):
    the port's soft timer (extmod/machine_timer.c; -1 is the only id); fired by fire_timers()
    while it has a callback. Timer(-1) alone makes one that does not run."""

    ONE_SHOT = 1  # SOFT_TIMER_MODE_ONE_SHOT
    PERIODIC = 2  # SOFT_TIMER_MODE_PERIODIC

    _INIT = (  # extmod/machine_timer.c machine_timer_init_helper
        ("mode", _KW_ONLY | _INT, 2),  # SOFT_TIMER_MODE_PERIODIC
        ("callback", _KW_ONLY | _OBJ, ...),
        ("period", _KW_ONLY | _INT, -1),  # 0xffffffff, in the C's (32-bit) mp_int_t
        ("tick_hz", _KW_ONLY | _INT, 1000),
        ("freq", _KW_ONLY | _OBJ, None),
        ("hard", _KW_ONLY | _BOOL, False),
    )

    def __init__(self, *args, **kwargs):
        id = -1
        if args:
            id = _int(args[0])
            args = args[1:]
        if id != -1:
            raise ValueError("Timer doesn't exist")
        self.id = id
        self.mode = Timer.PERIODIC
        self.freq = None
        self.period_ms = 1000
        self.callback = None
        self.hard = False
        if args or kwargs:
            self.init(*args, **kwargs)

    def init(self, *args, **kwargs):
        """Stop, then (re)start with what is given: the period from freq (Hz), else from
        period / tick_hz, else as before; at least 1 ms. A callback not given stays."""
        self.deinit()
        mode, callback, period, tick_hz, freq, hard = _parse(Timer._INIT, args, kwargs)
        period_ms = self.period_ms
        if freq is not None:
            if not isinstance(freq, (int, float)):
                raise TypeError("can't convert to float")
            # the port's 1000.0 / freq, cast to uint32 (saturating: 0 Hz is infinitely long)
            period_ms = int(1000.0 / freq) if freq > 0 else (0 if freq < 0 else 0x40000000)
        elif period != -1:  # (uint64_t) of a negative period: too large
            period_ms = period * 1000 // tick_hz if period >= 0 else 0x40000000
        if period_ms < 1:
            period_ms = 1
        elif period_ms >= 0x40000000:
            raise ValueError("period too large")
        self.mode = mode
        self.freq = freq
        self.period_ms = period_ms
        if callback is not ...:
            self.callback = callback
        self.hard = hard
        if self.callback is not None:
            _timers.append(self)

    def deinit(self):
        if self in _timers:
            _timers.remove(self)


class WDT:
    """machine.WDT(id=0, timeout=5000): counts feeds and remembers the last one (virtual us).
    The port's checks: id 0 only; the timeout (ms) must fit the IWDG (1..32767 ms)."""

    _NEW = (  # extmod/machine_wdt.c machine_wdt_make_new
        ("id", _INT, 0),
        ("timeout", _INT, 5000),
    )

    def __new__(cls, *args, **kwargs):
        return _handle(object.__new__(cls), args, kwargs)

    def __init__(self, *args, **kwargs):
        global watchdog
        id, timeout = _parse(WDT._NEW, args, kwargs)
        if id != 0:
            raise ValueError(f"WDT({id}) doesn't exist")
        ticks = timeout  # ports/stm32/machine_wdt.c: prescaler, then 8 ticks per ms
        prescaler = 0
        while prescaler < 6 and ticks >= 512:
            prescaler += 1
            ticks //= 2
        ticks *= 8
        if ticks <= 0:
            raise ValueError("WDT timeout too short")
        if ticks > 0xFFF:
            raise ValueError("WDT timeout too long")
        self.timeout_ms = timeout
        self.feeds = 0
        self.last_feed_us = time.now_us()
        watchdog = self

    def feed(self):
        _emu_in()
        self.feeds += 1
        self.last_feed_us = time.now_us()
        _emu_out()
