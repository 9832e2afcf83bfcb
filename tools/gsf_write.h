/* SPDX-License-Identifier: MIT */
/* gsf_write.h -- writing an image as a Gwyddion Simple Field file (.gsf; issue 30), a format
 * that AFM software opens (Gwyddion, and what reads Gwyddion's files); `afmtwin scan --gsf`
 * writes each of its images so. In its own file, apart from cmd_scan.c, because it is the
 * file format and nothing of a scan: a few lines of C instead of libgwyddion (GTK) as a
 * dependency, and another tool can write its images with it too.
 *
 * The format (gwyddion.net/documentation/user-guide-en/gsf.html): the line "Gwyddion Simple
 * Field 1.0", "name = value" lines (XRes, YRes, XReal, YReal, XOffset, YOffset, XYUnits,
 * ZUnits, Title), 1 to 4 NUL bytes so that the data start at a multiple of 4, then XRes x YRes
 * IEEE 754 binary32 values, little-endian, row by row: row 0 (at y = YOffset) first, each row
 * from x = XOffset up. Gwyddion's reader wants exactly that many values (no more, no fewer). */
#ifndef AFMT_GSF_WRITE_H
#define AFMT_GSF_WRITE_H

#include <stddef.h>
#include <stdio.h>

typedef struct {
    int xres, yres;          /* values per row, rows (>= 1) */
    double xreal, yreal;     /* the image's size in xy_units (finite, > 0) */
    double xoffset, yoffset; /* its corner at row 0, value 0 (finite) */
    const char *xy_units;    /* "m" */
    const char *z_units;     /* "m", "deg", "N", ...; NULL or "": none (the line left out) */
    const char *title;       /* the channel's name in Gwyddion (UTF-8) */
} afmt_gsf_header;

/* The header of h, with its NUL padding, to f; the data follow (afmt_gsf_write_values).
 * 0, or -1 with errno (EINVAL: a size out of range, a text with a line break in it). */
int afmt_gsf_write_header(FILE *f, const afmt_gsf_header *h);

/* n values to f as little-endian binary32 (a row: xres values). 0, or -1 (a write error). */
int afmt_gsf_write_values(FILE *f, const float *v, size_t n);

#endif
