/* SPDX-License-Identifier: MIT */
/* afm_io_records.h -- the output records of afm_io.h from what the runner's chain gives:
 * one mapping for the daemon's chain thread and `afmtwin replay`. No allocation. */
#ifndef AFM_IO_RECORDS_H
#define AFM_IO_RECORDS_H

#include "transport/afm_io.h"

/* A samples record from a chain block (b->n <= AFM_IO_MAX_BLOCK): floats, and the ADC
 * counts rounded to the nearest integer (0 without ADC). */
void afm_io_samples_from_block(afm_io_samples *o, const afm_chain_block *b, int64_t utime,
                               int64_t seq_applied, const afm_runner_oppoint *op);

/* A harmonics record from one period's estimates (p finished: afm_chain_period_finish). */
void afm_io_harmonics_from_period(afm_io_harmonics *o, const afm_chain_period *p, double fe_hz,
                                  int64_t utime, int64_t seq_applied, const afm_runner_oppoint *op);

/* Which periods' harmonics go out: every k-th. every > 0 is k itself; every <= 0 chooses
 * the smallest k for which at most max_hz records a second go out at the drive frequency
 * fe_hz (max_hz <= 0: 1000). The daemon's rule, and `afmtwin replay`'s. */
#define AFM_IO_HARMONICS_MAX_HZ 1000.0
int afm_io_harmonics_every(int every, double fe_hz, double max_hz);

#endif
