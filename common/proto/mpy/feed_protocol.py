"""The stimulus file as the feeding harnesses read it (host_emulator/emulated_board/mpy/feed.py, in
the MicroPython VMs) and the host writes it (common/proto/stimulus.py): one definition for both.

File: MAGIC, then the header (common/proto/stimulus.py), then one REC_LEN-byte record per
tick followed by its GNSS bytes, then TRAILER and the CRC. A record, little-endian:
gyro data registers (6 bytes, REC_GYRO), accel data registers (6, REC_ACCEL), temperature
register (int8, REC_TEMP), flags (u8, REC_FLAGS: FLAG_*), the PPS edge this long before the
tick (u16 us, REC_PPS_BEFORE_US), the GNSS bytes that follow (u16, REC_N).
"""

MAGIC = b"INSSTIM1"
TRAILER = b"END1"
TICK_US = 5000
REC_LEN = 18
REC_GYRO = 0
REC_ACCEL = 6
REC_TEMP = 12
REC_FLAGS = 13
REC_PPS_BEFORE_US = 14
REC_N = 16
FLAG_PPS = 0x01  # a PPS edge before this tick
FLAG_IMU_SILENT = 0x02  # the IMU does not answer in this interval
# the board is busy in this interval (an injected stall): the timer and the interrupt handlers
# run, the loop does not
FLAG_STALL = 0x04
EXIT_FIRMWARE_ERROR = 3  # a harness's exit status after reporting that the firmware raised
