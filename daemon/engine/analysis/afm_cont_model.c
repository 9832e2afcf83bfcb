/* SPDX-License-Identifier: MIT */
/* afm_cont_model.c -- continuation parameters and model instances (contract in
 * afm_cont_model.h). */
#include "analysis/afm_cont_model.h"

#include "runner/afm_cmd.h"
#include "runner/afm_twin.h"
#include "config/afm_err.h"
#include "config/afm_limits.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

int afm_cont_base_init(afm_cont_base *b, const afm_config *cfg, char *err, size_t errlen) {
    if (cfg->drive.n_tones != 1) {
        afm_err_set(err, errlen,
                    "continuation: the drive must be one tone (tone 0), the config has %d",
                    cfg->drive.n_tones);
        return -1;
    }
    static const afm_modal zero;
    b->cfg = *cfg;
    b->m = zero;
    if (afm_model_build(&cfg->model, &b->m, err, errlen) != 0) return -1;
    afm_force_params f;
    return afm_twin_forces(cfg, &b->m, NULL, &f, err, errlen);
}

int afm_cont_param_parse(const afm_cont_base *b, const char *name, afm_cont_param *p, char *err,
                         size_t errlen) {
    memset(p, 0, sizeof *p);
    p->entry = p->index = -1;
    snprintf(p->name, sizeof p->name, "%s", name ? name : "");
    if (!name || !*name) {
        afm_err_set(err, errlen, "continuation: empty parameter name");
        return -1;
    }
    if (!strcmp(name, "fe")) {
        p->kind = AFM_CONT_FE;
        snprintf(p->unit, sizeof p->unit, "Hz");
        return 0;
    }
    if (!strcmp(name, "z") || !strcmp(name, "drive.separation_m")) {
        p->kind = AFM_CONT_Z;
        snprintf(p->unit, sizeof p->unit, "m");
        return 0;
    }
    if (!strcmp(name, "ae")) {
        p->kind = AFM_CONT_AE;
        snprintf(p->unit, sizeof p->unit, "m");
        return 0;
    }
    char why[AFM_ERR_LEN];
    if (afm_param_lookup(name, &p->entry, &p->index, why, sizeof why) != 0) {
        afm_err_set(err, errlen, "continuation: %s (or fe, z, ae)", why);
        return -1;
    }
    int n;
    const afm_param_def *d = &afm_param_table(&n)[p->entry];
    if (d->effect == AFM_PARAM_GEOMETRY) {
        afm_err_set(err, errlen,
                    "continuation: '%s' changes the beam or lumped model, whose modes (the "
                    "orbit's coordinates) would change with it; continue in fe, z, ae, a force "
                    "or a damping parameter",
                    name);
        return -1;
    }
    if (d->n_index > 0 && p->index < 0) {
        afm_err_set(err, errlen, "continuation: '%s' needs an index, e.g. %s[0]", name, name);
        return -1;
    }
    p->kind = AFM_CONT_NAMED;
    snprintf(p->unit, sizeof p->unit, "%s", d->unit);
    /* whether it fits this config (a force term switched off, a mode past the model) */
    afm_config t = b->cfg;
    afm_cmd_param cp = {.n = 1};
    cp.entry[0] = p->entry;
    cp.index[0] = p->index;
    cp.value[0] = afm_param_get(&t, p->entry, p->index);
    if (afm_param_apply(&t, &cp, NULL, why, sizeof why) != 0) {
        afm_err_set(err, errlen, "continuation: %s", why);
        return -1;
    }
    return 0;
}

double afm_cont_param_value(const afm_cont_base *b, const afm_cont_param *p) {
    switch (p->kind) {
    case AFM_CONT_FE:
        return b->cfg.drive.tones[0].frequency_hz;
    case AFM_CONT_Z:
        return b->cfg.drive.separation_m;
    case AFM_CONT_AE:
        return b->cfg.drive.tones[0].amplitude_m;
    case AFM_CONT_NAMED:
        return afm_param_get(&b->cfg, p->entry, p->index);
    }
    return NAN;
}

static int check_direct(const afm_cont_param *p, double v, const afm_config *cfg, char *err,
                        size_t errlen) {
    double lo = 0, hi = 0;
    switch (p->kind) {
    case AFM_CONT_FE:
        lo = AFM_LIM_FREQUENCY_MIN_HZ;
        hi = 0.5 * cfg->sim.sample_rate_hz;
        if (isfinite(v) && v >= lo && v < hi) return 0;
        break;
    case AFM_CONT_Z:
        hi = AFM_LIM_SEPARATION_MAX_M;
        if (isfinite(v) && v >= lo && v <= hi) return 0;
        break;
    case AFM_CONT_AE:
        hi = AFM_LIM_TONE_AMPLITUDE_MAX_M;
        if (isfinite(v) && v >= lo && v <= hi) return 0;
        break;
    case AFM_CONT_NAMED:
        return 0;
    }
    afm_err_set(err, errlen, "continuation: %s = %g %s out of its range [%g, %g%c", p->name, v,
                p->unit, lo, hi, p->kind == AFM_CONT_FE ? ')' : ']');
    return -1;
}

int afm_cont_inst_at(const afm_cont_base *b, const afm_cont_param *ps, const double *vals, int np,
                     afm_cont_inst *out, char *err, size_t errlen) {
    afm_config cfg = b->cfg;
    afm_cmd_param cp = {.n = 0};
    for (int k = 0; k < np; k++) {
        const afm_cont_param *p = &ps[k];
        if (check_direct(p, vals[k], &cfg, err, errlen) != 0) return -1;
        switch (p->kind) {
        case AFM_CONT_FE:
            cfg.drive.tones[0].frequency_hz = vals[k];
            break;
        case AFM_CONT_Z:
            cfg.drive.separation_m = vals[k];
            break;
        case AFM_CONT_AE:
            cfg.drive.tones[0].amplitude_m = vals[k];
            break;
        case AFM_CONT_NAMED:
            cp.entry[cp.n] = p->entry;
            cp.index[cp.n] = p->index;
            cp.value[cp.n] = vals[k];
            cp.n++;
            break;
        }
    }
    char why[AFM_ERR_LEN];
    if (cp.n > 0 && afm_param_apply(&cfg, &cp, NULL, why, sizeof why) != 0) {
        afm_err_set(err, errlen, "continuation: %s", why);
        return -1;
    }
    out->m = b->m;
    for (int i = 0; i < out->m.n && cfg.model.n_damping > 0; i++)
        out->m.xi[i] =
            cfg.model.damping_ratio[i < cfg.model.n_damping ? i : cfg.model.n_damping - 1];
    if (afm_twin_forces(&cfg, &out->m, NULL, &out->f, err, errlen) != 0) return -1;
    out->fe_hz = cfg.drive.tones[0].frequency_hz;
    out->ae_m = cfg.drive.tones[0].amplitude_m;
    out->z_m = cfg.drive.separation_m;
    return 0;
}

double afm_cont_inst_contact_x(const afm_cont_inst *in) {
    const afm_force_params *f = &in->f;
    if (!(f->vdw_contact || f->viscoelastic || f->capillary || f->electrostatic)) return -HUGE_VAL;
    return afm_force_contact_x(f, in->z_m);
}
