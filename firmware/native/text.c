/* navk text kernels: the status page's integer formatting (lib/status_page.py), byte for byte
 * its Python references _text_num_py and _text_diff_py, which the page uses without navk.
 * Integer work only: what a turn of the page costs the loop is mostly these loops in Python
 * (measured on the emulated STM32F411: docs/display.md). */
#include <stdint.h>

#include "navk.h"
#include "layout.h"

/* status_page's forms of a number: width | decimals << 8 | TN_SIGNED | TN_ZEROS */

/* The int v over 10**dec into t[p:p+w], right-aligned, spaces (TN_ZEROS: zeros) before; with
 * TN_SIGNED its sign (+ or -) just before the first digit (|v| then; a space must be left for
 * it). Digits beyond the width are dropped (the caller clamps). p + w. */
int32_t navk_text_num(uint8_t *t, int32_t p, int32_t v, int32_t form) {
    int32_t w = form & TN_WIDTH;
    int32_t dec = (form >> TN_DEC_SHIFT) & TN_DEC;
    int32_t neg = v < 0;
    uint32_t u = neg ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
    int32_t i = p + w;
    while (dec) {
        t[--i] = (uint8_t)('0' + u % 10u);
        u /= 10u;
        if (--dec == 0) {
            t[--i] = '.';
        }
    }
    t[--i] = (uint8_t)('0' + u % 10u);
    u /= 10u;
    while (i > p) {
        if (u) {
            t[--i] = (uint8_t)('0' + u % 10u);
            u /= 10u;
        } else {
            t[--i] = (form & TN_ZEROS) ? '0' : ' ';
        }
    }
    if (form & TN_SIGNED) {
        i = p;
        while (t[i] == ' ') {
            i++;
        }
        t[i - 1] = neg ? '-' : '+';
    }
    return p + w;
}

/* Whether t[0:n] differs from s[o:o+n] (1) or not (0); s[o:o+n] becomes t[0:n]. */
int32_t navk_text_diff(uint8_t *s, int32_t o, const uint8_t *t, int32_t n) {
    int32_t d = 0;
    for (int32_t i = 0; i < n; i++) {
        if (s[o + i] != t[i]) {
            s[o + i] = t[i];
            d = 1;
        }
    }
    return d;
}
