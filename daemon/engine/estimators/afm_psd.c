/* SPDX-License-Identifier: MIT */
/* afm_psd.c -- streaming Welch PSD (Hann, 50 % overlap, one-sided) on FFTW3: afm_psd.h. */
#include "estimators/afm_psd.h"
#include "config/afm_err.h"

#include <fftw3.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PSD_MIN_SEG 16L
#define PSD_MAX_SEG (1L << 28)

struct afm_psd {
    long n, half, nb; /* segment length N, hop N/2, bins N/2 + 1 */
    double fs_hz;
    double scale; /* 1 / (fs sum w^2) */
    double *buf;  /* the segment being filled: fill samples so far */
    long fill;
    double *win;       /* periodic Hann */
    double *in;        /* fftw_malloc: windowed segment */
    fftw_complex *out; /* fftw_malloc: N/2 + 1 */
    fftw_plan plan;
    double *sum; /* sum over segments of |X_k|^2 */
    long segments;
};

afm_psd *afm_psd_create(long n_seg, double sample_rate_hz, char *err, size_t errlen) {
    if (n_seg < PSD_MIN_SEG || n_seg > PSD_MAX_SEG || n_seg % 2) {
        if (err && errlen)
            snprintf(err, errlen, "psd: segment length %ld must be even and in [%ld, %ld]", n_seg,
                     PSD_MIN_SEG, PSD_MAX_SEG);
        return NULL;
    }
    if (!(sample_rate_hz > 0) || !isfinite(sample_rate_hz)) {
        afm_err_set(err, errlen, "psd: sample rate must be finite and > 0");
        return NULL;
    }
    afm_psd *p = calloc(1, sizeof *p);
    if (!p) goto nomem;
    p->n = n_seg;
    p->half = n_seg / 2;
    p->nb = n_seg / 2 + 1;
    p->fs_hz = sample_rate_hz;
    p->buf = malloc((size_t)n_seg * sizeof *p->buf);
    p->win = malloc((size_t)n_seg * sizeof *p->win);
    p->sum = calloc((size_t)p->nb, sizeof *p->sum);
    p->in = fftw_malloc((size_t)n_seg * sizeof *p->in);
    p->out = fftw_malloc((size_t)p->nb * sizeof *p->out);
    if (!p->buf || !p->win || !p->sum || !p->in || !p->out) goto nomem;
    /* FFTW_ESTIMATE: no trial transforms, so create is fast and leaves in/out alone. */
    p->plan = fftw_plan_dft_r2c_1d((int)n_seg, p->in, p->out, FFTW_ESTIMATE);
    if (!p->plan) goto nomem;
    double s2 = 0;
    const double two_pi = 6.283185307179586476925286766559;
    for (long j = 0; j < n_seg; j++) {
        double w = 0.5 * (1.0 - cos(two_pi * (double)j / (double)n_seg));
        p->win[j] = w;
        s2 += w * w;
    }
    p->scale = 1.0 / (sample_rate_hz * s2);
    return p;
nomem:
    afm_err_set(err, errlen, "psd: out of memory");
    afm_psd_destroy(&p);
    return NULL;
}

void afm_psd_destroy(afm_psd **pp) {
    if (!pp || !*pp) return;
    afm_psd *p = *pp;
    if (p->plan) fftw_destroy_plan(p->plan);
    fftw_free(p->in);
    fftw_free(p->out);
    free(p->buf);
    free(p->win);
    free(p->sum);
    free(p);
    *pp = NULL;
}

/* Window, transform and accumulate the full segment in buf. */
static void psd_segment(afm_psd *p) {
    double mean = 0;
    for (long j = 0; j < p->n; j++)
        mean += p->buf[j];
    mean /= (double)p->n;
    for (long j = 0; j < p->n; j++)
        p->in[j] = (p->buf[j] - mean) * p->win[j];
    fftw_execute(p->plan);
    for (long k = 0; k < p->nb; k++) {
        double re = p->out[k][0], im = p->out[k][1];
        p->sum[k] += re * re + im * im;
    }
    p->segments++;
}

long afm_psd_push(afm_psd *p, const double *x, long n) {
    if (!p || n < 0 || (n > 0 && !x)) return -1;
    for (long i = 0; i < n; i++)
        if (!isfinite(x[i])) return -1;
    long done = 0;
    while (n > 0) {
        long take = p->n - p->fill < n ? p->n - p->fill : n;
        memcpy(p->buf + p->fill, x, (size_t)take * sizeof *x);
        p->fill += take;
        x += take;
        n -= take;
        if (p->fill == p->n) {
            psd_segment(p);
            done++;
            /* 50 % overlap: the second half starts the next segment. */
            memmove(p->buf, p->buf + p->half, (size_t)p->half * sizeof *p->buf);
            p->fill = p->half;
        }
    }
    return done;
}

void afm_psd_reset(afm_psd *p) {
    if (!p) return;
    p->fill = 0;
    p->segments = 0;
    memset(p->sum, 0, (size_t)p->nb * sizeof *p->sum);
}

long afm_psd_segments(const afm_psd *p) {
    return p->segments;
}
long afm_psd_n_bins(const afm_psd *p) {
    return p->nb;
}
long afm_psd_seg_len(const afm_psd *p) {
    return p->n;
}
double afm_psd_df_hz(const afm_psd *p) {
    return p->fs_hz / (double)p->n;
}
double afm_psd_sample_rate_hz(const afm_psd *p) {
    return p->fs_hz;
}

int afm_psd_get(const afm_psd *p, double *out) {
    if (!p || !out || p->segments == 0) return -1;
    double c = p->scale / (double)p->segments;
    for (long k = 0; k < p->nb; k++) {
        double ck = (k == 0 || k == p->nb - 1) ? c : 2.0 * c;
        out[k] = ck * p->sum[k];
    }
    return 0;
}
