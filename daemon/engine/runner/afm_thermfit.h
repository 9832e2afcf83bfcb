/* SPDX-License-Identifier: MIT */
/* afm_thermfit.h -- thermal-tune fit: eigenfrequency f_n, quality factor Q_n, modal
 * stiffness k_n and detection floor of one mode from a displacement PSD (thesis eq. 5.1).
 *
 * Layer runner/ (5): afm_thermfit_tune runs a twin; the fit itself is pure, no allocation. Model,
 * one-sided, m^2/Hz:
 *
 *   M(f) = (2 kB T / (pi k_n f_n Q_n)) / ((f^2/f_n^2 - 1)^2 + (f/(f_n Q_n))^2) + F,
 *
 * F = d_ds,n^2 the white floor (thesis eq. 5.1 is the square root of this). The integral
 * of the resonance term over f in (0, inf) is kB T / k_n (equipartition), so k_n is the
 * stiffness of the mode as seen where the displacement is measured.
 *
 * Fit: Whittle maximum likelihood. A Welch PSD bin is the true PSD times a chi-square
 * variable of many degrees of freedom divided by its mean, so the likelihood of the bins
 * is maximised by minimising sum_i (log M_i + P_i / M_i); its score equations are those
 * of least squares with weights 1 / M_i^2. The fit solves them by Levenberg-Marquardt
 * with the weights taken at the last accepted parameters (iteratively reweighted; at
 * convergence this is the Whittle estimate). Fitting log P instead would bias k_n by the
 * mean of log chi-square (about 1/K after K segments); unweighted least squares would let
 * the peak's few bins dominate. Four parameters (f, Q, k, F) with an analytic Jacobian: a
 * 4x4 Cholesky solve per iteration. SUNDIALS KINSOL solves F(u) = 0, not least squares:
 * it would need the normal equations written out by hand and gives no Marquardt damping,
 * so a small dedicated LM is shorter and has no allocation.
 *
 * Start: the highest (3-bin smoothed) bin in the band, the half-power width for Q, the
 * peak height for k, half the band's lowest level for F. Fit window: f_n +- w f_n / Q_n
 * (w linewidths, default 25) inside the band; fitted once on the start's window and again
 * on the fitted one. The caller chooses the band so that it holds one resonance.
 *
 * Sampled without an anti-alias filter (the twin's x and OBD reading are), a record has the
 * spectrum of the continuous one folded at the sample rate fs: given fs, M's resonance term
 * is summed over its images |j fs +- f| (afm_thermfit_mode). Fitting the bare Lorentzian to
 * a broad mode near Nyquist is biased: NCHV mode 3 (0.41 fs, Q 5) came out Q -11 %, k -13 %,
 * f +1.9 %. What one resonance plus a constant floor still cannot absorb (other modes' tails
 * and images in the band) is left: there f +0.4 %, Q +0.3 %, k +0.04 % (docs/numerics.md,
 * "Thermal fit near Nyquist"). */
#ifndef AFM_THERMFIT_H
#define AFM_THERMFIT_H

#include "config/afm_config.h"

#include <stdbool.h>
#include <stddef.h>

#define AFM_KB_J_K 1.380649e-23 /* Boltzmann constant (exact, SI 2019) */

typedef struct {
    double f_hz;        /* f_n */
    double q;           /* Q_n */
    double k_n_m;       /* k_n */
    double floor_m2_hz; /* F = d_ds,n^2; may come out slightly negative (noise) */
    /* Approximate 1-sigma statistical errors from the curvature of the likelihood, scaled
     * by the observed scatter of P/M and by the bin correlation of the Hann window (a
     * smooth function of the bins has 1.94 times the variance it would have with
     * independent bins). */
    double se_f_hz, se_q, se_k_n_m, se_floor_m2_hz;
    double fit_lo_hz, fit_hi_hz; /* window used */
    long n_bins;                 /* bins in it */
    int iterations;              /* LM iterations of both passes */
    double rel_scatter;          /* rms of P/M - 1 over the window: ~ 1/sqrt(0.947 K) if it fits */
    double linewidth_bins;       /* f_n / Q_n / df: below ~30 the Hann window's smoothing biases
                                    Q_n low by about 4/3 / linewidth_bins^2 */
} afm_thermfit;

/* The model M(f) in m^2/Hz for the parameters of r (f_hz, q, k_n_m, floor_m2_hz), folded at
 * sample_rate_hz (0: not folded; see afm_thermfit_mode). */
double afm_thermfit_model(const afm_thermfit *r, double temperature_k, double sample_rate_hz,
                          double f_hz);

/* Fit one mode. psd: n_bins one-sided values (m^2/Hz) at f = i df_hz (bin 0 = DC, never
 * used). sample_rate_hz > 0: the PSD is of samples taken at that rate with no anti-alias
 * filter, so the resonance term is folded: R(f) + sum_{j=1..16} (R(j fs - f) + R(j fs + f))
 * (the spectrum of the sampled process; R decays as f^-4, so the sum converges fast). It
 * matters for a broad mode near Nyquist: the images of NCHV mode 3 (5.78 MHz, Q 5 at
 * 14.06 MHz) add 3 % to its level at the peak and 100 % at Nyquist (docs/numerics.md,
 * "Thermal fit near Nyquist"). 0: a continuous-time spectrum, no folding.
 * band_lo_hz < band_hi_hz: where to look for the peak; window_linewidths <= 0 gives 25. Returns 0
 * with out filled, or -1 with err (bad input, too few bins, no peak, no convergence); out is
 * untouched on failure. */
int afm_thermfit_mode(const double *psd, long n_bins, double df_hz, double sample_rate_hz,
                      double temperature_k, double band_lo_hz, double band_hi_hz,
                      double window_linewidths, afm_thermfit *out, char *err, size_t errlen);

/* ---- The whole thermal tune on a config: what `afmtwin thermal` and the tests run ----
 *
 * The tune is taken far from the surface with the drive off, as on the instrument
 * (afm_thermfit_tune_config): every tone's amplitude 0, the separation 1 mm (the most
 * afm_sim_set_separation allows) and every tip-sample force switched off (vdW/contact,
 * viscoelastic, squeeze film, capillary, electrostatic), thermal noise on at the config's
 * temperature. Switching the forces off, not only moving away, matters for the squeeze
 * film: its damping lowers the effective Q (thesis section 5.3) and Starr's model still
 * gives a small nonzero coefficient at 1 mm; the intrinsic Q_n = 1 / (2 xi_n) is what the
 * tune should see. The modes start in thermal equilibrium (for mass-normalised modes
 * <q_i^2> = kB T / w_i^2, <q_i'^2> = kB T, drawn from the thermal seed), so no settling
 * time is lost, and the rt integrator adds the exact Gaussian increment of the Langevin
 * force per step (afm_sim_set_thermal), so the sampled record has the oscillators' exact
 * statistics at any sample rate. Each mode below the Nyquist frequency is looked for
 * between the geometric means of its model neighbours' frequencies. */

typedef struct {
    int n; /* mode number, 1 = fundamental */
    afm_thermfit fit;
    double model_f_hz;  /* w_n / 2 pi */
    double model_q;     /* 1 / (2 xi_n) */
    double model_k_n_m; /* w_n^2 / tip_n^2, divided by gain^2 for the OBD signal */
    double gain;        /* reading per unit mode-n tip displacement: 1 for x, g_n (afm_obd) */
} afm_thermfit_mode_result;

typedef struct {
    long n_samples, seg_len, segments;
    double df_hz;
    double cpu_s; /* CPU time of the simulation and PSD */
    int n_modes;  /* fitted modes in modes[] */
    afm_thermfit_mode_result modes[AFM_MAX_MODES];
    char skipped[AFM_ERR_LEN]; /* why modes below Nyquist were not fitted ("" if none) */
} afm_thermfit_tune_result;

/* Apply the tune's settings (above) to a config copy. */
void afm_thermfit_tune_config(afm_config *cfg);

/* Run the tune on a copy of cfg (tuned by afm_thermfit_tune_config): seconds of model time
 * at cfg's sample rate, Welch segments of seg_len samples (even, <= the run), the tip
 * displacement (obd false) or the OBD reading of the cfg's obd group (obd true); fit at
 * most max_modes modes. psd_out (may be NULL) receives a malloc'd copy of the PSD
 * (seg_len / 2 + 1 bins, caller frees). 0 with out filled (n_modes may be 0: see
 * skipped), or -1 with err (bad input, simulation failure, no memory). */
int afm_thermfit_tune(const afm_config *cfg, double seconds, long seg_len, bool obd, int max_modes,
                      afm_thermfit_tune_result *out, double **psd_out, char *err, size_t errlen);

#endif
