/* SPDX-License-Identifier: MIT */
/* afm_pi.c -- the reference PI Z controller (contract in afm_pi.h). */
#include "runner/afm_pi.h"

#include <math.h>

void afm_pi_init(afm_pi *p, const afm_pi_cfg *c, double a_free_m, double z0_m) {
    p->c = *c;
    p->a_set_m = c->setpoint_ratio * a_free_m;
    p->z_i_m = p->z_m = z0_m;
    p->e_m = 0.0;
}

double afm_pi_update(afm_pi *p, double a_m, double dt_s) {
    if (!isfinite(a_m) || !(dt_s > 0)) return p->z_m;
    double e = p->a_set_m - a_m;
    double zi = p->z_i_m + p->c.ki_hz * e * dt_s;
    /* anti-windup: the integrator stays inside the range */
    zi = fmin(fmax(zi, p->c.z_min_m), p->c.z_max_m);
    double z = fmin(fmax(zi + p->c.kp * e, p->c.z_min_m), p->c.z_max_m);
    double dz_max = p->c.z_rate_max_m_s * dt_s;
    if (z > p->z_m + dz_max) z = p->z_m + dz_max;
    if (z < p->z_m - dz_max) z = p->z_m - dz_max;
    p->z_i_m = zi;
    p->z_m = z;
    p->e_m = e;
    return z;
}
