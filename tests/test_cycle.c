/* SPDX-License-Identifier: MIT */
/* test_cycle.c -- afm_cycle_push and afm_cycle_push_n against a direct, non-streaming
 * computation of the per-period tapping metrics (afm_cycle.h's contract, in long double)
 * on tapping-like series: contact crossings, Hermite minima between samples, plateaus of f,
 * tone changes, rejected samples, uneven time steps. */
#include "estimators/afm_cycle.h"
#include "forces/afm_drive.h"
#include "check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double pi = 3.14159265358979323846;
static const long double two_pi_l = 6.283185307179586476925286766559L;

enum { NS = 60000, MAXP = 2000 };

/* ---- the direct computation ---- */

/* theta mod 2 pi in [0, 2 pi) (the exact clock: afm_clock_wrap's value) */
static double wrap(double th) {
    double m = floor(th * (1.0 / (2.0 * pi)));
    double ph = fma(-m, 2.0 * pi, th);
    if (ph < 0)
        ph = fma(-(m - 1.0), 2.0 * pi, th);
    else if (ph >= 2.0 * pi)
        ph = fma(-(m + 1.0), 2.0 * pi, th);
    return ph;
}

typedef struct {
    long double a, b, c, d; /* x(s) = ((a s + b) s + c) s + d, s in [0, 1] */
} lcubic;

static lcubic herm(const afm_sample *p, const afm_sample *q) {
    long double h = (long double)q->t_s - p->t_s, x0 = p->x_m, x1 = q->x_m;
    long double v0 = p->v_m_s, v1 = q->v_m_s;
    lcubic k = {2 * x0 + h * v0 - 2 * x1 + h * v1, -3 * x0 - 2 * h * v0 + 3 * x1 - h * v1, h * v0,
                x0};
    return k;
}

static long double at(const lcubic *k, long double s) {
    return ((k->a * s + k->b) * s + k->c) * s + k->d;
}

static long double slope(const lcubic *k, long double s) {
    return (3 * k->a * s + 2 * k->b) * s + k->c;
}

/* the crossing of x through xc in a step whose ends are on opposite sides (bisection) */
static long double root(const lcubic *k, long double xc) {
    long double lo = 0, hi = 1;
    bool pos = at(k, 0) >= xc;
    for (int it = 0; it < 200; it++) {
        long double mid = 0.5L * (lo + hi);
        if ((at(k, mid) >= xc) == pos)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5L * (lo + hi);
}

/* the parabola through a local maximum f0 and its neighbours (f0 if not a proper one) */
static long double parab(long double fm, long double f0, long double fp) {
    long double den = fm - 2 * f0 + fp;
    if (!(den < 0) || fm > f0 || fp > f0) return f0;
    return f0 - 0.125L * (fm - fp) * (fm - fp) / den;
}

typedef struct {
    long double t0, dur, peak, xmin, ct, e, xint, v_in, scale_e;
    double smin;   /* smallest sample */
    double xc_end; /* the contact line at the period's end */
    int nc;
} ref_period;

/* The metrics of every whole period of the accepted samples s[0 .. n-1] (theta th); the
 * contact line is xc1, xc2 from the step that ends at sample n2 on. */
static int reference(const afm_sample *s, const double *th, int n, double xc1, double xc2, int n2,
                     ref_period *out, int max_out) {
    int np = 0;
    bool active = false;
    ref_period cur = {0};
    for (int i = 1; i < n; i++) {
        const afm_sample *p = &s[i - 1], *q = &s[i];
        long double h = (long double)q->t_s - p->t_s;
        double xc = i >= n2 ? xc2 : xc1;
        double pp = wrap(th[i - 1]), pq = wrap(th[i]);
        bool cross = pq < pp;
        long double frac = cross ? (two_pi_l - pp) / ((long double)pq + two_pi_l - pp) : 1.0L;
        if (frac > 1) frac = 1;
        lcubic k = herm(p, q);
        /* the local maximum at p (its neighbours s[i - 2], q) belongs to the period of p */
        if (active && i >= 2) {
            long double pk = parab(s[i - 2].f_n, p->f_n, q->f_n);
            if (pk > cur.peak) cur.peak = pk;
        }
        /* stationary points of the cubic inside the step */
        long double r[2];
        int nr = 0;
        long double A = 3 * k.a, B = 2 * k.b, C = k.c, disc = B * B - 4 * A * C;
        if (fabsl(A) > 0 && disc >= 0) {
            r[nr++] = (-B + sqrtl(disc)) / (2 * A);
            r[nr++] = (-B - sqrtl(disc)) / (2 * A);
        } else if (A == 0 && B != 0) {
            r[nr++] = -C / B;
        }
        /* contact: [ca, cb] of the step, inward crossing r_in */
        bool in0 = p->x_m < xc, in1 = q->x_m < xc;
        long double ca = 0, cb = 0, r_in = -1;
        if (in0 && in1) cb = 1;
        if (in0 != in1) {
            long double rr = root(&k, xc);
            if (in1) {
                ca = r_in = rr;
                cb = 1;
            } else {
                cb = rr;
            }
        }
        long double e0 = -(long double)p->f_n * p->v_m_s, e1 = -(long double)q->f_n * q->v_m_s;
        /* two parts: [0, frac] to the current period, [frac, 1] to the next */
        for (int part = 0; part < (cross ? 2 : 1); part++) {
            long double lo = part ? frac : 0, hi = part ? 1 : frac;
            if (part == 1) { /* the new period */
                cur.xc_end = xc;
                if (active && np < max_out) out[np] = cur, np++;
                active = true;
                memset(&cur, 0, sizeof cur);
                cur.t0 = p->t_s + frac * h;
                cur.peak = q->f_n;
                cur.xmin = cur.smin = q->x_m;
                cur.v_in = NAN;
            }
            if (!active) continue;
            /* linear interpolants integrated over [lo, hi] */
            long double w1 = 0.5L * (hi * hi - lo * lo), w0 = (hi - lo) - w1;
            cur.e += h * (w0 * e0 + w1 * e1);
            cur.scale_e += h * (w0 * fabsl(e0) + w1 * fabsl(e1));
            cur.xint += h * (w0 * p->x_m + w1 * q->x_m);
            cur.dur += h * (hi - lo);
            long double l2 = ca > lo ? ca : lo, r2 = cb < hi ? cb : hi;
            if (r2 > l2) cur.ct += h * (r2 - l2);
            if (r_in >= lo && r_in < hi && !(part == 0 && r_in >= frac)) {
                if (cur.nc == 0) cur.v_in = slope(&k, r_in) / h;
                cur.nc++;
            }
            for (int j = 0; j < nr; j++)
                if (r[j] > lo && r[j] < hi && at(&k, r[j]) < cur.xmin) cur.xmin = at(&k, r[j]);
        }
        /* q belongs to the period that is current now (the new one if a boundary came) */
        if (active) {
            if (q->x_m < cur.xmin) cur.xmin = q->x_m;
            if (q->x_m < cur.smin) cur.smin = q->x_m;
            if (q->f_n > cur.peak) cur.peak = q->f_n;
        }
    }
    return np;
}

/* ---- the series ---- */

typedef struct {
    afm_sample s[NS];
    double th[NS];
    bool rejected[NS]; /* afm_cycle must refuse these */
    int n;
} series;

/* x = A (sin u + 0.3 sin(2u + 0.7) + 0.04 sin(5u)), u = theta - 0.4 (two minima per period
 * near the bottom, between samples), v = x' dtheta/dt, f: a spring-dashpot in contact below
 * xc, else a smooth attraction with extra local maxima, flat (exactly -F0) where sin u > 0.6
 * (> -0.5 when `flat`: most of the period, every sample a weak local maximum).
 * Two tone changes (theta from afm_drive); bad samples at a few places when `bad`; sample
 * times jittered by up to +-15 % of a step when `jitter`. */
static void make_series(series *z, double spp, double xc, bool bad, bool jitter, bool flat,
                        unsigned seed) {
    const double A = 20e-9, F0 = 1e-10, kc = 5.0, cd = 2e-7;
    double fe0 = 14.06e6 / spp;
    afm_cfg_drive c = {.separation_m = 30e-9, .n_tones = 1};
    c.tones[0].amplitude_m = 0.7e-9;
    c.tones[0].frequency_hz = fe0;
    c.tones[0].phase_rad = 0.3;
    afm_drive d;
    afm_drive_init(&d, &c);
    srand(seed);
    double t = 1.7e-6, fcur = fe0;
    z->n = NS;
    for (int i = 0; i < NS; i++) {
        double dt = 1.0 / 14.06e6;
        t += dt;
        /* uneven sample times on an even drive clock: afm_cycle takes any increasing times
         * (theta stays on the tracker's line, so the runs of push_n see the uneven steps) */
        double ts = jitter ? t + 0.3 * dt * ((double)rand() / RAND_MAX - 0.5) : t;
        if (i == NS / 3) {
            fcur = fe0 * 1.013;
            afm_drive_set_tone(&d, t - 0.4 * dt, 0, 0.7e-9, fcur);
        }
        if (i == 2 * NS / 3) {
            fcur = fe0 * 0.981;
            afm_drive_set_tone(&d, t - 0.3 * dt, 0, 0.7e-9, fcur);
        }
        double th = afm_drive_phase(&d, 0, t), w = 2 * pi * fcur, u = th - 0.4;
        double x = A * (sin(u) + 0.3 * sin(2 * u + 0.7) + 0.04 * sin(5 * u));
        double v = A * w * (cos(u) + 0.6 * cos(2 * u + 0.7) + 0.2 * cos(5 * u));
        double f;
        if (x < xc)
            f = kc * (xc - x) - cd * v;
        else if (sin(u) > (flat ? -0.5 : 0.6))
            f = -F0;
        else
            f = -F0 * (1.0 + 0.3 * cos(3 * u) * cos(3 * u) + 0.1 * sin(7 * u));
        z->s[i] = (afm_sample){.t_s = ts, .x_m = x, .v_m_s = v, .f_n = f};
        z->th[i] = th;
        z->rejected[i] = false;
    }
    if (bad) { /* a NaN force, a repeated time, theta stepping back (each inside a run) */
        int a = NS / 7 + 11, b = NS / 2 + 5, e = 4 * NS / 5 + 17;
        z->s[a].f_n = NAN;
        z->s[b].t_s = z->s[b - 1].t_s;
        z->th[e] = z->th[e - 1] - 0.01;
        z->rejected[a] = z->rejected[b] = z->rejected[e] = true;
    }
}

/* ---- the comparison ---- */

typedef struct {
    double t0, dur, peak, xmin, ind, ct, e, mean, v_in, nc;
} err_t;

static void compare(const afm_cycle_metrics *m, const ref_period *r, double ca, double xs,
                    double vs, err_t *e) {
    double xc = r->xc_end, ind = r->xmin < xc ? ca * (double)(xc - r->xmin) : 0.0;
    double pe = (double)r->dur;
    e->t0 = fmax(e->t0, fabs(m->t_start_s - (double)r->t0) / pe);
    e->dur = fmax(e->dur, fabs(m->duration_s - (double)r->dur) / pe);
    e->peak = fmax(e->peak, fabs(m->peak_force_n - (double)r->peak) / fabs((double)r->peak));
    e->xmin = fmax(e->xmin, fabs(m->min_deflection_m - (double)r->xmin) / xs);
    e->ind = fmax(e->ind, fabs(m->indentation_m - ind) / xs);
    e->ct = fmax(e->ct, fabs(m->contact_time_s - (double)r->ct) / pe);
    e->e = fmax(e->e, fabs(m->dissipated_energy_j - (double)r->e) / (double)r->scale_e);
    e->mean = fmax(e->mean, fabs(m->mean_deflection_m - (double)(r->xint / r->dur)) / xs);
    if (r->nc > 0)
        e->v_in = fmax(e->v_in, fabs(m->pre_contact_velocity_m_s - (double)r->v_in) / vs);
    else if (!isnan(m->pre_contact_velocity_m_s))
        e->v_in = 1;
    if (m->n_contacts != r->nc) e->nc = 1;
}

static series z;
static ref_period ref[MAXP];
static afm_cycle_metrics got_n[MAXP], got_1[MAXP];

/* One series through afm_cycle_push and through afm_cycle_push_n in blocks of random
 * lengths (as the chain calls it: each call up to a block's end): the same bits, and both
 * against the direct computation. */
static void run_case(const char *what, double spp, bool bad, bool jitter, bool flat, bool move_line,
                     unsigned seed) {
    const double xc = -14e-9, ca = cos(12 * pi / 180);
    make_series(&z, spp, xc, bad, jitter, flat, seed);
    /* a new contact line (afm_cycle_set_contact) before sample `change`: in the middle of a
     * contact (the previous sample in contact by both lines) */
    const double xc2 = move_line ? -12.5e-9 : xc;
    int change = NS;
    if (move_line)
        for (change = NS / 2; change < NS - 1; change++) /* 3 samples into a contact */
            if (z.s[change - 3].x_m < fmin(xc, xc2) - 0.5e-9 &&
                z.s[change - 1].x_m < fmin(xc, xc2) - 0.5e-9)
                break;
    /* the direct computation over the accepted samples */
    static afm_sample acc[NS];
    static double acc_th[NS];
    int na = 0, n_rej = 0, na2 = 0;
    for (int i = 0; i < z.n; i++) {
        if (i == change) na2 = na;
        if (z.rejected[i]) {
            n_rej++;
            continue;
        }
        acc[na] = z.s[i];
        acc_th[na++] = z.th[i];
    }
    int nref = reference(acc, acc_th, na, xc, xc2, move_line ? na2 : na, ref, MAXP);
    /* sample by sample */
    afm_cycle c1, c2;
    afm_cycle_init(&c1, xc, ca, NULL, 0);
    afm_cycle_init(&c2, xc, ca, NULL, 0);
    int n1 = 0, nn = 0, rej1 = 0;
    for (int i = 0; i < z.n; i++) {
        if (i == change) afm_cycle_set_contact(&c1, xc2);
        int rc = afm_cycle_push(&c1, &z.s[i], z.th[i]);
        if (rc < 0) rej1++;
        if (rc == 1 && n1 < MAXP) got_1[n1++] = c1.out;
    }
    /* blocks */
    long long rejn = 0;
    srand(seed * 7 + 1);
    for (int i = 0; i < z.n;) {
        int k = 1 + rand() % 1200;
        if (k > z.n - i) k = z.n - i;
        if (i < change && i + k > change) k = change - i;
        if (i == change) afm_cycle_set_contact(&c2, xc2);
        for (int j = 0, done; j < k;) {
            j += afm_cycle_push_n(&c2, z.s + i + j, z.th + i + j, k - j, &done, &rejn);
            if (done && nn < MAXP) got_n[nn++] = c2.out;
        }
        i += k;
    }
    double xs = 20e-9, vs = 20e-9 * 2 * pi * 14.06e6 / spp;
    err_t e1 = {0}, en = {0};
    int m = nref < n1 ? nref : n1;
    for (int p = 0; p < m; p++)
        compare(&got_1[p], &ref[p], ca, xs, vs, &e1);
    m = nref < nn ? nref : nn;
    for (int p = 0; p < m; p++)
        compare(&got_n[p], &ref[p], ca, xs, vs, &en);
    int contacts = 0, refined = 0;
    for (int p = 0; p < nref; p++) {
        contacts += ref[p].nc;
        refined += (double)ref[p].xmin < ref[p].smin - 1e-6 * xs * 1e-6;
    }
    printf("  %s: %d periods (%d contacts, %d with the Hermite minimum below the samples), "
           "rejects %d/%lld of %d\n",
           what, nref, contacts, refined, rej1, rejn, n_rej);
    printf("    push_n: t0 %.1e dur %.1e peak %.1e min %.1e ind %.1e ct %.1e E %.1e mean %.1e "
           "v_in %.1e\n",
           en.t0, en.dur, en.peak, en.xmin, en.ind, en.ct, en.e, en.mean, en.v_in);
    printf("    push:   t0 %.1e dur %.1e peak %.1e min %.1e ind %.1e ct %.1e E %.1e mean %.1e "
           "v_in %.1e\n",
           e1.t0, e1.dur, e1.peak, e1.xmin, e1.ind, e1.ct, e1.e, e1.mean, e1.v_in);
    char w[160];
    snprintf(w, sizeof w, "cycle %s: periods (push, push_n, direct) and rejects agree", what);
    check_true(nref > 50 && n1 == nref && nn == nref && rej1 == n_rej && rejn == n_rej, w);
    snprintf(w, sizeof w, "cycle %s: push_n = push bit for bit (every period, final state)", what);
    check_true(memcmp(got_1, got_n, (size_t)m * sizeof *got_1) == 0 &&
                   memcmp(&c1, &c2, sizeof c1) == 0,
               w);
    snprintf(w, sizeof w, "cycle %s: contacts and refined minima in most periods", what);
    check_true(contacts > nref / 2 && refined > nref / 2, w);
    /* Tolerances (both functions, against the long double computation): the period start
     * is rounded to a double time (ulp(5 ms) = 9e-19 s, 3e-13 of a period), the duration a
     * sum of differences of times (1e-13 of the period); the peak exactly as the
     * parabola's double arithmetic (1e-13 relative); the minimum, indentation and mean to
     * 1e-13 of the amplitude (the cubic's double coefficients cancel ~ 1e-16 of x); contact
     * time and pre-contact velocity to 1e-11 (crossings to ~1e-15 of the step, the slope
     * there); the energy, a sum of ~200 terms of both signs, to 1e-13 of sum |h f v|. */
    const err_t *es[2] = {&e1, &en};
    const char *nm[2] = {"push", "push_n"};
    for (int f = 0; f < 2; f++) {
        const err_t *e = es[f];
        snprintf(w, sizeof w, "cycle %s (%s): period start vs direct (period)", what, nm[f]);
        check_abs(e->t0, 0, 1e-12, w);
        snprintf(w, sizeof w, "cycle %s (%s): duration vs direct (period)", what, nm[f]);
        check_abs(e->dur, 0, 1e-13, w);
        snprintf(w, sizeof w, "cycle %s (%s): peak force (parabola) vs direct", what, nm[f]);
        check_abs(e->peak, 0, 1e-13, w);
        snprintf(w, sizeof w, "cycle %s (%s): Hermite minimum, indentation vs direct", what, nm[f]);
        check_abs(fmax(e->xmin, e->ind), 0, 1e-13, w);
        snprintf(w, sizeof w, "cycle %s (%s): contact time vs direct (period)", what, nm[f]);
        check_abs(e->ct, 0, 1e-11, w);
        snprintf(w, sizeof w, "cycle %s (%s): n_contacts, pre-contact velocity vs direct", what,
                 nm[f]);
        check_true(e->nc == 0 && e->v_in <= 1e-11, w);
        snprintf(w, sizeof w, "cycle %s (%s): dissipated energy vs direct (sum |h f v|)", what,
                 nm[f]);
        check_abs(e->e, 0, 1e-13, w);
        snprintf(w, sizeof w, "cycle %s (%s): mean deflection vs direct", what, nm[f]);
        check_abs(e->mean, 0, 1e-13, w);
    }
}

int main(void) {
    run_case("41.6 samples/period", 41.58, false, false, false, false, 1);
    run_case("167.27 samples/period", 167.27, false, false, false, false, 2);
    run_case("41.6 samples/period, bad samples", 41.58, true, false, false, false, 3);
    run_case("60 samples/period, uneven steps", 60.3, true, true, false, false, 4);
    run_case("167.27 samples/period, flat force", 167.27, true, false, true, false, 5);
    run_case("41.6 samples/period, contact line moved", 41.58, false, false, false, true, 6);
    run_case("60 samples/period, contact line moved", 60.3, true, false, false, true, 7);
    return check_done();
}
