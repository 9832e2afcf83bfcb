/* SPDX-License-Identifier: MIT */
/* afm_a0.c -- the free amplitude A0 (contract in afm_a0.h). */
#include "runner/afm_a0.h"

#include "beam/afm_model.h"
#include "forces/afm_drive.h"
#include "forces/afm_force_inline.h"
#include "runner/afm_twin.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define A0_TWO_PI 6.283185307179586476925286766559

/* The linear steady state with the tip force linearised about rest at separation z_m (the
 * far-field squeeze film: F = kx x + kv v): the tip response per unit base at w and, with h
 * non-NULL, each mode's (Q_i). */
static double complex linear_response(const afm_modal *m, const afm_force_params *f, double z_m,
                                      double w, double complex *h) {
    double kx = 0.0, kv = 0.0;
    if (f) (void)afm_force_squeeze_term(f, z_m, 0.0, 0.0, &kx, &kv);
    const double complex kf = kx + I * w * kv; /* tip force per unit tip displacement */
    double complex g = 0, htt = 0, hm[AFM_MAX_MODES], r[AFM_MAX_MODES];
    for (int i = 0; i < m->n; i++) {
        double hr, hi, wi = m->omega_rad_s[i];
        afm_model_mode_response(m, i, w, &hr, &hi);
        hm[i] = hr + I * hi;
        r[i] = 1.0 / (wi * wi - w * w + I * 2.0 * m->xi[i] * wi * w);
        g += m->tip[i] * hm[i];
        htt += m->tip[i] * m->tip[i] * r[i];
    }
    const double complex x = g / (1.0 - htt * kf);
    if (h)
        for (int i = 0; i < m->n; i++)
            h[i] = hm[i] + m->tip[i] * r[i] * kf * x;
    return x;
}

void afm_a0_linear_response(const afm_modal *m, const afm_force_params *f, double w_rad_s,
                            double *re, double *im) {
    double complex x = linear_response(m, f, AFM_A0_Z_M, w_rad_s, NULL);
    *re = creal(x);
    *im = cimag(x);
}

/* The linear steady state of s (linear_response) at s's separation: tip response X per unit
 * base, and the modal state now (q, qd) for the base Ae sin(theta0). */
static double complex linear_state(const afm_sim *s, double *q, double *qd) {
    const afm_modal *m = afm_sim_model(s);
    const afm_drive *d = afm_sim_drive(s);
    const double w = d->omega_rad_s[0], ae = d->amp_m[0];
    double complex h[AFM_MAX_MODES];
    const double complex x = linear_response(m, afm_sim_forces(s), afm_sim_separation(s), w, h);
    /* base Ae sin(theta) = Re(-i Ae e^{i theta}); q_i = Re(-i Ae H_i e^{i theta}) */
    const double complex e = cexp(I * afm_drive_phase(d, 0, afm_sim_time(s)));
    for (int i = 0; i < m->n; i++) {
        q[i] = creal(-I * ae * h[i] * e);
        qd[i] = creal(w * ae * h[i] * e);
    }
    return x;
}

int afm_a0_compute(const afm_config *cfg, afm_a0 *out, char *err, size_t errlen) {
    memset(out, 0, sizeof *out);
    if (cfg->drive.n_tones < 1 || !(cfg->drive.tones[0].frequency_hz > 0)) {
        snprintf(err, errlen, "A0: the drive has no tone 0");
        return -1;
    }
    afm_config *c = malloc(sizeof *c);
    if (!c) {
        snprintf(err, errlen, "A0: out of memory");
        return -1;
    }
    *c = *cfg;
    c->drive.separation_m = AFM_A0_Z_M;
    c->drive.n_tones = 1;
    c->forces.vdw_contact = false; /* the tip forces that depend on the gap vanish... */
    c->forces.viscoelastic = false;
    c->forces.capillary = false;
    c->forces.electrostatic = false; /* ...the squeeze film stays as it is at Z far */
    c->thermal.enabled = false;
    afm_sweep w = {0};
    int rc = -1;
    afm_sim *s = afm_twin_create(c, NULL, NULL, err, errlen);
    if (!s) goto done;
    const double fe = c->drive.tones[0].frequency_hz, ae = c->drive.tones[0].amplitude_m;
    double q[AFM_MAX_MODES], qd[AFM_MAX_MODES];
    double complex x = linear_state(s, q, qd);
    out->linear_amplitude_m = ae * cabs(x);
    out->linear_lag_deg = afm_orbit_lag_deg(carg(x) * (360.0 / A0_TWO_PI) - 90.0);
    out->z_m = AFM_A0_Z_M;
    if (afm_sim_set_state(s, q, qd) != AFM_SIM_OK) {
        snprintf(err, errlen, "A0: the linear warm start was refused");
        goto done;
    }
    const int ks[1] = {1};
    if (afm_sweep_init(&w, c->sim.sample_rate_hz, fe, AFM_A0_TOL, AFM_A0_MAX_PERIODS, ks, 1, err,
                       errlen))
        goto done;
    afm_orbit o;
    int st = afm_sweep_dwell(&w, s, &o, err, errlen);
    if (st < 0) goto done;
    out->settled = st == 1;
    out->periods = w.st.periods;
    out->amplitude_m = o.harmonics[0].x_amp_m;
    out->lag_deg = afm_orbit_lag_deg(o.harmonics[0].x_phase_deg);
    rc = 0;
done:
    afm_sweep_destroy(&w);
    afm_sim_destroy(&s);
    free(c);
    return rc;
}
