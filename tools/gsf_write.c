/* SPDX-License-Identifier: MIT */
/* gsf_write.c -- the Gwyddion Simple Field writer (gsf_write.h): kept apart from the scan
 * tool because it is only the file format (header, NUL padding, little-endian floats), small
 * enough to need no Gwyddion library, and usable by any tool that makes images. */
#include "gsf_write.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

_Static_assert(sizeof(float) == 4 && sizeof(uint32_t) == 4, "GSF data are IEEE binary32");

static int text_ok(const char *s) {
    return !s || !strpbrk(s, "\r\n");
}

int afmt_gsf_write_header(FILE *f, const afmt_gsf_header *h) {
    if (!(h->xres >= 1 && h->yres >= 1 && isfinite(h->xreal) && h->xreal > 0 &&
          isfinite(h->yreal) && h->yreal > 0 && isfinite(h->xoffset) && isfinite(h->yoffset) &&
          text_ok(h->xy_units) && text_ok(h->z_units) && text_ok(h->title))) {
        errno = EINVAL;
        return -1;
    }
    /* %.10g: the C locale's decimal point, which Gwyddion's g_ascii_strtod reads */
    int n = fprintf(f,
                    "Gwyddion Simple Field 1.0\n"
                    "XRes = %d\nYRes = %d\nXReal = %.10g\nYReal = %.10g\n"
                    "XOffset = %.10g\nYOffset = %.10g\n",
                    h->xres, h->yres, h->xreal, h->yreal, h->xoffset, h->yoffset);
    if (n < 0) return -1;
    long len = n;
    if (h->xy_units && h->xy_units[0]) {
        if ((n = fprintf(f, "XYUnits = %s\n", h->xy_units)) < 0) return -1;
        len += n;
    }
    if (h->z_units && h->z_units[0]) {
        if ((n = fprintf(f, "ZUnits = %s\n", h->z_units)) < 0) return -1;
        len += n;
    }
    if (h->title && h->title[0]) {
        if ((n = fprintf(f, "Title = %s\n", h->title)) < 0) return -1;
        len += n;
    }
    /* at least one NUL ends the header; 4 when it already ends at a multiple of 4 */
    static const char nul[4] = {0};
    size_t pad = 4 - (size_t)(len % 4);
    return fwrite(nul, 1, pad, f) == pad ? 0 : -1;
}

int afmt_gsf_write_values(FILE *f, const float *v, size_t n) {
    unsigned char buf[4096];
    size_t k = 0;
    for (size_t i = 0; i < n; i++) {
        uint32_t u;
        memcpy(&u, &v[i], sizeof u);
        for (int b = 0; b < 4; b++)
            buf[k++] = (unsigned char)(u >> (8 * b));
        if (k == sizeof buf) {
            if (fwrite(buf, 1, k, f) != k) return -1;
            k = 0;
        }
    }
    return k && fwrite(buf, 1, k, f) != k ? -1 : 0;
}
