/* SPDX-License-Identifier: MIT */
/* afm_lcm_encode.h -- the one mapping from the daemon's output records (afm_io.h) to the
 * generated LCM types: the LCM transport publishes them, `afmtwin replay` writes them to
 * a log. The messages point into the records (and, for harmonics, into a caller's
 * buffer): valid while those live. No allocation. */
#ifndef AFM_LCM_ENCODE_H
#define AFM_LCM_ENCODE_H

#include "transport/afm_io.h"

#include "afmtwin_harmonics_t.h"
#include "afmtwin_samples_t.h"
#include "afmtwin_status_t.h"
#include "afmtwin_tick_done_t.h"

#include <stdint.h>

typedef struct {
    int16_t k[AFM_MAX_HARMONICS];
    double xa[AFM_MAX_HARMONICS], xp[AFM_MAX_HARMONICS], xl[AFM_MAX_HARMONICS];
    double fa[AFM_MAX_HARMONICS], fp[AFM_MAX_HARMONICS], pd[AFM_MAX_HARMONICS];
} afm_lcm_harm_buf;

void afm_lcm_samples_msg(const afm_io_samples *s, afmtwin_samples_t *m);
/* t_s of the message is the period's start (p.cycle.t_start_s). */
void afm_lcm_harmonics_msg(const afm_io_harmonics *h, afm_lcm_harm_buf *buf,
                           afmtwin_harmonics_t *m);
void afm_lcm_status_msg(const afm_io_status *s, afmtwin_status_t *m);
void afm_lcm_tick_done_msg(const afm_io_tick_done *d, afmtwin_tick_done_t *m);

/* The digest a tick_done_t carries, of the samples and harmonics messages published since the
 * previous one, so that a lockstep client can tell that it has all of them and
 * `afmtwin replay` (which cuts the streams into messages elsewhere) gives the same number:
 * one running 64-bit hash per output stream over its samples one by one (seq_applied and the
 * bits of deflection, obd, counts, force of each; not the time stamps or how the samples were
 * cut into messages), combined by afm_lcm_digest_samples_final; one over the harmonics
 * messages in order (every field but utime); the message counts beside (they depend on the
 * cutting). Start from afm_lcm_digest_init. */
#define AFM_LCM_DIGEST_STREAMS 8
typedef struct {
    uint64_t stream[AFM_LCM_DIGEST_STREAMS];
    uint64_t harmonics;
    int64_t n_samples_msgs, n_harmonics_msgs;
} afm_lcm_digest;
void afm_lcm_digest_init(afm_lcm_digest *d);
void afm_lcm_digest_samples(afm_lcm_digest *d, const afmtwin_samples_t *m);
void afm_lcm_digest_harmonics(afm_lcm_digest *d, const afmtwin_harmonics_t *m);
uint64_t afm_lcm_digest_samples_final(const afm_lcm_digest *d);

#endif
