/* SPDX-License-Identifier: MIT */
/* afm_sim.c -- the simulator handle: picks a backend, checks inputs, samples outputs. */
#include "integrators/afm_sim_impl.h"

#include "config/afm_limits.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The rt backend; in a portable x86-64 build (AFM_MULTIVERSION) the copy of afm_rt.c
 * compiled for x86-64-v3 where the CPU has AVX2, FMA and BMI1/2, else the baseline copy
 * (afm_rt.c's head). */
static const afm_sim_backend *rt_backend(void) {
#if defined(AFM_MULTIVERSION) && defined(__x86_64__) && defined(__GNUC__)
    __builtin_cpu_init();
    bool v3 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
              __builtin_cpu_supports("bmi") && __builtin_cpu_supports("bmi2");
    return v3 ? &afm_rt_backend_v3 : &afm_rt_backend_base;
#else
    return &afm_rt_backend;
#endif
}

static const afm_sim_backend *backend_for(afm_integrator_kind k) {
    switch (k) {
    case AFM_INTEGRATOR_RT:
        return rt_backend();
    case AFM_INTEGRATOR_REFERENCE:
        return &afm_cvode_backend;
    case AFM_INTEGRATOR_ARKODE_ERK:
        return &afm_arkode_erk_backend;
    }
    return NULL;
}

double afm_sim_tip_x(const afm_sim *s, const double *q) {
    double x = 0.0;
    for (int i = 0; i < s->m.n; i++)
        x += s->m.tip[i] * q[i];
    return x;
}

double afm_sim_rhs(const afm_sim *s, double t_s, const double *q, const double *qd, double *qdd) {
    const afm_modal *m = &s->m;
    double x = 0.0, v = 0.0, acc;
    for (int i = 0; i < m->n; i++) {
        x += m->tip[i] * q[i];
        v += m->tip[i] * qd[i];
    }
    double ub = afm_drive_x(&s->drive, t_s, &acc);
    double f = afm_force_tip(&s->f, s->z_m, x, v, NULL, NULL);
    for (int i = 0; i < m->n; i++) {
        double w = m->omega_rad_s[i];
        qdd[i] = -2.0 * m->xi[i] * w * qd[i] - w * w * q[i] + m->tip[i] * f - m->base_k[i] * ub -
                 m->base_m[i] * acc;
    }
    return f;
}

afm_sim *afm_sim_create(const afm_modal *m, const afm_force_params *f, const afm_cfg_drive *drive,
                        const afm_cfg_sim *cfg, char *err, size_t errlen) {
    const afm_sim_backend *be = backend_for(cfg->integrator);
    if (!be || !(cfg->sample_rate_hz > 0) || m->n < 1 || m->n > AFM_MAX_MODES) {
        snprintf(err, errlen, "afm_sim_create: bad integrator, sample rate or model size");
        return NULL;
    }
    afm_sim *s = calloc(1, sizeof *s);
    if (!s) {
        snprintf(err, errlen, "afm_sim_create: out of memory");
        return NULL;
    }
    s->m = *m;
    s->f = *f;
    s->cfg = *cfg;
    afm_drive_init(&s->drive, drive);
    s->z_m = drive->separation_m;
    s->dt_s = 1.0 / cfg->sample_rate_hz;
    afm_drive_set_grid(&s->drive, s->t_start_s, s->dt_s);
    s->be = be;
    if (be->init(s, err, errlen) != 0) {
        free(s);
        return NULL;
    }
    s->f_last_n = afm_force_tip(&s->f, s->z_m, 0.0, 0.0, NULL, NULL);
    return s;
}

void afm_sim_destroy(afm_sim **sp) {
    if (!sp || !*sp) return;
    afm_sim *s = *sp;
    s->be->destroy(s);
    free(s);
    *sp = NULL;
}

static bool state_finite(const afm_sim *s) {
    /* x, v are sums over every mode (tip_i q_i; tip_i finite): any non-finite q_i shows. */
    if (s->be_fills_tip)
        return isfinite(s->x_last_m) && isfinite(s->v_last_m) && fabs(s->x_last_m) < 1e-3;
    for (int i = 0; i < s->m.n; i++)
        if (!isfinite(s->q[i]) || !isfinite(s->qd[i])) return false;
    /* Runaway: a tip excursion of a millimetre is no cantilever any more. */
    return fabs(afm_sim_tip_x(s, s->q)) < 1e-3;
}

int afm_sim_run(afm_sim *s, int n, afm_sample *out) {
    if (s->be->run) {
        int rc = s->be->run(s, n, out);
        if (rc != AFM_SIM_OK) {
            afm_sim_reset(s);
            return rc == AFM_SIM_ESOLVER ? rc : AFM_SIM_EBLOWUP;
        }
        return AFM_SIM_OK;
    }
    for (int k = 0; k < n; k++) {
        int rc = s->be->advance(s);
        s->step++;
        s->t_s = s->t_start_s + (double)s->step * s->dt_s;
        if (rc != 0 || !state_finite(s)) {
            afm_sim_reset(s);
            return rc == AFM_SIM_ESOLVER ? rc : AFM_SIM_EBLOWUP;
        }
        if (out) {
            afm_sample *o = &out[k];
            double x = 0, v = 0, th = 0;
            if (s->be_fills_tip) {
                for (int i = 0; i < s->m.n; i++)
                    th += s->m.rot[i] * s->q[i];
                x = s->x_last_m;
                v = s->v_last_m;
                o->base_m = s->base_last_m;
            } else {
                for (int i = 0; i < s->m.n; i++) {
                    x += s->m.tip[i] * s->q[i];
                    v += s->m.tip[i] * s->qd[i];
                    th += s->m.rot[i] * s->q[i];
                }
                o->base_m = afm_drive_x(&s->drive, s->t_s, NULL);
            }
            o->t_s = s->t_s;
            o->x_m = x;
            o->v_m_s = v;
            o->f_n = s->f_last_n;
            o->theta_rad = th + s->m.rot_base * o->base_m;
        }
    }
    return AFM_SIM_OK;
}

int afm_sim_set_tone(afm_sim *s, int j, double amp_m, double freq_hz) {
    if (j < 0 || j > s->drive.n || j >= AFM_MAX_TONES || !isfinite(amp_m) || !isfinite(freq_hz) ||
        amp_m < 0 || amp_m > AFM_LIM_TONE_AMPLITUDE_MAX_M || freq_hz <= 0 ||
        freq_hz >= 0.5 * s->cfg.sample_rate_hz)
        return AFM_SIM_EINVAL;
    afm_drive_set_tone(&s->drive, s->t_s, j, amp_m, freq_hz);
    s->be->changed(s);
    return AFM_SIM_OK;
}

int afm_sim_set_tone_phase(afm_sim *s, int j, double amp_m, double freq_hz, double theta_rad) {
    if (j < 0 || j > s->drive.n || j >= AFM_MAX_TONES || !isfinite(amp_m) || !isfinite(freq_hz) ||
        !isfinite(theta_rad) || amp_m < 0 || amp_m > AFM_LIM_TONE_AMPLITUDE_MAX_M || freq_hz <= 0 ||
        freq_hz >= 0.5 * s->cfg.sample_rate_hz)
        return AFM_SIM_EINVAL;
    afm_drive_set_tone_phase(&s->drive, s->t_s, j, amp_m, freq_hz, theta_rad);
    s->be->changed(s);
    return AFM_SIM_OK;
}

int afm_sim_set_separation(afm_sim *s, double z_m) {
    if (!isfinite(z_m) || z_m < 0 || z_m > AFM_LIM_SEPARATION_MAX_M) return AFM_SIM_EINVAL;
    s->z_m = z_m;
    if (s->be->changed_z)
        s->be->changed_z(s);
    else
        s->be->changed(s);
    return AFM_SIM_OK;
}

void afm_sim_reset(afm_sim *s) {
    memset(s->q, 0, sizeof s->q);
    memset(s->qd, 0, sizeof s->qd);
    s->f_last_n = afm_force_tip(&s->f, s->z_m, 0.0, 0.0, NULL, NULL);
    s->be->changed(s);
}

int afm_sim_set_thermal(afm_sim *s, const afm_cfg_thermal *t, char *err, size_t errlen) {
    if (!t) {
        snprintf(err, errlen, "afm_sim_set_thermal: no settings");
        return AFM_SIM_EINVAL;
    }
    if (t->enabled && !(t->temperature_k > 0 && isfinite(t->temperature_k))) {
        snprintf(err, errlen, "thermal: temperature %g K is not > 0", t->temperature_k);
        return AFM_SIM_EINVAL;
    }
    if (t->enabled && !s->be->thermal) {
        snprintf(err, errlen, "thermal: the %s integrator has no thermal force (use rt)",
                 s->be->name);
        return AFM_SIM_EINVAL;
    }
    if (s->be->thermal && s->be->thermal(s, t, err, errlen) != 0) return AFM_SIM_EINVAL;
    s->thermal = *t;
    return AFM_SIM_OK;
}

double afm_sim_time(const afm_sim *s) {
    return s->t_s;
}
double afm_sim_dt(const afm_sim *s) {
    return s->dt_s;
}
double afm_sim_separation(const afm_sim *s) {
    return s->z_m;
}
const afm_drive *afm_sim_drive(const afm_sim *s) {
    return &s->drive;
}
const afm_modal *afm_sim_model(const afm_sim *s) {
    return &s->m;
}
const afm_force_params *afm_sim_forces(const afm_sim *s) {
    return &s->f;
}
const char *afm_sim_integrator_name(const afm_sim *s) {
    return s->be->name;
}

const char *afm_sim_scheme_name(const afm_sim *s) {
    return s->be->scheme ? s->be->scheme(s) : "-";
}

int afm_sim_set_scheme(afm_sim *s, bool accurate) {
    if (!s->be->set_scheme) return AFM_SIM_EINVAL;
    s->be->set_scheme(s, accurate);
    return AFM_SIM_OK;
}

void afm_sim_get_state(const afm_sim *s, double *q, double *qd) {
    for (int i = 0; i < s->m.n; i++) {
        if (q) q[i] = s->q[i];
        if (qd) qd[i] = s->qd[i];
    }
}

int afm_sim_set_state(afm_sim *s, const double *q, const double *qd) {
    if (!q || !qd) return AFM_SIM_EINVAL;
    for (int i = 0; i < s->m.n; i++)
        if (!isfinite(q[i]) || !isfinite(qd[i])) return AFM_SIM_EINVAL;
    for (int i = 0; i < s->m.n; i++) {
        s->q[i] = q[i];
        s->qd[i] = qd[i];
    }
    double x = afm_sim_tip_x(s, s->q), v = afm_sim_tip_x(s, s->qd);
    s->f_last_n = afm_force_tip(&s->f, s->z_m, x, v, NULL, NULL);
    s->be->changed(s);
    return AFM_SIM_OK;
}

void afm_sim_set_events(afm_sim *s, afm_step_events *ring, int cap) {
    if (!ring || cap < 1) {
        s->ev_ring = NULL;
        s->ev_cap = 0;
        return;
    }
    for (int i = 0; i < cap; i++)
        ring[i].step = -1;
    s->ev_ring = ring;
    s->ev_cap = cap;
}

const afm_step_events *afm_sim_events_at(const afm_sim *s, double t_s) {
    if (!s->ev_ring) return NULL;
    double k = nearbyint((t_s - s->t_start_s) / s->dt_s);
    if (!(k >= 0.0 && k < 9e18)) return NULL;
    long step = (long)k;
    const afm_step_events *e = &s->ev_ring[step % s->ev_cap];
    return e->step == step ? e : NULL;
}
