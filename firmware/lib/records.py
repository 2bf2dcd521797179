"""Additional output records, CRC-32 protected: the extended frame and the raw-input record.

Common layout: 0xEB, type, payload length n (u8), counter (u8), n - 1 payload bytes (the
counter counts in n), CRC-32 (u32 LE, binascii.crc32 / crcmod's crc-32) of everything
before it. Little-endian; floats are IEEE float32 copied byte for byte from the navigator's
buffers (no rounding: the host sees the board's bits).

Extended frame, type 0x91 (every `ext_every_ticks`), payload after the counter:
     0 health u8 (0 normal, 1 warning, 2 fault; a configuration fallback counts as 1)
     1 navigation state u8, 2 configuration status u8 (config.OK/MISSING/CORRUPT/INVALID)
     3 flags u8: bit 0 GNSS valid, bit 1 standstill, bit 2 IMU saturated
     4 worst tick us u16, 6 mean tick us u16, 8 overruns u16 (wrapping), 10 GC runs u16
    12 P diagonal, 15 x f32 (the error-state order of docs/requirements.md); the position's three
    hold P's plus the
       receiver's error the filter cannot see (Navigator.cv, nav_kern.consistency)
    72 gyro bias rad/s 3 x f32, 84 accel bias m/s^2 3 x f32
    96 position m 3 x f32 (ENU from the origin), 108 origin lat i32, 112 origin lon i32
       (1e-7 deg; the integrated lat/lon is the origin plus the position, through geo.py)
   116 tick u32 (navigator ticks, wrapping), 120 origin height f32 (m, ellipsoidal: the
       position's U is relative to it), 124 causes u32 (why health is not 0: nav.CAUSE_*
       and the app's CAUSE_CONFIG, CAUSE_OVERRUN; docs/health.md)
Raw-input record, type 0x92 (every tick when `raw_record`; what a bit-exact replay needs):
     0 tick start us u32 (time.ticks_us), 4 PPS edge us u32 (the parser's pps_us)
     8 gyro data registers 6 bytes, 14 accel data registers 6 bytes (as read from the chip)
    20 flags u8: bit 0 saturated; 21 n GNSS bytes u8, 22 the n bytes fed to the parser

Allocation: the extended frame is one native kernel call (`ext_pack`, CRC included) that
allocates nothing; its Python reference boxes floats and binascii.crc32's result (a long int
on the board for three values in four). So is the raw record (`raw_pack`: its CRC over its
variable length takes a slice in Python, a heap object every tick; with the garbage collector
off while navigating, the heap ran out after ~2 s on the board's image: measured on the
emulated STM32F411).
"""

import struct
from array import array
from binascii import crc32

from micropython import const

import frame
import geo
import ins
import kern

EXT_TYPE = const(0x91)
RAW_TYPE = const(0x92)
EXT_PAYLOAD = const(128)  # bytes after the counter
EXT_LEN = const(4 + EXT_PAYLOAD + 4)
RAW_MAX_GNSS = const(232)  # the length byte counts 23 + n <= 255
RAW_MAX_LEN = const(4 + 22 + RAW_MAX_GNSS + 4)
# The int fields of the extended frame (`ExtFrame.fields`; layout.h is generated from them)
EF_COUNTER = const(0)
EF_HEALTH = const(1)
EF_STATE = const(2)
EF_CONFIG = const(3)
EF_FLAGS = const(4)
EF_WORST_US = const(5)
EF_MEAN_US = const(6)
EF_OVERRUNS = const(7)
EF_GC_RUNS = const(8)
EF_LAT0_E7 = const(9)
EF_LON0_DEG = const(10)
EF_LON0_FRAC = const(11)
EF_TICK = const(12)
EF_CAUSES = const(13)
NEF = const(14)
# The int fields of the raw-input record (`RawRecord.fields`; layout.h is generated from them)
RF_COUNTER = const(0)
RF_T0_US = const(1)  # the tick's start, time.ticks_us
RF_PPS_US = const(2)  # the parser's PPS edge time
RF_SATURATED = const(3)  # 1 if the IMU saturated
RF_N = const(4)  # GNSS bytes fed to the parser this tick
NRF = const(5)


def _head(buf, rtype, n, counter):
    buf[0] = 0xEB
    buf[1] = rtype
    buf[2] = n
    buf[3] = counter & 0xFF


def seal(buf, mv, n):
    """CRC-32 of buf[0:n] (mv: a memoryview of exactly buf[0:n], made once) into buf[n:n+4]."""
    frame.put_i32(buf, n, crc32(mv) & 0xFFFFFFFF)


def _ext_pack_py(d, fi, p, x, coef, cv):
    """The extended frame into d (EXT_LEN bytes) from its int fields fi (EF_*), the covariance
    P (15 x 15), the navigation state x (ins.x), the origin's coefficients and the unseen
    GNSS variances cv (horizontal, vertical: added to P's position diagonal); the reference
    of the native kernel `ext_pack` (which also computes the CRC without allocating)."""
    _head(d, EXT_TYPE, EXT_PAYLOAD + 1, fi[EF_COUNTER])
    d[4] = fi[EF_HEALTH]
    d[5] = fi[EF_STATE]
    d[6] = fi[EF_CONFIG]
    d[7] = fi[EF_FLAGS]
    for k in range(4):
        v = fi[EF_WORST_US + k]
        frame.put_u16(d, 8 + 2 * k, v if v < 65535 else 65535)
    for i in range(15):
        struct.pack_into("<f", d, 16 + 4 * i, p[16 * i])  # P[i][i]
    struct.pack_into("<f", d, 16, p[0] + cv[0])
    struct.pack_into("<f", d, 20, p[16] + cv[0])
    struct.pack_into("<f", d, 24, p[32] + cv[1])
    for i in range(3):
        struct.pack_into("<f", d, 76 + 4 * i, x[ins.X_BG + i])
        struct.pack_into("<f", d, 88 + 4 * i, x[ins.X_BA + i])
        struct.pack_into("<f", d, 100 + 4 * i, x[ins.X_P + i])
    frame.put_i32(d, 112, fi[EF_LAT0_E7])
    frame.put_e7(d, 116, fi[EF_LON0_DEG], fi[EF_LON0_FRAC])
    frame.put_i32(d, 120, fi[EF_TICK])
    struct.pack_into("<f", d, 124, coef[geo.H0])
    frame.put_i32(d, 128, fi[EF_CAUSES])
    seal(d, memoryview(d)[0 : EXT_LEN - 4], EXT_LEN - 4)


ext_pack = kern.pick("ext_pack", _ext_pack_py)


def _raw_pack_py(d, fi, raw_gyro, raw_accel, rx):
    """The raw-input record into d from its int fields fi (RF_*), the data registers as read
    and the GNSS bytes rx[0:fi[RF_N]]; the reference of the native `raw_pack`, which also takes
    the CRC without allocating (the slice here is a heap object on the board)."""
    n = fi[RF_N]
    _head(d, RAW_TYPE, 23 + n, fi[RF_COUNTER])
    frame.put_i32(d, 4, fi[RF_T0_US])
    frame.put_i32(d, 8, fi[RF_PPS_US])
    for i in range(6):
        d[12 + i] = raw_gyro[i]
        d[18 + i] = raw_accel[i]
    d[24] = 1 if fi[RF_SATURATED] else 0
    d[25] = n
    for i in range(n):
        d[26 + i] = rx[i]
    seal(d, memoryview(d)[0 : 26 + n], 26 + n)


raw_pack = kern.pick("raw_pack", _raw_pack_py)


class ExtFrame:
    """Preallocated extended frame: fill `fields` (EF_*), then `pack`; `data` is what to send.
    The overflow counters wrap at 16 bits, the tick times saturate at 65535 us. `cv`: the
    navigator's unseen GNSS variances (Navigator.cv), bound once: one argument more to `pack`
    would put its frame on the heap at every call (tests/runtimes/test_frames.py)."""

    def __init__(self, cv):
        self.data = bytearray(EXT_LEN)
        self.fields = array("i", bytes(4 * NEF))
        self.cv = cv

    def pack(self, p, x, coef):
        ext_pack(self.data, self.fields, p, x, coef, self.cv)


class RawRecord:
    """Preallocated raw-input record of variable length (up to RAW_MAX_GNSS GNSS bytes): fill
    `fields` (RF_*), then `pack`; data[0:length] is what to send."""

    def __init__(self):
        self.data = bytearray(RAW_MAX_LEN)
        self.fields = array("i", bytes(4 * NRF))
        self.length = 0

    def pack(self, raw_gyro, raw_accel, rx):
        raw_pack(self.data, self.fields, raw_gyro, raw_accel, rx)
        self.length = 30 + self.fields[RF_N]
