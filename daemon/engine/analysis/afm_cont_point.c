/* SPDX-License-Identifier: MIT */
/* afm_cont_point.c -- Newton shooting on the period map with CVODES sensitivities, the
 * Floquet multipliers and the tangent (contract in afm_cont_point.h). */
#include "analysis/afm_cont_point.h"

#include "beam/afm_linalg.h"
#include "config/afm_err.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* Relative step of the +-delta instances of the parameter derivative (of ls). */
#define POINT_DELTA 1e-6
/* Default convergence: scaled residual (1e-9 of a_ref of tip motion) */
#define POINT_TOL 1e-9
#define POINT_MAX_ITER 8

int afm_cont_ctx_init(afm_cont_ctx *c, const afm_config *cfg, const char *name, double ls,
                      double a_ref_m, char *err, size_t errlen) {
    memset(c, 0, sizeof *c);
    if (!(ls > 0) || !isfinite(ls) || !(a_ref_m > 0) || !isfinite(a_ref_m)) {
        afm_err_set(err, errlen, "continuation: bad scales (parameter %g, orbit %g m)", ls,
                    a_ref_m);
        return -1;
    }
    if (afm_cont_base_init(&c->base, cfg, err, errlen) != 0) return -1;
    if (afm_cont_param_parse(&c->base, name, &c->par, err, errlen) != 0) return -1;
    c->n = c->base.m.n;
    c->N = 2 * c->n;
    c->ls = ls;
    c->a_ref_m = a_ref_m;
    c->tol = POINT_TOL;
    c->max_iter = POINT_MAX_ITER;
    c->flow = afm_cont_flow_create(c->n, cfg->sim.ref_rtol, err, errlen);
    if (!c->flow) return -1;
    afm_cont_set_aref(c, a_ref_m);
    return 0;
}

void afm_cont_set_aref(afm_cont_ctx *c, double a_ref_m) {
    if (!(a_ref_m > 0) || !isfinite(a_ref_m)) return;
    double w[AFM_CONT_MAX_N];
    afm_cont_flow_weights(&c->base.m, w);
    c->a_ref_m = a_ref_m;
    for (int i = 0; i < c->N; i++)
        c->ys[i] = a_ref_m / w[i];
    afm_cont_flow_set_scale(c->flow, a_ref_m);
}

double afm_cont_now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void afm_cont_ctx_free(afm_cont_ctx *c) {
    afm_cont_flow_destroy(&c->flow);
}

int afm_cont_set_lambda(afm_cont_ctx *c, double lambda, char *err, size_t errlen) {
    afm_cont_inst at, plus, minus;
    double d = POINT_DELTA * c->ls, lp = lambda + d, lm = lambda - d;
    if (afm_cont_inst_at(&c->base, &c->par, &lambda, 1, &at, err, errlen) != 0) return -1;
    /* at the edge of the range, a one-sided difference */
    if (afm_cont_inst_at(&c->base, &c->par, &lp, 1, &plus, err, errlen) != 0) {
        lp = lambda;
        plus = at;
    }
    if (afm_cont_inst_at(&c->base, &c->par, &lm, 1, &minus, err, errlen) != 0) {
        lm = lambda;
        minus = at;
    }
    double dpar = lp - lm;
    if (afm_cont_flow_set_model(c->flow, &at, 1, &plus, &minus, &dpar) != 0) {
        afm_err_set(err, errlen, "continuation: %s = %g changes the model's force terms",
                    c->par.name, lambda);
        return -1;
    }
    return 0;
}

int afm_cont_settle(afm_cont_ctx *c, double lambda, double *y, int periods, char *err,
                    size_t errlen) {
    if (afm_cont_set_lambda(c, lambda, err, errlen) != 0) return -1;
    while (periods > 0) {
        int k = periods < AFM_CONT_MAX_P ? periods : AFM_CONT_MAX_P;
        double y1[AFM_CONT_MAX_N];
        if (afm_cont_flow_map(c->flow, y, k, 0, NULL, false, y1, NULL, NULL, err, errlen) != 0)
            return -1;
        memcpy(y, y1, sizeof(double) * (size_t)c->N);
        periods -= k;
    }
    return 0;
}

void afm_cont_scaled(const afm_cont_ctx *c, const double *y, double lambda, double *u) {
    for (int i = 0; i < c->N; i++)
        u[i] = y[i] / c->ys[i];
    u[c->N] = lambda / c->ls;
}

/* One map with sensitivities at (y, lambda): G = y(pT) - y, M, fl; y_half. */
static int eval(afm_cont_ctx *c, const double *y, double lambda, int p, double *G, double *M,
                double *fl, double *y_half, char *err, size_t errlen) {
    const int N = c->N, ns = N + 1;
    if (afm_cont_set_lambda(c, lambda, err, errlen) != 0) return -1;
    double V[AFM_CONT_MAX_N * AFM_CONT_MAX_N], S[AFM_CONT_MAX_N * AFM_CONT_MAX_U],
        y1[AFM_CONT_MAX_N];
    double poinc[AFM_CONT_MAX_P * AFM_CONT_MAX_N];
    memset(V, 0, sizeof(double) * (size_t)(N * N));
    for (int i = 0; i < N; i++)
        V[i * N + i] = 1.0;
    c->maps++;
    if (afm_cont_flow_map(c->flow, y, p, N, V, true, y1, S, poinc, err, errlen) != 0) return -1;
    for (int i = 0; i < N; i++) {
        G[i] = y1[i] - y[i];
        for (int j = 0; j < N; j++)
            M[i * N + j] = S[i * ns + j];
        fl[i] = S[i * ns + N];
    }
    if (p % 2 == 0)
        memcpy(y_half, poinc + (size_t)(p / 2 - 1) * (size_t)N, sizeof(double) * (size_t)N);
    else
        memcpy(y_half, y, sizeof(double) * (size_t)N);
    return 0;
}

/* The scaled extended Jacobian [D^-1 (M - I) D, D^-1 fl ls] (N x (N + 1)) into A's first N
 * rows (row-major, N + 1 columns). */
static void scaled_jacobian(const afm_cont_ctx *c, const double *M, const double *fl, double *A) {
    const int N = c->N, U = N + 1;
    for (int i = 0; i < N; i++) {
        for (int j = 0; j < N; j++)
            A[i * U + j] = (M[i * N + j] - (i == j ? 1.0 : 0.0)) * c->ys[j] / c->ys[i];
        A[i * U + N] = fl[i] * c->ls / c->ys[i];
    }
}

int afm_cont_correct(afm_cont_ctx *c, const double *y_pred, double lambda_pred, const double *cn,
                     int p, afm_cont_pt *out, char *err, size_t errlen) {
    const int N = c->N, U = N + 1;
    double u_pred[AFM_CONT_MAX_U], en[AFM_CONT_MAX_U];
    afm_cont_scaled(c, y_pred, lambda_pred, u_pred);
    if (!cn) {
        memset(en, 0, sizeof(double) * (size_t)U);
        en[N] = 1.0;
        cn = en;
    }
    double y[AFM_CONT_MAX_N], lambda = lambda_pred, G[AFM_CONT_MAX_N];
    memcpy(y, y_pred, sizeof(double) * (size_t)N);
    out->p = p;
    double last = HUGE_VAL;
    for (int it = 1; it <= c->max_iter; it++) {
        if (eval(c, y, lambda, p, G, out->M, out->fl, out->y_half, err, errlen) != 0) {
            /* a map that fails off the branch (a runaway predictor) is a failed corrector */
            return it == 1 ? -1 : 1;
        }
        double r = 0.0;
        for (int i = 0; i < N; i++)
            r = fmax(r, fabs(G[i] / c->ys[i]));
        out->residual = r;
        out->iterations = it;
        memcpy(out->y, y, sizeof(double) * (size_t)N);
        out->lambda = lambda;
        if (r < c->tol) {
            afm_la_eigvals(N, out->M, out->mult_re, out->mult_im, NULL);
            return 0;
        }
        if (!isfinite(r) || (it > 2 && r > 2.0 * last && !(c->max_du > 0))) return 1;
        last = r;
        double A[AFM_CONT_MAX_U * AFM_CONT_MAX_U], b[AFM_CONT_MAX_U], u[AFM_CONT_MAX_U];
        scaled_jacobian(c, out->M, out->fl, A);
        afm_cont_scaled(c, y, lambda, u);
        double g = 0.0;
        for (int j = 0; j < U; j++) {
            A[N * U + j] = cn[j];
            g += cn[j] * (u[j] - u_pred[j]);
        }
        for (int i = 0; i < N; i++)
            b[i] = -G[i] / c->ys[i];
        b[N] = -g;
        if (afm_la_solve(U, A, b) != 0) return 1;
        double bn = 0.0; /* a damped step where asked for (branch switching) */
        for (int j = 0; j < U; j++)
            bn = fmax(bn, fabs(b[j]));
        if (c->max_du > 0 && bn > c->max_du)
            for (int j = 0; j < U; j++)
                b[j] *= c->max_du / bn;
        for (int i = 0; i < N; i++)
            y[i] += b[i] * c->ys[i];
        lambda += b[N] * c->ls;
        if (!isfinite(lambda)) return 1;
    }
    return 1;
}

int afm_cont_tangent(const afm_cont_ctx *c, afm_cont_pt *pt, const double *ref, int dir) {
    const int N = c->N, U = N + 1;
    double A[AFM_CONT_MAX_U * AFM_CONT_MAX_U], b[AFM_CONT_MAX_U];
    scaled_jacobian(c, pt->M, pt->fl, A);
    /* the last row: ref, or (without one) e_lambda, which fails only at a fold */
    for (int j = 0; j < U; j++) {
        A[N * U + j] = ref ? ref[j] : (j == N ? 1.0 : 0.0);
        b[j] = 0.0;
    }
    b[N] = 1.0;
    if (afm_la_solve(U, A, b) != 0) return -1;
    double nn = 0.0;
    for (int j = 0; j < U; j++)
        nn += b[j] * b[j];
    nn = sqrt(nn);
    if (!(nn > 0) || !isfinite(nn)) return -1;
    double s = 0.0;
    for (int j = 0; j < U; j++)
        s += (ref ? ref[j] : (j == N ? (double)dir : 0.0)) * b[j];
    double sg = s < 0 ? -1.0 : 1.0;
    for (int j = 0; j < U; j++)
        pt->t[j] = sg * b[j] / nn;
    return 0;
}

bool afm_cont_stable(const afm_cont_ctx *c, const afm_cont_pt *pt) {
    for (int i = 0; i < c->N; i++)
        if (hypot(pt->mult_re[i], pt->mult_im[i]) >= 1.0) return false;
    return true;
}
