/* The 52-byte output frame (firmware/lib/frame.py `pack` is the reference, field by field) and
 * the extended frame (firmware/lib/records.py `_ext_pack_py`). */
#include <stdint.h>

#include "fmath32.h" /* F32_BITS and tuning.h: CDEG_PER_RAD */
#include "layout.h"
#include "navk.h"


/* frame.round_div: num / den (den > 0) rounded half away from zero (Python floor division). */
static int32_t round_div(int64_t num, int64_t den) {
    if (num >= 0) {
        return (int32_t)((2 * num + den) / (2 * den));
    }
    return (int32_t)-((-2 * num + den) / (2 * den));
}

static int32_t clamp16(int32_t x) {
    return x > 32767 ? 32767 : (x < -32768 ? -32768 : x);
}

/* frame._round_clamp: the float x rounded half away from zero, clamped; NaN gives 0. The
 * limits compare as floats, as MicroPython compares a float with an int. */
static int32_t round_clamp(float x, int32_t lo, int32_t hi) {
    if (x >= (float)hi) {
        return hi;
    }
    if (x <= (float)lo) {
        return lo;
    }
    if (x != x) {
        return 0;
    }
    if (x >= 0.0f) {
        return (int32_t)(x + 0.5f);
    }
    return -(int32_t)(0.5f - x);
}

static void put_u16(uint8_t *buf, int off, int32_t x) {
    buf[off] = (uint8_t)(x & 0xFF);
    buf[off + 1] = (uint8_t)((x >> 8) & 0xFF);
}

static void put_i32(uint8_t *buf, int off, int32_t x) {
    buf[off] = (uint8_t)(x & 0xFF);
    buf[off + 1] = (uint8_t)((x >> 8) & 0xFF);
    buf[off + 2] = (uint8_t)((x >> 16) & 0xFF);
    buf[off + 3] = (uint8_t)((x >> 24) & 0xFF);
}

/* frame.put_e7: int32 deg * 1e7 + frac_e7 through 16-bit halves (1e7 = 152 * 65536 + 38528). */
static void put_e7(uint8_t *buf, int off, int32_t deg, int32_t frac_e7) {
    int32_t t = deg * 38528 + frac_e7;
    int32_t lo = t & 0xFFFF;
    int32_t hi = deg * 152 + (t >> 16);
    buf[off] = (uint8_t)(lo & 0xFF);
    buf[off + 1] = (uint8_t)(lo >> 8);
    buf[off + 2] = (uint8_t)(hi & 0xFF);
    buf[off + 3] = (uint8_t)((hi >> 8) & 0xFF);
}

void navk_frame_pack(uint8_t *buf, const int32_t *fields, const int16_t *gyro,
    const int16_t *accel, const int32_t *lat, const int32_t *lon, const float *ypr,
    const float *v_n, const float *p_n, float ypr_cdeg_scale) {
    for (int i = 0; i < 3; i++) {
        put_u16(buf, FB_GYRO + 2 * i,
            clamp16(round_div((int64_t)gyro[i] * GYRO_FRAME_X100, 10 * (int64_t)fields[F_GYRO_LSB_X10])));
        put_u16(buf, FB_ACCEL + 2 * i,
            clamp16(round_div((int64_t)accel[i] * ACCEL_FRAME, fields[F_ACCEL_LSB])));
        put_u16(buf, FB_YAW + 2 * i, round_clamp(ypr[i] * ypr_cdeg_scale, -32768, 32767));
        put_u16(buf, FB_VE + 2 * i, round_clamp(v_n[i] * 100.0f, -32768, 32767));
    }
    buf[FB_PPS] = fields[F_PPS] ? 1 : 0;
    buf[FB_GGA] = fields[F_GGA] ? 1 : 0;
    buf[FB_VALID] = fields[F_VALID] ? 1 : 0;
    put_e7(buf, FB_LAT, lat[0], lat[1]);
    put_e7(buf, FB_LON, lon[0], lon[1]);
    put_u16(buf, FB_HEIGHT, clamp16(fields[F_HEIGHT_DM]));
    buf[FB_STATE] = (uint8_t)(fields[F_STATE] & 0xFF);
    put_i32(buf, FB_PE, round_clamp(p_n[0] * 100.0f, -1073741823, 1073741823));
    put_i32(buf, FB_PN, round_clamp(p_n[1] * 100.0f, -1073741823, 1073741823));
    put_u16(buf, FB_PU, round_clamp(p_n[2] * 10.0f, -32768, 32767));
    buf[0] = 0xEB;
    buf[1] = 0x90;
    buf[FB_COUNTER] = (uint8_t)(fields[F_COUNTER] & 0xFF);
    int32_t sum = 0;
    for (int i = FB_COUNTER; i < FB_SUM; i++) {
        sum += buf[i];
    }
    buf[FB_SUM] = (uint8_t)(sum & 0xFF);
}

/* binascii.crc32 (reflected 0xEDB88320, initial and final complement), a nibble at a time:
 * a 16-entry table on the stack (a native module has no static data it can write, and a
 * const table costs a relocation). */
static uint32_t crc32(const uint8_t *buf, int n) {
    uint32_t table[16];
    for (uint32_t i = 0; i < 16; i++) {
        uint32_t c = i;
        for (int k = 0; k < 4; k++) {
            c = (c & 1u) ? (c >> 1) ^ 0xEDB88320u : c >> 1;
        }
        table[i] = c;
    }
    uint32_t crc = 0xFFFFFFFFu;
    for (int i = 0; i < n; i++) {
        crc ^= buf[i];
        crc = (crc >> 4) ^ table[crc & 15u];
        crc = (crc >> 4) ^ table[crc & 15u];
    }
    return ~crc;
}

static void put_f32(uint8_t *buf, int off, float x) {
    union {
        float f;
        uint32_t u;
    } b;
    b.f = x;
    put_i32(buf, off, (int32_t)b.u);
}


void navk_ext_pack(uint8_t *buf, const int32_t *fields, const float *p, const float *x,
    const float *coef, const float *cv) {
    buf[0] = 0xEB;
    buf[1] = 0x91;
    buf[2] = EXT_LEN - 7; /* payload bytes after the head, the counter included */
    buf[3] = (uint8_t)(fields[EF_COUNTER] & 0xFF);
    buf[4] = (uint8_t)fields[EF_HEALTH];
    buf[5] = (uint8_t)fields[EF_STATE];
    buf[6] = (uint8_t)fields[EF_CONFIG];
    buf[7] = (uint8_t)fields[EF_FLAGS];
    for (int k = 0; k < 4; k++) {
        int32_t v = fields[EF_WORST_US + k];
        put_u16(buf, 8 + 2 * k, v < 65535 ? v : 65535);
    }
    for (int i = 0; i < 15; i++) {
        put_f32(buf, 16 + 4 * i, p[16 * i]);
    }
    /* the position's: P's plus the receiver's unseen error (nav_kern.consistency) */
    put_f32(buf, 16, p[0] + cv[0]);
    put_f32(buf, 20, p[16] + cv[0]);
    put_f32(buf, 24, p[32] + cv[1]);
    for (int i = 0; i < 3; i++) {
        put_f32(buf, 76 + 4 * i, x[X_BG + i]);
        put_f32(buf, 88 + 4 * i, x[X_BA + i]);
        put_f32(buf, 100 + 4 * i, x[X_P + i]);
    }
    put_i32(buf, 112, fields[EF_LAT0_E7]);
    put_e7(buf, 116, fields[EF_LON0_DEG], fields[EF_LON0_FRAC]);
    put_i32(buf, 120, fields[EF_TICK]);
    put_f32(buf, 124, coef[GEO_H0]);
    put_i32(buf, 128, fields[EF_CAUSES]);
    put_i32(buf, EXT_LEN - 4, (int32_t)crc32(buf, EXT_LEN - 4));
}

/* records._raw_pack_py: the raw-input record of a tick from its int fields (RF_*), the data
 * registers as read and the GNSS bytes fed to the parser, CRC included (in Python the CRC
 * over the record's variable length takes a slice: a heap object every tick) */
void navk_raw_pack(uint8_t *buf, const int32_t *fields, const uint8_t *raw_gyro,
    const uint8_t *raw_accel, const uint8_t *rx) {
    int32_t n = fields[RF_N];
    buf[0] = 0xEB;
    buf[1] = 0x92;
    buf[2] = (uint8_t)(23 + n);
    buf[3] = (uint8_t)(fields[RF_COUNTER] & 0xFF);
    put_i32(buf, 4, fields[RF_T0_US]);
    put_i32(buf, 8, fields[RF_PPS_US]);
    for (int i = 0; i < 6; i++) {
        buf[12 + i] = raw_gyro[i];
        buf[18 + i] = raw_accel[i];
    }
    buf[24] = fields[RF_SATURATED] ? 1 : 0;
    buf[25] = (uint8_t)n;
    for (int32_t i = 0; i < n; i++) {
        buf[26 + i] = rx[i];
    }
    put_i32(buf, 26 + n, (int32_t)crc32(buf, 26 + n));
}

/* drivers/uart_dma._copy_py: n bytes of src into dst from dst[off] (the DMA transmitter's
 * queue; a memoryview slice would be a heap object every tick) */
void navk_bytes_copy(uint8_t *dst, int32_t off, const uint8_t *src, int32_t n) {
    for (int32_t i = 0; i < n; i++) {
        dst[off + i] = src[i];
    }
}

/* nav_kern.nav_frame: the frame of the navigator's state in m (Navigator.mem), the attitude as
 * yaw, pitch, roll into m's ypr first; the fix's latitude and longitude from fields. */
void navk_nav_frame(uint8_t *buf, const int32_t *fields, const int16_t *gyro,
    const int16_t *accel, float *m) {
    int32_t lat[2] = { fields[F_LAT_DEG], fields[F_LAT_FRAC] };
    int32_t lon[2] = { fields[F_LON_DEG], fields[F_LON_FRAC] };
    navk_euler(m + M_YPR, m + M_X + X_C);
    navk_frame_pack(buf, fields, gyro, accel, lat, lon, m + M_YPR, m + M_X + X_V, m + M_X + X_P,
        CDEG_PER_RAD);
}
