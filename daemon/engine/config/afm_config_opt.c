/* SPDX-License-Identifier: MIT */
/* afm_config_opt.c -- the config loader's optional groups: the instruments around the
 * cantilever that are off unless their group is in the file -- sample (issue 18), can
 * (issue 6), fm (issue 32), am (issue 18). Each reads its keys and their types only (with
 * afm_config_read.h); ranges and consistency are afm_config_check.c's. Split from
 * afm_config.c, which reads the groups every config has and calls these (contract in
 * afm_config_opt.h). */
#include "config/afm_config_opt.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* sample: optional group (issue 18): features = ( { type = "..."; ... }, ... ), an image
 * group and materials = ( { ... }, ... ). Ranges are checked in afm_config_check.c. */
static int load_feature(const afm_cfgr *L, const config_setting_t *g, afm_cfg_feature *f) {
    static const char *const keys[] = {"type",    "height_m", "position_m", "angle_deg", "pitch_m",
                                       "duty",    "edge_m",   "x_m",        "y_m",       "radius_m",
                                       "slope_x", "slope_y",  "material",   NULL};
    static const char *const kinds[] = {"tilt", "step", "grating", "sphere", NULL};
    if (config_setting_type(g) != CONFIG_TYPE_GROUP)
        return afm_cfgr_fail(L, g, NULL, "expected a group { type = ...; ... }, got %s",
                             afm_cfgr_type(g));
    int kind = 0;
    *f = (afm_cfg_feature){.duty = 0.5, .edge_m = 1e-8};
    if (afm_cfgr_only_keys(L, g, keys) || afm_cfgr_choice(L, g, "type", true, kinds, &kind) ||
        afm_cfgr_num(L, g, "height_m", false, &f->height_m, NULL) ||
        afm_cfgr_num(L, g, "position_m", false, &f->position_m, NULL) ||
        afm_cfgr_num(L, g, "angle_deg", false, &f->angle_deg, NULL) ||
        afm_cfgr_num(L, g, "pitch_m", kind == AFM_FEATURE_GRATING, &f->pitch_m, NULL) ||
        afm_cfgr_num(L, g, "duty", false, &f->duty, NULL) ||
        afm_cfgr_num(L, g, "edge_m", false, &f->edge_m, NULL) ||
        afm_cfgr_num(L, g, "x_m", false, &f->x_m, NULL) ||
        afm_cfgr_num(L, g, "y_m", false, &f->y_m, NULL) ||
        afm_cfgr_num(L, g, "radius_m", kind == AFM_FEATURE_SPHERE, &f->radius_m, NULL) ||
        afm_cfgr_num(L, g, "slope_x", false, &f->slope_x, NULL) ||
        afm_cfgr_num(L, g, "slope_y", false, &f->slope_y, NULL) ||
        afm_cfgr_int(L, g, "material", false, &f->material))
        return -1;
    f->kind = (afm_feature_kind)kind;
    return 0;
}

static int load_material(const afm_cfgr *L, const config_setting_t *g, afm_cfg_material *m) {
    static const char *const keys[] = {"reduced_modulus_pa", "hamaker_j", "a0_m", "eta_pa_s", NULL};
    if (config_setting_type(g) != CONFIG_TYPE_GROUP)
        return afm_cfgr_fail(L, g, NULL, "expected a group { reduced_modulus_pa = ...; }, got %s",
                             afm_cfgr_type(g));
    *m = (afm_cfg_material){NAN, NAN, NAN, NAN};
    return afm_cfgr_only_keys(L, g, keys) ||
                   afm_cfgr_num(L, g, "reduced_modulus_pa", false, &m->reduced_modulus_pa, NULL) ||
                   afm_cfgr_num(L, g, "hamaker_j", false, &m->hamaker_j, NULL) ||
                   afm_cfgr_num(L, g, "a0_m", false, &m->a0_m, NULL) ||
                   afm_cfgr_num(L, g, "eta_pa_s", false, &m->eta_pa_s, NULL)
               ? -1
               : 0;
}

static int one_feature(const afm_cfgr *L, const config_setting_t *g, void *f) {
    return load_feature(L, g, f);
}
static int one_material(const afm_cfgr *L, const config_setting_t *g, void *m) {
    return load_material(L, g, m);
}

int afm_config_opt_sample(const afm_cfgr *L, const config_setting_t *root, afm_cfg_sample *c) {
    static const char *const keys[] = {"enabled", "features", "materials", "image", NULL};
    static const char *const ikeys[] = {"file", "pixel_m", "height_per_level_m",
                                        "x0_m", "y0_m",    NULL};
    config_setting_t *g, *im, *s;
    if (afm_cfgr_feature(L, root, "sample", &g, &c->enabled)) return -1;
    if (!g) return 0;
    if (afm_cfgr_only_keys(L, g, keys) ||
        afm_cfgr_list(L, g, "features", AFM_MAX_FEATURES, &c->n_features, one_feature, c->features,
                      sizeof c->features[0]) ||
        afm_cfgr_list(L, g, "materials", AFM_MAX_MATERIALS, &c->n_materials, one_material,
                      c->materials, sizeof c->materials[0]) ||
        afm_cfgr_group(L, g, "image", false, &im))
        return -1;
    if (!im) return 0;
    if (afm_cfgr_only_keys(L, im, ikeys) || afm_cfgr_member(L, im, "file", true, &s) ||
        afm_cfgr_num(L, im, "pixel_m", true, &c->image_pixel_m, NULL) ||
        afm_cfgr_num(L, im, "height_per_level_m", true, &c->image_height_per_level_m, NULL) ||
        afm_cfgr_num(L, im, "x0_m", false, &c->image_x0_m, NULL) ||
        afm_cfgr_num(L, im, "y0_m", false, &c->image_y0_m, NULL))
        return -1;
    if (config_setting_type(s) != CONFIG_TYPE_STRING)
        return afm_cfgr_fail(L, s, NULL, "expected a file name, got %s", afm_cfgr_type(s));
    /* relative to the config file's folder */
    const char *v = config_setting_get_string(s), *slash = strrchr(L->path, '/');
    int dir = v[0] != '/' && slash ? (int)(slash - L->path) + 1 : 0;
    if ((size_t)dir + strlen(v) >= sizeof c->image_file)
        return afm_cfgr_fail(L, s, NULL,
                             "path too long (at most %zu characters with the config's folder)",
                             sizeof c->image_file - 1);
    snprintf(c->image_file, sizeof c->image_file, "%.*s%s", dir, L->path, v);
    return 0;
}

/* can: optional group (issue 6); enabled defaults to true when the group is present. Ids
 * and ranges are checked in afm_config_check.c. */
static const char *const can_id_keys[AFM_CAN_N_SIGNALS + 1] = {"dither_frequency",
                                                               "dither_amplitude",
                                                               "dither_phase",
                                                               "setpoint",
                                                               "enable",
                                                               "heartbeat",
                                                               NULL};

int afm_config_opt_can(const afm_cfgr *L, const config_setting_t *root, afm_cfg_can *c) {
    static const char *const keys[] = {
        "enabled",         "interface", "fd",    "extended_ids",        "byte_order",
        "encoding",        "ids",       "scale", "heartbeat_timeout_s", "reconnect_min_s",
        "reconnect_max_s", NULL};
    static const char *const skeys[] = {"frequency_hz", "amplitude_m", "phase_rad",
                                        "separation_m", "ramp_m_s",    NULL};
    static const char *const orders[] = {"little", "big", NULL};
    static const char *const encodings[] = {"scaled", "float32", NULL};
    config_setting_t *g, *s;
    if (afm_cfgr_feature(L, root, "can", &g, &c->enabled)) return -1;
    if (!g) return 0;
    int order = c->big_endian ? 1 : 0, enc = (int)c->encoding;
    if (afm_cfgr_only_keys(L, g, keys) || afm_cfgr_bool(L, g, "fd", &c->fd) ||
        afm_cfgr_bool(L, g, "extended_ids", &c->extended_ids) ||
        afm_cfgr_choice(L, g, "byte_order", false, orders, &order) ||
        afm_cfgr_choice(L, g, "encoding", false, encodings, &enc) ||
        afm_cfgr_num(L, g, "heartbeat_timeout_s", false, &c->heartbeat_timeout_s, NULL) ||
        afm_cfgr_num(L, g, "reconnect_min_s", false, &c->reconnect_min_s, NULL) ||
        afm_cfgr_num(L, g, "reconnect_max_s", false, &c->reconnect_max_s, NULL) ||
        afm_cfgr_member(L, g, "interface", false, &s))
        return -1;
    c->big_endian = order == 1;
    c->encoding = (afm_can_encoding)enc;
    if (s) {
        if (config_setting_type(s) != CONFIG_TYPE_STRING)
            return afm_cfgr_fail(L, s, NULL, "expected a string (e.g. \"can0\"), got %s",
                                 afm_cfgr_type(s));
        const char *v = config_setting_get_string(s);
        size_t n = strlen(v);
        if (n < 1 || n >= sizeof c->interface || strpbrk(v, " \t\n/:"))
            return afm_cfgr_fail(L, s, NULL,
                                 "\"%s\" is not an interface name (1 to %zu characters, no "
                                 "spaces, '/' or ':')",
                                 v, sizeof c->interface - 1);
        memcpy(c->interface, v, n + 1);
    }
    if (afm_cfgr_group(L, g, "ids", false, &s)) return -1;
    if (s) {
        if (afm_cfgr_only_keys(L, s, can_id_keys)) return -1;
        for (int i = 0; i < AFM_CAN_N_SIGNALS; i++) {
            config_setting_t *m = config_setting_get_member(s, can_id_keys[i]);
            int v;
            if (!m) continue;
            if (afm_cfgr_as_int(L, m, &v)) return -1;
            if (v < 0) return afm_cfgr_fail(L, m, NULL, "a frame id is >= 0 (got %d)", v);
            c->id[i] = (unsigned)v;
        }
    }
    if (afm_cfgr_group(L, g, "scale", false, &s)) return -1;
    if (s && (afm_cfgr_only_keys(L, s, skeys) ||
              afm_cfgr_num(L, s, "frequency_hz", false, &c->scale_frequency_hz, NULL) ||
              afm_cfgr_num(L, s, "amplitude_m", false, &c->scale_amplitude_m, NULL) ||
              afm_cfgr_num(L, s, "phase_rad", false, &c->scale_phase_rad, NULL) ||
              afm_cfgr_num(L, s, "separation_m", false, &c->scale_separation_m, NULL) ||
              afm_cfgr_num(L, s, "ramp_m_s", false, &c->scale_ramp_m_s, NULL)))
        return -1;
    return 0;
}

/* fm: optional group (issue 32); enabled defaults to true when the group is present. Ranges
 * are checked in afm_config_check.c. */
int afm_config_opt_fm(const afm_cfgr *L, const config_setting_t *root, afm_cfg_fm *c) {
    static const char *const keys[] = {"enabled",
                                       "phase_setpoint_deg",
                                       "pll_bandwidth_hz",
                                       "pll_kp_hz_per_deg",
                                       "pll_ki_hz_per_deg_s",
                                       "max_shift_hz",
                                       "lock_threshold_deg",
                                       "lock_time_s",
                                       "amplitude_setpoint_m",
                                       "amplitude_bandwidth_hz",
                                       "amplitude_kp",
                                       "amplitude_ki_hz",
                                       "drive_max_m",
                                       "update_samples",
                                       "control",
                                       "drive",
                                       NULL};
    static const char *const controls[] = {"none", "internal", NULL};
    static const char *const drives[] = {"pll", "self", NULL};
    int control = (int)c->control, drive = (int)c->drive;
    config_setting_t *g;
    if (afm_cfgr_feature(L, root, "fm", &g, &c->enabled)) return -1;
    if (!g) return 0;
    if (afm_cfgr_only_keys(L, g, keys) ||
        afm_cfgr_num(L, g, "phase_setpoint_deg", false, &c->phase_setpoint_deg, NULL) ||
        afm_cfgr_num(L, g, "pll_bandwidth_hz", false, &c->pll_bandwidth_hz, NULL) ||
        afm_cfgr_num(L, g, "pll_kp_hz_per_deg", false, &c->pll_kp_hz_per_deg, NULL) ||
        afm_cfgr_num(L, g, "pll_ki_hz_per_deg_s", false, &c->pll_ki_hz_per_deg_s, NULL) ||
        afm_cfgr_num(L, g, "max_shift_hz", false, &c->max_shift_hz, NULL) ||
        afm_cfgr_num(L, g, "lock_threshold_deg", false, &c->lock_threshold_deg, NULL) ||
        afm_cfgr_num(L, g, "lock_time_s", false, &c->lock_time_s, NULL) ||
        afm_cfgr_num(L, g, "amplitude_setpoint_m", false, &c->amplitude_setpoint_m, NULL) ||
        afm_cfgr_num(L, g, "amplitude_bandwidth_hz", false, &c->amplitude_bandwidth_hz, NULL) ||
        afm_cfgr_num(L, g, "amplitude_kp", false, &c->amplitude_kp, NULL) ||
        afm_cfgr_num(L, g, "amplitude_ki_hz", false, &c->amplitude_ki_hz, NULL) ||
        afm_cfgr_num(L, g, "drive_max_m", false, &c->drive_max_m, NULL) ||
        afm_cfgr_int(L, g, "update_samples", false, &c->update_samples) ||
        afm_cfgr_choice(L, g, "control", false, controls, &control) ||
        afm_cfgr_choice(L, g, "drive", false, drives, &drive))
        return -1;
    c->control = (afm_fm_control)control;
    c->drive = (afm_fm_drive)drive;
    return 0;
}

/* am: optional group (issue 18); enabled defaults to true when the group is present. Ranges
 * are checked in afm_config_check.c. */
int afm_config_opt_am(const afm_cfgr *L, const config_setting_t *root, afm_cfg_am *c) {
    static const char *const keys[] = {"enabled",        "control", "setpoint_ratio", "kp", "ki_hz",
                                       "z_rate_max_m_s", "z_min_m", "z_max_m",        NULL};
    static const char *const controls[] = {"none", "internal", NULL};
    int control = (int)c->control;
    config_setting_t *g;
    if (afm_cfgr_feature(L, root, "am", &g, &c->enabled)) return -1;
    if (!g) return 0;
    if (afm_cfgr_only_keys(L, g, keys) ||
        afm_cfgr_num(L, g, "setpoint_ratio", false, &c->setpoint_ratio, NULL) ||
        afm_cfgr_num(L, g, "kp", false, &c->kp, NULL) ||
        afm_cfgr_num(L, g, "ki_hz", false, &c->ki_hz, NULL) ||
        afm_cfgr_num(L, g, "z_rate_max_m_s", false, &c->z_rate_max_m_s, NULL) ||
        afm_cfgr_num(L, g, "z_min_m", false, &c->z_min_m, NULL) ||
        afm_cfgr_num(L, g, "z_max_m", false, &c->z_max_m, NULL) ||
        afm_cfgr_choice(L, g, "control", false, controls, &control))
        return -1;
    c->control = (afm_am_control)control;
    return 0;
}
