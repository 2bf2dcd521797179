"""The emulated board the runtimes run the firmware on: what `machine` and `time` give the
firmware's own board.py and drivers, backed by emulated peripherals on a virtual clock.

    mpy/  machine.py (the stm32 port's API, as strict as the port about arguments: pins, SPI,
          UARTs, timer, watchdog; allocation-free per tick), bmi055_model.py (the BMI055
          register model machine.py puts on the SPI bus and re-exports, on a clock given to
          it) and time.py (the virtual clock and MicroPython's tick functions), plain Python
          that runs unchanged in a MicroPython VM and on CPython; emulate.py and
          emulate_m4f.py, the harnesses that replay a stimulus through the firmware inside the
          unix VM (mpy_unix) and on the emulated Cortex-M4F (m4f), with feed.py;
          backup_domain.py, the virtual board's stand-in for `stm.mem32` over the RTC backup
          registers (the firmware's maintenance marker), shared by its two VMs through a file

One board for every runtime: the VM finds machine.py, bmi055_model.py and time.py on its
sys.path, the emulated Cortex-M4F has them frozen (runtimes/m4f/manifest.py); the cpython
runtime, the model's virtual clock and the tests load them with
host_emulator.firmware_env.install_machine() (machine.py as `machine`, bmi055_model.py as
`bmi055_model`, time.py's functions on CPython's `time`); firmware_env.bmi055_model() loads
the register model alone. mpy/ is not a host package: it is loaded by file.
"""

import pathlib

MPY_DIR = pathlib.Path(__file__).resolve().parent / "mpy"
EMULATE = MPY_DIR / "emulate.py"  # the VM's harness: micropython emulate.py FW STIM CFG OUT
