/* SPDX-License-Identifier: MIT */
/* test_thermal.c -- thermal tune: the Welch PSD (afm_psd), the eq. 5.1 fit (afm_thermfit)
 * on an exactly simulated thermally driven oscillator, and the whole chain on nchv.conf.
 *
 *  - PSD: white noise of variance s^2 reads 2 s^2 / fs (one-sided); a sine of amplitude A
 *    integrates to A^2 / 2 (Parseval through the Hann window); bad input is refused and
 *    changes nothing.
 *  - Fit on synthetic data: a damped oscillator x'' + 2 xi w x' + w^2 x = thermal force,
 *    sampled exactly (the state (x, v) is a Gauss-Markov chain: x_{j+1} = Phi x_j + w_j,
 *    Cov w = S - Phi S Phi', S = diag(kB T / k, w^2 kB T / k) the equipartition
 *    covariance), so the sampled record has exactly the oscillator's statistics. The fit
 *    must find f, Q, k within 1 % (clean) and also the floor when white detection noise is
 *    added. See synthetic() for why the record length makes 1 % a safe bound.
 *  - End to end: afm_thermfit_tune (what `afmtwin thermal` runs: rt integrator with its
 *    thermal force, drive off, forces off) on nchv.conf, modes 1 and 2 within 2 % of the
 *    model's f_n, Q_n, k_n, mode 3 (Q 5, 0.41 of the sample rate) within 1.5 %; see
 *    end_to_end() for the run lengths.
 *  - Near Nyquist: a broad mode at 0.41 fs, sampled exactly; the fit folded at fs finds it
 *    within 1 %, the unfolded one is > 5 % low in Q and k. */
#include "config/afm_config.h"
#include "estimators/afm_psd.h"
#include "forces/afm_rng.h"
#include "runner/afm_thermfit.h"
#include "check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double pi = 3.14159265358979323846;

/* ---- PSD ---- */

static void psd_units(void) {
    char err[256];
    const double fs = 1e6;
    const long nseg = 4096, nsamp = 1L << 21;
    afm_psd *p = afm_psd_create(nseg, fs, err, sizeof err);
    if (!check_true(p != NULL, "psd create")) return;
    double *x = malloc((size_t)nsamp * sizeof *x), *out = malloc((nseg / 2 + 1) * sizeof *out);
    afm_rng r;
    afm_rng_seed(&r, 7);
    const double sigma = 3e-9;
    for (long i = 0; i < nsamp; i++)
        x[i] = sigma * afm_rng_normal(&r);
    long got = afm_psd_push(p, x, nsamp);
    /* 2^21 samples in half-overlapped 4096-sample segments: 2 * 512 - 1 = 1023. */
    check_true(got == 1023 && afm_psd_segments(p) == 1023, "1023 segments from 2^21 samples");
    afm_psd_get(p, out);
    double mean = 0;
    for (long k = 10; k < nseg / 2 - 10; k++)
        mean += out[k];
    mean /= (double)(nseg / 2 - 20);
    /* ~2000 bins x 1023 segments: the mean level has a relative error ~ 1e-3. */
    check_rel(mean, 2 * sigma * sigma / fs, 5e-3, "white noise reads 2 s^2 / fs (m^2/Hz)");

    /* A bad block changes nothing. */
    double bad[3] = {1e-9, NAN, 1e-9}, before = out[100];
    check_true(afm_psd_push(p, bad, 3) == -1, "NaN sample refused");
    check_true(afm_psd_push(p, NULL, 5) == -1 && afm_psd_push(p, x, -1) == -1,
               "NULL/negative n refused");
    afm_psd_get(p, out);
    check_true(afm_psd_segments(p) == 1023 && out[100] == before, "refused blocks change nothing");

    /* Sine of amplitude A at a non-bin frequency: the PSD integrates to A^2 / 2. */
    afm_psd_reset(p);
    check_true(afm_psd_get(p, out) == -1, "no segment after reset: get refused");
    const double a = 2e-9, f = 123456.7;
    for (long i = 0; i < 8 * nseg; i++)
        x[i] = a * sin(2 * pi * f * (double)i / fs + 0.3);
    for (long i = 0; i < 8 * nseg; i += 1000) /* odd block sizes */
        afm_psd_push(p, x + i, i + 1000 <= 8 * nseg ? 1000 : 8 * nseg - i);
    afm_psd_get(p, out);
    double pw = 0;
    for (long k = 0; k < nseg / 2 + 1; k++)
        pw += out[k] * afm_psd_df_hz(p);
    /* Hann leakage outside the bins summed is nil (all bins are summed); the per-segment
     * mean removal takes away < (A / (pi f T_seg))^2 / ... ~ 1e-7 of the power. */
    check_rel(pw, a * a / 2, 1e-4, "sine integrates to A^2/2 (Parseval)");
    afm_psd_destroy(&p);
    check_true(p == NULL, "destroy clears the handle");
    check_true(afm_psd_create(4095, fs, err, sizeof err) == NULL, "odd segment refused");
    check_true(afm_psd_create(4096, -1, err, sizeof err) == NULL, "negative rate refused");
    printf("  (error text: %s)\n", err);
    free(x);
    free(out);
}

/* ---- exact thermally driven oscillator ---- */

typedef struct {
    double phi[2][2], l11, l21, l22, x, v;
} osc;

static void osc_init(osc *o, double f_hz, double q, double k_n_m, double t_k, double dt,
                     afm_rng *r) {
    double w = 2 * pi * f_hz, xi = 1 / (2 * q), wd = w * sqrt(1 - xi * xi);
    double e = exp(-xi * w * dt), c = cos(wd * dt), s = sin(wd * dt);
    o->phi[0][0] = e * (c + xi * w / wd * s);
    o->phi[0][1] = e * s / wd;
    o->phi[1][0] = -e * w * w * s / wd;
    o->phi[1][1] = e * (c - xi * w / wd * s);
    double sx = AFM_KB_J_K * t_k / k_n_m, sv = w * w * sx; /* variances */
    double(*p)[2] = o->phi;
    double q11 = sx - (p[0][0] * p[0][0] * sx + p[0][1] * p[0][1] * sv);
    double q21 = -(p[1][0] * p[0][0] * sx + p[1][1] * p[0][1] * sv);
    double q22 = sv - (p[1][0] * p[1][0] * sx + p[1][1] * p[1][1] * sv);
    o->l11 = sqrt(q11);
    o->l21 = q21 / o->l11;
    o->l22 = sqrt(q22 - o->l21 * o->l21);
    o->x = sqrt(sx) * afm_rng_normal(r); /* start in the stationary distribution */
    o->v = sqrt(sv) * afm_rng_normal(r);
}

static void osc_run(osc *o, afm_rng *r, double *out, long n, double noise_sigma) {
    for (long i = 0; i < n; i++) {
        double z1 = afm_rng_normal(r), z2 = afm_rng_normal(r);
        double x = o->phi[0][0] * o->x + o->phi[0][1] * o->v + o->l11 * z1;
        double v = o->phi[1][0] * o->x + o->phi[1][1] * o->v + o->l21 * z1 + o->l22 * z2;
        o->x = x;
        o->v = v;
        out[i] = x + (noise_sigma > 0 ? noise_sigma * afm_rng_normal(r) : 0);
    }
}

/* Fit accuracy on synthetic data. f = 100 kHz, Q = 50, k = 2 N/m, T = 295 K, fs = 1 MHz,
 * 2^25 samples (33.6 s), segments of 2^15 (32.8 ms, df = 30.5 Hz: the linewidth f/Q = 2 kHz
 * is 66 bins, so the Hann smoothing biases Q by ~ 4/3 / 66^2 = 3e-4). Statistical error:
 * the fitted area ~ the record's mean square of x, whose relative variance is 1 / (lambda
 * T_rec) for a narrow-band process with envelope decay rate lambda = pi f / Q = 6283 /s
 * (two quadratures, each an Ornstein-Uhlenbeck process): 1 / sqrt(6283 * 33.6) = 0.22 %
 * for k and of the same order for Q; so 1 % is more than 4 sigma. */
static void synthetic(double floor_frac) {
    const double f0 = 100e3, q0 = 50, k0 = 2.0, tk = 295, fs = 1e6;
    const long nseg = 1L << 15, nsamp = 1L << 25, block = 1L << 16;
    char err[256], what[160];
    afm_rng r;
    afm_rng_seed(&r, floor_frac > 0 ? 11 : 5);
    osc o;
    osc_init(&o, f0, q0, k0, tk, 1 / fs, &r);
    /* White detection floor F as a fraction of the peak PSD 2 kB T Q / (pi k f). */
    double peak = 2 * AFM_KB_J_K * tk * q0 / (pi * k0 * f0), fl = floor_frac * peak;
    double sigma_n = sqrt(fl * fs / 2);
    afm_psd *p = afm_psd_create(nseg, fs, err, sizeof err);
    double *x = malloc((size_t)block * sizeof *x), *psd = malloc((nseg / 2 + 1) * sizeof *psd);
    for (long i = 0; i < nsamp; i += block) {
        osc_run(&o, &r, x, block, sigma_n);
        afm_psd_push(p, x, block);
    }
    afm_psd_get(p, psd);
    afm_thermfit fit;
    int rc = afm_thermfit_mode(psd, afm_psd_n_bins(p), afm_psd_df_hz(p), fs, tk, 50e3, 200e3, 0,
                               &fit, err, sizeof err);
    snprintf(what, sizeof what, "synthetic fit converges (floor %g of peak)", floor_frac);
    if (check_true(rc == 0, what)) {
        printf("  f %.6g Hz (se %.2g)  Q %.5g (se %.2g)  k %.5g N/m (se %.2g)  floor %.4g "
               "m^2/Hz (se %.2g, true %.4g)  window %.0f..%.0f Hz, %ld bins, %d iterations, "
               "scatter %.4f (1/sqrt(0.947 K) = %.4f)\n",
               fit.f_hz, fit.se_f_hz, fit.q, fit.se_q, fit.k_n_m, fit.se_k_n_m, fit.floor_m2_hz,
               fit.se_floor_m2_hz, fl, fit.fit_lo_hz, fit.fit_hi_hz, fit.n_bins, fit.iterations,
               fit.rel_scatter, 1 / sqrt(0.947 * (double)afm_psd_segments(p)));
        check_rel(fit.f_hz, f0, 1e-2, "synthetic f within 1 %");
        check_rel(fit.q, q0, 1e-2, "synthetic Q within 1 %");
        check_rel(fit.k_n_m, k0, 1e-2, "synthetic k within 1 %");
        /* The standard errors are what the record length predicts (0.22 % for k). */
        check_true(fit.se_k_n_m / k0 < 4e-3 && fit.se_k_n_m / k0 > 1e-3, "se(k) ~ 0.2 %");
        if (floor_frac > 0)
            check_rel(fit.floor_m2_hz, fl, 3e-2, "synthetic floor within 3 %");
        else
            check_abs(fit.floor_m2_hz / peak, 0, 1e-5, "no floor: fitted floor ~ 0");
    }
    afm_psd_destroy(&p);
    free(x);
    free(psd);
}

/* A broad mode near Nyquist, sampled exactly with no anti-alias filter: f = 410 kHz = 0.41 fs,
 * Q = 5, k = 2 N/m, fs = 1 MHz (NCHV mode 3's 5.78 MHz, Q 5 at 14.06 MHz is 0.41 fs too).
 * Its images |j fs +- f| add 3 % (at f) to 100 % (at Nyquist) to the continuous-time
 * Lorentzian's level; the unfolded fit then gives Q and k 10 to 13 % low (below, and
 * docs/numerics.md "Thermal fit near Nyquist"). Folded, the fit must find them within 1-1.5 %.
 * Statistics: lambda = pi f / Q = 2.6e5 /s, 2^22 samples = 4.19 s: 1 / sqrt(lambda T) = 9.5e-4;
 * the fit reports se 0.16 % for k and 0.26 % for Q (f, Q, k and the floor are correlated over
 * so broad a peak), so 1 % for f and k and 1.5 % for Q are > 5 sigma; the unfolded fit's bias
 * (Q -12 %, k -13 %) is far outside them. */
static void synthetic_nyquist(void) {
    const double f0 = 410e3, q0 = 5, k0 = 2.0, tk = 295, fs = 1e6;
    const long nseg = 1L << 12, nsamp = 1L << 22, block = 1L << 16;
    char err[256];
    afm_rng r;
    afm_rng_seed(&r, 17);
    osc o;
    osc_init(&o, f0, q0, k0, tk, 1 / fs, &r);
    afm_psd *p = afm_psd_create(nseg, fs, err, sizeof err);
    double *x = malloc((size_t)block * sizeof *x), *psd = malloc((nseg / 2 + 1) * sizeof *psd);
    for (long i = 0; i < nsamp; i += block) {
        osc_run(&o, &r, x, block, 0);
        afm_psd_push(p, x, block);
    }
    afm_psd_get(p, psd);
    afm_thermfit fit, raw;
    int rc = afm_thermfit_mode(psd, afm_psd_n_bins(p), afm_psd_df_hz(p), fs, tk, 150e3, fs / 2, 0,
                               &fit, err, sizeof err);
    int rc0 = afm_thermfit_mode(psd, afm_psd_n_bins(p), afm_psd_df_hz(p), 0, tk, 150e3, fs / 2, 0,
                                &raw, err, sizeof err);
    if (check_true(rc == 0 && rc0 == 0, "near-Nyquist fits converge")) {
        printf("  folded: f %.6g Hz  Q %.5g (se %.2g)  k %.5g N/m (se %.2g)  window %.0f..%.0f Hz\n"
               "  unfolded: f %.6g Hz  Q %.5g  k %.5g N/m\n",
               fit.f_hz, fit.q, fit.se_q, fit.k_n_m, fit.se_k_n_m, fit.fit_lo_hz, fit.fit_hi_hz,
               raw.f_hz, raw.q, raw.k_n_m);
        check_rel(fit.f_hz, f0, 1e-2, "near Nyquist, folded: f within 1 %");
        check_rel(fit.q, q0, 1.5e-2, "near Nyquist, folded: Q within 1.5 %");
        check_rel(fit.k_n_m, k0, 1e-2, "near Nyquist, folded: k within 1 %");
        check_true(fit.se_k_n_m / k0 < 3e-3, "near Nyquist: se(k) < 0.3 %");
        check_true(raw.q < 0.95 * q0 && raw.k_n_m < 0.95 * k0,
                   "near Nyquist, unfolded (continuous Lorentzian): Q and k > 5 % low");
    }
    afm_psd_destroy(&p);
    free(x);
    free(psd);
}

static void fit_bad_input(void) {
    char err[256] = "";
    double psd[64];
    for (int i = 0; i < 64; i++)
        psd[i] = 1e-26;
    afm_thermfit fit = {.f_hz = -1};
    check_true(afm_thermfit_mode(psd, 64, 10, 0, 295, 100, 500, 0, &fit, err, sizeof err) == -1,
               "flat spectrum: no peak, refused");
    printf("  (error text: %s)\n", err);
    check_true(afm_thermfit_mode(psd, 64, 10, 0, -1, 100, 500, 0, &fit, err, sizeof err) == -1,
               "negative temperature refused");
    check_true(afm_thermfit_mode(psd, 64, 10, 0, 295, 500, 100, 0, &fit, err, sizeof err) == -1,
               "empty band refused");
    psd[20] = NAN;
    check_true(afm_thermfit_mode(psd, 64, 10, 0, 295, 100, 500, 0, &fit, err, sizeof err) == -1,
               "NaN bin refused");
    check_true(fit.f_hz == -1, "failed fits leave the result untouched");
}

/* One tune of nchv.conf at sample rate fs_hz for seconds, segments of seg_s; checks mode
 * `mode` (1-based) within tol of the model. */
static void tune_check(double fs_hz, double seconds, double seg_s, int mode, double tol) {
    static afm_config cfg;
    static afm_thermfit_tune_result res;
    char err[AFM_ERR_LEN], what[200];
    if (!check_true(afm_config_load("config/nchv.conf", &cfg, err, sizeof err) == 0,
                    "load config/nchv.conf"))
        return;
    cfg.sim.sample_rate_hz = fs_hz;
    for (int j = 0; j < cfg.drive.n_tones; j++) /* keep the (silent) tones below Nyquist */
        if (cfg.drive.tones[j].frequency_hz >= fs_hz / 2)
            cfg.drive.tones[j].frequency_hz = fs_hz / 4;
    long nseg = 2 * (long)floor(seg_s * fs_hz / 2 + 0.5);
    int rc = afm_thermfit_tune(&cfg, seconds, nseg, false, mode, &res, NULL, err, sizeof err);
    snprintf(what, sizeof what, "nchv tune at %g MHz, %g s: mode %d fitted", fs_hz / 1e6, seconds,
             mode);
    const afm_thermfit_mode_result *r = NULL;
    for (int i = 0; rc == 0 && i < res.n_modes; i++)
        if (res.modes[i].n == mode) r = &res.modes[i];
    if (!check_true(r != NULL, what)) {
        printf("  (%s%s)\n", rc ? err : "", res.skipped);
        return;
    }
    printf("  %ld samples, %.2f s CPU, %ld segments of %ld (df %.3g Hz); se: f %.1e, Q %.1e, "
           "k %.1e; linewidth %.0f bins\n",
           res.n_samples, res.cpu_s, res.segments, res.seg_len, res.df_hz,
           r->fit.se_f_hz / r->fit.f_hz, r->fit.se_q / r->fit.q, r->fit.se_k_n_m / r->fit.k_n_m,
           r->fit.linewidth_bins);
    snprintf(what, sizeof what, "nchv mode %d f_n (model w/2pi)", mode);
    check_rel(r->fit.f_hz, r->model_f_hz, tol, what);
    snprintf(what, sizeof what, "nchv mode %d Q_n (model 1/(2 xi))", mode);
    check_rel(r->fit.q, r->model_q, tol, what);
    snprintf(what, sizeof what, "nchv mode %d k_n (model w^2/tip^2)", mode);
    check_rel(r->fit.k_n_m, r->model_k_n_m, tol, what);
}

/* End to end on nchv.conf. The statistical error of k_n and Q_n from a record of T s is
 * about 1 / sqrt(lambda_n T), lambda_n = pi f_n / Q_n (see synthetic()): lambda_1 = 2549 /s
 * (f 338 kHz, Q 417), lambda_2 = 22430 /s (2.075 MHz, Q 291). At the config's 14.06 MHz
 * and ~100 ns per sample (rt with thermal force + PSD), 2 % at 4 sigma for mode 1 needs
 * T = 16 s, i.e. 30 s of CPU: too long for `make test`. The thermal increments of the rt
 * integrator are exact (Gaussian with the exact covariance of each step) and out of contact
 * the modal propagation is exact, so the sampled record has the oscillator's exact
 * statistics at any sample rate; the sample rate only has to put the mode below Nyquist.
 * So `make test` takes mode 1 at 1 MHz (Nyquist 500 kHz; mode 2 aliases to 75 kHz, outside
 * mode 1's band; the Q = 5 modes alias to a level ~1e-5 of mode 1's at its window edge):
 * T = 16 s, 16e6 samples, sigma 0.5 %; and mode 2 at 5 MHz: T = 2 s, 10e6 samples, sigma
 * 0.47 %; 2 % is 4 sigma for both. Segments: 0.1 s (df 10 Hz, mode 1's linewidth 811 Hz
 * is 81 bins: Hann bias on Q 2e-4) and 0.01 s (df 100 Hz, mode 2's 7.1 kHz = 71 bins).
 * AFMTWIN_VALIDATE=full runs modes 1 and 2 at the config's own 14.06 MHz for 16 s.
 *
 * Mode 3 (5.78 MHz, Q 5) at the config's 14.06 MHz: 0.41 fs, so its images fold into its
 * band (synthetic_nyquist()); the fit folds its model at fs. lambda_3 = 3.6e6 /s; the fit's
 * se at 2 s is 0.20 % for Q and 0.19 % for k, 1.4e-4 for f. What a single folded resonance
 * plus a constant floor cannot absorb (mode 2's tail, modes 4 and 5 above Nyquist folded in
 * at 2.23 and 7.0 MHz) leaves f +0.42 %, Q +0.31 %, k +0.04 % on the noise-free expected
 * spectrum (docs/numerics.md); 1.5 % is that plus > 5 sigma. Unfolded it was Q -11 %,
 * k -13 %. 2 s: 28e6 samples, ~3 s CPU. */
static void end_to_end(bool full) {
    if (full) {
        tune_check(14.06e6, 16.0, 0.1, 1, 2e-2);
        tune_check(14.06e6, 2.0, 0.01, 2, 2e-2);
    } else {
        tune_check(1e6, 16.0, 0.1, 1, 2e-2);
        tune_check(5e6, 2.0, 0.01, 2, 2e-2);
    }
    tune_check(14.06e6, 2.0, 0.01, 3, 1.5e-2);
}

int main(void) {
    psd_units();
    synthetic(0);
    synthetic(0.01);
    synthetic_nyquist();
    fit_bad_input();
    const char *v = getenv("AFMTWIN_VALIDATE");
    end_to_end(v && !strcmp(v, "full"));
    return check_done();
}
