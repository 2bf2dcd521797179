"""The emulated board the runtimes run the firmware on: what `machine` and `time` give the
firmware's own board.py and drivers, backed by emulated peripherals on a virtual clock.

    cpython/  a `machine` module for CPython (machine.py), an SPI bus with chip selects
              (spi.py) and a BMI055 register model (bmi055.py) with its faults and a record of
              every transaction, for the cpython runtime and the driver tests
    mpy/      the same board as MicroPython code for the VM (machine.py, time.py: pins, SPI,
              BMI055, UARTs, timer, watchdog; allocation-free per tick), and emulate.py, the
              harness that replays a stimulus through the firmware inside a VM (mpy_unix now;
              an emulated Cortex-M4F next)

There are two because code that runs inside a MicroPython VM cannot import host modules; a
test drives both BMI055 models with the same random transactions (tests/runtimes/
test_mpy_unix.py), and the tick arithmetic is checked equal (tests/proto/test_formats.py).
`mpy/` is not a host package: nothing on CPython imports it.
"""

import pathlib

MPY_DIR = pathlib.Path(__file__).resolve().parent / "mpy"
EMULATE = MPY_DIR / "emulate.py"  # the VM's harness: micropython emulate.py FW STIM CFG OUT
