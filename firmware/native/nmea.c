/* The NMEA parser's byte loop, line checks and field parsing (firmware/drivers/gnss.py: `_scan_py`
 * and the functions it calls are the reference, step by step). Integers only: every value stays
 * below 1e9 in magnitude, as in the reference, so int32 arithmetic is exact and C's truncating
 * division equals Python's floor division (no operand is negative where one is taken). */
#include <stdint.h>

#include "layout.h"
#include "navk.h"


/* gnss_kern._num */
static int32_t num(const uint8_t *line, int32_t a, int32_t b, int32_t k) {
    if (a >= b) {
        return NMEA_EMPTY;
    }
    int32_t c = line[a];
    int32_t neg = c == 45;
    if (neg || c == 43) {
        a += 1;
    }
    int32_t v = 0;
    int32_t nd = 0;
    int32_t dec = -1;
    int32_t up = 0;
    while (a < b) {
        c = line[a] - 48;
        a += 1;
        if (0 <= c && c <= 9) {
            nd += 1;
            if (dec < k) {
                if (v >= NMEA_CAP) {
                    return NMEA_BAD;
                }
                v = v * 10 + c;
                if (dec >= 0) {
                    dec += 1;
                }
            } else if (dec == k) {
                up = c >= 5;
                dec += 1;
            }
        } else if (c == -2 && dec < 0) {
            dec = 0;
        } else {
            return NMEA_BAD;
        }
    }
    if (nd == 0) {
        return NMEA_BAD;
    }
    if (dec < 0) {
        dec = 0;
    }
    while (dec < k) {
        if (v >= NMEA_CAP) {
            return NMEA_BAD;
        }
        v *= 10;
        dec += 1;
    }
    if (up) {
        v += 1;
    }
    return neg ? -v : v;
}

/* gnss_kern._nn */
static int32_t nn(int32_t v) {
    if (v == NMEA_EMPTY) {
        return -1;
    }
    if (v < 0) {
        return NMEA_BAD;
    }
    return v;
}

/* gnss_kern._mins */
static int32_t mins(const uint8_t *line, int32_t a, int32_t b) {
    int32_t p = a;
    while (p < b && line[p] != 46) {
        p += 1;
    }
    p -= 2;
    if (p <= a || p - a > 3) {
        return -1;
    }
    return p;
}

/* gnss_kern._uint */
static int32_t uint_(const uint8_t *line, int32_t a, int32_t p) {
    int32_t v = 0;
    while (a < p) {
        int32_t c = line[a] - 48;
        if (c < 0 || c > 9) {
            return -1;
        }
        v = v * 10 + c;
        a += 1;
    }
    return v;
}

/* gnss_kern._min_e7 */
static int32_t min_e7(const uint8_t *line, int32_t p, int32_t b) {
    int32_t v = 0;
    int32_t i = p;
    int32_t n = 0;
    while (i < b) {
        int32_t c = line[i] - 48;
        if (i == p + 2) {
            if (c != -2) {
                return -1;
            }
        } else if (0 <= c && c <= 9) {
            if (i < p + 2) {
                v = v * 10 + c;
            } else if (n < 7) {
                v = v * 10 + c;
                n += 1;
            }
        } else {
            return -1;
        }
        i += 1;
    }
    if (i < p + 2) {
        return -1;
    }
    while (n < 7) {
        v *= 10;
        n += 1;
    }
    return (v + 30) / 60;
}

/* gnss._utc_ms */
static int32_t utc_ms(const uint8_t *line, int32_t a, int32_t b) {
    if (a >= b) {
        return -1;
    }
    if (b - a < 6) {
        return NMEA_BAD;
    }
    int32_t v = 0;
    for (int32_t i = a; i < a + 6; i++) {
        int32_t c = line[i] - 48;
        if (c < 0 || c > 9) {
            return NMEA_BAD;
        }
        v = v * 10 + c;
    }
    int32_t ms = 0;
    int32_t n = 0;
    int32_t i = a + 6;
    if (i < b) {
        if (line[i] != 46) {
            return NMEA_BAD;
        }
        i += 1;
        while (i < b) {
            int32_t c = line[i] - 48;
            if (c < 0 || c > 9) {
                return NMEA_BAD;
            }
            if (n < 3) {
                ms = ms * 10 + c;
                n += 1;
            }
            i += 1;
        }
    }
    while (n < 3) {
        ms *= 10;
        n += 1;
    }
    int32_t h = v / 10000;
    int32_t m = v / 100 % 100;
    int32_t s = v % 100;
    if (h > 23 || m > 59 || s > 60 || (s == 60 && h * 100 + m != 2359)) {
        return -1; /* a leap second is 23:59:60 only */
    }
    return ((h * 60 + m) * 60 + s) * 1000 + ms;
}

/* gnss_kern._char */
static int32_t chr_(const uint8_t *line, int32_t a, int32_t b) {
    if (a >= b) {
        return 0;
    }
    if (b - a > 1) {
        return -1;
    }
    return line[a];
}

/* gnss_kern._hex */
static int32_t hex(int32_t c) {
    if (48 <= c && c <= 57) {
        return c - 48;
    }
    if (65 <= c && c <= 70) {
        return c - 55;
    }
    if (97 <= c && c <= 102) {
        return c - 87;
    }
    return -1;
}

/* gnss._pos: fields i..i+3 into s[NS_LAT..NS_FRAC]; 1 valid, 0 empty or out of range, -1 bad */
static int32_t pos(int32_t *s, const uint8_t *line, const uint8_t *fs, int32_t i) {
    int32_t a = fs[i];
    int32_t b = fs[i + 1] - 1;
    int32_t c = fs[i + 2] - 1;
    int32_t d = fs[i + 3] - 1;
    int32_t e = fs[i + 4] - 1;
    if (a == b && c + 1 == d) {
        return 0;
    }
    int32_t p = mins(line, a, b);
    if (p < 0) {
        return -1;
    }
    int32_t deg = uint_(line, a, p);
    int32_t fr = min_e7(line, p, b);
    if (deg < 0 || fr < 0) {
        return -1;
    }
    int32_t ok = 1;
    if (deg > 90 || fr > 10000000) {
        ok = 0;
        deg = 0;
    }
    int32_t lat = deg * 10000000 + fr;
    p = mins(line, c + 1, d);
    if (p < 0) {
        return -1;
    }
    deg = uint_(line, c + 1, p);
    fr = min_e7(line, p, d);
    if (deg < 0 || fr < 0) {
        return -1;
    }
    if (fr > 10000000) {
        ok = 0;
    } else if (fr == 10000000) {
        deg += 1;
        fr = 0;
    }
    if (lat > 900000000 || deg > 180 || (deg == 180 && fr > 0)) {
        ok = 0;
    }
    int32_t ns = chr_(line, b + 1, c);
    int32_t ew = chr_(line, d + 1, e);
    if (ns == 83) {
        lat = -lat;
    } else if (ns != 78) {
        ok = 0;
    }
    if (ew == 87) {
        deg = -deg;
        fr = -fr;
    } else if (ew != 69) {
        ok = 0;
    }
    s[NS_LAT] = lat;
    s[NS_DEG] = deg;
    s[NS_FRAC] = fr;
    return ok;
}

/* 1e-4 kn -> mm/s: * 1852e3 / 3600e4 = * 463 / 9000, in two parts (kn >= 0) */
static int32_t knots_mm_s(int32_t kn) {
    return kn / 9000 * 463 + (kn % 9000 * 463 + 4500) / 9000;
}

/* gnss._gga_fields */
static int32_t gga(int32_t *s, const uint8_t *line, const uint8_t *fs, int32_t nf) {
    if (nf < 10) {
        return 0;
    }
    int32_t utc = utc_ms(line, fs[1], fs[2] - 1);
    int32_t p = pos(s, line, fs, 2);
    int32_t q = nn(num(line, fs[6], fs[7] - 1, 0));
    int32_t ns = nn(num(line, fs[7], fs[8] - 1, 0));
    int32_t hd = nn(num(line, fs[8], fs[9] - 1, 2));
    int32_t alt = num(line, fs[9], fs[10] - 1, 3);
    int32_t sep = NMEA_EMPTY;
    if (nf >= 12) {
        sep = num(line, fs[11], fs[12] - 1, 3);
    }
    if (utc == NMEA_BAD || p < 0 || q == NMEA_BAD || ns == NMEA_BAD || hd == NMEA_BAD) {
        return 0;
    }
    if (alt == NMEA_BAD || sep == NMEA_BAD) {
        return 0;
    }
    s[NS_UTC] = utc;
    s[NS_POS] = p;
    s[NS_A] = q;
    s[NS_B] = ns;
    s[NS_C] = hd;
    s[NS_D] = alt;
    s[NS_E] = sep;
    return 1;
}

/* gnss._rmc_fields */
static int32_t rmc(int32_t *s, const uint8_t *line, const uint8_t *fs, int32_t nf) {
    if (nf < 10) {
        return 0;
    }
    int32_t utc = utc_ms(line, fs[1], fs[2] - 1);
    int32_t st = chr_(line, fs[2], fs[3] - 1);
    int32_t p = pos(s, line, fs, 3);
    int32_t kn = nn(num(line, fs[7], fs[8] - 1, 4));
    int32_t crs = nn(num(line, fs[8], fs[9] - 1, 2));
    int32_t a = fs[9];
    int32_t b = fs[10] - 1;
    int32_t date = -1;
    if (b - a == 6) {
        date = uint_(line, a, b);
        if (date < 0) {
            return 0;
        }
        int32_t d = date / 10000;
        int32_t m = date / 100 % 100;
        date = (date % 100) * 10000 + m * 100 + d;
        if (d < 1 || d > 31 || m < 1 || m > 12) {
            date = -1;
        }
    } else if (a != b) {
        return 0;
    }
    int32_t mode = 0;
    if (nf > 12) {
        mode = chr_(line, fs[12], fs[13] - 1);
    }
    if (utc == NMEA_BAD || st < 0 || p < 0 || mode < 0) {
        return 0;
    }
    if (kn == NMEA_BAD || crs == NMEA_BAD) {
        return 0;
    }
    s[NS_UTC] = utc;
    s[NS_POS] = p;
    s[NS_A] = st;
    s[NS_B] = kn >= 0 ? knots_mm_s(kn) : -1;
    s[NS_C] = crs;
    s[NS_D] = date;
    s[NS_E] = mode;
    return 1;
}

/* gnss._vtg_fields */
static int32_t vtg(int32_t *s, const uint8_t *line, const uint8_t *fs, int32_t nf) {
    if (nf < 9) {
        return 0;
    }
    int32_t crs = nn(num(line, fs[1], fs[2] - 1, 2));
    int32_t kn = nn(num(line, fs[5], fs[6] - 1, 4));
    int32_t kmh = nn(num(line, fs[7], fs[8] - 1, 4));
    int32_t mode = 0;
    if (nf > 9) {
        mode = chr_(line, fs[9], fs[10] - 1);
    }
    if (crs == NMEA_BAD || kn == NMEA_BAD || kmh == NMEA_BAD || mode < 0) {
        return 0;
    }
    int32_t spd = -1;
    if (kmh >= 0) {
        spd = (kmh + 18) / 36; /* 1e-4 km/h -> mm/s */
    } else if (kn >= 0) {
        spd = knots_mm_s(kn);
    }
    s[NS_B] = spd;
    s[NS_C] = crs;
    s[NS_E] = mode;
    return 1;
}

/* gnss._gsa_fields */
static int32_t gsa(int32_t *s, const uint8_t *line, const uint8_t *fs, int32_t nf) {
    if (nf < 18) {
        return 0;
    }
    int32_t mode = chr_(line, fs[1], fs[2] - 1);
    int32_t fix = nn(num(line, fs[2], fs[3] - 1, 0));
    int32_t pd = nn(num(line, fs[15], fs[16] - 1, 2));
    int32_t hd = nn(num(line, fs[16], fs[17] - 1, 2));
    int32_t vd = nn(num(line, fs[17], fs[18] - 1, 2));
    if (mode < 0 || fix == NMEA_BAD || pd == NMEA_BAD || hd == NMEA_BAD || vd == NMEA_BAD) {
        return 0;
    }
    int32_t nsv = 0;
    for (int32_t i = 3; i < 15; i++) {
        if (fs[i + 1] - 1 > fs[i]) {
            nsv += 1;
        }
    }
    s[NS_A] = fix;
    s[NS_B] = nsv;
    s[NS_C] = hd;
    s[NS_D] = pd;
    s[NS_E] = mode;
    s[NS_F] = vd;
    return 1;
}

/* gnss_kern._line: a line lb[0:k] ended by CR/LF: the result of the scan */
static int32_t line_end(int32_t *s, uint8_t *lb, int32_t k, int32_t x, int32_t star, int32_t nf) {
    const uint8_t *line = lb;
    uint8_t *fs = lb + NMEA_MAXLEN;
    s[NS_LEN] = k;
    if (star < 0) {
        return NR_NO_CSUM;
    }
    if (k != star + 3) {
        return NR_MALFORMED;
    }
    int32_t h = hex(line[star + 1]);
    int32_t lo = hex(line[star + 2]);
    if (h < 0 || lo < 0) {
        return NR_MALFORMED;
    }
    if (h * 16 + lo != x) {
        return NR_BAD_CSUM;
    }
    fs[nf] = (uint8_t)(star + 1);
    int32_t kind = 0;
    if (fs[1] == 6) { /* a five-letter address */
        int32_t t = (line[0] << 8) | line[1];
        /* any talker (GP GN GL GA GB BD GQ QZ IN ...): two capitals, P (proprietary) excepted */
        if (line[0] >= 65 && line[0] <= 90 && line[0] != 80 && line[1] >= 65 && line[1] <= 90) {
            int32_t f = (line[2] << 16) | (line[3] << 8) | line[4];
            if (f == NMEA_FMT_GGA) {
                kind = NR_GGA;
            } else if (f == NMEA_FMT_RMC) {
                kind = NR_RMC;
            } else if (f == NMEA_FMT_VTG) {
                kind = NR_VTG;
            } else if (f == NMEA_FMT_GSA) {
                kind = NR_GSA;
            }
            s[NS_TALKER] = t;
        }
    }
    if (kind == 0) {
        return NR_IGNORED;
    }
    int32_t ok;
    if (nf >= NMEA_MAXF) {
        ok = 0;
    } else if (kind == NR_GGA) {
        ok = gga(s, line, fs, nf);
    } else if (kind == NR_RMC) {
        ok = rmc(s, line, fs, nf);
    } else if (kind == NR_VTG) {
        ok = vtg(s, line, fs, nf);
    } else {
        ok = gsa(s, line, fs, nf);
    }
    return ok ? kind : NR_BAD_FIELD;
}

/* gnss_kern.scan: consume buf[s[NS_I]:n] up to the first thing the parser reports (a line's
 * end, a rejection); 0 when all n bytes are consumed. The framing state lives in s between
 * calls, the line and its comma table in lb (NMEA_MAXLEN + NMEA_MAXF + 1 bytes). */
int32_t navk_nmea_scan(int32_t *s, uint8_t *lb, const uint8_t *buf, int32_t n) {
    uint8_t *fs = lb + NMEA_MAXLEN;
    int32_t k = s[NS_K];
    int32_t x = s[NS_X];
    int32_t star = s[NS_STAR];
    int32_t nf = s[NS_NF];
    int32_t r = 0;
    int32_t i = s[NS_I];
    while (i < n && r == 0) {
        int32_t b = buf[i];
        i += 1;
        if (b == 36) { /* '$': a new sentence, whatever came before */
            if (k >= 0) {
                r = NR_COLLIDED;
            }
            k = 0;
            x = 0;
            star = -1;
            nf = 1;
            fs[0] = 0;
        } else if (k < 0) {
            /* outside a sentence: skip */
        } else if (b == 13 || b == 10) {
            r = line_end(s, lb, k, x, star, nf);
            k = -1;
        } else if (b < 32 || b > 126) {
            r = NR_MALFORMED;
            k = -1;
        } else if (k >= NMEA_MAXLEN) {
            r = NR_OVERLONG;
            k = -1;
        } else {
            lb[k] = (uint8_t)b;
            if (star < 0) {
                if (b == 42) { /* '*' */
                    star = k;
                } else {
                    x ^= b;
                    if (b == 44 && nf < NMEA_MAXF) { /* ',' */
                        fs[nf] = (uint8_t)(k + 1);
                        nf += 1;
                    }
                }
            }
            k += 1;
        }
    }
    s[NS_I] = i;
    s[NS_K] = k;
    s[NS_X] = x;
    s[NS_STAR] = star;
    s[NS_NF] = nf;
    return r;
}
