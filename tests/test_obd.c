/* SPDX-License-Identifier: MIT */
/* test_obd.c -- the OBD sensor model (afm_obd), its noise generator (afm_rng) and the
 * output chain around them (afm_chain):
 *  - calibration: a pure mode-1 deflection of the NCHV model reads exactly as x; the
 *    higher modes' factors g_n are printed (docs/obd.md quotes them);
 *  - noise: the averaged periodogram of the sensor output is flat at the configured
 *    one-sided density D^2 (400 periodograms x 511 bins: statistical error ~0.2 %, checked
 *    to 2 %); normal deviates, one at a time and in bulk (afm_rng_normal_fill), have mean
 *    0, variance 1, fourth moment 3, the normal CDF and tails, and (bulk) no correlation
 *    between neighbours or between the two deviates of one draw;
 *  - ADC: the step is 2 full_scale / 2^bits, rounding and clamping exact, clamps counted;
 *  - block reads: afm_obd_read_block gives afm_obd_read's bits and clamp counts for every
 *    sensor variant (noise, ADC, none, disabled, lumped; NaN and infinite input) however the
 *    samples are split into calls;
 *  - chain: a tone through default.conf's streams (16, 256) comes out with gain 1 and
 *    time stamps that line up with the input (group delay removed) to 1e-4; the outputs do
 *    not depend on how the input is split into pushes; NaN samples are counted by the
 *    decimators and the outputs stay finite;
 *  - a week of uptime: the drive phase (afm_drive_phase_mod, what the rt integrator's
 *    phasors and the chain's estimators take) and the lock-in's phase lag one week after the
 *    tone was set, against the exact phase 2 pi frac(f dt n) in integer arithmetic: within
 *    2e-5 rad, 1 pm of a 50 nm tapping orbit (issue 11). */
#include "estimators/afm_chain.h"
#include "config/afm_config.h"
#include "beam/afm_model.h"
#include "estimators/afm_obd.h"
#include "forces/afm_rng.h"
#include "check.h"
#include "fixtures.h"

#include <stdint.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double pi = 3.14159265358979323846;

/* In-place radix-2 FFT (n a power of 2). */
static void fft(double *re, double *im, int n) {
    for (int i = 1, j = 0; i < n; i++) {
        int bit = n >> 1;
        for (; j & bit; bit >>= 1)
            j ^= bit;
        j ^= bit;
        if (i < j) {
            double t = re[i];
            re[i] = re[j];
            re[j] = t;
            t = im[i];
            im[i] = im[j];
            im[j] = t;
        }
    }
    for (int len = 2; len <= n; len <<= 1) {
        double a = -2 * pi / len;
        for (int i = 0; i < n; i += len)
            for (int k = 0; k < len / 2; k++) {
                double wr = cos(a * k), wi = sin(a * k);
                double xr = re[i + k + len / 2] * wr - im[i + k + len / 2] * wi;
                double xi = re[i + k + len / 2] * wi + im[i + k + len / 2] * wr;
                re[i + k + len / 2] = re[i + k] - xr;
                im[i + k + len / 2] = im[i + k] - xi;
                re[i + k] += xr;
                im[i + k] += xi;
            }
    }
}

static int setup(const char *path, afm_config *cfg, afm_modal *m) {
    char err[AFM_ERR_LEN];
    if (!check_true(afm_config_load(path, cfg, err, sizeof err) == 0, path)) return -1;
    if (!check_true(afm_model_build(&cfg->model, m, err, sizeof err) == 0, "model builds"))
        return -1;
    return 0;
}

/* default.conf with a noiseless, unquantised sensor (obd_m = the calibrated signal). */
static int setup_noiseless(afm_config *cfg, afm_modal *m) {
    if (setup("config/default.conf", cfg, m)) return -1;
    cfg->obd.noise_density_m_rthz = 0;
    cfg->obd.adc_bits = 0;
    return 0;
}

static void calibration(void) {
    afm_config cfg;
    afm_modal m;
    afm_obd o;
    char err[AFM_ERR_LEN];
    if (setup("config/nchv.conf", &cfg, &m)) return;
    cfg.obd.noise_density_m_rthz = 0;
    cfg.obd.adc_bits = 0;
    check_true(afm_obd_init(&o, &cfg, &m, err, sizeof err) == 0, "obd init on nchv");
    /* q = (c, 0, ...): x = tip_1 c, theta = rot_1 c (base at rest). */
    double worst = 0;
    for (double c = -3e-9; c <= 3e-9; c += 0.37e-9) {
        afm_sample s = {0};
        s.x_m = m.tip[0] * c;
        s.theta_rad = m.rot[0] * c;
        int32_t cnt;
        double v = afm_obd_read(&o, &s, &cnt);
        worst = fmax(worst, fabs(v - s.x_m) / fabs(s.x_m));
    }
    check_abs(worst, 0, 4e-16, "pure mode-1 deflection reads as x (relative error)");
    check_abs(afm_obd_mode_gain(&o, &m, 0), 1.0, 1e-15, "g_1 = 1");
    printf("nchv.conf: cal = tip_1/rot_1 = %.6g m/rad (beam length %.4g m)\n", o.cal_m_rad,
           m.beam_length_m);
    for (int i = 0; i < m.n; i++)
        printf("  mode %d: f = %10.2f kHz  rot/tip = %.6g 1/m  g = %.5f\n", i + 1,
               m.omega_rad_s[i] / (2 * pi) * 1e-3, m.rot[i] / m.tip[i],
               afm_obd_mode_gain(&o, &m, i));
    /* Static point load at the tip: q_i = tip_i F / w_i^2. */
    double x = 0, th = 0;
    for (int i = 0; i < m.n; i++) {
        x += m.tip[i] * m.tip[i] / (m.omega_rad_s[i] * m.omega_rad_s[i]);
        th += m.rot[i] * m.tip[i] / (m.omega_rad_s[i] * m.omega_rad_s[i]);
    }
    printf("  static tip load: theta/x = %.6g 1/m  g_static = %.5f\n", th / x,
           th / x * o.cal_m_rad);
    /* Disabled sensor passes x; lumped model (no slope) reads x. */
    cfg.obd.enabled = false;
    afm_obd_init(&o, &cfg, &m, err, sizeof err);
    afm_sample s = {.x_m = 1.25e-9, .theta_rad = 3.0};
    int32_t cnt;
    check_true(afm_obd_read(&o, &s, &cnt) == 1.25e-9, "disabled sensor passes x");
    afm_config lc;
    afm_modal lm;
    if (setup("config/thesis-1dof.conf", &lc, &lm) == 0) {
        lc.obd.adc_bits = 0;
        afm_obd_init(&o, &lc, &lm, err, sizeof err);
        check_true(afm_obd_read(&o, &s, &cnt) == 1.25e-9, "lumped model: the sensor reads x");
    }
}

static void noise(void) {
    afm_config cfg;
    afm_modal m;
    afm_obd o;
    char err[AFM_ERR_LEN];
    if (setup("config/nchv.conf", &cfg, &m)) return;
    const double D = 50e-15, fs = cfg.sim.sample_rate_hz;
    cfg.obd.noise_density_m_rthz = D;
    cfg.obd.adc_bits = 0;
    cfg.obd.seed = 12345;
    afm_obd_init(&o, &cfg, &m, err, sizeof err);
    enum { N = 1024, SEG = 400 };
    static double re[N], im[N], psd[N / 2];
    afm_sample s = {0};
    int32_t cnt;
    for (int g = 0; g < SEG; g++) {
        for (int i = 0; i < N; i++) {
            re[i] = afm_obd_read(&o, &s, &cnt);
            im[i] = 0;
        }
        fft(re, im, N);
        for (int k = 1; k < N / 2; k++) /* one-sided: 2 |X_k|^2 / (fs N) */
            psd[k] += 2 * (re[k] * re[k] + im[k] * im[k]) / (fs * N) / SEG;
    }
    double lo = 0, hi = 0, all = 0;
    for (int k = 1; k < N / 2; k++) {
        all += psd[k];
        if (k < N / 8) lo += psd[k];
        if (k >= 3 * N / 8) hi += psd[k];
    }
    all /= N / 2 - 1;
    lo /= N / 8 - 1;
    hi /= N / 2 - 3 * N / 8;
    check_rel(sqrt(all), D, 0.02, "noise: mean one-sided density = D (m/rtHz)");
    check_rel(sqrt(lo), D, 0.03, "noise: density below fs/16 = D (white)");
    check_rel(sqrt(hi), D, 0.03, "noise: density above 3 fs/16 = D (white)");

    /* Normal deviates: 4e6 draws; standard errors 5e-4 (mean), 7e-4 (variance), 2.6e-5 (tail). */
    afm_rng r;
    afm_rng_seed(&r, 7);
    double sum = 0, sq = 0, q4 = 0;
    long tail = 0, n = 4000000;
    for (long i = 0; i < n; i++) {
        double z = afm_rng_normal(&r);
        sum += z;
        sq += z * z;
        q4 += z * z * z * z;
        tail += fabs(z) > 3.0;
    }
    check_abs(sum / n, 0, 3e-3, "normal: mean 0");
    check_abs(sq / n, 1, 4e-3, "normal: variance 1");
    check_abs(q4 / n, 3, 0.03, "normal: fourth moment 3");
    check_abs((double)tail / n, 0.0026998, 1.5e-4, "normal: P(|z| > 3)");
    afm_rng a, b;
    afm_rng_seed(&a, 99);
    afm_rng_seed(&b, 99);
    int same = 1;
    for (int i = 0; i < 1000; i++)
        same &= afm_rng_normal(&a) == afm_rng_normal(&b);
    check_true(same, "same seed, same sequence");
}

/* Bulk normals: 4e6 deviates (standard errors: mean 5e-4, variance 7e-4, fourth moment
 * 5e-3, a CDF point <= 2.5e-4, P(|z| > 3) 2.6e-5, P(|z| > 4) 4e-6, a correlation 5e-4);
 * tolerances ~6 standard errors. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__aarch64__)
/* gcc 12 for arm64 stops with an internal compiler error (vect_transform_reduction)
 * vectorising the moment loop below: not vectorised there. */
#define NOT_VECTORISED_ON_ARM64 __attribute__((optimize("no-tree-vectorize")))
#else
#define NOT_VECTORISED_ON_ARM64
#endif
NOT_VECTORISED_ON_ARM64 static void bulk_normals(void) {
    enum { N = 4000000, LAGS = 8 };
    static double z[N];
    afm_rng r;
    afm_rng_seed(&r, 2024);
    afm_rng_normal_fill(&r, z, N);
    double sum = 0, sq = 0, q4 = 0, lag[LAGS + 1] = {0}, alag4 = 0, asum = 0, asq = 0;
    const double xs[] = {-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0};
    long below[7] = {0}, tail3 = 0, tail4 = 0;
    for (long i = 0; i < N; i++) {
        double v = z[i], a = fabs(v);
        sum += v;
        sq += v * v;
        q4 += v * v * v * v;
        asum += a;
        asq += a * a;
        tail3 += a > 3.0;
        tail4 += a > 4.0;
        for (int k = 0; k < 7; k++)
            below[k] += v < xs[k];
        for (int k = 1; k <= LAGS && i + k < N; k++)
            lag[k] += v * z[i + k];
        if (i + 4 < N) alag4 += a * fabs(z[i + 4]);
    }
    check_abs(sum / N, 0, 3e-3, "bulk normal: mean 0");
    check_abs(sq / N, 1, 4e-3, "bulk normal: variance 1");
    check_abs(q4 / N, 3, 0.03, "bulk normal: fourth moment 3");
    check_abs((double)tail3 / N, 0.0026998, 1.5e-4, "bulk normal: P(|z| > 3)");
    check_abs((double)tail4 / N, 6.3342e-5, 2.5e-5, "bulk normal: P(|z| > 4)");
    double worst_cdf = 0;
    for (int k = 0; k < 7; k++) /* Phi(x) = erfc(-x / sqrt 2) / 2 */
        worst_cdf = fmax(worst_cdf, fabs((double)below[k] / N - 0.5 * erfc(-xs[k] / sqrt(2.0))));
    check_abs(worst_cdf, 0, 1.5e-3, "bulk normal: CDF at -2 .. 2 (worst error)");
    double worst_lag = 0;
    for (int k = 1; k <= LAGS; k++)
        worst_lag = fmax(worst_lag, fabs(lag[k] / (N - k)));
    check_abs(worst_lag, 0, 3e-3, "bulk normal: correlation at lags 1..8 (worst)");
    /* lag 4: the two deviates of one 64-bit draw; |z| catches dependence beyond linear */
    double ma = asum / N, va = asq / N - ma * ma;
    check_abs((alag4 / (N - 4) - ma * ma) / va, 0, 3e-3,
              "bulk normal: |z| of the two halves of a draw uncorrelated");
    /* the sequence does not depend on how it is split into calls */
    afm_rng a;
    afm_rng_seed(&a, 2024);
    static double y[4096];
    for (int k = 0; k < 4096;) {
        int m = 8 * (1 + k % 5);
        if (m > 4096 - k) m = 4096 - k;
        afm_rng_normal_fill(&a, y + k, m);
        k += m;
    }
    check_true(memcmp(y, z, sizeof y) == 0, "bulk normal: the same sequence in calls of 8 .. 40");
}

static void adc(void) {
    afm_config cfg;
    afm_modal m;
    afm_obd o;
    char err[AFM_ERR_LEN];
    if (setup("config/nchv.conf", &cfg, &m)) return;
    cfg.obd.noise_density_m_rthz = 0;
    cfg.obd.adc_bits = 8;
    cfg.obd.full_scale_m = 1e-6;
    afm_obd_init(&o, &cfg, &m, err, sizeof err);
    const double lsb = 2e-6 / 256; /* 7.8125e-9 m, exact in binary */
    check_true(o.lsb_m == lsb, "ADC step 2 full_scale / 2^bits");
    const struct {
        double v;
        int counts;
        long long sat;
    } cases[] = {{3.4 * lsb, 3, 0},       {-3.6 * lsb, -4, 0}, {127.4 * lsb, 127, 0},
                 {127.6 * lsb, 127, 1},   {2e-6, 127, 2},      {-128.4 * lsb, -128, 2},
                 {-128.6 * lsb, -128, 3}, {-5e-6, -128, 4},    {0.0, 0, 4}};
    int ok = 1;
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        afm_sample s = {0};
        s.theta_rad = cases[i].v / o.cal_m_rad;
        s.x_m = cases[i].v;
        int32_t cnt;
        double v = afm_obd_read(&o, &s, &cnt);
        int good = cnt == cases[i].counts && v == cnt * lsb && o.n_saturated == cases[i].sat;
        if (!good)
            printf("  ADC case %zu: v %g -> %d (%g), sat %lld\n", i, cases[i].v, cnt, v,
                   o.n_saturated);
        ok &= good;
    }
    check_true(ok, "ADC: rounding to counts, value = counts * lsb, clamping at -128..127 counted");
    cfg.obd.adc_bits = 32;
    afm_obd_init(&o, &cfg, &m, err, sizeof err);
    afm_sample s = {.theta_rad = 1.0};
    int32_t cnt;
    afm_obd_read(&o, &s, &cnt);
    check_true(cnt == INT32_MAX && o.n_saturated == 1, "32-bit ADC clamps at INT32_MAX");
}

/* One sensor variant: afm_obd_read sample by sample against afm_obd_read_block in uneven
 * calls on an identically initialised sensor: same bits (NaN where NaN), same clamps. */
static int block_case(const afm_config *cfg, const afm_modal *m, const char *what) {
    enum { N = 3000 };
    static afm_sample s[N];
    static double one[N], blk[N];
    char err[AFM_ERR_LEN], msg[200];
    afm_obd a, b;
    if (afm_obd_init(&a, cfg, m, err, sizeof err) || afm_obd_init(&b, cfg, m, err, sizeof err))
        return check_true(false, err);
    double fs_m = cfg->obd.full_scale_m;
    for (int i = 0; i < N; i++) { /* sweeps past the full scale both ways */
        double v = 1.3 * fs_m * sin(0.01 * i);
        s[i] = (afm_sample){.t_s = i * 1e-7, .x_m = v, .theta_rad = v / a.cal_m_rad};
        if (!a.use_slope) s[i].theta_rad = 0.0;
    }
    s[17].theta_rad = s[17].x_m = NAN;
    s[18].theta_rad = s[18].x_m = INFINITY;
    s[19].theta_rad = s[19].x_m = -INFINITY;
    int32_t cnt;
    for (int i = 0; i < N; i++)
        one[i] = afm_obd_read(&a, &s[i], &cnt);
    static const int sizes[] = {1, 3, 7, 512, 13, 600, 2, 1000, 5};
    for (int i = 0, k = 0; i < N; k++) {
        int n = sizes[k % 9] < N - i ? sizes[k % 9] : N - i;
        afm_obd_read_block(&b, s + i, n, blk + i);
        i += n;
    }
    int same = a.n_saturated == b.n_saturated;
    for (int i = 0; i < N; i++)
        same &= isnan(one[i]) ? isnan(blk[i]) : memcmp(&one[i], &blk[i], sizeof one[i]) == 0;
    snprintf(msg, sizeof msg, "block read = per-sample reads, %s (%lld clamps)", what,
             a.n_saturated);
    return check_true(same, msg);
}

static void block_reads(void) {
    afm_config cfg;
    afm_modal m;
    if (setup("config/nchv.conf", &cfg, &m)) return;
    cfg.obd.enabled = true;
    cfg.obd.full_scale_m = 200e-9;
    cfg.obd.noise_density_m_rthz = 50e-15;
    cfg.obd.adc_bits = 16;
    block_case(&cfg, &m, "noise + 16-bit ADC");
    cfg.obd.adc_bits = 0;
    block_case(&cfg, &m, "noise, no ADC");
    cfg.obd.noise_density_m_rthz = 0;
    cfg.obd.adc_bits = 12;
    block_case(&cfg, &m, "12-bit ADC, no noise");
    cfg.obd.adc_bits = 0;
    block_case(&cfg, &m, "no noise, no ADC");
    cfg.obd.enabled = false;
    block_case(&cfg, &m, "disabled");
    afm_config lc;
    afm_modal lm;
    if (setup("config/thesis-1dof.conf", &lc, &lm) == 0) {
        lc.obd.enabled = true;
        lc.obd.full_scale_m = 200e-9;
        lc.obd.noise_density_m_rthz = 50e-15;
        lc.obd.adc_bits = 16;
        block_case(&lc, &lm, "lumped model (reads x), noise + ADC");
    }
    /* NaN input: a NaN reading and counts 0, not a clamp; infinite input clamps */
    afm_obd o;
    char err[AFM_ERR_LEN];
    cfg.obd.enabled = true;
    cfg.obd.adc_bits = 16;
    afm_obd_init(&o, &cfg, &m, err, sizeof err);
    afm_sample sn = {.theta_rad = NAN}, si = {.theta_rad = INFINITY};
    int32_t cn = 1, ci = 0;
    double vn = afm_obd_read(&o, &sn, &cn), vi = afm_obd_read(&o, &si, &ci);
    check_true(isnan(vn) && cn == 0 && vi == 32767 * o.lsb_m && ci == 32767 && o.n_saturated == 1,
               "NaN theta reads NaN (no clamp), +inf clamps to 32767 counts (one clamp)");
}

/* A tone at 20 kHz (in the 256 stream's band: 0.8 x 27.5 kHz) through default.conf's chain. */
static void chain(void) {
    afm_config cfg;
    afm_modal m;
    char err[AFM_ERR_LEN];
    if (setup_noiseless(&cfg, &m)) return;
    afm_chain *c = afm_chain_create(&cfg, &m, err, sizeof err);
    if (!check_true(c != NULL, "chain: create on default.conf")) {
        printf("  %s\n", err);
        return;
    }
    check_true(afm_chain_n_streams(c) == 2, "chain: two streams");
    const double fs = cfg.sim.sample_rate_hz, f = 20e3, A = 10e-9;
    double cal = m.tip[0] / m.rot[0];
    enum { BLK = 4096 };
    static afm_sample s[BLK];
    long n_total = (long)(0.01 * fs), t_i = 0;
    double worst[2] = {0, 0};
    long got[2] = {0, 0};
    while (t_i < n_total) {
        for (int i = 0; i < BLK; i++, t_i++) {
            double t = t_i / fs, x = A * sin(2 * pi * f * t);
            s[i] = (afm_sample){
                .t_s = t, .x_m = x, .theta_rad = x / cal, .f_n = 1e-9 * x / A, .base_m = 0};
        }
        afm_chain_push(c, s, BLK);
        for (int k = 0; k < 2; k++) {
            afm_chain_block b;
            while (afm_chain_take_block(c, k, &b, 0) > 0)
                for (int i = 0; i < b.n; i++, got[k]++) {
                    if (b.t_s[i] < 2e-3) continue; /* filters filled */
                    double want = A * sin(2 * pi * f * b.t_s[i]);
                    worst[k] = fmax(worst[k], fabs(b.obd_m[i] - want) / A);
                    worst[k] = fmax(worst[k], fabs(b.x_m[i] - want) / A);
                    worst[k] = fmax(worst[k], fabs(b.f_n[i] * A / 1e-9 - want) / A);
                }
        }
    }
    check_true(got[0] == t_i / 16 && got[1] == t_i / 256,
               "chain: one sample per 16 and per 256 inputs");
    /* Gain error <= 0.01 dB = 1.2e-3 worst case; at 20 kHz it is ~1e-4 */
    check_abs(worst[0], 0, 2e-4, "chain /16: obd, x, f = the tone at their time stamps");
    check_abs(worst[1], 0, 2e-4, "chain /256 (cascaded): the tone at its time stamps");
    afm_chain_stats st = afm_chain_stats_get(c);
    check_true(st.pushed == t_i && st.nonfinite == 0 && st.dropped[0] == 0,
               "chain: counters (pushed, nothing dropped)");
    afm_chain_destroy(&c);
    check_true(c == NULL, "chain: destroy clears the pointer");
}

/* Everything a chain stream produced (t, x, obd, counts, f, base per sample). */
typedef struct {
    long n[2];
    double *v[2];
} chain_log;

static void drain(afm_chain *c, chain_log *g) {
    afm_chain_block b;
    for (int k = 0; k < 2; k++)
        while (afm_chain_take_block(c, k, &b, 0) > 0)
            for (int i = 0; i < b.n; i++, g->n[k]++) {
                double *w = g->v[k] + 6 * g->n[k];
                w[0] = b.t_s[i];
                w[1] = b.x_m[i];
                w[2] = b.obd_m[i];
                w[3] = b.obd_counts ? b.obd_counts[i] : 0;
                w[4] = b.f_n[i];
                w[5] = b.base_m[i];
            }
}

/* default.conf's chain (16-bit ADC, 50 fm/rtHz noise) fed a tone: the same input pushed in
 * one call per 4096 samples and in calls of 1, 7, 13, 512, 1000, 3 samples gives the same
 * outputs bit for bit; NaN samples (theta, x) are counted once each by the first-stage
 * decimator, infinite theta as a clamp, and every output stays finite. */
static void chain_slices(void) {
    afm_config cfg;
    afm_modal m;
    char err[AFM_ERR_LEN];
    if (setup("config/default.conf", &cfg, &m)) return;
    enum { N = 40000 };
    static afm_sample s[N];
    const double fs = cfg.sim.sample_rate_hz, cal = m.tip[0] / m.rot[0];
    for (int i = 0; i < N; i++) {
        double t = i / fs, x = 20e-9 * sin(2 * pi * 300e3 * t);
        s[i] = (afm_sample){.t_s = t,
                            .x_m = x,
                            .theta_rad = x / cal,
                            .f_n = 1e-9 * cos(x),
                            .base_m = 1e-10 * sin(2 * pi * 300e3 * t)};
    }
    chain_log g[2];
    for (int r = 0; r < 2; r++) {
        g[r].n[0] = g[r].n[1] = 0;
        g[r].v[0] = malloc(6 * (N / 16 + 8) * sizeof(double));
        g[r].v[1] = malloc(6 * (N / 256 + 8) * sizeof(double));
        afm_chain *c = afm_chain_create(&cfg, &m, err, sizeof err);
        if (!check_true(c != NULL, "slices: create")) return;
        static const int sizes[] = {1, 7, 13, 512, 1000, 3};
        for (int i = 0, k = 0; i < N; k++) {
            int n = r == 0 ? 4096 : sizes[k % 6];
            if (n > N - i) n = N - i;
            afm_chain_push(c, s + i, n);
            drain(c, &g[r]);
            i += n;
        }
        afm_chain_destroy(&c);
    }
    bool same = g[0].n[0] == g[1].n[0] && g[0].n[1] == g[1].n[1] && g[0].n[0] == N / 16 &&
                g[0].n[1] == N / 256;
    for (int k = 0; k < 2 && same; k++)
        same = memcmp(g[0].v[k], g[1].v[k], 6 * (size_t)g[0].n[k] * sizeof(double)) == 0;
    check_true(same, "chain: pushes of 4096 vs 1, 7, 13, 512, 1000, 3 samples: identical outputs");

    /* non-finite samples */
    s[1000].theta_rad = NAN;
    s[3000].x_m = NAN;
    s[5000].theta_rad = INFINITY;
    afm_chain *c = afm_chain_create(&cfg, &m, err, sizeof err);
    if (!check_true(c != NULL, "nan: create")) return;
    g[0].n[0] = g[0].n[1] = 0;
    for (int i = 0; i < N; i += 1000)
        afm_chain_push(c, s + i, 1000);
    drain(c, &g[0]);
    afm_chain_stats st = afm_chain_stats_get(c);
    bool finite = true;
    for (int k = 0; k < 2; k++)
        for (long i = 0; i < 6 * g[0].n[k]; i++)
            finite &= isfinite(g[0].v[k][i]);
    check_true(st.nonfinite == 2 && st.obd_saturated == 1 && st.pushed == N,
               "chain: 2 NaN samples counted by the decimators, +inf theta as 1 clamp");
    check_true(finite && g[0].n[0] == N / 16 && g[0].n[1] == N / 256,
               "chain: after NaN input every output finite, none missing");
    afm_chain_destroy(&c);
    for (int r = 0; r < 2; r++)
        for (int k = 0; k < 2; k++)
            free(g[r].v[k]);
}

/* frac(f dt n) exactly, for doubles f, dt and n < 2^62: f dt = Mf Md 2^-fb with 53-bit
 * integers Mf, Md, and frac(Mf Md n 2^-fb) needs only Mf Md n mod 2^fb (fb < 128 here). */
__extension__ typedef unsigned __int128 u128;
static double exact_turns(double f, double dt, long long n) {
    int ef, ed;
    double mf = frexp(f, &ef), md = frexp(dt, &ed);
    u128 prod = (u128)(uint64_t)ldexp(mf, 53) * (uint64_t)ldexp(md, 53) * (u128)n;
    int fb = 106 - ef - ed;
    if (fb <= 0 || fb >= 128) return NAN;
    return ldexp((double)(prod & (((u128)1 << fb) - 1)), -fb);
}

/* default.conf's tone, set at t = 0 on the 14.06 MHz grid; samples from one week on. */
static void week_of_uptime(void) {
    afm_config cfg;
    afm_modal m;
    char err[AFM_ERR_LEN];
    if (setup_noiseless(&cfg, &m)) return;
    afm_force_params nof = fixture_no_forces();
    afm_sim *sim = afm_sim_create(&m, &nof, &cfg.drive, &cfg.sim, err, sizeof err);
    afm_chain *c = afm_chain_create(&cfg, &m, err, sizeof err);
    if (!check_true(sim && c && afm_chain_attach(c, sim, err, sizeof err) == 0,
                    "week: sim and chain"))
        return;
    const afm_drive *d = afm_sim_drive(sim);
    const double fs = cfg.sim.sample_rate_hz, dt = 1 / fs, f0 = d->freq_hz[0];
    const double phi = d->phase_rad[0], A = 10e-9, lag = 1.0, cal = m.tip[0] / m.rot[0];
    const long long n0 = llround(7 * 86400.0 * fs);
    enum { BLK = 4096, NBLK = 600 }; /* 2.5e6 samples: past two of the chain's origins */
    static afm_sample s[BLK];
    static afm_chain_period per[64];
    double e_mod = 0, e_old = 0, e_lock = 0;
    int records = 0;
    for (int b = 0; b < NBLK; b++) {
        for (int i = 0; i < BLK; i++) {
            long long n = n0 + (long long)b * BLK + i;
            double t = 0.0 + (double)n * dt; /* afm_sim: t_start + step dt */
            double th = fmod(phi + 2 * pi * exact_turns(f0, dt, n), 2 * pi);
            double x = A * sin(th - lag);
            s[i] = (afm_sample){.t_s = t, .x_m = x, .theta_rad = x / cal, .base_m = 0};
            if (i % 97 == 0) {
                e_mod = fmax(e_mod, fabs(remainder(afm_drive_phase_mod(d, 0, t) - th, 2 * pi)));
                e_old = fmax(e_old, fabs(remainder(afm_drive_phase(d, 0, t) - th, 2 * pi)));
            }
        }
        afm_chain_push(c, s, BLK);
        int k;
        while ((k = afm_chain_take_periods(c, per, 64)) > 0)
            for (int j = 0; j < k; j++, records++)
                if (b > NBLK / 4) /* the lock-in settled (time constant << 0.04 s) */
                    e_lock = fmax(e_lock, fabs(per[j].lockin_phase_deg * pi / 180 - lag));
    }
    printf("  a week of uptime (n = %lld steps): drive phase error %.2e rad (the double "
           "expression phi + w t: %.2e), lock-in lag error %.2e rad over %d records\n",
           n0, e_mod, e_old, e_lock, records);
    check_abs(e_mod, 0, 2e-5,
              "week: drive phase from the step count within 2e-5 rad (1 pm at 50 nm)");
    check_true(records > 1000, "week: the chain's lock-in gives records");
    check_abs(e_lock, 0, 2e-5, "week: lock-in phase lag within 2e-5 rad of the signal's");
    afm_chain_destroy(&c);
    afm_sim_destroy(&sim);
}

int main(void) {
    week_of_uptime();
    calibration();
    noise();
    bulk_normals();
    adc();
    block_reads();
    chain();
    chain_slices();
    return check_done();
}
