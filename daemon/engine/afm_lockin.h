/* SPDX-License-Identifier: MIT */
/* afm_lockin.h -- lock-in amplifier at tone 0's frequency: what an AM-AFM controller sees.
 *
 * Layer "estimators". The reference is the exact drive phase theta of tone 0 (dither
 * x_dit = A sin theta), passed with every sample: afm_drive_phase(afm_sim_drive(s), 0, t).
 * The input is whatever deflection signal the caller has (the OBD signal in the daemon,
 * the tip displacement in the CLI). Demodulation: X = LPF(2 u sin theta),
 * Y = LPF(2 u cos theta), LPF = `order` cascaded identical first-order low-pass stages of
 * time constant tau, each discretised exactly for an input held over the step:
 * y += alpha (in - y), alpha = 1 - exp(-dt / tau). For u = R sin(theta - lag):
 * X -> R cos(lag), Y -> -R sin(lag).
 *
 * Outputs: amplitude R (m) and the phase LAG of the deflection behind the drive in
 * degrees, (-180, 180], as commercial AM-AFM reports it: a free cantilever driven at its
 * resonance reads 90, below resonance less, above more; the repulsive regime reads below
 * 90. The 2 fe ripple left by the filter is about R / (2 w tau)^order (order 1 with tau
 * = 10 periods: 8e-3 R; order 4: 4e-9 R).
 *
 * Nothing allocates; push is O(order) per sample with no transcendental function: sin and
 * cos of theta come from a phasor rotated by e^{i dphi} per sample while theta follows
 * th_ref + n dphi to a few ulps (afm_phase_track in afm_est_internal.h), and are computed
 * exactly from theta otherwise (a jump or drift of theta, every 4096 samples). */
#ifndef AFM_LOCKIN_H
#define AFM_LOCKIN_H

#include "afm_config.h"
#include "afm_est_internal.h"

#define AFM_LOCKIN_MAX_ORDER 8

typedef struct {
    int order;
    double tau_s, dt_s, alpha;
    double xy[AFM_LOCKIN_MAX_ORDER][2]; /* stage outputs: [i][0] in-phase, [i][1] quadrature */
    long n;                             /* samples since reset */
    afm_phase_track trk;
    double c, s;   /* cos, sin theta of the last sample */
    double rc, rs; /* cos, sin dphi: one step */
} afm_lockin;

/* tau > 0, order 1..AFM_LOCKIN_MAX_ORDER, dt_s > 0 (the sample interval). Filter state
 * starts at 0. 0, or -1 with err (l untouched). */
int afm_lockin_init(afm_lockin *l, const afm_cfg_lockin *cfg, double dt_s, char *err,
                    size_t errlen);

/* Zero the filter state (keeps tau, order, dt). */
void afm_lockin_reset(afm_lockin *l);

/* One sample of the deflection u (m) at drive phase theta. 0, or -1 (nothing changed) if
 * either is not finite. */
int afm_lockin_push(afm_lockin *l, double u_m, double theta_rad);

/* n samples u[i], theta[i] as n calls of afm_lockin_push (same results, bit for bit; the
 * runs of fast-path samples keep the filter state in registers). Returns the count of
 * rejected samples. */
int afm_lockin_push_n(afm_lockin *l, const double *u_m, const double *theta_rad, int n);

/* In-phase X (with sin theta) and quadrature Y (with cos theta), m. */
double afm_lockin_x(const afm_lockin *l);
double afm_lockin_y(const afm_lockin *l);
/* R = hypot(X, Y) (m) and the lag atan2(-Y, X) in degrees. */
double afm_lockin_amplitude(const afm_lockin *l);
double afm_lockin_phase_deg(const afm_lockin *l);

#endif
