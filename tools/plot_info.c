/* SPDX-License-Identifier: MIT */
/* plot_info.c -- the config and drive line under an `afmtwin plot` title (plot_info.h). */
#include "plot_info.h"

#include "config/afm_config.h"
#include "config/afm_err.h"
#include "estimators/afm_orbit.h"
#include "runner/afm_a0.h"
#include "runner/afm_twin.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#define PI_TWO_PI 6.283185307179586
#define PI_LAG_TOL_DEG 0.5 /* a free lag further from the model's: the run drove elsewhere */

void plot_info_init(plot_info *pi) {
    memset(pi, 0, sizeof *pi);
    pi->cfg_fe_hz = pi->cfg_ae_m = pi->cfg_z_m = NAN;
    pi->opt_fe_hz = pi->opt_ae_m = pi->opt_z_m = NAN;
    pi->a0_m = pi->a0_lag_deg = NAN;
    pi->fe_lo_hz = pi->fe_hi_hz = pi->z_lo_m = pi->z_hi_m = NAN;
    pi->p_lo = pi->p_hi = NAN;
    pi->temperature_k = pi->seconds = NAN;
}

int plot_info_config(plot_info *pi, const char *path) {
    static afm_config cfg;
    char err[AFM_ERR_LEN];
    if (afm_config_load(path, &cfg, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin plot: %s\n", err);
        return -1;
    }
    if (afm_model_build(&cfg.model, &pi->model, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin plot: %s: %s\n", path, err);
        return -1;
    }
    pi->have_forces = afm_twin_forces(&cfg, &pi->model, NULL, &pi->forces, err, sizeof err) == 0;
    const char *b = strrchr(path, '/');
    snprintf(pi->config, sizeof pi->config, "%s", b ? b + 1 : path);
    pi->have_model = pi->model.n > 0;
    pi->cfg_z_m = cfg.drive.separation_m;
    if (cfg.drive.n_tones > 0) {
        pi->cfg_fe_hz = cfg.drive.tones[0].frequency_hz;
        pi->cfg_ae_m = cfg.drive.tones[0].amplitude_m;
    }
    return 0;
}

static void widen(double *lo, double *hi, double v) {
    if (!isfinite(v)) return;
    if (!(*lo <= v)) *lo = v; /* NAN too */
    if (!(*hi >= v)) *hi = v;
}

void plot_info_fe(plot_info *pi, double fe_hz) {
    widen(&pi->fe_lo_hz, &pi->fe_hi_hz, fe_hz);
}

void plot_info_z(plot_info *pi, double z_m) {
    widen(&pi->z_lo_m, &pi->z_hi_m, z_m);
}

void plot_info_param(plot_info *pi, const char *name, double v) {
    if (strcmp(pi->param, name)) {
        snprintf(pi->param, sizeof pi->param, "%s", name);
        pi->p_lo = pi->p_hi = NAN;
    }
    widen(&pi->p_lo, &pi->p_hi, v);
}

int plot_info_free(const plot_info *pi, double f_hz, double *gain, double *lag_deg) {
    if (!pi->have_model || !isfinite(f_hz)) return -1;
    double re, im;
    afm_a0_linear_response(&pi->model, pi->have_forces ? &pi->forces : NULL, PI_TWO_PI * f_hz, &re,
                           &im);
    *gain = hypot(re, im);
    *lag_deg = afm_orbit_lag_deg(atan2(im, re) * (360.0 / PI_TWO_PI) - 90.0);
    return 0;
}

typedef struct {
    char *s;
    size_t n, len;
    const char *sep; /* before the next item */
    const char *pre; /* before the next item, once */
} line_buf;

static void add(line_buf *b, const char *fmt, ...) {
    if (b->len + 1 >= b->n) return;
    int w = snprintf(b->s + b->len, b->n - b->len, "%s%s", b->sep, b->pre);
    if (w > 0) b->len += (size_t)w;
    b->sep = ", ";
    b->pre = "";
    if (b->len + 1 >= b->n) {
        b->len = b->n - 1;
        return;
    }
    va_list ap;
    va_start(ap, fmt);
    w = vsnprintf(b->s + b->len, b->n - b->len, fmt, ap);
    va_end(ap);
    if (w > 0) b->len += (size_t)w;
    if (b->len >= b->n) b->len = b->n - 1;
}

/* "300 kHz", "1.2 MHz" */
static void fmt_hz(char *o, size_t n, double f) {
    if (fabs(f) >= 1e6)
        snprintf(o, n, "%.6g MHz", f * 1e-6);
    else if (fabs(f) >= 1e3)
        snprintf(o, n, "%.6g kHz", f * 1e-3);
    else
        snprintf(o, n, "%.6g Hz", f);
}

/* "20 nm", "66.67 pm" */
static void fmt_m(char *o, size_t n, double m) {
    if (fabs(m) >= 1e-6)
        snprintf(o, n, "%.4g um", m * 1e6);
    else if (fabs(m) >= 1e-9 || m == 0)
        snprintf(o, n, "%.4g nm", m * 1e9);
    else
        snprintf(o, n, "%.4g pm", m * 1e12);
}

/* "NAME lo-hi UNIT" or "NAME v UNIT" */
static void add_range(line_buf *b, const char *name, double lo, double hi,
                      void (*fmt)(char *, size_t, double)) {
    char a[32], c[32];
    fmt(c, sizeof c, hi);
    if (lo == hi) {
        add(b, "%s %s", name, c);
        return;
    }
    fmt(a, sizeof a, lo);
    const char *ua = strchr(a, ' '), *uc = strchr(c, ' ');
    if (ua && uc && !strcmp(ua, uc)) /* one unit: "295-305 kHz" */
        add(b, "%s %.*s-%s", name, (int)(ua - a), a, c);
    else
        add(b, "%s %s - %s", name, a, c);
}

void plot_info_line(const plot_info *pi, char *out, size_t n) {
    line_buf b = {out, n, 0, "", ""};
    if (n == 0) return;
    out[0] = 0;
    if (pi->config[0]) {
        if (pi->have_model) {
            char f0[32];
            fmt_hz(f0, sizeof f0, pi->model.omega_rad_s[0] / PI_TWO_PI);
            add(&b, "%s: f0 %s", pi->config, f0);
            if (pi->model.xi[0] > 0) add(&b, "Q %.4g", 0.5 / pi->model.xi[0]);
            if (pi->model.static_stiffness_n_m > 0)
                add(&b, "k %.4g N/m", pi->model.static_stiffness_n_m);
        } else {
            add(&b, "%s", pi->config);
        }
        b.sep = "; ";
    }
    if (isfinite(pi->temperature_k)) add(&b, "%.4g K", pi->temperature_k);
    if (isfinite(pi->seconds)) add(&b, "%.4g s", pi->seconds);
    if (pi->no_drive) return;
    b.pre = "drive ";
    const bool p_fe = !strcmp(pi->param, "fe"), p_ae = !strcmp(pi->param, "ae"),
               p_z = !strcmp(pi->param, "z");
    const bool fe_one = isfinite(pi->fe_lo_hz) && pi->fe_lo_hz == pi->fe_hi_hz;
    /* fe: the records', the run's, or the config's where the records agree with it */
    double fe = NAN, gain = NAN, lag = NAN;
    if (p_fe && isfinite(pi->p_lo)) {
        add_range(&b, "fe", pi->p_lo, pi->p_hi, fmt_hz);
    } else if (isfinite(pi->fe_lo_hz)) {
        add_range(&b, "fe", pi->fe_lo_hz, pi->fe_hi_hz, fmt_hz);
        if (fe_one) fe = pi->fe_lo_hz;
    } else if (isfinite(pi->opt_fe_hz)) {
        fe = pi->opt_fe_hz;
    } else if (isfinite(pi->cfg_fe_hz)) {
        fe = pi->cfg_fe_hz;
        if (isfinite(pi->a0_lag_deg) && plot_info_free(pi, fe, &gain, &lag) == 0 &&
            fabs(lag - pi->a0_lag_deg) > PI_LAG_TOL_DEG)
            fe = NAN; /* the run drove at another fe */
    }
    if (isfinite(fe) && !fe_one) {
        char s[32];
        fmt_hz(s, sizeof s, fe);
        add(&b, "fe %s", s);
    }
    if (!isfinite(fe) || plot_info_free(pi, fe, &gain, &lag) != 0) gain = NAN;
    /* Ae: the parameter's range, the run's, from A0, or the config's */
    double ae = NAN;
    if (p_ae && isfinite(pi->p_lo)) {
        add_range(&b, "Ae", pi->p_lo, pi->p_hi, fmt_m);
    } else {
        if (isfinite(pi->opt_ae_m))
            ae = pi->opt_ae_m;
        else if (isfinite(pi->a0_m) && isfinite(gain) && gain > 0)
            ae = fabs(pi->cfg_ae_m * gain / pi->a0_m - 1) < 0.01 ? pi->cfg_ae_m /* measured A0 */
                                                                 : pi->a0_m / gain;
        else if (!isfinite(pi->a0_m) && (isfinite(fe) || isfinite(pi->fe_lo_hz) || p_fe))
            ae = pi->cfg_ae_m;
        if (isfinite(ae)) {
            char s[32];
            fmt_m(s, sizeof s, ae);
            add(&b, "Ae %s", s);
        }
    }
    /* A0: the records', else the model's free amplitude at fe */
    double a0 = pi->a0_m;
    if (!isfinite(a0) && isfinite(ae) && isfinite(gain)) a0 = ae * gain;
    if (isfinite(a0)) {
        char s[32];
        fmt_m(s, sizeof s, a0);
        /* alone (no fe or Ae known: no --config) A0 is no drive setting: "drive A0 20 nm"
         * read as a drive amplitude */
        if (b.pre[0]) b.pre = "free amplitude ";
        add(&b, "A0 %s", s);
    }
    if (pi->no_z) return;
    b.pre = "";
    if (b.len > 0) b.sep = "; ";
    if (p_z && isfinite(pi->p_lo)) {
        add_range(&b, "Z", pi->p_lo, pi->p_hi, fmt_m);
    } else if (isfinite(pi->z_lo_m)) {
        add_range(&b, "Z", pi->z_lo_m, pi->z_hi_m, fmt_m);
    } else {
        double z = isfinite(pi->opt_z_m) ? pi->opt_z_m : pi->cfg_z_m;
        if (isfinite(z)) {
            char s[32];
            fmt_m(s, sizeof s, z);
            add(&b, "Z %s", s);
        }
    }
    if (pi->param[0] && !p_fe && !p_ae && !p_z && isfinite(pi->p_lo))
        add(&b, "%s %.4g to %.4g", pi->param, pi->p_lo, pi->p_hi);
}
