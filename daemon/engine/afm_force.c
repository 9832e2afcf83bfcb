/* SPDX-License-Identifier: MIT */
/* afm_force.c -- tip-sample interaction forces and their partials (contract in afm_force.h). */
#include "afm_force.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>

static const double pi = 3.14159265358979323846;
static const double eps0_f_m = 8.8541878128e-12; /* vacuum permittivity (CODATA 2018) */

/* Veijola's rarefied-gas fit, eq. (2.34): eta_e = eta0 / (1 + VEIJOLA_A Kn^VEIJOLA_B). */
#define VEIJOLA_A 9.638
#define VEIJOLA_B 1.159

static void set_err(char *err, size_t errlen, const char *fmt, ...) {
    if (!err || errlen == 0)
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

/* Table 2.3: fc at beta = 0.1, 0.2, ..., 1.0. */
static const double fc_table[10] = {0.94, 0.87, 0.81, 0.75, 0.69, 0.63, 0.57, 0.52, 0.47, 0.42};

double afm_force_fc(double beta) {
    if (isnan(beta))
        return beta;
    if (beta <= 0.1)
        return fc_table[0];
    if (beta >= 1.0)
        return fc_table[9];
    double s = (beta - 0.1) * 10.0; /* in (0, 9) */
    int i = (int)s;
    if (i > 8)
        i = 8;
    double t = s - i;
    return fc_table[i] + t * (fc_table[i + 1] - fc_table[i]);
}

/* Validation helpers: each returns 0 if ok, else -1 with err naming the field. */
static int need_pos(double v, const char *name, const char *why, char *err, size_t errlen) {
    if (isfinite(v) && v > 0.0)
        return 0;
    set_err(err, errlen, "forces.%s = %g: must be finite and > 0 (%s)", name, v, why);
    return -1;
}

static int need_nonneg(double v, const char *name, const char *why, char *err, size_t errlen) {
    if (isfinite(v) && v >= 0.0)
        return 0;
    set_err(err, errlen, "forces.%s = %g: must be finite and >= 0 (%s)", name, v, why);
    return -1;
}

static int need_finite(double v, const char *name, const char *why, char *err, size_t errlen) {
    if (isfinite(v))
        return 0;
    set_err(err, errlen, "forces.%s = %g: must be finite (%s)", name, v, why);
    return -1;
}

int afm_force_init(afm_force_params *p, const afm_cfg_forces *cfg, double beam_length_m,
                   double beam_width_m, char *err, size_t errlen) {
    if (!p || !cfg) {
        set_err(err, errlen, "afm_force_init: NULL argument");
        return -1;
    }
    const afm_cfg_forces *c = cfg;
    afm_force_params q = {0};

    double alpha = c->inclination_rad;
    if (!(isfinite(alpha) && alpha >= 0.0 && alpha < 0.5 * pi)) {
        set_err(err, errlen, "forces.inclination_rad = %g: must be in [0, pi/2)", alpha);
        return -1;
    }
    q.cos_alpha = cos(alpha);

    bool sq_starr = c->squeeze == AFM_SQUEEZE_STARR;
    bool sq_lin = c->squeeze == AFM_SQUEEZE_LINEAR;
    if (!(c->squeeze == AFM_SQUEEZE_NONE || sq_starr || sq_lin)) {
        set_err(err, errlen, "forces.squeeze = %d: unknown kind (none, starr or linear)",
                (int)c->squeeze);
        return -1;
    }

    /* a0 bounds every term near the sample (Hertz branch, D = max(d, a0), Starr's h floor). */
    bool need_a0 = c->vdw_contact || c->viscoelastic || c->capillary || c->electrostatic ||
                   sq_starr;
    bool need_r = c->vdw_contact || c->viscoelastic || c->capillary;
    if (need_a0 && need_pos(c->a0_m, "a0_m", "intermolecular distance", err, errlen))
        return -1;
    if (need_r && need_pos(c->radius_m, "radius_m", "tip radius", err, errlen))
        return -1;
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
        if (need_nonneg(c->eta_pa_s, "eta_pa_s", "viscoelastic", err, errlen))
            return -1;
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
            set_err(err, errlen, "forces.kappa = %g: must be in [0, 1] (%s)", c->kappa, w);
            return -1;
        }
        double fc = afm_force_fc(beam_width_m / beam_length_m);
        q.sq_coef = c->eta0_pa_s * beam_length_m * beam_width_m * beam_width_m * beam_width_m * fc;
        q.sq_lambda_m =
            c->eta0_pa_s * sqrt(2.0 * c->gas_constant_j_kg_k * c->temperature_k) / c->pressure_pa;
        q.sq_offset_m = c->kappa * c->tip_length_m * q.cos_alpha;
        if (!(isfinite(q.sq_coef) && isfinite(q.sq_lambda_m) && q.sq_lambda_m > 0.0)) {
            set_err(err, errlen, "forces: Starr squeeze-film constants overflow (coef %g, "
                    "mean free path %g m)", q.sq_coef, q.sq_lambda_m);
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
            set_err(err, errlen, "forces.contact_angle_rad = %g: must be in [0, pi] (%s)", th, w);
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
            set_err(err, errlen, "forces.cone_half_angle_rad = %g: must be in (0, pi/2) (%s)",
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
            set_err(err, errlen, "forces: electrostatic coefficient overflows (%g N)",
                    q.es_coef_n);
            return -1;
        }
    }

    if (!(isfinite(q.vdw_coef) && isfinite(q.f_adhesion_n) && isfinite(q.hertz_coef) &&
          isfinite(q.visco_coef) && isfinite(q.cap_coef_n))) {
        set_err(err, errlen, "forces: a precomputed coefficient overflows (check magnitudes)");
        return -1;
    }
    *p = q;
    return 0;
}

/* The one evaluation both public functions use, so their totals agree bit for bit.
 * part[0..2] = conservative, viscoelastic, squeeze; *jx, *jv = partials of the total. */
static inline double eval(const afm_force_params *p, double z, double x, double v,
                          double part[3], double *jx, double *jv) {
    const double ca = p->cos_alpha;
    const double d = x * ca + z;
    const bool out = d >= p->a0_m; /* out of contact: d >= a0 */
    double fcons = 0.0, kx = 0.0, fvis = 0.0, fsq = 0.0, kv = 0.0;

    if (p->vdw_contact) {
        if (out) {
            double id = 1.0 / d;
            double fv = p->vdw_coef * id * id;
            fcons = -fv;
            kx = 2.0 * fv * id * ca;
        } else {
            double u = p->a0_m - d;
            double su = sqrt(u);
            fcons = p->hertz_coef * u * su - p->f_adhesion_n;
            kx = -1.5 * p->hertz_coef * su * ca;
        }
    }
    if (p->viscoelastic && !out) {
        double u = p->a0_m - d;
        double su = sqrt(u); /* > 0 here: u > 0 strictly */
        double cvis = p->visco_coef * su;
        fvis = -cvis * v;
        kv -= cvis;
        kx += 0.5 * p->visco_coef * v * ca / su; /* d/dx of -eta sqrt(R u) v, du/dx = -ca */
    }
    if (p->capillary) {
        double dm = p->cap_d_m;
        double D = out ? d : p->a0_m;
        double g = 1.0 / (1.0 + D / dm);
        fcons += -p->cap_coef_n * g;
        if (out)
            kx += p->cap_coef_n * g * g / dm * ca;
    }
    if (p->electrostatic) {
        double D = out ? d : p->a0_m;
        double r = p->es_cone_m / (4.0 * D);
        if (r > 1.0) {
            fcons += -p->es_coef_n * log(r);
            if (out)
                kx += p->es_coef_n * ca / d;
        }
    }
    if (p->squeeze == AFM_SQUEEZE_STARR) {
        double h = z + x * ca + p->sq_offset_m;
        bool floored = !(h > p->a0_m);
        if (floored)
            h = p->a0_m;
        double ih = 1.0 / h;
        double knp = pow(p->sq_lambda_m * ih, VEIJOLA_B); /* Kn^1.159 */
        double gi = 1.0 / (1.0 + VEIJOLA_A * knp);               /* eta_e / eta0 */
        double c = p->sq_coef * gi * ih * ih * ih;
        fsq = -c * v;
        kv -= c;
        if (!floored) {
            /* dc/dh = c (-3/h + A B Kn^B / (h (1 + A Kn^B))), dh/dx = ca */
            double dcdh = c * ih * (-3.0 + VEIJOLA_A * VEIJOLA_B * knp * gi);
            kx += -dcdh * ca * v;
        }
    } else if (p->squeeze == AFM_SQUEEZE_LINEAR) {
        double c = p->p1 * (z + x) + p->p2;
        if (c > 0.0) {
            fsq = -c * v;
            kv -= c;
            kx += -p->p1 * v;
        }
    }
    part[0] = fcons;
    part[1] = fvis;
    part[2] = fsq;
    *jx = kx;
    *jv = kv;
    return (fcons + fvis) + fsq;
}

double afm_force_tip(const afm_force_params *p, double z_m, double x_m, double v_m_s,
                     double *dfdx, double *dfdv) {
    double part[3], jx, jv;
    double f = eval(p, z_m, x_m, v_m_s, part, &jx, &jv);
    if (dfdx)
        *dfdx = jx;
    if (dfdv)
        *dfdv = jv;
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

double afm_force_contact_x(const afm_force_params *p, double z_m) {
    return (p->a0_m - z_m) / p->cos_alpha;
}
