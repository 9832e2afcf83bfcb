/* SPDX-License-Identifier: MIT */
/* afm_sim_live.c -- live changes to a running simulator (contract in afm_sim_live.h). */
#include "integrators/afm_sim_live.h"

#include "integrators/afm_sim_impl.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double two_pi = 6.283185307179586476925286766559;

int afm_sim_start_tone(afm_sim *s, int j, double amp_m, double freq_hz, double phase_rad) {
    if (!isfinite(phase_rad)) return AFM_SIM_EINVAL;
    bool starts = j == s->drive.n;
    int rc = afm_sim_set_tone(s, j, amp_m, freq_hz);
    if (rc != AFM_SIM_OK || !starts) return rc;
    double ph = fmod(phase_rad, two_pi);
    if (ph < 0) ph += two_pi;
    s->drive.phase_rad[j] = ph; /* t0_j is now (afm_drive_set_tone) */
    s->be->changed(s);
    return AFM_SIM_OK;
}

int afm_sim_drop_tones(afm_sim *s, int n) {
    if (n < 1 || n > s->drive.n) return AFM_SIM_EINVAL;
    if (n == s->drive.n) return AFM_SIM_OK;
    for (int j = n; j < AFM_MAX_TONES; j++) {
        s->drive.amp_m[j] = s->drive.omega_rad_s[j] = s->drive.freq_hz[j] = 0;
        s->drive.phase_rad[j] = s->drive.t0_s[j] = 0;
        s->drive.on_grid[j] = false;
    }
    s->drive.n = n;
    s->be->changed(s);
    return AFM_SIM_OK;
}

int afm_sim_set_forces(afm_sim *s, const afm_force_params *f) {
    if (!f || f->vdw_contact != s->f.vdw_contact || f->viscoelastic != s->f.viscoelastic ||
        f->squeeze != s->f.squeeze || f->capillary != s->f.capillary ||
        f->electrostatic != s->f.electrostatic)
        return AFM_SIM_EINVAL;
    s->f = *f;
    /* Keep the tip force of the current state consistent with the new constants. */
    double x = afm_sim_tip_x(s, s->q), v = afm_sim_tip_x(s, s->qd);
    s->f_last_n = afm_force_tip(&s->f, s->z_m, x, v, NULL, NULL);
    s->be->changed(s);
    return AFM_SIM_OK;
}

int afm_sim_set_time(afm_sim *s, double t_s) {
    if (!isfinite(t_s) || t_s < 0 || t_s > 1e9) return AFM_SIM_EINVAL;
    afm_drive_retime(&s->drive, s->t_s, t_s);
    s->t_start_s = s->t_s = t_s;
    s->step = 0;
    afm_drive_set_grid(&s->drive, s->t_start_s, s->dt_s);
    s->be->changed(s);
    return AFM_SIM_OK;
}

int afm_sim_continue(afm_sim *dst, const afm_sim *src, unsigned what) {
    if ((what & AFM_SIM_KEEP_STATE) && dst->m.n != src->m.n) return AFM_SIM_EINVAL;
    double t = src->t_s;
    /* Time: same step count and origin, so t_s = t_start + step dt stays exact. A reload
     * may change dt; then the new simulator starts its own step count at t. */
    if (dst->dt_s == src->dt_s) {
        dst->t_start_s = src->t_start_s;
        dst->step = src->step;
    } else {
        dst->t_start_s = t;
        dst->step = 0;
    }
    dst->t_s = t;
    if (what & AFM_SIM_KEEP_DRIVE) {
        dst->drive = src->drive;
        dst->z_m = src->z_m;
        afm_drive_retime(&dst->drive, t, t); /* from t, exact on src's grid */
    } else {
        afm_drive_restart(&dst->drive, t); /* phase_rad[j] is the configured phase */
    }
    afm_drive_set_grid(&dst->drive, dst->t_start_s, dst->dt_s);
    if (what & AFM_SIM_KEEP_STATE) {
        memcpy(dst->q, src->q, sizeof dst->q);
        memcpy(dst->qd, src->qd, sizeof dst->qd);
    } else {
        memset(dst->q, 0, sizeof dst->q);
        memset(dst->qd, 0, sizeof dst->qd);
    }
    double x = afm_sim_tip_x(dst, dst->q), v = afm_sim_tip_x(dst, dst->qd);
    dst->f_last_n = afm_force_tip(&dst->f, dst->z_m, x, v, NULL, NULL);
    dst->be->changed(dst);
    return AFM_SIM_OK;
}

/* ---- mirror ------------------------------------------------------------------------- */

static int mirror_run(afm_sim *s, int n, afm_sample *out) {
    (void)s;
    (void)n;
    (void)out;
    return AFM_SIM_EINVAL; /* a mirror has no integrator */
}
static int mirror_advance(afm_sim *s) {
    (void)s;
    return AFM_SIM_EINVAL;
}
static void mirror_changed(afm_sim *s) {
    (void)s;
}
static void mirror_destroy(afm_sim *s) {
    (void)s;
}

static const afm_sim_backend mirror_backend = {
    .name = "mirror",
    .advance = mirror_advance,
    .run = mirror_run,
    .changed = mirror_changed,
    .destroy = mirror_destroy,
};

afm_sim *afm_sim_mirror_create(const afm_sim *src, char *err, size_t errlen) {
    afm_sim *m = malloc(sizeof *m);
    if (!m) {
        if (err && errlen) snprintf(err, errlen, "sim mirror: out of memory");
        return NULL;
    }
    *m = *src;
    m->be = &mirror_backend;
    m->be_state = NULL;
    return m;
}

void afm_sim_mirror_set(afm_sim *mirror, const afm_drive *d, const afm_force_params *f,
                        double z_m) {
    if (d) mirror->drive = *d;
    if (f) mirror->f = *f;
    mirror->z_m = z_m;
}
