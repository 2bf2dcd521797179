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
    12 P diagonal, 15 x f32 (seed 001 state order)
    72 gyro bias rad/s 3 x f32, 84 accel bias m/s^2 3 x f32
    96 position m 3 x f32 (ENU from the origin), 108 origin lat i32, 112 origin lon i32
       (1e-7 deg; the integrated lat/lon is the origin plus the position, through geo.py)
   116 tick u32 (navigator ticks, wrapping), 120 origin height f32 (m, ellipsoidal: the
       position's U is relative to it)
Raw-input record, type 0x92 (every tick when `raw_record`; what a bit-exact replay needs):
     0 tick start us u32 (time.ticks_us), 4 PPS edge us u32 (the parser's pps_us)
     8 gyro data registers 6 bytes, 14 accel data registers 6 bytes (as read from the chip)
    20 flags u8: bit 0 saturated; 21 n GNSS bytes u8, 22 the n bytes fed to the parser

Allocation: binascii.crc32 returns an int that is a long int on the board for three values in
four, and the raw record slices a memoryview for its variable length: a few small objects
per record, against hundreds of float boxes per tick. The extended frame's default rate is
10 Hz; the raw record is a replay/debug mode.
"""

from binascii import crc32

import frame
from micropython import const

import geo

EXT_TYPE = const(0x91)
RAW_TYPE = const(0x92)
EXT_PAYLOAD = const(124)  # bytes after the counter
EXT_LEN = const(4 + EXT_PAYLOAD + 4)
RAW_MAX_GNSS = const(232)  # the length byte counts 23 + n <= 255
RAW_MAX_LEN = const(4 + 22 + RAW_MAX_GNSS + 4)


def copy_f32(buf, off, view, index, n):
    """n float32 values from a byte view (f32.byte_view) starting at float `index`."""
    b = 4 * index
    for i in range(4 * n):
        buf[off + i] = view[b + i]


def _head(buf, rtype, n, counter):
    buf[0] = 0xEB
    buf[1] = rtype
    buf[2] = n
    buf[3] = counter & 0xFF


def seal(buf, mv, n):
    """CRC-32 of buf[0:n] (mv: a memoryview of exactly buf[0:n], made once) into buf[n:n+4]."""
    frame.put_i32(buf, n, crc32(mv) & 0xFFFFFFFF)


class ExtFrame:
    """Preallocated extended frame; `pack` fills it, `data` is what to send."""

    def __init__(self):
        self.data = bytearray(EXT_LEN)
        self._mv = memoryview(self.data)[0 : EXT_LEN - 4]

    def pack(
        self,
        counter,
        health,
        state,
        cfg_status,
        flags,
        worst_us,
        mean_us,
        overruns,
        gc_runs,
        p_view,
        bg_view,
        ba_view,
        pos_view,
        lat0_e7,
        lon0_deg,
        lon0_frac,
        tick,
        coef_view,
    ):
        d = self.data
        _head(d, EXT_TYPE, EXT_PAYLOAD + 1, counter)
        d[4] = health
        d[5] = state
        d[6] = cfg_status
        d[7] = flags
        frame.put_u16(d, 8, worst_us if worst_us < 65535 else 65535)
        frame.put_u16(d, 10, mean_us if mean_us < 65535 else 65535)
        frame.put_u16(d, 12, overruns)
        frame.put_u16(d, 14, gc_runs)
        for i in range(15):
            copy_f32(d, 16 + 4 * i, p_view, 16 * i, 1)  # P[i][i]
        copy_f32(d, 76, bg_view, 0, 3)
        copy_f32(d, 88, ba_view, 0, 3)
        copy_f32(d, 100, pos_view, 0, 3)
        frame.put_i32(d, 112, lat0_e7)
        frame.put_e7(d, 116, lon0_deg, lon0_frac)
        frame.put_i32(d, 120, tick)
        copy_f32(d, 124, coef_view, geo.H0, 1)
        seal(d, self._mv, EXT_LEN - 4)


class RawRecord:
    """Preallocated raw-input record of variable length (up to RAW_MAX_GNSS GNSS bytes)."""

    def __init__(self):
        self.data = bytearray(RAW_MAX_LEN)
        self._mv = memoryview(self.data)
        self.length = 0

    def pack(self, counter, t0_us, pps_us, raw_gyro, raw_accel, saturated, rx, n):
        d = self.data
        _head(d, RAW_TYPE, 23 + n, counter)
        frame.put_i32(d, 4, t0_us)
        frame.put_i32(d, 8, pps_us)
        for i in range(6):
            d[12 + i] = raw_gyro[i]
            d[18 + i] = raw_accel[i]
        d[24] = 1 if saturated else 0
        d[25] = n
        for i in range(n):
            d[26 + i] = rx[i]
        seal(d, self._mv[0 : 26 + n], 26 + n)  # the slice: one small object per record
        self.length = 30 + n
