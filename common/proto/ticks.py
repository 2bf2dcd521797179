"""MicroPython's tick arithmetic, as the stm32 and unix ports do it: `time.ticks_us()` and
`ticks_ms()` wrap at 2**30 (MICROPY_PY_TIME_TICKS_PERIOD), and `ticks_diff(a, b)` is a - b
taken modulo that period into -2**29 .. 2**29 - 1.

The host's one copy (the model's loop, the session replay). The emulated board's clock,
emulated_board/mpy/time.py, runs inside a MicroPython VM too and cannot import host modules, so it
has its own; tests/proto/test_formats.py checks that the two agree.
"""

TICKS_PERIOD = 1 << 30


def ticks_diff(a, b):
    """a - b for two tick values, signed, modulo TICKS_PERIOD."""
    d = (int(a) - int(b)) % TICKS_PERIOD
    return d - TICKS_PERIOD if d >= TICKS_PERIOD // 2 else d
