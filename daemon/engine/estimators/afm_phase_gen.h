/* SPDX-License-Identifier: MIT */
/* afm_phase_gen.h -- tone 0's phase theta at each sample, as a function of the sample index
 * alone: the reference that every estimator and controller lock-in of the twin takes, so that
 * how the samples are cut into pushes changes no bit (the chain's estimators, and the
 * runner's control lock-in of the internal AM and FM loops: with its own slice-anchored
 * phase, lockstep and replay --block 700 imaged a scan a few ulp apart from replay --block
 * 1024, issue 18).
 *
 * Layer estimators/ (4). theta = p_org + wdt (k - k_org) at the sample k steps after the
 * drive's t0 (theta = phase_rad + omega (t - t0) there), with the origin k_org a multiple of
 * AFM_PHASE_GEN_REBASE: theta stays below 2 pi + wdt AFM_PHASE_GEN_REBASE, and crossing into
 * the next segment wraps p_org mod 2 pi (a jump of whole turns, which the trackers keep their
 * lock through). The count is exact, so theta carries only roundings relative to itself (~3
 * eps |theta|), not the rounding of the sample time t (omega ulp(t): 4e-9 rad at 20 s,
 * growing with uptime), which the estimators' trackers must not mistake for a changing rate.
 * The origin moves at fixed indices. A new drive starts from its own origin: p_org of the
 * segment it is in, from phase_rad. A tone on a simulator's sample grid takes each origin
 * from afm_drive_phase_mod (exact from the step count), not from the sum of the segments
 * before: over a week the sum's roundings would add up to ~1e-4 rad of lock-in phase.
 * Samples off the drive's time grid (not made by a simulator at this rate) get afm_drive_phase's
 * own expression. No allocation; O(1) per sample. */
#ifndef AFM_PHASE_GEN_H
#define AFM_PHASE_GEN_H

#include "forces/afm_drive.h"
#include "integrators/afm_sim.h"

#include <stdbool.h>

#define AFM_PHASE_GEN_REBASE 1048576.0

typedef struct {
    double fs;        /* sample rate (Hz) */
    bool set;         /* the origin is set for the drive below */
    double ph, w, t0; /* the drive's tone 0 it follows */
    double wdt;       /* phase step per sample */
    double k_org;     /* origin: a sample index (from t0), multiple of AFM_PHASE_GEN_REBASE */
    double p_org;     /* theta at k_org, mod 2 pi */
    double t_last;    /* time of the last sample given (NAN: none) */
} afm_phase_gen;

/* What afm_phase_gen_run saw of tone 0 before s[0]. */
typedef enum {
    AFM_PHASE_SAME = 0, /* unchanged (or the first frame) */
    AFM_PHASE_STEP = 1, /* changed right before s[0], which follows the last sample given:
                           the estimators may take the new rate at once (their O(1) rebase
                           with theta th[0] - wdt at the last sample, in the new frame) */
    AFM_PHASE_JUMP = 2  /* changed, with a gap (reset, first samples after a jump) */
} afm_phase_change;

/* Forget the origin and the last sample (a new chain, a reset). */
void afm_phase_gen_reset(afm_phase_gen *g, double fs_hz);
/* theta[i] of samples s[0..n) (n >= 1) for tone 0 of d; what changed before s[0]. */
afm_phase_change afm_phase_gen_run(afm_phase_gen *g, const afm_drive *d, const afm_sample *s, int n,
                                   double *th);

#endif
