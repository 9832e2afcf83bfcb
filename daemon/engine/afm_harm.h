/* SPDX-License-Identifier: MIT */
/* afm_harm.h -- streaming harmonics of the deflection and of the tip-sample force, one
 * result per drive period (the real-time counterpart of afm_orbit_analyse's harmonics).
 *
 * Layer "estimators". Fed sample by sample with the deflection x (m; the tip displacement
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
 * Nothing allocates; the caller owns the struct. Cost per sample: one complex rotation and
 * four multiply-adds per harmonic (vectorised 4 harmonics at a time). e^{-ik theta} is
 * carried by per-harmonic phasors rotated by e^{-ik dphi} (afm_phase_track in
 * afm_est_internal.h: within a few ulps of theta of the supplied phase, else the sample is
 * computed exactly). At a period boundary on the tracker's prediction they keep rotating
 * (the theta they stand for is carried along and must stay within the tracker's tol of the
 * supplied one); after a jump or drift of theta, a tolerance miss and every 4096 samples
 * they are recomputed exactly from theta mod 2 pi (one sincos and O(log k) complex
 * products per harmonic). */
#ifndef AFM_HARM_H
#define AFM_HARM_H

#include "afm_est_internal.h"
#include "afm_model.h"
#include "afm_orbit.h"

typedef struct {
    long period;    /* sequence number: 0 for the first whole period since init/reset */
    double samples; /* its length in sample intervals (fractional) */
    int n_harmonics;
    afm_orbit_harmonic h[AFM_MAX_HARMONICS]; /* in the order they were configured */
} afm_harm_result;

/* Harmonic lanes: harmonic 1 then the configured ones, padded to a multiple of 4 (pads have
 * k = 0: e^0 = 1, never reported). */
#define AFM_HARM_LANES ((AFM_MAX_HARMONICS + 1 + 3) / 4 * 4)

typedef struct {
    int nk;                 /* configured harmonics */
    int nl;                 /* lanes in use: nk + 1 rounded up to 4 */
    int ks[AFM_HARM_LANES]; /* [0] = 1 (for phi_1), then the configured ones */
    afm_phase_track trk;
    bool active; /* inside a period that started at a boundary */
    double x_prev, f_prev;
    double er[AFM_HARM_LANES], ei[AFM_HARM_LANES]; /* e^{-ik phi} of the last sample */
    double rr[AFM_HARM_LANES], ri[AFM_HARM_LANES]; /* e^{-ik dphi}: one step */
    double imp_ref; /* theta the phasors stand for at the tracker's th_ref */
    double n_sync;  /* samples since the phasors were computed exactly */
    /* running sums of x e^{-ik phi}, f e^{-ik phi}: weight 1 per sample, the ends corrected
     * to the trapezoid with fractional ends at the boundaries */
    double xr[AFM_HARM_LANES], xi[AFM_HARM_LANES];
    double fr[AFM_HARM_LANES], fi[AFM_HARM_LANES];
    double wsum;         /* sample intervals accumulated */
    long periods;        /* completed periods since init/reset */
    afm_harm_result out; /* the last completed period (valid if periods > 0) */
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
 * afm_harm_push) are added to *rejects. Same results as afm_harm_push, bit for bit: runs
 * of fast-path samples keep the phasors and sums in registers (AVX2, 4 harmonics per
 * vector). */
int afm_harm_push_n(afm_harm *h, const double *x, const double *f, const double *theta_rad, int n,
                    int *done, long long *rejects);

/* Default list when cfg.sim.n_harmonics == 0: 1, 2, 3 and the integers nearest f2/fe and
 * f3/fe (modes 2 and 3 of m, when m has them), de-duplicated, ascending, into ks (room
 * for 5). Returns the count (0 if fe_hz is not > 0). */
int afm_harm_default_list(const afm_modal *m, double fe_hz, int *ks);

#endif
