# The `m4f` module of the emulated Cortex-M4F board (host_emulator/runtimes/m4f).
M4F_MOD_DIR := $(USERMOD_DIR)
SRC_USERMOD_C += $(M4F_MOD_DIR)/m4f.c
