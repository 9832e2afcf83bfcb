/* SPDX-License-Identifier: MIT */
/* afm_fm.c -- the FM-AFM phase-locked loop and amplitude controller (contract in afm_fm.h). */
#include "runner/afm_fm.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define PI 3.14159265358979323846
#define ACQUIRE_LOCK_TIMES 20.0 /* never locked after this many lock times: LOST */

const char *afm_fm_drive_name(afm_fm_drive d) {
    return d == AFM_FM_DRIVE_SELF ? "self" : "pll";
}

const char *afm_fm_lock_name(afm_fm_lock l) {
    switch (l) {
    case AFM_FM_LOCKED:
        return "locked";
    case AFM_FM_LOST:
        return "lost";
    default:
        return "acquiring";
    }
}

void afm_fm_plant_of(const afm_modal *m, afm_fm_plant *p) {
    double w = m->omega_rad_s[0], re, im;
    afm_model_tip_response(m, w, &re, &im);
    p->f0_hz = w / (2.0 * PI);
    p->q = 0.5 / m->xi[0];
    p->gain = hypot(re, im);
}

static double clamp(double v, double lo, double hi, bool *limited) {
    if (v <= lo) {
        *limited = true;
        return lo;
    }
    if (v >= hi) {
        *limited = true;
        return hi;
    }
    return v;
}

int afm_fm_init(afm_fm *f, const afm_cfg_fm *c, const afm_cfg_lockin *lk, const afm_fm_plant *p,
                double sample_rate_hz, double f_center_hz, double f_start_hz, double drive_start_m,
                char *err, size_t errlen) {
#define FM_BAD(...) return snprintf(err, errlen, "fm: " __VA_ARGS__), -1
    if (!(p->f0_hz > 0 && p->q > 0 && p->gain > 0 && isfinite(p->f0_hz * p->q * p->gain)))
        FM_BAD("the model's mode 1 (f0 %g Hz, Q %g, gain %g) cannot be locked to", p->f0_hz, p->q,
               p->gain);
    if (!(sample_rate_hz > 0 && f_center_hz > 0 && f_center_hz < 0.5 * sample_rate_hz &&
          f_start_hz > 0 && f_start_hz < 0.5 * sample_rate_hz))
        FM_BAD("centre %g Hz and start %g Hz must lie in (0, rate/2 = %g Hz)", f_center_hz,
               f_start_hz, 0.5 * sample_rate_hz);
    if (!(fabs(f_start_hz - f_center_hz) <= c->max_shift_hz))
        FM_BAD("the start frequency %g Hz is more than max_shift_hz = %g Hz from the centre %g "
               "Hz",
               f_start_hz, c->max_shift_hz, f_center_hz);
    if (!(drive_start_m >= 0 && drive_start_m <= c->drive_max_m))
        FM_BAD("the start drive %g m is outside [0, drive_max_m = %g m]", drive_start_m,
               c->drive_max_m);
    if (!(c->update_samples >= 1 && c->update_samples <= 4096))
        FM_BAD("update_samples must be in [1, 4096] (got %d)", c->update_samples);
    if (!(c->pll_bandwidth_hz > 0 && c->amplitude_bandwidth_hz > 0 && c->lock_threshold_deg > 0 &&
          c->max_shift_hz > 0 && c->pll_kp_hz_per_deg >= 0 && c->pll_ki_hz_per_deg_s >= 0 &&
          c->amplitude_kp >= 0 && c->amplitude_ki_hz >= 0 && c->lock_time_s >= 0 &&
          c->amplitude_setpoint_m >= 0))
        FM_BAD("bandwidths, threshold and max shift must be > 0, gains and times >= 0");
    const double bws[2] = {c->pll_bandwidth_hz, c->amplitude_bandwidth_hz};
    for (int k = 0; k < 2; k++) {
        double lag = lk->order * atan(2.0 * PI * lk->time_constant_s * bws[k]);
        if (lag > 0.25 * PI)
            FM_BAD("%s bandwidth %g Hz is too fast for the lock-in (order %d, time constant %g "
                   "s: %.0f deg of lag at crossover, at most 45)",
                   k ? "the amplitude" : "the PLL", bws[k], lk->order, lk->time_constant_s,
                   lag * 180.0 / PI);
    }
    if (c->drive == AFM_FM_DRIVE_SELF) {
        double f_lo = fmax(f_center_hz - c->max_shift_hz, 1e-3 * sample_rate_hz);
        int D = (int)nearbyint(sample_rate_hz / (4.0 * f_lo));
        if (2 * D + 1 > AFM_FM_SELF_CAP)
            FM_BAD("drive = \"self\": half a period at %g Hz is %d samples at %g Hz, the delay "
                   "line holds %d",
                   f_lo, 2 * D, sample_rate_hz, AFM_FM_SELF_CAP - 1);
    }
#undef FM_BAD
    memset(f, 0, sizeof *f);
    f->c = *c;
    f->rate_hz = sample_rate_hz;
    f->tau_c_s = p->q / (PI * p->f0_hz);
    f->k_phi_deg_hz = 360.0 * p->q / (PI * p->f0_hz);
    f->ki = c->pll_ki_hz_per_deg_s > 0 ? c->pll_ki_hz_per_deg_s
                                       : 2.0 * PI * c->pll_bandwidth_hz / f->k_phi_deg_hz;
    f->kp = c->pll_kp_hz_per_deg > 0 ? c->pll_kp_hz_per_deg : f->ki * f->tau_c_s;
    f->aki = c->amplitude_ki_hz > 0 ? c->amplitude_ki_hz
                                    : 2.0 * PI * c->amplitude_bandwidth_hz / p->gain;
    f->akp = c->amplitude_kp > 0 ? c->amplitude_kp : f->aki * f->tau_c_s;
    f->lock_time_s = c->lock_time_s > 0 ? c->lock_time_s : 5.0 / (2.0 * PI * c->pll_bandwidth_hz);
    f->f_center_hz = f_center_hz;
    f->df_i_hz = f_start_hz - f_center_hz;
    f->freq_hz = f_start_hz;
    f->drive_i_m = f->drive_m = drive_start_m;
    f->a_set_m = c->amplitude_setpoint_m;
    f->amplitude_m = f->lag_deg = NAN;
    f->lock = AFM_FM_ACQUIRING;
    f->reacquiring = false;
    f->t_lock_s = NAN;
    afm_fm_self_init(&f->self, sample_rate_hz, f_start_hz, c->pll_bandwidth_hz);
    return 0;
}

void afm_fm_hold_amplitude(afm_fm *f, double a_set_m) {
    if (!(a_set_m >= 0) || !isfinite(a_set_m)) return;
    f->a_set_m = a_set_m;
    f->drive_i_m = f->drive_m; /* bumpless */
    if (a_set_m == 0) f->amp_error_m = 0.0;
}

void afm_fm_recenter(afm_fm *f) {
    /* the integrator keeps its absolute frequency, re-expressed about the new centre */
    f->df_i_hz += f->f_center_hz - f->freq_hz;
    f->f_center_hz = f->freq_hz;
}

double afm_fm_shift_hz(const afm_fm *f) {
    return f->freq_hz - f->f_center_hz;
}

void afm_fm_update(afm_fm *f, double amplitude_m, double lag_deg, double dt_s) {
    if (!isfinite(amplitude_m) || !isfinite(lag_deg) || !(dt_s > 0)) return;
    f->amplitude_m = amplitude_m;
    f->lag_deg = lag_deg;
    f->t_s += dt_s;
    f->updates++;
    /* PLL */
    double e = remainder(lag_deg - f->c.phase_setpoint_deg, 360.0);
    const double lim = f->c.max_shift_hz;
    const double lo = fmax(-lim, 1e-3 * f->rate_hz - f->f_center_hz),
                 hi = fmin(lim, 0.499 * f->rate_hz - f->f_center_hz);
    bool lim_i = false, lim_o = false;
    double df;
    if (f->c.drive == AFM_FM_DRIVE_SELF) {
        /* the oscillation's own frequency (afm_fm_self_measure), clamped to the window */
        df = clamp(f->self.f_est_hz - f->f_center_hz, lo, hi, &lim_o);
        f->df_i_hz = df;
        if (f->self_ok)
            f->drive_phase_rad = f->self.phase_rad + f->c.phase_setpoint_deg * (PI / 180.0);
    } else {
        f->df_i_hz = clamp(f->df_i_hz - f->ki * e * dt_s, lo, hi, &lim_i);
        df = clamp(f->df_i_hz - f->kp * e, lo, hi, &lim_o);
    }
    f->freq_hz = f->f_center_hz + df;
    f->f_limited = lim_o;
    f->phase_error_deg = e;
    /* amplitude */
    if (f->a_set_m > 0) {
        double ea = f->a_set_m - amplitude_m;
        bool li = false, lo2 = false;
        f->drive_i_m = clamp(f->drive_i_m + f->aki * ea * dt_s, 0.0, f->c.drive_max_m, &li);
        f->drive_m = clamp(f->drive_i_m + f->akp * ea, 0.0, f->c.drive_max_m, &lo2);
        f->drive_limited = lo2;
        f->amp_error_m = ea;
    } else {
        f->drive_limited = false;
        f->amp_error_m = 0.0;
    }
    /* lock state */
    bool inside = fabs(e) <= f->c.lock_threshold_deg && !f->f_limited;
    if (inside) {
        f->t_in_s += dt_s;
        f->t_out_s = 0.0;
        if (f->lock != AFM_FM_LOCKED && f->t_in_s >= f->lock_time_s) {
            f->lock = AFM_FM_LOCKED;
            f->t_lock_s = f->t_s;
            f->reacquiring = false;
        } else if (f->lock == AFM_FM_LOST) { /* tracking again: not lost, not yet locked */
            f->lock = AFM_FM_ACQUIRING;
            f->reacquiring = true;
        }
    } else {
        f->t_out_s += dt_s;
        f->t_in_s = 0.0;
        if (f->lock == AFM_FM_LOCKED) {
            if (f->t_out_s >= f->lock_time_s) f->lock = AFM_FM_LOST;
        } else if (f->lock == AFM_FM_ACQUIRING &&
                   (f->reacquiring || (f->f_limited && f->t_out_s >= f->lock_time_s) ||
                    f->t_out_s >= ACQUIRE_LOCK_TIMES * f->lock_time_s)) {
            f->lock = AFM_FM_LOST; /* a re-acquisition that left the window is lost again */
            f->reacquiring = false;
        }
    }
}

int afm_fm_run(afm_fm *f, afm_sim *s, afm_lockin *l, afm_sample *buf, int cap, long n_updates,
               afm_fm_on_samples cb, void *ctx, char *err, size_t errlen) {
    const int n = f->c.update_samples;
    if (n > cap) {
        snprintf(err, errlen, "fm: a buffer of %d samples for updates of %d", cap, n);
        return -1;
    }
    const double dt = n * afm_sim_dt(s);
    for (long u = 0; u < n_updates; u++) {
        int rc = afm_sim_run(s, n, buf);
        if (rc != AFM_SIM_OK) {
            snprintf(err, errlen, "fm: simulation failed (code %d) at t = %.9g s", rc,
                     afm_sim_time(s));
            return -1;
        }
        const afm_drive *d = afm_sim_drive(s);
        for (int i = 0; i < n; i++)
            afm_lockin_push(l, buf[i].x_m, afm_drive_phase(d, 0, buf[i].t_s));
        const bool self = f->c.drive == AFM_FM_DRIVE_SELF;
        if (self)
            for (int i = 0; i < n; i++)
                afm_fm_self_push(&f->self, buf[i].x_m);
        if (cb) cb(ctx, s, buf, n);
        double a, lag;
        afm_lockin_polar(l, &a, &lag);
        double f_old = f->freq_hz, d_old = f->drive_m;
        if (self) f->self_ok = afm_fm_self_measure(&f->self, f->freq_hz, dt);
        afm_fm_update(f, a, lag, dt);
        if (self && f->self_ok) {
            /* re-synthesised: the deflection's phase plus the set-point, now */
            afm_lockin_retune(l);
            rc = afm_sim_set_tone_phase(s, 0, f->drive_m, f->freq_hz, f->drive_phase_rad);
            if (rc != AFM_SIM_OK) {
                snprintf(err, errlen, "fm: tone 0 (%g m, %g Hz, %g rad) refused (code %d)",
                         f->drive_m, f->freq_hz, f->drive_phase_rad, rc);
                return -1;
            }
        } else if (f->freq_hz != f_old || f->drive_m != d_old) {
            if (f->freq_hz != f_old) afm_lockin_retune(l);
            rc = afm_sim_set_tone(s, 0, f->drive_m, f->freq_hz);
            if (rc != AFM_SIM_OK) {
                snprintf(err, errlen, "fm: tone 0 (%g m, %g Hz) refused (code %d)", f->drive_m,
                         f->freq_hz, rc);
                return -1;
            }
        }
    }
    return 0;
}

/* afm_fm_run one update at a time, summing the window's means. */
typedef struct {
    double f, d, a, e, lag;
} fm_sums;

int afm_fm_settle(afm_fm *f, afm_sim *s, afm_lockin *l, afm_sample *buf, int cap,
                  long window_updates, int max_windows, double tol_hz, double tol_rel,
                  afm_fm_on_samples cb, void *ctx, afm_fm_means *out, char *err, size_t errlen) {
    if (window_updates < 1 || max_windows < 2) {
        snprintf(err, errlen, "fm: need windows of >= 1 update and >= 2 windows");
        return -1;
    }
    double f_prev = NAN;
    memset(out, 0, sizeof *out);
    for (int w = 0; w < max_windows; w++) {
        fm_sums z = {0};
        for (long u = 0; u < window_updates; u++) {
            if (afm_fm_run(f, s, l, buf, cap, 1, cb, ctx, err, errlen)) return -1;
            z.f += f->freq_hz;
            z.d += f->drive_m;
            z.a += f->amplitude_m;
            z.e += f->phase_error_deg;
            z.lag += f->lag_deg;
        }
        double n = (double)window_updates;
        out->freq_hz = z.f / n;
        out->shift_hz = out->freq_hz - f->f_center_hz;
        out->drive_m = z.d / n;
        out->amplitude_m = z.a / n;
        out->phase_error_deg = z.e / n;
        out->lag_deg = z.lag / n;
        out->lock = f->lock;
        out->windows = w + 1;
        bool amp_ok =
            !(f->a_set_m > 0) || fabs(out->amplitude_m - f->a_set_m) <= tol_rel * f->a_set_m;
        if (w > 0 && f->lock == AFM_FM_LOCKED && fabs(out->freq_hz - f_prev) <= tol_hz && amp_ok) {
            out->settled = true;
            return 0;
        }
        f_prev = out->freq_hz;
    }
    return 0;
}
