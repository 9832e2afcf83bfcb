/* SPDX-License-Identifier: MIT */
/* afm_cont_flow_impl.h -- private: the flow's struct, its CVODES engines and the vector
 * field in phase time, shared by afm_cont_flow.c (period maps, sensitivities) and
 * afm_cont_metrics.c (the metric pass). Contract: afm_cont_flow.h. */
#ifndef AFM_CONT_FLOW_IMPL_H
#define AFM_CONT_FLOW_IMPL_H

#include "analysis/afm_cont_flow.h"
#include "forces/afm_force_inline.h"

#include <math.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#define FLOW_MAX_KINKS 3    /* contact line, electrostatic cut-off, linear squeeze zero */
#define FLOW_METRIC_ROOTS 2 /* tip velocity (x extrema), dF/dtau (force extrema) */
#define FLOW_METRIC_QUADS 6 /* int x, x sin, x cos dtau; int F_ts v, F_ts x, F_sq v dt */
#define FLOW_MAX_ENGINES 8
#define FLOW_MAX_SENS (AFM_CONT_MAX_N + AFM_CONT_MAX_PAR)

/* One CVODES instance: a fixed number of sensitivities, roots and quadratures. */
typedef struct {
    void *mem;
    int ns;      /* sensitivities */
    bool metric; /* metric roots and quadratures on */
    SUNMatrix A;
    SUNLinearSolver ls;
    N_Vector *yS; /* ns vectors */
    N_Vector yQ;  /* quadratures (metric) */
} flow_engine;

struct afm_cont_flow {
    SUNContext ctx;
    int n, N; /* modes, state size 2n */
    double rtol;
    double rtol_sens; /* > 0: the sensitivities in the error test at this rtol */
    N_Vector y, atol;
    afm_cont_inst at, plus[AFM_CONT_MAX_PAR], minus[AFM_CONT_MAX_PAR];
    double dpar[AFM_CONT_MAX_PAR];
    int np;
    bool have_model;
    int nk;                        /* kinks located */
    double x_kink[FLOW_MAX_KINKS]; /* their tip positions (m) */
    int ns_state, ns_par;          /* of the current run: state directions, parameters */
    double a_ref;                  /* orbit size for the direction scaling (m) */
    double w[AFM_CONT_MAX_N];      /* tip weights (afm_cont_flow_weights) */
    flow_engine eng[FLOW_MAX_ENGINES];
    int n_eng;
    afm_cont_flow_stats st;
    char msg[256]; /* last CVODES error message */
};

/* The squeeze film's part of the tip force at (x, v) (N; afm_force_squeeze_term), *sx, *sv
 * its partials: the metrics report the tip-sample force, the total less this (issue 30). */
static inline double flow_squeeze(const afm_cont_inst *I, double x, double v, double *sx,
                                  double *sv) {
    return afm_force_squeeze_term(&I->f, I->z_m, x, v, sx, sv);
}

/* The vector field of instance I at phase time tau: dy (2n). Returns the tip force; *fx, *fv
 * (may be NULL) its partials, *x, *v (may be NULL) the tip displacement and velocity. */
static inline double flow_vf(const afm_cont_inst *I, double tau, const double *y, double *dy,
                             double *fx, double *fv, double *xo, double *vo) {
    const afm_modal *m = &I->m;
    const int n = m->n;
    const double *q = y, *u = y + n;
    double x = 0.0, v = 0.0;
    for (int i = 0; i < n; i++) {
        x += m->tip[i] * q[i];
        v += m->tip[i] * u[i];
    }
    double kx, kv;
    double F = afm_force_tip(&I->f, I->z_m, x, v, &kx, &kv);
    const double two_pi = 6.283185307179586476925286766559;
    double sn = sin(two_pi * tau), we = two_pi * I->fe_hz, ife = 1.0 / I->fe_hz;
    double ub = I->ae_m * sn, acc = -we * we * ub;
    for (int i = 0; i < n; i++) {
        double w = m->omega_rad_s[i];
        dy[i] = u[i] * ife;
        dy[n + i] = (m->tip[i] * F - 2.0 * m->xi[i] * w * u[i] - w * w * q[i] - m->base_k[i] * ub -
                     m->base_m[i] * acc) *
                    ife;
    }
    if (fx) *fx = kx;
    if (fv) *fv = kv;
    if (xo) *xo = x;
    if (vo) *vo = v;
    return F;
}

/* The engine with ns sensitivities (metric: the metric pass's), created on first use. NULL
 * with f->msg on failure. */
flow_engine *afm_cont_flow_engine(afm_cont_flow *f, int ns, bool metric);

/* Called at every root return of the metric pass (info: CVodeGetRootInfo's, entries
 * 0..nk-1 the kinks, then the metric roots) and once at tau = 0 with info NULL. */
typedef void (*flow_root_hook)(void *ctx, double tau, const double *y, const int *info);

/* Integrate engine e from y (2n, overwritten with the state at tau = p), restarting at every
 * kink crossing; the sensitivities start from f->eng's yS as set by the caller; poinc
 * (may be NULL) gets the state after each period. hook (metric engine) is called at each
 * root. 0 or -1 with err. */
int afm_cont_flow_integrate(afm_cont_flow *f, flow_engine *e, double *y, int p, double *poinc,
                            flow_root_hook hook, void *hook_ctx, char *err, size_t errlen);

#endif
