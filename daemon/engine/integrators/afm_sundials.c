/* SPDX-License-Identifier: MIT */
/* afm_sundials.c -- the offline integrators behind afm_sim: CVODE ("reference") and
 * ARKODE fixed-step ERK ("arkode-erk"), both over the state y = [q_1..q_n, q'_1..q'_n].
 *
 * Neither is real-time: SUNDIALS allocates in CVodeReInit/ERKStepReInit and costs
 * 1e3..1e5 ns per output step (docs/numerics). They exist to measure the rt backend
 * against. Each instance owns its SUNContext. SUNDIALS' error messages are kept in the
 * backend state (never printed). */
#include "integrators/afm_sim_impl.h"
#include "integrators/afm_sundials_ev.h"

#include <arkode/arkode_erkstep.h>
#include <cvodes/cvodes.h>
#include <math.h>
#include <nvector/nvector_serial.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

/* Default CVODE relative tolerance when cfg.ref_rtol is 0. */
#define SUND_DEFAULT_RTOL 1e-10
/* Tip displacement (m) that one unit of absolute tolerance is scaled to: atol(q_i) =
 * rtol * SUND_X_REF / |tip_i|, i.e. 1e-19 m of tip motion per mode at rtol 1e-10, well
 * below any amplitude of interest (0.1..100 nm); atol(q'_i) = atol(q_i) * w_i. */
#define SUND_X_REF 1e-9
/* ERK substeps per output step when cfg.rt_substeps_contact is 0: numerics.md found
 * classical RK4 stable while tapping from 5 substeps at 14.06 MHz; the default ARKODE
 * order-4 table (Zonneveld 5-3-4) has a similar stability region. */
#define SUND_ERK_DEFAULT_SUBSTEPS 5
/* Internal steps CVODE may take per output step (contact can need thousands). */
#define SUND_CVODE_MAX_STEPS 200000L

typedef struct {
    SUNContext ctx;
    void *mem;             /* CVODE or ARKODE memory */
    N_Vector y, atol, tmp; /* tmp: afm_cv_step_events' scratch */
    SUNMatrix A;
    SUNLinearSolver ls;
    int substeps;  /* ERK only */
    char msg[256]; /* last SUNDIALS error message */
} sund_state;

/* ---- shared pieces ---------------------------------------------------------------- */

static void sund_err_handler(int code, const char *module, const char *function, char *msg,
                             void *data) {
    sund_state *b = data;
    snprintf(b->msg, sizeof b->msg, "%s %s (%d): %s", module ? module : "?",
             function ? function : "?", code, msg ? msg : "");
}

/* y' = [q', q''(t, q, q')]. Non-finite output is unrecoverable: it is a model failure, not
 * a too-large step. */
static int sund_rhs(sunrealtype t, N_Vector y, N_Vector ydot, void *user) {
    const afm_sim *s = user;
    const int n = s->m.n;
    const double *yv = N_VGetArrayPointer(y);
    double *dv = N_VGetArrayPointer(ydot);
    memcpy(dv, yv + n, (size_t)n * sizeof *dv);
    double f = afm_sim_rhs(s, t, yv, yv + n, dv + n);
    if (!isfinite(f)) return -1;
    for (int i = 0; i < n; i++)
        if (!isfinite(dv[n + i])) return -1;
    return 0;
}

static void state_to_y(const afm_sim *s, N_Vector y) {
    double *yv = N_VGetArrayPointer(y);
    for (int i = 0; i < s->m.n; i++) {
        yv[i] = s->q[i];
        yv[s->m.n + i] = s->qd[i];
    }
}

/* Copy the end state back and evaluate the tip force there. */
static void y_to_state(afm_sim *s, N_Vector y) {
    const double *yv = N_VGetArrayPointer(y);
    double x = 0.0, v = 0.0;
    for (int i = 0; i < s->m.n; i++) {
        s->q[i] = yv[i];
        s->qd[i] = yv[s->m.n + i];
        x += s->m.tip[i] * s->q[i];
        v += s->m.tip[i] * s->qd[i];
    }
    s->f_last_n = afm_force_tip(&s->f, s->z_m, x, v, NULL, NULL);
}

/* End time of the current output step, computed like afm_sim_run computes t_s so the
 * integrator's clock never drifts from the handle's. */
static double step_end(const afm_sim *s) {
    return s->t_start_s + (double)(s->step + 1) * s->dt_s;
}

static void sund_free(sund_state *b) {
    if (!b) return;
    if (b->ls) SUNLinSolFree(b->ls);
    if (b->A) SUNMatDestroy(b->A);
    if (b->y) N_VDestroy(b->y);
    if (b->atol) N_VDestroy(b->atol);
    if (b->tmp) N_VDestroy(b->tmp);
    if (b->ctx) SUNContext_Free(&b->ctx);
    free(b);
}

static sund_state *sund_alloc(const afm_sim *s, char *err, size_t errlen) {
    sund_state *b = calloc(1, sizeof *b);
    if (!b) {
        snprintf(err, errlen, "sundials: out of memory");
        return NULL;
    }
    if (SUNContext_Create(NULL, &b->ctx) != 0) {
        snprintf(err, errlen, "sundials: SUNContext_Create failed");
        free(b);
        return NULL;
    }
    b->y = N_VNew_Serial(2 * s->m.n, b->ctx);
    b->atol = N_VNew_Serial(2 * s->m.n, b->ctx);
    b->tmp = N_VNew_Serial(2 * s->m.n, b->ctx);
    if (!b->y || !b->atol || !b->tmp) {
        snprintf(err, errlen, "sundials: N_VNew_Serial failed");
        sund_free(b);
        return NULL;
    }
    return b;
}

static bool model_finite(const afm_sim *s, char *err, size_t errlen) {
    for (int i = 0; i < s->m.n; i++)
        if (!(s->m.omega_rad_s[i] > 0) || !isfinite(s->m.omega_rad_s[i])) {
            snprintf(err, errlen, "sundials: mode %d has angular frequency %g, need > 0", i,
                     s->m.omega_rad_s[i]);
            return false;
        }
    return true;
}

/* ---- CVODE (reference) ---------------------------------------------------------------- */

/* Analytic Jacobian: d q''_i / d q_j = -w_i^2 delta_ij + tip_i tip_j dF/dx, and the same
 * with -2 xi_i w_i and dF/dv for q'. */
static int cv_jac(sunrealtype t, N_Vector y, N_Vector fy, SUNMatrix J, void *user, N_Vector t1,
                  N_Vector t2, N_Vector t3) {
    (void)t;
    (void)fy;
    (void)t1;
    (void)t2;
    (void)t3;
    const afm_sim *s = user;
    const int n = s->m.n;
    const double *yv = N_VGetArrayPointer(y);
    double x = afm_sim_tip_x(s, yv), v = afm_sim_tip_x(s, yv + n);
    double dfdx = 0.0, dfdv = 0.0;
    afm_force_tip(&s->f, s->z_m, x, v, &dfdx, &dfdv);
    if (!isfinite(dfdx) || !isfinite(dfdv)) return -1;
    SUNMatZero(J);
    for (int i = 0; i < n; i++) {
        double w = s->m.omega_rad_s[i];
        SM_ELEMENT_D(J, i, n + i) = 1.0;
        for (int j = 0; j < n; j++) {
            double tt = s->m.tip[i] * s->m.tip[j];
            SM_ELEMENT_D(J, n + i, j) = tt * dfdx;
            SM_ELEMENT_D(J, n + i, n + j) = tt * dfdv;
        }
        SM_ELEMENT_D(J, n + i, i) -= w * w;
        SM_ELEMENT_D(J, n + i, n + i) -= 2.0 * s->m.xi[i] * w;
    }
    return 0;
}

static int cv_init(afm_sim *s, char *err, size_t errlen) {
    if (!model_finite(s, err, errlen)) return -1;
    double rtol = s->cfg.ref_rtol > 0 ? s->cfg.ref_rtol : SUND_DEFAULT_RTOL;
    if (!(rtol >= 1e-15 && rtol < 1e-2)) {
        snprintf(err, errlen, "reference: ref_rtol %g outside [1e-15, 1e-2)", rtol);
        return -1;
    }
    sund_state *b = sund_alloc(s, err, errlen);
    if (!b) return -1;
    const int n = s->m.n;
    double tipmax = 0.0;
    for (int i = 0; i < n; i++)
        tipmax = fmax(tipmax, fabs(s->m.tip[i]));
    double *av = N_VGetArrayPointer(b->atol);
    for (int i = 0; i < n; i++) {
        /* A mode that barely moves the tip still gets a finite tolerance. */
        double tip = fmax(fabs(s->m.tip[i]), 1e-6 * tipmax);
        if (!(tip > 0)) tip = 1.0;
        av[i] = rtol * SUND_X_REF / tip;
        av[n + i] = av[i] * s->m.omega_rad_s[i];
    }
    state_to_y(s, b->y);
    const char *what = "CVodeCreate";
    b->mem = CVodeCreate(CV_BDF, b->ctx);
    if (!b->mem) goto fail;
    what = "CVodeSetErrHandlerFn";
    if (CVodeSetErrHandlerFn(b->mem, sund_err_handler, b) != CV_SUCCESS) goto fail;
    what = "CVodeInit";
    if (CVodeInit(b->mem, sund_rhs, s->t_s, b->y) != CV_SUCCESS) goto fail;
    what = "CVodeSVtolerances";
    if (CVodeSVtolerances(b->mem, rtol, b->atol) != CV_SUCCESS) goto fail;
    what = "CVodeSetUserData";
    if (CVodeSetUserData(b->mem, s) != CV_SUCCESS) goto fail;
    what = "CVodeSetMaxNumSteps";
    if (CVodeSetMaxNumSteps(b->mem, SUND_CVODE_MAX_STEPS) != CV_SUCCESS) goto fail;
    what = "SUNDenseMatrix";
    b->A = SUNDenseMatrix(2 * n, 2 * n, b->ctx);
    if (!b->A) goto fail;
    what = "SUNLinSol_Dense";
    b->ls = SUNLinSol_Dense(b->y, b->A, b->ctx);
    if (!b->ls) goto fail;
    what = "CVodeSetLinearSolver";
    if (CVodeSetLinearSolver(b->mem, b->ls, b->A) != CV_SUCCESS) goto fail;
    what = "CVodeSetJacFn";
    if (CVodeSetJacFn(b->mem, cv_jac) != CV_SUCCESS) goto fail;
    s->be_state = b;
    return 0;
fail:
    snprintf(err, errlen, "reference: %s failed%s%s", what, b->msg[0] ? ": " : "", b->msg);
    if (b->mem) CVodeFree(&b->mem);
    sund_free(b);
    return -1;
}

static int cv_advance(afm_sim *s) {
    sund_state *b = s->be_state;
    double tout = step_end(s), tret = s->t_s;
    if (CVodeSetStopTime(b->mem, tout) != CV_SUCCESS) return AFM_SIM_ESOLVER;
    if (s->ev_ring) { /* the step's record from the continuous solution (afm_sundials_ev.h) */
        afm_step_events rec;
        if (afm_cv_step_events(s, b->mem, b->y, b->tmp, tout, &rec) != 0) return AFM_SIM_ESOLVER;
        rec.step = s->step + 1; /* afm_sim_run counts the step after advance */
        s->ev_ring[rec.step % s->ev_cap] = rec;
        y_to_state(s, b->y);
        return AFM_SIM_OK;
    }
    int flag = CVode(b->mem, tout, b->y, &tret, CV_NORMAL);
    if (flag < 0) return AFM_SIM_ESOLVER;
    y_to_state(s, b->y);
    return AFM_SIM_OK;
}

static void cv_changed(afm_sim *s) {
    sund_state *b = s->be_state;
    state_to_y(s, b->y);
    /* Only fails on bad memory or a NULL vector, neither possible here; a failed re-init
     * would surface as an error on the next CVode call. */
    (void)CVodeReInit(b->mem, s->t_s, b->y);
}

static void cv_destroy(afm_sim *s) {
    sund_state *b = s->be_state;
    if (!b) return;
    if (b->mem) CVodeFree(&b->mem);
    sund_free(b);
    s->be_state = NULL;
}

const afm_sim_backend afm_cvode_backend = {
    .name = "reference",
    .init = cv_init,
    .advance = cv_advance,
    .changed = cv_changed,
    .destroy = cv_destroy,
};

/* ---- ARKODE ERKStep, fixed step (arkode-erk) ----------------------------------------- */

static int erk_init(afm_sim *s, char *err, size_t errlen) {
    if (!model_finite(s, err, errlen)) return -1;
    int sub =
        s->cfg.rt_substeps_contact > 0 ? s->cfg.rt_substeps_contact : SUND_ERK_DEFAULT_SUBSTEPS;
    if (sub > 100000) {
        snprintf(err, errlen, "arkode-erk: %d substeps per sample is too many (max 100000)", sub);
        return -1;
    }
    sund_state *b = sund_alloc(s, err, errlen);
    if (!b) return -1;
    b->substeps = sub;
    state_to_y(s, b->y);
    const char *what = "ERKStepCreate";
    b->mem = ERKStepCreate(sund_rhs, s->t_s, b->y, b->ctx);
    if (!b->mem) goto fail;
    what = "ERKStepSetErrHandlerFn";
    if (ERKStepSetErrHandlerFn(b->mem, sund_err_handler, b) != ARK_SUCCESS) goto fail;
    what = "ERKStepSetUserData";
    if (ERKStepSetUserData(b->mem, s) != ARK_SUCCESS) goto fail;
    /* The built-in order-4 table; 6.4.1 mishandles a user classical RK4 table (FSAL). */
    what = "ERKStepSetOrder";
    if (ERKStepSetOrder(b->mem, 4) != ARK_SUCCESS) goto fail;
    what = "ERKStepSetFixedStep";
    if (ERKStepSetFixedStep(b->mem, s->dt_s / sub) != ARK_SUCCESS) goto fail;
    what = "ERKStepSetMaxNumSteps";
    if (ERKStepSetMaxNumSteps(b->mem, 2L * sub + 10) != ARK_SUCCESS) goto fail;
    s->be_state = b;
    return 0;
fail:
    snprintf(err, errlen, "arkode-erk: %s failed%s%s", what, b->msg[0] ? ": " : "", b->msg);
    if (b->mem) ERKStepFree(&b->mem);
    sund_free(b);
    return -1;
}

static int erk_advance(afm_sim *s) {
    sund_state *b = s->be_state;
    double tout = step_end(s), tret = s->t_s;
    if (ERKStepSetStopTime(b->mem, tout) != ARK_SUCCESS) return AFM_SIM_ESOLVER;
    int flag = ERKStepEvolve(b->mem, tout, b->y, &tret, ARK_NORMAL);
    if (flag < 0) return AFM_SIM_ESOLVER;
    y_to_state(s, b->y);
    return AFM_SIM_OK;
}

static void erk_changed(afm_sim *s) {
    sund_state *b = s->be_state;
    state_to_y(s, b->y);
    /* ReInit keeps the fixed step and the other options. */
    (void)ERKStepReInit(b->mem, sund_rhs, s->t_s, b->y);
}

static void erk_destroy(afm_sim *s) {
    sund_state *b = s->be_state;
    if (!b) return;
    if (b->mem) ERKStepFree(&b->mem);
    sund_free(b);
    s->be_state = NULL;
}

const afm_sim_backend afm_arkode_erk_backend = {
    .name = "arkode-erk",
    .init = erk_init,
    .advance = erk_advance,
    .changed = erk_changed,
    .destroy = erk_destroy,
};
