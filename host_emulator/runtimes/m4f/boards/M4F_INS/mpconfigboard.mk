# The emulated board of host_emulator/runtimes/m4f: QEMU's MPS2 AN386 (a Cortex-M4 with the
# single-precision FPU, fpv4-sp-d16), built as the stm32 port builds for the STM32F411:
# hard-float ABI, MICROPY_FLOAT_IMPL = float, mpy-cross -march=armv7emsp, object
# representation A (floats boxed on the heap) and the stm32 port's feature level.
QEMU_ARCH = arm
QEMU_MACHINE = mps2-an386

CFLAGS += -mthumb -mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard
CFLAGS += -DQEMU_SOC_MPS2
CFLAGS += -DMICROPY_HW_MCU_NAME='"Cortex-M4F"'
SUPPORTS_HARDWARE_FP_SINGLE = 1
# The interpreter as the stm32 port builds it (ports/stm32/mpconfigport.h): computed goto.
CFLAGS += -DMICROPY_OPT_COMPUTED_GOTO=1
MICROPY_FLOAT_IMPL = float

LDSCRIPT = mcu/arm/mps2.ld

SRC_BOARD_O = shared/runtime/gchelper_native.o shared/runtime/gchelper_thumb2.o

MPY_CROSS_FLAGS += -march=armv7emsp

# /flash as on the board: FAT on a RAM disk (the m4f module's, outside the heap).
MICROPY_VFS_FAT = 1
# FatFs configured as the stm32 port configures it (ports/stm32/mpconfigport.h).
CFLAGS += -DMICROPY_FATFS_ENABLE_LFN=2 -DMICROPY_FATFS_LFN_CODE_PAGE=437
CFLAGS += -DMICROPY_FATFS_USE_LABEL=1 -DMICROPY_FATFS_RPATH=2 -DMICROPY_FATFS_MULTI_PARTITION=1
SRC_C += shared/timeutils/timeutils.c
