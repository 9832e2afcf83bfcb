/* SPDX-License-Identifier: MIT */
/* afm_lockin.c -- lock-in at tone 0 with cascaded first-order filters (contract in
 * afm_lockin.h). */
#include "afm_lockin.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

int afm_lockin_init(afm_lockin *l, const afm_cfg_lockin *cfg, double dt_s, char *err,
                    size_t errlen) {
    if (!l || !cfg || !(cfg->time_constant_s > 0) || !isfinite(cfg->time_constant_s) ||
        cfg->order < 1 || cfg->order > AFM_LOCKIN_MAX_ORDER || !(dt_s > 0) || !isfinite(dt_s)) {
        if (err && errlen)
            snprintf(err, errlen,
                     "lock-in: need time constant > 0 (got %g s), order 1..%d (got %d), sample "
                     "interval > 0 (got %g s)",
                     cfg ? cfg->time_constant_s : NAN, AFM_LOCKIN_MAX_ORDER, cfg ? cfg->order : 0,
                     dt_s);
        return -1;
    }
    memset(l, 0, sizeof *l);
    l->order = cfg->order;
    l->tau_s = cfg->time_constant_s;
    l->dt_s = dt_s;
    l->alpha = -expm1(-dt_s / cfg->time_constant_s);
    afm_lockin_reset(l);
    return 0;
}

void afm_lockin_reset(afm_lockin *l) {
    memset(l->xy, 0, sizeof l->xy);
    l->n = 0;
    afm_track_init(&l->trk, false);
    l->c = l->rc = 1.0;
    l->s = l->rs = 0.0;
}

/* theta off the tracker's prediction: sin and cos from theta itself, resynchronise. */
AFM_EST_COLD static int phase_slow(afm_lockin *l, double theta_rad) {
    double p, frac;
    bool rate_changed;
    if (afm_track_check(&l->trk, theta_rad, &p) != AFM_CLOCK_NONE) return -1;
    afm_track_advance(&l->trk, theta_rad, p, &frac, &rate_changed);
    l->c = cos(theta_rad);
    l->s = sin(theta_rad);
    if (l->trk.locked && rate_changed) {
        l->rc = cos(l->trk.dphi);
        l->rs = sin(l->trk.dphi);
    }
    return 0;
}

int afm_lockin_push(afm_lockin *l, double u_m, double theta_rad) {
    if (!isfinite(u_m)) return -1;
    if (afm_track_fast(&l->trk, theta_rad)) {
        double c = fma(l->c, l->rc, -l->s * l->rs);
        l->s = fma(l->s, l->rc, l->c * l->rs);
        l->c = c;
    } else if (phase_slow(l, theta_rad)) {
        return -1;
    }
    /* y += alpha (in - y) per stage, both channels side by side */
    double in[2] = {2.0 * u_m * l->s, 2.0 * u_m * l->c}, a = l->alpha;
    for (int i = 0; i < l->order; i++)
        for (int k = 0; k < 2; k++) {
            l->xy[i][k] = fma(a, in[k] - l->xy[i][k], l->xy[i][k]);
            in[k] = l->xy[i][k];
        }
    l->n++;
    return 0;
}

/* L fast-path samples with the cascade of ORDER stages unrolled (the same operations as
 * afm_lockin_push, so the same roundings). */
#if defined(__GNUC__)
#define ALWAYS_INLINE __attribute__((always_inline))
#else
#define ALWAYS_INLINE
#endif
#if defined(__FMA__) && defined(__SSE2__)
#include <immintrin.h>
/* Both channels in one 2-lane vector (lane 0 in-phase with sin, lane 1 quadrature with
 * cos): per lane exactly afm_lockin_push's operations. The phasor (s, c) is rotated as
 * s' = fma(s, rc, c rs), c' = fma(c, rc, -(s rs)): the swapped vector times (rs, -rs). */
static inline ALWAYS_INLINE void run_order(afm_lockin *l, const double *u, int L, const int order) {
    __m128d xy[AFM_LOCKIN_MAX_ORDER];
    for (int k = 0; k < order; k++)
        xy[k] = _mm_loadu_pd(l->xy[k]);
    __m128d v = _mm_set_pd(l->c, l->s), rc = _mm_set1_pd(l->rc);
    __m128d rsm = _mm_set_pd(-l->rs, l->rs), a = _mm_set1_pd(l->alpha);
    for (int i = 0; i < L; i++) {
        __m128d t = _mm_mul_pd(_mm_shuffle_pd(v, v, 1), rsm);
        v = _mm_fmadd_pd(v, rc, t);
        __m128d in = _mm_mul_pd(_mm_set1_pd(2.0 * u[i]), v);
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC unroll 8
#endif
        for (int k = 0; k < order; k++) {
            xy[k] = _mm_fmadd_pd(a, _mm_sub_pd(in, xy[k]), xy[k]);
            in = xy[k];
        }
    }
    for (int k = 0; k < order; k++)
        _mm_storeu_pd(l->xy[k], xy[k]);
    l->s = _mm_cvtsd_f64(v);
    l->c = _mm_cvtsd_f64(_mm_unpackhi_pd(v, v));
}
#else
static inline ALWAYS_INLINE void run_order(afm_lockin *l, const double *u, int L, const int order) {
    double xy[AFM_LOCKIN_MAX_ORDER][2];
    for (int k = 0; k < order; k++)
        xy[k][0] = l->xy[k][0], xy[k][1] = l->xy[k][1];
    double c = l->c, s = l->s, rc = l->rc, rs = l->rs, a = l->alpha;
    for (int i = 0; i < L; i++) {
        double cn = fma(c, rc, -s * rs);
        s = fma(s, rc, c * rs);
        c = cn;
        double in0 = 2.0 * u[i] * s, in1 = 2.0 * u[i] * c;
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC unroll 8
#endif
        for (int k = 0; k < order; k++) {
            xy[k][0] = fma(a, in0 - xy[k][0], xy[k][0]);
            xy[k][1] = fma(a, in1 - xy[k][1], xy[k][1]);
            in0 = xy[k][0];
            in1 = xy[k][1];
        }
    }
    for (int k = 0; k < order; k++)
        l->xy[k][0] = xy[k][0], l->xy[k][1] = xy[k][1];
    l->c = c;
    l->s = s;
}
#endif

int afm_lockin_push_n(afm_lockin *l, const double *u, const double *th, int n) {
    int rej = 0, i = 0;
    while (i < n) {
        const afm_phase_track *t = &l->trk;
        double nn = t->n;
        int L = 0;
        for (; i + L < n; L++) {
            nn += 1.0;
            if (!(nn <= t->n_end && fabs((th[i + L] - t->th_ref) - nn * t->dphi) <= t->tol) ||
                !isfinite(u[i + L]))
                break;
        }
        if (L > 0) {
            switch (l->order) {
            case 1:
                run_order(l, u + i, L, 1);
                break;
            case 2:
                run_order(l, u + i, L, 2);
                break;
            case 3:
                run_order(l, u + i, L, 3);
                break;
            case 4:
                run_order(l, u + i, L, 4);
                break;
            case 5:
                run_order(l, u + i, L, 5);
                break;
            case 6:
                run_order(l, u + i, L, 6);
                break;
            case 7:
                run_order(l, u + i, L, 7);
                break;
            default:
                run_order(l, u + i, L, 8);
                break;
            }
            l->trk.n = t->n + (double)L;
            l->trk.th_prev = th[i + L - 1];
            l->n += L;
            i += L;
            continue;
        }
        if (afm_lockin_push(l, u[i], th[i])) rej++;
        i++;
    }
    return rej;
}

double afm_lockin_x(const afm_lockin *l) {
    return l->xy[l->order - 1][0];
}

double afm_lockin_y(const afm_lockin *l) {
    return l->xy[l->order - 1][1];
}

double afm_lockin_amplitude(const afm_lockin *l) {
    return hypot(afm_lockin_x(l), afm_lockin_y(l));
}

double afm_lockin_phase_deg(const afm_lockin *l) {
    return atan2(-afm_lockin_y(l), afm_lockin_x(l)) * 57.295779513082320876798154814105;
}
