/* SPDX-License-Identifier: MIT */
/* afm_cont_curve.h -- two-parameter continuation of LPC and PD points: the curves in a
 * parameter plane (fe and Z, fe and Ae, ...) along which a periodic orbit has a Floquet
 * multiplier at +1 (a fold: the bounds of a bistable window) or at -1 (a period doubling:
 * the bounds of the period-doubled region). What `afmtwin continue --param2` runs from the
 * LPC and PD points of a one-parameter run.
 *
 * Layer analysis/ (6; offline, allocates). On afm_cont_point's shooting (scaled state,
 * CVODES sensitivities of the period-p map: the monodromy M and dy(pT)/dlambda_k for both
 * parameters).
 *
 * The minimally augmented system (Govaerts, "Numerical methods for bifurcations of
 * dynamical equilibria", SIAM 2000, ch. 4): unknowns u = (y, lambda_1, lambda_2) (N + 2,
 * scaled), equations
 *   y(pT) - y = 0                                   (N: a period-p orbit)
 *   g(y, lambda) = 0                                (1: the orbit is at the bifurcation)
 *   t . (u - u_pred) = 0                            (1: pseudo-arclength)
 * with A = M - I (LPC) or M + I (PD), scaled, and g the last entry of the solution of the
 * bordered system [A b; c^T 0] [v; g] = [0; 1]: zero exactly where A is singular, smooth and
 * regular there when b, c are not orthogonal to A's left and right null vectors. Its
 * gradient g_u = -w^T A_u v (w from the transposed system), where A_u v is the derivative of
 * M v in u, by central differences of the period map with the one direction v at u +- h e_j
 * (2 (N + 2) single-direction maps per Newton step: no second-order sensitivities). b and c
 * are replaced by w and v after every point, so the bordered matrix stays well conditioned.
 * A PD curve is continued on the period-p orbit that doubles (p, not 2p).
 *
 * A curve: from the start point (the event of a one-parameter run, refined to g = 0 with
 * lambda_2 fixed), both ways along the curve (side 0 towards larger lambda_2 first, side 1
 * the other way), each until it leaves the rectangle of the two ranges (landing on its edge;
 * a start on an edge with the tangent leading out ends that side at once), comes back to
 * its start (a closed curve), or the step falls below h_min. Converged per point after at
 * least one Newton step, at the map's noise floor (afm_cont_curve.c; docs/numerics.md). Step
 * control as afm_cont.h's, one step later (x1.5 after <= 4 Newton steps, x0.7 after >= 7, halving
 * on failure or a turn of the tangent over 30 deg). The stability of the orbit along the curve is
 * reported per point (the other multipliers); a cusp of an LPC curve shows as a turn of lambda_1
 * and lambda_2 together (the curve is smooth in (y, lambda)). */
#ifndef AFM_CONT_CURVE_H
#define AFM_CONT_CURVE_H

#include "analysis/afm_cont.h"

typedef struct {
    const char *param, *param2; /* the first (the event's) and the second parameter */
    double from, to;            /* range of param */
    double from2, to2;          /* range of param2 (its config value inside) */
    afm_cont_kind kind;         /* AFM_CONT_LPC or AFM_CONT_PD */
    int p;                      /* periods of the orbit at the event (PD: the one that doubles) */
    const double *y;            /* the event's state at drive phase 0 (2n) */
    double lambda;              /* param at the event; param2 is at its config value */
    int curve;                  /* index carried into the records */
    int max_points;             /* per side (0: 400) */
    double h0, h_min, h_max;    /* scaled steps (0: 0.02, 1e-6, 0.1) */
    double a_ref_m;             /* orbit size of a scaled unit (0: the event orbit's amplitude) */
} afm_cont_curve_opts;

typedef struct {
    bool end;           /* a side ended: stop_reason */
    afm_cont_kind kind; /* LPC or PD */
    int curve, side, p; /* side 0 towards to2's side of the start, 1 the other */
    double param, param2;
    bool stable; /* the orbit's other multipliers all inside the unit circle */
    int n_mult;
    const double *mult_re, *mult_im;
    double multiplier[2]; /* the critical one (nearest +1 or -1) */
    double g;             /* the test function at the point */
    afm_cont_metrics metrics;
    const double *y;       /* the state (2n) */
    double residual;       /* scaled orbit residual */
    int iterations;        /* Newton steps */
    char stop_reason[400]; /* end */
    int points;            /* end: points of the side */
} afm_cont_curve_record;

typedef int (*afm_cont_curve_emit)(void *ctx, const afm_cont_curve_record *r);

/* Continue the curve of o->kind through the event of o in (param, param2). 0 (both sides
 * ended, each with its reason), or -1 with err (bad options, the start not refined). sum
 * gets the points and maps (bifurcations: 0). */
int afm_cont_curve_run(const afm_config *cfg, const afm_cont_curve_opts *o,
                       afm_cont_curve_emit emit, void *ctx, afm_cont_summary *sum, char *err,
                       size_t errlen);

#endif
