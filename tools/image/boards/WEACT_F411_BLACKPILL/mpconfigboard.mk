# The WeAct Black Pill from MicroPython's own board folder (make runs in ports/stm32); only its
# mpconfigboard.h is changed (see there). The port wants pins.csv in BOARD_DIR: tools/image/
# build.py assembles the folder in the build tree from these files and the tree's pins.csv.
include boards/WEACT_F411_BLACKPILL/mpconfigboard.mk

# No littlefs (the tree's board enables it): the filesystem is FAT, formatted by the port on its
# first start, and the tools write FAT only.
MICROPY_VFS_LFS2 = 0
