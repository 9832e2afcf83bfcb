/* SPDX-License-Identifier: MIT */
/* afm_cmd.c -- command validation and the live parameter table (contract in
 * runner/afm_cmd.h; the LCM decoding is in daemon/transport/afm_cmd_lcm.c, the CAN one in
 * daemon/transport/afm_can_codec.c).
 * It lives in the engine library because afm_runner applies parameters with it. */
#include "runner/afm_cmd.h"
#include "config/afm_err.h"
#include "config/afm_limits.h"
#include "runner/afm_scan.h"

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double deg = 3.14159265358979323846 / 180.0;

/* What the running config must have for a name to mean anything. */
enum {
    NEED_NONE,
    NEED_BEAM,
    NEED_LUMPED,
    NEED_VDW,
    NEED_VISCO,
    NEED_STARR,
    NEED_LINEAR,
    NEED_CAP,
    NEED_ES
};
/* How the value maps to the config field. */
enum { CONV_NONE, CONV_DEG, CONV_Q };

typedef struct {
    size_t offset; /* of the double (element 0) in afm_config */
    int need, conv;
} param_ext;

#define OFF(field) offsetof(afm_config, field)
/* Ranges: physically meaningful bounds wide enough for any AFM probe, afm_limits.h's where
 * the config loader checks the same key; the whole config is re-validated after the change
 * (afm_config_validate) as well.
 * X(name, n_index, scalar_ok, min, max, min_open, max_open, effect, unit, field, need, conv) */
#define PARAM_LIST(X)                                                                              \
    X("drive.separation_m", 0, false, 0, AFM_LIM_SEPARATION_MAX_M, false, false,                   \
      AFM_PARAM_SEPARATION, "m", drive.separation_m, NEED_NONE, CONV_NONE)                         \
    X("forces.radius_m", 0, false, 0, 1e-6, true, false, AFM_PARAM_FORCE, "m", forces.radius_m,    \
      NEED_NONE, CONV_NONE)                                                                        \
    X("forces.vdw_contact.hamaker_j", 0, false, 0, 1e-17, false, false, AFM_PARAM_FORCE, "J",      \
      forces.hamaker_j, NEED_VDW, CONV_NONE)                                                       \
    X("forces.vdw_contact.a0_m", 0, false, 0, 1e-8, true, false, AFM_PARAM_FORCE, "m",             \
      forces.a0_m, NEED_VDW, CONV_NONE)                                                            \
    X("forces.vdw_contact.reduced_modulus_pa", 0, false, AFM_LIM_MODULUS_MIN_PA,                   \
      AFM_LIM_MODULUS_MAX_PA, false, false, AFM_PARAM_FORCE, "Pa", forces.reduced_modulus_pa,      \
      NEED_VDW, CONV_NONE)                                                                         \
    X("forces.viscoelastic.eta_pa_s", 0, false, 0, 1e6, false, false, AFM_PARAM_FORCE, "Pa s",     \
      forces.eta_pa_s, NEED_VISCO, CONV_NONE)                                                      \
    X("forces.squeeze.p1_n_s_m2", 0, false, -1, 1, false, false, AFM_PARAM_FORCE, "N s/m^2",       \
      forces.p1_n_s_m2, NEED_LINEAR, CONV_NONE)                                                    \
    X("forces.squeeze.p2_n_s_m", 0, false, -1e-3, 1e-3, false, false, AFM_PARAM_FORCE, "N s/m",    \
      forces.p2_n_s_m, NEED_LINEAR, CONV_NONE)                                                     \
    X("forces.squeeze.eta0_pa_s", 0, false, 0, 1, true, false, AFM_PARAM_FORCE, "Pa s",            \
      forces.eta0_pa_s, NEED_STARR, CONV_NONE)                                                     \
    X("forces.squeeze.temperature_k", 0, false, 0, 1e4, true, false, AFM_PARAM_FORCE, "K",         \
      forces.temperature_k, NEED_STARR, CONV_NONE)                                                 \
    X("forces.squeeze.pressure_pa", 0, false, 0, 1e8, true, false, AFM_PARAM_FORCE, "Pa",          \
      forces.pressure_pa, NEED_STARR, CONV_NONE)                                                   \
    X("forces.squeeze.kappa", 0, false, 0, 1, false, false, AFM_PARAM_FORCE, "", forces.kappa,     \
      NEED_STARR, CONV_NONE)                                                                       \
    X("forces.squeeze.tip_length_m", 0, false, 0, 1e-3, true, false, AFM_PARAM_FORCE, "m",         \
      forces.tip_length_m, NEED_STARR, CONV_NONE)                                                  \
    X("forces.capillary.surface_energy_j_m2", 0, false, 0, 1, false, false, AFM_PARAM_FORCE,       \
      "J/m^2", forces.surface_energy_j_m2, NEED_CAP, CONV_NONE)                                    \
    X("forces.capillary.contact_angle_deg", 0, false, 0, 180, false, false, AFM_PARAM_FORCE,       \
      "deg", forces.contact_angle_rad, NEED_CAP, CONV_DEG)                                         \
    X("forces.capillary.meniscus_d_m", 0, false, 0, 1e-6, true, false, AFM_PARAM_FORCE, "m",       \
      forces.meniscus_d_m, NEED_CAP, CONV_NONE)                                                    \
    X("forces.electrostatic.voltage_v", 0, false, -1e3, 1e3, false, false, AFM_PARAM_FORCE, "V",   \
      forces.voltage_v, NEED_ES, CONV_NONE)                                                        \
    X("forces.electrostatic.cone_half_angle_deg", 0, false, 0, 90, true, true, AFM_PARAM_FORCE,    \
      "deg", forces.cone_half_angle_rad, NEED_ES, CONV_DEG)                                        \
    X("forces.electrostatic.cone_length_m", 0, false, 0, 1e-3, true, false, AFM_PARAM_FORCE, "m",  \
      forces.cone_length_m, NEED_ES, CONV_NONE)                                                    \
    X("model.damping_ratio", AFM_MAX_MODES, false, 0, 1, true, true, AFM_PARAM_DAMPING, "",        \
      model.damping_ratio, NEED_NONE, CONV_NONE)                                                   \
    X("model.quality_factor", AFM_MAX_MODES, false, 0.5, 1e9, true, false, AFM_PARAM_DAMPING, "",  \
      model.damping_ratio, NEED_NONE, CONV_Q)                                                      \
    X("model.beam.youngs_modulus_pa", 0, false, AFM_LIM_YOUNGS_MIN_PA, AFM_LIM_YOUNGS_MAX_PA,      \
      false, false, AFM_PARAM_GEOMETRY, "Pa", model.beam.youngs_modulus_pa, NEED_BEAM, CONV_NONE)  \
    X("model.beam.density_kg_m3", 0, false, AFM_LIM_DENSITY_MIN_KG_M3, AFM_LIM_DENSITY_MAX_KG_M3,  \
      false, false, AFM_PARAM_GEOMETRY, "kg/m^3", model.beam.density_kg_m3, NEED_BEAM, CONV_NONE)  \
    X("model.beam.length_m", 0, false, AFM_LIM_LENGTH_MIN_M, AFM_LIM_LENGTH_MAX_M, false, false,   \
      AFM_PARAM_GEOMETRY, "m", model.beam.length_m, NEED_BEAM, CONV_NONE)                          \
    X("model.beam.width_m", 2, true, AFM_LIM_SECTION_MIN_M, AFM_LIM_SECTION_MAX_M, false, false,   \
      AFM_PARAM_GEOMETRY, "m", model.beam.width_m, NEED_BEAM, CONV_NONE)                           \
    X("model.beam.height_m", 2, true, AFM_LIM_SECTION_MIN_M, AFM_LIM_SECTION_MAX_M, false, false,  \
      AFM_PARAM_GEOMETRY, "m", model.beam.height_m, NEED_BEAM, CONV_NONE)                          \
    X("model.beam.tip_mass_kg", 0, false, 0, AFM_LIM_TIP_MASS_MAX_KG, false, false,                \
      AFM_PARAM_GEOMETRY, "kg", model.beam.tip_mass_kg, NEED_BEAM, CONV_NONE)                      \
    X("model.lumped.stiffness_n_m", 0, false, AFM_LIM_STIFFNESS_MIN_N_M,                           \
      AFM_LIM_STIFFNESS_MAX_N_M, false, false, AFM_PARAM_GEOMETRY, "N/m",                          \
      model.lumped.stiffness_n_m, NEED_LUMPED, CONV_NONE)                                          \
    X("model.lumped.resonance_hz", 0, false, AFM_LIM_RESONANCE_MIN_HZ, AFM_LIM_RESONANCE_MAX_HZ,   \
      false, false, AFM_PARAM_GEOMETRY, "Hz", model.lumped.resonance_hz, NEED_LUMPED, CONV_NONE)

#define DEF(nm, nidx, sc, lo, hi, lo_open, hi_open, eff, unit, fld, need, conv)                    \
    {nm, nidx, sc, lo, hi, lo_open, hi_open, eff, unit},
#define EXT(nm, nidx, sc, lo, hi, lo_open, hi_open, eff, unit, fld, need, conv)                    \
    {OFF(fld), need, conv},
static const afm_param_def defs[] = {PARAM_LIST(DEF)};
static const param_ext ext[] = {PARAM_LIST(EXT)};
#define N_ROWS ((int)(sizeof defs / sizeof defs[0]))

const afm_param_def *afm_param_table(int *n) {
    if (n) *n = N_ROWS;
    return defs;
}

const char *afm_cmd_kind_name(afm_cmd_kind k) {
    switch (k) {
    case AFM_CMD_DITHER:
        return "dither";
    case AFM_CMD_SETPOINT:
        return "setpoint";
    case AFM_CMD_PARAM:
        return "param";
    case AFM_CMD_CONTROL:
        return "control";
    case AFM_CMD_TICK:
        return "tick";
    case AFM_CMD_RELOAD:
        return "reload";
    case AFM_CMD_SCAN:
        return "scan";
    }
    return "?";
}

void afm_param_name(int entry, int index, char *buf, size_t len) {
    if (entry < 0 || entry >= N_ROWS) {
        snprintf(buf, len, "?");
    } else if (index >= 0) {
        snprintf(buf, len, "%s[%d]", defs[entry].name, index);
    } else {
        snprintf(buf, len, "%s", defs[entry].name);
    }
}

int afm_param_lookup(const char *name, int *entry, int *index, char *err, size_t errlen) {
    if (!name || !*name) {
        afm_err_set(err, errlen, "empty parameter name");
        return -1;
    }
    size_t len = strnlen(name, AFM_CMD_NAME_LEN);
    if (len >= AFM_CMD_NAME_LEN) {
        afm_err_set(err, errlen, "parameter name too long (max %d characters)",
                    AFM_CMD_NAME_LEN - 1);
        return -1;
    }
    char shown[4 * AFM_CMD_NAME_LEN]; /* the name as it may be echoed: printable */
    afm_err_printable(shown, sizeof shown, name, len);
    const char *br = strchr(name, '[');
    size_t base = br ? (size_t)(br - name) : len;
    int idx = -1;
    if (br) {
        char *end;
        if (br[1] < '0' || br[1] > '9') goto bad_index;
        long v = strtol(br + 1, &end, 10);
        if (*end != ']' || end[1] != '\0' || v > 1000000) goto bad_index;
        idx = (int)v;
    }
    for (int i = 0; i < N_ROWS; i++) {
        const afm_param_def *d = &defs[i];
        if (strlen(d->name) != base || strncmp(d->name, name, base) != 0) continue;
        if (idx >= 0 && d->n_index == 0) {
            afm_err_set(err, errlen, "parameter '%s' takes no index", d->name);
            return -1;
        }
        if (idx >= d->n_index && d->n_index > 0) {
            afm_err_set(err, errlen, "parameter '%s': index %d out of range 0..%d", d->name, idx,
                        d->n_index - 1);
            return -1;
        }
        if (idx < 0 && d->n_index > 0 && !d->scalar_ok) {
            afm_err_set(err, errlen, "parameter '%s' needs an index [0..%d]", d->name,
                        d->n_index - 1);
            return -1;
        }
        *entry = i;
        *index = idx;
        return 0;
    }
    {
        char list[300] = ""; /* whole names that fit, then how many more */
        size_t n = 0;
        int i = 0;
        for (; i < N_ROWS; i++) {
            size_t w = strlen(defs[i].name) + (i ? 2 : 0);
            if (n + w + 40 >= sizeof list) break;
            snprintf(list + n, sizeof list - n, "%s%s", i ? ", " : "", defs[i].name);
            n += w;
        }
        if (i < N_ROWS)
            snprintf(list + n, sizeof list - n, " and %d more (afmtwin send --help)", N_ROWS - i);
        char b[4 * AFM_CMD_NAME_LEN];
        afm_err_printable(b, sizeof b, name, base);
        afm_err_set(err, errlen, "unknown parameter '%s' (known: %s)", b, list);
    }
    return -1;
bad_index:
    afm_err_set(err, errlen, "parameter '%s': bad index (want name[N])", shown);
    return -1;
}

static int check_range(const afm_param_def *d, const char *name, double v, char *err,
                       size_t errlen) {
    if (!isfinite(v)) {
        afm_err_set(err, errlen, "param %s: value is not a finite number", name);
        return -1;
    }
    bool lo_ok = d->min_open ? v > d->min : v >= d->min;
    bool hi_ok = d->max_open ? v < d->max : v <= d->max;
    if (!lo_ok || !hi_ok) {
        afm_err_set(err, errlen, "param %s: %g %s out of range %c%g, %g%c", name, v, d->unit,
                    d->min_open ? '(' : '[', d->min, d->max, d->max_open ? ')' : ']');
        return -1;
    }
    return 0;
}

/* Highest mode frequency of the model (Hz). */
static double top_mode_hz(const afm_modal *m) {
    double w = 0;
    for (int i = 0; i < m->n; i++)
        if (m->omega_rad_s[i] > w) w = m->omega_rad_s[i];
    return w / (2 * 3.14159265358979323846);
}

int afm_cmd_check_drive(const afm_modal *m, int n, const double *f_hz, const double *a_m,
                        double *free_m, char *err, size_t errlen) {
    double f_top = AFM_LIM_MODEL_RANGE * top_mode_hz(m), x = 0;
    for (int j = 0; j < n; j++) {
        if (f_hz[j] > f_top) {
            afm_err_set(err, errlen,
                        "dither: tone %d frequency_hz %g is above the model's range (%g x its "
                        "highest mode, %g Hz)",
                        j, f_hz[j], AFM_LIM_MODEL_RANGE, f_top);
            return -1;
        }
        double re, im;
        afm_model_tip_response(m, 2 * 3.14159265358979323846 * f_hz[j], &re, &im);
        x += a_m[j] * hypot(re, im);
    }
    if (free_m) *free_m = x;
    if (!(x <= AFM_LIM_FREE_AMPLITUDE_MAX_M)) {
        afm_err_set(err, errlen,
                    "dither: the drive would swing the free tip to %.3g m (sum over the tones of "
                    "amplitude x the model's gain), more than the %g m a cantilever survives "
                    "(tapping is 1 nm .. 1 um)",
                    x, AFM_LIM_FREE_AMPLITUDE_MAX_M);
        return -1;
    }
    return 0;
}

int afm_cmd_check_cfg_drive(const afm_modal *m, const afm_cfg_drive *d, char *err, size_t errlen) {
    double f[AFM_MAX_TONES], a[AFM_MAX_TONES], x;
    int n = d->n_tones < AFM_MAX_TONES ? d->n_tones : AFM_MAX_TONES;
    for (int j = 0; j < n; j++) {
        f[j] = d->tones[j].frequency_hz;
        a[j] = d->tones[j].amplitude_m;
    }
    char why[AFM_ERR_LEN];
    if (afm_cmd_check_drive(m, n, f, a, &x, why, sizeof why) == 0) return 0;
    afm_err_set(err, errlen, "drive.tones: %s", why + (strncmp(why, "dither: ", 8) ? 0 : 8));
    return -1;
}

static int check_dither(const afm_cmd_dither *d, const afm_cmd_limits *lim, char *err,
                        size_t errlen) {
    if (d->n_tones < 1 || d->n_tones > AFM_MAX_TONES) {
        afm_err_set(err, errlen, "dither: n_tones %d not in 1..%d", d->n_tones, AFM_MAX_TONES);
        return -1;
    }
    double nyq = lim && lim->sample_rate_hz > 0 ? 0.5 * lim->sample_rate_hz : HUGE_VAL;
    double sum = 0;
    for (int j = 0; j < d->n_tones; j++) {
        double f = d->frequency_hz[j], a = d->amplitude_m[j], p = d->phase_rad[j];
        if (!isfinite(f) || !isfinite(a) || !isfinite(p)) {
            afm_err_set(err, errlen,
                        "dither: tone %d has a non-finite value (f %g Hz, A %g m, "
                        "phase %g rad)",
                        j, f, a, p);
            return -1;
        }
        if (!(a >= 0 && a <= AFM_LIM_TONE_AMPLITUDE_MAX_M)) {
            afm_err_set(err, errlen, "dither: tone %d amplitude_m %g not in 0..%g m", j, a,
                        AFM_LIM_TONE_AMPLITUDE_MAX_M);
            return -1;
        }
        sum += a;
        if (!(f >= AFM_LIM_FREQUENCY_MIN_HZ && f < nyq)) {
            if (isfinite(nyq))
                afm_err_set(err, errlen,
                            "dither: tone %d frequency_hz %g must be >= %g and < %g "
                            "(half the sample rate)",
                            j, f, AFM_LIM_FREQUENCY_MIN_HZ, nyq);
            else
                afm_err_set(err, errlen, "dither: tone %d frequency_hz %g must be >= %g", j, f,
                            AFM_LIM_FREQUENCY_MIN_HZ);
            return -1;
        }
    }
    if (!(sum <= AFM_LIM_DRIVE_AMPLITUDE_MAX_M)) {
        afm_err_set(err, errlen,
                    "dither: the tones' amplitudes add up to %g m, more than the %g m a dither "
                    "piezo strokes",
                    sum, AFM_LIM_DRIVE_AMPLITUDE_MAX_M);
        return -1;
    }
    if (lim && lim->model)
        return afm_cmd_check_drive(lim->model, d->n_tones, d->frequency_hz, d->amplitude_m, NULL,
                                   err, errlen);
    return 0;
}

/* A scan command's positions and afmtwin scan's origin share one range:
 * AFM_CMD_SCAN_POS_MAX_M == AFM_SCAN_ORIGIN_MAX_M (floating constants: clang refuses them in
 * a _Static_assert, so keep the two equal by hand). */

const char *afm_scan_mode_name(int mode) {
    switch (mode) {
    case AFM_SCAN_HOLD:
        return "hold";
    case AFM_SCAN_MOVE:
        return "move";
    case AFM_SCAN_VELOCITY:
        return "velocity";
    case AFM_SCAN_RASTER:
        return "raster";
    }
    return "?";
}

/* A scan command (issue 18): the ranges of afm_cmd.h. */
static int check_scan(const afm_cmd_lateral *s, char *err, size_t errlen) {
    const double v[] = {s->x_m,    s->y_m,      s->speed_m_s, s->vx_m_s,
                        s->vy_m_s, s->size_x_m, s->size_y_m,  s->line_rate_hz};
    static const char *const nm[] = {"x_m",    "y_m",      "speed_m_s", "vx_m_s",
                                     "vy_m_s", "size_x_m", "size_y_m",  "line_rate_hz"};
    for (int i = 0; i < (int)(sizeof v / sizeof v[0]); i++)
        if (!isfinite(v[i])) {
            afm_err_set(err, errlen, "scan: %s is not finite (%g)", nm[i], v[i]);
            return -1;
        }
    const double P = AFM_CMD_SCAN_POS_MAX_M, V = AFM_CMD_SCAN_SPEED_MAX_M_S;
    switch (s->mode) {
    case AFM_SCAN_HOLD:
        return 0;
    case AFM_SCAN_MOVE:
        if (!(fabs(s->x_m) <= P && fabs(s->y_m) <= P)) {
            afm_err_set(err, errlen, "scan: move to (%g, %g) m: |x|, |y| must be <= %g m", s->x_m,
                        s->y_m, P);
            return -1;
        }
        if (!(s->speed_m_s >= 0 && s->speed_m_s <= V)) {
            afm_err_set(err, errlen, "scan: move speed_m_s %g not in 0..%g m/s", s->speed_m_s, V);
            return -1;
        }
        return 0;
    case AFM_SCAN_VELOCITY:
        if (!(hypot(s->vx_m_s, s->vy_m_s) <= V)) {
            afm_err_set(err, errlen, "scan: velocity (%g, %g) m/s: its size must be <= %g m/s",
                        s->vx_m_s, s->vy_m_s, V);
            return -1;
        }
        return 0;
    case AFM_SCAN_RASTER:
        if (!(s->size_x_m > 0 && s->size_x_m <= AFM_SCAN_SIZE_MAX_M) ||
            !(s->size_y_m >= 0 && s->size_y_m <= AFM_SCAN_SIZE_MAX_M)) {
            afm_err_set(err, errlen,
                        "scan: raster size %g x %g m: x must be in (0, %g], y in [0, %g] m",
                        s->size_x_m, s->size_y_m, AFM_SCAN_SIZE_MAX_M, AFM_SCAN_SIZE_MAX_M);
            return -1;
        }
        if (!(s->lines >= 1 && s->lines <= AFM_SCAN_LINES_MAX) ||
            !(s->pixels >= 2 && s->pixels <= AFM_SCAN_PIXELS_MAX)) {
            afm_err_set(err, errlen,
                        "scan: raster of %d lines of %d pixels: lines 1..%d, pixels 2..%d",
                        s->lines, s->pixels, AFM_SCAN_LINES_MAX, AFM_SCAN_PIXELS_MAX);
            return -1;
        }
        if (!(s->line_rate_hz > 0 && s->line_rate_hz <= AFM_SCAN_LINE_RATE_MAX_HZ)) {
            afm_err_set(err, errlen, "scan: line_rate_hz %g not in (0, %g]", s->line_rate_hz,
                        AFM_SCAN_LINE_RATE_MAX_HZ);
            return -1;
        }
        if (!(fabs(s->x_m) <= P && fabs(s->y_m) <= P && fabs(s->x_m + s->size_x_m) <= P &&
              fabs(s->y_m + s->size_y_m) <= P)) {
            afm_err_set(err, errlen,
                        "scan: raster from (%g, %g) m of %g x %g m leaves |x|, |y| <= %g m", s->x_m,
                        s->y_m, s->size_x_m, s->size_y_m, P);
            return -1;
        }
        return 0;
    }
    afm_err_set(err, errlen, "scan: unknown mode %d (0 hold, 1 move, 2 velocity, 3 raster)",
                s->mode);
    return -1;
}

int afm_cmd_validate(const afm_cmd *c, const afm_cmd_limits *lim, char *err, size_t errlen) {
    if (!c) {
        afm_err_set(err, errlen, "no command");
        return -1;
    }
    switch (c->kind) {
    case AFM_CMD_DITHER:
        return check_dither(&c->u.dither, lim, err, errlen);
    case AFM_CMD_SETPOINT: {
        const afm_cmd_setpoint *s = &c->u.setpoint;
        if (!isfinite(s->separation_m) || !isfinite(s->ramp_rate_m_s)) {
            afm_err_set(err, errlen,
                        "setpoint: non-finite value (separation_m %g, ramp_rate_m_s %g)",
                        s->separation_m, s->ramp_rate_m_s);
            return -1;
        }
        if (!(s->separation_m >= 0 && s->separation_m <= AFM_LIM_SEPARATION_MAX_M)) {
            afm_err_set(err, errlen, "setpoint: separation_m %g not in 0..%g m", s->separation_m,
                        AFM_LIM_SEPARATION_MAX_M);
            return -1;
        }
        if (!(s->ramp_rate_m_s >= 0 && s->ramp_rate_m_s <= AFM_LIM_RAMP_MAX_M_S)) {
            afm_err_set(err, errlen, "setpoint: ramp_rate_m_s %g not in 0..%g m/s",
                        s->ramp_rate_m_s, AFM_LIM_RAMP_MAX_M_S);
            return -1;
        }
        return 0;
    }
    case AFM_CMD_PARAM: {
        const afm_cmd_param *p = &c->u.param;
        if (p->n < 1 || p->n > AFM_CMD_MAX_PARAMS) {
            afm_err_set(err, errlen, "param: n %d not in 1..%d", p->n, AFM_CMD_MAX_PARAMS);
            return -1;
        }
        for (int i = 0; i < p->n; i++) {
            char name[AFM_CMD_NAME_LEN + 16];
            if (p->entry[i] < 0 || p->entry[i] >= N_ROWS) {
                afm_err_set(err, errlen, "param: entry %d: unknown parameter", i);
                return -1;
            }
            const afm_param_def *d = &defs[p->entry[i]];
            afm_param_name(p->entry[i], p->index[i], name, sizeof name);
            if ((p->index[i] < 0 && d->n_index > 0 && !d->scalar_ok) ||
                (p->index[i] >= 0 && p->index[i] >= d->n_index)) {
                afm_err_set(err, errlen, "param %s: bad index", name);
                return -1;
            }
            if (check_range(d, name, p->value[i], err, errlen)) return -1;
            for (int k = 0; k < i; k++)
                if (p->entry[k] == p->entry[i] && p->index[k] == p->index[i]) {
                    afm_err_set(err, errlen, "param %s: given twice", name);
                    return -1;
                }
        }
        return 0;
    }
    case AFM_CMD_CONTROL: {
        const afm_cmd_control *k = &c->u.control;
        if (k->action < AFM_CTL_RUN || k->action > AFM_CTL_STEP) {
            afm_err_set(err, errlen, "control: unknown action %d (1 run, 2 pause, 3 reset, 4 step)",
                        k->action);
            return -1;
        }
        if (k->action == AFM_CTL_STEP && (k->n_samples < 1 || k->n_samples > AFM_CMD_MAX_STEP)) {
            afm_err_set(err, errlen, "control: step n_samples %lld not in 1..%lld", k->n_samples,
                        AFM_CMD_MAX_STEP);
            return -1;
        }
        return 0;
    }
    case AFM_CMD_TICK:
        if (c->u.tick.n_samples < 1 || c->u.tick.n_samples > AFM_CMD_MAX_STEP) {
            afm_err_set(err, errlen, "tick: n_samples %lld not in 1..%lld", c->u.tick.n_samples,
                        AFM_CMD_MAX_STEP);
            return -1;
        }
        return 0;
    case AFM_CMD_RELOAD:
        return 0;
    case AFM_CMD_SCAN:
        return check_scan(&c->u.scan, err, errlen);
    }
    afm_err_set(err, errlen, "unknown command kind %d", (int)c->kind);
    return -1;
}

/* ---- applying parameters to a config --------------------------------------------------- */

static double *field(afm_config *cfg, int entry, int index) {
    char *base = (char *)cfg + ext[entry].offset;
    return (double *)base + (index > 0 ? index : 0);
}

static int n_modes(const afm_config *cfg) {
    return cfg->model.kind == AFM_MODEL_LUMPED ? 1 : cfg->model.beam.n_kept + 2;
}

static const char *need_text(int need, const afm_config *cfg) {
    const afm_cfg_forces *f = &cfg->forces;
    switch (need) {
    case NEED_BEAM:
        return cfg->model.kind == AFM_MODEL_BEAM ? NULL : "the model is lumped, not a beam";
    case NEED_LUMPED:
        return cfg->model.kind == AFM_MODEL_LUMPED ? NULL : "the model is a beam, not lumped";
    case NEED_VDW:
        return f->vdw_contact ? NULL : "vdw_contact forces are off in this config";
    case NEED_VISCO:
        return f->viscoelastic ? NULL : "viscoelastic forces are off in this config";
    case NEED_STARR:
        return f->squeeze == AFM_SQUEEZE_STARR ? NULL : "squeeze model is not \"starr\"";
    case NEED_LINEAR:
        return f->squeeze == AFM_SQUEEZE_LINEAR ? NULL : "squeeze model is not \"linear\"";
    case NEED_CAP:
        return f->capillary ? NULL : "capillary forces are off in this config";
    case NEED_ES:
        return f->electrostatic ? NULL : "electrostatic forces are off in this config";
    }
    return NULL;
}

int afm_param_apply(afm_config *cfg, const afm_cmd_param *p, afm_param_effect *effect, char *err,
                    size_t errlen) {
    afm_cmd c = {.kind = AFM_CMD_PARAM};
    c.u.param = *p;
    if (afm_cmd_validate(&c, NULL, err, errlen)) return -1;
    afm_config t = *cfg;
    afm_param_effect strongest = AFM_PARAM_SEPARATION;
    for (int i = 0; i < p->n; i++) {
        const param_ext *r = &ext[p->entry[i]];
        const afm_param_def *def = &defs[p->entry[i]];
        char name[AFM_CMD_NAME_LEN + 16];
        afm_param_name(p->entry[i], p->index[i], name, sizeof name);
        const char *why = need_text(r->need, &t);
        if (why) {
            afm_err_set(err, errlen, "param %s: %s", name, why);
            return -1;
        }
        double v = p->value[i];
        if (r->conv == CONV_DEG) v *= deg;
        if (r->conv == CONV_Q) v = 1.0 / (2.0 * v);
        if (def->effect == AFM_PARAM_DAMPING) {
            int k = p->index[i], nm = n_modes(&t);
            if (k >= nm) {
                afm_err_set(err, errlen, "param %s: the model has %d modes (index 0..%d)", name, nm,
                            nm - 1);
                return -1;
            }
            /* Modes past the list take its last value: materialise them up to k. */
            for (int j = t.model.n_damping; j <= k && j < AFM_MAX_MODES; j++)
                t.model.damping_ratio[j] = t.model.damping_ratio[t.model.n_damping - 1];
            if (k >= t.model.n_damping) t.model.n_damping = k + 1;
        }
        if (def->n_index > 0 && p->index[i] < 0) {
            for (int j = 0; j < def->n_index; j++)
                *field(&t, p->entry[i], j) = v;
        } else {
            *field(&t, p->entry[i], p->index[i]) = v;
        }
        if (def->effect > strongest) strongest = def->effect;
    }
    char why[AFM_ERR_LEN];
    if (afm_config_validate(&t, why, sizeof why)) {
        afm_err_set(err, errlen, "param: the config would be invalid: %s", why);
        return -1;
    }
    *cfg = t;
    if (effect) *effect = strongest;
    return 0;
}

double afm_param_get(const afm_config *cfg, int entry, int index) {
    if (entry < 0 || entry >= N_ROWS) return NAN;
    const param_ext *r = &ext[entry];
    const afm_param_def *def = &defs[entry];
    if (def->n_index > 0 && (index >= def->n_index)) return NAN;
    if (def->n_index == 0 && index >= 0) return NAN;
    double v = *field((afm_config *)cfg, entry, index);
    if (def->effect == AFM_PARAM_DAMPING && index >= cfg->model.n_damping)
        v = cfg->model.damping_ratio[cfg->model.n_damping - 1];
    if (r->conv == CONV_DEG) v /= deg;
    if (r->conv == CONV_Q) v = 1.0 / (2.0 * v);
    return v;
}
