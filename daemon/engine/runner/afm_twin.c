/* SPDX-License-Identifier: MIT */
/* afm_twin.c -- config -> model -> forces -> simulator, and the sweep step on top. */
#include "runner/afm_twin.h"

#include "beam/afm_model.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void afm_twin_plate(const afm_config *cfg, const afm_modal *m, double *length_m, double *width_m) {
    /* Starr's squeezing plate is the beam itself; the lumped model names its own. */
    *length_m = m->beam_length_m > 0 ? m->beam_length_m : cfg->forces.plate_length_m;
    *width_m = m->beam_mean_width_m > 0 ? m->beam_mean_width_m : cfg->forces.plate_width_m;
}

int afm_twin_forces(const afm_config *cfg, const afm_modal *m, const afm_cfg_forces *fc,
                    afm_force_params *out, char *err, size_t errlen) {
    double len, wid;
    afm_twin_plate(cfg, m, &len, &wid);
    return afm_force_init(out, fc ? fc : &cfg->forces, len, wid, err, errlen);
}

afm_sim *afm_twin_create(const afm_config *cfg, afm_modal *m_out, afm_force_params *f_out,
                         char *err, size_t errlen) {
    static const afm_modal zero_modal;
    afm_modal *m = malloc(sizeof *m);
    afm_force_params f;
    afm_sim *s = NULL;
    if (!m) {
        snprintf(err, errlen, "out of memory");
        return NULL;
    }
    *m = zero_modal;
    if (afm_model_build(&cfg->model, m, err, errlen) != 0) goto done;
    if (afm_twin_forces(cfg, m, NULL, &f, err, errlen) != 0) goto done;
    s = afm_sim_create(m, &f, &cfg->drive, &cfg->sim, err, errlen);
    if (s && cfg->thermal.enabled && afm_sim_set_thermal(s, &cfg->thermal, err, errlen) != 0)
        afm_sim_destroy(&s);
    if (s && m_out) *m_out = *m;
    if (s && f_out) *f_out = f;
done:
    free(m);
    return s;
}

afm_sim *afm_twin_fork(const afm_sim *src, const afm_cfg_sim *sim, char *err, size_t errlen) {
    const afm_drive *d = afm_sim_drive(src);
    double t = afm_sim_time(src), q[AFM_MAX_MODES], qd[AFM_MAX_MODES];
    afm_cfg_drive dc = {.separation_m = afm_sim_separation(src), .n_tones = d->n};
    for (int j = 0; j < d->n; j++) {
        dc.tones[j].amplitude_m = d->amp_m[j];
        dc.tones[j].frequency_hz = d->freq_hz[j];
        dc.tones[j].phase_rad = afm_drive_phase_mod(d, j, t);
    }
    afm_sim *s = afm_sim_create(afm_sim_model(src), afm_sim_forces(src), &dc, sim, err, errlen);
    afm_sim_get_state(src, q, qd);
    if (s && afm_sim_set_state(s, q, qd) != AFM_SIM_OK) {
        snprintf(err, errlen, "fork: the state to copy is not finite");
        afm_sim_destroy(&s);
    }
    return s;
}

int afm_sweep_init(afm_sweep *w, double sample_rate_hz, double fe_min_hz, double tol_rel,
                   int max_periods, const int *ks, int nk, char *err, size_t errlen) {
    memset(w, 0, sizeof *w);
    if (nk < 0 || nk > AFM_MAX_HARMONICS || !(tol_rel > 0) || max_periods < 2 || !(fe_min_hz > 0)) {
        snprintf(err, errlen, "sweep: bad harmonics count, tolerance, period cap or frequency");
        return -1;
    }
    w->cap = afm_orbit_settle_capacity(sample_rate_hz, fe_min_hz, AFM_ORBIT_MAX_P);
    w->buf = w->cap > 0 ? malloc((size_t)w->cap * sizeof *w->buf) : NULL;
    if (!w->buf) {
        snprintf(err, errlen, "sweep: cannot allocate %d samples", w->cap);
        return -1;
    }
    w->tol_rel = tol_rel;
    w->max_periods = max_periods;
    w->nk = nk;
    memcpy(w->ks, ks, (size_t)nk * sizeof *ks);
    return 0;
}

void afm_sweep_destroy(afm_sweep *w) {
    free(w->buf);
    w->buf = NULL;
}

static const char *sim_rc_text(int rc) {
    switch (rc) {
    case AFM_SIM_EINVAL:
        return "value rejected (NaN, or out of range)";
    case AFM_SIM_EBLOWUP:
        return "numerical blow-up (state reset to rest)";
    case AFM_SIM_ESOLVER:
        return "SUNDIALS solver failure (state reset to rest)";
    default:
        return "unknown failure";
    }
}

int afm_sweep_step(afm_sweep *w, afm_sim *s, double fe_hz, double amp_m, afm_orbit *out, char *err,
                   size_t errlen) {
    int rc = afm_sim_set_tone(s, 0, amp_m, fe_hz);
    if (rc != AFM_SIM_OK) {
        snprintf(err, errlen, "cannot set %g Hz, %g m: %s", fe_hz, amp_m, sim_rc_text(rc));
        return -1;
    }
    return afm_sweep_dwell(w, s, out, err, errlen);
}

int afm_sweep_dwell(afm_sweep *w, afm_sim *s, afm_orbit *out, char *err, size_t errlen) {
    const double fe_hz =
        afm_sim_drive(s)->omega_rad_s[0] / 6.283185307179586; /* tone 0 (Hz), for the messages */
    if (afm_orbit_settle_begin(&w->st, w->buf, w->cap, AFM_ORBIT_MAX_P, w->tol_rel, s) != 0) {
        snprintf(err, errlen, "sample buffer too small for %g Hz", fe_hz);
        return -1;
    }
    int settled = 0;
    while (w->st.periods < w->max_periods) {
        double t_fed = afm_sim_time(s); /* samples after this time are new */
        settled = afm_orbit_settle_period(&w->st, s);
        if (settled >= 0 && w->on_samples) {
            int i = w->st.n;
            while (i > 0 && w->st.buf[i - 1].t_s > t_fed)
                i--;
            if (i < w->st.n) w->on_samples(w->on_samples_ctx, s, w->st.buf + i, w->st.n - i);
        }
        if (settled != 0) break;
        if (w->on_period) w->on_period(w->on_period_ctx, &w->st, fe_hz);
    }
    if (settled < 0) {
        snprintf(err, errlen, "at %g Hz after %d periods: %s", fe_hz, w->st.periods,
                 sim_rc_text(settled));
        return -1;
    }
    double xc = afm_force_contact_x(afm_sim_forces(s), afm_sim_separation(s));
    int p = settled ? w->st.p : w->st.p_best;
    if (afm_orbit_analyse(w->st.buf, w->st.n, afm_sim_drive(s), p, xc, w->ks, w->nk, out, err,
                          errlen) != 0)
        return -1;
    return settled ? 1 : 0;
}
