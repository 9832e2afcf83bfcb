/* SPDX-License-Identifier: MIT */
/* afm_config.c -- reads a libconfig file into afm_config and checks it (contract in
 * afm_config.h, keys in config/README.md).
 *
 * Two passes. The loader walks the file group by group (its typed reads: afm_config_read.c;
 * the optional groups sample, can, fm and am: afm_config_opt.c): every member must be a known
 * key of the right type, required keys must be present, and values with no struct field of
 * their own (quality factors, tip/sample moduli) are range-checked on the spot.
 * Then the filled struct goes through the same checks afm_config_validate() runs after CLI
 * overrides (afm_config_check.c); that pass names the failing key by its config path, and the
 * loader turns the path back into a line number. Every failure leaves the caller's struct
 * untouched. */
#include "config/afm_config.h"
#include "config/afm_config_impl.h"
#include "config/afm_config_opt.h"
#include "config/afm_config_read.h"

#include <errno.h>
#include <libconfig.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static const double deg = 3.14159265358979323846 / 180.0;

#define KEY_LEN AFM_CONFIG_KEY_LEN

/* ------------------------------------------------------------------ defaults */

void afm_config_defaults(afm_config *cfg) {
    memset(cfg, 0, sizeof *cfg);
    afm_cfg_model *m = &cfg->model;
    m->kind = AFM_MODEL_BEAM;
    m->beam.poisson_ratio = 0.28;
    m->beam.n_elements = 20;
    m->beam.n_kept = 2;
    m->n_damping = 1;
    m->damping_ratio[0] = 0.005; /* Q = 100 */

    afm_cfg_forces *f = &cfg->forces;
    f->squeeze = AFM_SQUEEZE_NONE;
    f->eta0_pa_s = 1.81e-5;         /* air, Table C.1 footnote 2 */
    f->gas_constant_j_kg_k = 286.9; /* air */
    f->temperature_k = 293.15;
    f->pressure_pa = 101325.0;

    afm_cfg_sim *s = &cfg->sim;
    s->sample_rate_hz = 14.06e6;
    s->integrator = AFM_INTEGRATOR_RT;
    s->rt_substeps_contact = 0; /* 0: the engine chooses */
    s->rt_scheme = AFM_RT_SCHEME_AUTO;
    s->step_events = AFM_STEP_EVENTS_AUTO;
    s->ref_rtol = 1e-10;
    s->n_harmonics = 0; /* the estimators choose (afm_harm_default_list) */

    cfg->obd.enabled = true;
    cfg->obd.noise_density_m_rthz = 0.0;
    cfg->obd.adc_bits = 0;
    cfg->obd.full_scale_m = 1e-6;
    cfg->obd.seed = 1;
    cfg->thermal.enabled = false;
    cfg->thermal.temperature_k = 295.0;
    cfg->thermal.seed = 2;
    cfg->lockin.time_constant_s = 1e-4;
    cfg->lockin.order = 4;
    cfg->output.n_outputs = 1;
    cfg->output.decimation[0] = 16;
    cfg->output.passband_fraction = 0.8;

    /* CAN (issue 6): the default map of docs/can.md, used when a can group is present. */
    afm_cfg_can *c = &cfg->can;
    c->enabled = false;
    snprintf(c->interface, sizeof c->interface, "can0");
    c->encoding = AFM_CAN_SCALED;
    c->id[AFM_CAN_DITHER_FREQUENCY] = 0x200;
    c->id[AFM_CAN_DITHER_AMPLITUDE] = 0x201;
    c->id[AFM_CAN_DITHER_PHASE] = 0x202;
    c->id[AFM_CAN_SETPOINT] = 0x210;
    c->id[AFM_CAN_ENABLE] = 0x220;
    c->id[AFM_CAN_HEARTBEAT] = 0x701; /* CANopen-style heartbeat of node 1 */
    c->scale_frequency_hz = 0.01;
    c->scale_amplitude_m = 1e-15;
    c->scale_phase_rad = 1e-6;
    c->scale_separation_m = 1e-12;
    c->scale_ramp_m_s = 1e-9;
    c->heartbeat_timeout_s = 0.5;
    c->reconnect_min_s = 0.1;
    c->reconnect_max_s = 5.0;

    /* FM control (issue 32): used offline by approach --mode fm with or without a group */
    afm_cfg_fm *fm = &cfg->fm;
    fm->enabled = false;
    fm->phase_setpoint_deg = 90.0;
    fm->pll_bandwidth_hz = 100.0;
    fm->max_shift_hz = 5000.0;
    fm->lock_threshold_deg = 2.0;
    fm->amplitude_bandwidth_hz = 50.0;
    fm->drive_max_m = 1e-6;
    fm->update_samples = 1024; /* the daemon's ring item: 73 us at 14.06 MHz */
    fm->drive = AFM_FM_DRIVE_PLL;

    /* AM Z control (issue 18): afmtwin scan's controller with or without a group */
    afm_cfg_am *am = &cfg->am;
    am->enabled = false;
    am->setpoint_ratio = 0.8;
    am->kp = 0.0;
    am->ki_hz = 2000.0;
    am->z_rate_max_m_s = 1e-3;
    am->z_min_m = 0.0;
    am->z_max_m = 1e-5;
    am->control = AFM_AM_CONTROL_NONE;
}

/* ------------------------------------------------------------------ loader */

/* Geometric profile: a scalar (uniform) or [clamp, free end]. */
static int get_profile(const afm_cfgr *L, const config_setting_t *g, const char *name,
                       double v[2]) {
    config_setting_t *s;
    if (afm_cfgr_member(L, g, name, true, &s)) return -1;
    int t = config_setting_type(s);
    if (t == CONFIG_TYPE_ARRAY || t == CONFIG_TYPE_LIST) {
        int n;
        if (afm_cfgr_vector(L, s, v, 2, &n)) return -1;
        if (n == 1) v[1] = v[0];
        return 0;
    }
    if (afm_cfgr_as_num(L, s, &v[0])) return -1;
    v[1] = v[0];
    return 0;
}

static int load_beam(const afm_cfgr *L, const config_setting_t *g, afm_cfg_beam *b) {
    static const char *const keys[] = {
        "youngs_modulus_pa", "density_kg_m3", "poisson_ratio", "length_m",   "width_m",
        "height_m",          "tip_mass_kg",   "elements",      "kept_modes", NULL};
    if (afm_cfgr_only_keys(L, g, keys) ||
        afm_cfgr_num(L, g, "youngs_modulus_pa", true, &b->youngs_modulus_pa, NULL) ||
        afm_cfgr_num(L, g, "density_kg_m3", true, &b->density_kg_m3, NULL) ||
        afm_cfgr_num(L, g, "poisson_ratio", false, &b->poisson_ratio, NULL) ||
        afm_cfgr_num(L, g, "length_m", true, &b->length_m, NULL) ||
        get_profile(L, g, "width_m", b->width_m) || get_profile(L, g, "height_m", b->height_m) ||
        afm_cfgr_num(L, g, "tip_mass_kg", true, &b->tip_mass_kg, NULL) ||
        afm_cfgr_int(L, g, "elements", false, &b->n_elements) ||
        afm_cfgr_int(L, g, "kept_modes", true, &b->n_kept))
        return -1;
    return 0;
}

static int load_model(const afm_cfgr *L, const config_setting_t *root, afm_cfg_model *m) {
    static const char *const keys[] = {"kind",          "beam",           "lumped",
                                       "damping_ratio", "quality_factor", NULL};
    static const char *const kinds[] = {"beam", "lumped", NULL};
    config_setting_t *g, *beam, *lumped, *xi, *q;
    int kind = 0;
    if (afm_cfgr_group(L, root, "model", true, &g) || afm_cfgr_only_keys(L, g, keys) ||
        afm_cfgr_choice(L, g, "kind", true, kinds, &kind))
        return -1;
    m->kind = (afm_model_kind)kind;
    if (afm_cfgr_group(L, g, "beam", false, &beam) ||
        afm_cfgr_group(L, g, "lumped", false, &lumped))
        return -1;
    if (m->kind == AFM_MODEL_BEAM) {
        if (lumped) return afm_cfgr_fail(L, lumped, NULL, "not used when kind = \"beam\"");
        if (!beam) return afm_cfgr_fail(L, g, "beam", "missing required group (kind = \"beam\")");
        if (load_beam(L, beam, &m->beam)) return -1;
    } else {
        static const char *const lkeys[] = {"stiffness_n_m", "resonance_hz", NULL};
        if (beam) return afm_cfgr_fail(L, beam, NULL, "not used when kind = \"lumped\"");
        if (!lumped)
            return afm_cfgr_fail(L, g, "lumped", "missing required group (kind = \"lumped\")");
        if (afm_cfgr_only_keys(L, lumped, lkeys) ||
            afm_cfgr_num(L, lumped, "stiffness_n_m", true, &m->lumped.stiffness_n_m, NULL) ||
            afm_cfgr_num(L, lumped, "resonance_hz", true, &m->lumped.resonance_hz, NULL))
            return -1;
    }

    xi = config_setting_get_member(g, "damping_ratio");
    q = config_setting_get_member(g, "quality_factor");
    if (xi && q) return afm_cfgr_fail(L, q, NULL, "give damping_ratio or quality_factor, not both");
    if (!xi && !q)
        return afm_cfgr_fail(L, g, "damping_ratio", "missing required key (or quality_factor)");
    if (xi) return afm_cfgr_vector(L, xi, m->damping_ratio, AFM_MAX_MODES, &m->n_damping);
    double qv[AFM_MAX_MODES];
    int n;
    if (afm_cfgr_vector(L, q, qv, AFM_MAX_MODES, &n)) return -1;
    for (int i = 0; i < n; i++) {
        if (!(qv[i] > 0.5))
            return afm_cfgr_fail(L, config_setting_get_elem(q, (unsigned)i), NULL,
                                 "quality factor must be > 0.5 (damping ratio < 1), got %g", qv[i]);
        m->damping_ratio[i] = 1.0 / (2.0 * qv[i]);
    }
    m->n_damping = n;
    return 0;
}

static int load_vdw(const afm_cfgr *L, const config_setting_t *g, afm_cfg_forces *f) {
    static const char *const keys[] = {"enabled",
                                       "hamaker_j",
                                       "a0_m",
                                       "reduced_modulus_pa",
                                       "tip_modulus_pa",
                                       "tip_poisson",
                                       "sample_modulus_pa",
                                       "sample_poisson",
                                       NULL};
    if (afm_cfgr_only_keys(L, g, keys) ||
        afm_cfgr_num(L, g, "hamaker_j", f->vdw_contact, &f->hamaker_j, NULL) ||
        afm_cfgr_num(L, g, "a0_m", f->vdw_contact, &f->a0_m, NULL))
        return -1;
    static const char *const parts[] = {"tip_modulus_pa", "tip_poisson", "sample_modulus_pa",
                                        "sample_poisson"};
    config_setting_t *er = config_setting_get_member(g, "reduced_modulus_pa");
    int nparts = 0;
    for (int i = 0; i < 4; i++)
        nparts += config_setting_get_member(g, parts[i]) != NULL;
    if (er && nparts)
        return afm_cfgr_fail(
            L, er, NULL,
            "give reduced_modulus_pa or the tip/sample moduli and Poisson ratios, not both");
    if (er) return afm_cfgr_as_num(L, er, &f->reduced_modulus_pa);
    if (nparts == 0) {
        if (f->vdw_contact)
            return afm_cfgr_fail(
                L, g, "reduced_modulus_pa",
                "missing required key (or tip_modulus_pa, tip_poisson, sample_modulus_pa, "
                "sample_poisson)");
        return 0;
    }
    double v[4];
    for (int i = 0; i < 4; i++) {
        config_setting_t *s;
        if (afm_cfgr_member(L, g, parts[i], true, &s) || afm_cfgr_as_num(L, s, &v[i])) return -1;
        bool modulus = (i % 2) == 0;
        if (modulus && !(v[i] > 0)) return afm_cfgr_fail(L, s, NULL, "must be > 0 (got %g)", v[i]);
        if (!modulus && !(v[i] > -1 && v[i] < 0.5))
            return afm_cfgr_fail(L, s, NULL, "must be in (-1, 0.5) (got %g)", v[i]);
    }
    /* Eq. 2.22: 1/Er = (1 - nu_t^2)/E_t + (1 - nu_s^2)/E_s */
    f->reduced_modulus_pa = 1.0 / ((1 - v[1] * v[1]) / v[0] + (1 - v[3] * v[3]) / v[2]);
    return 0;
}

static int load_squeeze(const afm_cfgr *L, const config_setting_t *g, afm_model_kind kind,
                        afm_cfg_forces *f) {
    static const char *const beam_keys[] = {
        "model", "eta0_pa_s",    "gas_constant_j_kg_k", "temperature_k", "pressure_pa",
        "kappa", "tip_length_m", "p1_n_s_m2",           "p2_n_s_m",      NULL};
    static const char *const lumped_keys[] = {
        "model",       "eta0_pa_s",      "gas_constant_j_kg_k", "temperature_k",
        "pressure_pa", "kappa",          "tip_length_m",        "p1_n_s_m2",
        "p2_n_s_m",    "plate_length_m", "plate_width_m",       NULL};
    static const char *const models[] = {"none", "starr", "linear", NULL};
    if (kind == AFM_MODEL_BEAM) {
        const char *plate[] = {"plate_length_m", "plate_width_m"};
        for (int i = 0; i < 2; i++) {
            config_setting_t *s = config_setting_get_member(g, plate[i]);
            if (s)
                return afm_cfgr_fail(
                    L, s, NULL, "only for kind = \"lumped\"; a beam takes it from its geometry");
        }
    }
    int sq = 0;
    if (afm_cfgr_only_keys(L, g, kind == AFM_MODEL_BEAM ? beam_keys : lumped_keys) ||
        afm_cfgr_choice(L, g, "model", true, models, &sq))
        return -1;
    f->squeeze = (afm_squeeze_kind)sq;
    bool starr = f->squeeze == AFM_SQUEEZE_STARR, lin = f->squeeze == AFM_SQUEEZE_LINEAR;
    if (afm_cfgr_num(L, g, "eta0_pa_s", false, &f->eta0_pa_s, NULL) ||
        afm_cfgr_num(L, g, "gas_constant_j_kg_k", false, &f->gas_constant_j_kg_k, NULL) ||
        afm_cfgr_num(L, g, "temperature_k", false, &f->temperature_k, NULL) ||
        afm_cfgr_num(L, g, "pressure_pa", false, &f->pressure_pa, NULL) ||
        afm_cfgr_num(L, g, "kappa", starr, &f->kappa, NULL) ||
        afm_cfgr_num(L, g, "tip_length_m", starr, &f->tip_length_m, NULL) ||
        afm_cfgr_num(L, g, "p1_n_s_m2", lin, &f->p1_n_s_m2, NULL) ||
        afm_cfgr_num(L, g, "p2_n_s_m", lin, &f->p2_n_s_m, NULL))
        return -1;
    if (kind == AFM_MODEL_LUMPED &&
        (afm_cfgr_num(L, g, "plate_length_m", starr, &f->plate_length_m, NULL) ||
         afm_cfgr_num(L, g, "plate_width_m", starr, &f->plate_width_m, NULL)))
        return -1;
    return 0;
}

static int load_forces(const afm_cfgr *L, const config_setting_t *root, afm_model_kind kind,
                       afm_cfg_forces *f) {
    static const char *const keys[] = {"inclination_deg", "radius_m", "vdw_contact",
                                       "viscoelastic",    "squeeze",  "capillary",
                                       "electrostatic",   NULL};
    config_setting_t *g, *s;
    double a = 0;
    if (afm_cfgr_group(L, root, "forces", false, &g)) return -1;
    if (!g) return 0; /* no tip forces at all */
    if (afm_cfgr_only_keys(L, g, keys)) return -1;

    if (afm_cfgr_feature(L, g, "vdw_contact", &s, &f->vdw_contact) || (s && load_vdw(L, s, f)))
        return -1;
    if (afm_cfgr_feature(L, g, "viscoelastic", &s, &f->viscoelastic)) return -1;
    if (s) {
        static const char *const vkeys[] = {"enabled", "eta_pa_s", NULL};
        if (afm_cfgr_only_keys(L, s, vkeys) ||
            afm_cfgr_num(L, s, "eta_pa_s", f->viscoelastic, &f->eta_pa_s, NULL))
            return -1;
    }
    if (afm_cfgr_group(L, g, "squeeze", false, &s) || (s && load_squeeze(L, s, kind, f))) return -1;
    if (afm_cfgr_feature(L, g, "capillary", &s, &f->capillary)) return -1;
    if (s) {
        static const char *const ckeys[] = {"enabled", "surface_energy_j_m2", "contact_angle_deg",
                                            "meniscus_d_m", NULL};
        bool on = f->capillary;
        if (afm_cfgr_only_keys(L, s, ckeys) ||
            afm_cfgr_num(L, s, "surface_energy_j_m2", on, &f->surface_energy_j_m2, NULL) ||
            afm_cfgr_num(L, s, "contact_angle_deg", on, &a, NULL) ||
            afm_cfgr_num(L, s, "meniscus_d_m", on, &f->meniscus_d_m, NULL))
            return -1;
        f->contact_angle_rad = a * deg;
    }
    if (afm_cfgr_feature(L, g, "electrostatic", &s, &f->electrostatic)) return -1;
    if (s) {
        static const char *const ekeys[] = {"enabled", "voltage_v", "cone_half_angle_deg",
                                            "cone_length_m", NULL};
        bool on = f->electrostatic;
        a = 0;
        if (afm_cfgr_only_keys(L, s, ekeys) ||
            afm_cfgr_num(L, s, "voltage_v", on, &f->voltage_v, NULL) ||
            afm_cfgr_num(L, s, "cone_half_angle_deg", on, &a, NULL) ||
            afm_cfgr_num(L, s, "cone_length_m", on, &f->cone_length_m, NULL))
            return -1;
        f->cone_half_angle_rad = a * deg;
    }

    a = 0;
    if (afm_cfgr_num(L, g, "inclination_deg", false, &a, NULL)) return -1;
    f->inclination_rad = a * deg;
    bool need_r = f->vdw_contact || f->viscoelastic || f->capillary;
    return afm_cfgr_num(L, g, "radius_m", need_r, &f->radius_m, NULL);
}

static int load_drive(const afm_cfgr *L, const config_setting_t *root, afm_cfg_drive *d) {
    static const char *const keys[] = {"separation_m", "tones", NULL};
    static const char *const tkeys[] = {"amplitude_m", "frequency_hz", "phase_deg", NULL};
    config_setting_t *g, *tones;
    if (afm_cfgr_group(L, root, "drive", true, &g) || afm_cfgr_only_keys(L, g, keys) ||
        afm_cfgr_num(L, g, "separation_m", true, &d->separation_m, NULL) ||
        afm_cfgr_member(L, g, "tones", true, &tones))
        return -1;
    if (config_setting_type(tones) != CONFIG_TYPE_LIST)
        return afm_cfgr_fail(L, tones, NULL, "expected a list ( { ... }, ... ), got %s",
                             afm_cfgr_type(tones));
    int n = config_setting_length(tones);
    if (n < 1 || n > AFM_MAX_TONES)
        return afm_cfgr_fail(L, tones, NULL, "needs 1 to %d tones (got %d)", AFM_MAX_TONES, n);
    for (int j = 0; j < n; j++) {
        config_setting_t *t = config_setting_get_elem(tones, (unsigned)j);
        afm_cfg_tone *tone = &d->tones[j];
        double ph = 0;
        if (config_setting_type(t) != CONFIG_TYPE_GROUP)
            return afm_cfgr_fail(L, t, NULL,
                                 "expected a group { amplitude_m; frequency_hz; ... }, got %s",
                                 afm_cfgr_type(t));
        if (afm_cfgr_only_keys(L, t, tkeys) ||
            afm_cfgr_num(L, t, "amplitude_m", true, &tone->amplitude_m, NULL) ||
            afm_cfgr_num(L, t, "frequency_hz", true, &tone->frequency_hz, NULL) ||
            afm_cfgr_num(L, t, "phase_deg", false, &ph, NULL))
            return -1;
        tone->phase_rad = ph * deg;
    }
    d->n_tones = n;
    return 0;
}

static int load_sim(const afm_cfgr *L, const config_setting_t *root, afm_cfg_sim *s) {
    static const char *const keys[] = {"sample_rate_hz", "integrator",  "rt_substeps_contact",
                                       "rt_scheme",      "step_events", "ref_rtol",
                                       "harmonics",      NULL};
    static const char *const integrators[] = {"rt", "reference", "arkode-erk", NULL};
    static const char *const schemes[] = {"auto", "accurate", "fast", NULL};
    static const char *const step_events[] = {"auto", "on", "off", NULL};
    config_setting_t *g, *h;
    int integ = (int)s->integrator, scheme = (int)s->rt_scheme, ev = (int)s->step_events;
    if (afm_cfgr_group(L, root, "sim", false, &g)) return -1;
    if (!g) return 0;
    if (afm_cfgr_only_keys(L, g, keys) ||
        afm_cfgr_num(L, g, "sample_rate_hz", false, &s->sample_rate_hz, NULL) ||
        afm_cfgr_choice(L, g, "integrator", false, integrators, &integ) ||
        afm_cfgr_int(L, g, "rt_substeps_contact", false, &s->rt_substeps_contact) ||
        afm_cfgr_choice(L, g, "rt_scheme", false, schemes, &scheme) ||
        afm_cfgr_choice(L, g, "step_events", false, step_events, &ev) ||
        afm_cfgr_num(L, g, "ref_rtol", false, &s->ref_rtol, NULL) ||
        afm_cfgr_member(L, g, "harmonics", false, &h))
        return -1;
    s->integrator = (afm_integrator_kind)integ;
    s->rt_scheme = (afm_rt_scheme_kind)scheme;
    s->step_events = (afm_step_events_kind)ev;
    if (h) {
        int t = config_setting_type(h), n = config_setting_length(h);
        if (t != CONFIG_TYPE_ARRAY && t != CONFIG_TYPE_LIST)
            return afm_cfgr_fail(L, h, NULL, "expected an array of integers, got %s",
                                 afm_cfgr_type(h));
        if (n < 1 || n > AFM_MAX_HARMONICS)
            return afm_cfgr_fail(L, h, NULL, "needs 1 to %d values (got %d)", AFM_MAX_HARMONICS, n);
        for (int i = 0; i < n; i++)
            if (afm_cfgr_as_int(L, config_setting_get_elem(h, (unsigned)i), &s->harmonics[i]))
                return -1;
        s->n_harmonics = n;
    }
    return 0;
}

/* Non-negative integer that fits an unsigned long (noise generator seeds). */
static int get_seed(const afm_cfgr *L, const config_setting_t *g, const char *name,
                    unsigned long *out) {
    config_setting_t *s;
    if (afm_cfgr_member(L, g, name, false, &s)) return -1;
    if (!s) return 0;
    long long v = 0;
    if (afm_cfgr_as_integer(L, s, &v)) return -1;
    if (v < 0) return afm_cfgr_fail(L, s, NULL, "must be >= 0 (got %lld)", v);
    *out = (unsigned long)v;
    return 0;
}

/* obd, thermal, lockin, output: optional groups (issue 4). obd is on unless the group
 * says enabled = false; thermal is off unless its group is present (enabled defaults to
 * true then, as for the force features). */
static int load_chain(const afm_cfgr *L, const config_setting_t *root, afm_config *c) {
    static const char *const okeys[] = {
        "enabled", "noise_density_m_rthz", "adc_bits", "full_scale_m", "seed", NULL};
    static const char *const tkeys[] = {"enabled", "temperature_k", "seed", NULL};
    static const char *const lkeys[] = {"time_constant_s", "order", NULL};
    static const char *const outkeys[] = {"decimation", "passband_fraction", NULL};
    config_setting_t *g, *s;
    if (afm_cfgr_group(L, root, "obd", false, &g)) return -1;
    if (g &&
        (afm_cfgr_only_keys(L, g, okeys) || afm_cfgr_bool(L, g, "enabled", &c->obd.enabled) ||
         afm_cfgr_num(L, g, "noise_density_m_rthz", false, &c->obd.noise_density_m_rthz, NULL) ||
         afm_cfgr_int(L, g, "adc_bits", false, &c->obd.adc_bits) ||
         afm_cfgr_num(L, g, "full_scale_m", false, &c->obd.full_scale_m, NULL) ||
         get_seed(L, g, "seed", &c->obd.seed)))
        return -1;
    if (afm_cfgr_feature(L, root, "thermal", &g, &c->thermal.enabled)) return -1;
    if (g && (afm_cfgr_only_keys(L, g, tkeys) ||
              afm_cfgr_num(L, g, "temperature_k", false, &c->thermal.temperature_k, NULL) ||
              get_seed(L, g, "seed", &c->thermal.seed)))
        return -1;
    if (afm_cfgr_group(L, root, "lockin", false, &g)) return -1;
    if (g && (afm_cfgr_only_keys(L, g, lkeys) ||
              afm_cfgr_num(L, g, "time_constant_s", false, &c->lockin.time_constant_s, NULL) ||
              afm_cfgr_int(L, g, "order", false, &c->lockin.order)))
        return -1;
    if (afm_cfgr_group(L, root, "output", false, &g)) return -1;
    if (!g) return 0;
    if (afm_cfgr_only_keys(L, g, outkeys) ||
        afm_cfgr_num(L, g, "passband_fraction", false, &c->output.passband_fraction, NULL) ||
        afm_cfgr_member(L, g, "decimation", false, &s))
        return -1;
    if (s) {
        int t = config_setting_type(s), n = config_setting_length(s);
        if (t != CONFIG_TYPE_ARRAY && t != CONFIG_TYPE_LIST)
            return afm_cfgr_fail(L, s, NULL, "expected an array of integers, got %s",
                                 afm_cfgr_type(s));
        if (n < 1 || n > AFM_MAX_OUTPUTS)
            return afm_cfgr_fail(L, s, NULL, "needs 1 to %d values (got %d)", AFM_MAX_OUTPUTS, n);
        for (int i = 0; i < n; i++)
            if (afm_cfgr_as_int(L, config_setting_get_elem(s, (unsigned)i),
                                &c->output.decimation[i]))
                return -1;
        c->output.n_outputs = n;
    }
    return 0;
}

#define MAX_CONFIG_BYTES (1 << 20) /* a config is a few kB; a larger file is not one */

static int load_parsed(config_t *lc, afm_cfgr *L, afm_config *tmp, afm_config *cfg);

/* A config from the libconfig text in text (name: what messages call it). */
int afm_config_parse(const char *text, const char *name, afm_config *cfg, char *err,
                     size_t errlen) {
    if (!name) name = "(string)";
    afm_cfgr L = {name, err, errlen};
    if (err && errlen) err[0] = '\0';
    if (!text || !cfg) {
        if (err && errlen) snprintf(err, errlen, "afm_config_parse: NULL argument");
        return -1;
    }
    static afm_config tmp; /* not on the stack: 1.2 kB, and callers are not real-time */
    afm_config_defaults(&tmp);
    snprintf(tmp.path, sizeof tmp.path, "%s", name);
    config_t lc;
    config_init(&lc);
    if (config_read_string(&lc, text) != CONFIG_TRUE) {
        if (err && errlen)
            snprintf(err, errlen, "%s:%d: cannot parse: %s", name, config_error_line(&lc),
                     config_error_text(&lc) ? config_error_text(&lc) : "?");
        config_destroy(&lc);
        return -1;
    }
    return load_parsed(&lc, &L, &tmp, cfg);
}

int afm_config_load(const char *path, afm_config *cfg, char *err, size_t errlen) {
    afm_cfgr L = {path ? path : "(null)", err, errlen};
    if (err && errlen) err[0] = '\0';
    if (!path || !cfg) {
        if (err && errlen) snprintf(err, errlen, "afm_config_load: NULL argument");
        return -1;
    }
    afm_config tmp;
    afm_config_defaults(&tmp);
    if (strlen(path) >= sizeof tmp.path) {
        if (err && errlen)
            snprintf(err, errlen, "%s: path longer than %zu characters", path, sizeof tmp.path - 1);
        return -1;
    }
    snprintf(tmp.path, sizeof tmp.path, "%s", path);
    struct stat st;
    if (stat(path, &st) == 0 && (S_ISDIR(st.st_mode) || st.st_size > MAX_CONFIG_BYTES)) {
        if (err && errlen)
            snprintf(err, errlen, "%s: %s", path,
                     S_ISDIR(st.st_mode) ? "is a directory, not a config file"
                                         : "larger than 1 MiB: not a config file");
        return -1;
    }

    config_t lc;
    config_init(&lc);
    errno = 0;
    if (config_read_file(&lc, path) != CONFIG_TRUE) {
        if (err && errlen) {
            if (config_error_type(&lc) == CONFIG_ERR_FILE_IO)
                snprintf(err, errlen, "%s: cannot read file: %s", path,
                         errno ? strerror(errno) : "I/O error");
            else
                snprintf(err, errlen, "%s:%d: cannot parse: %s",
                         config_error_file(&lc) ? config_error_file(&lc) : path,
                         config_error_line(&lc), config_error_text(&lc));
        }
        config_destroy(&lc);
        return -1;
    }
    return load_parsed(&lc, &L, &tmp, cfg);
}

/* The groups and the checks of a parsed file; destroys lc. */
static int load_parsed(config_t *lc, afm_cfgr *L, afm_config *tmp, afm_config *cfg) {
    int rc = -1;
    char *err = L->err;
    size_t errlen = L->errlen;
    const config_setting_t *root = config_root_setting(lc);
    static const char *const keys[] = {"model",   "forces", "drive",  "sim", "obd",
                                       "thermal", "lockin", "output", "can", "sample",
                                       "fm",      "am",     NULL};
    if (afm_cfgr_only_keys(L, root, keys) || load_model(L, root, &tmp->model) ||
        load_forces(L, root, tmp->model.kind, &tmp->forces) || load_drive(L, root, &tmp->drive) ||
        load_sim(L, root, &tmp->sim) || load_chain(L, root, tmp) ||
        afm_config_opt_can(L, root, &tmp->can) || afm_config_opt_sample(L, root, &tmp->sample) ||
        afm_config_opt_fm(L, root, &tmp->fm) || afm_config_opt_am(L, root, &tmp->am))
        goto out;

    char key[KEY_LEN], why[AFM_ERR_LEN];
    if (afm_config_check_all(tmp, key, why, sizeof why)) {
        /* Name the key as the file spells it: quality_factor for Q given damping ratios,
         * width_m rather than width_m[1] for a scalar standing for both ends. */
        static const char xi_key[] = "model.damping_ratio";
        if (strncmp(key, xi_key, sizeof xi_key - 1) == 0 &&
            config_lookup(lc, "model.quality_factor")) {
            char rest[16]; /* "" or "[i]" */
            snprintf(rest, sizeof rest, "%.15s", key + sizeof xi_key - 1);
            snprintf(key, sizeof key, "model.quality_factor%s", rest);
        }
        const config_setting_t *s = afm_cfgr_resolve(root, key);
        char *br = strrchr(key, '[');
        /* "x.width_m[1]" resolved to a named scalar (not an array element): drop "[1]" */
        if (br && !strchr(br, '.') && config_setting_is_scalar(s) && config_setting_name(s))
            *br = '\0';
        if (err && errlen)
            snprintf(err, errlen, "%s:%d: key '%s': %s", afm_cfgr_file(L, s), afm_cfgr_line(s), key,
                     why);
        goto out;
    }
    *cfg = *tmp;
    rc = 0;
out:
    config_destroy(lc);
    return rc;
}
