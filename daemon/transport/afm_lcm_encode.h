/* SPDX-License-Identifier: MIT */
/* afm_lcm_encode.h -- the one mapping from the daemon's output records (afm_io.h) to the
 * generated LCM types: the LCM transport publishes them, `afmtwin replay` writes them to
 * a log. The messages point into the records (and, for harmonics, into a caller's
 * buffer): valid while those live. No allocation. */
#ifndef AFM_LCM_ENCODE_H
#define AFM_LCM_ENCODE_H

#include "afm_io.h"

#include "afmtwin_harmonics_t.h"
#include "afmtwin_samples_t.h"
#include "afmtwin_status_t.h"

typedef struct {
    int16_t k[AFM_MAX_HARMONICS];
    double xa[AFM_MAX_HARMONICS], xp[AFM_MAX_HARMONICS];
    double fa[AFM_MAX_HARMONICS], fp[AFM_MAX_HARMONICS], pd[AFM_MAX_HARMONICS];
} afm_lcm_harm_buf;

void afm_lcm_samples_msg(const afm_io_samples *s, afmtwin_samples_t *m);
/* t_s of the message is the period's start (p.cycle.t_start_s). */
void afm_lcm_harmonics_msg(const afm_io_harmonics *h, afm_lcm_harm_buf *buf,
                           afmtwin_harmonics_t *m);
void afm_lcm_status_msg(const afm_io_status *s, afmtwin_status_t *m);

#endif
