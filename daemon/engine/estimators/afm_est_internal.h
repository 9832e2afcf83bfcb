/* SPDX-License-Identifier: MIT */
/* afm_est_internal.h -- small helpers shared by the estimators (afm_orbit, afm_harm,
 * afm_cycle, afm_lockin): cubic Hermite pieces in (x, v), contact-line crossings, the 3-point
 * peak, the thesis App. E.4 phase difference, the drive-phase tracker (period clock) with
 * its vectorised run check (afm_track_run), and 4-lane vector helpers (afm_v4). Internal:
 * not installed, not part of any contract. Only what the per-sample loops must inline is
 * here (static inline: each user gets its own copy); the tracker's slow path is in
 * afm_est_track.c, the helpers only afm_orbit uses (stationary points, eq. E.12-E.13) are
 * in afm_orbit.c. */
#ifndef AFM_EST_INTERNAL_H
#define AFM_EST_INTERNAL_H

#include "integrators/afm_sim.h"

#include <math.h>
#if defined(__SSE4_1__) || defined(__AVX__)
#include <immintrin.h>
#endif
#include <stdbool.h>

/* Slow paths of the estimators: kept out of line so that the per-sample fast path stays a
 * leaf function without a stack frame. */
#if defined(__GNUC__)
#define AFM_EST_COLD __attribute__((noinline, cold))
#else
#define AFM_EST_COLD
#endif

#define AFM_EST_PI 3.14159265358979323846264338327950
#define AFM_EST_TWO_PI 6.283185307179586476925286766559
#define AFM_EST_RAD2DEG 57.295779513082320876798154814105

/* Cubic Hermite on [t_j, t_j + h] from (x, v) at both ends: coefficients in s = (t-t_j)/h. */
typedef struct {
    double a, b, c, d;
} afm_cubic;

static inline afm_cubic afm_hermite(const afm_sample *s0, const afm_sample *s1, double h) {
    afm_cubic q;
    q.a = 2.0 * s0->x_m + h * s0->v_m_s - 2.0 * s1->x_m + h * s1->v_m_s;
    q.b = -3.0 * s0->x_m - 2.0 * h * s0->v_m_s + 3.0 * s1->x_m - h * s1->v_m_s;
    q.c = h * s0->v_m_s;
    q.d = s0->x_m;
    return q;
}

static inline double afm_cubic_at(const afm_cubic *q, double s) {
    return ((q->a * s + q->b) * s + q->c) * s + q->d;
}

static inline double afm_cubic_slope(const afm_cubic *q, double s) {
    return (3.0 * q->a * s + 2.0 * q->b) * s + q->c;
}

/* Crossing of x through xc inside [s0, s1] (x on opposite sides at the two samples, step h):
 * bisection on the Hermite cubic. *frac gets the position in the interval (0..1), *v the
 * velocity there (derivative of the cubic). */
static inline void afm_hermite_crossing(const afm_sample *s0, const afm_sample *s1, double h,
                                        double xc, double *frac, double *v) {
    afm_cubic q = afm_hermite(s0, s1, h);
    double lo = 0.0, hi = 1.0;
    double glo = q.d - xc;
    for (int it = 0; it < 200 && hi - lo > 1e-15; it++) {
        double mid = 0.5 * (lo + hi);
        double g = afm_cubic_at(&q, mid) - xc;
        if ((g >= 0) == (glo >= 0)) {
            lo = mid;
            glo = g;
        } else {
            hi = mid;
        }
    }
    double s = 0.5 * (lo + hi);
    *frac = s;
    *v = afm_cubic_slope(&q, s) / h;
}

/* Peak of a sampled maximum f0 by the parabola through (fm, f0, fp); f0 if it is not a
 * proper local maximum. */
static inline double afm_parabola_peak(double fm, double f0, double fp) {
    double den = fm - 2.0 * f0 + fp;
    if (!(den < 0) || fm > f0 || fp > f0) return f0;
    double delta = 0.5 * (fm - fp) / den;
    return f0 - 0.25 * (fm - fp) * delta;
}

/* floor(x), inline (one rounding instruction where SSE4.1 is there): the same value. */
static inline double afm_floor(double x) {
#if defined(__SSE4_1__)
    __m128d q = _mm_set_sd(x);
    return _mm_cvtsd_f64(_mm_round_sd(q, q, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC));
#else
    return floor(x);
#endif
}

/* theta mod 2 pi in [0, 2 pi), bit for bit fmod(theta, 2 pi) (+ 2 pi if negative) for
 * |theta| < 2^52: the remainder theta - m 2 pi is exactly representable, so the one
 * rounding of fma(-m, 2 pi, theta) is exact once m is right (corrected by one if the
 * quotient rounded across an integer). fmod itself costs ~150 instructions. */
static inline double afm_clock_wrap(double th) {
    if (!(fabs(th) < 0x1p52)) {
        double ph = fmod(th, AFM_EST_TWO_PI);
        return ph < 0 ? ph + AFM_EST_TWO_PI : ph;
    }
    double m = afm_floor(th * (1.0 / AFM_EST_TWO_PI));
    double ph = fma(-m, AFM_EST_TWO_PI, th);
    if (ph < 0) {
        ph = fma(-(m - 1.0), AFM_EST_TWO_PI, th);
    } else if (ph >= AFM_EST_TWO_PI) {
        ph = fma(-(m + 1.0), AFM_EST_TWO_PI, th);
    }
    return ph;
}

/* |(x, y)|: sqrt(x^2 + y^2) (within an ulp of hypot, a fraction of its cost) when the
 * squares neither overflow nor lose precision to underflow, hypot otherwise. */
static inline double afm_est_hypot(double x, double y) {
    double q = x * x + y * y;
    return q > 1e-290 && q < 1e290 ? sqrt(q) : hypot(x, y);
}

/* Drive-phase tracker for the streaming estimators (afm_harm, afm_cycle, afm_lockin): it
 * follows the phase theta of tone 0 supplied with every sample so that the estimators need
 * no transcendental function per sample.
 *
 * Fast path (afm_track_fast, a few flops): the tracker predicts theta_n = th_ref + n dphi
 * from the last resynchronisation (th_ref, exact) and a phase-step estimate dphi. The
 * sample takes the fast path when the supplied theta is within tol of the prediction
 * (tol = 2e-11 rad + 8 eps |theta| + the noise floor observed in theta, at most 1e-6 rad:
 * a few ulps of theta, or of omega t when t is large and theta small) and n <= n_end: for a clock,
 * the predicted theta mod 2 pi p_ref + n dphi stays more than 2 tol + 1e-12 below 2 pi (and dphi >
 * 4 tol + 1e-12 keeps it above 0). Then theta mod 2 pi = p_ref + (theta - th_ref) exactly, so no
 * period boundary lies in the step and the step is in (0, pi): the answer of the exact clock is
 * known without computing it, and an estimator's phasors rotated by e^{i dphi} since th_ref are
 * within tol (plus rounding) of e^{i theta}.
 *
 * Slow path (afm_track_check + afm_track_advance, one or two exact reductions mod 2 pi): the
 * first sample, the sample after each period boundary, a jump of theta (afm_drive re-wraps
 * its phase at a tone change, so the unwrapped theta jumps by 2 pi m; the step in which the
 * frequency changes), a drift of more than tol, and every 4096 (clock) or 1024 samples. It is
 * the exact drive-period clock: periods are the intervals between the instants where
 * theta is a multiple of 2 pi; only theta mod 2 pi is used; for a clock a step must advance
 * the phase by more than 0 and less than pi (tone 0 below half the sample rate). It then
 * resynchronises (th_ref = theta) and updates dphi: after a jump the next step's increment
 * (one sample of exact clock in between); otherwise the running average of the clean
 * intervals' increments, refined only when that moves the prediction over a run by more
 * than tol / 8 (so an estimator's per-step rotations are rarely recomputed). A non-clock
 * tracker (the lock-in) accepts any finite theta and never looks at theta mod 2 pi.
 *
 * Bounded cost (every dphi change makes the estimators rebuild their tables, ~1e4
 * instructions): a step off the rate by a whole number of turns (theta re-wrapped: afm_drive
 * at a tone change that keeps the frequency, the chain's phase origin moving) keeps the lock
 * and dphi; a step off the rate again within a window of the last lock is read as noise in
 * theta that tol did not cover (twice its size, at most 1e-6 rad, becomes the noise floor; the
 * lock and dphi stay) instead of a new rate each time. A theta computed as phi + w (t - t0) at a
 * large model time t carries w ulp(t) of rounding (4e-9 rad at t = 20 s and 338 kHz) however small
 * theta is; before this rule such a tracker unlocked and relocked every other sample, rebuilding
 * the tables each time (the daemon's real-time collapse of issue 12). The chain now computes theta
 * from the sample count, with only rounding relative to theta itself (afm_chain.c). */
typedef struct {
    bool clock;             /* period clock: monotone phase, boundaries (harm, cycle) */
    bool started;           /* a sample has been accepted since init/reset */
    bool locked;            /* dphi is known: the fast path may run */
    double th_prev;         /* theta of the last accepted sample, as supplied */
    double th_ref;          /* theta at the last resynchronisation */
    double p_ref;           /* th_ref mod 2 pi (clock), else 0 */
    double n;               /* steps since the resynchronisation */
    double dphi;            /* phase step, rad */
    double nb;              /* steps behind the dphi estimate (capped) */
    double tol;             /* |theta - th_ref - n dphi| allowed on the fast path; -1: none */
    double noise;           /* observed noise floor of theta (rad), see afm_track_advance */
    double n_end;           /* fast path for n <= n_end: for a clock, p_ref + n dphi stays more
                             * than 2 tol + 1e-12 below 2 pi; at most the window below */
    double age;             /* steps since the tracker last locked */
    long long rate_changes; /* times dphi took a new value (each an estimator table rebuild) */
} afm_phase_track;

/* Resynchronise at least every so many steps (rounding of the rotations; the rate estimate
 * must hold tol over the window): a clock also does at every boundary. */
#define AFM_TRACK_WINDOW_CLOCK 4096.0
#define AFM_TRACK_WINDOW_FREE 1024.0
#define AFM_TRACK_MAX_BASELINE 4096.0

#define AFM_CLOCK_BAD (-1) /* theta non-finite, or (clock) a phase step not in (0, pi) */
#define AFM_CLOCK_NONE 0   /* no boundary in (previous sample, this one] */
#define AFM_CLOCK_CROSS                                                                            \
    1                     /* boundary in (previous, this]: *frac in (0, 1] of the step             \
                           * lies before it */
#define AFM_CLOCK_START 2 /* first sample, exactly on a boundary */

/* The tracker's slow path (afm_est_track.c: once a period or window per estimator, out
 * of line). */
void afm_track_init(afm_phase_track *t, bool clock);

/* Slow path, part 1: check theta without changing anything: AFM_CLOCK_BAD or
 * AFM_CLOCK_NONE; *p gets theta mod 2 pi (clock; 0 otherwise). */
int afm_track_check(const afm_phase_track *t, double th, double *p);

/* Slow path, part 2: advance to theta (checked, p from afm_track_check) and resynchronise.
 * Returns AFM_CLOCK_NONE/CROSS/START (always NONE for a non-clock); *frac as for CROSS;
 * *rate_changed set when dphi took a new value (the caller's per-step rotation must be
 * recomputed from it; only meaningful while t->locked). */
int afm_track_advance(afm_phase_track *t, double th, double p, double *frac, bool *rate_changed);

/* Phase-continuous retune (issue 32: an NCO or a command moving tone 0's frequency, as often
 * as every sample): the caller knows that the rate changes to dphi after the last accepted
 * sample and that th is that sample's theta in the frame of the samples to come (the same
 * phase up to whole turns and rounding: |th - th_prev - 2 pi m| <= 1e-9 rad). The tracker
 * then takes dphi as its rate at once, locked, resynchronised at th (n = 0; a clock's p_ref
 * and n_end from th mod 2 pi), so that the next samples take the fast path instead of
 * reading the step as a jump (unlock, the exact clock, a new rate learnt from the next
 * increments) or, for a small change, as noise followed by a drift and a rate refined sample
 * after sample (one table rebuild each: the FM collapse). O(1). Counted in rate_changes
 * (the caller's per-step rotation must follow dphi). Returns false and changes nothing when
 * the tracker has no accepted sample, th or dphi is not finite, th is not th_prev's phase,
 * or (clock) dphi is not a valid step (in (4 tol, pi - 4 tol)): the caller then leaves the
 * change to the slow path, as before. */
bool afm_track_rebase(afm_phase_track *t, double th, double dphi);

/* afm_track_check then afm_track_advance for a clock tracker, in one: the same checks, result and
 * tracker state, with theta_prev reduced mod 2 pi once. AFM_CLOCK_BAD (nothing changed), else as
 * afm_track_advance (*frac for a boundary). */
int afm_track_step(afm_phase_track *t, double th, double *frac);

/* The fast path: true (and the tracker advanced) when theta is the predicted next phase;
 * false (nothing changed) otherwise, then call afm_track_check / afm_track_advance. */
static inline bool afm_track_fast(afm_phase_track *t, double th) {
    double n = t->n + 1.0;
    if (!(n <= t->n_end && fabs((th - t->th_ref) - n * t->dphi) <= t->tol)) return false;
    t->n = n;
    t->th_prev = th;
    return true;
}

/* Weights of the two samples of a step split at frac s (linear interpolant of the integrand,
 * integrated exactly; units of the step): the part before the split gets w_before[0] g_prev
 * + w_before[1] g_cur, the part after w_after[0] g_prev + w_after[1] g_cur. s = 1 leaves
 * the whole step before the split (plain trapezoid). */
static inline void afm_split_weights(double s, double w_before[2], double w_after[2]) {
    w_before[0] = s - 0.5 * s * s;
    w_before[1] = 0.5 * s * s;
    w_after[0] = 0.5 * (1.0 - s) * (1.0 - s);
    w_after[1] = 0.5 * (1.0 - s * s);
}

/* 4 doubles side by side (afm_harm's harmonic lanes, afm_lockin's filter stages): a GNU
 * vector (gcc and clang), so the same code is AVX registers in an x86-64-v3 build or in the
 * x86-64-v3 copy of a portable build's multiversioned functions (AFM_CLONES,
 * config/afm_clones.h), and pairs of SSE2 registers in the baseline copy. Every
 * operation rounds once per lane, AFM_V4_FMA included (__builtin_fma: one vfmadd where the
 * target has FMA, libm's fma otherwise), so every copy gives the same bits. The operations
 * are macros, not functions: clang refuses a vector passed by value between functions of
 * different targets (a multiversioned function and a plain inline helper). */
typedef double afm_v4 __attribute__((vector_size(32)));
typedef long long afm_v4i __attribute__((vector_size(32))); /* lane masks: 0 or -1 */
typedef double afm_v4u __attribute__((vector_size(32), aligned(8), may_alias));
#define AFM_V4_LD(p) ((afm_v4)(*(const afm_v4u *)(const void *)(p)))
#define AFM_V4_ST(p, a) (*(afm_v4u *)(void *)(p) = (a))
#define AFM_V4_SET1(x) ((afm_v4){(x), (x), (x), (x)})
#define AFM_V4_ADD(a, b) ((a) + (b))
#define AFM_V4_SUB(a, b) ((a) - (b))
#define AFM_V4_MUL(a, b) ((a) * (b))
/* a b + c, c - a b and a b - c, one rounding per lane (the arguments are read once per
 * lane: expressions without side effects, nested ones folded by the compiler) */
#if defined(__AVX__) && defined(__FMA__) /* an x86-64-v3 build: one vfmadd, certainly */
#define AFM_V4_FMA(a, b, c) ((afm_v4)_mm256_fmadd_pd((a), (b), (c)))
#else /* lane by lane: gcc and clang fold the four into one vfmadd in an x86-64-v3 clone */
#define AFM_V4_FMA(a, b, c)                                                                        \
    ((afm_v4){__builtin_fma((a)[0], (b)[0], (c)[0]), __builtin_fma((a)[1], (b)[1], (c)[1]),        \
              __builtin_fma((a)[2], (b)[2], (c)[2]), __builtin_fma((a)[3], (b)[3], (c)[3])})
#endif
#define AFM_V4_FNMA(a, b, c) AFM_V4_FMA(-(a), (b), (c))
#define AFM_V4_FMS(a, b, c) AFM_V4_FMA((a), (b), -(c))

/* Complex products on 4 lanes (re, im apart), rounded as (a + i b) (c + i d) =
 * fma(a, c, -(b d)) + i fma(a, d, b c): into the afm_v4 lvalues re, im. */
#define AFM_V4_CMUL(a, b, c, d, re, im)                                                            \
    do {                                                                                           \
        afm_v4 ca_ = (a), cb_ = (b), cc_ = (c), cd_ = (d);                                         \
        (re) = AFM_V4_FMS(ca_, cc_, cb_ * cd_);                                                    \
        (im) = AFM_V4_FMA(ca_, cd_, cb_ * cc_);                                                    \
    } while (0)

/* How many of th[0..nmax) take the tracker's fast path in a row (afm_track_fast's test,
 * (theta - th_ref) - n dphi within tol and n <= n_end, evaluated with the same roundings),
 * with a[i] and, if b is not NULL, b[i] finite. Nothing changes: the caller then advances
 * t->n by the count and sets t->th_prev. 16, then 8 samples per step (afm_v4 lanes). */
#if defined(__GNUC__)
#define AFM_EST_INLINE __attribute__((always_inline))
#else
#define AFM_EST_INLINE
#endif
/* |theta - prediction| <= tol on 4 lanes (a lane mask), false where a or (use_b) b is not
 * finite (a 0 is NaN then). The error as (th_ref - theta) + n dphi: exactly -((theta - th_ref)
 * - n dphi) (rounding to nearest is symmetric); without b nothing is added for it (the sign of
 * a zero error is all that could change, and the test does not see it). */
#define AFM_TRACK_OK4(th, a, b, nn, ref, dp, tol, use_b)                                           \
    __extension__({                                                                                \
        afm_v4 e_ = ((ref) - (th)) + (nn) * (dp);                                                  \
        e_ = e_ + (a)*0.0;                                                                         \
        if (use_b) e_ = e_ + (b)*0.0;                                                              \
        (afm_v4i)((e_ <= (tol)) & (e_ >= -(tol)));                                                 \
    })
/* Every lane of a lane mask set: two shuffles and ands, then lane 0 (lane by lane it moves
 * every lane to an integer register; issue 12). */
#define AFM_V4I_ALL(m)                                                                             \
    __extension__({                                                                                \
        afm_v4i a_ = (m)&__builtin_shufflevector((m), (m), 2, 3, 0, 1);                            \
        a_ = a_ & __builtin_shufflevector(a_, a_, 1, 0, 3, 2);                                     \
        a_[0] != 0;                                                                                \
    })
static inline AFM_EST_INLINE int afm_track_run_v4(const afm_phase_track *t, const double *th,
                                                  const double *a, const double *b, int nmax,
                                                  const bool use_b) {
    double room = t->n_end - t->n; /* integer-valued, as n */
    if (!(room >= 1.0) || nmax <= 0) return 0;
    int lim = room < (double)nmax ? (int)room : nmax;
    const afm_v4 ref = AFM_V4_SET1(t->th_ref), dp = AFM_V4_SET1(t->dphi);
    const afm_v4 tol = AFM_V4_SET1(t->tol), zero = AFM_V4_SET1(0.0);
    afm_v4 nn = AFM_V4_SET1(t->n) + (afm_v4){1.0, 2.0, 3.0, 4.0};
    int i = 0;
#define AFM_TRACK_OK4_AT(o) /* the 4 samples from i + o */                                         \
    AFM_TRACK_OK4(AFM_V4_LD(th + i + (o)), AFM_V4_LD(a + i + (o)),                                 \
                  use_b ? AFM_V4_LD(b + i + (o)) : zero, (o) ? nn + (double)(o) : nn, ref, dp,     \
                  tol, use_b)
    /* 16 samples a step (one test of the lanes for 16: issue 12), then 8 */
    for (; i + 16 <= lim; i += 16) {
        afm_v4i ok = (AFM_TRACK_OK4_AT(0) & AFM_TRACK_OK4_AT(4)) &
                     (AFM_TRACK_OK4_AT(8) & AFM_TRACK_OK4_AT(12));
        if (!AFM_V4I_ALL(ok)) break;
        nn = nn + 16.0;
    }
    for (; i + 8 <= lim; i += 8) {
        afm_v4i ok = AFM_TRACK_OK4_AT(0) & AFM_TRACK_OK4_AT(4);
        if (!AFM_V4I_ALL(ok)) break;
        nn = nn + 8.0;
    }
#undef AFM_TRACK_OK4_AT
    for (;; i += 4) { /* the rest, or the step of 8 that failed: 4 at a time */
        int left = lim - i;
        if (left <= 0) return lim;
        afm_v4 x, y, z = zero;
        /* 4 loads whenever the arrays (nmax long) have 4 more samples, even past lim: a lane
         * at or past lim never decides the count (issue 12: a clock's run ends at n_end, a
         * few samples before the caller's end, once a period; lane by lane cost ~20) */
        if (left >= 4 || nmax - i >= 4) {
            x = AFM_V4_LD(th + i);
            y = AFM_V4_LD(a + i);
            if (use_b) z = AFM_V4_LD(b + i);
        } else { /* the lanes past the end are 0 (their result is not used) */
            x = y = zero;
            for (int l = 0; l < left; l++) {
                x[l] = th[i + l];
                y[l] = a[i + l];
                if (use_b) z[l] = b[i + l];
            }
        }
        afm_v4i ok = AFM_TRACK_OK4(x, y, z, nn, ref, dp, tol, use_b);
        for (int l = 0; l < 4; l++)
            if (!ok[l]) return i + (l < left ? l : left);
        nn = nn + 4.0;
    }
}

static inline AFM_EST_INLINE int afm_track_run(const afm_phase_track *t, const double *th,
                                               const double *a, const double *b, int nmax) {
    return b ? afm_track_run_v4(t, th, a, b, nmax, true)
             : afm_track_run_v4(t, th, a, NULL, nmax, false);
}

#endif
