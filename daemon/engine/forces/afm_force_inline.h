/* SPDX-License-Identifier: MIT */
/* afm_force_inline.h -- private: the tip-force formulas as static inline functions, so that
 * afm_force.c (the public afm_force_tip / afm_force_parts_at) and the real-time integrator
 * (afm_rt.c, which inlines them into its step) evaluate the same expressions. Contract and
 * equations: afm_force.h. Only engine files include this. */
#ifndef AFM_FORCE_INLINE_H
#define AFM_FORCE_INLINE_H

#include "forces/afm_force.h"

#include <math.h>

/* Veijola's rarefied-gas fit, eq. (2.34): eta_e = eta0 / (1 + VEIJOLA_A Kn^VEIJOLA_B). */
#define AFM_VEIJOLA_A 9.638
#define AFM_VEIJOLA_B 1.159

/* The terms out of contact (d >= a0): vdW, capillary and electrostatic at gap d; *jx
 * receives their slope in x. One division 1/d serves the vdW value and its slope. */
static inline double afm_force_out_terms(const afm_force_params *p, double d, double *jx) {
    const double ca = p->cos_alpha;
    double fc = 0.0, kx = 0.0;
    if (p->vdw_contact) {
        double id = 1.0 / d;
        double fv = p->vdw_coef * id * id;
        fc = -fv;
        kx = 2.0 * fv * id * ca;
    }
    if (p->capillary) {
        double g = 1.0 / (1.0 + d / p->cap_d_m);
        fc += -p->cap_coef_n * g;
        kx += p->cap_coef_n * g * g / p->cap_d_m * ca;
    }
    if (p->electrostatic) {
        double r = p->es_cone_m / (4.0 * d);
        if (r > 1.0) {
            fc += -p->es_coef_n * log(r);
            kx += p->es_coef_n * ca / d;
        }
    }
    *jx = kx;
    return fc;
}

/* The same in contact (d < a0): DMT/Hertz, viscoelastic (into *fvis), and the capillary
 * and electrostatic forces frozen at D = a0. *fcons, *fvis the parts, *jx, *jv the slopes
 * of their sum. */
static inline void afm_force_in_terms(const afm_force_params *p, double d, double v, double *fcons,
                                      double *fvis, double *jx, double *jv) {
    const double ca = p->cos_alpha;
    double fc = 0.0, kx = 0.0, fvi = 0.0, kv = 0.0;
    double u = p->a0_m - d;
    double su = sqrt(u); /* > 0 here: u > 0 strictly */
    if (p->vdw_contact) {
        fc = p->hertz_coef * u * su - p->f_adhesion_n;
        kx = -1.5 * p->hertz_coef * su * ca;
    }
    if (p->viscoelastic) {
        double cvis = p->visco_coef * su;
        fvi = -cvis * v;
        kv -= cvis;
        kx += 0.5 * p->visco_coef * v * ca / su; /* d/dx of -eta sqrt(R u) v, du/dx = -ca */
    }
    if (p->capillary) fc += -p->cap_coef_n * (1.0 / (1.0 + p->a0_m / p->cap_d_m));
    if (p->electrostatic) {
        double r = p->es_cone_m / (4.0 * p->a0_m);
        if (r > 1.0) fc += -p->es_coef_n * log(r);
    }
    *fcons = fc;
    *fvis = fvi;
    *jx = kx;
    *jv = kv;
}

/* Every term but the squeeze film (vdW/DMT, viscoelastic, capillary, electrostatic) at gap
 * d = x cos(alpha) + Z and velocity v. *fcons and *fvis receive the conservative and
 * viscoelastic parts; *jx, *jv the partials of their sum in x and v. */
static inline double afm_force_near_terms(const afm_force_params *p, double d, double v,
                                          double *fcons, double *fvis, double *jx, double *jv) {
    if (d >= p->a0_m) { /* out of contact */
        *fcons = afm_force_out_terms(p, d, jx);
        *fvis = *jv = 0.0;
        return *fcons;
    }
    afm_force_in_terms(p, d, v, fcons, fvis, jx, jv);
    return *fcons + *fvis;
}

/* Starr's squeeze-film coefficient c(h) = eta_e(h) L W^3 fc / h^3 (N s/m) at plate gap
 * h > 0 (eq. 3.6 with eq. 2.34), and dc/dh into *dcdh. */
static inline double afm_force_starr_c(const afm_force_params *p, double h, double *dcdh) {
    double ih = 1.0 / h;
    double knp = pow(p->sq_lambda_m * ih, AFM_VEIJOLA_B); /* Kn^1.159 */
    double gi = 1.0 / (1.0 + AFM_VEIJOLA_A * knp);        /* eta_e / eta0 */
    double c = p->sq_coef * gi * ih * ih * ih;
    /* dc/dh = c (-3/h + A B Kn^B / (h (1 + A Kn^B))) */
    *dcdh = c * ih * (-3.0 + AFM_VEIJOLA_A * AFM_VEIJOLA_B * knp * gi);
    return c;
}

/* Plate gap of Starr's squeeze film at tip displacement x: h = Z + x cos(alpha) + kappa l
 * cos(alpha) (the floor at a0 is the caller's). */
static inline double afm_force_starr_h(const afm_force_params *p, double z, double x) {
    return z + x * p->cos_alpha + p->sq_offset_m;
}

/* The squeeze-film force -c v; *kx, *kv receive its partials. */
static inline double afm_force_squeeze_term(const afm_force_params *p, double z, double x, double v,
                                            double *kx, double *kv) {
    *kx = *kv = 0.0;
    if (p->squeeze == AFM_SQUEEZE_STARR) {
        double h = afm_force_starr_h(p, z, x);
        bool floored = !(h > p->a0_m);
        if (floored) h = p->a0_m;
        double dcdh, c = afm_force_starr_c(p, h, &dcdh);
        *kv = -c;
        if (!floored) *kx = -dcdh * p->cos_alpha * v; /* dh/dx = cos(alpha) */
        return -c * v;
    }
    if (p->squeeze == AFM_SQUEEZE_LINEAR) {
        double c = p->p1 * (z + x) + p->p2;
        if (c > 0.0) {
            *kv = -c;
            *kx = -p->p1 * v;
            return -c * v;
        }
    }
    return 0.0;
}

#endif
