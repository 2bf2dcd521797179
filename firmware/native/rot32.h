/* Quaternion and DCM helpers of the kernels: C versions of firmware/lib/rot.py, same
 * conventions (q_bn = [w, x, y, z], Hamilton, C_bn row-major) and the same operation order
 * (C evaluates a + b + c as (a + b) + c, as Python does). */
#ifndef NAVK_ROT32_H
#define NAVK_ROT32_H

#include <stdint.h>

#include "fmath32.h"

/* rot.py's series constants, each one float32 division (folded by the compiler, which
 * rounds float32 arithmetic exactly as the FPU does). */
#define ROT_SERIES_MAX_N2 (1.0f / 64.0f)
#define ROT_C8 (1.0f / 8.0f)
#define ROT_C384 (1.0f / 384.0f)
#define ROT_C48 (1.0f / 48.0f)
#define ROT_C3840 (1.0f / 3840.0f)

static inline void rot_q_identity(float *q) {
    q[0] = 1.0f;
    q[1] = 0.0f;
    q[2] = 0.0f;
    q[3] = 0.0f;
}

/* out = p (x) q; out must not alias p or q. */
static inline void rot_q_mul(float *out, const float *p, const float *q) {
    float pw = p[0], px = p[1], py = p[2], pz = p[3];
    float qw = q[0], qx = q[1], qy = q[2], qz = q[3];
    out[0] = pw * qw - px * qx - py * qy - pz * qz;
    out[1] = pw * qx + px * qw + py * qz - pz * qy;
    out[2] = pw * qy - px * qz + py * qw + pz * qx;
    out[3] = pw * qz + px * qy - py * qx + pz * qw;
}

/* rot.q_normalize: unit norm in place; zero or non-finite -> identity, returns 0. */
static inline int32_t rot_q_normalize(float *q) {
    float w = q[0], x = q[1], y = q[2], z = q[3];
    float n2 = w * w + x * x + y * y + z * z;
    if (!(n2 > 0.0f) || n2 - n2 != 0.0f) {
        rot_q_identity(q);
        return 0;
    }
    float inv = 1.0f / __builtin_sqrtf(n2);
    q[0] = w * inv;
    q[1] = x * inv;
    q[2] = y * inv;
    q[3] = z * inv;
    return 1;
}

/* rot._half_angle: cs = [cos(|t|/2), sin(|t|/2)/|t|] for n2 = |t|^2. */
static inline void rot_half_angle(float *cs, float n2) {
    if (n2 < ROT_SERIES_MAX_N2) {
        cs[0] = 1.0f - n2 * (ROT_C8 - n2 * ROT_C384);
        cs[1] = 0.5f - n2 * (ROT_C48 - n2 * ROT_C3840);
    } else {
        float n = __builtin_sqrtf(n2);
        float h = 0.5f * n;
        cs[0] = f32_cos(h);
        cs[1] = f32_sin(h) / n;
    }
}

/* rot.q_update: q advanced by the body rotation vector th (seed eq. 5-17), normalized. */
static inline int32_t rot_q_update(float *q, const float *th) {
    float tx = th[0], ty = th[1], tz = th[2];
    float cs[2];
    rot_half_angle(cs, tx * tx + ty * ty + tz * tz);
    float c = cs[0], s = cs[1];
    float w = q[0], x = q[1], y = q[2], z = q[3];
    q[0] = c * w - s * (tx * x + ty * y + tz * z);
    q[1] = c * x + s * (tx * w + tz * y - ty * z);
    q[2] = c * y + s * (ty * w - tz * x + tx * z);
    q[3] = c * z + s * (tz * w + ty * x - tx * y);
    return rot_q_normalize(q);
}

/* rot.q_from_rotvec */
static inline void rot_q_from_rotvec(float *out, const float *th) {
    float tx = th[0], ty = th[1], tz = th[2];
    float cs[2];
    rot_half_angle(cs, tx * tx + ty * ty + tz * tz);
    float s = cs[1];
    out[0] = cs[0];
    out[1] = s * tx;
    out[2] = s * ty;
    out[3] = s * tz;
}

/* rot.q_to_dcm */
static inline void rot_q_to_dcm(float *c, const float *q) {
    float w = q[0], x = q[1], y = q[2], z = q[3];
    float xx = x * x, yy = y * y, zz = z * z;
    float xy = x * y, xz = x * z, yz = y * z;
    float wx = w * x, wy = w * y, wz = w * z;
    c[0] = 1.0f - 2.0f * (yy + zz);
    c[1] = 2.0f * (xy - wz);
    c[2] = 2.0f * (xz + wy);
    c[3] = 2.0f * (xy + wz);
    c[4] = 1.0f - 2.0f * (xx + zz);
    c[5] = 2.0f * (yz - wx);
    c[6] = 2.0f * (xz - wy);
    c[7] = 2.0f * (yz + wx);
    c[8] = 1.0f - 2.0f * (xx + yy);
}

/* rot.dcm_to_euler: ypr = [yaw, pitch, roll] from C_bn. */
static inline void rot_dcm_to_euler(float *ypr, const float *c) {
    float s = c[7];
    if (s > 1.0f) {
        s = 1.0f;
    } else if (s < -1.0f) {
        s = -1.0f;
    }
    ypr[1] = f32_asin(s);
    ypr[2] = f32_atan2(-c[6], c[8]);
    ypr[0] = f32_atan2(-c[1], c[4]);
}

/* rot.euler_to_q: q_bn = q_z(yaw) (x) q_x(pitch) (x) q_y(roll), stored with w >= 0 */
static inline void rot_euler_to_q(float *q, const float *ypr) {
    float hy = 0.5f * ypr[0];
    float hp = 0.5f * ypr[1];
    float hr = 0.5f * ypr[2];
    float sz = f32_sin(hy);
    float cz = f32_cos(hy);
    float sx = f32_sin(hp);
    float cx = f32_cos(hp);
    float sr = f32_sin(hr);
    float cr = f32_cos(hr);
    float czcx = cz * cx;
    float szsx = sz * sx;
    float czsx = cz * sx;
    float szcx = sz * cx;
    float w = czcx * cr - szsx * sr;
    float x = czsx * cr - szcx * sr;
    float y = czcx * sr + szsx * cr;
    float z = szcx * cr + czsx * sr;
    if (w < 0.0f) {
        w = -w;
        x = -x;
        y = -y;
        z = -z;
    }
    q[0] = w;
    q[1] = x;
    q[2] = y;
    q[3] = z;
}

#endif
