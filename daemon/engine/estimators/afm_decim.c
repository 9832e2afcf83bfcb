/* SPDX-License-Identifier: MIT */
/* afm_decim.c -- multi-stage polyphase FIR decimator (contract in afm_decim.h). */
#include "estimators/afm_decim.h"

#include "config/afm_clones.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double pi = 3.14159265358979323846;

/* One frame of all channels: a 256-bit vector (GNU vector extension, gcc and clang), so a
 * tap is one multiply-add for every channel. */
typedef double v4 __attribute__((vector_size(32)));
#if !defined(__AVX__) && defined(__GNUC__) && !defined(__clang__)
/* Without AVX, gcc warns that passing v4 by value has another ABI; every such function here
 * is static, so no other object file sees that ABI. */
#pragma GCC diagnostic ignored "-Wpsabi"
#endif
_Static_assert(AFM_DECIM_CH == 4, "one v4 per frame");

#define DESIGN_DB 86.0  /* Kaiser design attenuation */
#define CHECK_DB 81.0   /* each stage must meet this over its whole stopband... */
#define RIPPLE_DB 0.004 /* ...and this over the kept band (4 stages stay < 0.01 dB) */
#define MAX_TAPS 20000  /* per stage */

typedef struct {
    int r, n, phase; /* factor, taps, inputs since the last output */
    int cap;         /* input frames per pass (at most) */
    int len, pos;    /* lin holds len frames; the window history starts at pos */
    int hb;          /* halfband (r = 2, n = 4 np - 1, taps at even offsets from the centre 0) */
    int np;          /* taps pairs the kernel sums (halfband: the nonzero ones) */
    double *h;       /* taps */
    v4 *g;           /* kernel coefficients broadcast to all channels: g[q] multiplies pair q
                        (halfband: taps c -+ (2 q + 1), else q and n - 1 - q), g[np] the
                        centre tap (0 for even n) */
    v4 *lin;         /* at pos: the n - 1 previous frames, then this pass's input (the
                        window slides on; the history moves back to 0 when a pass would not
                        fit: one move of n - 1 frames per max(cap, 2 (n - 1)) inputs) */
} stage;

/* Input frames per pass of the first stage (any n is split into passes of this size). */
#define PASS 512

struct afm_decim {
    int factor, n_st;
    double delay, cost;
    long long nonfinite;
    v4 *pass; /* factor 1: the input buffer of afm_decim_in */
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

/* Kaiser window w(r) for r in [-1, 1], shape beta, i0b = I0(beta). */
static double kaiser(double beta, double i0b, double r) {
    return bessel_i0(beta * sqrt(fmax(0.0, 1.0 - r * r))) / i0b;
}

/* Halfband taps, n = 4 np - 1: centre 1/2, zeros at even offsets, the odd ones a Kaiser
 * (beta) windowed sinc at a quarter of the rate scaled to sum 1/2 (unit gain at DC, and
 * H(f) + H(1/2 - f) = 1 exactly). */
static void halfband_taps(double *h, int n, double beta) {
    int c = (n - 1) / 2;
    double i0b = bessel_i0(beta), sum = 0;
    for (int k = 0; k < n; k++) {
        int t = k - c, a = t < 0 ? -t : t;
        h[k] = 0.0;
        if (a % 2 == 0) continue;
        h[k] = ((a / 2) % 2 ? -1.0 : 1.0) / (pi * a) * kaiser(beta, i0b, (double)t / c);
        sum += h[k];
    }
    for (int k = 0; k < n; k++)
        h[k] *= 0.5 / sum;
    h[c] = 0.5;
}

/* The maximally flat halfband of n = 4 np - 1 taps (the Lagrange interpolator of the
 * midpoint from the 2 np odd neighbours, halved): a zero of order 2 np at 1/2 and a flat
 * passband, shorter than a windowed sinc where the transition band is wide. */
static void lagrange_taps(double *h, int n) {
    int c = (n - 1) / 2, np = (n + 1) / 4;
    for (int k = 0; k < n; k++)
        h[k] = 0.0;
    for (int j = 0; j < np; j++) { /* node x_j = 2 j + 1 and its mirror -x_j */
        double xj = 2 * j + 1, w = 1.0;
        for (int m = 0; m < np; m++) { /* product over the other 2 np - 1 nodes +-x_m */
            double xm = 2 * m + 1;
            if (m != j) w *= (xm * xm) / (xm * xm - xj * xj); /* (0 - x)(0 + x) pairs */
        }
        w *= 0.5; /* the mirror node -x_j: (0 + x_j) / (x_j + x_j) */
        h[c - (2 * j + 1)] = h[c + (2 * j + 1)] = 0.5 * w;
    }
    h[c] = 0.5;
}

/* Halfband stage for edges fp and 1/2 - fp: the shortest n = 4 np - 1 for which the
 * maximally flat design or some window shape (Kaiser beta of 80 to 100 dB) meets the spec,
 * searched from a little below the Kaiser estimate. 0, or -1 when none up to MAX_TAPS does. */
static int design_halfband(stage *s, double fp) {
    double fs = 0.5 - fp;
    int est = kaiser_taps(fp, fs), np = (int)(0.7 * est + 1) / 4;
    if (np < 1) np = 1;
    for (; 4 * np - 1 <= MAX_TAPS; np++) {
        int n = 4 * np - 1;
        double *h = malloc((size_t)n * sizeof *h);
        if (!h) return -1;
        for (int v = -1; v <= 20; v++) { /* maximally flat, then Kaiser for 80 .. 100 dB */
            if (v < 0)
                lagrange_taps(h, n);
            else
                halfband_taps(h, n, 0.1102 * (80.0 + v - 8.7));
            if (meets_spec(h, n, fp, fs)) {
                s->h = h;
                s->n = n;
                s->hb = 1;
                s->np = np;
                return 0;
            }
        }
        free(h);
        if (n > 4 * est) break; /* the estimate is never this far off: give up */
    }
    return -1;
}

/* Design stage taps for edges fp < fs (cycles per stage input sample). */
static int design(stage *s, double fp, double fs, char *err, size_t errlen) {
    if (s->r == 2 && design_halfband(s, fp) == 0) return 0;
    int n = kaiser_taps(fp, fs);
    for (int tries = 0; tries < 30 && n <= MAX_TAPS; tries++) {
        s->h = malloc((size_t)n * sizeof *s->h);
        if (!s->h) break;
        kaiser_sinc(s->h, n, 0.5 * (fp + fs));
        if (meets_spec(s->h, n, fp, fs)) {
            s->n = n;
            s->hb = 0;
            s->np = n / 2;
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

/* Instructions per output of a stage of n taps and factor r (the kernels below): a
 * halfband sums about 2.5 per nonzero pair, a general stage 3 per pair, plus the output's
 * own overhead. */
static double stage_cost(int n, int r) {
    if (r == 2) {
        int np = (n + 4) / 4; /* n rounded up to 4 np - 1 */
        return 2.5 * np + 4.5;
    }
    return 1.5 * n + 8.0;
}

/* Cheapest split of the remaining factor rem (stages after a product prev): instructions
 * per input sample. fp in input cycles/sample. */
static double best_split(int rem, int prev, double fp, int depth, int *fac, int *nfac) {
    double best = INFINITY;
    int tmp[AFM_DECIM_MAX_STAGES], ntmp;
    for (int d = 2; d <= rem; d++) {
        if (rem % d) continue;
        if (d != rem && depth + 1 >= AFM_DECIM_MAX_STAGES) continue;
        double fin = 1.0 / prev; /* stage input rate */
        double fpn = fp / fin, fsn = 1.0 / d - fpn;
        double c = stage_cost(kaiser_taps(fpn, fsn), d) / d / prev;
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
    if (factor == 1) {
        d->pass = aligned_alloc(32, PASS * sizeof *d->pass);
        if (!d->pass) goto oom;
        return d;
    }
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
        s->len = s->n - 1 + s->cap + (s->cap > 2 * (s->n - 1) ? s->cap : 2 * (s->n - 1));
        s->lin = aligned_alloc(32, (size_t)s->len * sizeof *s->lin);
        s->g = aligned_alloc(32, ((size_t)s->np + 1) * sizeof *s->g);
        if (!s->lin || !s->g) goto oom;
        int c = (s->n - 1) / 2;
        for (int q = 0; q < s->np; q++) {
            double h = s->hb ? s->h[c - 1 - 2 * q] : s->h[q];
            s->g[q] = (v4){h, h, h, h};
        }
        double hc = s->n % 2 ? s->h[c] : 0.0;
        s->g[s->np] = (v4){hc, hc, hc, hc};
        d->delay += 0.5 * (s->n - 1) * prev;
        d->cost += (double)(s->hb ? 2 * s->np + 1 : s->n) / s->r / prev;
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
        free(d->st[i].g);
        free(d->st[i].lin);
    }
    free(d->pass);
    free(d);
    *dp = NULL;
}

/* ------------------------------------------------------------------ run */

static void clear_lines(afm_decim *d) {
    for (int i = 0; i < d->n_st; i++)
        if (d->st[i].lin)
            memset(d->st[i].lin + d->st[i].pos, 0, ((size_t)d->st[i].n - 1) * sizeof(v4));
}

void afm_decim_reset(afm_decim *d) {
    for (int i = 0; i < d->n_st; i++)
        d->st[i].phase = d->st[i].pos = 0;
    clear_lines(d);
}

/* Where stage g's next input (up to cap frames) goes, after moving the history back to the
 * start of lin if they would not fit. */
static v4 *stage_in(stage *g) {
    if (g->pos + g->n - 1 + g->cap > g->len) {
        memmove(g->lin, g->lin + g->pos, ((size_t)g->n - 1) * sizeof(v4));
        g->pos = 0;
    }
    return g->lin + g->pos + (g->n - 1);
}

/* acc + h w, one rounding per lane (__builtin_fma: one vfmadd where the target has FMA,
 * as in the x86-64-v3 copies of a portable build's multiversioned functions, libm's fma
 * otherwise): every build sums the same bits. Macros, not functions taking vectors by
 * value: clang refuses those between functions of different targets (AFM_CLONES). */
#if defined(__AVX__) && defined(__FMA__)
#include <immintrin.h>
#define MADD(h, w, acc) ((v4)_mm256_fmadd_pd((h), (w), (acc)))
#else
#define MADD(h, w, acc)                                                                            \
    __extension__({                                                                                \
        v4 h_ = (h), w_ = (w), a_ = (acc);                                                         \
        (v4){__builtin_fma(h_[0], w_[0], a_[0]), __builtin_fma(h_[1], w_[1], a_[1]),               \
             __builtin_fma(h_[2], w_[2], a_[2]), __builtin_fma(h_[3], w_[3], a_[3])};              \
    })
#endif

/* Frame k of dst = y. */
#define PUT(dst, k, y)                                                                             \
    do {                                                                                           \
        v4 y_ = (y);                                                                               \
        memcpy((dst) + (size_t)(k)*AFM_DECIM_CH, &y_, sizeof y_);                                  \
    } while (0)

/* One halfband output over the window w (n = 4 np - 1 frames, oldest first): the centre
 * term, then the pairs q = 0, 1, ... (the order every halfband output is summed in). */
static inline void hb_one(const v4 *w, const v4 *g, int np, double *dst, int k) {
    v4 a = g[np] * w[2 * np - 1];
#pragma GCC unroll 16
    for (int q = 0; q < np; q++)
        a = MADD(g[q], w[2 * np - 2 - 2 * q] + w[2 * np + 2 * q], a);
    PUT(dst, k, a);
}

/* Halfband outputs at window starts j, j + 2, ... < m of the frames lin (coefficients gq)
 * into dst, np a constant after inlining (fully unrolled: every frame offset a constant).
 * Four outputs at a time share their loads: pair q of output u adds frames
 * 2 (np - 1 - q + u) and 2 (np + q + u) of the first window. Every output is summed exactly
 * as hb_one sums it. Returns the outputs written. */
static inline __attribute__((always_inline)) int hb_run_np(const v4 *restrict lin, int j, int m,
                                                           double *restrict dst,
                                                           const v4 *restrict gq, const int np) {
    const v4 hc = gq[np];
    int k = 0;
    for (; j + 6 < m; j += 8, k += 4) {
        const v4 *w = lin + j;
        v4 a0 = hc * w[2 * np - 1], a1 = hc * w[2 * np + 1], a2 = hc * w[2 * np + 3],
           a3 = hc * w[2 * np + 5];
#pragma GCC unroll 32
        for (int q = 0; q < np; q++) {
            v4 c = gq[q];
            a0 = MADD(c, w[2 * (np - 1 - q)] + w[2 * (np + q)], a0);
            a1 = MADD(c, w[2 * (np - q)] + w[2 * (np + q + 1)], a1);
            a2 = MADD(c, w[2 * (np + 1 - q)] + w[2 * (np + q + 2)], a2);
            a3 = MADD(c, w[2 * (np + 2 - q)] + w[2 * (np + q + 3)], a3);
        }
        PUT(dst, k, a0);
        PUT(dst, k + 1, a1);
        PUT(dst, k + 2, a2);
        PUT(dst, k + 3, a3);
    }
    for (; j < m; j += 2)
        hb_one(lin + j, gq, np, dst, k++);
    return k;
}

/* hb_run_np for the stage's np: specialised up to 16 pairs (63 taps), a loop beyond. */
AFM_CLONES static int hb_run(const stage *g, int j, int m, double *dst) {
    const v4 *lin = g->lin + g->pos, *gq = g->g;
    switch (g->np) {
#define HB_CASE(P)                                                                                 \
    case P:                                                                                        \
        return hb_run_np(lin, j, m, dst, gq, P);
        HB_CASE(1)
        HB_CASE(2)
        HB_CASE(3)
        HB_CASE(4)
        HB_CASE(5)
        HB_CASE(6)
        HB_CASE(7)
        HB_CASE(8)
        HB_CASE(9)
        HB_CASE(10)
        HB_CASE(11)
        HB_CASE(12)
        HB_CASE(13)
        HB_CASE(14)
        HB_CASE(15)
        HB_CASE(16)
#undef HB_CASE
    default: {
        int k = 0;
        for (; j < m; j += 2)
            hb_one(lin + j, gq, g->np, dst, k++);
        return k;
    }
    }
}

/* General symmetric outputs at window starts j, j + r, ... < m: pairs q and n - 1 - q
 * summed first, four accumulators over q mod 4, then the centre tap for odd n. */
AFM_CLONES static int sym_run(const stage *g, int j, int m, double *restrict dst) {
    const int n = g->n, np = g->np, r = g->r;
    const v4 *restrict gq = g->g, *restrict lin = g->lin + g->pos;
    int k = 0;
    for (; j < m; j += r) {
        const v4 *w = lin + j;
        v4 a0 = {0}, a1 = {0}, a2 = {0}, a3 = {0};
        int q = 0;
        for (; q + 4 <= np; q += 4) {
            a0 = MADD(gq[q], w[q] + w[n - 1 - q], a0);
            a1 = MADD(gq[q + 1], w[q + 1] + w[n - 2 - q], a1);
            a2 = MADD(gq[q + 2], w[q + 2] + w[n - 3 - q], a2);
            a3 = MADD(gq[q + 3], w[q + 3] + w[n - 4 - q], a3);
        }
        for (; q < np; q++)
            a0 = MADD(gq[q], w[q] + w[n - 1 - q], a0);
        v4 y = (a0 + a1) + (a2 + a3);
        if (n % 2) y = MADD(gq[np], w[np], y);
        PUT(dst, k++, y);
    }
    return k;
}

/* Stage i has m new frames after its history in lin: compute its outputs (into the next
 * stage's input, or out), slide the window on by m (the newest n - 1 frames are the
 * history). Returns frames written to out. */
static int run_stages(afm_decim *d, int i, int m, double *out) {
    int written = 0;
    for (; i < d->n_st; i++) {
        stage *g = &d->st[i];
        int last = i + 1 == d->n_st;
        double *dst =
            last ? out + (size_t)written * AFM_DECIM_CH : (double *)stage_in(&d->st[i + 1]);
        /* output when the input at index j completes r inputs; its window starts at j */
        int j = g->r - g->phase - 1;
        int k = g->hb ? hb_run(g, j, m, dst) : sym_run(g, j, m, dst);
        g->phase = (g->phase + m) % g->r;
        g->pos += m;
        if (last) written += k;
        if (last || k == 0) break;
        m = k;
    }
    return written;
}

/* Index of the first frame of f[0 .. n-1] with a non-finite channel, n if none. */
AFM_CLONES static int first_nonfinite(const v4 *f, int n) {
    v4 z0 = {0}, z1 = {0}, zero = {0};
    int k = 0;
    for (; k + 2 <= n; k += 2) { /* x 0 is 0 for finite x, NaN for inf and NaN */
        z0 = MADD(f[k], zero, z0);
        z1 = MADD(f[k + 1], zero, z1);
    }
    if (k < n) z0 = MADD(f[k], zero, z0);
    z0 += z1;
    if ((z0[0] + z0[1]) + (z0[2] + z0[3]) == 0.0) return n;
    for (k = 0; k < n; k++) {
        v4 x = f[k] * 0.0;
        if ((x[0] + x[1]) + (x[2] + x[3]) != 0.0) break;
    }
    return k;
}

double *afm_decim_in(afm_decim *d, int *room) {
    if (room) *room = d->factor == 1 ? PASS : d->st[0].cap;
    return (double *)(d->factor == 1 ? d->pass : stage_in(&d->st[0]));
}

/* factor 1: in to out, non-finite frames zeroed and counted. */
static int pass_through(afm_decim *d, const double *in, int n, double *out) {
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

int afm_decim_commit(afm_decim *d, int n, int all_finite, double *out) {
    if (d->factor == 1) return pass_through(d, (const double *)d->pass, n, out);
    if (all_finite) return run_stages(d, 0, n, out);
    /* The frames stay where they were written: every run of the first stage slides its
     * window on by the frames it took, so the next input slot is always the next frame. */
    v4 *in = d->st[0].lin + d->st[0].pos + (d->st[0].n - 1);
    int written = 0;
    for (int i = 0; i < n;) {
        int k = i + first_nonfinite(in + i, n - i);
        if (k > i) written += run_stages(d, 0, k - i, out + (size_t)written * AFM_DECIM_CH);
        if (k == n) break;
        /* in[k] is not finite: clear every line, it enters as 0 */
        clear_lines(d);
        d->nonfinite++;
        in[k] = (v4){0};
        written += run_stages(d, 0, 1, out + (size_t)written * AFM_DECIM_CH);
        i = k + 1;
    }
    return written;
}

int afm_decim_run(afm_decim *d, const double *in, int n, double *out) {
    if (d->factor == 1) return pass_through(d, in, n, out);
    int m = 0;
    for (int i = 0; i < n;) {
        int room;
        double *dst = afm_decim_in(d, &room);
        int len = n - i < room ? n - i : room;
        memcpy(dst, in + (size_t)i * AFM_DECIM_CH, (size_t)len * AFM_DECIM_CH * sizeof *in);
        m += afm_decim_commit(d, len, 0, out + (size_t)m * AFM_DECIM_CH);
        i += len;
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
