/* SPDX-License-Identifier: MIT */
/* afm_cont_flow.h -- the period map of the modal model with its tip forces and its
 * derivatives, by CVODES: the flow over p drive periods with forward sensitivities (the
 * monodromy matrix, the derivative in one or two parameters), the force kinks located by
 * root finding. What shooting and continuation of periodic orbits stand on.
 *
 * Layer analysis/ (6, above the runner) (offline; allocates in create and on the first run of each
 * kind).
 *
 * Time is the drive's phase time tau = fe t, so that a period-p orbit always spans
 * tau in [0, p] and the drive is x_dit = Ae sin(2 pi tau) whatever fe is; the state is
 * y = [q_1..q_n, q'_1..q'_n] (q' = dq/dt, physical), and
 *   dq/dtau = q' / fe,  dq'/dtau = (-2 xi w q' - w^2 q + tip F(x, v) - base_k x_dit
 *                                    - base_m x_dit'') / fe,
 * x = sum tip_i q_i, v = sum tip_i q'_i (afm_model.h). The forces are afm_force_tip's.
 *
 * Kinks: the contact line x = x_c (d = a0, where the Hertz and viscoelastic terms start
 * and the capillary and electrostatic ones freeze), the electrostatic cut-off (l / 4D = 1)
 * and the zero of the linear squeeze coefficient are roots of CVODES' root finding; at each
 * crossing the integration stops and restarts (CVodeReInit, CVodeSensReInit) from the state
 * there, so that no BDF step or history spans a kink, as the rt integrator splits its
 * pieces at the contact line. The vector field is continuous across every kink, so the
 * sensitivities carry over unchanged (no saltation matrix); only its Jacobian jumps.
 *
 * Sensitivities: state directions s(0) = v_j with s' = J(tau, y) s (J analytic, the
 * force's partials one-sided at a kink, as afm_force_tip returns them); parameter
 * sensitivities s(0) = 0 with s' = J s + df/dp_k, df/dp_k by the central difference of the
 * vector field between the instances at p_k +- delta (afm_cont_flow_set_model). They are
 * solved by CVODES' staggered corrector on the state's steps, each direction scaled to the
 * orbit's size first (afm_cont_flow_set_scale), but are not in its error test (unless
 * afm_cont_flow_set_sens_rtol asks): with them in
 * it at the state's rtol (1e-10) a map costs 30-100 times more (the stiff modes' directions
 * decide the steps). Their accuracy then rests on the step: FLOW_MAX_STEP (afm_cont_flow.c)
 * = 1/2000 period, at which the linear model's multipliers have the modulus exp(-xi w T)
 * to 5e-8 (mode 1, 2) and 1e-9 absolute (the stiff modes 3, 4); at 1/100 period mode 2's was
 * 2e-4 low (BDF's damping of an unresolved direction). Test: tests/test_continue.c.
 *
 * Tolerances: rtol (create; the config's sim.ref_rtol, default 1e-10), and per mode
 * atol(q_i) = rtol 1e-9 m / |tip_i|, atol(q'_i) = atol(q_i) w_i (1e-19 m of tip motion per
 * mode at rtol 1e-10), as the reference integrator (afm_sundials.c). */
#ifndef AFM_CONT_FLOW_H
#define AFM_CONT_FLOW_H

#include "analysis/afm_cont_model.h"

#include <stdbool.h>
#include <stddef.h>

#define AFM_CONT_MAX_PAR 2 /* parameters with a sensitivity */
#define AFM_CONT_MAX_P 16  /* longest orbit, drive periods */
#define AFM_CONT_MAX_N (2 * AFM_MAX_MODES)

typedef struct afm_cont_flow afm_cont_flow;

/* Work done, summed over every run since create. */
typedef struct {
    long maps;      /* runs of any kind */
    long sens_maps; /* runs with sensitivities */
    long steps;     /* CVODES steps */
    long rhs;       /* vector-field evaluations (CVODES' count, not the sensitivities') */
    long crossings; /* kink crossings located (each a restart) */
} afm_cont_flow_stats;

/* n_modes: the model's n (all instances share it); rtol in [1e-14, 1e-3] (0: 1e-10). NULL
 * with err on failure. */
afm_cont_flow *afm_cont_flow_create(int n_modes, double rtol, char *err, size_t errlen);
void afm_cont_flow_destroy(afm_cont_flow **f);

/* The model of the next runs: instance at, and for each of np (0..AFM_CONT_MAX_PAR)
 * parameters the instances plus[k], minus[k] at p_k +- delta_k; the parameter
 * sensitivities are then with respect to a unit in which those two lie dpar[k] apart
 * (df/dp_k ~ (f(plus[k]) - f(minus[k])) / dpar[k]). The instances are copied. Every
 * instance must have the model size given at create and the same force terms switched on.
 * 0, or -1 (nothing changed). */
int afm_cont_flow_set_model(afm_cont_flow *f, const afm_cont_inst *at, int np,
                            const afm_cont_inst *plus, const afm_cont_inst *minus,
                            const double *dpar);

/* rtol_sens > 0: the sensitivities in CVODES' error test at that relative tolerance (their
 * absolute tolerances the state's scaled alike), for callers that need M to better than the
 * ~1e-4 that the step rule alone gives in hard contact (second derivatives by differences
 * of M, afm_cont_curve); 0 (default): out of it. Before the first run only (the engines are
 * made on first use). 0, or -1 (too late, or out of [0, 1e-3]). */
int afm_cont_flow_set_sens_rtol(afm_cont_flow *f, double rtol_sens);

/* The orbit size (tip metres) that each state direction is scaled to before integration
 * (tolerances of the sensitivities); default 1e-8 m. Values <= 0 are ignored. */
void afm_cont_flow_set_scale(afm_cont_flow *f, double a_ref_m);

/* The state after p drive periods from y0 (2n entries, at drive phase 0) into y. With nd > 0
 * state directions V (2n x nd, row-major: V[i nd + j] is entry i of direction j) and/or
 * par (the np parameters of set_model), S (2n x (nd + np_used), row-major) receives
 * dy(p)/d(direction j) in its first nd columns and dy(p)/dp_k after them; S may be NULL
 * when nd = 0 and !par. poinc (may be NULL) receives the state after each period
 * 1..p (p rows of 2n). Returns 0, or -1 with err (CVODES failure, non-finite state). */
int afm_cont_flow_map(afm_cont_flow *f, const double *y0, int p, int nd, const double *V, bool par,
                      double *y, double *S, double *poinc, char *err, size_t errlen);

const afm_cont_flow_stats *afm_cont_flow_get_stats(const afm_cont_flow *f);
/* The instance runs use (set_model's at). */
const afm_cont_inst *afm_cont_flow_inst(const afm_cont_flow *f);

/* Tip weights of the state entries: |tip_i| for q_i, |tip_i| / w_i for q'_i (floored at 1e-3
 * of the largest, so that no mode is invisible), so that sum_i w_i |y_i| is tip metres. */
void afm_cont_flow_weights(const afm_modal *m, double *w);

#endif
