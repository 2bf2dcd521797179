"""The firmware image: MicroPython v1.28.0 for an STM32F411 board with firmware/ frozen in.

    python -m tools.image build [--board B] [--out DIR]     (make image [BOARD=B])
    python -m tools.image boards

build.py builds it out of tree (build/image/<board>/) with Debian's arm-none-eabi-gcc and the
tree's own mpy-cross, budget.py measures it from the linker's output, fwid.py defines the
firmware id the image carries as the frozen module `fwid`, boards/ holds the board
definitions the vendored tree lacks (NUCLEO_F411RE). tools.flash image writes it to a board in
DFU mode. See docs/image.md.
"""
