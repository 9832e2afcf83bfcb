/* SPDX-License-Identifier: MIT */
/* afm_config_check.c -- the range and consistency checks on a filled afm_config: what
 * afm_config_validate() runs, and the loader's second pass (afm_config.c), which turns the
 * failing key path back into a file line. Keys and limits: config/README.md. */
#include "config/afm_config.h"
#include "config/afm_config_impl.h"
#include "config/afm_limits.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

static const double deg = 3.14159265358979323846 / 180.0;

#define MAX_HARMONIC 64       /* highest harmonic number an estimator may track */
#define MAX_FULL_SCALE_M 1e-3 /* OBD ADC range: beyond a millimetre is a typo */
#define MAX_TEMPERATURE_K 1e4
#define MAX_DECIMATION 65536 /* AFM_DECIM_MAX_FACTOR */
#define MAX_PASSBAND                                                                               \
    0.95 /* AFM_DECIM_MAX_PASSBAND: the anti-alias transition band                                 \
            shrinks to nothing as the fraction approaches 1 */
#define KEY_LEN AFM_CONFIG_KEY_LEN

/* Write the failing key path and the reason; always returns -1. */
static int bad(char *key, char *why, size_t why_len, const char *path, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
static int bad(char *key, char *why, size_t why_len, const char *path, const char *fmt, ...) {
    snprintf(key, KEY_LEN, "%s", path);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, why_len, fmt, ap);
    va_end(ap);
    return -1;
}

#define BAD(...) return bad(key, why, why_len, __VA_ARGS__)
#define NEED(cond, ...)                                                                            \
    do {                                                                                           \
        if (!(cond)) BAD(__VA_ARGS__);                                                             \
    } while (0)
#define FINITE(v, path) NEED(isfinite(v), path, "not a finite number")
#define POS(v, path) NEED(isfinite(v) && (v) > 0, path, "must be > 0 (got %g)", (v))
#define NONNEG(v, path) NEED(isfinite(v) && (v) >= 0, path, "must be >= 0 (got %g)", (v))
/* A plausibility range of afm_limits.h, both ends included. */
#define RANGE(v, lo, hi, path, unit)                                                               \
    NEED(isfinite(v) && (v) >= (lo) && (v) <= (hi), path, "must be in [%g, %g] %s (got %g)", (lo), \
         (hi), unit, (v))

static int check_model(const afm_config *c, char *key, char *why, size_t why_len) {
    const afm_cfg_model *m = &c->model;
    const afm_cfg_beam *b = &m->beam;
    if (m->kind == AFM_MODEL_BEAM) {
        RANGE(b->youngs_modulus_pa, AFM_LIM_YOUNGS_MIN_PA, AFM_LIM_YOUNGS_MAX_PA,
              "model.beam.youngs_modulus_pa", "Pa");
        RANGE(b->density_kg_m3, AFM_LIM_DENSITY_MIN_KG_M3, AFM_LIM_DENSITY_MAX_KG_M3,
              "model.beam.density_kg_m3", "kg/m^3");
        NEED(isfinite(b->poisson_ratio) && b->poisson_ratio > -1 && b->poisson_ratio < 0.5,
             "model.beam.poisson_ratio", "must be in (-1, 0.5) (got %g)", b->poisson_ratio);
        RANGE(b->length_m, AFM_LIM_LENGTH_MIN_M, AFM_LIM_LENGTH_MAX_M, "model.beam.length_m", "m");
        for (int i = 0; i < 2; i++) {
            char p[64];
            snprintf(p, sizeof p, "model.beam.width_m[%d]", i);
            RANGE(b->width_m[i], AFM_LIM_SECTION_MIN_M, AFM_LIM_SECTION_MAX_M, p, "m");
            snprintf(p, sizeof p, "model.beam.height_m[%d]", i);
            RANGE(b->height_m[i], AFM_LIM_SECTION_MIN_M, AFM_LIM_SECTION_MAX_M, p, "m");
        }
        RANGE(b->tip_mass_kg, 0.0, AFM_LIM_TIP_MASS_MAX_KG, "model.beam.tip_mass_kg", "kg");
        NEED(b->n_elements >= 1 && b->n_elements <= AFM_MAX_ELEMENTS, "model.beam.elements",
             "must be in [1, %d] (got %d)", AFM_MAX_ELEMENTS, b->n_elements);
        NEED(b->n_kept >= 0, "model.beam.kept_modes", "must be >= 0 (got %d)", b->n_kept);
        NEED(b->n_kept + 2 <= AFM_MAX_MODES, "model.beam.kept_modes",
             "kept_modes + 2 reduced modes must be <= %d (got %d)", AFM_MAX_MODES, b->n_kept);
        /* Guided-free beam, ne elements: 2 ne + 1 free DOF once theta1 = 0. Rubin keeps
         * 1 rigid + nk elastic + 2 residual modes, so nk <= 2 ne + 1 - 3. */
        NEED(b->n_kept <= 2 * b->n_elements - 2, "model.beam.kept_modes",
             "%d elements give at most %d kept modes (2*elements - 2), got %d", b->n_elements,
             2 * b->n_elements - 2, b->n_kept);
    } else if (m->kind == AFM_MODEL_LUMPED) {
        RANGE(m->lumped.stiffness_n_m, AFM_LIM_STIFFNESS_MIN_N_M, AFM_LIM_STIFFNESS_MAX_N_M,
              "model.lumped.stiffness_n_m", "N/m");
        RANGE(m->lumped.resonance_hz, AFM_LIM_RESONANCE_MIN_HZ, AFM_LIM_RESONANCE_MAX_HZ,
              "model.lumped.resonance_hz", "Hz");
        NEED(m->lumped.resonance_hz < c->sim.sample_rate_hz / 2, "model.lumped.resonance_hz",
             "must be below half the sample rate (%g Hz), got %g", c->sim.sample_rate_hz / 2,
             m->lumped.resonance_hz);
    } else {
        BAD("model.kind", "unknown model kind %d", (int)m->kind);
    }

    int nmodes = m->kind == AFM_MODEL_BEAM ? b->n_kept + 2 : 1;
    NEED(m->n_damping >= 1 && m->n_damping <= AFM_MAX_MODES, "model.damping_ratio",
         "needs 1 to %d values (got %d)", AFM_MAX_MODES, m->n_damping);
    NEED(m->n_damping <= nmodes, "model.damping_ratio",
         "%d values given but the model has %d mode%s", m->n_damping, nmodes,
         nmodes == 1 ? "" : "s");
    for (int i = 0; i < m->n_damping; i++) {
        char p[64];
        snprintf(p, sizeof p, "model.damping_ratio[%d]", i);
        double xi = m->damping_ratio[i];
        NEED(isfinite(xi) && xi > 0 && xi < 1, p, "must be in (0, 1) (got %g)", xi);
    }
    return 0;
}

static int check_forces(const afm_config *c, char *key, char *why, size_t why_len) {
    const afm_cfg_forces *f = &c->forces;
    /* Finite everywhere, enabled or not: a NaN must not sleep in a disabled group. */
    const struct {
        double v;
        const char *path;
    } all[] = {
        {f->inclination_rad, "forces.inclination_deg"},
        {f->radius_m, "forces.radius_m"},
        {f->hamaker_j, "forces.vdw_contact.hamaker_j"},
        {f->a0_m, "forces.vdw_contact.a0_m"},
        {f->reduced_modulus_pa, "forces.vdw_contact.reduced_modulus_pa"},
        {f->eta_pa_s, "forces.viscoelastic.eta_pa_s"},
        {f->eta0_pa_s, "forces.squeeze.eta0_pa_s"},
        {f->gas_constant_j_kg_k, "forces.squeeze.gas_constant_j_kg_k"},
        {f->temperature_k, "forces.squeeze.temperature_k"},
        {f->pressure_pa, "forces.squeeze.pressure_pa"},
        {f->kappa, "forces.squeeze.kappa"},
        {f->tip_length_m, "forces.squeeze.tip_length_m"},
        {f->plate_length_m, "forces.squeeze.plate_length_m"},
        {f->plate_width_m, "forces.squeeze.plate_width_m"},
        {f->p1_n_s_m2, "forces.squeeze.p1_n_s_m2"},
        {f->p2_n_s_m, "forces.squeeze.p2_n_s_m"},
        {f->surface_energy_j_m2, "forces.capillary.surface_energy_j_m2"},
        {f->contact_angle_rad, "forces.capillary.contact_angle_deg"},
        {f->meniscus_d_m, "forces.capillary.meniscus_d_m"},
        {f->voltage_v, "forces.electrostatic.voltage_v"},
        {f->cone_half_angle_rad, "forces.electrostatic.cone_half_angle_deg"},
        {f->cone_length_m, "forces.electrostatic.cone_length_m"},
    };
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++)
        FINITE(all[i].v, all[i].path);

    NEED(f->inclination_rad >= 0 && f->inclination_rad < 90 * deg, "forces.inclination_deg",
         "must be in [0, 90) degrees (got %g)", f->inclination_rad / deg);
    if (f->vdw_contact || f->viscoelastic || f->capillary) POS(f->radius_m, "forces.radius_m");
    if (f->vdw_contact) {
        NONNEG(f->hamaker_j, "forces.vdw_contact.hamaker_j");
        POS(f->a0_m, "forces.vdw_contact.a0_m");
        RANGE(f->reduced_modulus_pa, AFM_LIM_MODULUS_MIN_PA, AFM_LIM_MODULUS_MAX_PA,
              "forces.vdw_contact.reduced_modulus_pa", "Pa");
    }
    if (f->viscoelastic) {
        NEED(f->vdw_contact, "forces.viscoelastic.enabled",
             "the viscoelastic term (eq. 3.3) needs vdw_contact enabled (it uses a0)");
        NONNEG(f->eta_pa_s, "forces.viscoelastic.eta_pa_s");
    }
    switch (f->squeeze) {
    case AFM_SQUEEZE_NONE:
    case AFM_SQUEEZE_LINEAR: /* p1, p2 of eq. 5.3 may have any sign; finite checked above */
        break;
    case AFM_SQUEEZE_STARR:
        POS(f->eta0_pa_s, "forces.squeeze.eta0_pa_s");
        POS(f->gas_constant_j_kg_k, "forces.squeeze.gas_constant_j_kg_k");
        POS(f->temperature_k, "forces.squeeze.temperature_k");
        POS(f->pressure_pa, "forces.squeeze.pressure_pa");
        NEED(f->kappa >= 0 && f->kappa <= 1, "forces.squeeze.kappa", "must be in [0, 1] (got %g)",
             f->kappa);
        POS(f->tip_length_m, "forces.squeeze.tip_length_m");
        if (c->model.kind == AFM_MODEL_LUMPED) {
            POS(f->plate_length_m, "forces.squeeze.plate_length_m");
            POS(f->plate_width_m, "forces.squeeze.plate_width_m");
        }
        break;
    default:
        BAD("forces.squeeze.model", "unknown squeeze model %d", (int)f->squeeze);
    }
    if (f->capillary) {
        POS(f->surface_energy_j_m2, "forces.capillary.surface_energy_j_m2");
        NEED(f->contact_angle_rad >= 0 && f->contact_angle_rad <= 180 * deg,
             "forces.capillary.contact_angle_deg", "must be in [0, 180] degrees (got %g)",
             f->contact_angle_rad / deg);
        POS(f->meniscus_d_m, "forces.capillary.meniscus_d_m");
    }
    if (f->electrostatic) {
        NEED(f->cone_half_angle_rad > 0 && f->cone_half_angle_rad < 90 * deg,
             "forces.electrostatic.cone_half_angle_deg", "must be in (0, 90) degrees (got %g)",
             f->cone_half_angle_rad / deg);
        POS(f->cone_length_m, "forces.electrostatic.cone_length_m");
    }
    return 0;
}

static int check_drive_sim(const afm_config *c, char *key, char *why, size_t why_len) {
    const afm_cfg_sim *s = &c->sim;
    RANGE(s->sample_rate_hz, AFM_LIM_SAMPLE_RATE_MIN_HZ, AFM_LIM_SAMPLE_RATE_MAX_HZ,
          "sim.sample_rate_hz", "Hz");
    NEED(s->integrator == AFM_INTEGRATOR_RT || s->integrator == AFM_INTEGRATOR_REFERENCE ||
             s->integrator == AFM_INTEGRATOR_ARKODE_ERK,
         "sim.integrator", "unknown integrator %d", (int)s->integrator);
    NEED(s->rt_substeps_contact >= 0 && s->rt_substeps_contact <= AFM_MAX_RT_SUBSTEPS,
         "sim.rt_substeps_contact", "must be in [0, %d] (0 = engine default), got %d",
         AFM_MAX_RT_SUBSTEPS, s->rt_substeps_contact);
    NEED(s->rt_scheme == AFM_RT_SCHEME_AUTO || s->rt_scheme == AFM_RT_SCHEME_ACCURATE ||
             s->rt_scheme == AFM_RT_SCHEME_FAST,
         "sim.rt_scheme", "unknown scheme %d", (int)s->rt_scheme);
    NEED(s->step_events == AFM_STEP_EVENTS_AUTO || s->step_events == AFM_STEP_EVENTS_ON ||
             s->step_events == AFM_STEP_EVENTS_OFF,
         "sim.step_events", "unknown value %d (auto, on or off)", (int)s->step_events);
    NEED(isfinite(s->ref_rtol) && s->ref_rtol > 0 && s->ref_rtol < 1e-2, "sim.ref_rtol",
         "must be in (0, 1e-2) (got %g)", s->ref_rtol);
    NEED(s->n_harmonics >= 0 && s->n_harmonics <= AFM_MAX_HARMONICS, "sim.harmonics",
         "needs 0 (estimators choose) to %d values (got %d)", AFM_MAX_HARMONICS, s->n_harmonics);
    for (int i = 0; i < s->n_harmonics; i++) {
        char p[64];
        snprintf(p, sizeof p, "sim.harmonics[%d]", i);
        NEED(s->harmonics[i] >= 1 && s->harmonics[i] <= MAX_HARMONIC, p,
             "must be in [1, %d] (got %d)", MAX_HARMONIC, s->harmonics[i]);
    }

    const afm_cfg_drive *d = &c->drive;
    RANGE(d->separation_m, 0.0, AFM_LIM_SEPARATION_MAX_M, "drive.separation_m", "m");
    NEED(d->n_tones >= 1 && d->n_tones <= AFM_MAX_TONES, "drive.tones",
         "needs 1 to %d tones (got %d)", AFM_MAX_TONES, d->n_tones);
    double sum_a = 0;
    for (int j = 0; j < d->n_tones; j++) {
        const afm_cfg_tone *t = &d->tones[j];
        char p[64];
        snprintf(p, sizeof p, "drive.tones[%d].amplitude_m", j);
        RANGE(t->amplitude_m, 0.0, AFM_LIM_TONE_AMPLITUDE_MAX_M, p, "m");
        sum_a += t->amplitude_m;
        snprintf(p, sizeof p, "drive.tones[%d].frequency_hz", j);
        NEED(isfinite(t->frequency_hz) && t->frequency_hz >= AFM_LIM_FREQUENCY_MIN_HZ &&
                 t->frequency_hz < s->sample_rate_hz / 2,
             p, "must be in [%g, sample_rate_hz/2 = %g) Hz (got %g)", AFM_LIM_FREQUENCY_MIN_HZ,
             s->sample_rate_hz / 2, t->frequency_hz);
        snprintf(p, sizeof p, "drive.tones[%d].phase_deg", j);
        FINITE(t->phase_rad, p);
    }
    NEED(sum_a <= AFM_LIM_DRIVE_AMPLITUDE_MAX_M, "drive.tones",
         "the amplitudes add up to %g m, more than the %g m a dither piezo strokes", sum_a,
         AFM_LIM_DRIVE_AMPLITUDE_MAX_M);
    return 0;
}

/* obd, thermal, lockin, output (issue 4). */
static int check_chain(const afm_config *c, char *key, char *why, size_t why_len) {
    const afm_cfg_obd *o = &c->obd;
    NONNEG(o->noise_density_m_rthz, "obd.noise_density_m_rthz");
    NEED(o->adc_bits == 0 || (o->adc_bits >= 2 && o->adc_bits <= 32), "obd.adc_bits",
         "must be 0 (no ADC) or in [2, 32] (got %d)", o->adc_bits);
    POS(o->full_scale_m, "obd.full_scale_m");
    NEED(o->full_scale_m <= MAX_FULL_SCALE_M, "obd.full_scale_m", "must be <= %g m (got %g)",
         MAX_FULL_SCALE_M, o->full_scale_m);
    POS(c->thermal.temperature_k, "thermal.temperature_k");
    NEED(c->thermal.temperature_k <= MAX_TEMPERATURE_K, "thermal.temperature_k",
         "must be <= %g K (got %g)", MAX_TEMPERATURE_K, c->thermal.temperature_k);
    const afm_cfg_lockin *l = &c->lockin;
    POS(l->time_constant_s, "lockin.time_constant_s");
    NEED(l->time_constant_s * c->sim.sample_rate_hz >= 1.0, "lockin.time_constant_s",
         "must be at least one sample interval (%g s), got %g", 1.0 / c->sim.sample_rate_hz,
         l->time_constant_s);
    NEED(l->order >= 1 && l->order <= 8, "lockin.order", "must be in [1, 8] (got %d)", l->order);
    const afm_cfg_output *out = &c->output;
    NEED(out->n_outputs >= 1 && out->n_outputs <= AFM_MAX_OUTPUTS, "output.decimation",
         "needs 1 to %d values (got %d)", AFM_MAX_OUTPUTS, out->n_outputs);
    for (int i = 0; i < out->n_outputs; i++) {
        char p[64];
        snprintf(p, sizeof p, "output.decimation[%d]", i);
        NEED(out->decimation[i] >= 1 && out->decimation[i] <= MAX_DECIMATION, p,
             "must be in [1, %d] (got %d)", MAX_DECIMATION, out->decimation[i]);
        for (int j = 0; j < i; j++)
            NEED(out->decimation[j] != out->decimation[i], p, "repeats decimation[%d] = %d", j,
                 out->decimation[i]);
    }
    NEED(isfinite(out->passband_fraction) && out->passband_fraction > 0 &&
             out->passband_fraction <= MAX_PASSBAND,
         "output.passband_fraction", "must be in (0, %g] (got %g)", MAX_PASSBAND,
         out->passband_fraction);
    return 0;
}

/* can (issue 6): frame ids, scales, timing. Checked whether or not the group is enabled. */
static int check_can(const afm_config *c, char *key, char *why, size_t why_len) {
    static const char *const names[AFM_CAN_N_SIGNALS] = {
        "dither_frequency", "dither_amplitude", "dither_phase", "setpoint", "enable", "heartbeat"};
    const afm_cfg_can *k = &c->can;
    size_t n = strnlen(k->interface, sizeof k->interface);
    NEED(n >= 1 && n < sizeof k->interface, "can.interface", "must be 1 to %zu characters",
         sizeof k->interface - 1);
    NEED(k->encoding == AFM_CAN_SCALED || k->encoding == AFM_CAN_FLOAT32, "can.encoding",
         "unknown encoding %d", (int)k->encoding);
    unsigned max_id = k->extended_ids ? 0x1FFFFFFFu : 0x7FFu;
    for (int i = 0; i < AFM_CAN_N_SIGNALS; i++) {
        char p[64];
        snprintf(p, sizeof p, "can.ids.%s", names[i]);
        NEED(k->id[i] <= max_id, p, "0x%X does not fit %s identifier (max 0x%X%s)", k->id[i],
             k->extended_ids ? "a 29-bit" : "an 11-bit", max_id,
             k->extended_ids ? "" : "; set extended_ids = true for 29-bit ids");
        for (int j = 0; j < i; j++)
            NEED(k->id[j] != k->id[i], p, "0x%X is also the id of %s", k->id[i], names[j]);
    }
    const struct {
        double v, max;
        const char *path;
    } sc[] = {{k->scale_frequency_hz, 0.5 * c->sim.sample_rate_hz, "can.scale.frequency_hz"},
              {k->scale_amplitude_m, AFM_LIM_TONE_AMPLITUDE_MAX_M, "can.scale.amplitude_m"},
              {k->scale_phase_rad, 6.283185307179586, "can.scale.phase_rad"},
              {k->scale_separation_m, AFM_LIM_SEPARATION_MAX_M, "can.scale.separation_m"},
              {k->scale_ramp_m_s, AFM_LIM_RAMP_MAX_M_S, "can.scale.ramp_m_s"}};
    for (size_t i = 0; i < sizeof sc / sizeof sc[0]; i++)
        NEED(isfinite(sc[i].v) && sc[i].v > 0 && sc[i].v <= sc[i].max, sc[i].path,
             "value per bit must be in (0, %g] (got %g)", sc[i].max, sc[i].v);
    NEED(isfinite(k->heartbeat_timeout_s) &&
             (k->heartbeat_timeout_s == 0 ||
              (k->heartbeat_timeout_s >= 1e-3 && k->heartbeat_timeout_s <= 3600)),
         "can.heartbeat_timeout_s", "must be 0 (not monitored) or in [0.001, 3600] s (got %g)",
         k->heartbeat_timeout_s);
    NEED(isfinite(k->reconnect_min_s) && k->reconnect_min_s >= 1e-3 && k->reconnect_min_s <= 60,
         "can.reconnect_min_s", "must be in [0.001, 60] s (got %g)", k->reconnect_min_s);
    NEED(isfinite(k->reconnect_max_s) && k->reconnect_max_s >= k->reconnect_min_s &&
             k->reconnect_max_s <= 3600,
         "can.reconnect_max_s", "must be in [reconnect_min_s = %g, 3600] s (got %g)",
         k->reconnect_min_s, k->reconnect_max_s);
    return 0;
}

/* The sample (issue 18): features' sizes and materials' moduli in the ranges a surface
 * can have (heights up to 1 um, edges of at least 0.1 nm: an edge is a smooth C1 ramp). */
static int check_sample(const afm_config *c, char *key, char *why, size_t why_len) {
    const afm_cfg_sample *sm = &c->sample;
    char p[64];
    if (!sm->enabled) return 0;
    for (int i = 0; i < sm->n_features; i++) {
        const afm_cfg_feature *f = &sm->features[i];
#define FP(name) (snprintf(p, sizeof p, "sample.features[%d].%s", i, name), p)
        NEED(isfinite(f->height_m) && fabs(f->height_m) <= 1e-6, FP("height_m"),
             "must be in [-1e-06, 1e-06] m (got %g)", f->height_m);
        FINITE(f->position_m, FP("position_m"));
        FINITE(f->angle_deg, FP("angle_deg"));
        FINITE(f->x_m, FP("x_m"));
        FINITE(f->y_m, FP("y_m"));
        NEED(isfinite(f->slope_x) && fabs(f->slope_x) <= 0.5, FP("slope_x"),
             "must be in [-0.5, 0.5] (got %g)", f->slope_x);
        NEED(isfinite(f->slope_y) && fabs(f->slope_y) <= 0.5, FP("slope_y"),
             "must be in [-0.5, 0.5] (got %g)", f->slope_y);
        NEED(f->material >= 0 && f->material <= sm->n_materials, FP("material"),
             "must be 0 (the forces group's sample) to %d (the materials listed; got %d)",
             sm->n_materials, f->material);
        if (f->kind == AFM_FEATURE_STEP || f->kind == AFM_FEATURE_GRATING)
            RANGE(f->edge_m, 1e-10, 1e-5, FP("edge_m"), "m");
        if (f->kind == AFM_FEATURE_GRATING) {
            RANGE(f->pitch_m, 1e-9, 1e-3, FP("pitch_m"), "m");
            NEED(isfinite(f->duty) && f->duty > 0 && f->duty < 1, FP("duty"),
                 "must be in (0, 1) (got %g)", f->duty);
            NEED(f->edge_m < 0.5 * f->duty * f->pitch_m &&
                     f->edge_m < 0.5 * (1 - f->duty) * f->pitch_m,
                 FP("edge_m"), "must be below half of the top and of the gap (got %g m)",
                 f->edge_m);
        }
        if (f->kind == AFM_FEATURE_SPHERE) RANGE(f->radius_m, 1e-10, 1e-5, FP("radius_m"), "m");
#undef FP
    }
    for (int i = 0; i < sm->n_materials; i++) {
        const afm_cfg_material *m = &sm->materials[i];
#define MP(name) (snprintf(p, sizeof p, "sample.materials[%d].%s", i, name), p)
        if (!isnan(m->reduced_modulus_pa))
            RANGE(m->reduced_modulus_pa, 1e5, 2e12, MP("reduced_modulus_pa"), "Pa");
        if (!isnan(m->hamaker_j)) RANGE(m->hamaker_j, 0.0, 1e-17, MP("hamaker_j"), "J");
        if (!isnan(m->a0_m)) RANGE(m->a0_m, 1e-11, 1e-8, MP("a0_m"), "m");
        if (!isnan(m->eta_pa_s)) RANGE(m->eta_pa_s, 0.0, 1e6, MP("eta_pa_s"), "Pa s");
#undef MP
    }
    if (sm->image_file[0]) {
        RANGE(sm->image_pixel_m, 1e-11, 1e-4, "sample.image.pixel_m", "m");
        NEED(isfinite(sm->image_height_per_level_m) && fabs(sm->image_height_per_level_m) <= 1e-7,
             "sample.image.height_per_level_m", "must be in [-1e-07, 1e-07] m (got %g)",
             sm->image_height_per_level_m);
        FINITE(sm->image_x0_m, "sample.image.x0_m");
        FINITE(sm->image_y0_m, "sample.image.y0_m");
    }
    return 0;
}

/* fm (issue 32): ranges whether or not the group is enabled (the offline tools use the values
 * either way); the loops' fit to the lock-in only when it is (afm_fm_init checks it always). */
static int check_fm(const afm_config *c, char *key, char *why, size_t why_len) {
    const afm_cfg_fm *f = &c->fm;
    NEED(isfinite(f->phase_setpoint_deg) && f->phase_setpoint_deg > 0 &&
             f->phase_setpoint_deg < 180,
         "fm.phase_setpoint_deg", "must be in (0, 180) deg (got %g)", f->phase_setpoint_deg);
    NEED(isfinite(f->pll_bandwidth_hz) && f->pll_bandwidth_hz > 0 && f->pll_bandwidth_hz <= 1e5,
         "fm.pll_bandwidth_hz", "must be in (0, 1e+05] Hz (got %g)", f->pll_bandwidth_hz);
    RANGE(f->pll_kp_hz_per_deg, 0.0, 1e6, "fm.pll_kp_hz_per_deg", "Hz/deg (0: derived)");
    RANGE(f->pll_ki_hz_per_deg_s, 0.0, 1e9, "fm.pll_ki_hz_per_deg_s", "Hz/(deg s) (0: derived)");
    NEED(isfinite(f->max_shift_hz) && f->max_shift_hz > 0 && f->max_shift_hz <= 1e6,
         "fm.max_shift_hz", "must be in (0, 1e+06] Hz (got %g)", f->max_shift_hz);
    NEED(isfinite(f->lock_threshold_deg) && f->lock_threshold_deg > 0 && f->lock_threshold_deg < 90,
         "fm.lock_threshold_deg", "must be in (0, 90) deg (got %g)", f->lock_threshold_deg);
    RANGE(f->lock_time_s, 0.0, 10.0, "fm.lock_time_s", "s (0: derived)");
    RANGE(f->amplitude_setpoint_m, 0.0, 1e-6, "fm.amplitude_setpoint_m",
          "m (0: the free amplitude at tone 0's drive)");
    NEED(isfinite(f->amplitude_bandwidth_hz) && f->amplitude_bandwidth_hz > 0 &&
             f->amplitude_bandwidth_hz <= 1e5,
         "fm.amplitude_bandwidth_hz", "must be in (0, 1e+05] Hz (got %g)",
         f->amplitude_bandwidth_hz);
    RANGE(f->amplitude_kp, 0.0, 1e6, "fm.amplitude_kp", "(0: derived)");
    RANGE(f->amplitude_ki_hz, 0.0, 1e12, "fm.amplitude_ki_hz", "1/s (0: derived)");
    NEED(isfinite(f->drive_max_m) && f->drive_max_m > 0 &&
             f->drive_max_m <= AFM_LIM_DRIVE_AMPLITUDE_MAX_M,
         "fm.drive_max_m", "must be in (0, %g] m (got %g)", AFM_LIM_DRIVE_AMPLITUDE_MAX_M,
         f->drive_max_m);
    NEED(f->update_samples >= 1 && f->update_samples <= 4096, "fm.update_samples",
         "must be in [1, 4096] (got %d)", f->update_samples);
    NEED(f->control == AFM_FM_CONTROL_NONE || f->control == AFM_FM_CONTROL_INTERNAL, "fm.control",
         "must be \"none\" or \"internal\" (got %d)", (int)f->control);
    NEED(f->control == AFM_FM_CONTROL_NONE || f->enabled, "fm.control",
         "\"internal\" needs the fm group enabled (fm.enabled = true)");
    NEED(f->drive == AFM_FM_DRIVE_PLL || f->drive == AFM_FM_DRIVE_SELF, "fm.drive",
         "must be \"pll\" or \"self\" (got %d)", (int)f->drive);
    if (f->enabled) {
        /* the lock-in's filter must leave the loops 45 deg of phase margin at crossover */
        double lag = c->lockin.order * atan(2.0 * 3.14159265358979323846 *
                                            c->lockin.time_constant_s * f->pll_bandwidth_hz);
        NEED(lag <= 0.25 * 3.14159265358979323846, "fm.pll_bandwidth_hz",
             "%g Hz is too fast for the lock-in (order %d, time constant %g s: %.0f deg of lag "
             "at crossover, at most 45)",
             f->pll_bandwidth_hz, c->lockin.order, c->lockin.time_constant_s, lag / deg);
        lag = c->lockin.order * atan(2.0 * 3.14159265358979323846 * c->lockin.time_constant_s *
                                     f->amplitude_bandwidth_hz);
        NEED(lag <= 0.25 * 3.14159265358979323846, "fm.amplitude_bandwidth_hz",
             "%g Hz is too fast for the lock-in (order %d, time constant %g s: %.0f deg of lag "
             "at crossover, at most 45)",
             f->amplitude_bandwidth_hz, c->lockin.order, c->lockin.time_constant_s, lag / deg);
    }
    return 0;
}

/* am (issue 18): ranges whether or not the group is enabled (afmtwin scan uses the values
 * either way); the same as afm_scan_run's (AFM_PI_KP_MAX, AFM_PI_KI_MAX_HZ,
 * AFM_PI_Z_RATE_MAX_M_S in runner/afm_pi.h, a layer above). */
static int check_am(const afm_config *c, char *key, char *why, size_t why_len) {
    const afm_cfg_am *a = &c->am;
    NEED(isfinite(a->setpoint_ratio) && a->setpoint_ratio > 0 && a->setpoint_ratio < 1,
         "am.setpoint_ratio", "must be in (0, 1) (got %g)", a->setpoint_ratio);
    RANGE(a->kp, 0.0, 1e3, "am.kp", "m/m");
    NEED(isfinite(a->ki_hz) && a->ki_hz > 0 && a->ki_hz <= 1e8, "am.ki_hz",
         "must be in (0, 1e+08] 1/s (got %g)", a->ki_hz);
    NEED(isfinite(a->z_rate_max_m_s) && a->z_rate_max_m_s > 0 && a->z_rate_max_m_s <= 10.0,
         "am.z_rate_max_m_s", "must be in (0, 10] m/s (got %g)", a->z_rate_max_m_s);
    RANGE(a->z_min_m, 0.0, AFM_LIM_SEPARATION_MAX_M, "am.z_min_m", "m");
    RANGE(a->z_max_m, 0.0, AFM_LIM_SEPARATION_MAX_M, "am.z_max_m", "m");
    NEED(a->z_min_m < a->z_max_m, "am.z_max_m", "must be above am.z_min_m (%g m; got %g m)",
         a->z_min_m, a->z_max_m);
    NEED(a->control == AFM_AM_CONTROL_NONE || a->control == AFM_AM_CONTROL_INTERNAL, "am.control",
         "must be \"none\" or \"internal\" (got %d)", (int)a->control);
    NEED(a->control == AFM_AM_CONTROL_NONE || a->enabled, "am.control",
         "\"internal\" needs the am group enabled (am.enabled = true)");
    NEED(a->control == AFM_AM_CONTROL_NONE || c->fm.control == AFM_FM_CONTROL_NONE, "am.control",
         "\"internal\" and fm.control = \"internal\" both at once: one Z loop on the amplitude "
         "and an FM loop on it too; choose one");
    return 0;
}

int afm_config_check_all(const afm_config *c, char *key, char *why, size_t why_len) {
    if (check_model(c, key, why, why_len) || check_forces(c, key, why, why_len) ||
        check_drive_sim(c, key, why, why_len) || check_chain(c, key, why, why_len) ||
        check_can(c, key, why, why_len) || check_sample(c, key, why, why_len) ||
        check_fm(c, key, why, why_len) || check_am(c, key, why, why_len))
        return -1;
    return 0;
}

#undef BAD
#undef NEED
#undef FINITE
#undef POS
#undef NONNEG
#undef RANGE

int afm_config_validate(const afm_config *cfg, char *err, size_t errlen) {
    char key[KEY_LEN], why[AFM_ERR_LEN];
    if (afm_config_check_all(cfg, key, why, sizeof why) == 0) return 0;
    if (err && errlen) {
        if (cfg->path[0])
            snprintf(err, errlen, "%s: key '%s': %s", cfg->path, key, why);
        else
            snprintf(err, errlen, "key '%s': %s", key, why);
    }
    return -1;
}
