/* SPDX-License-Identifier: MIT */
/* afm_force.c -- tip-sample interaction forces and their partials (contract in afm_force.h). */
#include "forces/afm_force.h"
#include "config/afm_err.h"
#include "forces/afm_force_inline.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>

static const double pi = 3.14159265358979323846;
static const double eps0_f_m = 8.8541878128e-12; /* vacuum permittivity (CODATA 2018) */

/* Table 2.3: fc at beta = 0.1, 0.2, ..., 1.0. */
static const double fc_table[10] = {0.94, 0.87, 0.81, 0.75, 0.69, 0.63, 0.57, 0.52, 0.47, 0.42};

double afm_force_fc(double beta) {
    if (isnan(beta)) return beta;
    if (beta <= 0.1) return fc_table[0];
    if (beta >= 1.0) return fc_table[9];
    double s = (beta - 0.1) * 10.0; /* in (0, 9) */
    int i = (int)s;
    if (i > 8) i = 8;
    double t = s - i;
    return fc_table[i] + t * (fc_table[i + 1] - fc_table[i]);
}

/* Validation helpers: each returns 0 if ok, else -1 with err naming the field. */
static int need_pos(double v, const char *name, const char *why, char *err, size_t errlen) {
    if (isfinite(v) && v > 0.0) return 0;
    afm_err_set(err, errlen, "forces.%s = %g: must be finite and > 0 (%s)", name, v, why);
    return -1;
}

static int need_nonneg(double v, const char *name, const char *why, char *err, size_t errlen) {
    if (isfinite(v) && v >= 0.0) return 0;
    afm_err_set(err, errlen, "forces.%s = %g: must be finite and >= 0 (%s)", name, v, why);
    return -1;
}

static int need_finite(double v, const char *name, const char *why, char *err, size_t errlen) {
    if (isfinite(v)) return 0;
    afm_err_set(err, errlen, "forces.%s = %g: must be finite (%s)", name, v, why);
    return -1;
}

int afm_force_init(afm_force_params *p, const afm_cfg_forces *cfg, double beam_length_m,
                   double beam_width_m, char *err, size_t errlen) {
    if (!p || !cfg) {
        afm_err_set(err, errlen, "afm_force_init: NULL argument");
        return -1;
    }
    const afm_cfg_forces *c = cfg;
    afm_force_params q = {0};

    double alpha = c->inclination_rad;
    if (!(isfinite(alpha) && alpha >= 0.0 && alpha < 0.5 * pi)) {
        afm_err_set(err, errlen, "forces.inclination_rad = %g: must be in [0, pi/2)", alpha);
        return -1;
    }
    q.cos_alpha = cos(alpha);

    bool sq_starr = c->squeeze == AFM_SQUEEZE_STARR;
    bool sq_lin = c->squeeze == AFM_SQUEEZE_LINEAR;
    if (!(c->squeeze == AFM_SQUEEZE_NONE || sq_starr || sq_lin)) {
        afm_err_set(err, errlen, "forces.squeeze = %d: unknown kind (none, starr or linear)",
                    (int)c->squeeze);
        return -1;
    }

    /* a0 bounds every term near the sample (Hertz branch, D = max(d, a0), Starr's h floor). */
    bool need_a0 =
        c->vdw_contact || c->viscoelastic || c->capillary || c->electrostatic || sq_starr;
    bool need_r = c->vdw_contact || c->viscoelastic || c->capillary;
    if (need_a0 && need_pos(c->a0_m, "a0_m", "intermolecular distance", err, errlen)) return -1;
    if (need_r && need_pos(c->radius_m, "radius_m", "tip radius", err, errlen)) return -1;
    /* Kept when valid even if unused, so afm_force_contact_x stays meaningful. */
    q.a0_m = (need_a0 || (isfinite(c->a0_m) && c->a0_m > 0.0)) ? c->a0_m : 0.0;

    if (c->vdw_contact) {
        if (need_nonneg(c->hamaker_j, "hamaker_j", "vdw_contact", err, errlen) ||
            need_pos(c->reduced_modulus_pa, "reduced_modulus_pa", "vdw_contact", err, errlen))
            return -1;
        q.vdw_contact = true;
        q.vdw_coef = c->hamaker_j * c->radius_m / 6.0;
        q.f_adhesion_n = q.vdw_coef / (c->a0_m * c->a0_m);
        q.hertz_coef = 4.0 / 3.0 * c->reduced_modulus_pa * sqrt(c->radius_m);
    }

    if (c->viscoelastic) {
        if (need_nonneg(c->eta_pa_s, "eta_pa_s", "viscoelastic", err, errlen)) return -1;
        q.viscoelastic = true;
        q.visco_coef = c->eta_pa_s * sqrt(c->radius_m);
    }

    q.squeeze = c->squeeze;
    if (sq_starr) {
        const char *w = "squeeze = starr";
        if (need_pos(c->eta0_pa_s, "eta0_pa_s", w, err, errlen) ||
            need_pos(c->gas_constant_j_kg_k, "gas_constant_j_kg_k", w, err, errlen) ||
            need_pos(c->temperature_k, "temperature_k", w, err, errlen) ||
            need_pos(c->pressure_pa, "pressure_pa", w, err, errlen) ||
            need_nonneg(c->tip_length_m, "tip_length_m", w, err, errlen) ||
            need_pos(beam_length_m, "plate_length_m", w, err, errlen) ||
            need_pos(beam_width_m, "plate_width_m", w, err, errlen))
            return -1;
        if (!(isfinite(c->kappa) && c->kappa >= 0.0 && c->kappa <= 1.0)) {
            afm_err_set(err, errlen, "forces.kappa = %g: must be in [0, 1] (%s)", c->kappa, w);
            return -1;
        }
        double fc = afm_force_fc(beam_width_m / beam_length_m);
        q.sq_coef = c->eta0_pa_s * beam_length_m * beam_width_m * beam_width_m * beam_width_m * fc;
        q.sq_lambda_m =
            c->eta0_pa_s * sqrt(2.0 * c->gas_constant_j_kg_k * c->temperature_k) / c->pressure_pa;
        q.sq_offset_m = c->kappa * c->tip_length_m * q.cos_alpha;
        if (!(isfinite(q.sq_coef) && isfinite(q.sq_lambda_m) && q.sq_lambda_m > 0.0)) {
            afm_err_set(err, errlen,
                        "forces: Starr squeeze-film constants overflow (coef %g, "
                        "mean free path %g m)",
                        q.sq_coef, q.sq_lambda_m);
            return -1;
        }
    } else if (sq_lin) {
        const char *w = "squeeze = linear";
        if (need_finite(c->p1_n_s_m2, "p1_n_s_m2", w, err, errlen) ||
            need_finite(c->p2_n_s_m, "p2_n_s_m", w, err, errlen))
            return -1;
        q.p1 = c->p1_n_s_m2;
        q.p2 = c->p2_n_s_m;
    }

    if (c->capillary) {
        const char *w = "capillary";
        if (need_nonneg(c->surface_energy_j_m2, "surface_energy_j_m2", w, err, errlen) ||
            need_pos(c->meniscus_d_m, "meniscus_d_m", w, err, errlen))
            return -1;
        double th = c->contact_angle_rad;
        if (!(isfinite(th) && th >= 0.0 && th <= pi)) {
            afm_err_set(err, errlen, "forces.contact_angle_rad = %g: must be in [0, pi] (%s)", th,
                        w);
            return -1;
        }
        q.capillary = true;
        q.cap_coef_n = 4.0 * pi * c->radius_m * c->surface_energy_j_m2 * cos(th);
        q.cap_d_m = c->meniscus_d_m;
    }

    if (c->electrostatic) {
        const char *w = "electrostatic";
        if (need_finite(c->voltage_v, "voltage_v", w, err, errlen) ||
            need_pos(c->cone_length_m, "cone_length_m", w, err, errlen))
            return -1;
        double th = c->cone_half_angle_rad;
        if (!(isfinite(th) && th > 0.0 && th < 0.5 * pi)) {
            afm_err_set(err, errlen, "forces.cone_half_angle_rad = %g: must be in (0, pi/2) (%s)",
                        th, w);
            return -1;
        }
        double ct = cos(th);
        double lg = log((1.0 + ct) / (1.0 - ct));
        double four_pi_e0 = 4.0 * pi * eps0_f_m;
        double lambda0 = four_pi_e0 * c->voltage_v / lg; /* eq. (2.20), C/m */
        q.electrostatic = true;
        q.es_coef_n = lambda0 * lambda0 / four_pi_e0;
        q.es_cone_m = c->cone_length_m;
        if (!isfinite(q.es_coef_n)) {
            afm_err_set(err, errlen, "forces: electrostatic coefficient overflows (%g N)",
                        q.es_coef_n);
            return -1;
        }
    }

    if (!(isfinite(q.vdw_coef) && isfinite(q.f_adhesion_n) && isfinite(q.hertz_coef) &&
          isfinite(q.visco_coef) && isfinite(q.cap_coef_n))) {
        afm_err_set(err, errlen, "forces: a precomputed coefficient overflows (check magnitudes)");
        return -1;
    }
    *p = q;
    return 0;
}

/* The one evaluation both public functions use, so their totals agree bit for bit (the
 * formulas are in afm_force_inline.h, shared with the rt integrator).
 * part[0..2] = conservative, viscoelastic, squeeze; *jx, *jv = partials of the total. */
static inline double eval(const afm_force_params *p, double z, double x, double v, double part[3],
                          double *jx, double *jv) {
    double kx, kv, sx, sv;
    double fn = afm_force_near_terms(p, x * p->cos_alpha + z, v, &part[0], &part[1], &kx, &kv);
    part[2] = afm_force_squeeze_term(p, z, x, v, &sx, &sv);
    *jx = kx + sx;
    *jv = kv + sv;
    return fn + part[2];
}

double afm_force_tip(const afm_force_params *p, double z_m, double x_m, double v_m_s, double *dfdx,
                     double *dfdv) {
    double part[3], jx, jv;
    double f = eval(p, z_m, x_m, v_m_s, part, &jx, &jv);
    if (dfdx) *dfdx = jx;
    if (dfdv) *dfdv = jv;
    return f;
}

void afm_force_parts_at(const afm_force_params *p, double z_m, double x_m, double v_m_s,
                        afm_force_parts *out) {
    double part[3], jx, jv;
    out->total_n = eval(p, z_m, x_m, v_m_s, part, &jx, &jv);
    out->conservative_n = part[0];
    out->viscoelastic_n = part[1];
    out->squeeze_n = part[2];
}

/* An antiderivative in the gap d of the conservative force F_cons(d) (N m): continuous,
 * with the terms' own closed forms out of contact and the DMT/Hertz term (capillary and
 * electrostatic frozen at a0) integrated from a0 in contact. */
static double cons_antiderivative(const afm_force_params *p, double d) {
    const double a0 = p->a0_m, dd = d < a0 ? a0 : d;
    double a = 0.0, f_a0 = 0.0; /* out of contact at max(d, a0); f_a0: the frozen terms */
    if (p->vdw_contact) a += p->vdw_coef / dd;
    if (p->capillary) {
        a += -p->cap_coef_n * p->cap_d_m * log1p(dd / p->cap_d_m);
        f_a0 += -p->cap_coef_n / (1.0 + a0 / p->cap_d_m);
    }
    if (p->electrostatic) {
        double l4 = 0.25 * p->es_cone_m, de = dd < l4 ? dd : l4;
        a += -p->es_coef_n * (de * log(l4 / de) + de);
        if (a0 < l4) f_a0 += -p->es_coef_n * log(l4 / a0);
    }
    if (d < a0) { /* minus the integral of F_in over u = a0 - d' from 0 to a0 - d */
        double u = a0 - d, fin0 = f_a0;
        if (p->vdw_contact) {
            a -= p->hertz_coef * u * u * sqrt(u) / 2.5;
            fin0 -= p->f_adhesion_n;
        }
        a -= fin0 * u;
    }
    return a;
}

double afm_force_cons(const afm_force_params *p, double z_m, double x_m) {
    double fc, fv, jx, jv;
    afm_force_near_terms(p, fma(x_m, p->cos_alpha, z_m), 0.0, &fc, &fv, &jx, &jv);
    return fc;
}

double afm_force_cons_work(const afm_force_params *p, double z_m, double x0_m, double x1_m) {
    const double ca = p->cos_alpha;
    return (cons_antiderivative(p, fma(x1_m, ca, z_m)) -
            cons_antiderivative(p, fma(x0_m, ca, z_m))) /
           ca;
}

double afm_force_contact_x(const afm_force_params *p, double z_m) {
    return (p->a0_m - z_m) / p->cos_alpha;
}
