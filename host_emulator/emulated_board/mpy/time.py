"""The emulated board's `time`: the board's tick functions on a virtual clock.

In the MicroPython VM this file is `time` (host_emulator/emulated_board/mpy/emulate.py puts this
directory first on sys.path, so the firmware's `import time` finds it instead of the built-in
module). On CPython, host_emulator.emulated_board.install_machine() loads it once and puts its
MicroPython-only functions (ticks_*, sleep_ms, sleep_us, now_us, set_us, advance_us) on
CPython's own `time`, whose time(), sleep() and perf_counter() stay the host's.

The clock is an integer count of microseconds since power-on, `now_us()`. Only the emulator
moves it forward (`set_us`, `advance_us`), and the firmware's own waits (`sleep_ms`,
`sleep_us`) advance it by the time they ask for: the firmware's run time is zero on this clock.
`ticks_us`/`ticks_ms` wrap at 2**30 like the stm32 port's (and common/proto/ticks.py);
`ticks_diff`/`ticks_add` do the port's modular arithmetic. Nothing here allocates (all values
are small ints), so a tick's GC blocks are the firmware's own. On the emulated Cortex-M4F the
tick functions run between `_emu_in()` and `_emu_out()` (see machine.py): they are the board's
C functions, emulated.
"""

try:
    from m4f import emu_in as _emu_in
    from m4f import emu_out as _emu_out
except ImportError:

    def _emu_in():
        pass

    def _emu_out():
        pass


_PERIOD = 1 << 30  # ticks_us / ticks_ms wrap here (MICROPY_PY_TIME_TICKS_PERIOD)
_HALF = 1 << 29
_MASK = _PERIOD - 1

_now = 0  # us since power-on


def now_us():
    """The virtual clock: us since power-on (not wrapped)."""
    return _now


def set_us(t):
    """Set the clock to t us since power-on. The emulator only moves it forward; machine's
    power_on() sets it to the power-on time."""
    global _now
    _now = t


def advance_us(dt):
    """Move the clock forward by dt us."""
    global _now
    _now += dt


def ticks_us():
    """us since power-on, wrapped to 0 .. 2**30 - 1."""
    _emu_in()
    r = _now & _MASK
    _emu_out()
    return r


def ticks_ms():
    """ms since power-on, wrapped to 0 .. 2**30 - 1."""
    _emu_in()
    r = (_now // 1000) & _MASK
    _emu_out()
    return r


def ticks_cpu():
    """Same as ticks_us (no CPU cycle counter on the virtual board)."""
    _emu_in()
    r = _now & _MASK
    _emu_out()
    return r


def ticks_diff(a, b):
    """a - b for two tick values, in -2**29 .. 2**29 - 1 (the port's signed difference)."""
    _emu_in()
    r = ((a - b + _HALF) & _MASK) - _HALF
    _emu_out()
    return r


def ticks_add(t, delta):
    """A tick value delta ticks after t (wrapped)."""
    _emu_in()
    r = (t + delta) & _MASK
    _emu_out()
    return r


def sleep_ms(ms):
    """Wait ms milliseconds: the clock advances by them."""
    global _now
    if ms > 0:
        _now += 1000 * ms


def sleep_us(us):
    """Wait us microseconds: the clock advances by them."""
    global _now
    if us > 0:
        _now += us


def sleep(s):
    """Wait s seconds (int or float): the clock advances by them (rounded down to 1 us)."""
    global _now
    if s > 0:
        _now += int(s * 1000000)


def time():
    """Seconds since power-on (int), for code that only wants a coarse clock."""
    return _now // 1000000


# On the emulated Cortex-M4F the firmware's tick functions are C callables, as on the board:
# calling one costs a C call, the Python above runs inside an emulation bracket (machine.py).
try:
    from m4f import Periph as _Periph
except ImportError:
    _Periph = None
if _Periph is not None:
    ticks_us = _Periph(ticks_us)
    ticks_ms = _Periph(ticks_ms)
    ticks_diff = _Periph(ticks_diff)
    ticks_add = _Periph(ticks_add)
