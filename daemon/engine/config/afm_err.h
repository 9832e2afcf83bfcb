/* SPDX-License-Identifier: MIT */
/* afm_err.h -- the one way the library writes an error message into a caller's buffer,
 * and how untrusted bytes are quoted in one. */
#ifndef AFM_ERR_H
#define AFM_ERR_H

#include <stddef.h>

/* printf-style into err (errlen bytes, always terminated); no-op when err is NULL or
 * errlen is 0. The library never prints: callers decide where messages go. */
void afm_err_set(char *err, size_t errlen, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* src (at most srclen bytes, up to a NUL) as printable ASCII into dst (dstlen bytes, always
 * terminated, cut short if needed): bytes outside 0x20..0x7e and the backslash become \xNN,
 * so that bytes from the network cannot put control characters (terminal escapes, new
 * lines) into a log line or a status string. Returns dst. */
char *afm_err_printable(char *dst, size_t dstlen, const char *src, size_t srclen);

#endif
