/* SPDX-License-Identifier: MIT */
/* afm_est_internal.h -- small helpers shared by the estimators (afm_orbit, afm_harm,
 * afm_cycle): cubic Hermite pieces in (x, v), contact-line crossings, the 3-point peak, the
 * thesis App. E.4 phase difference and the drive-period clock. Internal: not installed,
 * not part of any contract; everything is static inline so each user gets its own copy. */
#ifndef AFM_EST_INTERNAL_H
#define AFM_EST_INTERNAL_H

#include "afm_sim.h"

#include <math.h>
#include <stdbool.h>

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

/* Stationary points of the cubic (roots of 3a s^2 + 2b s + c) into r; returns how many
 * (0..2), unfiltered: the caller keeps those in [0, 1]. */
static inline int afm_cubic_stationary(const afm_cubic *q, double r[2]) {
    double A = 3.0 * q->a, B = 2.0 * q->b, C = q->c;
    int nr = 0;
    if (fabs(A) < 1e-300) {
        if (fabs(B) > 1e-300) r[nr++] = -C / B;
    } else {
        double disc = B * B - 4.0 * A * C;
        if (disc >= 0) {
            double sq = sqrt(disc);
            double qq = -0.5 * (B + (B >= 0 ? sq : -sq));
            r[nr++] = qq / A;
            if (qq != 0) r[nr++] = C / qq;
        }
    }
    return nr;
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

/* Thesis eq. E.12-E.13: mod(k (pi - phi_1) + phi_k, 2 pi) in degrees, [0, 360); phi_1 and
 * phi_k are the deflection phases (rad) of A cos(k theta + phi). */
static inline double afm_phase_diff_deg(int k, double phi1_rad, double phik_rad) {
    double dphi = fmod((double)k * (AFM_EST_PI - phi1_rad) + phik_rad, AFM_EST_TWO_PI);
    if (dphi < 0) dphi += AFM_EST_TWO_PI;
    double deg = dphi * AFM_EST_RAD2DEG;
    return deg >= 360.0 ? 0.0 : deg;
}

/* Drive-period clock for streaming estimators: periods are the intervals between the
 * instants where tone 0's phase theta is a multiple of 2 pi. Only theta mod 2 pi is used,
 * so the 2 pi m jumps of afm_drive_phase at a phase-continuous tone change (afm_drive
 * keeps its phase wrapped) do not matter. A step must advance the phase by more than 0
 * and less than pi (tone 0 below half the sample rate). */
typedef struct {
    bool started;
    double ph_prev; /* theta mod 2 pi of the last sample, [0, 2 pi) */
} afm_period_clock;

#define AFM_CLOCK_BAD (-1)   /* theta non-finite, or a phase step not in (0, pi) */
#define AFM_CLOCK_NONE 0     /* no boundary in (previous sample, this one] */
#define AFM_CLOCK_CROSS 1    /* boundary in (previous, this]: *frac in (0, 1] of the step
                              * lies before it */
#define AFM_CLOCK_START 2    /* first sample, exactly on a boundary */

static inline double afm_clock_wrap(double th) {
    double ph = fmod(th, AFM_EST_TWO_PI);
    return ph < 0 ? ph + AFM_EST_TWO_PI : ph;
}

/* Check theta against the clock without changing it: AFM_CLOCK_BAD or AFM_CLOCK_NONE. */
static inline int afm_clock_check(const afm_period_clock *c, double th) {
    if (!isfinite(th)) return AFM_CLOCK_BAD;
    if (c->started) {
        double d = afm_clock_wrap(th) - c->ph_prev;
        if (d < 0) d += AFM_EST_TWO_PI;
        if (!(d > 0 && d < AFM_EST_PI)) return AFM_CLOCK_BAD;
    }
    return AFM_CLOCK_NONE;
}

/* Advance to th (checked with afm_clock_check first); *ph gets theta mod 2 pi, the phase
 * since the last boundary. */
static inline int afm_clock_advance(afm_period_clock *c, double th, double *frac, double *ph) {
    int rc = AFM_CLOCK_NONE;
    double p = afm_clock_wrap(th);
    if (!c->started) {
        c->started = true;
        if (p == 0.0) rc = AFM_CLOCK_START;
    } else if (p < c->ph_prev) {
        *frac = (AFM_EST_TWO_PI - c->ph_prev) / (p + AFM_EST_TWO_PI - c->ph_prev);
        if (*frac > 1.0) *frac = 1.0;
        rc = AFM_CLOCK_CROSS;
    }
    c->ph_prev = p;
    *ph = p;
    return rc;
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

#endif
