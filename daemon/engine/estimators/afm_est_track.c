/* SPDX-License-Identifier: MIT */
/* afm_est_track.c -- the drive-phase tracker's slow path (afm_est_internal.h): the check of
 * a sample off the prediction, the period boundary, the rate estimate, lock and
 * resynchronisation. Out of line: the estimators take it once a period or window, their
 * per-sample loops only the inline fast path (afm_track_fast, afm_track_run). */
#include "estimators/afm_est_internal.h"

#include "config/afm_clones.h"

/* afm_track_advance and afm_track_step (twice a period in the output chain, issue 12) are
 * multiversioned with their helpers inlined: the x86-64-v3 copy has its fmas and roundings
 * inline, not libm calls; the same bits. */
#if defined(__GNUC__)
#define TRACK_INLINE inline __attribute__((always_inline))
#else
#define TRACK_INLINE inline
#endif

void afm_track_init(afm_phase_track *t, bool clock) {
    t->clock = clock;
    t->started = t->locked = false;
    t->th_prev = t->th_ref = t->p_ref = t->n = t->dphi = t->nb = t->noise = t->age = 0.0;
    t->tol = -1.0;
    t->n_end = 0.0;
    t->rate_changes = 0;
}

/* a - 2 pi m for the integer m nearest a / 2 pi: the deviation of a step from the rate up to
 * whole turns (the fma is exact: the remainder is representable). */
static TRACK_INLINE double afm_track_off_turns(double a) {
    double m = nearbyint(a * (1.0 / AFM_EST_TWO_PI));
    return fma(-m, AFM_EST_TWO_PI, a);
}

/* Slow path, part 1: check theta without changing anything: AFM_CLOCK_BAD or
 * AFM_CLOCK_NONE; *p gets theta mod 2 pi (clock; 0 otherwise). */
int afm_track_check(const afm_phase_track *t, double th, double *p) {
    *p = 0.0;
    if (!isfinite(th)) return AFM_CLOCK_BAD;
    if (!t->clock) return AFM_CLOCK_NONE;
    *p = afm_clock_wrap(th);
    if (t->started) {
        double d = *p - afm_clock_wrap(t->th_prev);
        if (d < 0) d += AFM_EST_TWO_PI;
        if (!(d > 0 && d < AFM_EST_PI)) return AFM_CLOCK_BAD;
    }
    return AFM_CLOCK_NONE;
}

/* n_end of a tracker just resynchronised at p (theta mod 2 pi for a clock) with tolerance
 * tol: the fast path's room (0 while unlocked). */
static TRACK_INLINE void track_window(afm_phase_track *t, double p, double tol) {
    t->n_end = 0.0;
    if (t->locked && !t->clock) {
        t->n_end = AFM_TRACK_WINDOW_FREE;
    } else if (t->locked) {
        double lim = AFM_EST_TWO_PI - (2.0 * tol + 1e-12);
        double m = afm_floor((lim - p) / t->dphi);
        if (m > AFM_TRACK_WINDOW_CLOCK) m = AFM_TRACK_WINDOW_CLOCK;
        while (m > 0 && !(p + m * t->dphi < lim))
            m -= 1.0; /* rounding of the division */
        t->n_end = m > 0 ? m : 0.0;
    }
}

/* The common end of afm_track_advance and afm_track_step: the rate estimate, the lock and
 * the resynchronisation at theta (p = theta mod 2 pi for a clock, else 0); *rate_changed as
 * for afm_track_advance. */
static TRACK_INLINE void afm_track_resync(afm_phase_track *t, double th, double p,
                                          bool *rate_changed) {
    double n = t->n + 1.0;
    *rate_changed = false;
    double err = (th - t->th_ref) - n * t->dphi;
    bool drift = t->locked && n <= t->n_end && fabs(err) > t->tol; /* not boundary/window */
    double dev = (th - t->th_prev) - t->dphi;                      /* this step against the rate */
    t->age += n;
    if (!t->started) {
        t->locked = false;
    } else if (t->locked && !(fabs(dev) <= 4.0 * t->tol)) {
        /* Off the rate. By whole turns (tol of the larger theta: the step rounds to its ulp):
         * the same rate, nothing to average from this interval. Else a new rate, or noise
         * when it happens again soon after the last lock (see the header). */
        double big = fmax(fabs(th), fabs(t->th_prev));
        double offt = afm_track_off_turns(dev);
        if (!(fabs(offt) <= 4.0 * (2e-11 + 1.8e-15 * big + t->noise))) {
            if (t->age < AFM_TRACK_WINDOW_CLOCK && fabs(offt) <= 1e-6)
                t->noise = fmin(2.0 * fabs(offt), 1e-6); /* noise: keep the rate */
            else
                t->locked = false; /* a new rate: take the next step's increment */
        }
    } else if (t->locked) {
        /* same rate (the step is consistent): average in the increments since th_ref. A
         * drift failure raises the noise floor (theta carries the rounding of the sample
         * time, omega ulp(t), which the tracker cannot know); it decays otherwise. */
        t->noise = drift ? fmin(fmax(t->noise, 2.0 * fabs(err)), 1e-6) : 0.97 * t->noise;
        double d = (t->dphi * t->nb + (th - t->th_ref)) / (t->nb + n);
        double tol = 2e-11 + 1.8e-15 * fabs(th) + t->noise;
        double win = t->clock ? AFM_TRACK_WINDOW_CLOCK : AFM_TRACK_WINDOW_FREE;
        if (t->clock && t->dphi > 0 && AFM_EST_TWO_PI / t->dphi < win)
            win = AFM_EST_TWO_PI / t->dphi; /* the run between two boundaries */
        if (fabs(d - t->dphi) * win > 0.125 * tol) {
            t->dphi = d;
            *rate_changed = true;
        }
        t->nb = t->nb + n < AFM_TRACK_MAX_BASELINE ? t->nb + n : AFM_TRACK_MAX_BASELINE;
    } else {
        t->dphi = th - t->th_prev;
        t->nb = 1.0;
        t->locked = true;
        t->age = 0.0;
        *rate_changed = true;
    }
    t->rate_changes += *rate_changed;
    double tol = 2e-11 + 1.8e-15 * fabs(th) + t->noise;
    if (t->locked && t->clock && !(t->dphi > 4.0 * tol + 1e-12 && t->dphi < AFM_EST_PI - 4.0 * tol))
        t->locked = false;
    t->started = true;
    t->th_prev = t->th_ref = th;
    t->p_ref = p;
    t->n = 0.0;
    t->tol = t->locked ? tol : -1.0;
    track_window(t, p, tol);
}

bool afm_track_rebase(afm_phase_track *t, double th, double dphi) {
    if (!t->started || !isfinite(th) || !isfinite(dphi)) return false;
    if (!(fabs(afm_track_off_turns(th - t->th_prev)) <= 1e-9)) return false;
    double tol = 2e-11 + 1.8e-15 * fabs(th) + t->noise;
    if (t->clock && !(dphi > 4.0 * tol + 1e-12 && dphi < AFM_EST_PI - 4.0 * tol)) return false;
    t->locked = true;
    t->dphi = dphi;
    t->nb = AFM_TRACK_MAX_BASELINE;  /* exact: the running average must not move it */
    t->age = AFM_TRACK_WINDOW_CLOCK; /* a later step off this rate is a new rate, not noise */
    t->rate_changes++;
    t->th_prev = t->th_ref = th;
    t->p_ref = t->clock ? afm_clock_wrap(th) : 0.0;
    t->n = 0.0;
    t->tol = tol;
    track_window(t, t->p_ref, tol);
    return true;
}

/* Slow path, part 2: advance to theta (checked, p from afm_track_check) and resynchronise.
 * Returns AFM_CLOCK_NONE/CROSS/START (always NONE for a non-clock); *frac as for CROSS;
 * *rate_changed set when dphi took a new value (the caller's per-step rotation must be
 * recomputed from it; only meaningful while t->locked). */
AFM_CLONES int afm_track_advance(afm_phase_track *t, double th, double p, double *frac,
                                 bool *rate_changed) {
    int rc = AFM_CLOCK_NONE;
    if (t->clock) {
        if (!t->started) {
            if (p == 0.0) rc = AFM_CLOCK_START;
        } else {
            double pp = afm_clock_wrap(t->th_prev);
            if (p < pp) {
                *frac = (AFM_EST_TWO_PI - pp) / (p + AFM_EST_TWO_PI - pp);
                if (*frac > 1.0) *frac = 1.0;
                rc = AFM_CLOCK_CROSS;
            }
        }
    }
    afm_track_resync(t, th, p, rate_changed);
    return rc;
}

/* afm_track_check then afm_track_advance for a clock tracker, in one: the same checks, result and
 * tracker state, with theta_prev reduced mod 2 pi once. AFM_CLOCK_BAD (nothing changed), else as
 * afm_track_advance (*frac for a boundary). */
AFM_CLONES int afm_track_step(afm_phase_track *t, double th, double *frac) {
    if (!isfinite(th)) return AFM_CLOCK_BAD;
    double p = afm_clock_wrap(th), pp = 0.0;
    int rc = AFM_CLOCK_NONE;
    if (t->started) {
        pp = afm_clock_wrap(t->th_prev);
        double d = p - pp;
        if (d < 0) d += AFM_EST_TWO_PI;
        if (!(d > 0 && d < AFM_EST_PI)) return AFM_CLOCK_BAD;
        if (p < pp) {
            *frac = (AFM_EST_TWO_PI - pp) / (p + AFM_EST_TWO_PI - pp);
            if (*frac > 1.0) *frac = 1.0;
            rc = AFM_CLOCK_CROSS;
        }
    } else if (p == 0.0) {
        rc = AFM_CLOCK_START;
    }
    bool rate_changed;
    afm_track_resync(t, th, p, &rate_changed);
    return rc;
}
