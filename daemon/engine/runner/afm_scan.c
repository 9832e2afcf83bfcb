/* SPDX-License-Identifier: MIT */
/* afm_scan.c -- offline imaging with the reference controller (contract in afm_scan.h). */
#include "runner/afm_scan.h"

#include "estimators/afm_cycle.h"
#include "estimators/afm_lockin.h"
#include "integrators/afm_sim_live.h"
#include "runner/afm_a0.h"
#include "runner/afm_twin.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* What a run keeps (heap: the lock-in's tables are large). */
typedef struct {
    afm_lockin lockin;
    afm_cycle cycle;
    afm_force_params mat[AFM_MAX_MATERIALS + 1];
    afm_sample buf[AFM_SCAN_UPDATE_MAX];
    afm_pi pi;
    int material;    /* the region whose forces the integrator has */
    double z_eff_m;  /* the separation it has */
    double a_free_m; /* A0, the free amplitude (runner/afm_a0.h) */
    double z_origin; /* height offset of the image: z_s(origin) - Z at the engage's end */
    /* the pixel being accumulated */
    int px_line, px_pixel, px_n, px_periods;
    bool px_retrace, px_open;
    double s_z, s_a, s_e, s_ph, s_fmax, s_ed, s_esq;
} scan_state;

void afm_scan_position(const afm_scan_cfg *sc, double t_s, double *x_m, double *y_m, int *line,
                       int *pixel, bool *retrace) {
    double T = 1.0 / sc->line_rate_hz, tl = t_s / T;
    int ln = (int)floor(tl);
    double f = tl - ln; /* 0..1 through the line: trace [0, 1/2), retrace [1/2, 1) */
    bool back = f >= 0.5;
    double u = back ? 2.0 - 2.0 * f : 2.0 * f; /* 0..1 along x */
    *x_m = sc->x0_m + u * sc->size_x_m;
    double pitch = sc->lines > 1 ? sc->size_y_m / (sc->lines - 1) : 0.0;
    *y_m = sc->y0_m + tl * pitch;
    if (line) *line = ln;
    if (retrace) *retrace = back;
    if (pixel) {
        int p = (int)floor(u * sc->pixels);
        *pixel = p < 0 ? 0 : p >= sc->pixels ? sc->pixels - 1 : p;
    }
}

static int check_cfg(const afm_scan_cfg *sc, const afm_pi_cfg *pc, char *err, size_t errlen) {
#define SCAN_BAD(...) return snprintf(err, errlen, "scan: " __VA_ARGS__), -1
    if (!(sc->pixels >= 2 && sc->pixels <= AFM_SCAN_PIXELS_MAX))
        SCAN_BAD("pixels must be 2..%d", AFM_SCAN_PIXELS_MAX);
    if (!(sc->lines >= 1 && sc->lines <= AFM_SCAN_LINES_MAX))
        SCAN_BAD("lines must be 1..%d", AFM_SCAN_LINES_MAX);
    if (!(sc->line_rate_hz > 0 && sc->line_rate_hz <= AFM_SCAN_LINE_RATE_MAX_HZ))
        SCAN_BAD("line rate must be in (0, %g] Hz", AFM_SCAN_LINE_RATE_MAX_HZ);
    if (!(sc->size_x_m > 0 && sc->size_x_m <= AFM_SCAN_SIZE_MAX_M))
        SCAN_BAD("scan size x must be in (0, %g] m", AFM_SCAN_SIZE_MAX_M);
    if (!(sc->size_y_m >= 0 && sc->size_y_m <= AFM_SCAN_SIZE_MAX_M))
        SCAN_BAD("scan size y must be in [0, %g] m", AFM_SCAN_SIZE_MAX_M);
    if (!(fabs(sc->x0_m) <= AFM_SCAN_ORIGIN_MAX_M && fabs(sc->y0_m) <= AFM_SCAN_ORIGIN_MAX_M))
        SCAN_BAD("the origin must be within %g m of 0", AFM_SCAN_ORIGIN_MAX_M);
    if (!(sc->engage_s >= 0 && sc->engage_s <= AFM_SCAN_ENGAGE_MAX_S))
        SCAN_BAD("engage time must be 0..%g s", AFM_SCAN_ENGAGE_MAX_S);
    if (!(sc->update_samples >= 1 && sc->update_samples <= AFM_SCAN_UPDATE_MAX))
        SCAN_BAD("update period must be 1..%d samples", AFM_SCAN_UPDATE_MAX);
    if (!(pc->kp >= 0 && pc->kp <= AFM_PI_KP_MAX)) SCAN_BAD("kp must be in [0, %g]", AFM_PI_KP_MAX);
    if (!(pc->ki_hz > 0 && pc->ki_hz <= AFM_PI_KI_MAX_HZ))
        SCAN_BAD("ki must be in (0, %g] 1/s", AFM_PI_KI_MAX_HZ);
    if (!(pc->setpoint_ratio > 0 && pc->setpoint_ratio < 1))
        SCAN_BAD("the set-point ratio must be in (0, 1)");
    if (!(pc->z_rate_max_m_s > 0 && pc->z_rate_max_m_s <= AFM_PI_Z_RATE_MAX_M_S))
        SCAN_BAD("the Z slew limit must be in (0, %g] m/s", AFM_PI_Z_RATE_MAX_M_S);
    if (!(pc->z_min_m < pc->z_max_m)) SCAN_BAD("the Z range is empty");
#undef SCAN_BAD
    return 0;
}

/* Hand the integrator the separation and forces at the tip's position (x, y). */
static int place_tip(afm_sim *s, const afm_surface *surf, scan_state *st, double z_ctrl_m, double x,
                     double y, char *err, size_t errlen) {
    int m = afm_surface_material(surf, x, y);
    bool changed = m != st->material;
    if (changed) {
        if (afm_sim_set_forces(s, &st->mat[m]) != AFM_SIM_OK) {
            snprintf(err, errlen, "scan: the forces of material %d were refused", m);
            return -1;
        }
        st->material = m;
    }
    double z = z_ctrl_m - afm_surface_height(surf, x, y);
    if (z != st->z_eff_m) {
        if (afm_sim_set_separation(s, z) != AFM_SIM_OK) {
            snprintf(err, errlen, "scan: separation %g m refused (the surface rose past the tip)",
                     z);
            return -1;
        }
        st->z_eff_m = z;
        changed = true;
    }
    if (changed) afm_cycle_set_forces(&st->cycle, &st->mat[m], z);
    return 0;
}

/* Run n samples through the estimators; periods that end while a pixel is open count in it. */
static int advance(afm_sim *s, scan_state *st, int n, char *err, size_t errlen) {
    int rc = afm_sim_run(s, n, st->buf);
    if (rc != AFM_SIM_OK) {
        snprintf(err, errlen, "scan: simulation failed (code %d) at t = %.9g s", rc,
                 afm_sim_time(s));
        return -1;
    }
    const afm_drive *d = afm_sim_drive(s);
    for (int i = 0; i < n; i++) {
        double th = afm_drive_phase(d, 0, st->buf[i].t_s);
        afm_lockin_push(&st->lockin, st->buf[i].x_m, th);
        /* the integrator's record of the step when the caller set one (afm_sim_set_events:
         * afmtwin scan does), else NULL and the samples alone */
        const afm_step_events *ev = afm_sim_events_at(s, st->buf[i].t_s);
        if (afm_cycle_push_ev(&st->cycle, &st->buf[i], th, ev) == 1 && st->px_open) {
            st->px_periods++;
            st->s_fmax += st->cycle.out.peak_force_n;
            st->s_ed += st->cycle.out.dissipated_energy_j;
            st->s_esq += st->cycle.out.squeeze_dissipated_energy_j;
        }
    }
    return 0;
}

static void pixel_emit(const afm_scan_cfg *sc, const afm_surface *surf, scan_state *st,
                       afm_scan_on_pixel on_pixel, void *ctx) {
    if (!st->px_open || st->px_n == 0) return;
    afm_scan_pixel px = {.line = st->px_line, .pixel = st->px_pixel, .retrace = st->px_retrace};
    /* the pixel's middle: its centre along x, the slow axis at that time */
    double u = (st->px_pixel + 0.5) / sc->pixels;
    double T = 1.0 / sc->line_rate_hz;
    double t = (st->px_line + (st->px_retrace ? 1.0 - 0.5 * u : 0.5 * u)) * T;
    afm_scan_position(sc, t, &px.x_m, &px.y_m, NULL, NULL, NULL);
    px.true_height_m = afm_surface_height(surf, px.x_m, px.y_m);
    px.material = afm_surface_material(surf, px.x_m, px.y_m);
    double n = st->px_n;
    px.z_m = st->s_z / n;
    px.height_m = px.z_m + st->z_origin;
    px.amplitude_m = st->s_a / n;
    px.error_m = st->s_e / n;
    px.phase_lag_deg = st->s_ph / n;
    px.periods = st->px_periods;
    px.peak_force_n = st->px_periods ? st->s_fmax / st->px_periods : NAN;
    px.dissipated_energy_j = st->px_periods ? st->s_ed / st->px_periods : NAN;
    px.squeeze_dissipated_energy_j = st->px_periods ? st->s_esq / st->px_periods : NAN;
    px.free_amplitude_m = st->a_free_m;
    on_pixel(ctx, &px);
}

static void pixel_open(scan_state *st, int line, int pixel, bool retrace) {
    st->px_line = line;
    st->px_pixel = pixel;
    st->px_retrace = retrace;
    st->px_open = true;
    st->px_n = st->px_periods = 0;
    st->s_z = st->s_a = st->s_e = st->s_ph = st->s_fmax = st->s_ed = st->s_esq = 0.0;
}

/* Retract to Z = 1 um and ring up there (the lock-in settles too) before the engage; the
 * set-point's reference is A0 (runner/afm_a0.h), the same free amplitude as approach's and
 * the daemon's. */
static int free_amplitude(afm_sim *s, const afm_config *cfg, scan_state *st, double settle_s,
                          char *err, size_t errlen) {
    afm_a0 a0;
    if (afm_a0_compute(cfg, &a0, err, errlen)) return -1;
    st->a_free_m = a0.amplitude_m;
    if (afm_sim_set_separation(s, a0.z_m) != AFM_SIM_OK) {
        snprintf(err, errlen, "scan: cannot retract to ring up far from the sample");
        return -1;
    }
    long n = (long)ceil(settle_s / afm_sim_dt(s));
    while (n > 0) {
        int k = n > AFM_SCAN_UPDATE_MAX ? AFM_SCAN_UPDATE_MAX : (int)n;
        if (advance(s, st, k, err, errlen)) return -1;
        n -= k;
    }
    return 0;
}

afm_sim *afm_scan_twin_create(afm_config *cfg, afm_modal *m, char *err, size_t errlen) {
    afm_cfg_forces f0;
    afm_surface_material_forces(&cfg->sample, &cfg->forces, 0, &f0);
    cfg->forces = f0;
    return afm_twin_create(cfg, m, NULL, err, errlen);
}

int afm_scan_run(afm_sim *s, const afm_config *cfg, const afm_modal *m, const afm_surface *surf,
                 const afm_scan_cfg *sc, const afm_pi_cfg *pc, afm_scan_on_pixel on_pixel,
                 void *ctx, char *err, size_t errlen) {
    if (check_cfg(sc, pc, err, errlen)) return -1;
    const afm_cfg_sample *sample = &cfg->sample;
    const afm_cfg_lockin *lockin = &cfg->lockin;
    scan_state *st = calloc(1, sizeof *st);
    if (!st) {
        snprintf(err, errlen, "scan: out of memory");
        return -1;
    }
    int rc = -1;
    double dt = afm_sim_dt(s), z0 = afm_sim_separation(s);
    for (int k = 0; k <= sample->n_materials; k++) {
        afm_cfg_forces f;
        afm_surface_material_forces(sample, &cfg->forces, k, &f);
        if (afm_twin_forces(cfg, m, &f, &st->mat[k], err, errlen)) goto out;
    }
    if (afm_lockin_init(&st->lockin, lockin, dt, err, errlen) ||
        afm_cycle_init(&st->cycle, afm_force_contact_x(&st->mat[0], 1e-6), st->mat[0].cos_alpha,
                       err, errlen))
        goto out;
    if (afm_sim_set_forces(s, &st->mat[0]) != AFM_SIM_OK) {
        snprintf(err, errlen, "scan: the sample's forces were refused");
        goto out;
    }
    double settle = fmax(sc->engage_s, 12.0 * lockin->time_constant_s * lockin->order);
    if (free_amplitude(s, cfg, st, settle, err, errlen)) goto out;
    afm_pi_init(&st->pi, pc, st->a_free_m, z0);
    st->z_eff_m = NAN;
    const int N = sc->update_samples;
    /* engage at the origin */
    long n_eng = (long)ceil(sc->engage_s / (dt * N));
    for (long k = 0; k < n_eng; k++) {
        if (place_tip(s, surf, st, st->pi.z_m, sc->x0_m, sc->y0_m, err, errlen) ||
            advance(s, st, N, err, errlen))
            goto out;
        afm_pi_update(&st->pi, afm_lockin_amplitude(&st->lockin), N * dt);
    }
    st->z_origin = afm_surface_height(surf, sc->x0_m, sc->y0_m) - st->pi.z_m;
    /* the raster */
    double t_total = sc->lines / sc->line_rate_hz;
    long n_upd = (long)ceil(t_total / (dt * N));
    for (long k = 0; k < n_upd; k++) {
        double t_mid = (k + 0.5) * N * dt, x, y;
        int line, pixel;
        bool back;
        afm_scan_position(sc, t_mid, &x, &y, &line, &pixel, &back);
        if (line >= sc->lines) break;
        if (!st->px_open || line != st->px_line || pixel != st->px_pixel ||
            back != st->px_retrace) {
            pixel_emit(sc, surf, st, on_pixel, ctx);
            pixel_open(st, line, pixel, back);
        }
        if (place_tip(s, surf, st, st->pi.z_m, x, y, err, errlen) || advance(s, st, N, err, errlen))
            goto out;
        double a = afm_lockin_amplitude(&st->lockin), lag = afm_lockin_phase_deg(&st->lockin);
        afm_pi_update(&st->pi, a, N * dt);
        st->px_n++;
        st->s_z += st->pi.z_m;
        st->s_a += a;
        st->s_e += st->pi.e_m;
        st->s_ph += lag;
    }
    pixel_emit(sc, surf, st, on_pixel, ctx);
    rc = 0;
out:
    free(st);
    return rc;
}
