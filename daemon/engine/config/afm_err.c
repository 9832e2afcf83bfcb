/* SPDX-License-Identifier: MIT */
/* afm_err.c -- see afm_err.h. */
#include "config/afm_err.h"

#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>

void afm_err_set(char *err, size_t errlen, const char *fmt, ...) {
    if (!err || !errlen) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

char *afm_err_printable(char *dst, size_t dstlen, const char *src, size_t srclen) {
    static const char hex[] = "0123456789abcdef";
    if (!dst || !dstlen) return dst;
    size_t o = 0;
    for (size_t i = 0; src && i < srclen && src[i]; i++) {
        unsigned char c = (unsigned char)src[i];
        bool plain = c >= 0x20 && c <= 0x7e && c != '\\';
        if (o + (plain ? 1 : 4) >= dstlen) break;
        if (plain) {
            dst[o++] = (char)c;
        } else {
            dst[o++] = '\\';
            dst[o++] = 'x';
            dst[o++] = hex[c >> 4];
            dst[o++] = hex[c & 15];
        }
    }
    dst[o] = 0;
    return dst;
}
