/* SPDX-License-Identifier: MIT */
/* afm_io_records.c -- output records from chain outputs (contract in afm_io_records.h). */
#include "transport/afm_io_records.h"

#include <math.h>

void afm_io_samples_from_block(afm_io_samples *o, const afm_chain_block *b, int64_t utime,
                               int64_t seq_applied, const afm_runner_oppoint *op) {
    int n = b->n < AFM_IO_MAX_BLOCK ? b->n : AFM_IO_MAX_BLOCK;
    o->op = *op;
    o->utime = utime;
    o->seq_applied = seq_applied;
    o->stream = b->stream;
    o->t0_s = b->t_s[0];
    o->rate_hz = b->rate_hz;
    o->decimation = b->decimation;
    o->passband_hz = b->passband_hz;
    o->stopband_hz = b->stopband_hz;
    o->n = n;
    for (int i = 0; i < n; i++) {
        o->deflection_m[i] = (float)b->x_m[i];
        o->obd_m[i] = (float)b->obd_m[i];
        o->obd_counts[i] = b->obd_counts ? (int32_t)lrint(b->obd_counts[i]) : 0;
        o->force_n[i] = (float)b->f_n[i];
    }
}

void afm_io_harmonics_from_period(afm_io_harmonics *o, const afm_chain_period *p, double fe_hz,
                                  int64_t utime, int64_t seq_applied,
                                  const afm_runner_oppoint *op) {
    o->op = *op;
    o->utime = utime;
    o->seq_applied = seq_applied;
    /* the period's own tone 0 (its item's drive: under FM control the NCO moves it between
     * items), not the newest one the chain has seen */
    o->fe_hz = op->n_tones > 0 ? op->freq_hz[0] : fe_hz;
    o->p.harm = p->harm;
    o->p.cycle = p->cycle;
    o->p.lockin_amplitude_m = p->lockin_amplitude_m;
    o->p.lockin_phase_deg = p->lockin_phase_deg;
}

int afm_io_harmonics_every(int every, double fe_hz, double max_hz) {
    if (every > 0) return every;
    double f = fe_hz / (max_hz > 0 ? max_hz : AFM_IO_HARMONICS_MAX_HZ);
    return f > 1 ? (f < 1e9 ? (int)ceil(f) : 1000000000) : 1; /* no int overflow */
}
