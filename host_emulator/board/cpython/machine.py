"""The emulated board on CPython, as a `machine` module: the subset of the stm32 port's API
that `firmware/board.py` uses, backed by emulated peripherals, so the firmware's own board.py,
drivers and loop run unchanged.

One `Hardware` object is the emulated board. Pins are shared by name (`machine.Pin("B6")`
returns the pin the emulator wired a device to), SPI buses by id (devices attached with
`hw.spi(1).attach(device, hw.pin("B6"))`), UARTs by id (`hw.uart(2).feed(b"$GPGGA...")` for
received bytes, `hw.uart(1).take_tx()` for what the firmware sent). Timers and pin interrupts
run only when the emulator says so (`hw.fire_timers()`, `pin.fire()`): time is virtual,
`hw.now_us`, advanced by the emulator (`hw.advance_us`) and by the firmware's `sleep_ms`; the
MicroPython-only `time.ticks_us/ticks_ms/ticks_diff/sleep_ms` read it.

    hw = machine.Hardware()
    firmware_env.install_machine(hw)    # before the firmware imports machine
"""

from host_emulator.board.cpython.spi import FakePin, FakeSPI
from host_emulator.proto.ticks import TICKS_PERIOD, ticks_diff  # noqa: F401 (time.ticks_diff)

_hw = None


def use(hw):
    """Make hw the board that `machine.*` constructors return parts of."""
    global _hw
    _hw = hw


class Pin(FakePin):
    """machine.Pin: one object per pin name; `irq` keeps the handler for `fire()`."""

    IRQ_RISING = 1
    IRQ_FALLING = 2

    def __new__(cls, id, *args, **kwargs):
        return _hw.pin(id)

    def __init__(self, id, mode=-1, pull=-1, value=None):
        self.init(mode, pull, value)

    def irq(self, handler=None, trigger=IRQ_RISING):
        self.irq_handler = handler
        self.irq_trigger = trigger

    def fire(self):
        """A rising edge on an input (e.g. PPS): runs the registered handler like an ISR."""
        handler = getattr(self, "irq_handler", None)
        if handler is not None:
            handler(self)


class SPI:
    """machine.SPI(id, ...) returns the emulated bus `id`, set up as asked."""

    MSB = FakeSPI.MSB

    def __new__(cls, id, baudrate=1_000_000, polarity=0, phase=0, **kwargs):
        bus = _hw.spi(id)
        bus.init(baudrate=baudrate, polarity=polarity, phase=phase)
        return bus


class UARTPort:
    """One UART: bytes the emulator feeds in, bytes the firmware writes out."""

    def __init__(self, id):
        self.id = id
        self.baudrate = None
        self.rxbuf = 64  # the stm32 port's default receive ring
        self.overflow = 0  # received bytes dropped because the ring was full
        self._rx = bytearray()
        self._tx = bytearray()

    def init(self, baudrate=9600, rxbuf=64, **kwargs):
        self.baudrate = baudrate
        self.rxbuf = rxbuf

    def feed(self, data):
        """Bytes that arrived; what does not fit the receive ring is lost, as on the board."""
        room = self.rxbuf - len(self._rx)
        if len(data) > room:
            self.overflow += len(data) - max(room, 0)
            data = data[: max(room, 0)]
        self._rx += data

    def take_tx(self):
        out = bytes(self._tx)
        self._tx = bytearray()
        return out

    # the machine.UART API the firmware uses
    def any(self):
        return len(self._rx)

    def readinto(self, buf, nbytes=None):
        n = min(len(buf), len(self._rx) if nbytes is None else nbytes, len(self._rx))
        if n == 0:
            return None  # as the stm32 port does when nothing has arrived
        buf[:n] = self._rx[:n]
        del self._rx[:n]
        return n

    def write(self, buf):
        self._tx += buf
        return len(buf)


def UART(id, baudrate=9600, **kwargs):
    port = _hw.uart(id)
    port.init(baudrate=baudrate, **kwargs)
    return port


class Timer:
    """machine.Timer(-1, mode=PERIODIC, freq=..., callback=...): fired by hw.fire_timers()."""

    PERIODIC = 1
    ONE_SHOT = 0

    def __init__(self, id=-1, mode=PERIODIC, freq=None, period=None, callback=None):
        self.freq = freq
        self.callback = callback
        _hw.timers.append(self)

    def deinit(self):
        _hw.timers.remove(self)


class WDT:
    """machine.WDT: counts feeds; the emulator checks they keep coming."""

    def __init__(self, id=0, timeout=5000):
        self.timeout_ms = timeout
        self.feeds = 0
        _hw.wdt = self

    def feed(self):
        self.feeds += 1


def idle():
    pass


class Hardware:
    """The emulated board: pins, SPI buses and UARTs by name/id, timers, the watchdog."""

    def __init__(self):
        self.pins = {}
        self.spis = {}
        self.uarts = {}
        self.timers = []
        self.wdt = None
        self.now_us = 0

    def advance_us(self, us):
        self.now_us += us

    def pin(self, name):
        p = self.pins.get(name)
        if p is None:
            p = object.__new__(Pin)
            FakePin.__init__(p, name)
            self.pins[name] = p
        return p

    def spi(self, id):
        if id not in self.spis:
            self.spis[id] = FakeSPI(id)
        return self.spis[id]

    def uart(self, id):
        if id not in self.uarts:
            self.uarts[id] = UARTPort(id)
        return self.uarts[id]

    def fire_timers(self):
        for t in list(self.timers):
            if t.callback is not None:
                t.callback(t)


# MicroPython's time functions on the virtual clock (installed into `time` by firmware_env;
# the tick arithmetic is proto/ticks.py's)


def ticks_us():
    return _hw.now_us % TICKS_PERIOD


def ticks_ms():
    return (_hw.now_us // 1000) % TICKS_PERIOD


def sleep_ms(ms):
    _hw.now_us += 1000 * ms
