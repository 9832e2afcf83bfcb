/* SPDX-License-Identifier: MIT */
/* afm_cont.c -- pseudo-arclength continuation, bifurcations and branch switching (contract
 * in afm_cont.h). */
#include "analysis/afm_cont_run.h"

#include "beam/afm_linalg.h"
#include "config/afm_err.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CONT_COS_TURN 0.866 /* largest turn of the tangent per step: 30 deg */
#define CONT_REFINE_ITER 24
/* The bracket of a refined event, relative to the step: the test functions carry the
 * sensitivities' error (~1e-4 of their range near zero), below which the secant wanders */
#define CONT_REFINE_REL 1e-6
#define CONT_REFINE_ACCEPT 1e-4

/* The multiplier that an event of kind moves through the unit circle: the real one nearest
 * -1 (PD) or +1 (LPC, a branch point), the complex one nearest the circle (NS); -1 if none. */
static int critical_of(const cont_run *R, const afm_cont_pt *pt, afm_cont_kind kind) {
    int best = -1;
    double bd = HUGE_VAL;
    for (int i = 0; i < R->c.N; i++) {
        double re = pt->mult_re[i], im = pt->mult_im[i], d;
        if (kind == AFM_CONT_NS) {
            if (im == 0.0) continue;
            d = fabs(hypot(re, im) - 1.0);
        } else {
            if (im != 0.0) continue;
            d = fabs(re - (kind == AFM_CONT_PD ? -1.0 : 1.0));
        }
        if (d < bd) bd = d, best = i;
    }
    return best;
}

/* Test functions (zero at the event, smooth along a branch: symmetric functions of the
 * multipliers, i.e. polynomials in M's entries): LPC the tangent's parameter component;
 * PD det(M + I) = prod (1 + mu); a branch point (AFM_CONT_END here) det(M - I) =
 * prod (mu - 1); NS prod_{i<j} (mu_i mu_j - 1) (also zero at a neutral saddle, mu_i mu_j = 1
 * with both real: not reported). Each is divided by its modulus at the event's bracket ends
 * by the caller's sign test only, so their scale does not matter. */
double afm_cont_psi(const cont_run *R, const afm_cont_pt *pt, afm_cont_kind kind) {
    const int N = R->c.N;
    if (kind == AFM_CONT_LPC) return pt->t[N];
    double complex prod = 1.0;
    if (kind == AFM_CONT_NS) {
        for (int i = 0; i < N; i++)
            for (int j = i + 1; j < N; j++) {
                double complex a = (pt->mult_re[i] + I * pt->mult_im[i]);
                double complex b = (pt->mult_re[j] + I * pt->mult_im[j]);
                prod *= a * b - 1.0;
            }
        return creal(prod);
    }
    double shift = kind == AFM_CONT_PD ? 1.0 : -1.0;
    for (int i = 0; i < N; i++)
        prod *= (pt->mult_re[i] + I * pt->mult_im[i]) + shift;
    return creal(prod);
}

/* Scaled distance between an orbit's start and its state half-way (0 for p odd). */
static double half_gap(const cont_run *R, const afm_cont_pt *pt) {
    double d = 0.0;
    for (int i = 0; i < R->c.N; i++)
        d = fmax(d, fabs(pt->y[i] - pt->y_half[i]) / R->c.ys[i]);
    return d;
}

static int emit_rec(cont_run *R, afm_cont_record *rec) {
    if (R->stopped) return 1;
    if (R->emit && R->emit(R->ectx, rec) != 0) R->stopped = true;
    return R->stopped ? 1 : 0;
}

/* Emit pt as a record of kind (POINT or an event). */
/* A record of kind for pt on branch (parent): the point's own fields (stability,
 * multipliers, state, convergence). */
static void rec_of_pt(const cont_run *R, const afm_cont_pt *pt, afm_cont_kind kind, int branch,
                      int parent, afm_cont_record *rec) {
    memset(rec, 0, sizeof *rec);
    rec->kind = kind;
    rec->branch = branch;
    rec->parent = parent;
    rec->p = pt->p;
    rec->param = pt->lambda;
    rec->stable = afm_cont_stable(&R->c, pt);
    rec->n_mult = R->c.N;
    rec->mult_re = pt->mult_re;
    rec->mult_im = pt->mult_im;
    rec->y = pt->y;
    rec->residual = pt->residual;
    rec->iterations = pt->iterations;
}

int afm_cont_emit_pt(cont_run *R, const afm_cont_pt *pt, afm_cont_kind kind, int branch,
                     int parent) {
    afm_cont_record rec;
    rec_of_pt(R, pt, kind, branch, parent, &rec);
    if (kind != AFM_CONT_POINT) {
        rec.refined = R->refined;
        int i = critical_of(R, pt, kind);
        if (i >= 0) rec.multiplier[0] = pt->mult_re[i], rec.multiplier[1] = pt->mult_im[i];
        R->sum->bifurcations++;
    } else {
        R->sum->points++;
        if (afm_cont_store_add(&R->store, branch, pt) != 0) {
            snprintf(R->err, R->errlen, "continuation: out of memory");
            return -1;
        }
    }
    if (afm_cont_set_lambda(&R->c, pt->lambda, R->err, R->errlen) != 0 ||
        afm_cont_metrics_of(R->c.flow, pt->y, pt->p, &rec.metrics, R->err, R->errlen) != 0)
        return -1;
    return emit_rec(R, &rec);
}

static int emit_end(cont_run *R, int branch, int parent, int p, double lambda, int points,
                    const char *why, const cont_join *j) {
    afm_cont_record rec;
    memset(&rec, 0, sizeof rec);
    rec.kind = AFM_CONT_END;
    rec.branch = branch;
    rec.parent = parent;
    rec.p = p;
    rec.param = lambda;
    rec.points = points;
    rec.via = R->via;
    rec.via_param = R->via_param;
    rec.joined = j ? j->branch : -1;
    if (j) rec.join_dist = j->dist, rec.join_diff = j->diff;
    snprintf(rec.how, sizeof rec.how, "%s", R->how ? R->how : "");
    snprintf(rec.stop_reason, sizeof rec.stop_reason, "%s", why);
    return emit_rec(R, &rec);
}

/* The record that opens a branch: how it was reached, at its first point pt. */
static int emit_branch(cont_run *R, int branch, int parent, const afm_cont_pt *pt) {
    afm_cont_record rec;
    rec_of_pt(R, pt, AFM_CONT_BRANCH, branch, parent, &rec);
    rec.via = R->via;
    rec.via_param = R->via_param;
    rec.joined = -1;
    snprintf(rec.how, sizeof rec.how, "%s", R->how ? R->how : "");
    return emit_rec(R, &rec);
}

/* Predictor from a along its tangent by h, corrector normal to a's tangent, tangent at out
 * (oriented along a's). 0, 1 (not converged or turned too far), -1 error. */
int afm_cont_step_from(cont_run *R, const afm_cont_pt *a, double h, afm_cont_pt *out) {
    const int N = R->c.N;
    double y[AFM_CONT_MAX_N];
    for (int i = 0; i < N; i++)
        y[i] = a->y[i] + h * a->t[i] * R->c.ys[i];
    double lambda = a->lambda + h * a->t[N] * R->c.ls;
    int rc = afm_cont_correct(&R->c, y, lambda, a->t, a->p, out, R->err, R->errlen);
    if (rc != 0) return rc;
    if (afm_cont_tangent(&R->c, out, a->t, 1) != 0) return 1;
    double dot = 0.0;
    for (int j = 0; j <= N; j++)
        dot += out->t[j] * a->t[j];
    return dot >= CONT_COS_TURN ? 0 : 1;
}

/* Locate the zero of afm_cont_psi(kind) between a (step 0, value fa) and the step hb (value fb) by
 * the Illinois method, into R->r. 0, or 1 (no convergence: R->r is the last iterate), -1. */
int afm_cont_refine(cont_run *R, const afm_cont_pt *a, double hb, double fa, double fb,
                    afm_cont_kind kind) {
    double lo = 0.0, hi = hb;
    int side = 0;
    for (int it = 0; it < CONT_REFINE_ITER; it++) {
        double h = (fb - fa) != 0.0 ? (lo * fb - hi * fa) / (fb - fa) : 0.5 * (lo + hi);
        if (!(h > fmin(lo, hi) && h < fmax(lo, hi))) h = 0.5 * (lo + hi);
        int rc = afm_cont_step_from(R, a, h, &R->r);
        if (rc < 0) return -1;
        if (rc > 0) return 1;
        double f = afm_cont_psi(R, &R->r, kind);
        if (!isfinite(f)) return 1;
        if ((f > 0) == (fa > 0)) {
            lo = h, fa = f;
            if (side == -1) fb *= 0.5;
            side = -1;
        } else {
            hi = h, fb = f;
            if (side == 1) fa *= 0.5;
            side = 1;
        }
        if (fabs(hi - lo) < CONT_REFINE_REL * fabs(hb) || f == 0.0) return 0;
    }
    return fabs(hi - lo) < CONT_REFINE_ACCEPT * fabs(hb) ? 0 : 1;
}

/* The step of b from a along a's tangent (the projection of b - a on it). */
double afm_cont_step_of(const cont_run *R, const afm_cont_pt *a, const afm_cont_pt *b) {
    double ua[AFM_CONT_MAX_U], ub[AFM_CONT_MAX_U], h = 0.0;
    afm_cont_scaled(&R->c, a->y, a->lambda, ua);
    afm_cont_scaled(&R->c, b->y, b->lambda, ub);
    for (int j = 0; j <= R->c.N; j++)
        h += a->t[j] * (ub[j] - ua[j]);
    return h;
}

/* Queue a switch onto the period-2p branch at the PD point R->r; one where a branch ended
 * (the far end of a period-2p band) first. */
static void queue_switch(cont_run *R, int branch) {
    const afm_cont_pt *pd = &R->r;
    const int N = R->c.N;
    if (R->o->no_switch || 2 * pd->p > AFM_CONT_MAX_P) return;
    double re[AFM_CONT_MAX_N], im[AFM_CONT_MAX_N], V[AFM_CONT_MAX_N * AFM_CONT_MAX_N];
    if (afm_la_eigvals(N, pd->M, re, im, V) != 0) return;
    int k = -1;
    double bd = HUGE_VAL;
    for (int i = 0; i < N; i++)
        if (im[i] == 0.0 && fabs(re[i] + 1.0) < bd) bd = fabs(re[i] + 1.0), k = i;
    if (k < 0) return;
    cont_switch s;
    memset(&s, 0, sizeof s);
    s.via = AFM_CONT_VIA_PD;
    memcpy(s.y, pd->y, sizeof(double) * (size_t)N);
    for (int i = 0; i < N; i++)
        s.v[i] = V[i * N + k];
    s.lambda = s.via_param = pd->lambda;
    s.p = 2 * pd->p;
    s.parent = branch;
    s.group = R->ngroup++;
    int e = R->o->no_end_switch ? -1 : afm_cont_end_near(R, s.lambda, s.y, s.p);
    s.far = e >= 0;
    afm_cont_pd_how(R, &s, e);
    afm_cont_queue_push(R, &s, s.far);
}

/* The events between R->a and R->b, refined and emitted in the order of the step. For a
 * branch point on a period-2p branch (the merge with the period-p orbit) *merged is set and
 * R->r holds it. 0, or -1 / 1 (error / stopped). */
static int events(cont_run *R, int branch, int parent, bool *merged) {
    const afm_cont_pt *a = &R->a, *b = &R->b;
    const int N = R->c.N;
    bool fold = (a->t[N] > 0) != (b->t[N] > 0);
    afm_cont_kind kinds[4];
    int nk = 0;
    if (fold) kinds[nk++] = AFM_CONT_LPC;
    if ((afm_cont_psi(R, a, AFM_CONT_PD) > 0) != (afm_cont_psi(R, b, AFM_CONT_PD) > 0))
        kinds[nk++] = AFM_CONT_PD;
    if ((afm_cont_psi(R, a, AFM_CONT_NS) > 0) != (afm_cont_psi(R, b, AFM_CONT_NS) > 0))
        kinds[nk++] = AFM_CONT_NS;
    if (!fold && a->p > 1 &&
        (afm_cont_psi(R, a, AFM_CONT_END) > 0) != (afm_cont_psi(R, b, AFM_CONT_END) > 0))
        kinds[nk++] = AFM_CONT_END;
    double hb = afm_cont_step_of(R, a, b);
    for (int e = 0; e < nk; e++) {
        double fa = afm_cont_psi(R, a, kinds[e]), fb = afm_cont_psi(R, b, kinds[e]);
        int rc = afm_cont_refine(R, a, hb, fa, fb, kinds[e]);
        if (rc < 0) return -1;
        R->refined = rc == 0;
        if (rc > 0) R->r = *b;         /* not located: reported at the later point */
        if (kinds[e] == AFM_CONT_NS) { /* a neutral saddle is no bifurcation */
            int i = critical_of(R, &R->r, AFM_CONT_NS);
            if (i < 0 || fabs(hypot(R->r.mult_re[i], R->r.mult_im[i]) - 1.0) > 1e-3) continue;
        }
        if (kinds[e] == AFM_CONT_END) {
            if (half_gap(R, &R->r) < 1e-2) {
                *merged = true;
                return 0;
            }
            continue; /* a branch point elsewhere: not reported */
        }
        rc = afm_cont_emit_pt(R, &R->r, kinds[e], branch, parent);
        if (rc) return rc;
        if (kinds[e] == AFM_CONT_PD) queue_switch(R, branch);
    }
    return 0;
}

/* The merge of a period-2p branch with the period-p orbit between R->a and R->b (whose
 * half-orbits have collapsed): bisection on the step from R->a for the last point whose
 * half-orbits still differ by more than gap_min (near the merge the gap falls as the square
 * root of the distance), into R->r. 0, or -1. */
static int locate_merge(cont_run *R, double gap_min) {
    double lo = 0.0, hi = afm_cont_step_of(R, &R->a, &R->b);
    R->r = R->a;
    R->refined = false;
    for (int it = 0; it < 30 && hi - lo > CONT_REFINE_REL * hi; it++) {
        double h = 0.5 * (lo + hi);
        static afm_cont_pt t;
        int rc = afm_cont_step_from(R, &R->a, h, &t);
        if (rc < 0) return -1;
        if (rc > 0) break;
        if (half_gap(R, &t) > gap_min) {
            lo = h;
            R->r = t;
        } else {
            hi = h;
        }
    }
    R->refined = hi - lo <= CONT_REFINE_REL * hi;
    return 0;
}

/* Follow one branch from R->a (a converged point with its tangent), emitted already. */
static int follow(cont_run *R, int branch, int parent, double h) {
    const afm_cont_opts *o = R->o;
    const int N = R->c.N;
    double h_min = o->h_min > 0 ? o->h_min : 1e-7, h_max = o->h_max > 0 ? o->h_max : 0.25;
    int points = 1, max_bp = o->max_branch_points;
    const int jp = o->no_end_switch ? 0 : o->join_points > 0 ? o->join_points : 3;
    cont_join J = {.branch = -1};
    bool joined = false;
    double gap_max = R->a.p > 1 ? half_gap(R, &R->a) : 0.0;
    char why[400];
    double ua0[AFM_CONT_MAX_U];
    afm_cont_scaled(&R->c, R->a.y, R->a.lambda, ua0);
    for (;;) {
        if (R->sum->points >= R->max_points) {
            snprintf(why, sizeof why, "--max-points (%d) reached", R->max_points);
            break;
        }
        if (max_bp > 0 && points >= max_bp) {
            snprintf(why, sizeof why, "--max-branch-points (%d) reached", max_bp);
            break;
        }
        int rc = afm_cont_step_from(R, &R->a, h, &R->b);
        if (rc < 0) return -1;
        if (rc > 0) {
            h *= 0.5;
            if (h < h_min) {
                snprintf(why, sizeof why,
                         "step below the minimum %g at %s = %.10g: no convergence (a cusp, a "
                         "grazing contact or a branch the corrector cannot follow)",
                         h_min, R->c.par.name, R->a.lambda);
                break;
            }
            continue;
        }
        /* the range: end exactly on its bound */
        bool out = R->b.lambda < R->lo || R->b.lambda > R->hi;
        if (out) {
            double bound = R->b.lambda < R->lo ? R->lo : R->hi;
            double f = (bound - R->a.lambda) / (R->b.lambda - R->a.lambda);
            double y[AFM_CONT_MAX_N];
            for (int i = 0; i < N; i++)
                y[i] = R->a.y[i] + f * (R->b.y[i] - R->a.y[i]);
            afm_cont_pt keep = R->b;
            rc = afm_cont_correct(&R->c, y, bound, NULL, R->a.p, &R->b, R->err, R->errlen);
            if (rc < 0) return -1;
            if (rc > 0 || afm_cont_tangent(&R->c, &R->b, R->a.t, 1) != 0) R->b = keep;
        }
        bool merged = false;
        rc = events(R, branch, parent, &merged);
        if (rc) return rc;
        /* past the merge without a located branch point: the half-orbits collapsed onto the
         * period-p/2 orbit (now followed as a period-p one) */
        double gap = R->a.p > 1 ? half_gap(R, &R->b) : 0.0;
        gap_max = fmax(gap_max, gap);
        if (!merged && R->a.p > 1 && gap_max > 1e-2 && gap < 1e-4 * gap_max) {
            merged = true;
            rc = locate_merge(R, 1e-6 * gap_max);
            if (rc < 0) return -1;
        }
        if (merged) {
            int e = -1;
            if (R->nend < CONT_MAX_BRANCHES) {
                e = R->nend++;
                cont_end *E = &R->ends[e];
                E->lambda = R->r.lambda;
                memcpy(E->y, R->r.y, sizeof E->y);
                E->p = R->r.p;
                E->branch = branch;
                E->from = R->from_of[branch];
            }
            rc = afm_cont_emit_pt(R, &R->r, AFM_CONT_POINT, branch, parent);
            if (rc) return rc;
            points++;
            snprintf(why, sizeof why,
                     "met the period-%d orbit at %s = %.10g (a PD point of the period-%d "
                     "branch)",
                     R->r.p / 2, R->c.par.name, R->r.lambda, R->r.p / 2);
            if (!o->no_end_switch) {
                if (e >= 0) afm_cont_promote_far(R, e);
                int dir = R->r.t[N] > 0 ? 1 : -1;
                if (R->r.lambda != R->a.lambda) dir = R->r.lambda > R->a.lambda ? 1 : -1;
                rc = afm_cont_queue_end(R, branch, dir);
                if (rc < 0) return -1;
                size_t n = strlen(why);
                if (rc)
                    snprintf(why + n, sizeof why - n,
                             "; no branch computed so far passes there: the period-%d orbit is "
                             "continued from there both ways",
                             R->r.p / 2);
                else
                    snprintf(why + n, sizeof why - n, "; a branch computed before passes there");
            }
            R->a = R->r;
            break;
        }
        if (jp > 0 && branch > 0 && afm_cont_join_test(R, branch, &R->b, &J) != 0) return -1;
        rc = afm_cont_emit_pt(R, &R->b, AFM_CONT_POINT, branch, parent);
        if (rc) return rc;
        points++;
        R->a = R->b;
        if (jp > 0 && J.n >= jp) {
            joined = true;
            R->sum->joins++;
            snprintf(why, sizeof why,
                     "joins branch %d: the same period-%d branch, computed before (%d "
                     "points: its orbit, interpolated at this branch's %s, within %.2g of "
                     "the orbit size (%.2g m of tip motion); Newton from there lands on "
                     "this branch's within %.2g (%.2g m))",
                     J.branch, R->a.p, J.n, R->c.par.name, J.dist, J.dist * R->c.a_ref_m, J.diff,
                     J.diff * R->c.a_ref_m);
            break;
        }
        if (out) {
            snprintf(why, sizeof why, "reached the end of the range (%s = %.10g)", R->c.par.name,
                     R->a.lambda);
            rc = afm_cont_beyond_range(R, branch, parent, h, why, sizeof why);
            if (rc) return rc;
            break;
        }
        double ua[AFM_CONT_MAX_U], d = 0.0;
        afm_cont_scaled(&R->c, R->a.y, R->a.lambda, ua);
        for (int j = 0; j <= N; j++)
            d = fmax(d, fabs(ua[j] - ua0[j]));
        if (points > 10 && d < 0.5 * h) {
            snprintf(why, sizeof why, "closed loop: back at the branch's start");
            break;
        }
        if (R->a.iterations <= 3)
            h = fmin(1.5 * h, h_max);
        else if (R->a.iterations >= 6)
            h *= 0.7;
    }
    return emit_end(R, branch, parent, R->a.p, R->a.lambda, points, why, joined ? &J : NULL);
}

/* The first point of a switched branch: the period-2p orbit at scaled distance h along the
 * PD eigenvector. 0, 1 (not found), -1. */
static int switch_start(cont_run *R, const cont_switch *s) {
    const int N = R->c.N, max_iter = R->c.max_iter;
    double vs[AFM_CONT_MAX_N], nn = 0.0, t0[AFM_CONT_MAX_U];
    for (int i = 0; i < N; i++) {
        vs[i] = s->v[i] / R->c.ys[i];
        nn += vs[i] * vs[i];
    }
    nn = sqrt(nn);
    if (!(nn > 0)) return 1;
    for (int i = 0; i < N; i++)
        t0[i] = vs[i] / nn;
    t0[N] = 0.0;
    static const double hs[] = {0.002, 0.005, 0.01, 0.02, 0.05};
    int rc = 1;
    for (size_t k = 0; k < sizeof hs / sizeof hs[0]; k++) {
        /* near the pitchfork the corrector's system is close to singular (O(h)): damped
         * Newton steps keep it from jumping to the period-p orbit elsewhere */
        R->c.max_du = 0.5 * hs[k];
        R->c.max_iter = 40;
        double y[AFM_CONT_MAX_N];
        for (int i = 0; i < N; i++)
            y[i] = s->y[i] + hs[k] * t0[i] * R->c.ys[i];
        int cr = afm_cont_correct(&R->c, y, s->lambda, t0, s->p, &R->a, R->err, R->errlen);
        if (cr < 0) {
            rc = -1;
            break;
        }
        if (cr > 0 || half_gap(R, &R->a) < 0.25 * hs[k]) continue;
        if (afm_cont_tangent(&R->c, &R->a, t0, 1) != 0) continue;
        rc = 0;
        break;
    }
    R->c.max_du = 0.0;
    R->c.max_iter = max_iter;
    return rc;
}

/* The first point of a branch continued from an end (END_PD, FOLD): the period-p orbit at
 * s->lambda, its tangent in direction s->dir of the parameter. 0, 1 (not found), -1. */
static int cont_start(cont_run *R, const cont_switch *s) {
    int rc = afm_cont_correct(&R->c, s->y, s->lambda, NULL, s->p, &R->a, R->err, R->errlen);
    if (rc != 0) return rc;
    return afm_cont_tangent(&R->c, &R->a, NULL, s->dir) == 0 ? 0 : 1;
}

/* The start orbit of branch 0 at o->from into R->a, with its tangent towards o->to. */
static int start_orbit(cont_run *R) {
    const afm_cont_opts *o = R->o;
    const int N = R->c.N;
    double y[AFM_CONT_MAX_N] = {0};
    int p = o->p > 0 ? o->p : 1;
    if (o->start_y) {
        memcpy(y, o->start_y, sizeof(double) * (size_t)N);
    } else {
        int settle = o->settle_periods;
        if (settle <= 0) {
            double q1 = 0.5 / R->c.base.m.xi[0];
            settle = (int)fmax(50.0, 5.0 * q1 / 3.141592653589793);
        }
        settle = (settle + p - 1) / p * p; /* whole orbits: the start phase stays 0 */
        if (afm_cont_settle(&R->c, o->from, y, settle, R->err, R->errlen) != 0) return -1;
    }
    if (!(o->a_ref_m > 0)) { /* the orbit's tip amplitude as the scale of the state */
        double x = 0.0, v = 0.0, w1 = R->c.base.m.omega_rad_s[0];
        for (int i = 0; i < R->c.n; i++) {
            x += R->c.base.m.tip[i] * y[i];
            v += R->c.base.m.tip[i] * y[R->c.n + i];
        }
        afm_cont_set_aref(&R->c, fmax(hypot(x, v / w1), 1e-10));
    }
    int rc = afm_cont_correct(&R->c, y, o->from, NULL, p, &R->a, R->err, R->errlen);
    if (rc < 0) return -1;
    if (rc > 0) {
        afm_err_set(R->err, R->errlen,
                    "continuation: no period-%d orbit found at %s = %g from the %s (residual "
                    "%.3g of the orbit's size after %d Newton steps)",
                    p, R->c.par.name, o->from, o->start_y ? "given state" : "time integration",
                    R->a.residual, R->a.iterations);
        return -1;
    }
    if (afm_cont_tangent(&R->c, &R->a, NULL, o->to > o->from ? 1 : -1) != 0) {
        afm_err_set(R->err, R->errlen, "continuation: the start orbit is at a fold");
        return -1;
    }
    return 0;
}

int afm_cont_run(const afm_config *cfg, const afm_cont_opts *o, afm_cont_emit emit, void *ectx,
                 afm_cont_summary *sum, char *err, size_t errlen) {
    memset(sum, 0, sizeof *sum);
    double t0 = afm_cont_now_s();
    if (!o->param || !isfinite(o->from) || !isfinite(o->to) || o->from == o->to || o->p < 0 ||
        o->p > AFM_CONT_MAX_P || o->max_points < 0 || o->h0 < 0 || o->h_min < 0 || o->h_max < 0 ||
        o->join_points < 0 || o->max_branch_points < 0 || !isfinite(o->beyond)) {
        afm_err_set(err, errlen,
                    "continuation: needs a parameter, finite --from != --to, period 1..%d, "
                    "non-negative counts and steps",
                    AFM_CONT_MAX_P);
        return -1;
    }
    cont_run *R = calloc(1, sizeof *R);
    if (!R) {
        afm_err_set(err, errlen, "continuation: out of memory");
        return -1;
    }
    R->o = o;
    R->emit = emit;
    R->ectx = ectx;
    R->sum = sum;
    R->err = err;
    R->errlen = errlen;
    R->lo = fmin(o->from, o->to);
    R->hi = fmax(o->from, o->to);
    R->max_points = o->max_points > 0 ? o->max_points : 2000;
    int rc = afm_cont_ctx_init(&R->c, cfg, o->param, R->hi - R->lo,
                               o->a_ref_m > 0 ? o->a_ref_m : 1e-9, err, errlen);
    if (rc == 0 && o->sens_rtol != 0 && afm_cont_flow_set_sens_rtol(R->c.flow, o->sens_rtol) != 0) {
        afm_err_set(err, errlen, "continuation: sens_rtol %g (0..1e-3)", o->sens_rtol);
        rc = -1;
    }
    if (rc == 0)
        rc = afm_cont_inst_at(&R->c.base, &R->c.par, &o->from, 1, &(afm_cont_inst){0}, err, errlen);
    if (rc == 0) rc = start_orbit(R);
    double h0 = o->h0 > 0 ? o->h0 : 0.02;
    if (rc == 0) {
        char how0[300];
        snprintf(how0, sizeof how0, "the start orbit at %s = %.10g (period %d, from %s)",
                 R->c.par.name, o->from, R->a.p,
                 o->start_y ? "the given state" : "time integration from rest");
        R->nbranch = 1;
        R->ngroup = 1;
        R->parent_of[0] = -1;
        R->from_of[0] = NAN;
        R->via = R->via_of[0] = AFM_CONT_VIA_START;
        R->via_param = o->from;
        R->how = how0;
        rc = emit_branch(R, 0, -1, &R->a);
        if (rc == 0) rc = afm_cont_emit_pt(R, &R->a, AFM_CONT_POINT, 0, -1);
        if (rc == 0) rc = follow(R, 0, -1, h0);
        R->how = NULL;
    }
    const int max_b = o->max_branches > 0 ? o->max_branches : 8;
    while (rc == 0 && R->next < R->nq && !R->stopped) {
        if (R->nbranch >= max_b || R->nbranch >= CONT_MAX_BRANCHES) {
            sum->not_started += R->nq - R->next;
            break;
        }
        const cont_switch s = R->q[R->next++]; /* a copy: starts are queued in front */
        /* --no-end-switch: no switch where a branch came back (the far end of its band) */
        if (o->no_end_switch && s.via == AFM_CONT_VIA_PD &&
            afm_cont_end_near(R, s.lambda, s.y, s.p) >= 0)
            continue;
        int b = R->nbranch;
        int r2 = s.via == AFM_CONT_VIA_PD ? switch_start(R, &s) : cont_start(R, &s);
        if (r2 < 0) {
            rc = -1;
            break;
        }
        R->nbranch++;
        R->group[b] = s.group;
        R->parent_of[b] = s.parent;
        R->via_of[b] = s.via;
        R->from_of[b] = s.via == AFM_CONT_VIA_PD ? s.lambda : NAN;
        R->via = s.via;
        R->via_param = s.via_param;
        R->how = s.how;
        if (r2 > 0) {
            char why[400];
            snprintf(why, sizeof why, "no period-%d orbit found %s %s = %.10g", s.p,
                     s.via == AFM_CONT_VIA_PD ? "next to the PD at" : "to continue from at",
                     R->c.par.name, s.lambda);
            rc = emit_end(R, b, s.parent, s.p, s.lambda, 0, why, NULL);
            continue;
        }
        rc = emit_branch(R, b, s.parent, &R->a);
        if (rc == 0) rc = afm_cont_emit_pt(R, &R->a, AFM_CONT_POINT, b, s.parent);
        if (rc == 0) rc = follow(R, b, s.parent, h0);
        R->how = NULL;
    }
    if (rc > 0) rc = 0; /* stopped by the caller */
    sum->branches = R->nbranch;
    sum->maps = R->c.maps;
    if (R->c.flow) sum->flow_steps = afm_cont_flow_get_stats(R->c.flow)->steps;
    sum->seconds = afm_cont_now_s() - t0;
    afm_cont_ctx_free(&R->c);
    afm_cont_store_free(&R->store);
    free(R);
    return rc;
}
