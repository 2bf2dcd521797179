# The WeAct Black Pill from MicroPython's own board folder (make runs in ports/stm32), with our
# changes: its mpconfigboard.h (see there), the flash layout and littlefs below. The port wants
# pins.csv in BOARD_DIR: tools/image/build.py assembles the folder in the build tree from these
# files and the tree's pins.csv, with the shared files of tools/image/boards beside it.
include boards/WEACT_F411_BLACKPILL/mpconfigboard.mk

# Our F411 layout (../stm32f411_fs48.ld; docs/image.md, the flash layout): vectors in sector 0,
# the filesystem in sectors 1-3 (48 KB), the code from sector 4 (0x08010000, 448 KB), as for
# NUCLEO_F411RE. The tree's board takes the port's boards/stm32f411.ld: the filesystem 64 KB
# (into sector 4), the code 384 KB from sector 5 (TEXT1_ADDR 0x08020000).
LD_FILES = $(BOARD_DIR)/../stm32f411_fs48.ld boards/common_ifs.ld
TEXT1_ADDR = 0x08010000

# No littlefs (the tree's board enables it): the filesystem is FAT, formatted by the port on its
# first start, and the tools write FAT only.
MICROPY_VFS_LFS2 = 0
