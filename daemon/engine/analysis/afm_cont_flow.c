/* SPDX-License-Identifier: MIT */
/* afm_cont_flow.c -- the period map and its sensitivities by CVODES, kinks located by root
 * finding (contract in afm_cont_flow.h). */
#include "analysis/afm_cont_flow_impl.h"

#include <cvodes/cvodes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Default relative tolerance (the reference integrator's). */
#define FLOW_DEFAULT_RTOL 1e-10
/* atol(q_i) = rtol FLOW_X_REF / |tip_i|, as afm_sundials.c. */
#define FLOW_X_REF 1e-9
/* Longest step, drive periods: the sensitivities are outside the error test (see
 * afm_cont_flow.h), so the step must resolve the second mode (6.3 oscillations per period on
 * the Fig. 4.2 beam: 300 steps each); and a contact (typically 5% of a period) cannot hide
 * inside one step, where the root finder, which compares the kinks' signs at step ends,
 * would miss it. In contact the error test takes ~1500 steps per period anyway. */
#define FLOW_MAX_STEP 0.0005
#define FLOW_MAX_STEPS 2000000L

static void flow_err_handler(int code, const char *module, const char *function, char *msg,
                             void *data) {
    afm_cont_flow *f = data;
    snprintf(f->msg, sizeof f->msg, "%s %s (%d): %s", module ? module : "?",
             function ? function : "?", code, msg ? msg : "");
}

void afm_cont_flow_weights(const afm_modal *m, double *w) {
    double tmax = 0.0;
    for (int i = 0; i < m->n; i++)
        tmax = fmax(tmax, fabs(m->tip[i]));
    for (int i = 0; i < m->n; i++) {
        double t = fmax(fabs(m->tip[i]), 1e-3 * tmax);
        w[i] = t;
        w[m->n + i] = t / m->omega_rad_s[i];
    }
}

static int flow_rhs(double tau, N_Vector y, N_Vector ydot, void *user) {
    const afm_cont_flow *f = user;
    double *dy = N_VGetArrayPointer(ydot);
    double F = flow_vf(&f->at, tau, N_VGetArrayPointer(y), dy, NULL, NULL, NULL, NULL);
    if (!isfinite(F)) return -1;
    for (int i = 0; i < f->N; i++)
        if (!isfinite(dy[i])) return -1;
    return 0;
}

/* The tip force's partials at state y of instance I. */
static void force_partials(const afm_cont_inst *I, const double *y, double *kx, double *kv) {
    const int n = I->m.n;
    double x = 0.0, v = 0.0;
    for (int i = 0; i < n; i++) {
        x += I->m.tip[i] * y[i];
        v += I->m.tip[i] * y[n + i];
    }
    afm_force_tip(&I->f, I->z_m, x, v, kx, kv);
}

/* Analytic Jacobian in phase time: (1 / fe) [[0, I], [-w^2 + tip tip^T Fx, -2 xi w + tip
 * tip^T Fv]]. */
static int flow_jac(double tau, N_Vector y, N_Vector fy, SUNMatrix J, void *user, N_Vector t1,
                    N_Vector t2, N_Vector t3) {
    (void)tau;
    (void)fy;
    (void)t1;
    (void)t2;
    (void)t3;
    const afm_cont_flow *f = user;
    const afm_modal *m = &f->at.m;
    const int n = m->n;
    double kx, kv, ife = 1.0 / f->at.fe_hz;
    force_partials(&f->at, N_VGetArrayPointer(y), &kx, &kv);
    if (!isfinite(kx) || !isfinite(kv)) return -1;
    SUNMatZero(J);
    for (int i = 0; i < n; i++) {
        double w = m->omega_rad_s[i];
        SM_ELEMENT_D(J, i, n + i) = ife;
        for (int j = 0; j < n; j++) {
            double tt = m->tip[i] * m->tip[j] * ife;
            SM_ELEMENT_D(J, n + i, j) = tt * kx;
            SM_ELEMENT_D(J, n + i, n + j) = tt * kv;
        }
        SM_ELEMENT_D(J, n + i, i) -= w * w * ife;
        SM_ELEMENT_D(J, n + i, n + i) -= 2.0 * m->xi[i] * w * ife;
    }
    return 0;
}

/* s' = J s for the state directions, J s + df/dp_k for the parameters. */
static int flow_sens_rhs(int ns, double tau, N_Vector y, N_Vector ydot, N_Vector *yS,
                         N_Vector *ySdot, void *user, N_Vector t1, N_Vector t2) {
    (void)ydot;
    (void)t1;
    (void)t2;
    const afm_cont_flow *f = user;
    const afm_modal *m = &f->at.m;
    const int n = m->n, N = f->N;
    const double *yv = N_VGetArrayPointer(y);
    double kx, kv, ife = 1.0 / f->at.fe_hz;
    force_partials(&f->at, yv, &kx, &kv);
    if (!isfinite(kx) || !isfinite(kv)) return -1;
    double dfp[AFM_CONT_MAX_PAR][AFM_CONT_MAX_N];
    for (int k = 0; k < f->ns_par; k++) {
        double a[AFM_CONT_MAX_N], b[AFM_CONT_MAX_N];
        flow_vf(&f->plus[k], tau, yv, a, NULL, NULL, NULL, NULL);
        flow_vf(&f->minus[k], tau, yv, b, NULL, NULL, NULL, NULL);
        for (int i = 0; i < N; i++)
            dfp[k][i] = (a[i] - b[i]) / f->dpar[k];
    }
    for (int s = 0; s < ns; s++) {
        const double *sv = N_VGetArrayPointer(yS[s]);
        double *ds = N_VGetArrayPointer(ySdot[s]);
        double sx = 0.0, su = 0.0;
        for (int i = 0; i < n; i++) {
            sx += m->tip[i] * sv[i];
            su += m->tip[i] * sv[n + i];
        }
        double fs = kx * sx + kv * su;
        for (int i = 0; i < n; i++) {
            double w = m->omega_rad_s[i];
            ds[i] = sv[n + i] * ife;
            ds[n + i] = (m->tip[i] * fs - 2.0 * m->xi[i] * w * sv[n + i] - w * w * sv[i]) * ife;
        }
        int k = s - f->ns_state;
        if (k >= 0)
            for (int i = 0; i < N; i++)
                ds[i] += dfp[k][i];
        for (int i = 0; i < N; i++)
            if (!isfinite(ds[i])) return -1;
    }
    return 0;
}

/* Kinks: x - x_k. */
static int flow_g_kinks(double tau, N_Vector y, double *g, void *user) {
    (void)tau;
    const afm_cont_flow *f = user;
    const double *yv = N_VGetArrayPointer(y);
    double x = 0.0;
    for (int i = 0; i < f->n; i++)
        x += f->at.m.tip[i] * yv[i];
    for (int k = 0; k < f->nk; k++)
        g[k] = x - f->x_kink[k];
    return 0;
}

/* The kinks, then the tip velocity (x extrema) and dF_ts/dtau (extrema of the tip-sample
 * force: the total less the squeeze film). */
static int flow_g_metric(double tau, N_Vector y, double *g, void *user) {
    const afm_cont_flow *f = user;
    const double *yv = N_VGetArrayPointer(y);
    double dy[AFM_CONT_MAX_N], kx, kv, x, v, sx, sv;
    flow_vf(&f->at, tau, yv, dy, &kx, &kv, &x, &v);
    flow_squeeze(&f->at, x, v, &sx, &sv);
    kx -= sx;
    kv -= sv;
    double dv = 0.0;
    for (int i = 0; i < f->n; i++)
        dv += f->at.m.tip[i] * dy[f->n + i];
    for (int k = 0; k < f->nk; k++)
        g[k] = x - f->x_kink[k];
    g[f->nk] = v;
    g[f->nk + 1] = kx * v / f->at.fe_hz + kv * dv;
    return 0;
}

/* int x dtau, x sin(2 pi tau), x cos(2 pi tau); int F_ts v dt, F_ts x dt, F_sq v dt
 * (dt = dtau / fe; F_ts the tip-sample force, F_sq the squeeze film's). */
static int flow_quad(double tau, N_Vector y, N_Vector yQdot, void *user) {
    const afm_cont_flow *f = user;
    double dy[AFM_CONT_MAX_N], x, v, sx, sv;
    double F = flow_vf(&f->at, tau, N_VGetArrayPointer(y), dy, NULL, NULL, &x, &v);
    double Fs = flow_squeeze(&f->at, x, v, &sx, &sv);
    F -= Fs;
    double *q = N_VGetArrayPointer(yQdot), th = 6.283185307179586476925286766559 * tau;
    q[0] = x;
    q[1] = x * sin(th);
    q[2] = x * cos(th);
    q[3] = F * v / f->at.fe_hz;
    q[4] = F * x / f->at.fe_hz;
    q[5] = Fs * v / f->at.fe_hz;
    return isfinite(F) ? 0 : -1;
}

afm_cont_flow *afm_cont_flow_create(int n_modes, double rtol, char *err, size_t errlen) {
    if (rtol == 0) rtol = FLOW_DEFAULT_RTOL;
    if (n_modes < 1 || n_modes > AFM_MAX_MODES || !(rtol >= 1e-14 && rtol <= 1e-3)) {
        snprintf(err, errlen, "flow: %d modes (1..%d), rtol %g (1e-14..1e-3)", n_modes,
                 AFM_MAX_MODES, rtol);
        return NULL;
    }
    afm_cont_flow *f = calloc(1, sizeof *f);
    if (!f) {
        snprintf(err, errlen, "flow: out of memory");
        return NULL;
    }
    f->n = n_modes;
    f->N = 2 * n_modes;
    f->rtol = rtol;
    f->a_ref = 1e-8;
    if (SUNContext_Create(NULL, &f->ctx) != 0) {
        snprintf(err, errlen, "flow: SUNContext_Create failed");
        free(f);
        return NULL;
    }
    f->y = N_VNew_Serial(f->N, f->ctx);
    f->atol = N_VNew_Serial(f->N, f->ctx);
    if (!f->y || !f->atol) {
        snprintf(err, errlen, "flow: N_VNew_Serial failed");
        afm_cont_flow_destroy(&f);
        return NULL;
    }
    return f;
}

static void engine_free(flow_engine *e) {
    if (e->mem) CVodeFree(&e->mem);
    if (e->yS) N_VDestroyVectorArray(e->yS, e->ns);
    if (e->yQ) N_VDestroy(e->yQ);
    if (e->ls) SUNLinSolFree(e->ls);
    if (e->A) SUNMatDestroy(e->A);
    memset(e, 0, sizeof *e);
}

void afm_cont_flow_destroy(afm_cont_flow **fp) {
    if (!fp || !*fp) return;
    afm_cont_flow *f = *fp;
    for (int i = 0; i < f->n_eng; i++)
        engine_free(&f->eng[i]);
    if (f->y) N_VDestroy(f->y);
    if (f->atol) N_VDestroy(f->atol);
    if (f->ctx) SUNContext_Free(&f->ctx);
    free(f);
    *fp = NULL;
}

/* The kinks of instance I (tip positions). */
static int kinks_of(const afm_cont_inst *I, double *xk) {
    const afm_force_params *p = &I->f;
    int nk = 0;
    double xc = afm_cont_inst_contact_x(I);
    if (isfinite(xc)) xk[nk++] = xc;
    if (p->electrostatic && 0.25 * p->es_cone_m > p->a0_m)
        xk[nk++] = (0.25 * p->es_cone_m - I->z_m) / p->cos_alpha;
    if (p->squeeze == AFM_SQUEEZE_LINEAR && p->p1 != 0.0) xk[nk++] = -p->p2 / p->p1 - I->z_m;
    return nk;
}

int afm_cont_flow_set_model(afm_cont_flow *f, const afm_cont_inst *at, int np,
                            const afm_cont_inst *plus, const afm_cont_inst *minus,
                            const double *dpar) {
    if (at->m.n != f->n || np < 0 || np > AFM_CONT_MAX_PAR || !(at->fe_hz > 0)) return -1;
    for (int k = 0; k < np; k++)
        if (plus[k].m.n != f->n || minus[k].m.n != f->n || !(dpar[k] != 0) || !isfinite(dpar[k]))
            return -1;
    double xk[FLOW_MAX_KINKS];
    int nk = kinks_of(at, xk);
    if (f->have_model && nk != f->nk) return -1; /* engines are made for f->nk roots */
    f->at = *at;
    for (int k = 0; k < np; k++) {
        f->plus[k] = plus[k];
        f->minus[k] = minus[k];
        f->dpar[k] = dpar[k];
    }
    f->np = np;
    f->nk = nk;
    memcpy(f->x_kink, xk, sizeof xk);
    afm_cont_flow_weights(&at->m, f->w);
    double *av = N_VGetArrayPointer(f->atol);
    for (int i = 0; i < f->n; i++) {
        av[i] = f->rtol * FLOW_X_REF / f->w[i];
        av[f->n + i] = av[i] * at->m.omega_rad_s[i];
    }
    f->have_model = true;
    return 0;
}

int afm_cont_flow_set_sens_rtol(afm_cont_flow *f, double rtol_sens) {
    if (f->n_eng > 0 || !(rtol_sens >= 0 && rtol_sens <= 1e-3)) return -1;
    f->rtol_sens = rtol_sens;
    return 0;
}

void afm_cont_flow_set_scale(afm_cont_flow *f, double a_ref_m) {
    if (a_ref_m > 0 && isfinite(a_ref_m)) f->a_ref = a_ref_m;
}

const afm_cont_flow_stats *afm_cont_flow_get_stats(const afm_cont_flow *f) {
    return &f->st;
}

const afm_cont_inst *afm_cont_flow_inst(const afm_cont_flow *f) {
    return &f->at;
}

static int engine_init(afm_cont_flow *f, flow_engine *e, int ns, bool metric) {
    e->ns = ns;
    e->metric = metric;
    N_VConst(0.0, f->y);
    e->mem = CVodeCreate(CV_BDF, f->ctx);
    if (!e->mem || CVodeSetErrHandlerFn(e->mem, flow_err_handler, f) != CV_SUCCESS ||
        CVodeInit(e->mem, flow_rhs, 0.0, f->y) != CV_SUCCESS ||
        CVodeSVtolerances(e->mem, f->rtol, f->atol) != CV_SUCCESS ||
        CVodeSetUserData(e->mem, f) != CV_SUCCESS ||
        CVodeSetMaxNumSteps(e->mem, FLOW_MAX_STEPS) != CV_SUCCESS ||
        CVodeSetMaxStep(e->mem, FLOW_MAX_STEP) != CV_SUCCESS)
        return -1;
    e->A = SUNDenseMatrix(f->N, f->N, f->ctx);
    e->ls = e->A ? SUNLinSol_Dense(f->y, e->A, f->ctx) : NULL;
    if (!e->ls || CVodeSetLinearSolver(e->mem, e->ls, e->A) != CV_SUCCESS ||
        CVodeSetJacFn(e->mem, flow_jac) != CV_SUCCESS)
        return -1;
    int nr = f->nk + (metric ? FLOW_METRIC_ROOTS : 0);
    if (nr > 0) {
        if (CVodeRootInit(e->mem, nr, metric ? flow_g_metric : flow_g_kinks) != CV_SUCCESS)
            return -1;
        CVodeSetNoInactiveRootWarn(e->mem);
    }
    if (ns > 0) {
        e->yS = N_VCloneVectorArray(ns, f->y);
        N_Vector *aS = N_VCloneVectorArray(ns, f->atol);
        if (!e->yS || !aS) {
            if (aS) N_VDestroyVectorArray(aS, ns);
            return -1;
        }
        for (int s = 0; s < ns; s++) {
            N_VConst(0.0, e->yS[s]);
            N_VScale(f->rtol_sens > 0 ? f->rtol_sens / f->rtol : 1.0, f->atol, aS[s]);
        }
        int rc = CVodeSensInit(e->mem, ns, CV_STAGGERED, flow_sens_rhs, e->yS);
        bool con = f->rtol_sens > 0;
        if (rc == CV_SUCCESS) rc = CVodeSensSVtolerances(e->mem, con ? f->rtol_sens : f->rtol, aS);
        if (rc == CV_SUCCESS) rc = CVodeSetSensErrCon(e->mem, con ? SUNTRUE : SUNFALSE);
        N_VDestroyVectorArray(aS, ns);
        if (rc != CV_SUCCESS) return -1;
    }
    if (metric) {
        e->yQ = N_VNew_Serial(FLOW_METRIC_QUADS, f->ctx);
        if (!e->yQ) return -1;
        N_VConst(0.0, e->yQ);
        if (CVodeQuadInit(e->mem, flow_quad, e->yQ) != CV_SUCCESS ||
            CVodeSetQuadErrCon(e->mem, SUNFALSE) != CV_SUCCESS)
            return -1;
    }
    return 0;
}

flow_engine *afm_cont_flow_engine(afm_cont_flow *f, int ns, bool metric) {
    for (int i = 0; i < f->n_eng; i++)
        if (f->eng[i].ns == ns && f->eng[i].metric == metric) return &f->eng[i];
    if (f->n_eng == FLOW_MAX_ENGINES || !f->have_model) {
        snprintf(f->msg, sizeof f->msg, "flow: no model set, or too many kinds of runs");
        return NULL;
    }
    flow_engine *e = &f->eng[f->n_eng];
    if (engine_init(f, e, ns, metric) != 0) {
        if (!f->msg[0]) snprintf(f->msg, sizeof f->msg, "flow: CVODES set-up failed");
        engine_free(e);
        return NULL;
    }
    f->n_eng++;
    return e;
}

/* The engine's counters since its last (re)initialisation into the totals. */
static void add_stats(afm_cont_flow *f, flow_engine *e) {
    long nst = 0, nfe = 0;
    CVodeGetNumSteps(e->mem, &nst);
    CVodeGetNumRhsEvals(e->mem, &nfe);
    f->st.steps += nst;
    f->st.rhs += nfe;
}

/* Restart e at tau from y (and its current yS, yQ). */
static int restart(afm_cont_flow *f, flow_engine *e, double tau, double *yv) {
    memcpy(N_VGetArrayPointer(f->y), yv, sizeof(double) * (size_t)f->N);
    if (CVodeReInit(e->mem, tau, f->y) != CV_SUCCESS) return -1;
    if (e->ns > 0 && CVodeSensReInit(e->mem, CV_STAGGERED, e->yS) != CV_SUCCESS) return -1;
    if (e->metric && CVodeQuadReInit(e->mem, e->yQ) != CV_SUCCESS) return -1;
    return 0;
}

int afm_cont_flow_integrate(afm_cont_flow *f, flow_engine *e, double *y, int p, double *poinc,
                            flow_root_hook hook, void *hook_ctx, char *err, size_t errlen) {
    const int N = f->N;
    f->msg[0] = '\0';
    f->st.maps++;
    if (e->ns > 0) f->st.sens_maps++;
    double tau = 0.0;
    if (restart(f, e, 0.0, y) != 0) goto fail;
    if (hook) hook(hook_ctx, 0.0, y, NULL);
    int info[FLOW_MAX_KINKS + FLOW_METRIC_ROOTS];
    for (int k = 1; k <= p; k++) {
        if (CVodeSetStopTime(e->mem, (double)k) != CV_SUCCESS) goto fail;
        while (tau < (double)k) {
            int flag = CVode(e->mem, (double)k, f->y, &tau, CV_NORMAL);
            if (flag < 0) goto fail;
            double *yv = N_VGetArrayPointer(f->y);
            if (flag != CV_ROOT_RETURN) continue;
            if (CVodeGetRootInfo(e->mem, info) != CV_SUCCESS) goto fail;
            if (hook) hook(hook_ctx, tau, yv, info);
            bool kink = false;
            for (int j = 0; j < f->nk; j++)
                kink |= info[j] != 0;
            if (!kink) continue;
            /* a kink: restart from here, the sensitivities and quadratures carried over */
            f->st.crossings++;
            if (e->ns > 0 && CVodeGetSens(e->mem, &tau, e->yS) != CV_SUCCESS) goto fail;
            if (e->metric && CVodeGetQuad(e->mem, &tau, e->yQ) != CV_SUCCESS) goto fail;
            add_stats(f, e);
            double yk[AFM_CONT_MAX_N];
            memcpy(yk, yv, sizeof(double) * (size_t)N);
            if (restart(f, e, tau, yk) != 0) goto fail;
            if (CVodeSetStopTime(e->mem, (double)k) != CV_SUCCESS) goto fail;
        }
        if (poinc)
            memcpy(poinc + (size_t)(k - 1) * (size_t)N, N_VGetArrayPointer(f->y),
                   sizeof(double) * (size_t)N);
    }
    if (e->ns > 0 && CVodeGetSens(e->mem, &tau, e->yS) != CV_SUCCESS) goto fail;
    if (e->metric && CVodeGetQuad(e->mem, &tau, e->yQ) != CV_SUCCESS) goto fail;
    add_stats(f, e);
    memcpy(y, N_VGetArrayPointer(f->y), sizeof(double) * (size_t)N);
    for (int i = 0; i < N; i++)
        if (!isfinite(y[i])) {
            snprintf(err, errlen, "flow: the state is not finite after %d periods", p);
            return -1;
        }
    return 0;
fail:
    add_stats(f, e);
    snprintf(err, errlen, "flow: CVODES failed at phase %.6f of %d periods%s%s", tau, p,
             f->msg[0] ? ": " : "", f->msg);
    return -1;
}

int afm_cont_flow_map(afm_cont_flow *f, const double *y0, int p, int nd, const double *V, bool par,
                      double *y, double *S, double *poinc, char *err, size_t errlen) {
    const int N = f->N;
    int npar = par ? f->np : 0, ns = nd + npar;
    if (!f->have_model || p < 1 || p > AFM_CONT_MAX_P || nd < 0 || nd > AFM_CONT_MAX_N ||
        (ns > 0 && !S)) {
        snprintf(err, errlen, "flow: no model, or bad periods (1..%d) or directions",
                 AFM_CONT_MAX_P);
        return -1;
    }
    flow_engine *e = afm_cont_flow_engine(f, ns, false);
    if (!e) {
        snprintf(err, errlen, "%s", f->msg);
        return -1;
    }
    f->ns_state = nd;
    f->ns_par = npar;
    double c[FLOW_MAX_SENS];
    for (int j = 0; j < nd; j++) {
        double nv = 0.0;
        for (int i = 0; i < N; i++)
            nv += f->w[i] * fabs(V[i * nd + j]);
        c[j] = nv > 0 ? f->a_ref / nv : 1.0;
        double *s = N_VGetArrayPointer(e->yS[j]);
        for (int i = 0; i < N; i++)
            s[i] = c[j] * V[i * nd + j];
    }
    for (int k = 0; k < npar; k++) {
        c[nd + k] = 1.0;
        N_VConst(0.0, e->yS[nd + k]);
    }
    memcpy(y, y0, sizeof(double) * (size_t)N);
    if (afm_cont_flow_integrate(f, e, y, p, poinc, NULL, NULL, err, errlen) != 0) return -1;
    for (int j = 0; j < ns; j++) {
        const double *s = N_VGetArrayPointer(e->yS[j]);
        for (int i = 0; i < N; i++)
            S[i * ns + j] = s[i] / c[j];
    }
    return 0;
}
