/* SPDX-License-Identifier: MIT */
/* afm_err.h -- the one way the library writes an error message into a caller's buffer. */
#ifndef AFM_ERR_H
#define AFM_ERR_H

#include <stddef.h>

/* printf-style into err (errlen bytes, always terminated); no-op when err is NULL or
 * errlen is 0. The library never prints: callers decide where messages go. */
void afm_err_set(char *err, size_t errlen, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

#endif
