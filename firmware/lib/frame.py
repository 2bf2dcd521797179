"""The 52-byte output frame (docs/requirements.md: output frame, frame encoding rules), packed
without allocating.

| bytes | field | scale | filled by |
|---|---|---|---|
| 0-1 | header 0xEB 0x90 | | `finish` |
| 2 | counter, u8 wrapping | | app `_send_frame` (F_COUNTER) |
| 3-8 | gyro x, y, z, int16 | 131.07 per deg/s | the tick's sample, F_GYRO_LSB_X10 (`_start_imu`) |
| 9-14 | accel x, y, z, int16 | 16383 per g | the tick's sample, F_ACCEL_LSB (`_start_imu`) |
| 15 / 16 | PPS flag / GGA flag, u8 | | app `_send_frame` (F_PPS, F_GGA) |
| 17 | GNSS valid, u8 | | app `_deliver_fix` (F_VALID) |
| 18-21 / 22-25 | latitude / longitude, int32 | 1e7 per deg (the GNSS fix) | app `_fix_fields` |
| 26-27 | height, int16 | 10 per m (the GNSS fix) | app `_fix_fields` (F_HEIGHT_DM) |
| 28 | navigation state, u8 | 1 aligning, 2 navigating | app `_send_frame` (F_STATE) |
| 29-34 | yaw, pitch, roll, int16 | 100 per deg | `nav_frame`, from Navigator.mem |
| 35-40 | velocity E, N, U, int16 | 100 per m/s | `nav_frame` |
| 41-48 | position E, N, int32 | 100 per m | `nav_frame` |
| 49-50 | position U, int16 | 10 per m | `nav_frame` |
| 51 | checksum, u8 | sum of bytes 2..50 mod 256 | `finish` |

This module owns the frame: its length, the byte offset of each field (_FB_*) and the int
fields (F_*) that the app fills where the value is known, in App._fields; one call of
`pack_fields` (natively frame.c, from the generated layout.h) writes every byte of the frame
from them and the navigator's float buffers. frame.c, the app and the status page take the
offsets and fields from here (common/native/layout.py, const_copies.py: generated, never
written by hand).

Little-endian, signed unless noted; every value is physical x scale, rounded half away from
zero and clamped to the field's range (a clamped value is the field's limit, never a wrap).

The sensor fields are what the sensor measured (before calibration) at the frame's own scale:
the BMI055's sensitivity is not the frame's (131.2 vs 131.07 LSB per deg/s at +-250 deg/s,
16384 vs 16383 per g at +-2 g), so counts are converted exactly in integer arithmetic, for any
configured range. Values beyond what the frame can hold (over 250 deg/s, over 2 g) clamp.

Longitudes beyond +-107.37 deg do not fit MicroPython's 31-bit small ints in 1e-7 deg, so
angles are passed as (whole degrees, fraction in 1e-7 deg, same sign) and packed through
16-bit halves: 1e7 = 152 * 65536 + 38528.
"""

from micropython import const

import kern

FRAME_LEN = const(52)
# Each field's first byte (the table above)
_FB_COUNTER = const(2)
_FB_GYRO = const(3)
_FB_ACCEL = const(9)
_FB_PPS = const(15)
_FB_GGA = const(16)
_FB_VALID = const(17)
_FB_LAT = const(18)
_FB_LON = const(22)
_FB_HEIGHT = const(26)
_FB_STATE = const(28)
_FB_YAW = const(29)
_FB_PITCH = const(31)
_FB_ROLL = const(33)
_FB_VE = const(35)
_FB_VN = const(37)
_FB_VU = const(39)
_FB_PE = const(41)
_FB_PN = const(45)
_FB_PU = const(49)
_FB_SUM = const(51)
# The int fields of `pack_fields` (firmware/native/layout.h is generated from them)
F_COUNTER = const(0)
F_GYRO_LSB_X10 = const(1)
F_ACCEL_LSB = const(2)
F_PPS = const(3)
F_GGA = const(4)
F_VALID = const(5)
F_HEIGHT_DM = const(6)
F_STATE = const(7)
F_LAT_DEG = const(8)  # the fix's latitude and longitude as (degrees, 1e-7 deg fraction): read
F_LAT_FRAC = const(9)  # by nav.nav_frame (`pack_fields` takes them as two arrays)
F_LON_DEG = const(10)
F_LON_FRAC = const(11)
NF = const(12)
_GYRO_FRAME_X100 = const(13107)  # 131.07 per deg/s, x100
_ACCEL_FRAME = const(16383)  # per g


def _bytes_copy_py(dst, off, src, n):
    """n bytes of src into dst from dst[off]: the reference of the native `bytes_copy` (a
    memoryview slice of src would be a heap object every call)."""
    for i in range(n):
        dst[off + i] = src[i]


bytes_copy = kern.pick("bytes_copy", _bytes_copy_py)


def round_div(num, den):
    """num / den (den > 0) rounded half away from zero, in integers."""
    if num >= 0:
        return (2 * num + den) // (2 * den)
    return -((-2 * num + den) // (2 * den))


def _clamp16(x):
    if x > 32767:
        return 32767
    if x < -32768:
        return -32768
    return x


def _round_clamp(x, lo, hi):
    """The float x rounded half away from zero, clamped to [lo, hi] (ints); NaN gives 0
    (int() of a NaN would raise and end the loop)."""
    if x >= hi:
        return hi
    if x <= lo:
        return lo
    if x != x:
        return 0
    if x >= 0.0:
        return int(x + 0.5)
    return -int(0.5 - x)


def gyro_to_frame(counts, lsb_per_dps_x10):
    """Frame gyro value of `counts` at a sensitivity of lsb_per_dps_x10/10 LSB per deg/s."""
    return _clamp16(round_div(counts * _GYRO_FRAME_X100, 10 * lsb_per_dps_x10))


def accel_to_frame(counts, lsb_per_g):
    """Frame accel value of 12-bit `counts` at lsb_per_g LSB per g."""
    return _clamp16(round_div(counts * _ACCEL_FRAME, lsb_per_g))


def put_i16(buf, off, x):
    x = _clamp16(x)
    buf[off] = x & 0xFF
    buf[off + 1] = (x >> 8) & 0xFF


def put_u16(buf, off, x):
    buf[off] = x & 0xFF
    buf[off + 1] = (x >> 8) & 0xFF


def put_i32(buf, off, x):
    """The low 32 bits of x, a small int (|x| < 2**30 on the board): int32 or uint32."""
    buf[off] = x & 0xFF
    buf[off + 1] = (x >> 8) & 0xFF
    buf[off + 2] = (x >> 16) & 0xFF
    buf[off + 3] = (x >> 24) & 0xFF


def put_e7(buf, off, deg, frac_e7):
    """int32 deg * 1e7 + frac_e7 (frac with deg's sign), without forming the (long) int."""
    t = deg * 38528 + frac_e7  # |t| < 2**25
    lo = t & 0xFFFF
    hi = deg * 152 + (t >> 16)
    buf[off] = lo & 0xFF
    buf[off + 1] = lo >> 8
    buf[off + 2] = hi & 0xFF
    buf[off + 3] = (hi >> 8) & 0xFF


def put_scaled16(buf, off, x, scale):
    """int16 of the float x * scale, rounded half away from zero, clamped."""
    put_i16(buf, off, _round_clamp(x * scale, -32768, 32767))


def put_scaled32(buf, off, x, scale):
    """int32 of the float x * scale (the board's small ints bound it to +-2**30)."""
    put_i32(buf, off, _round_clamp(x * scale, -1073741823, 1073741823))


def checksum(buf):
    s = 0
    for i in range(_FB_COUNTER, _FB_SUM):
        s += buf[i]
    return s & 0xFF


def finish(buf, counter):
    """Header, counter and checksum; the fields must already be in place."""
    buf[0] = 0xEB
    buf[1] = 0x90
    buf[_FB_COUNTER] = counter & 0xFF
    buf[_FB_SUM] = checksum(buf)


def pack(
    buf,
    counter,
    gyro,
    accel,
    gyro_lsb_x10,
    accel_lsb_per_g,
    pps,
    gga,
    gnss_valid,
    lat,
    lon,
    height_dm,
    nav_state,
    ypr_cdeg_scale,
    ypr,
    v_n,
    p_n,
):
    """Fill buf[0:52]. gyro, accel: sensor counts (3 each) at the given sensitivities;
    lat, lon: (degrees, fraction in 1e-7 deg) pairs in 2-element int buffers; height_dm: the
    fix height in decimetres (int); ypr (rad), v_n (m/s), p_n (m): float32 buffers;
    ypr_cdeg_scale: centidegrees per radian (18000/pi, float32)."""
    for i in range(3):
        put_i16(buf, _FB_GYRO + 2 * i, gyro_to_frame(gyro[i], gyro_lsb_x10))
        put_i16(buf, _FB_ACCEL + 2 * i, accel_to_frame(accel[i], accel_lsb_per_g))
        put_scaled16(buf, _FB_YAW + 2 * i, ypr[i], ypr_cdeg_scale)
        put_scaled16(buf, _FB_VE + 2 * i, v_n[i], 100)
    buf[_FB_PPS] = 1 if pps else 0
    buf[_FB_GGA] = 1 if gga else 0
    buf[_FB_VALID] = 1 if gnss_valid else 0
    put_e7(buf, _FB_LAT, lat[0], lat[1])
    put_e7(buf, _FB_LON, lon[0], lon[1])
    put_i16(buf, _FB_HEIGHT, height_dm)
    buf[_FB_STATE] = nav_state & 0xFF
    put_scaled32(buf, _FB_PE, p_n[0], 100)
    put_scaled32(buf, _FB_PN, p_n[1], 100)
    put_scaled16(buf, _FB_PU, p_n[2], 10)
    finish(buf, counter)


def _pack_fields_py(buf, fields, gyro, accel, lat, lon, ypr, v_n, p_n, ypr_cdeg_scale):
    """`pack` with its int arguments in the int32 buffer `fields` (F_*): the signature of the
    native kernel, which packs a whole frame in one call."""
    pack(
        buf,
        fields[F_COUNTER],
        gyro,
        accel,
        fields[F_GYRO_LSB_X10],
        fields[F_ACCEL_LSB],
        fields[F_PPS],
        fields[F_GGA],
        fields[F_VALID],
        lat,
        lon,
        fields[F_HEIGHT_DM],
        fields[F_STATE],
        ypr_cdeg_scale,
        ypr,
        v_n,
        p_n,
    )


pack_fields = kern.pick("frame_pack", _pack_fields_py)
