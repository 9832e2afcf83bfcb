/* SPDX-License-Identifier: MIT */
/* afm_rt_coef.h -- private to the rt backend: the exact step coefficients it precomputes.
 *
 * For one mode  q'' + 2 xi w q' + w^2 q = tip F(t) - base_k u(t) - base_m u''(t)  and one
 * step of length tau, with F linear over the step (F0 at the start, F1 at the end) and u a
 * sum of tones A_j sin(theta_j), the exact solution is
 *
 *   [q; q'](tau) = Phi [q; q'](0) + G0 F0 + G1 F1 + sum_j Im(D_j e^{i theta_j(0)}),
 *
 * G0 = int_0^tau Phi(tau - s) [0; tip] (1 - s/tau) ds, G1 = same with s/tau (both from one
 * exponential of an augmented 4x4 matrix, Van Loan, so xi >= 1 needs no special case), and
 * D_j = P(tau) - Phi P(0) with P(s) the steady-state response [c; i wd c] e^{i wd s} to tone
 * j. Build time (and drive changes) only; afm_rt.c reads the tables on the real-time path. */
#ifndef AFM_RT_COEF_H
#define AFM_RT_COEF_H

#include "afm_config.h"

/* All coefficients for one step length tau and n modes, stored with a stride np >= n
 * (zeros past n). c and d point into a block the owner allocates: c has 12 np doubles
 * (p11, p12, p21, p22, g0q, g0v, g1q, g1v, then tip_i times p11, p12, p21, p22: the rows
 * that give x and x' directly; np each), d has 4 np per tone (dq_re, dq_im, dv_re, dv_im;
 * np each) for AFM_MAX_TONES tones. */
#define AFM_RT_COEF_ROWS 12
typedef struct {
    double tau_s;
    double gx, gv;   /* sum_i tip_i G1_i: d(x, v)(tau) / dF1 */
    double gx0, gv0; /* sum_i tip_i G0_i: d(x, v)(tau) / dF0 */
    double rot_re[AFM_MAX_TONES], rot_im[AFM_MAX_TONES]; /* e^{i wd_j tau} */
    double dx_re[AFM_MAX_TONES], dx_im[AFM_MAX_TONES]; /* sum_i tip_i Dq_i */
    double dv_re[AFM_MAX_TONES], dv_im[AFM_MAX_TONES]; /* sum_i tip_i Dv_i */
    double *c;
    double *d;
} afm_rt_prop;

/* Per-mode part of p (Phi, G0, G1, gx, gv) for n modes w (rad/s > 0), xi (>= 0), tip;
 * stride np >= n. */
void afm_rt_coef_modes(afm_rt_prop *p, int n, int np, const double *w, const double *xi,
                       const double *tip, double tau_s);

/* Drive part of p for tones wd[j] (rad/s), j < ntones, with the steady-state modal
 * amplitudes c[j][i] (re, im; zero past n), tip (np, zero past n). Needs afm_rt_coef_modes first (uses Phi). */
void afm_rt_coef_drive(afm_rt_prop *p, int np, const double *tip, int ntones, const double *wd,
                       const double (*c_re)[AFM_MAX_MODES], const double (*c_im)[AFM_MAX_MODES]);

/* Steady-state response of one mode to the base tone A sin(theta), theta' = wd:
 * q_p = Im(c e^{i theta}); returns c as (re, im). The modal force amplitude is
 * (-base_k + wd^2 base_m) A (the base acceleration is -wd^2 A sin(theta)). */
void afm_rt_coef_particular(double w, double xi, double base_k, double base_m, double amp_m,
                            double wd, double *c_re, double *c_im);

/* exp(A) of an n x n row-major matrix (n <= 8), scaling and squaring with a Taylor series
 * of the scaled matrix; relative accuracy about 1e-15 for the well-scaled, dissipative
 * matrices used here. */
void afm_rt_coef_expm(int n, const double *a, double *e);

#endif
