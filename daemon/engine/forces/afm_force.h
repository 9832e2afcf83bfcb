/* SPDX-License-Identifier: MIT */
/* afm_force.h -- tip-sample interaction forces at the tip (thesis ch. 2-3, App. B).
 *
 * Layer forces/ (2) (after config and model). Pure functions of the tip state; no allocation.
 * Sign convention: x is the tip's transversal displacement (m), negative towards the
 * sample; the gap is d = x cos(alpha) + Z. A returned force is the force on the tip DOF
 * along +x (N): attraction towards the sample is negative, repulsion positive. Every
 * dissipative term is returned as a force too (e.g. squeeze film: -c_sq(x) v).
 *
 *  vdW + DMT/Hertz (eq. 3.2): d >= a0: -Ha R / (6 d^2);
 *                             d <  a0: -Ha R / (6 a0^2) + 4/3 Er sqrt(R) (a0 - d)^1.5
 *  viscoelastic (eq. 3.3):    d <  a0: -eta sqrt(R (a0 - d)) v
 *  squeeze Starr (eq. 3.6, 2.34, B.2, Table 2.3):
 *      h = Z + x cos(alpha) + kappa l cos(alpha); Kn = lambda/h, lambda = eta0 sqrt(2 Ra T)/pa;
 *      eta_e = eta0 / (1 + 9.638 Kn^1.159); c = eta_e L W^3 fc(W/L) / h^3; F = -c v
 *  squeeze linear (eq. 5.3):  c = p1 (Z + x) + p2 (clamped at >= 0); F = -c v
 *  capillary (eq. 2.18):      D = max(d, a0): F = -4 pi R gamma cos(theta) / (1 + D/dm)
 *  electrostatic (eq. 2.19-20): D = max(d, a0), lambda0 = 4 pi e0 dV / ln((1+cos th)/(1-cos th)),
 *                             F = -lambda0^2/(4 pi e0) ln(l / (4 D)) while l/(4D) > 1, else 0 */
#ifndef AFM_FORCE_H
#define AFM_FORCE_H

#include "config/afm_config.h"

/* Constants precomputed from the config (SI). Treat as read-only after afm_force_init. */
typedef struct {
    double cos_alpha;
    double a0_m;
    bool vdw_contact;
    double vdw_coef;     /* Ha R / 6, N m^2 */
    double f_adhesion_n; /* Ha R / (6 a0^2) */
    double hertz_coef;   /* 4/3 Er sqrt(R), N m^-1.5 */
    bool viscoelastic;
    double visco_coef; /* eta sqrt(R), N s m^-1.5 */
    afm_squeeze_kind squeeze;
    double sq_coef;     /* eta0 L W^3 fc(beta), N s m^2 (Starr) */
    double sq_lambda_m; /* mean free path (Starr) */
    double sq_offset_m; /* kappa l cos(alpha) (Starr) */
    double p1, p2;      /* linear fit */
    bool capillary;
    double cap_coef_n; /* 4 pi R gamma cos(theta) */
    double cap_d_m;
    bool electrostatic;
    double es_coef_n; /* lambda0^2 / (4 pi e0) */
    double es_cone_m; /* cone length l */
} afm_force_params;

/* The parts, for reporting and for energy bookkeeping (N). */
typedef struct {
    double conservative_n; /* vdW + Hertz/DMT + capillary + electrostatic */
    double viscoelastic_n;
    double squeeze_n;
    double total_n;
} afm_force_parts;

/* fc(beta) of Table 2.3, linear interpolation, clamped to [0.1, 1]. */
double afm_force_fc(double beta);

/* Precompute from the config; beam_length_m and beam_width_m feed Starr's plate (the
 * lumped model passes the config's plate values). 0 or -1 with err. */
int afm_force_init(afm_force_params *p, const afm_cfg_forces *cfg, double beam_length_m,
                   double beam_width_m, char *err, size_t errlen);

/* Total force on the tip (N) at separation z_m, tip displacement x_m, velocity v_m_s;
 * if dfdx / dfdv are non-NULL they receive the partial derivatives (N/m, N s/m). These
 * are one-sided at d = a0 where the Hertz term has its 3/2-power kink. */
double afm_force_tip(const afm_force_params *p, double z_m, double x_m, double v_m_s, double *dfdx,
                     double *dfdv);

/* Same value split into parts. */
void afm_force_parts_at(const afm_force_params *p, double z_m, double x_m, double v_m_s,
                        afm_force_parts *out);

/* The conservative part alone (vdW or DMT/Hertz, capillary, electrostatic) at x_m (N). */
double afm_force_cons(const afm_force_params *p, double z_m, double x_m);

/* Work of the conservative part (vdW or DMT/Hertz, capillary, electrostatic) on the tip
 * moving from x0_m to x1_m at separation z_m (J), exactly: the difference of its
 * antiderivative in the gap, divided by cos(alpha). Over a closed orbit it is zero; what
 * the tip-sample force dissipates is then the work of the velocity terms alone. */
double afm_force_cons_work(const afm_force_params *p, double z_m, double x0_m, double x1_m);

/* Tip displacement at which the gap closes to a0: x_c = (a0 - Z) / cos(alpha). */
double afm_force_contact_x(const afm_force_params *p, double z_m);

#endif
