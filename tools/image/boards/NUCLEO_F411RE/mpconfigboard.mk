# ST NUCLEO-F411RE (MB1136): STM32F411RET6, 512 KB flash, 128 KB RAM. Built with
# python -m tools.image build --board NUCLEO_F411RE, which passes BOARD_DIR=<this folder>
# to MicroPython's stm32 port (paths below are relative to ports/stm32, where make runs).
MCU_SERIES = f4
CMSIS_MCU = STM32F411xE
AF_FILE = boards/stm32f411_af.csv
# Our F411 layout (../stm32f411_fs48.ld; docs/image.md, the flash layout): vectors in sector 0,
# the filesystem in sectors 1-3 (48 KB), the code from sector 4 (0x08010000, 448 KB), as for
# WEACT_F411_BLACKPILL. The port's boards/stm32f411.ld gives the filesystem 64 KB (into sector
# 4) and the code 384 KB from sector 5.
LD_FILES = $(BOARD_DIR)/../stm32f411_fs48.ld boards/common_ifs.ld
TEXT0_ADDR = 0x08000000
TEXT1_ADDR = 0x08010000
