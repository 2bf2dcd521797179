"""The emulated board the runtimes run the firmware on: what `machine` and `time` give the
firmware's own board.py and drivers, backed by emulated peripherals on a virtual clock.

    mpy/  machine.py (pins, SPI, BMI055 register model, UARTs, timer, watchdog; allocation-free
          per tick) and time.py (the virtual clock and MicroPython's tick functions), plain
          Python that runs unchanged in a MicroPython VM and on CPython; and emulate.py, the
          harness that replays a stimulus through the firmware inside a VM (mpy_unix now; an
          emulated Cortex-M4F next)

One board for every runtime: the VM finds machine.py and time.py on its sys.path; the cpython
runtime, the model's virtual clock and the tests load them with
host_emulator.firmware_env.install_machine() (machine.py as `machine`, time.py's functions on
CPython's `time`). mpy/ is not a host package: it is loaded by file.
"""

import pathlib

MPY_DIR = pathlib.Path(__file__).resolve().parent / "mpy"
EMULATE = MPY_DIR / "emulate.py"  # the VM's harness: micropython emulate.py FW STIM CFG OUT
