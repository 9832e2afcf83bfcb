/* SPDX-License-Identifier: MIT */
/* afm_sundials_ev.c -- the CVODE reference's per-step record (afm_step_events) from its own
 * continuous solution: what test_rt_steady and issue 11's bounds compare the rt accurate
 * scheme's record against, so that neither side goes through afm_cycle's sample estimator.
 *
 * Contract in afm_sundials_ev.h. How: the output step is taken in CVODE's own internal steps
 * (CV_ONE_STEP up to the stop time at the step's end: the same steps as CV_NORMAL, so the
 * samples are the ones without a ring). Each internal step [ta, tb] has CVODE's dense output
 * (CVodeGetDky, its Nordsieck polynomial, accurate to the local error test, ~rtol). On it:
 *  - where v changes sign (looked for at the step's two ends and its middle), the turn is
 *    located (Illinois on v); a turn from - to + is a minimum of x there;
 *  - on each monotone piece, a change of side of the contact line is located (Illinois on
 *    x - xc), its velocity v there;
 *  - the pieces between turns and crossings are smooth: their work int (F - F_sq) v dt by
 *    4-point Gauss-Legendre (exact to degree 7 on a piece of one CVODE step, ~1e-10 of the
 *    period), F - F_sq the tip-sample force as afm_force_parts_at splits it; their share in
 *    contact by their middle's side.
 * The minimum of x is kept for every step (never NAN: the dense output resolves it). */
#include "integrators/afm_sundials_ev.h"

#include <cvodes/cvodes.h>
#include <math.h>
#include <nvector/nvector_serial.h>

/* The tip on CVODE's dense output at t: x, v; 0, or -1 when CVODE refused t. */
typedef struct {
    const afm_sim *s;
    void *mem;
    N_Vector tmp;
    double xc;
} cv_dense;

static int tip_at(const cv_dense *d, double t, double *x, double *v) {
    if (CVodeGetDky(d->mem, t, 0, d->tmp) != CV_SUCCESS) return -1;
    const double *y = N_VGetArrayPointer(d->tmp);
    const int n = d->s->m.n;
    double xs = 0.0, vs = 0.0;
    for (int i = 0; i < n; i++) {
        xs += d->s->m.tip[i] * y[i];
        vs += d->s->m.tip[i] * y[n + i];
    }
    *x = xs;
    *v = vs;
    return 0;
}

/* Root of g(t) (which: 0 x - xc, 1 v) in (a, b), g(a) = ga and g(b) = gb of opposite signs
 * (Illinois regula falsi, to a few ulps of t). */
static double root(const cv_dense *d, int which, double a, double ga, double b, double gb) {
    int side = 0;
    for (int it = 0; it < 200 && fabs(b - a) > 4e-16 * fabs(b) + 1e-300; it++) {
        double t = (a * gb - b * ga) / (gb - ga);
        if (!(t > a && t < b)) t = 0.5 * (a + b);
        double x, v;
        if (tip_at(d, t, &x, &v) != 0) break;
        double g = which ? v : x - d->xc;
        if ((g < 0) == (gb < 0)) {
            b = t;
            gb = g;
            if (side == -1) ga *= 0.5;
            side = -1;
        } else {
            a = t;
            ga = g;
            if (side == 1) gb *= 0.5;
            side = 1;
        }
    }
    return 0.5 * (a + b);
}

/* The tip-sample power (F - F_sq) v at (x, v). */
static double power_ts(const afm_sim *s, double x, double v) {
    afm_force_parts p;
    afm_force_parts_at(&s->f, s->z_m, x, v, &p);
    return (p.total_n - p.squeeze_n) * v;
}

/* A smooth piece [a, b] of the step starting at t0 (length dt): its work and contact share. */
static void smooth_piece(const cv_dense *d, afm_step_events *r, double a, double b) {
    static const double gx[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                                 0.8611363115940526};
    static const double gw[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                                 0.3478548451374538};
    double c = 0.5 * (a + b), h = 0.5 * (b - a), w = 0.0;
    for (int k = 0; k < 4; k++) {
        double x, v;
        if (tip_at(d, c + h * gx[k], &x, &v) != 0) {
            r->work_ts_j = NAN;
            return;
        }
        w += gw[k] * power_ts(d->s, x, v);
    }
    r->work_ts_j += h * w;
    double xm, vm;
    if (tip_at(d, c, &xm, &vm) == 0 && xm < d->xc) r->contact_frac += (b - a) / d->s->dt_s;
}

/* A piece [a, b] on which x is monotone (ends xa, xb): split at a crossing. */
static void monotone_piece(const cv_dense *d, afm_step_events *r, double t0, double a, double xa,
                           double b, double xb) {
    bool in_a = xa < d->xc, in_b = xb < d->xc;
    if (in_a == in_b || !(b > a)) {
        if (b > a) smooth_piece(d, r, a, b);
        return;
    }
    double tc = root(d, 0, a, xa - d->xc, b, xb - d->xc), xcr, vcr;
    double fr = (tc - t0) / d->s->dt_s;
    if (in_b) {
        if (r->n_in++ == 0) {
            r->in_frac = fr;
            r->v_in_m_s = tip_at(d, tc, &xcr, &vcr) == 0 ? vcr : NAN;
        }
    } else if (r->n_out++ == 0) {
        r->out_frac = fr;
    }
    smooth_piece(d, r, a, tc);
    smooth_piece(d, r, tc, b);
}

/* One internal step's span [a, b] (inside its dense output) of the output step from t0. */
static int span(const cv_dense *d, afm_step_events *r, double t0, double a, double b) {
    double t[3] = {a, 0.5 * (a + b), b}, x[3], v[3];
    for (int k = 0; k < 3; k++)
        if (tip_at(d, t[k], &x[k], &v[k]) != 0) return -1;
    for (int k = 0; k < 3; k++)
        if (x[k] < r->x_min_m) r->x_min_m = x[k];
    for (int k = 0; k < 2; k++) {
        double ta = t[k], xa = x[k], tb = t[k + 1];
        if ((v[k] < 0.0 && v[k + 1] > 0.0) || (v[k] > 0.0 && v[k + 1] < 0.0)) {
            double tv = root(d, 1, t[k], v[k], t[k + 1], v[k + 1]), xv, vv;
            if (tip_at(d, tv, &xv, &vv) != 0) return -1;
            if (xv < r->x_min_m) r->x_min_m = xv;
            monotone_piece(d, r, t0, ta, xa, tv, xv);
            ta = tv;
            xa = xv;
        }
        monotone_piece(d, r, t0, ta, xa, tb, x[k + 1]);
    }
    return 0;
}

int afm_cv_step_events(afm_sim *s, void *mem, N_Vector y, N_Vector tmp, double tout,
                       afm_step_events *rec) {
    const cv_dense d = {s, mem, tmp, afm_force_contact_x(&s->f, s->z_m)};
    const double t0 = s->t_s;
    rec->n_in = rec->n_out = 0;
    rec->contact_frac = 0.0;
    rec->in_frac = rec->out_frac = rec->v_in_m_s = NAN;
    rec->x_min_m = HUGE_VAL;
    rec->work_ts_j = 0.0;
    double done = t0; /* the output step is recorded up to here */
    for (;;) {
        double tret = done, hu = 0.0;
        int flag = CVode(mem, tout, y, &tret, CV_ONE_STEP);
        if (flag < 0) return -1;
        if (CVodeGetLastStep(mem, &hu) != CV_SUCCESS) return -1;
        double tn = 0.0;
        if (CVodeGetCurrentTime(mem, &tn) != CV_SUCCESS) return -1;
        /* the internal step [tn - hu, tn], within the output step [done, tout] */
        double a = fmax(done, tn - hu), b = fmin(tn, tout);
        if (b > a && span(&d, rec, t0, a, b) != 0) return -1;
        if (b > done) done = b;
        if (flag == CV_TSTOP_RETURN || tret >= tout) break;
    }
    if (rec->contact_frac > 1.0) rec->contact_frac = 1.0;
    return 0;
}
