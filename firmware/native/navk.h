/* navk: the firmware's native float32 kernels (docs/requirements.md, float32 contract rule 7).
 *
 * This header is the one interface of the kernels. The bindings are generated from it: the
 * MicroPython native module (armv7emsp for the board, x64 for the desktop VM) and the cffi
 * extension for CPython. So it holds only plain prototypes, one per line, of these types:
 *   float * / const float *       a float32 buffer (array('f') on the board, numpy.float32)
 *   int32_t * / const int32_t *   an int32 buffer (array('i'))
 *   int16_t * / const int16_t *   an int16 buffer (array('h'))
 *   uint8_t * / const uint8_t *   a byte buffer (bytearray)
 *   int32_t                       a small int
 *   float                         a float scalar (boxes a float: tests only, never per tick)
 * returning void, int32_t or float. Every exported name starts with navk_.
 */
int32_t navk_abi(void);
void navk_add(float *out, const float *a, const float *b, int32_t n);
void navk_ins_step(float *x, const float *w_b, const float *f_b, int32_t coning);
void navk_eskf_work(float *e, int32_t *ii, int32_t n);
int32_t navk_eskf_diagonal_ok(const float *e);
int32_t navk_imu_cal(float *w, float *f, const int16_t *gyro, const int16_t *accel, const float *cal, int32_t flags);
int32_t navk_still(float *st, const float *f, const float *w, const float *x, const float *prm, int32_t flags);
void navk_ring_put(float *ring_p, float *ring_v, const float *x, const float *corr, int32_t b);
int32_t navk_ins_finite(const float *x);
void navk_inject(float *x, float *e, float *corr);
void navk_euler(float *ypr, const float *c_bn);
void navk_frame_pack(uint8_t *buf, const int32_t *fields, const int16_t *gyro, const int16_t *accel, const int32_t *lat, const int32_t *lon, const float *ypr, const float *v_n, const float *p_n, float ypr_cdeg_scale);
void navk_nav_frame(uint8_t *buf, const int32_t *fields, const int16_t *gyro, const int16_t *accel, float *m);
void navk_ext_pack(uint8_t *buf, const int32_t *fields, const float *p, const float *x, const float *coef,
    const float *cv);
void navk_raw_pack(uint8_t *buf, const int32_t *fields, const uint8_t *raw_gyro, const uint8_t *raw_accel, const uint8_t *rx);
void navk_bytes_copy(uint8_t *dst, int32_t off, const uint8_t *src, int32_t n);
int32_t navk_tx_write(int32_t *tx, uint8_t *bufs, const uint8_t *src, int32_t n);
int32_t navk_tx_poll(int32_t *tx, uint8_t *bufs);
int32_t navk_text_num(uint8_t *t, int32_t p, int32_t v, int32_t form);
int32_t navk_text_diff(uint8_t *s, int32_t o, const uint8_t *t, int32_t n);
void navk_fix_in(float *fx, const int32_t *fi, const float *aid);
void navk_gnss_fix(int32_t *c, float *m, const int32_t *fi);
int32_t navk_fix_usable(int32_t *c, float *m);
int32_t navk_fix_check(float *st, const float *fx, const float *x, const float *aid,
                       const float *p, int32_t any_hdop);
void navk_geo_enu(float *enu, const float *coef, const float *h, const int32_t *d_e7);
void navk_geo_coef(float *c, int32_t lat0_e7);
int32_t navk_bmi055_decode(int16_t *gyro, int16_t *accel, const uint8_t *raw_gyro, const uint8_t *raw_accel);
void navk_prop_start(float *x, float *e, int32_t *ii, int32_t ticks);
void navk_zupt_rows(float *e, int32_t *ii, const float *x, const float *aid);
void navk_nhc_rows(float *e, int32_t *ii, const float *x, const float *aid);
void navk_gnss_rows(float *e, int32_t *ii, const float *x, const float *ring_p, const float *ring_v, const float *corr, float *gp, const float *fx, float *used, const float *w, const float *aid, int32_t b, float rk, float rvel);
int32_t navk_nmea_scan(int32_t *s, uint8_t *lb, const uint8_t *buf, int32_t n);
void navk_nav_start(int32_t *c, int32_t *ii, float *m);
void navk_nav_restart(int32_t *c, int32_t *ii, float *m, int32_t kind);
void navk_gsf_accum(float *m);
int32_t navk_gsf_step(int32_t *c, float *m);
int32_t navk_nav_tick(int32_t *c, int32_t *ki, float *m, const int16_t *gyro, const int16_t *accel);

/* ---- fmath32 (vectorised, for the exhaustive tests): the host's only, not the board's (its
 * module's code sits in its heap) ---- */
#ifndef NAVK_NATMOD
void navk_sin_n(float *out, const float *x, int32_t n);
void navk_cos_n(float *out, const float *x, int32_t n);
void navk_asin_n(float *out, const float *x, int32_t n);
void navk_atan2_n(float *out, const float *y, const float *x, int32_t n);
#endif
