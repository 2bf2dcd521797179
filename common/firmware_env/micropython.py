"""Stand-in for MicroPython's `micropython` module on CPython: `const(x)` is x, as the
compiler makes it on the board; the memory functions do nothing here (mem_total: nothing is
counted, CPython's heap is not the board's)."""


def const(x):
    return x


def heap_lock():
    return 0


def heap_unlock():
    return 0


def mem_total():
    return 0
