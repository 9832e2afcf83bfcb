/* SPDX-License-Identifier: MIT */
/* afm_harm.h -- streaming harmonics of the deflection and of the tip-sample force, one
 * result per drive period (the real-time counterpart of afm_orbit_analyse's harmonics).
 *
 * Layer estimators/ (4). Fed sample by sample with the deflection x (m; the tip displacement
 * or the OBD signal), the tip-sample force f (N) and the exact drive phase theta of tone 0
 * at the sample time, afm_drive_phase(afm_sim_drive(s), 0, sample.t_s). Periods are the
 * intervals between theta = 2 pi m, so a phase-continuous change of fe is followed
 * exactly (only theta mod 2 pi is used: afm_drive re-wraps its phase at a tone change);
 * the first, partial period is skipped. Samples must be uniformly spaced in time
 * (the integral is taken in units of the sample interval).
 *
 * At each completed period, for each configured k (conventions of afm_orbit.h, thesis App.
 * E.4): x(t) ~ A cos(k theta + phi) with theta counted from the period's start, i.e.
 * A e^{i phi} = (2 / T) int x(t) e^{-i k theta(t)} dt over the period, the same for f, and
 * phase_diff_deg = mod(k (180 - phi_1) + phi_k, 360) (eq. E.12-E.13; harmonic 1 is always
 * computed for it). The integral is the trapezoid sum over the samples with fractional
 * ends: the step that contains a period boundary is split there and each part gets the
 * exact integral of the linear interpolant of x e^{-ik theta} (weights in
 * afm_est_internal.h). Hence:
 *  - a period of exactly N samples (boundaries on samples) gives the DFT of those N
 *    samples (2 |X_k| / N, arg X_k) to rounding;
 *  - otherwise the end pieces carry an O(h^3) error: for a pure tone measured at its own
 *    harmonic k, relative error <~ (2 k w h)^2 / (12 N) per period with N = T / h samples
 *    (2.8e-6 for k = 1 at 167 samples per period, the thesis's 84 kHz at 14.06 MHz).
 *
 * Nothing allocates; the caller owns the struct. e^{-ik theta} comes from the drive-phase
 * tracker (afm_phase_track in afm_est_internal.h): while the supplied theta follows its
 * prediction th_ref + n dphi to a few ulps, sample n's phasor is b T[n - n_b], b =
 * e^{-ik phi} at a chunk base n_b steps after th_ref and T[m] = e^{-ik m dphi} tabulated for
 * m = 0..AFM_HARM_TAB (rebuilt when the tracker's dphi changes, rarely). Per sample that is
 * two multiply-adds per harmonic (x and f into chunk sums, 4 harmonics per vector, no
 * rotation); a chunk goes into the period sums (times b) when it reaches AFM_HARM_TAB
 * samples or at a sample off the prediction, where b moves on. At a sample off the
 * prediction (the period boundary: one per period; a jump or drift of theta) the clock is
 * exact (theta mod 2 pi); on the prediction the phasors keep rotating (b T[m + 1] with a
 * first-order correction for the residual, the theta they stand for carried along and kept
 * within the tracker's tol of the supplied one); after a jump or drift of theta, a
 * tolerance miss and every 4096 samples they are recomputed exactly from theta mod 2 pi
 * (one sincos and O(log k) complex products per harmonic). Harmonic 1 shares the lane of a
 * configured k = 1. The sums, the chunk positions and the flushes depend only on the sample
 * sequence, not on how it is split into calls. */
#ifndef AFM_HARM_H
#define AFM_HARM_H

#include "estimators/afm_est_internal.h"
#include "beam/afm_model.h"
#include "estimators/afm_orbit.h"

/* Harmonic lanes: the configured harmonics in their order, then harmonic 1 if it is not
 * among them (for phi_1), padded to a multiple of 4 (pads have k = 0: e^0 = 1, never
 * reported). Complex arrays over the lanes are kept by groups of 4 lanes: 4 real parts, then
 * 4 imaginary parts (lane j at (j / 4) * 8 + j % 4, its imaginary part 4 further). */
#define AFM_HARM_LANES ((AFM_MAX_HARMONICS + 1 + 3) / 4 * 4)

typedef struct {
    long period;    /* sequence number: 0 for the first whole period since init/reset */
    double samples; /* its length in sample intervals (fractional) */
    int n_harmonics;
    /* The period's sums of x e^{-ik phi} and f e^{-ik phi} (trapezoid with fractional ends,
     * unscaled) by groups of 4 lanes: group g at raw + 16 g holds x's 4 real parts, x's 4
     * imaginary parts, then f's. h[] is their polar form (afm_harm_polar). */
    double raw[4 * AFM_HARM_LANES];
    afm_orbit_harmonic h[AFM_MAX_HARMONICS]; /* in the order they were configured */
} afm_harm_result;
/* Steps of the phasor table: e^{-ik m dphi} for m = 0..AFM_HARM_TAB. */
#define AFM_HARM_TAB 64

typedef struct {
    int nk;                    /* configured harmonics */
    int nl;                    /* lanes in use, a multiple of 4 */
    int lane1;                 /* the lane of harmonic 1 */
    int ks[AFM_HARM_LANES];    /* harmonic number of each lane */
    double kd[AFM_HARM_LANES]; /* the same as doubles */
    afm_phase_track trk;
    bool active; /* inside a period that started at a boundary */
    double x_prev, f_prev;
    /* e^{-ik phi} of the chunk base: the sample nbase steps after the tracker's th_ref; the
     * last sample lies trk.n - nbase (0..AFM_HARM_TAB - 1) steps after it */
    double b[2 * AFM_HARM_LANES];
    double nbase;
    double imp_ref; /* theta the phasors stand for at the tracker's th_ref */
    double n_sync;  /* samples since the phasors were computed exactly */
    /* chunk sums since the chunk base: x e^{-ik (phi - phi_base)}, f the same (weight 1 per
     * sample); period sums of x e^{-ik phi}, f e^{-ik phi} before the chunk base, with the
     * ends weighted for the trapezoid with fractional ends */
    double cx[2 * AFM_HARM_LANES], cf[2 * AFM_HARM_LANES];
    double sx[2 * AFM_HARM_LANES], sf[2 * AFM_HARM_LANES];
    double wsum;         /* sample intervals of the period's first (partial) step */
    double nsteps;       /* whole steps since then */
    long periods;        /* completed periods since init/reset */
    bool deferred;       /* out.h[] left to afm_harm_polar (afm_harm_set_deferred) */
    afm_harm_result out; /* the last completed period (valid if periods > 0 and out_at NULL) */
    /* where the next completed period goes (NULL: out): the output chain points it at its
     * next period record, so that the sums are written there once (afm_chain.c, put_period).
     * out_at: where the last completed period went (NULL: out; no pointer into h itself, so
     * that h can be copied). */
    afm_harm_result *out_to;
    const afm_harm_result *out_at;
    /* e^{-ik m dphi} for the tracker's dphi, m = 0..AFM_HARM_TAB: entry m at m * 2 nl */
    double tab[(AFM_HARM_TAB + 1) * 2 * AFM_HARM_LANES];
} afm_harm;

/* ks[0..nk): harmonic numbers 1..AFM_HARM_MAX_K, nk 1..AFM_MAX_HARMONICS. 0, or -1 with err
 * (h untouched). */
#define AFM_HARM_MAX_K 1000
int afm_harm_init(afm_harm *h, const int *ks, int nk, char *err, size_t errlen);

/* Forget the partial period and the sample history (keeps the harmonic list); e.g. after a
 * discontinuity of the signal or a simulator reset. */
void afm_harm_reset(afm_harm *h);

/* One sample. Returns 1 when it completed a period (h->out holds it), 0 otherwise, -1 if
 * x, f or theta is not finite, or theta did not increase by less than pi since the last
 * sample (nothing changed then). */
int afm_harm_push(afm_harm *h, double x, double f, double theta_rad);

/* Samples x[i], f[i], theta[i], i = 0..n-1, as n calls of afm_harm_push, stopping after
 * the sample that completes a period. Returns the samples consumed (<= n); *done is 1 if
 * the last of them completed a period (h->out), else 0; rejected samples (-1 from
 * afm_harm_push) are added to *rejects. Same results as afm_harm_push, bit for bit
 * (afm_harm_push is this with n = 1): runs on the tracker's prediction are checked 8
 * samples at a time and summed with the sums in registers (4 harmonics per afm_v4). */
int afm_harm_push_n(afm_harm *h, const double *x, const double *f, const double *theta_rad, int n,
                    int *done, long long *rejects);

/* Tone 0's rate changes to dphi (rad per sample) after the last sample, phase continuously,
 * and theta_rad is that sample's phase in the frame of the samples to come
 * (afm_track_rebase): the open chunk goes into the period sums, the base phasor moves onto
 * the last sample and the table follows the new dphi (one sincos and AFM_HARM_TAB complex
 * products per 4 harmonics, by rotation); the period, its sums and the phasors continue, the
 * next samples on the fast path. false (nothing changed) when the period clock is not locked
 * or the phase does not continue (the samples then take the slow path, as a jump). */
bool afm_harm_rebase(afm_harm *h, double theta_rad, double dphi);

/* deferred: completed periods carry their sums (out.raw) only, and out.h[] is left as it
 * was until the caller asks for it with afm_harm_polar (a chain that publishes one period in
 * many skips the arctangents of the others). Off after init. */
void afm_harm_set_deferred(afm_harm *h, bool deferred);

/* r->h[0 .. n_harmonics) from r->raw, for a record h made (its harmonic list): the values
 * afm_harm_push leaves in h->out when not deferred, bit for bit. */
void afm_harm_polar(const afm_harm *h, afm_harm_result *r);

/* e^{-i phi} of the last sample as the estimator carries it (harmonic 1's phasor, phi =
 * theta mod 2 pi): what the phase-tracking test compares with the supplied theta. */
void afm_harm_phasor1(const afm_harm *h, double *re, double *im);

/* Default list when cfg.sim.n_harmonics == 0: 1, 2, 3 and the integers nearest f2/fe and
 * f3/fe (modes 2 and 3 of m, when m has them), de-duplicated, ascending, into ks (room
 * for 5). Returns the count (0 if fe_hz is not > 0). */
int afm_harm_default_list(const afm_modal *m, double fe_hz, int *ks);

#endif
