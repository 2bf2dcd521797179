# ST NUCLEO-F411RE (MB1136): STM32F411RET6, 512 KB flash, 128 KB RAM. Built with
# python -m tools.image build --board NUCLEO_F411RE, which passes BOARD_DIR=<this folder>
# to MicroPython's stm32 port (paths below are relative to ports/stm32, where make runs).
MCU_SERIES = f4
CMSIS_MCU = STM32F411xE
AF_FILE = boards/stm32f411_af.csv
# The port's F411 layout: vectors in sector 0, the filesystem in sectors 1-3, code from
# sector 5 (0x08020000, 384 KB), exactly as for WEACT_F411_BLACKPILL.
LD_FILES = boards/stm32f411.ld boards/common_ifs.ld
TEXT0_ADDR = 0x08000000
TEXT1_ADDR = 0x08020000
