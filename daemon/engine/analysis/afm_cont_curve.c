/* SPDX-License-Identifier: MIT */
/* afm_cont_curve.c -- two-parameter continuation of LPC and PD points by the minimally
 * augmented system (contract in afm_cont_curve.h). */
#include "analysis/afm_cont_curve.h"

#include "beam/afm_linalg.h"
#include "config/afm_err.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CURVE_DELTA 1e-6 /* +-delta instances of the parameter derivatives (of the range) */
/* Scaled step of the central differences of M v (g_u). Their noise is that of M v (~1e-6
 * at CURVE_SENS_RTOL) over 2 h; only the Newton steps depend on g_u, not the converged point.
 * At 1e-4 (5e-3 of noise) the period-1 LPC of config/thesis-fig-4-2.conf (85.03 kHz, Z 30 nm,
 * in hard contact, a multiplier -2.97 beside the +1) did not refine: g_u . v, the only way
 * the corrector can set g, is of that size there, the first step along v came out 6x too
 * long (orbit residual 1.5e-9 -> 1.2e-2 -> 0.25 in 3 steps). At 1e-2 (0.3 nm of a 33 nm
 * orbit, half its 0.67 nm indentation) the contact makes the difference wrong in sign (g
 * grows for 12 steps). 1e-3: 5e-4 of noise, the start refines in 5-8 steps (tests/
 * test_continue.c "fig42lpc"). */
#define CURVE_FD_H 1e-3
/* scaled orbit residual of convergence: 1e-10 of the orbit's size, or 1e-8 once a Newton
 * step no longer takes it 3x below the best iterate so far (the map's own noise once the
 * sensitivities steer the steps: 1e-9..1e-8 in contact, scattering 5e-10..3e-8 on fig 4-2's
 * period-1 LPC, where a comparison with the last iterate missed it for 12 steps). Near a fold the
 * residual's component along the left null vector moves the point along the curve by far more than
 * its size: with 1e-8 alone the lumped lever's fold curve lay 0.014-0.026 Hz off the one-parameter
 * folds, at 1e-10 within 1e-4 Hz. */
#define CURVE_TOL_FINE 1e-10
#define CURVE_TOL 1e-8
/* The sensitivities in the error test at this rtol: g_u is a difference of M's, and with the
 * step rule alone M carries ~1e-4 of error in hard contact that jumps with the step sequence
 * (g then wanders by 1e-4 between Newton steps at the same point and the start never
 * refines); at 1e-6 g is reproducible to ~1e-6, at a similar cost per map */
#define CURVE_SENS_RTOL 1e-6
/* |g| of convergence. g's scale is that of the parameters (O(1) per range): |g| < 1e-5
 * let a point 1e-5 of the range off the curve pass (0.03 Hz of a fold on the lumped lever,
 * where Newton takes g to 1e-10 in two steps). So: |g| < CURVE_GTOL_FINE, or |g| <
 * CURVE_GTOL once a Newton step no longer reduces it by 3x (its noise floor: ~1e-6 in hard
 * contact, above), and always after at least one Newton step. (A bound on the step itself,
 * 1e-5 scaled, stalled the lumped curve near its cusp, where g_u is small.) */
#define CURVE_GTOL 1e-5
#define CURVE_GTOL_FINE 1e-8
#define CURVE_MAX_ITER 12 /* Newton steps per corrector */
#define CURVE_COS_TURN 0.866
#define NMAX AFM_CONT_MAX_N
#define UMAX (AFM_CONT_MAX_N + 2)

typedef struct {
    double y[NMAX], lam[2];
    double M[NMAX * NMAX], fl[2][NMAX];
    double v[NMAX], w[NMAX], g; /* scaled right / left null vectors of A, the test function */
    double grad[UMAX];          /* g_u (scaled), at this point or the iterate before it */
    double t[UMAX];             /* unit tangent (scaled) */
    double mre[NMAX], mim[NMAX];
    double residual;
    int iterations; /* evaluations of the corrector, the predictor's included */
    int iters_tol;  /* the first of them within CURVE_TOL and CURVE_GTOL (the step control's) */
} curve_pt;

typedef struct {
    afm_cont_ctx c; /* base, flow, state scales; c.par, c.ls: the first parameter */
    afm_cont_param par2;
    double ls2;
    double lo[2], hi[2];
    double sgn;                /* A = M + sgn I: -1 LPC, +1 PD */
    double bb[NMAX], cb[NMAX]; /* the bordering vectors (scaled, unit) */
    const afm_cont_curve_opts *o;
    afm_cont_curve_emit emit;
    void *ectx;
    afm_cont_summary *sum;
    bool stopped;
    curve_pt start, a, b;
    char *err;
    size_t errlen;
} curve_run;

static double ls_of(const curve_run *R, int k) {
    return k == 0 ? R->c.ls : R->ls2;
}

/* The flow's model at lam, with the +-delta instances of both parameters when par. */
static int set_model(curve_run *R, const double *lam, bool par) {
    const afm_cont_param ps[2] = {R->c.par, R->par2};
    afm_cont_inst at, plus[2], minus[2];
    double dpar[2] = {0, 0};
    if (afm_cont_inst_at(&R->c.base, ps, lam, 2, &at, R->err, R->errlen) != 0) return -1;
    for (int k = 0; par && k < 2; k++) {
        char scratch[AFM_ERR_LEN];
        double d = CURVE_DELTA * ls_of(R, k), lp[2] = {lam[0], lam[1]}, lm[2] = {lam[0], lam[1]};
        lp[k] += d;
        lm[k] -= d;
        dpar[k] = 2.0 * d;
        if (afm_cont_inst_at(&R->c.base, ps, lp, 2, &plus[k], scratch, sizeof scratch) != 0) {
            plus[k] = at; /* at the edge of a range: one-sided */
            dpar[k] -= d;
        }
        if (afm_cont_inst_at(&R->c.base, ps, lm, 2, &minus[k], scratch, sizeof scratch) != 0) {
            minus[k] = at;
            dpar[k] -= d;
        }
    }
    if (afm_cont_flow_set_model(R->c.flow, &at, par ? 2 : 0, plus, minus, dpar) != 0) {
        afm_err_set(R->err, R->errlen, "continuation: %s = %g, %s = %g changes the force terms",
                    R->c.par.name, lam[0], R->par2.name, lam[1]);
        return -1;
    }
    return 0;
}

/* One map with all sensitivities at (y, lam): G = y(pT) - y, M, fl. */
static int eval(curve_run *R, const double *y, const double *lam, int p, double *G, curve_pt *pt) {
    const int N = R->c.N, ns = N + 2;
    if (set_model(R, lam, true) != 0) return -1;
    double V[NMAX * NMAX], S[NMAX * UMAX], y1[NMAX];
    memset(V, 0, sizeof V);
    for (int i = 0; i < N; i++)
        V[i * N + i] = 1.0;
    R->c.maps++;
    if (afm_cont_flow_map(R->c.flow, y, p, N, V, true, y1, S, NULL, R->err, R->errlen) != 0)
        return -1;
    for (int i = 0; i < N; i++) {
        G[i] = y1[i] - y[i];
        for (int j = 0; j < N; j++)
            pt->M[i * N + j] = S[i * ns + j];
        pt->fl[0][i] = S[i * ns + N];
        pt->fl[1][i] = S[i * ns + N + 1];
    }
    return 0;
}

/* A = D^-1 (M + sgn I) D (scaled), N x N. */
static void scaled_a(const curve_run *R, const double *M, double *A) {
    const int N = R->c.N;
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++)
            A[i * N + j] = (M[i * N + j] + (i == j ? R->sgn : 0.0)) * R->c.ys[j] / R->c.ys[i];
}

/* The bordered systems [A b; c^T 0] [v; g] = [0; 1] and its transpose: v, w, g. 0 or -1. */
static int bordered(const curve_run *R, const double *A, double *v, double *w, double *g) {
    const int N = R->c.N, K = N + 1;
    double B[(NMAX + 1) * (NMAX + 1)], BT[(NMAX + 1) * (NMAX + 1)], x[NMAX + 1], z[NMAX + 1];
    for (int i = 0; i < K; i++)
        for (int j = 0; j < K; j++) {
            double e = i < N && j < N ? A[i * N + j] : i < N ? R->bb[i] : j < N ? R->cb[j] : 0.0;
            B[i * K + j] = e;
            BT[j * K + i] = e;
        }
    for (int i = 0; i < K; i++)
        x[i] = z[i] = i == N ? 1.0 : 0.0;
    if (afm_la_solve(K, B, x) != 0 || afm_la_solve(K, BT, z) != 0) return -1;
    memcpy(v, x, sizeof(double) * (size_t)N);
    memcpy(w, z, sizeof(double) * (size_t)N);
    *g = x[N];
    return isfinite(*g) ? 0 : -1;
}

/* g_u = -w^T A_u v (scaled unknowns), A_u v by central differences of the period map with
 * the one direction D v. 0 or -1. */
static int grad_g(curve_run *R, const double *y, const double *lam, int p, const double *v,
                  const double *w, double *grad) {
    const int N = R->c.N;
    double vd[NMAX];
    for (int i = 0; i < N; i++)
        vd[i] = v[i] * R->c.ys[i];
    for (int j = 0; j < N + 2; j++) {
        double S2[2][NMAX];
        for (int s = 0; s < 2; s++) {
            double h = s == 0 ? CURVE_FD_H : -CURVE_FD_H, yp[NMAX], lp[2] = {lam[0], lam[1]},
                   y1[NMAX];
            memcpy(yp, y, sizeof(double) * (size_t)N);
            if (j < N)
                yp[j] += h * R->c.ys[j];
            else
                lp[j - N] += h * ls_of(R, j - N);
            if ((j < N ? j == 0 && s == 0 : true) && set_model(R, j < N ? lam : lp, false) != 0)
                return -1;
            if (afm_cont_flow_map(R->c.flow, yp, p, 1, vd, false, y1, S2[s], NULL, R->err,
                                  R->errlen) != 0)
                return -1;
        }
        double d = 0.0;
        for (int i = 0; i < N; i++)
            d += w[i] * (S2[0][i] - S2[1][i]) / R->c.ys[i];
        grad[j] = -d / (2.0 * CURVE_FD_H);
    }
    return 0;
}

/* The first N + 1 rows of the Jacobian (scaled, N + 2 columns): the orbit's [D^-1 (M - I) D,
 * D^-1 fl_k ls_k] and g_u. */
static void jacobian(const curve_run *R, const curve_pt *pt, double *J) {
    const int N = R->c.N, U = N + 2;
    for (int i = 0; i < N; i++) {
        for (int j = 0; j < N; j++)
            J[i * U + j] = (pt->M[i * N + j] - (i == j ? 1.0 : 0.0)) * R->c.ys[j] / R->c.ys[i];
        J[i * U + N] = pt->fl[0][i] * R->c.ls / R->c.ys[i];
        J[i * U + N + 1] = pt->fl[1][i] * R->ls2 / R->c.ys[i];
    }
    for (int j = 0; j < U; j++)
        J[N * U + j] = pt->grad[j];
}

static void scaled_u(const curve_run *R, const double *y, const double *lam, double *u) {
    const int N = R->c.N;
    for (int i = 0; i < N; i++)
        u[i] = y[i] / R->c.ys[i];
    u[N] = lam[0] / R->c.ls;
    u[N + 1] = lam[1] / R->ls2;
}

/* Newton from the predictor (y, lam) with the constraint normal cn (N + 2, scaled; NULL:
 * lambda_2 fixed), into out. G0: the predictor already evaluated into out (its M and fl),
 * G0 its orbit residual, or NULL. 0 converged, 1 not, -1 error. */
static int correct(curve_run *R, const double *y_pred, const double *lam_pred, const double *cn,
                   int p, const double *G0, curve_pt *out) {
    const int N = R->c.N, U = N + 2;
    double u_pred[UMAX], en[UMAX] = {0}, y[NMAX], lam[2] = {lam_pred[0], lam_pred[1]};
    scaled_u(R, y_pred, lam_pred, u_pred);
    if (!cn) {
        en[N + 1] = 1.0;
        cn = en;
    }
    memcpy(y, y_pred, sizeof(double) * (size_t)N);
    bool have_grad = false;
    double last = HUGE_VAL, r_min = HUGE_VAL, g_min = HUGE_VAL;
    out->iters_tol = 0;
    for (int it = 1; it <= CURVE_MAX_ITER; it++) {
        double G[NMAX], A[NMAX * NMAX];
        if (it == 1 && G0)
            memcpy(G, G0, sizeof(double) * (size_t)N);
        else if (eval(R, y, lam, p, G, out) != 0)
            return it == 1 ? -1 : 1;
        double r = 0.0;
        for (int i = 0; i < N; i++)
            r = fmax(r, fabs(G[i] / R->c.ys[i]));
        scaled_a(R, out->M, A);
        if (bordered(R, A, out->v, out->w, &out->g) != 0) return 1;
        memcpy(out->y, y, sizeof(double) * (size_t)N);
        out->lam[0] = lam[0];
        out->lam[1] = lam[1];
        out->residual = r;
        out->iterations = it;
        const double ag = fabs(out->g);
        if (!out->iters_tol && r < CURVE_TOL && ag < CURVE_GTOL) out->iters_tol = it;
        /* stagnant: not 3x below the best iterate so far (at the noise floor r and g
         * scatter, 5e-10..3e-8 and +-1e-6 on fig 4-2's period-1 LPC: a comparison with the
         * last iterate alone missed it for 12 steps) */
        const bool r_ok = r < CURVE_TOL_FINE || (r < CURVE_TOL && r > r_min / 3.0);
        if (it > 1 && r_ok && (ag < CURVE_GTOL_FINE || (ag < CURVE_GTOL && ag > g_min / 3.0))) {
            if (!have_grad && grad_g(R, y, lam, p, out->v, out->w, out->grad) != 0) return -1;
            afm_la_eigvals(N, out->M, out->mre, out->mim, NULL);
            return 0;
        }
        /* diverging: well above the noise floor and growing */
        if (!isfinite(r) || (it > 3 && r > 1e2 * CURVE_TOL && r > 2.0 * last)) return 1;
        last = r;
        r_min = fmin(r_min, r);
        g_min = fmin(g_min, ag);
        if (grad_g(R, y, lam, p, out->v, out->w, out->grad) != 0) return it == 1 ? -1 : 1;
        have_grad = true;
        double J[UMAX * UMAX], b[UMAX], u[UMAX];
        jacobian(R, out, J);
        scaled_u(R, y, lam, u);
        double c = 0.0;
        for (int j = 0; j < U; j++) {
            J[(N + 1) * U + j] = cn[j];
            c += cn[j] * (u[j] - u_pred[j]);
        }
        for (int i = 0; i < N; i++)
            b[i] = -G[i] / R->c.ys[i];
        b[N] = -out->g;
        b[N + 1] = -c;
        if (afm_la_solve(U, J, b) != 0) return 1;
        for (int i = 0; i < N; i++)
            y[i] += b[i] * R->c.ys[i];
        lam[0] += b[N] * R->c.ls;
        lam[1] += b[N + 1] * R->ls2;
        if (!isfinite(lam[0]) || !isfinite(lam[1])) return 1;
    }
    return 1;
}

/* The unit tangent of pt: null vector of the Jacobian's first N + 1 rows, oriented along ref
 * (N + 2), or without one so that lambda_2 moves the way dir says. 0 or -1. */
static int tangent(const curve_run *R, curve_pt *pt, const double *ref, int dir) {
    const int N = R->c.N, U = N + 2;
    double J[UMAX * UMAX], b[UMAX];
    jacobian(R, pt, J);
    for (int j = 0; j < U; j++) {
        J[(N + 1) * U + j] = ref ? ref[j] : (j == N + 1 ? 1.0 : 0.0);
        b[j] = j == N + 1 ? 1.0 : 0.0;
    }
    if (afm_la_solve(U, J, b) != 0) return -1;
    double nn = 0.0, s = 0.0;
    for (int j = 0; j < U; j++) {
        nn += b[j] * b[j];
        s += (ref ? ref[j] : (j == N + 1 ? (double)dir : 0.0)) * b[j];
    }
    nn = sqrt(nn);
    if (!(nn > 0) || !isfinite(nn)) return -1;
    double sg = s < 0 ? -1.0 : 1.0;
    for (int j = 0; j < U; j++)
        pt->t[j] = sg * b[j] / nn;
    return 0;
}

/* The bordering vectors from pt's null vectors (unit), for the next corrector. */
static void rebord(curve_run *R, const curve_pt *pt) {
    const int N = R->c.N;
    double nv = 0.0, nw = 0.0;
    for (int i = 0; i < N; i++) {
        nv += pt->v[i] * pt->v[i];
        nw += pt->w[i] * pt->w[i];
    }
    nv = sqrt(nv);
    nw = sqrt(nw);
    if (!(nv > 0) || !(nw > 0) || !isfinite(nv) || !isfinite(nw)) return;
    for (int i = 0; i < N; i++) {
        R->cb[i] = pt->v[i] / nv;
        R->bb[i] = pt->w[i] / nw;
    }
}

/* The critical multiplier: the real one nearest -sgn (+1 LPC, -1 PD). */
static int critical(const curve_run *R, const curve_pt *pt) {
    int best = -1;
    double bd = HUGE_VAL;
    for (int i = 0; i < R->c.N; i++) {
        double d = hypot(pt->mre[i] + R->sgn, pt->mim[i]);
        if (d < bd) bd = d, best = i;
    }
    return best;
}

static int emit_rec(curve_run *R, afm_cont_curve_record *rec) {
    if (R->stopped) return 1;
    if (R->emit && R->emit(R->ectx, rec) != 0) R->stopped = true;
    return R->stopped ? 1 : 0;
}

static int emit_pt(curve_run *R, const curve_pt *pt, int side) {
    const afm_cont_curve_opts *o = R->o;
    afm_cont_curve_record rec;
    memset(&rec, 0, sizeof rec);
    rec.kind = o->kind;
    rec.curve = o->curve;
    rec.side = side;
    rec.p = o->p;
    rec.param = pt->lam[0];
    rec.param2 = pt->lam[1];
    rec.n_mult = R->c.N;
    rec.mult_re = pt->mre;
    rec.mult_im = pt->mim;
    rec.g = pt->g;
    rec.y = pt->y;
    rec.residual = pt->residual;
    rec.iterations = pt->iterations;
    int ic = critical(R, pt);
    rec.stable = true;
    for (int i = 0; i < R->c.N; i++)
        if (i != ic && hypot(pt->mre[i], pt->mim[i]) >= 1.0) rec.stable = false;
    if (ic >= 0) rec.multiplier[0] = pt->mre[ic], rec.multiplier[1] = pt->mim[ic];
    R->sum->points++;
    if (set_model(R, pt->lam, false) != 0 ||
        afm_cont_metrics_of(R->c.flow, pt->y, o->p, &rec.metrics, R->err, R->errlen) != 0)
        return -1;
    return emit_rec(R, &rec);
}

static int emit_end(curve_run *R, int side, int points, const char *why) {
    afm_cont_curve_record rec;
    memset(&rec, 0, sizeof rec);
    rec.end = true;
    rec.kind = R->o->kind;
    rec.curve = R->o->curve;
    rec.side = side;
    rec.p = R->o->p;
    rec.param = R->a.lam[0];
    rec.param2 = R->a.lam[1];
    rec.points = points;
    snprintf(rec.stop_reason, sizeof rec.stop_reason, "%s", why);
    return emit_rec(R, &rec);
}

/* A step of h from R->a into R->b (tangent set, turn checked). 0, 1 (failed), -1. */
static int step(curve_run *R, double h) {
    const int N = R->c.N;
    double y[NMAX], lam[2];
    for (int i = 0; i < N; i++)
        y[i] = R->a.y[i] + h * R->a.t[i] * R->c.ys[i];
    lam[0] = R->a.lam[0] + h * R->a.t[N] * R->c.ls;
    lam[1] = R->a.lam[1] + h * R->a.t[N + 1] * R->ls2;
    int rc = correct(R, y, lam, R->a.t, R->o->p, NULL, &R->b);
    if (rc != 0) return rc;
    if (tangent(R, &R->b, R->a.t, 1) != 0) return 1;
    double dot = 0.0;
    for (int j = 0; j < N + 2; j++)
        dot += R->b.t[j] * R->a.t[j];
    return dot >= CURVE_COS_TURN ? 0 : 1;
}

/* R->b left the rectangle: put it on the edge it crossed first (the corrector with that
 * parameter fixed, from the chord between R->a and R->b). 0, 1 (kept as it was), -1. */
static int land_on_edge(curve_run *R, int *edge) {
    const int N = R->c.N;
    double f = 1.0;
    int k_edge = -1;
    double bound = 0.0;
    for (int k = 0; k < 2; k++) {
        double lk = R->b.lam[k], ak = R->a.lam[k];
        double bd = lk < R->lo[k] ? R->lo[k] : lk > R->hi[k] ? R->hi[k] : NAN;
        if (isnan(bd) || lk == ak) continue;
        double fk = (bd - ak) / (lk - ak);
        if (fk < f) f = fk, k_edge = k, bound = bd;
    }
    *edge = k_edge;
    if (k_edge < 0) return 1;
    double y[NMAX], lam[2], cn[UMAX] = {0};
    for (int i = 0; i < N; i++)
        y[i] = R->a.y[i] + f * (R->b.y[i] - R->a.y[i]);
    for (int k = 0; k < 2; k++)
        lam[k] = R->a.lam[k] + f * (R->b.lam[k] - R->a.lam[k]);
    lam[k_edge] = bound;
    cn[N + k_edge] = 1.0;
    curve_pt keep = R->b;
    int rc = correct(R, y, lam, cn, R->o->p, NULL, &R->b);
    if (rc < 0) return -1;
    if (rc > 0 || tangent(R, &R->b, R->a.t, 1) != 0) {
        R->b = keep;
        return 1;
    }
    return 0;
}

static bool inside(const curve_run *R, const curve_pt *pt) {
    for (int k = 0; k < 2; k++)
        if (pt->lam[k] < R->lo[k] || pt->lam[k] > R->hi[k]) return false;
    return true;
}

/* One side of the curve from R->a (its tangent set). */
static int follow(curve_run *R, int side) {
    const afm_cont_curve_opts *o = R->o;
    const int N = R->c.N;
    const double h_min = o->h_min > 0 ? o->h_min : 1e-6, h_max = o->h_max > 0 ? o->h_max : 0.1;
    const int max_points = o->max_points > 0 ? o->max_points : 400;
    double h = o->h0 > 0 ? o->h0 : 0.02, u0[UMAX];
    scaled_u(R, R->start.y, R->start.lam, u0);
    int points = 0;
    char why[400];
    for (int k = 0; k < 2; k++) { /* a start on an edge, the tangent leading out of it */
        double tk = R->a.t[N + k], lk = R->a.lam[k];
        if ((lk <= R->lo[k] && tk < 0) || (lk >= R->hi[k] && tk > 0)) {
            snprintf(why, sizeof why, "the start is on the edge of the range (%s = %.10g)",
                     k ? R->par2.name : R->c.par.name, lk);
            return emit_end(R, side, 0, why);
        }
    }
    for (;;) {
        if (points >= max_points) {
            snprintf(why, sizeof why, "the most points per side (%d) reached", max_points);
            break;
        }
        int rc = step(R, h);
        if (rc < 0) return -1;
        if (rc > 0) {
            h *= 0.5;
            if (h < h_min) {
                snprintf(why, sizeof why,
                         "step below the minimum %g at %s = %.10g, %s = %.10g: no convergence "
                         "(a degenerate point of the curve, or a contact the corrector cannot "
                         "follow)",
                         h_min, R->c.par.name, R->a.lam[0], R->par2.name, R->a.lam[1]);
                break;
            }
            continue;
        }
        bool out = !inside(R, &R->b);
        int edge = -1;
        if (out) { /* land on the edge; if that corrector fails, a shorter step first */
            int lr = land_on_edge(R, &edge);
            if (lr < 0) return -1;
            if (lr > 0 && h * 0.5 >= h_min) {
                h *= 0.5;
                continue;
            }
        }
        rebord(R, &R->b);
        rc = emit_pt(R, &R->b, side);
        if (rc) return rc;
        points++;
        R->a = R->b;
        if (out) {
            const char *name = edge == 1 ? R->par2.name : R->c.par.name;
            snprintf(why, sizeof why, "reached the edge of the range (%s = %.10g)", name,
                     R->a.lam[edge == 1 ? 1 : 0]);
            break;
        }
        double u[UMAX], d = 0.0;
        scaled_u(R, R->a.y, R->a.lam, u);
        for (int j = 0; j < N + 2; j++)
            d = fmax(d, fabs(u[j] - u0[j]));
        if (points > 10 && d < 0.5 * h) {
            snprintf(why, sizeof why, "closed curve: back at its start");
            break;
        }
        /* By the evaluations it took to come within the coarse tolerances, the predictor's
         * error: those spent after that, waiting for the noise floor to show (r and g
         * scattering, a stagnation test that needs at least one more step and in hard
         * contact took 5-10 in all), say nothing about the step. Grown unless that took
         * more than 5 (4 Newton steps: in hard contact, where g_u comes from differences,
         * Newton converges linearly and takes 4-5 at any step), shrunk from 7: counted over
         * all of them, or grown only up to 4, fig 4-2's period-1 LPC curve kept its first
         * step (0.02 scaled, 0.02-0.2 nm of Z a point) in the dead band between. */
        const int effort = R->a.iters_tol > 0 ? R->a.iters_tol : R->a.iterations;
        if (effort <= 5)
            h = fmin(1.5 * h, h_max);
        else if (effort >= 7)
            h *= 0.7;
    }
    return emit_end(R, side, points, why);
}

/* The start: the bordering vectors from M's eigenvectors at the event (the right and left
 * ones of its multiplier nearest -sgn), then the corrector with lambda_2 fixed. 0 or -1. */
static int start(curve_run *R) {
    const afm_cont_curve_opts *o = R->o;
    const int N = R->c.N;
    double lam[2] = {o->lambda, afm_cont_param_value(&R->c.base, &R->par2)}, G[NMAX];
    curve_pt *s = &R->start;
    if (eval(R, o->y, lam, o->p, G, s) != 0) return -1;
    double MT[NMAX * NMAX], re[NMAX], im[NMAX], V[NMAX * NMAX], W[NMAX * NMAX];
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++)
            MT[i * N + j] = s->M[j * N + i];
    if (afm_la_eigvals(N, s->M, re, im, V) != 0) goto fail;
    int iv = -1, iw = -1;
    double bv = HUGE_VAL, bw = HUGE_VAL;
    for (int i = 0; i < N; i++)
        if (im[i] == 0.0 && fabs(re[i] + R->sgn) < bv) bv = fabs(re[i] + R->sgn), iv = i;
    if (afm_la_eigvals(N, MT, re, im, W) != 0) goto fail;
    for (int i = 0; i < N; i++)
        if (im[i] == 0.0 && fabs(re[i] + R->sgn) < bw) bw = fabs(re[i] + R->sgn), iw = i;
    if (iv < 0 || iw < 0) goto fail;
    for (int i = 0; i < N; i++) {
        s->v[i] = V[i * N + iv] / R->c.ys[i];
        s->w[i] = W[i * N + iw] * R->c.ys[i];
    }
    rebord(R, s);
    int rc = correct(R, o->y, lam, NULL, o->p, G, s); /* the map above is its first */
    if (rc < 0) return -1;
    if (rc > 0) {
        afm_err_set(R->err, R->errlen,
                    "continuation: the %s at %s = %.10g does not refine to a point of its curve "
                    "(orbit residual %.3g, test function %.3g after %d Newton steps)",
                    o->kind == AFM_CONT_LPC ? "LPC" : "PD", R->c.par.name, o->lambda, s->residual,
                    s->g, s->iterations);
        return -1;
    }
    rebord(R, s);
    if (tangent(R, s, NULL, 1) != 0) {
        afm_err_set(R->err, R->errlen,
                    "continuation: the curve's tangent at its start is singular");
        return -1;
    }
    return 0;
fail:
    afm_err_set(R->err, R->errlen,
                "continuation: no real multiplier near %+g at the %s = %.10g to start its curve",
                -R->sgn, R->c.par.name, o->lambda);
    return -1;
}

static int check_opts(const afm_cont_curve_opts *o, char *err, size_t errlen) {
    if (!o->param || !o->param2 || !strcmp(o->param, o->param2) || !o->y ||
        (o->kind != AFM_CONT_LPC && o->kind != AFM_CONT_PD) || o->p < 1 || o->p > AFM_CONT_MAX_P ||
        !isfinite(o->lambda) || !isfinite(o->from) || !isfinite(o->to) || o->from == o->to ||
        !isfinite(o->from2) || !isfinite(o->to2) || o->from2 == o->to2 || o->max_points < 0 ||
        o->h0 < 0 || o->h_min < 0 || o->h_max < 0) {
        afm_err_set(err, errlen,
                    "continuation: a curve needs two different parameters, an LPC or PD start "
                    "with its state, finite ranges of non-zero width, period 1..%d, "
                    "non-negative counts and steps",
                    AFM_CONT_MAX_P);
        return -1;
    }
    return 0;
}

int afm_cont_curve_run(const afm_config *cfg, const afm_cont_curve_opts *o,
                       afm_cont_curve_emit emit, void *ectx, afm_cont_summary *sum, char *err,
                       size_t errlen) {
    memset(sum, 0, sizeof *sum);
    double t0 = afm_cont_now_s();
    if (check_opts(o, err, errlen) != 0) return -1;
    curve_run *R = calloc(1, sizeof *R);
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
    R->sgn = o->kind == AFM_CONT_LPC ? -1.0 : 1.0;
    R->lo[0] = fmin(o->from, o->to);
    R->hi[0] = fmax(o->from, o->to);
    R->lo[1] = fmin(o->from2, o->to2);
    R->hi[1] = fmax(o->from2, o->to2);
    R->ls2 = R->hi[1] - R->lo[1];
    int rc = afm_cont_ctx_init(&R->c, cfg, o->param, R->hi[0] - R->lo[0],
                               o->a_ref_m > 0 ? o->a_ref_m : 1e-9, err, errlen);
    if (rc == 0 && afm_cont_flow_set_sens_rtol(R->c.flow, CURVE_SENS_RTOL) != 0) {
        afm_err_set(err, errlen, "continuation: the flow refused the sensitivities' tolerance");
        rc = -1;
    }
    if (rc == 0) rc = afm_cont_param_parse(&R->c.base, o->param2, &R->par2, err, errlen);
    if (rc == 0) {
        double v2 = afm_cont_param_value(&R->c.base, &R->par2);
        if (!(v2 >= R->lo[1] && v2 <= R->hi[1]) ||
            !(o->lambda >= R->lo[0] && o->lambda <= R->hi[0])) {
            afm_err_set(err, errlen,
                        "continuation: the start (%s = %g, %s = %g) is outside the ranges",
                        o->param, o->lambda, o->param2, v2);
            rc = -1;
        }
    }
    if (rc == 0 && !(o->a_ref_m > 0)) { /* the event orbit's tip amplitude */
        double x = 0.0, v = 0.0, w1 = R->c.base.m.omega_rad_s[0];
        for (int i = 0; i < R->c.n; i++) {
            x += R->c.base.m.tip[i] * o->y[i];
            v += R->c.base.m.tip[i] * o->y[R->c.n + i];
        }
        afm_cont_set_aref(&R->c, fmax(hypot(x, v / w1), 1e-10));
    }
    if (rc == 0) rc = start(R);
    double bb0[NMAX], cb0[NMAX];
    if (rc == 0) {
        memcpy(bb0, R->bb, sizeof bb0);
        memcpy(cb0, R->cb, sizeof cb0);
        rc = emit_pt(R, &R->start, 0);
    }
    for (int side = 0; side < 2 && rc == 0; side++) {
        R->a = R->start;
        memcpy(R->bb, bb0, sizeof bb0);
        memcpy(R->cb, cb0, sizeof cb0);
        if (side == 1)
            for (int j = 0; j < R->c.N + 2; j++)
                R->a.t[j] = -R->a.t[j];
        rc = follow(R, side);
    }
    if (rc > 0) rc = 0; /* stopped by the caller */
    sum->branches = 1;
    sum->maps = R->c.maps;
    if (R->c.flow) sum->flow_steps = afm_cont_flow_get_stats(R->c.flow)->steps;
    sum->seconds = afm_cont_now_s() - t0;
    afm_cont_ctx_free(&R->c);
    free(R);
    return rc;
}
