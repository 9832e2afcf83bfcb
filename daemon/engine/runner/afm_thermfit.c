/* SPDX-License-Identifier: MIT */
/* afm_thermfit.c -- Whittle/Levenberg-Marquardt fit of thesis eq. 5.1 to one resonance of
 * a PSD: afm_thermfit.h. */
#include "runner/afm_thermfit.h"

#include "estimators/afm_obd.h"
#include "estimators/afm_psd.h"
#include "forces/afm_rng.h"
#include "runner/afm_twin.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define TF_NP 4 /* parameters: f, Q, k, F */
#define TF_MIN_BINS 8
#define TF_MAX_ITER 300
#define TF_DEFAULT_WIDTHS 25.0
/* Image pairs j fs +- f summed (j = 1..16): for f_n, f <= fs / 2 the rest is below
 * 2 (f_n / fs)^4 sum_{j > 16} (j - 1/2)^-4 < 1.2e-5 of the resonance's low-frequency level
 * a0 = c / (k f_n Q) (R(g) ~ a0 (f_n / g)^4 there), while R >= a0 / 9 up to 2 f_n: far below
 * the statistical errors (1e-3 for NCHV mode 3 at 2 s). Cost: 33 terms per evaluation,
 * paid only at the interpolation nodes of tf_sweep in the window sweeps. */
#define TF_IMAGES 16
#define TF_BIN_CORR 1.944 /* 1 + 2 (4/9 + 1/36): Hann bin-to-bin |correlation|^2 summed */

static const double tf_pi = 3.14159265358979323846264338327950;

/* Resonance term L of the continuous-time spectrum at frequency g >= 0 and its partial
 * derivatives in f_n, Q_n, k_n (d[0..2]). */
static double tf_res(const double *p, double c, double g, double *d) {
    double fn = p[0], q = p[1], k = p[2];
    double u = g / fn, u2m1 = u * u - 1.0;
    double den = u2m1 * u2m1 + u * u / (q * q);
    double a0 = c / (k * fn * q);
    double l = a0 / den;
    if (d) {
        double dden_du = 4.0 * u * u2m1 + 2.0 * u / (q * q);
        d[0] = l * (-1.0 / fn + u / (fn * den) * dden_du);
        d[1] = l * (-1.0 / q + 2.0 * u * u / (q * q * q * den));
        d[2] = -l / k;
    }
    return l;
}

/* The model at f and its partials: the resonance, folded over the images |f + j fs| for
 * |j| <= TF_IMAGES when fs > 0 (afm_thermfit.h), plus the floor. */
static double tf_eval(const double *p, double c, double fs, double f, double *d) {
    double l = tf_res(p, c, f, d);
    if (d) d[3] = 1.0;
    if (fs > 0) {
        for (int j = 1; j <= TF_IMAGES; j++) {
            double di[TF_NP];
            for (int s = -1; s <= 1; s += 2) {
                l += tf_res(p, c, fabs(j * fs + s * f), d ? di : NULL);
                if (d)
                    for (int n = 0; n < 3; n++)
                        d[n] += di[n];
            }
        }
    }
    return l + p[3];
}

double afm_thermfit_model(const afm_thermfit *r, double temperature_k, double sample_rate_hz,
                          double f_hz) {
    double p[TF_NP] = {r->f_hz, r->q, r->k_n_m, r->floor_m2_hz};
    return tf_eval(p, 2.0 * AFM_KB_J_K * temperature_k / tf_pi, sample_rate_hz, f_hz, NULL);
}

/* Solve (A + lambda diag A) x = g, scaled to unit diagonal; 0 or -1 if not positive definite. */
static int tf_solve(const double a[TF_NP][TF_NP], const double *g, double lambda, double *x) {
    double s[TF_NP], m[TF_NP][TF_NP], y[TF_NP];
    for (int i = 0; i < TF_NP; i++) {
        if (!(a[i][i] > 0)) return -1;
        s[i] = 1.0 / sqrt(a[i][i]);
    }
    for (int i = 0; i < TF_NP; i++)
        for (int j = 0; j < TF_NP; j++)
            m[i][j] = a[i][j] * s[i] * s[j] + (i == j ? lambda : 0.0);
    for (int j = 0; j < TF_NP; j++) { /* Cholesky, lower triangle in place */
        double d = m[j][j];
        for (int k = 0; k < j; k++)
            d -= m[j][k] * m[j][k];
        if (!(d > 1e-300)) return -1;
        m[j][j] = sqrt(d);
        for (int i = j + 1; i < TF_NP; i++) {
            double v = m[i][j];
            for (int k = 0; k < j; k++)
                v -= m[i][k] * m[j][k];
            m[i][j] = v / m[j][j];
        }
    }
    for (int i = 0; i < TF_NP; i++) {
        double v = g[i] * s[i];
        for (int k = 0; k < i; k++)
            v -= m[i][k] * y[k];
        y[i] = v / m[i][i];
    }
    for (int i = TF_NP - 1; i >= 0; i--) {
        double v = y[i];
        for (int k = i + 1; k < TF_NP; k++)
            v -= m[k][i] * x[k];
        x[i] = v / m[i][i];
    }
    for (int i = 0; i < TF_NP; i++)
        x[i] *= s[i];
    return 0;
}

typedef struct {
    const double *psd;
    double df, c, fs; /* fs: 0, or the sampling rate the model is folded at */
    long i0, i1;
} tf_data;

/* The image sum of tf_eval (the fold, without the direct term and the floor) varies on the
 * scale of the line width f_n / Q or slower in the window (the nearest image peak, at
 * fs - f_n, lies at or beyond Nyquist), far above the bin spacing: NCHV mode 3's line is
 * 1.16 MHz wide at df 20 Hz. So the window sweeps evaluate it exactly only at nodes every
 * m bins, h = m df <= (f_n / Q) / TF_NODE_PER_WIDTH, m <= TF_NODE_MAX, and take the bins in
 * between by 4-point Lagrange interpolation (error ~ (h / width)^4 ~ 1e-12). The
 * direct term and the floor stay exact at every bin. The fold then costs ~1/m of summing it
 * at every bin: the nchv 2 s tune takes 4.1 s of CPU instead of 7.1 s, with the fitted
 * figures unchanged to 4e-10 (docs/numerics.md "Thermal fit near Nyquist"). */
#define TF_NODE_PER_WIDTH 1024.0
#define TF_NODE_MAX 64

typedef struct {
    const double *p;
    double c, fs, df;
    long i0, m;     /* first bin, bins per node interval */
    long k, r;      /* the next bin is i0 + k m + r; nodes k-1 .. k+2 are in v[0..3] */
    double v[4][4]; /* image sum and its partials in f_n, Q, k at the four nodes */
} tf_sweep;

static void tf_node(const tf_sweep *w, long k, double *v) {
    double f = (double)(w->i0 + k * w->m) * w->df;
    v[0] = v[1] = v[2] = v[3] = 0;
    for (int j = 1; j <= TF_IMAGES; j++)
        for (int s = -1; s <= 1; s += 2) {
            double di[TF_NP];
            v[0] += tf_res(w->p, w->c, fabs(j * w->fs + s * f), di);
            for (int n = 0; n < 3; n++)
                v[n + 1] += di[n];
        }
}

static void tf_sweep_init(tf_sweep *w, const tf_data *dt, const double *p) {
    w->p = p;
    w->c = dt->c;
    w->fs = dt->fs;
    w->df = dt->df;
    w->i0 = dt->i0;
    double m = floor(p[0] / p[1] / TF_NODE_PER_WIDTH / dt->df);
    w->m = !(m >= 1) ? 1 : m > TF_NODE_MAX ? TF_NODE_MAX : (long)m;
    w->k = w->r = 0;
    if (w->fs > 0)
        for (int n = 0; n < 4; n++)
            tf_node(w, n - 1, w->v[n]);
}

/* As tf_eval at bin i; the bins must be dt->i0, dt->i0 + 1, ... in turn. */
static double tf_sweep_eval(tf_sweep *w, long i, double *d) {
    double f = (double)i * w->df;
    double l = tf_res(w->p, w->c, f, d);
    if (d) d[3] = 1.0;
    if (!(w->fs > 0)) return l + w->p[3];
    double u = (double)w->r / (double)w->m;
    double c[4] = {-u * (u - 1) * (u - 2) / 6, (u + 1) * (u - 1) * (u - 2) / 2,
                   -(u + 1) * u * (u - 2) / 2, (u + 1) * u * (u - 1) / 6};
    int nv = d ? 4 : 1;
    for (int n = 0; n < nv; n++) {
        double s = c[0] * w->v[0][n] + c[1] * w->v[1][n] + c[2] * w->v[2][n] + c[3] * w->v[3][n];
        if (n == 0)
            l += s;
        else
            d[n - 1] += s;
    }
    if (++w->r == w->m) { /* the next bin starts a new interval: slide the nodes by one */
        w->r = 0;
        w->k++;
        memmove(w->v[0], w->v[1], 3 * sizeof w->v[0]);
        tf_node(w, w->k + 2, w->v[3]);
    }
    return l + w->p[3];
}

/* Weighted sum of squares with weights 1/w_i^2 from wp (NULL: from p itself); -1 when the
 * model is not positive somewhere in the window. */
static double tf_cost(const tf_data *dt, const double *p, const double *wp) {
    double s = 0;
    tf_sweep sm, sw;
    tf_sweep_init(&sm, dt, p);
    if (wp) tf_sweep_init(&sw, dt, wp);
    for (long i = dt->i0; i <= dt->i1; i++) {
        double m = tf_sweep_eval(&sm, i, NULL);
        double w = wp ? tf_sweep_eval(&sw, i, NULL) : m;
        if (!(m > 0) || !(w > 0)) return -1;
        double r = (dt->psd[i] - m) / w;
        s += r * r;
    }
    return s;
}

/* Normal equations at p with weights 1/M(p)^2. */
static void tf_normal(const tf_data *dt, const double *p, double a[TF_NP][TF_NP], double *g) {
    for (int i = 0; i < TF_NP; i++) {
        g[i] = 0;
        for (int j = 0; j < TF_NP; j++)
            a[i][j] = 0;
    }
    tf_sweep sm;
    tf_sweep_init(&sm, dt, p);
    for (long i = dt->i0; i <= dt->i1; i++) {
        double d[TF_NP], m = tf_sweep_eval(&sm, i, d);
        double w = 1.0 / (m * m), r = dt->psd[i] - m;
        for (int j = 0; j < TF_NP; j++) {
            g[j] += w * d[j] * r;
            for (int k = 0; k <= j; k++)
                a[j][k] += w * d[j] * d[k];
        }
    }
    for (int j = 0; j < TF_NP; j++)
        for (int k = j + 1; k < TF_NP; k++)
            a[j][k] = a[k][j];
}

/* Levenberg-Marquardt from p (updated in place). Returns iterations, or -1. */
static int tf_lm(const tf_data *dt, double *p, double peak) {
    double lambda = 1e-3;
    double a[TF_NP][TF_NP], g[TF_NP], x[TF_NP], pt[TF_NP];
    for (int it = 1; it <= TF_MAX_ITER; it++) {
        tf_normal(dt, p, a, g);
        double s0 = tf_cost(dt, p, NULL);
        if (s0 < 0) return -1;
        for (;;) {
            if (lambda > 1e12) return it; /* no step lowers the cost: at the optimum */
            if (tf_solve((const double(*)[TF_NP])a, g, lambda, x) != 0) {
                lambda *= 10;
                continue;
            }
            for (int j = 0; j < TF_NP; j++)
                pt[j] = p[j] + x[j];
            double s1 = (pt[0] > 0 && pt[1] > 0 && pt[2] > 0) ? tf_cost(dt, pt, p) : -1;
            if (s1 >= 0 && s1 <= s0) break;
            lambda *= 4;
        }
        for (int j = 0; j < TF_NP; j++)
            p[j] = pt[j];
        lambda = fmax(lambda / 3, 1e-12);
        if (fabs(x[0]) < 1e-12 * p[0] && fabs(x[1]) < 1e-9 * p[1] && fabs(x[2]) < 1e-9 * p[2] &&
            fabs(x[3]) < 1e-9 * peak)
            return it;
    }
    return -1;
}

static long tf_bin_up(double f, double df) {
    return (long)ceil(f / df - 1e-9);
}
static long tf_bin_down(double f, double df) {
    return (long)floor(f / df + 1e-9);
}

int afm_thermfit_mode(const double *psd, long n_bins, double df_hz, double sample_rate_hz,
                      double temperature_k, double band_lo_hz, double band_hi_hz,
                      double window_linewidths, afm_thermfit *out, char *err, size_t errlen) {
#define TF_FAIL(...)                                                                               \
    do {                                                                                           \
        if (err && errlen) snprintf(err, errlen, __VA_ARGS__);                                     \
        return -1;                                                                                 \
    } while (0)
    if (!psd || !out || n_bins < TF_MIN_BINS + 1) TF_FAIL("thermfit: no PSD or too few bins");
    if (!(df_hz > 0) || !isfinite(df_hz)) TF_FAIL("thermfit: bin spacing must be > 0");
    if (!(temperature_k > 0) || !isfinite(temperature_k))
        TF_FAIL("thermfit: temperature must be > 0 K");
    if (!(band_lo_hz < band_hi_hz) || !isfinite(band_lo_hz) || !isfinite(band_hi_hz))
        TF_FAIL("thermfit: band [%g, %g] Hz is empty", band_lo_hz, band_hi_hz);
    if (!(window_linewidths > 0)) window_linewidths = TF_DEFAULT_WIDTHS;
    long b0 = tf_bin_up(band_lo_hz, df_hz), b1 = tf_bin_down(band_hi_hz, df_hz);
    if (b0 < 1) b0 = 1;
    if (b1 > n_bins - 1) b1 = n_bins - 1;
    if (b1 - b0 + 1 < TF_MIN_BINS)
        TF_FAIL("thermfit: band [%g, %g] Hz holds %ld bins of %g Hz, need >= %d", band_lo_hz,
                band_hi_hz, b1 - b0 + 1 > 0 ? b1 - b0 + 1 : 0, df_hz, TF_MIN_BINS);
    for (long i = b0; i <= b1; i++)
        if (!isfinite(psd[i]) || psd[i] < 0)
            TF_FAIL("thermfit: PSD bin %ld is not finite and >= 0", i);

    /* Start values from a smoothed spectrum: running means over s = 3, 9, 27, ... bins;
     * the largest s whose half-power width is still >= 4 s (so the smoothing does not set
     * the width, and single noisy bins are averaged out) gives the peak, width and level. */
    double f0 = 0, fl0 = 0, pmax = -1, fa = 0, fb = 0;
    long nband = b1 - b0 + 1;
    for (long sw = 3; sw <= nband / 8 || sw == 3; sw *= 3) {
        long h = sw / 2, ipk = b0;
        double pk = -1, pmin = INFINITY;
        /* running mean of sw bins centred on i, by a sliding sum */
        double acc = 0;
        for (long k = b0; k < b0 + sw - 1 && k <= b1; k++)
            acc += psd[k];
        for (long i = b0 + h; i <= b1 - h; i++) {
            acc += psd[i + h];
            double v = acc / (double)sw;
            acc -= psd[i - h];
            if (v > pk) pk = v, ipk = i;
            if (v < pmin) pmin = v;
        }
        if (!(pk > 2.0 * pmin) || ipk - h <= b0 || ipk + h >= b1) continue;
        double base = 0.5 * pmin, half = base + 0.5 * (pk - base);
        /* half-power points of the same running mean, walked in steps of s / 2 */
        double a = (double)b0 * df_hz, b = (double)b1 * df_hz;
#define TF_AVG(i, out)                                                                             \
    do {                                                                                           \
        double t_ = 0;                                                                             \
        for (long k_ = (i)-h; k_ <= (i) + h; k_++)                                                 \
            t_ += psd[k_];                                                                         \
        (out) = t_ / (double)sw;                                                                   \
    } while (0)
        for (long i = ipk, step = h > 0 ? h : 1; i - step - h >= b0; i -= step) {
            double v;
            TF_AVG(i - step, v);
            if (v < half) {
                a = (double)(i - step / 2) * df_hz;
                break;
            }
        }
        for (long i = ipk, step = h > 0 ? h : 1; i + step + h <= b1; i += step) {
            double v;
            TF_AVG(i + step, v);
            if (v < half) {
                b = (double)(i + step / 2) * df_hz;
                break;
            }
        }
#undef TF_AVG
        if (b - a < 4.0 * (double)sw * df_hz && pmax > 0) continue;
        f0 = (double)ipk * df_hz, fl0 = base, pmax = pk, fa = a, fb = b;
    }
    if (!(pmax > 0))
        TF_FAIL("thermfit: no resonance peak inside [%g, %g] Hz", band_lo_hz, band_hi_hz);
    double width = fmax(fb - fa, df_hz), q0 = f0 / width;
    double c = 2.0 * AFM_KB_J_K * temperature_k / tf_pi;
    double p[TF_NP] = {f0, q0, c / ((pmax - fl0) / (q0 * q0) * f0 * q0), fl0};

    tf_data dt = {.psd = psd, .df = df_hz, .c = c, .fs = sample_rate_hz > 0 ? sample_rate_hz : 0};
    int iters = 0;
    for (int pass = 0; pass < 2; pass++) {
        double hw = window_linewidths * p[0] / p[1];
        dt.i0 = tf_bin_up(p[0] - hw, df_hz);
        dt.i1 = tf_bin_down(p[0] + hw, df_hz);
        if (dt.i0 < b0) dt.i0 = b0;
        if (dt.i1 > b1) dt.i1 = b1;
        if (dt.i1 - dt.i0 + 1 < TF_MIN_BINS)
            TF_FAIL("thermfit: fit window around %g Hz holds fewer than %d bins", p[0],
                    TF_MIN_BINS);
        int n = tf_lm(&dt, p, pmax);
        if (n < 0) TF_FAIL("thermfit: no convergence near %g Hz", f0);
        iters += n;
        if (!(p[0] > (double)b0 * df_hz && p[0] < (double)b1 * df_hz))
            TF_FAIL("thermfit: fitted resonance %g Hz left the band [%g, %g] Hz", p[0], band_lo_hz,
                    band_hi_hz);
    }

    if (p[0] / p[1] < 2.0 * df_hz)
        TF_FAIL("thermfit: peak at %g Hz is narrower (%g Hz) than 2 bins of %g Hz: not resolved "
                "(longer segments) or not a resonance",
                p[0], p[0] / p[1], df_hz);

    /* Statistical errors: covariance = scatter^2 * bin correlation * (J' W J)^-1. */
    double a[TF_NP][TF_NP], g[TF_NP], s2 = 0;
    tf_normal(&dt, p, a, g);
    tf_sweep sw;
    tf_sweep_init(&sw, &dt, p);
    for (long i = dt.i0; i <= dt.i1; i++) {
        double r = psd[i] / tf_sweep_eval(&sw, i, NULL) - 1.0;
        s2 += r * r;
    }
    long nb = dt.i1 - dt.i0 + 1;
    s2 /= (double)(nb > TF_NP ? nb - TF_NP : 1);
    double se[TF_NP];
    for (int j = 0; j < TF_NP; j++) { /* diagonal of the inverse, column by column */
        double e[TF_NP] = {0}, col[TF_NP];
        e[j] = 1;
        se[j] = tf_solve((const double(*)[TF_NP])a, e, 0.0, col) == 0
                    ? sqrt(fmax(col[j], 0) * s2 * TF_BIN_CORR)
                    : NAN;
    }
    afm_thermfit r = {
        .f_hz = p[0],
        .q = p[1],
        .k_n_m = p[2],
        .floor_m2_hz = p[3],
        .se_f_hz = se[0],
        .se_q = se[1],
        .se_k_n_m = se[2],
        .se_floor_m2_hz = se[3],
        .fit_lo_hz = (double)dt.i0 * df_hz,
        .fit_hi_hz = (double)dt.i1 * df_hz,
        .n_bins = nb,
        .iterations = iters,
        .rel_scatter = sqrt(s2),
        .linewidth_bins = p[0] / p[1] / df_hz,
    };
    *out = r;
    return 0;
#undef TF_FAIL
}

/* ---- the whole tune ---- */

#define TUNE_BLOCK 65536L /* samples per afm_sim_run call */
static const double tf_two_pi = 6.283185307179586476925286766559;

void afm_thermfit_tune_config(afm_config *c) {
    c->thermal.enabled = true;
    for (int j = 0; j < c->drive.n_tones; j++)
        c->drive.tones[j].amplitude_m = 0;
    c->drive.separation_m = 1e-3;
    c->forces.vdw_contact = false;
    c->forces.viscoelastic = false;
    c->forces.squeeze = AFM_SQUEEZE_NONE;
    c->forces.capillary = false;
    c->forces.electrostatic = false;
}

int afm_thermfit_tune(const afm_config *cfg_in, double seconds, long seg_len, bool obd,
                      int max_modes, afm_thermfit_tune_result *out, double **psd_out, char *err,
                      size_t errlen) {
    afm_config *cfg = malloc(sizeof *cfg);
    afm_modal *m = malloc(sizeof *m);
    afm_obd *ob = malloc(sizeof *ob);
    afm_thermfit_tune_result *res = calloc(1, sizeof *res);
    afm_sample *buf = malloc(TUNE_BLOCK * sizeof *buf);
    double *x = malloc(TUNE_BLOCK * sizeof *x), *psd = NULL;
    afm_psd *p = NULL;
    afm_sim *s = NULL;
    int rc = -1;
    if (!cfg || !m || !ob || !res || !buf || !x) {
        snprintf(err, errlen, "thermal tune: out of memory");
        goto done;
    }
    *cfg = *cfg_in;
    afm_thermfit_tune_config(cfg);
    if (afm_config_validate(cfg, err, errlen) != 0) goto done;
    const double fs = cfg->sim.sample_rate_hz;
    if (!(seconds > 0) || !isfinite(seconds) || seconds * fs > 1e12) {
        snprintf(err, errlen, "thermal tune: %g s is not a usable run length", seconds);
        goto done;
    }
    long nsamp = (long)floor(seconds * fs + 0.5);
    if (seg_len < 16 || seg_len % 2 || seg_len > nsamp) {
        snprintf(err, errlen,
                 "thermal tune: segment of %ld samples must be even, >= 16 and no longer "
                 "than the run (%ld samples)",
                 seg_len, nsamp);
        goto done;
    }
    if (max_modes < 1) {
        snprintf(err, errlen, "thermal tune: at least one mode must be asked for");
        goto done;
    }
    if (!(s = afm_twin_create(cfg, m, NULL, err, errlen))) goto done;
    if (afm_sim_set_thermal(s, &cfg->thermal, err, errlen) != AFM_SIM_OK) goto done;
    if (obd && afm_obd_init(ob, cfg, m, err, errlen) != 0) goto done;
    if (!(p = afm_psd_create(seg_len, fs, err, errlen))) goto done;
    if (!(psd = malloc((size_t)afm_psd_n_bins(p) * sizeof *psd))) {
        snprintf(err, errlen, "thermal tune: out of memory");
        goto done;
    }
    afm_rng rng;
    afm_rng_seed(&rng, (uint64_t)cfg->thermal.seed ^ 0x7468726dULL);
    double q[AFM_MAX_MODES], qd[AFM_MAX_MODES], kt = AFM_KB_J_K * cfg->thermal.temperature_k;
    for (int i = 0; i < m->n; i++) {
        q[i] = sqrt(kt) / m->omega_rad_s[i] * afm_rng_normal(&rng);
        qd[i] = sqrt(kt) * afm_rng_normal(&rng);
    }
    afm_sim_set_state(s, q, qd);
    clock_t t0 = clock();
    for (long done = 0; done < nsamp;) {
        int n = (int)(nsamp - done < TUNE_BLOCK ? nsamp - done : TUNE_BLOCK);
        int r = afm_sim_run(s, n, buf);
        if (r != AFM_SIM_OK) {
            snprintf(err, errlen, "thermal tune: simulation failed at t = %g s (code %d)",
                     afm_sim_time(s), r);
            goto done;
        }
        for (int i = 0; i < n; i++) {
            int32_t counts;
            x[i] = obd ? afm_obd_read(ob, &buf[i], &counts) : buf[i].x_m;
        }
        if (afm_psd_push(p, x, n) < 0) {
            snprintf(err, errlen, "thermal tune: non-finite signal near t = %g s", afm_sim_time(s));
            goto done;
        }
        done += n;
    }
    res->cpu_s = (double)(clock() - t0) / CLOCKS_PER_SEC;
    afm_psd_get(p, psd);
    res->n_samples = nsamp;
    res->seg_len = seg_len;
    res->segments = afm_psd_segments(p);
    res->df_hz = afm_psd_df_hz(p);
    const double nyq = fs / 2;
    size_t used = 0;
    for (int i = 0; i < m->n && res->n_modes < max_modes; i++) {
        double fn = m->omega_rad_s[i] / tf_two_pi;
        if (fn >= nyq) break;
        double lo = i > 0 ? sqrt(fn * m->omega_rad_s[i - 1] / tf_two_pi) : fn / 2;
        double hi = i + 1 < m->n ? fmin(sqrt(fn * m->omega_rad_s[i + 1] / tf_two_pi), nyq) : nyq;
        afm_thermfit_mode_result *r = &res->modes[res->n_modes];
        char e[AFM_ERR_LEN];
        r->n = i + 1;
        r->model_f_hz = fn;
        r->model_q = 1 / (2 * m->xi[i]);
        r->gain = obd ? afm_obd_mode_gain(ob, m, i) : 1.0;
        r->model_k_n_m =
            m->omega_rad_s[i] * m->omega_rad_s[i] / (m->tip[i] * m->tip[i]) / (r->gain * r->gain);
        if (afm_thermfit_mode(psd, afm_psd_n_bins(p), res->df_hz, fs, cfg->thermal.temperature_k,
                              lo, hi, 0, &r->fit, e, sizeof e) == 0) {
            res->n_modes++;
        } else if (used < sizeof res->skipped) {
            int w = snprintf(res->skipped + used, sizeof res->skipped - used, "%smode %d: %s",
                             used ? "; " : "", i + 1, e);
            used += w > 0 ? (size_t)w : 0;
        }
    }
    *out = *res;
    if (psd_out) {
        *psd_out = psd;
        psd = NULL;
    }
    rc = 0;
done:
    afm_psd_destroy(&p);
    afm_sim_destroy(&s);
    free(cfg);
    free(m);
    free(ob);
    free(res);
    free(buf);
    free(x);
    free(psd);
    return rc;
}
