/* SPDX-License-Identifier: MIT */
/* afm_decim.c -- multi-stage polyphase FIR decimator (contract in afm_decim.h). */
#include "afm_decim.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double pi = 3.14159265358979323846;

/* One frame of all channels: a 256-bit vector (GNU vector extension, gcc and clang), so a
 * tap is one multiply-add for every channel. */
typedef double v4 __attribute__((vector_size(32)));
_Static_assert(AFM_DECIM_CH == 4, "one v4 per frame");

#define DESIGN_DB 86.0  /* Kaiser design attenuation */
#define CHECK_DB 81.0   /* each stage must meet this over its whole stopband... */
#define RIPPLE_DB 0.004 /* ...and this over the kept band (4 stages stay < 0.01 dB) */
#define MAX_TAPS 20000  /* per stage */

typedef struct {
    int r, n, phase; /* factor, taps, inputs since the last output */
    int cap;         /* input frames per pass: lin holds n - 1 + cap frames */
    double *h;       /* taps */
    v4 *hv;          /* taps broadcast to all channels (one load per multiply-add) */
    v4 *lin;         /* the n - 1 previous frames, then this pass's input */
} stage;

/* Input frames per pass of the first stage (any n is split into passes of this size). */
#define PASS 512

struct afm_decim {
    int factor, n_st;
    double delay, cost;
    long long nonfinite;
    stage st[AFM_DECIM_MAX_STAGES];
};

/* ------------------------------------------------------------------ design */

static double bessel_i0(double x) {
    double sum = 1.0, term = 1.0, q = 0.25 * x * x;
    for (int k = 1; k < 500 && term > 1e-17 * sum; k++) {
        term *= q / ((double)k * k);
        sum += term;
    }
    return sum;
}

/* Taps for edges fp, fs (cycles per input sample) by the Kaiser estimate. */
static int kaiser_taps(double fp, double fs) {
    double n = ceil((DESIGN_DB - 7.95) / (14.36 * (fs - fp))) + 1.0;
    return n > MAX_TAPS ? MAX_TAPS + 1 : (int)n;
}

static void kaiser_sinc(double *h, int n, double fc) {
    double beta = 0.1102 * (DESIGN_DB - 8.7), c = 0.5 * (n - 1), i0b = bessel_i0(beta), sum = 0;
    for (int k = 0; k < n; k++) {
        double t = k - c, r = n > 1 ? t / c : 0.0;
        double s = t == 0 ? 2 * fc : sin(2 * pi * fc * t) / (pi * t);
        h[k] = s * bessel_i0(beta * sqrt(fmax(0.0, 1.0 - r * r))) / i0b;
        sum += h[k];
    }
    for (int k = 0; k < n; k++)
        h[k] /= sum; /* unit gain at DC */
}

/* Zero-phase response of symmetric taps at f (cycles per sample). */
static double response(const double *h, int n, double f) {
    double c = 0.5 * (n - 1), a = 0;
    for (int k = 0; k < n / 2; k++)
        a += 2 * h[k] * cos(2 * pi * f * (k - c));
    if (n % 2) a += h[n / 2];
    return a;
}

static int meets_spec(const double *h, int n, double fp, double fs) {
    double tol = pow(10.0, RIPPLE_DB / 20.0) - 1.0, stop = pow(10.0, -CHECK_DB / 20.0);
    for (int i = 0; i <= 64; i++)
        if (fabs(response(h, n, fp * i / 64.0) - 1.0) > tol) return 0;
    int m = (int)ceil((0.5 - fs) * 16.0 * n) + 1;
    for (int i = 0; i <= m; i++)
        if (fabs(response(h, n, fs + (0.5 - fs) * i / m)) > stop) return 0;
    return 1;
}

/* Design stage taps for edges fp < fs (cycles per stage input sample). */
static int design(stage *s, double fp, double fs, char *err, size_t errlen) {
    int n = kaiser_taps(fp, fs);
    for (int tries = 0; tries < 30 && n <= MAX_TAPS; tries++) {
        s->h = malloc((size_t)n * sizeof *s->h);
        if (!s->h) break;
        kaiser_sinc(s->h, n, 0.5 * (fp + fs));
        if (meets_spec(s->h, n, fp, fs)) {
            s->n = n;
            return 0;
        }
        free(s->h);
        s->h = NULL;
        n += n / 12 + 2;
    }
    if (err && errlen)
        snprintf(err, errlen,
                 "decimator: no FIR of at most %d taps meets the spec (band edges %g, %g)",
                 MAX_TAPS, fp, fs);
    return -1;
}

/* Cheapest split of the remaining factor rem (stages after a product prev): multiply-adds
 * per input sample, plus 1.5 for each stage's delay-line writes. fp in input cycles/sample. */
static double best_split(int rem, int prev, double fp, int depth, int *fac, int *nfac) {
    double best = INFINITY;
    int tmp[AFM_DECIM_MAX_STAGES], ntmp;
    for (int d = 2; d <= rem; d++) {
        if (rem % d) continue;
        if (d != rem && depth + 1 >= AFM_DECIM_MAX_STAGES) continue;
        double fin = 1.0 / prev; /* stage input rate */
        double fpn = fp / fin, fsn = 1.0 / d - fpn;
        int taps = kaiser_taps(fpn, fsn);
        double c = ((double)taps / d + 1.5) / prev;
        ntmp = 0;
        if (d != rem) c += best_split(rem / d, prev * d, fp, depth + 1, tmp, &ntmp);
        if (c < best) {
            best = c;
            fac[0] = d;
            memcpy(fac + 1, tmp, (size_t)ntmp * sizeof *tmp);
            *nfac = 1 + ntmp;
        }
    }
    return best;
}

afm_decim *afm_decim_create(int factor, double p, char *err, size_t errlen) {
    if (factor < 1 || factor > AFM_DECIM_MAX_FACTOR || !(p > 0 && p <= AFM_DECIM_MAX_PASSBAND)) {
        if (err && errlen)
            snprintf(err, errlen,
                     "decimator: factor must be in [1, %d] and passband fraction in (0, %g] "
                     "(got %d, %g)",
                     AFM_DECIM_MAX_FACTOR, AFM_DECIM_MAX_PASSBAND, factor, p);
        return NULL;
    }
    afm_decim *d = calloc(1, sizeof *d);
    if (!d) goto oom;
    d->factor = factor;
    if (factor == 1) return d;
    int fac[AFM_DECIM_MAX_STAGES], nfac = 0;
    double fp = 0.5 * p / factor; /* kept band edge, cycles per input sample */
    best_split(factor, 1, fp, 0, fac, &nfac);
    int prev = 1;
    for (int i = 0; i < nfac; i++) {
        stage *s = &d->st[i];
        double fin = 1.0 / prev, fpn = fp / fin;
        s->r = fac[i];
        if (design(s, fpn, 1.0 / s->r - fpn, err, errlen)) goto fail;
        d->n_st = i + 1;
        s->cap = i == 0 ? PASS : d->st[i - 1].cap / d->st[i - 1].r + 1;
        s->lin = aligned_alloc(32, ((size_t)s->n - 1 + (size_t)s->cap) * sizeof *s->lin);
        s->hv = aligned_alloc(32, (size_t)s->n * sizeof *s->hv);
        if (!s->lin || !s->hv) goto oom;
        for (int k = 0; k < s->n; k++)
            s->hv[k] = (v4){s->h[k], s->h[k], s->h[k], s->h[k]};
        d->delay += 0.5 * (s->n - 1) * prev;
        d->cost += (double)s->n / s->r / prev;
        prev *= s->r;
    }
    afm_decim_reset(d);
    return d;
oom:
    if (err && errlen) snprintf(err, errlen, "decimator: out of memory");
fail:
    afm_decim_destroy(&d);
    return NULL;
}

void afm_decim_destroy(afm_decim **dp) {
    if (!dp || !*dp) return;
    afm_decim *d = *dp;
    for (int i = 0; i < AFM_DECIM_MAX_STAGES; i++) {
        free(d->st[i].h);
        free(d->st[i].hv);
        free(d->st[i].lin);
    }
    free(d);
    *dp = NULL;
}

/* ------------------------------------------------------------------ run */

static void clear_lines(afm_decim *d) {
    for (int i = 0; i < d->n_st; i++)
        if (d->st[i].lin) memset(d->st[i].lin, 0, ((size_t)d->st[i].n - 1) * sizeof(v4));
}

void afm_decim_reset(afm_decim *d) {
    clear_lines(d);
    for (int i = 0; i < d->n_st; i++)
        d->st[i].phase = 0;
}

/* acc + h w, fused where the target has FMA (ISO C mode does not contract a * b + c). */
#if defined(__FMA__)
#include <immintrin.h>
static inline v4 madd(v4 h, v4 w, v4 acc) {
    return (v4)_mm256_fmadd_pd((__m256d)h, (__m256d)w, (__m256d)acc);
}
#else
static inline v4 madd(v4 h, v4 w, v4 acc) {
    return acc + h * w;
}
#endif

/* Dot product of the taps with the window of the n newest frames (oldest first). */
static inline v4 dot(const v4 *h, const v4 *w, int n) {
    v4 a0 = {0}, a1 = {0}, a2 = {0}, a3 = {0};
    int k = 0;
    for (; k + 4 <= n; k += 4) {
        a0 = madd(h[k], w[k], a0);
        a1 = madd(h[k + 1], w[k + 1], a1);
        a2 = madd(h[k + 2], w[k + 2], a2);
        a3 = madd(h[k + 3], w[k + 3], a3);
    }
    for (; k < n; k++)
        a0 = madd(h[k], w[k], a0);
    return (a0 + a1) + (a2 + a3);
}

/* Stage i has m new frames after its history in lin: compute its outputs (into the next
 * stage's input, or out), keep the newest n - 1 frames as history. Returns frames written
 * to out. */
static int run_stages(afm_decim *d, int i, int m, double *out) {
    int written = 0;
    for (; i < d->n_st; i++) {
        stage *g = &d->st[i];
        v4 *dst = i + 1 < d->n_st ? d->st[i + 1].lin + (d->st[i + 1].n - 1) : NULL;
        int k = 0;
        /* output when the input at index j completes r inputs; its window starts at j */
        for (int j = g->r - g->phase - 1; j < m; j += g->r) {
            v4 y = dot(g->hv, g->lin + j, g->n);
            if (dst)
                dst[k++] = y;
            else
                memcpy(out + (size_t)written++ * AFM_DECIM_CH, &y, sizeof y);
        }
        g->phase = (g->phase + m) % g->r;
        memmove(g->lin, g->lin + m, ((size_t)g->n - 1) * sizeof(v4));
        if (!dst || k == 0) break;
        m = k;
    }
    return written;
}

int afm_decim_run(afm_decim *d, const double *in, int n, double *out) {
    if (d->factor == 1) {
        if (out != in) memmove(out, in, (size_t)n * AFM_DECIM_CH * sizeof *in);
        for (int i = 0; i < n; i++) {
            double *f = out + (size_t)i * AFM_DECIM_CH;
            if (!(isfinite(f[0]) && isfinite(f[1]) && isfinite(f[2]) && isfinite(f[3]))) {
                f[0] = f[1] = f[2] = f[3] = 0.0;
                d->nonfinite++;
            }
        }
        return n;
    }
    int m = 0;
    stage *g0 = &d->st[0];
    for (int i = 0; i < n;) {
        /* copy a pass of finite frames behind the first stage's history; a non-finite
         * frame ends the pass (and is handled after it) */
        v4 *dst = g0->lin + (g0->n - 1);
        int len = n - i < g0->cap ? n - i : g0->cap, k = 0;
        v4 z = {0};
        for (; k < len; k++) {
            v4 x;
            memcpy(&x, in + (size_t)(i + k) * AFM_DECIM_CH, sizeof x);
            dst[k] = x;
            z += x * 0.0; /* NaN in a lane after inf or NaN input */
        }
        if ((z[0] + z[1]) + (z[2] + z[3]) != 0.0) { /* find the first bad frame */
            for (k = 0; k < len; k++) {
                v4 x = dst[k] * 0.0;
                if ((x[0] + x[1]) + (x[2] + x[3]) != 0.0) break;
            }
        }
        if (k > 0) m += run_stages(d, 0, k, out + (size_t)m * AFM_DECIM_CH);
        i += k;
        if (k < len) { /* in[i] is not finite: clear every line, it enters as 0 */
            clear_lines(d);
            d->nonfinite++;
            dst[0] = (v4){0};
            m += run_stages(d, 0, 1, out + (size_t)m * AFM_DECIM_CH);
            i++;
        }
    }
    return m;
}

/* ------------------------------------------------------------------ queries */

int afm_decim_factor(const afm_decim *d) {
    return d->factor;
}
double afm_decim_delay(const afm_decim *d) {
    return d->delay;
}
long long afm_decim_nonfinite(const afm_decim *d) {
    return d->nonfinite;
}
double afm_decim_cost(const afm_decim *d) {
    return d->cost;
}

int afm_decim_phase(const afm_decim *d) {
    int ph = 0, mul = 1;
    for (int i = 0; i < d->n_st; i++) {
        ph += d->st[i].phase * mul;
        mul *= d->st[i].r;
    }
    return ph;
}

int afm_decim_stages(const afm_decim *d, int *factors, int *taps) {
    for (int i = 0; i < d->n_st; i++) {
        if (factors) factors[i] = d->st[i].r;
        if (taps) taps[i] = d->st[i].n;
    }
    return d->n_st;
}
