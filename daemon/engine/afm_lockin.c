/* SPDX-License-Identifier: MIT */
/* afm_lockin.c -- lock-in at tone 0 with cascaded first-order filters (contract in
 * afm_lockin.h). */
#include "afm_lockin.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

int afm_lockin_init(afm_lockin *l, const afm_cfg_lockin *cfg, double dt_s, char *err,
                    size_t errlen) {
    if (!l || !cfg || !(cfg->time_constant_s > 0) || !isfinite(cfg->time_constant_s) ||
        cfg->order < 1 || cfg->order > AFM_LOCKIN_MAX_ORDER || !(dt_s > 0) || !isfinite(dt_s)) {
        if (err && errlen)
            snprintf(err, errlen,
                     "lock-in: need time constant > 0 (got %g s), order 1..%d (got %d), sample "
                     "interval > 0 (got %g s)",
                     cfg ? cfg->time_constant_s : NAN, AFM_LOCKIN_MAX_ORDER, cfg ? cfg->order : 0,
                     dt_s);
        return -1;
    }
    memset(l, 0, sizeof *l);
    l->order = cfg->order;
    l->tau_s = cfg->time_constant_s;
    l->dt_s = dt_s;
    l->alpha = -expm1(-dt_s / cfg->time_constant_s);
    return 0;
}

void afm_lockin_reset(afm_lockin *l) {
    memset(l->x, 0, sizeof l->x);
    memset(l->y, 0, sizeof l->y);
    l->n = 0;
}

int afm_lockin_push(afm_lockin *l, double u_m, double theta_rad) {
    if (!isfinite(u_m) || !isfinite(theta_rad)) return -1;
    double ux = 2.0 * u_m * sin(theta_rad), uy = 2.0 * u_m * cos(theta_rad), a = l->alpha;
    for (int i = 0; i < l->order; i++) {
        l->x[i] += a * (ux - l->x[i]);
        l->y[i] += a * (uy - l->y[i]);
        ux = l->x[i];
        uy = l->y[i];
    }
    l->n++;
    return 0;
}

double afm_lockin_x(const afm_lockin *l) {
    return l->x[l->order - 1];
}

double afm_lockin_y(const afm_lockin *l) {
    return l->y[l->order - 1];
}

double afm_lockin_amplitude(const afm_lockin *l) {
    return hypot(afm_lockin_x(l), afm_lockin_y(l));
}

double afm_lockin_phase_deg(const afm_lockin *l) {
    return atan2(-afm_lockin_y(l), afm_lockin_x(l)) * 57.295779513082320876798154814105;
}
