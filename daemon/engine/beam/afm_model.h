/* SPDX-License-Identifier: MIT */
/* afm_model.h -- the reduced-order cantilever in modal form: what every integrator runs.
 *
 * Layer beam/ (1) (after config). Built from afm_cfg_model by FEM + Rubin CMS method 2 (thesis
 * App. D.3) or from the lumped 1-DOF model. The prescribed base displacement ux1(t) has
 * been imposed, so the n = nk + 2 modes are those of the clamped-base reduced model
 * (eq. D.33) diagonalised with mass-normalised eigenvectors. Each mode obeys
 *
 *   q_i'' + 2 xi_i w_i q_i' + w_i^2 q_i = tip_i F_tip(t) - base_k_i ux1(t) - base_m_i ux1''(t)
 *
 * with the tip displacement (absolute, the thesis's xr = uxp, m; negative towards the
 * sample) and the tip rotation (rad) read out as
 *
 *   x_tip = sum_i tip_i q_i,    theta_tip = rot_base ux1 + sum_i rot_i q_i.
 *
 * Units: q_i in m kg^0.5 (mass-normalised), tip_i in kg^-0.5, w_i in rad/s. */
#ifndef AFM_MODEL_H
#define AFM_MODEL_H

#include "config/afm_config.h"

typedef struct {
    int n;                             /* number of modes (nk + 2 for beams, 1 lumped) */
    double omega_rad_s[AFM_MAX_MODES]; /* ascending */
    double xi[AFM_MAX_MODES];          /* modal damping ratio */
    double tip[AFM_MAX_MODES];         /* tip displacement per unit q_i */
    double rot[AFM_MAX_MODES];         /* tip rotation per unit q_i */
    double base_k[AFM_MAX_MODES];      /* modal force per unit base displacement, N/(m kg^0.5)... */
    double base_m[AFM_MAX_MODES];      /* ...and per unit base acceleration */
    double rot_base;                   /* quasi-static tip rotation per unit base displacement */
    double static_stiffness_n_m;       /* tip force / tip displacement, clamped base, static */
    double beam_length_m;              /* L (0 for lumped) */
    double beam_mean_width_m;          /* mean W (0 for lumped) */
} afm_modal;

/* Linear steady state with the tip forces off: a base motion ux1 = Re(A e^{i w t}) gives
 * q_i = Re(A H_i e^{i w t}) and x_tip = Re(A G e^{i w t}). These write H_i (mode i, in
 * m kg^0.5 per m of base) and G = sum_i tip_i H_i (m of tip per m of base) as (re, im). */
void afm_model_mode_response(const afm_modal *m, int i, double w_rad_s, double *re, double *im);
void afm_model_tip_response(const afm_modal *m, double w_rad_s, double *re, double *im);

/* Build the modal form. 0 on success, -1 with err. */
int afm_model_build(const afm_cfg_model *cfg, afm_modal *m, char *err, size_t errlen);

/* What `afmtwin modes` reports (thesis Tables 2.1, 3.1, 3.2, E.2). Beam models only for
 * the FEM parts; n_analytical is 0 unless the beam is uniform. */
typedef struct {
    int n_analytical, n_unreduced, n_reduced;
    double analytical_hz[AFM_MAX_MODES];      /* clamped-free Euler-Bernoulli, no tip mass */
    double unreduced_hz[AFM_MAX_MODES];       /* full FEM, clamped, with tip mass (lowest ones) */
    double reduced_hz[AFM_MAX_MODES];         /* Rubin method 2 */
    double mac[AFM_MAX_MODES][AFM_MAX_MODES]; /* [reduced i][unreduced j], eq. 3.8-3.10 */
    double static_stiffness_n_m;              /* tip static stiffness */
    double effective_mass_kg;                 /* eq. 2.14 for mode 1 at the tip (unreduced) */
    double beam_mass_kg;                      /* mass of the beam alone */
} afm_modes_report;

int afm_model_report(const afm_cfg_model *cfg, afm_modes_report *r, char *err, size_t errlen);

#endif
