# The freeze list: what a MicroPython image built with this manifest carries in flash
# (MicroPython's manifest format, tools/makemanifest.py; e.g. make -C ports/stm32
# BOARD=WEACT_F411_BLACKPILL FROZEN_MANIFEST=<this file>). Frozen modules need no room on the
# board's small filesystem, which then holds only main.py (run at boot, so it stays a file),
# the native kernels lib/navk.mpy (a native module cannot be frozen) and ins.cfg.
#
# The layout is the board's: lib/ is on sys.path and its modules are imported flat
# (`import nav`), so they are frozen as top-level modules; drivers/ is a package. The port's
# default frozen modules (asyncio, dht, onewire) are not included: the firmware uses none.
#
# The Python reference kernels (lib/nav_kern.py, lib/yaw_gsf.py, drivers/gnss_kern.py: what
# navk does natively)
# are not frozen: a board runs navk, and a board without lib/navk.mpy says so and does not
# start (main.py; kern.py). include(..., reference_kernels=True) freezes them too, for a VM
# that runs the firmware with its Python kernels (the emulated Cortex-M4F's manifest).
# tests/test_manifest.py checks that this list is every firmware file but main.py (and the
# reference kernels) and that the firmware imports from the frozen layout.

metadata(description="INS/GNSS navigation firmware (STM32F411 + BMI055)", version="0.1.0")

module("app.py")
module("board.py")
drivers = ["__init__.py", "bmi055.py", "gnss.py", "uart_dma.py"]
lib = [
    "config", "eskf", "f32", "fmath", "frame", "geo", "ins", "kern", "mat", "nav", "nav_aid",
    "nav_align", "navcfg", "records", "rot", "status_page",
]  # fmt: skip
if options.reference_kernels:
    drivers.append("gnss_kern.py")
    lib.extend(("nav_kern", "yaw_gsf"))
package("drivers", files=sorted(drivers))
for name in sorted(lib):
    module(name + ".py", base_path="lib")
