"""A fake SPI bus and chip-select pins with the subset of machine.SPI / machine.Pin the
firmware's drivers use, routing every byte to the device whose chip select is low.

    bus = FakeSPI(1, baudrate=5_000_000, polarity=0, phase=0)
    cs = FakePin("A4", FakePin.OUT, value=1)
    bus.attach(device, cs)          # device: select(), exchange(byte) -> int | None, deselect()

A device sees `select()` on the falling edge of its chip select, one `exchange(mosi)` per
byte clocked while it is selected (returning its MISO byte, or None when it leaves MISO
floating), and `deselect()` on the rising edge. A floating MISO reads `miso_idle` (0xFF
with a pull-up, the usual case; 0x00 with a pull-down).

Driver bugs are loud when `strict` (the default): clocking bytes with no chip select low,
or with two low at once, raises RuntimeError. An SPI mode other than 0 or 3 shifts every
byte by one bit (the devices sample on the wrong edge), as a real bus would mangle them.
Nothing here depends on the rest of the emulator.
"""


class FakePin:
    """machine.Pin stand-in: value(), on(), off(), high(), low(), calling the pin, init()."""

    IN = 0
    OUT = 1
    OPEN_DRAIN = 2
    PULL_UP = 1
    PULL_DOWN = 2

    def __init__(self, id=None, mode=-1, pull=-1, value=None):
        self.id = id
        self.mode = mode
        self.pull = pull
        self._value = 1 if value is None else int(bool(value))
        self._watchers = []
        self.edges = 0  # level changes seen (for tests)

    def init(self, mode=-1, pull=-1, value=None):
        if mode != -1:
            self.mode = mode
        if pull != -1:
            self.pull = pull
        if value is not None:
            self.value(value)

    def watch(self, fn):
        """Call fn(level) on every level change (the bus uses this for chip selects)."""
        self._watchers.append(fn)

    def value(self, v=None):
        if v is None:
            return self._value
        v = int(bool(v))
        if v != self._value:
            self._value = v
            self.edges += 1
            for fn in self._watchers:
                fn(v)
        return None

    def __call__(self, v=None):
        return self.value(v)

    def on(self):
        self.value(1)

    def off(self):
        self.value(0)

    high = on
    low = off

    def __repr__(self):
        return f"FakePin({self.id!r}, value={self._value})"


class FakeSPI:
    """machine.SPI stand-in: write, read, readinto, write_readinto, init, deinit."""

    MSB = 0
    LSB = 1

    def __init__(
        self,
        id=1,
        baudrate=1_000_000,
        polarity=0,
        phase=0,
        bits=8,
        firstbit=MSB,
        *,
        miso_idle=0xFF,
        strict=True,
        record=False,
        **_pins,
    ):
        self.id = id
        self.miso_idle = miso_idle
        self.strict = strict
        self.record = record
        self.transactions = []  # when record: [device name, mosi bytearray, miso bytearray]
        self.bytes_clocked = 0
        self.stray_bytes = 0  # clocked with no device selected (non-strict)
        self._devices = []  # (device, cs pin)
        self._low = []  # devices whose chip select is low now (kept by the pins' edges)
        self._open = None  # the transaction being recorded
        self.init(baudrate, polarity, phase, bits, firstbit)

    def init(self, baudrate=1_000_000, polarity=0, phase=0, bits=8, firstbit=MSB, **_kw):
        if bits != 8:
            raise ValueError("FakeSPI supports 8-bit transfers only")
        self.baudrate = baudrate
        self.polarity = polarity
        self.phase = phase
        self.bits = bits
        self.firstbit = firstbit

    def deinit(self):
        pass

    @property
    def mode(self):
        return (self.polarity << 1) | self.phase

    def attach(self, device, cs):
        """Route bytes to `device` while the FakePin `cs` is low."""
        self._devices.append((device, cs))

        def on_edge(level):
            if level == 0:
                self._low.append(device)
                device.select()
                if self.record:
                    self._open = [getattr(device, "name", repr(device)), bytearray(), bytearray()]
                    self.transactions.append(self._open)
            else:
                if device in self._low:
                    self._low.remove(device)
                device.deselect()
                self._open = None

        cs.watch(on_edge)
        if cs.value() == 0:
            on_edge(0)

    # -- one byte --

    def _selected(self):
        low = self._low
        if not low:
            return None
        if len(low) > 1:
            names = ", ".join(getattr(d, "name", repr(d)) for d in low)
            raise RuntimeError(f"SPI bus contention: several chip selects low ({names})")
        return low[0]

    def _exchange(self, mosi):
        self.bytes_clocked += 1
        device = self._selected()
        if device is None:
            if self.strict:
                raise RuntimeError("SPI transfer with no chip select low")
            self.stray_bytes += 1
            return self.miso_idle
        wrong_edge = self.firstbit != self.MSB or self.mode not in (0, 3)
        seen = ((mosi << 1) & 0xFF) if wrong_edge else mosi
        miso = device.exchange(seen)
        miso = self.miso_idle if miso is None else miso & 0xFF
        if wrong_edge:
            miso = (miso >> 1) | (self.miso_idle & 0x80)
        if self._open is not None:
            self._open[1].append(mosi)
            self._open[2].append(miso)
        return miso

    # -- machine.SPI API --

    def write(self, buf):
        for b in bytes(buf):
            self._exchange(b)

    def read(self, nbytes, write=0x00):
        return bytes(self._exchange(write) for _ in range(nbytes))

    def readinto(self, buf, write=0x00):
        mv = memoryview(buf)
        for i in range(len(mv)):
            mv[i] = self._exchange(write)

    def write_readinto(self, write_buf, read_buf):
        out = bytes(write_buf)
        if len(out) != len(read_buf):
            raise ValueError("buffers must be the same length")
        mv = memoryview(read_buf)
        for i, b in enumerate(out):
            mv[i] = self._exchange(b)
