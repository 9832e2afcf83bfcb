/* SPDX-License-Identifier: MIT */
/* afm_cont_point.h -- one point of a branch of periodic orbits: the orbit's state at drive
 * phase 0 and the parameter, found by Newton's method on the period-p map (shooting), with
 * the monodromy matrix M = dy(pT)/dy(0) and the parameter derivative dy(pT)/dlambda from
 * CVODES forward sensitivities (afm_cont_flow: N + 1 sensitivities per map, the force kinks
 * located). Its Floquet multipliers (eigenvalues of M) and the branch's tangent there.
 *
 * Layer analysis/ (6, above the runner; offline, allocates in create only).
 *
 * Why sensitivities and not finite differences: a finite-difference M needs N + 1 extra
 * period maps whose differences carry CVODE's error divided by the perturbation (issue 11's
 * afm_shoot stalled at residuals of 1e-11 m near a multiplier at 1); the sensitivities are
 * integrated with the orbit under the same error control, at about the same cost, and are
 * exact derivatives of the discrete flow up to that tolerance.
 *
 * Scaled coordinates (what the arclength and the tangent are measured in): state entry i in
 * units of ys_i = a_ref / w_i (w: tip weights, afm_cont_flow_weights: one unit is a_ref metres
 * of tip motion), the parameter in units of ls (the continuation's range). Newton solves the
 * N + 1 equations [y(pT) - y(0) = 0; c . (u - u_pred) = 0] (u scaled, c the constraint's
 * normal: the predictor's tangent for pseudo-arclength, e_lambda for a fixed parameter). */
#ifndef AFM_CONT_POINT_H
#define AFM_CONT_POINT_H

#include "analysis/afm_cont_flow.h"

#define AFM_CONT_MAX_U (AFM_CONT_MAX_N + 1) /* unknowns: state and parameter */

typedef struct {
    int p;                                     /* drive periods of the orbit */
    double lambda;                             /* parameter value (its unit) */
    double y[AFM_CONT_MAX_N];                  /* state at drive phase 0: q then q' */
    double y_half[AFM_CONT_MAX_N];             /* state after p / 2 periods (p even), else y */
    double M[AFM_CONT_MAX_N * AFM_CONT_MAX_N]; /* monodromy, row-major */
    double fl[AFM_CONT_MAX_N];                 /* dy(pT) / dlambda */
    double t[AFM_CONT_MAX_U]; /* unit tangent (scaled), oriented along the branch */
    double mult_re[AFM_CONT_MAX_N], mult_im[AFM_CONT_MAX_N]; /* by modulus, largest first */
    double residual; /* scaled max |y(pT) - y(0)| at the last map */
    int iterations;  /* Newton maps taken */
} afm_cont_pt;

typedef struct {
    afm_cont_base base;
    afm_cont_param par;
    afm_cont_flow *flow;
    int n, N;                  /* modes, state size */
    double ys[AFM_CONT_MAX_N]; /* state scale */
    double ls;                 /* parameter scale */
    double a_ref_m;            /* orbit size of one scaled unit (m of tip motion) */
    double tol;                /* scaled residual of convergence */
    int max_iter;              /* Newton maps per corrector */
    double max_du;             /* > 0: largest Newton update (scaled, max norm): damping */
    long maps;                 /* Newton maps (with sensitivities) so far */
} afm_cont_ctx;

/* cfg: the config (one tone); name: the parameter (afm_cont_param_parse); ls > 0 its scale;
 * a_ref_m > 0 the orbit size of one scaled state unit. 0, or -1 with err. */
int afm_cont_ctx_init(afm_cont_ctx *c, const afm_config *cfg, const char *name, double ls,
                      double a_ref_m, char *err, size_t errlen);
void afm_cont_ctx_free(afm_cont_ctx *c);

/* Monotonic wall time in seconds, for the summaries' run times. */
double afm_cont_now_s(void);
/* A new orbit size of one scaled unit (> 0; others ignored). */
void afm_cont_set_aref(afm_cont_ctx *c, double a_ref_m);

/* Set the flow's model to the instance at lambda (with the +-delta instances for the
 * parameter sensitivity). 0, or -1 with err (lambda out of range). */
int afm_cont_set_lambda(afm_cont_ctx *c, double lambda, char *err, size_t errlen);

/* Integrate y (2n, overwritten) over periods drive periods at lambda, no sensitivities:
 * the time integration a branch starts from. 0, or -1 with err. */
int afm_cont_settle(afm_cont_ctx *c, double lambda, double *y, int periods, char *err,
                    size_t errlen);

/* Newton from the predictor (y_pred, lambda_pred) with the constraint normal cn (scaled, N + 1
 * entries; NULL: the parameter fixed at lambda_pred), period p. out gets the point (M, fl and
 * the multipliers at the converged state; its tangent is not set). Returns 0 converged, 1 not
 * converged within max_iter maps or diverging (out undefined), -1 with err on a failure. */
int afm_cont_correct(afm_cont_ctx *c, const double *y_pred, double lambda_pred, const double *cn,
                     int p, afm_cont_pt *out, char *err, size_t errlen);

/* The tangent of pt (unit, scaled): the null vector of [M - I, fl] (scaled), oriented so that
 * its product with ref (N + 1 entries) is positive, or when ref is NULL so that lambda grows
 * when dir > 0 (falls when dir < 0). 0, or -1 (singular). */
int afm_cont_tangent(const afm_cont_ctx *c, afm_cont_pt *pt, const double *ref, int dir);

/* Scaled vector of a point: u = (y / ys, lambda / ls). */
void afm_cont_scaled(const afm_cont_ctx *c, const double *y, double lambda, double *u);

/* Stable: every multiplier inside the unit circle. */
bool afm_cont_stable(const afm_cont_ctx *c, const afm_cont_pt *pt);

#endif
