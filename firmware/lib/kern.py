"""Where the float32 kernels come from, decided once for the whole firmware.

The hot float work of a tick (the INS step, the filter's slices, the frame's conversions...)
exists twice: as the readable Python reference kernels in lib/ (ins.py, eskf.py, ...) and as
the native module `navk` (firmware/native/navk.c: a MicroPython native module on the board and
in the desktop VM, a cffi extension on CPython). Both keep the same operation order, so they
give the same bits; the native one allocates nothing and costs a fraction of the time.

`pick(name, python_kernel)` returns navk's kernel of that name when the native module is
present and built for this firmware (its `abi()` equals ABI), else the Python kernel with the
same signature. `NATIVE` and `describe()` say which was chosen (the app prints it at start-up).

A board image does not freeze the Python kernels (nav_kern, drivers.gnss_kern: firmware/
manifest.py): on a board without a usable lib/navk.mpy the modules that load them raise
`missing(...)`, a `Missing`, and main.py prints its one line instead of starting.
"""

import sys as _sys

ABI = 11  # firmware/native/navk.c NAVK_ABI: signatures and buffer layouts of this firmware

navk = None
_why = "navk not found"
try:
    import navk as _navk

    if _navk.abi() == ABI:
        navk = _navk
    else:
        _why = "navk.mpy is for another firmware (abi " + str(_navk.abi()) + ")"
except ImportError:
    pass
except ValueError as e:  # a .mpy for another architecture or MicroPython version
    _why = "navk.mpy not loadable: " + str(e)

NATIVE = navk is not None
# CPython (the emulator's hosts, the tests): where a module's heap does not count (nav.py)
HOST = _sys.implementation.name != "micropython"
del _sys


class Missing(Exception):
    """Neither navk nor the Python kernels can be loaded: the firmware cannot run."""


def missing(err):
    """The Missing that stops the firmware: why navk is not used, and `err`, the ImportError
    of the Python kernels (a board image does not freeze them)."""
    return Missing(
        "no kernels: " + _why + ", and this image carries no Python kernels ("
        + str(err) + "): put lib/navk.mpy on /flash (make deploy PORT=...)"
    )  # fmt: skip


def pick(name, python_kernel):
    """The native kernel `name` if the native module is in use, else `python_kernel`."""
    if navk is None:
        return python_kernel
    return getattr(navk, name)


def describe():
    """One line for the console: which kernels run, and why not native."""
    if NATIVE:
        return "kernels: native (navk abi " + str(ABI) + ")"
    return "kernels: Python (" + _why + ")"
