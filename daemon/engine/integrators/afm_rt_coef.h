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
 * j. The rt backend integrates the homogeneous part qh = q - sum_j Im(c_j e^{i theta_j})
 * instead, for which the drive terms vanish (qh(tau) = Phi qh(0) + G0 F0 + G1 F1): only the
 * tip sums of the particular response are tabulated. Build time (and drive changes) only;
 * afm_rt.c reads the tables on the real-time path. */
#ifndef AFM_RT_COEF_H
#define AFM_RT_COEF_H

#include "config/afm_config.h"
#include "forces/afm_force.h"

#include <math.h>

/* All coefficients for one step length tau and n modes, stored with a stride np >= n
 * (zeros past n). c points into a block the owner allocates: AFM_RT_COEF_ROWS np doubles
 * (p11, p12, p21, p22, g0q, g0v, g1q, g1v, then tip_i times p11, p12, p21, p22: the rows
 * that give x and x' directly; then the accurate scheme's Hermite rows gcq, gcv, gd0q, gd0v,
 * gd1q, gd1v (afm_rt_coef_hermite; zero until it is called), then gd0q + gd1q, gd0v + gd1v (the
 * response to D0 while D1 is held at D0: the accurate scheme's solve, summed once here), then
 * g0q + gcq, g0v + gcv and g1q - gcq, g1v - gcv (the responses to F0 and F1 with the Hermite
 * correction folded in: the accurate scheme's free step, issue 29); np each).
 *
 * The accurate scheme takes the force over a step as the cubic Hermite interpolant of F0,
 * F1 and D0 = tau F'(0), D1 = tau F'(tau): in sigma = s / tau,
 *   F(sigma) = F0 (1 - sigma) + F1 sigma + (F0 - F1) c(sigma) + D0 h10(sigma) + D1 h11(sigma),
 *   c = sigma - 3 sigma^2 + 2 sigma^3, h10 = sigma - 2 sigma^2 + sigma^3, h11 = sigma^3 - sigma^2,
 * so its response is the linear one (G0, G1) plus Gc (F0 - F1) + Gd0 D0 + Gd1 D1. */
#define AFM_RT_COEF_ROWS 24
#define AFM_RT_ROW_GC 12   /* first Hermite row: gcq; gcv, gd0q, gd0v, gd1q, gd1v follow */
#define AFM_RT_ROW_GD01 18 /* gd0q + gd1q; gd0v + gd1v follows */
#define AFM_RT_ROW_K0 20   /* g0q + gcq; g0v + gcv follows */
#define AFM_RT_ROW_K1 22   /* g1q - gcq; g1v - gcv follows */
typedef struct {
    double tau_s;
    double gx, gv;                                       /* sum_i tip_i G1_i: d(x, v)(tau) / dF1 */
    double gx0, gv0;                                     /* sum_i tip_i G0_i: d(x, v)(tau) / dF0 */
    double rot_re[AFM_MAX_TONES], rot_im[AFM_MAX_TONES]; /* e^{i wd_j tau} */
    /* Particular tip response at the step's end per unit phasor at its start:
     * x_p(tau) = Im(dx e^{i theta(0)}), dx = cx e^{i wd tau}, cx = sum_i tip_i c_i; dv likewise
     * with i wd cx. */
    double dx_re[AFM_MAX_TONES], dx_im[AFM_MAX_TONES];
    double dv_re[AFM_MAX_TONES], dv_im[AFM_MAX_TONES];
    double hx, hv; /* d(x*, v*) / dF1 of a full step that follows this one (coef_chain) */
    /* sum_i tip_i of the Hermite rows: d(x, v)(tau) / d(F0 - F1), / dD0, / dD1 */
    double gcx, gcv, gd0x, gd0v, gd1x, gd1v;
    /* the same sums as the accurate scheme's solve takes them (D1 held at D0, F1 with the
     * Hermite correction): gx0 + gcx, gd0x + gd1x, gv0 + gcv, gd0v + gd1v, gx - gcx, gv - gcv
     * (afm_rt_coef_hermite; each rounded once, as the sum at run time was) */
    double hx0, hd0x, hv0, hd0v, hx1, hv1;
    /* the tip acceleration per unit end force F1 through the K1 rows, sum tip^2 included
     * (1/kg), and per unit end slope D1 through the Gd1 rows (1/kg): the accurate scheme's
     * piece writes its modal state once (afm_rt_acc.h; set by afm_rt.c, not here) */
    double acc_k1, acc_gd1;
    double *c;
} afm_rt_prop;

/* Per-mode part of p (Phi, G0, G1, gx, gv) for n modes w (rad/s > 0), xi (>= 0), tip;
 * stride np >= n. */
void afm_rt_coef_modes(afm_rt_prop *p, int n, int np, const double *w, const double *xi,
                       const double *tip, double tau_s);

/* The Hermite rows of p (AFM_RT_ROW_GC .. + 5) and their tip sums, for the same n, np, w,
 * xi, tip as afm_rt_coef_modes (called first: it zeroes them). One 6x6 exponential per mode
 * gives the responses to sigma^k, k = 0..3. Build time only. */
void afm_rt_coef_hermite(afm_rt_prop *p, int n, int np, const double *w, const double *xi,
                         const double *tip);

/* hx, hv of p for a full step pf after it: x*, v* of pf (the tip rows of pf applied to the
 * state after p, plus pf's G0 term) depend on p's end force F1 through
 * sum_i (tip p11f_i G1q_i + tip p12f_i G1v_i) + gx0f, and likewise for v. Needs
 * afm_rt_coef_modes on both. */
void afm_rt_coef_chain(afm_rt_prop *p, const afm_rt_prop *pf, int np);

/* Drive part (rot, dx, dv) of every cell of a table, prop[k].tau_s = (k + 1) prop[0].tau_s,
 * k < ncell (afm_rt_impl.h's grid), for tones wd[j] (rad/s), j < ntones, whose steady-state
 * tip response is x_p = Im(cx_j e^{i theta_j}); the rows of tones ntones..nheld - 1 (those
 * the cells held before, past ntones) zeroed, those past nheld left zero. Needs tau_s
 * (afm_rt_coef_modes) first. Runs at every drive change. The rotations e^{i wd tau_k} by sincos
 * only at every AFM_RT_DRIVE_ANCHOR-th cell and at the last (the full step), the cells between as
 * the anchor before them times the powers of the first cell's rotation: ncell / AFM_RT_DRIVE_ANCHOR
 * + AFM_RT_DRIVE_ANCHOR sincos a tone instead of ncell (a tone change at every FM update was ~256
 * sincos), within ~2 AFM_RT_DRIVE_ANCHOR ulp of sincos. */
#define AFM_RT_DRIVE_ANCHOR 8
void afm_rt_coef_drive_cells(afm_rt_prop *prop, int ncell, int ntones, int nheld, const double *wd,
                             const double *cx_re, const double *cx_im);

/* Thermal (Langevin) increment over p's step (tau_s) for n modes w, xi at kB T = kt_j (J),
 * stride np (zeros past n and for modes without damping). With mass-normalised modes and
 * <eta(t) eta(t')> = 4 xi w kB T delta(t - t'), the exact step adds to (q, q') a Gaussian of
 * covariance Sigma(tau) = int_0^tau Phi(s) diag(0, 4 xi w kB T) Phi(s)^T ds = P - Phi P Phi^T
 * with P = diag(kB T / w^2, kB T) the stationary covariance; the latter form only where the
 * mode decays strongly over the step (2 xi w tau > 0.5), Van Loan's exponential elsewhere
 * (no cancellation). Writes the Cholesky factor: (dq, dv) = (l11 n1, l21 n1 + l22 n2) with
 * n1, n2 standard normal. Needs afm_rt_coef_modes first (uses Phi). */
void afm_rt_coef_thermal(const afm_rt_prop *p, int n, int np, const double *w, const double *xi,
                         double kt_j, double *l11, double *l21, double *l22);

/* Brownian bridge of the thermal increment. An interval of length L whose increment xi
 * (per mode, on (q, q')) is already drawn is cut into a first part of length tau1 and the
 * rest: xi = Phi2 xi1 + xi2 with xi1 ~ N(0, Sigma1), xi2 independent. Writes the gain
 * K = Sigma1 Phi2^T Sigma(L)^-1 (k11, k12, k21, k22 at stride np), with which xi1 = xi1' +
 * K (xi - Phi2 xi1' - xi2') for fresh draws xi1', xi2' is distributed as xi1 given xi
 * (Matheron's rule). l1, ll: the Cholesky factors of Sigma1 and Sigma(L) as
 * afm_rt_coef_thermal writes them (l11, l21, l22 at stride np); phi2: Phi of the rest (the
 * first 4 np entries of its afm_rt_prop.c). Computed in (q, q' tau1), in long double; zero
 * for a mode without noise. */
void afm_rt_coef_bridge(int n, int np, double tau1_s, const double *l1, const double *ll,
                        const double *phi2, double *k);

/* exp(A) of an n x n row-major matrix (n <= 8), scaling and squaring with a Taylor series
 * of the scaled matrix; relative accuracy about 1e-15 for the well-scaled, dissipative
 * matrices used here. */
void afm_rt_coef_expm(int n, const double *a, double *e);

/* Starr's squeeze-film coefficient c(h) (afm_force_inline.h) near the rest plate gap
 * h0 = Z + kappa l cos(alpha), where the tip's excursion keeps it (|x| << h0): a quartic in
 * s = (h - h0) / hw on hw = AFM_RT_STARR_WINDOW h0, interpolated at the Chebyshev nodes of
 * the exact c. Relative error about 15 (hw / h0)^5 / 2^4 < 1e-8 on the window. */
#define AFM_RT_STARR_WINDOW 0.02
/* A Z change moves the rest gap; the interpolant stays exact to the same bound on its own
 * window, so a Z-only change keeps it while the new rest gap is within KEEP hw of h0 (the tip's
 * gap then stays inside for excursions up to (1 - KEEP) hw, 93 nm on a 9.3 um gap) and
 * rebuilds it otherwise (afm_rt.c, rt_changed_z). */
#define AFM_RT_STARR_KEEP 0.5
typedef struct {
    bool on;
    double h0, hw, ihw; /* m, m, 1/m */
    double a[5];        /* c = sum_k a_k s^k (N s/m) */
} afm_rt_starr;

/* Build st for separation z_m; st->on = false when p has no Starr film or the window would
 * reach the a0 floor (then the exact formula is the only one). Not real-time (pow, cos). */
void afm_rt_starr_build(afm_rt_starr *st, const afm_force_params *p, double z_m);

/* c(h) (N s/m) and dc/dh into *dcdh from st, or -1 when st is off or h is outside the
 * window (the caller then uses the exact formula). */
static inline double afm_rt_starr_eval(const afm_rt_starr *st, double h, double *dcdh) {
    double sg = (h - st->h0) * st->ihw;
    if (!st->on || !(fabs(sg) <= 1.0)) return -1.0;
    const double *a = st->a;
    *dcdh = fma(fma(fma(4.0 * a[4], sg, 3.0 * a[3]), sg, 2.0 * a[2]), sg, a[1]) * st->ihw;
    return fma(fma(fma(fma(a[4], sg, a[3]), sg, a[2]), sg, a[1]), sg, a[0]);
}

#endif
