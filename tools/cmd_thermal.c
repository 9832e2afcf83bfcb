/* SPDX-License-Identifier: MIT */
/* cmd_thermal.c -- `afmtwin thermal`: a thermal tune of the simulated cantilever (thesis
 * section 5.2): the Welch PSD of its Brownian motion, eq. 5.1 fitted per mode for f_n,
 * Q_n, k_n and the noise floor, compared with the model's own values.
 *
 * The tune is taken far from the surface with the drive off, as on the instrument: in a
 * copy of the config every tone's amplitude is set to 0, the separation to 1 mm (the most
 * afm_sim_set_separation allows) and every tip-sample force is switched off (vdW/contact,
 * viscoelastic, squeeze film, capillary, electrostatic). Switching them off, not only
 * moving away, matters for the squeeze film: its damping changes the effective Q (thesis
 * section 5.3) and the Starr model still gives a (tiny) nonzero coefficient at 1 mm; the
 * intrinsic Q_n = 1 / (2 xi_n) is only what the tune should see without any of it. */
#include "afmtwin_cmds.h"
#include "json_out.h"
#include "opts.h"

#include "config/afm_config.h"
#include "runner/afm_thermfit.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DEFAULT_MODES 3
#define DEFAULT_SEGMENT_S 0.05 /* df = 20 Hz: NCHV mode 1's linewidth (811 Hz) is 40 bins */
#define MIN_SEGMENTS 16        /* the default segment is at most seconds / MIN_SEGMENTS */
#define MAX_SECONDS 3600.0

typedef struct {
    const char *config, *psd_path;
    double seconds, segment_s; /* segment_s NAN: default */
    int modes;
    bool json;
    int obd; /* --signal: 1 the OBD reading, 0 the tip displacement */
} thermal_opts;

typedef afm_thermfit_mode_result mode_result;

static void thermal_usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin thermal --config FILE --seconds S [--modes N] [--segment-s X]\n"
            "                       [--signal x|obd] [--psd OUT] [--json]\n\n"
            "Thermal tune (thesis section 5.2): simulates the cantilever's Brownian motion at\n"
            "the config's thermal.temperature_k (thermal noise forced on), with the drive off,\n"
            "the sample 1 mm away and all tip-sample forces switched off, for S seconds at the\n"
            "OBD sample rate; takes the Welch PSD (Hann, 50%% overlap, one-sided, m^2/Hz) and\n"
            "fits eq. 5.1 to each of the first N modes below the Nyquist frequency:\n"
            "  d(f)^2 = R(f) + d_ds^2,\n"
            "  R(f) = 2 kB T / (pi k_n f_n Q_n) / ((f^2/f_n^2 - 1)^2 + (f/(f_n Q_n))^2),\n"
            "folded at the sample rate fs as the unfiltered samples are: R(f) + sum over j >= 1\n"
            "of R(j fs - f) + R(j fs + f) (it matters for a broad mode near Nyquist; other modes'\n"
            "tails and images in the band are not modelled: docs/numerics.md),\n"
            "and compares f_n, Q_n, k_n with the model's f_n = w_n / 2pi, Q_n = 1 / (2 xi_n),\n"
            "k_n = w_n^2 / tip_n^2 (the modal stiffness at the tip).\n\n"
            "options:\n"
            "  --config FILE   libconfig model file (see config/README.md)\n"
            "  --seconds S     simulated time (0 < S <= %g). The statistical error of k_1 and\n"
            "                  Q_1 is about 1 / sqrt(pi f_1 / Q_1 * S): 0.6 %% for NCHV at 10 s\n"
            "  --modes N       fit at most N modes (default %d)\n"
            "  --segment-s X   Welch segment length in s (default min(%g, S / %d)); the\n"
            "                  resolution 1/X should be well below the narrowest f_n / Q_n\n"
            "  --signal x|obd  x: the tip displacement (default); obd: the OBD sensor's\n"
            "                  calibrated reading with its noise floor and ADC (config obd\n"
            "                  group). It reads mode n with the gain g_n of docs/obd.md, so the\n"
            "                  model value shown for k_n is then k_n / g_n^2\n"
            "  --psd OUT       also write the PSD: columns f_hz, psd_m2_per_hz\n"
            "  --json          one JSON object: run parameters and \"modes\": [{n, f_hz, q,\n"
            "                  k_n_per_m, floor_m_rthz, model_f_hz, model_q, model_k_n_per_m,\n"
            "                  rel_err_f, rel_err_q, rel_err_k, se_f_hz, se_q, se_k_n_per_m,\n"
            "                  fit_lo_hz, fit_hi_hz, linewidth_bins}]\n"
            "  --help          this text\n",
            MAX_SECONDS, DEFAULT_MODES, DEFAULT_SEGMENT_S, MIN_SEGMENTS);
}

/* --signal x|obd: what the PSD is of (1: the OBD reading). */
static const afmt_choice signal_choices[] = {{"x", 0}, {"obd", 1}, {NULL, 0}};

static int parse_args(int argc, char **argv, thermal_opts *o) {
    *o = (thermal_opts){.seconds = NAN, .segment_s = NAN, .modes = DEFAULT_MODES};
    const afmt_opt opts[] = {
        AFMT_FLAG("--json", &o->json),
        AFMT_STRING("--config", &o->config),
        AFMT_STRING("--psd", &o->psd_path),
        AFMT_DOUBLE_ABOVE("--seconds", &o->seconds, 0, MAX_SECONDS, NULL),
        AFMT_DOUBLE_ABOVE("--segment-s", &o->segment_s, 0, HUGE_VAL, "seconds > 0"),
        AFMT_INT("--modes", &o->modes, 1, AFM_MAX_MODES, NULL),
        AFMT_CHOICE("--signal", &o->obd, signal_choices),
        AFMT_OPTS_END,
    };
    int rc = afmt_opts_parse("thermal", opts, argc, argv, 1);
    if (rc == AFMT_OPTS_HELP) thermal_usage(stdout);
    if (rc) return rc == AFMT_OPTS_HELP ? 1 : -1;
    if (!o->config || isnan(o->seconds)) {
        fprintf(stderr, "afmtwin thermal: --config FILE and --seconds S are required\n");
        return -1;
    }
    return 0;
}

static void print_text(const thermal_opts *o, const afm_config *c, long nsamp, long nseg, double df,
                       long segs, double elapsed_s, const mode_result *r, int nr) {
    printf("thermal tune of %s: %g s at %g Hz (%ld samples, %.1f s CPU), T = %g K, signal %s\n"
           "Welch PSD: Hann segments of %ld samples (df = %.4g Hz), 50%% overlap, %ld averaged\n\n",
           o->config, o->seconds, c->sim.sample_rate_hz, nsamp, elapsed_s, c->thermal.temperature_k,
           o->obd ? "obd" : "x", nseg, df, segs);
    printf("%4s %14s %14s %9s %9s %9s %9s %11s %11s %9s %12s\n", "mode", "f_hz", "model_f_hz",
           "err_f", "q", "model_q", "err_q", "k_n_per_m", "model_k", "err_k", "floor_m_rthz");
    for (int i = 0; i < nr; i++) {
        const afm_thermfit *f = &r[i].fit;
        printf("%4d %14.8g %14.8g %+9.2e %9.5g %9.5g %+9.2e %11.5g %11.5g %+9.2e %12.4g\n", r[i].n,
               f->f_hz, r[i].model_f_hz, f->f_hz / r[i].model_f_hz - 1, f->q, r[i].model_q,
               f->q / r[i].model_q - 1, f->k_n_m, r[i].model_k_n_m, f->k_n_m / r[i].model_k_n_m - 1,
               sqrt(fmax(f->floor_m2_hz, 0)));
    }
    printf("\nstatistical 1-sigma errors (relative) and fit windows:\n");
    for (int i = 0; i < nr; i++) {
        const afm_thermfit *f = &r[i].fit;
        printf("  mode %d: f %.1e  q %.1e  k %.1e   window %.6g..%.6g Hz (%ld bins, linewidth "
               "%.1f bins)%s\n",
               r[i].n, f->se_f_hz / f->f_hz, f->se_q / f->q, f->se_k_n_m / f->k_n_m, f->fit_lo_hz,
               f->fit_hi_hz, f->n_bins, f->linewidth_bins,
               f->linewidth_bins < 30 ? "  [coarse: lengthen --segment-s]" : "");
    }
}

static int print_json(const thermal_opts *o, const afm_config *c, long nsamp, long nseg, double df,
                      long segs, const mode_result *r, int nr) {
    cJSON *j = cJSON_CreateObject(), *ms = cJSON_CreateArray();
    cJSON_AddStringToObject(j, "config", o->config);
    cJSON_AddNumberToObject(j, "seconds", o->seconds);
    cJSON_AddNumberToObject(j, "sample_rate_hz", c->sim.sample_rate_hz);
    cJSON_AddNumberToObject(j, "samples", (double)nsamp);
    cJSON_AddNumberToObject(j, "temperature_k", c->thermal.temperature_k);
    cJSON_AddStringToObject(j, "signal", o->obd ? "obd" : "x");
    cJSON_AddNumberToObject(j, "segment_samples", (double)nseg);
    cJSON_AddNumberToObject(j, "df_hz", df);
    cJSON_AddNumberToObject(j, "segments", (double)segs);
    for (int i = 0; i < nr; i++) {
        const afm_thermfit *f = &r[i].fit;
        cJSON *m = cJSON_CreateObject();
        cJSON_AddNumberToObject(m, "n", r[i].n);
        cJSON_AddNumberToObject(m, "f_hz", f->f_hz);
        cJSON_AddNumberToObject(m, "q", f->q);
        cJSON_AddNumberToObject(m, "k_n_per_m", f->k_n_m);
        cJSON_AddNumberToObject(m, "floor_m_rthz", sqrt(fmax(f->floor_m2_hz, 0)));
        cJSON_AddNumberToObject(m, "model_f_hz", r[i].model_f_hz);
        cJSON_AddNumberToObject(m, "model_q", r[i].model_q);
        cJSON_AddNumberToObject(m, "model_k_n_per_m", r[i].model_k_n_m);
        cJSON_AddNumberToObject(m, "rel_err_f", f->f_hz / r[i].model_f_hz - 1);
        cJSON_AddNumberToObject(m, "rel_err_q", f->q / r[i].model_q - 1);
        cJSON_AddNumberToObject(m, "rel_err_k", f->k_n_m / r[i].model_k_n_m - 1);
        cJSON_AddNumberToObject(m, "se_f_hz", f->se_f_hz);
        cJSON_AddNumberToObject(m, "se_q", f->se_q);
        cJSON_AddNumberToObject(m, "se_k_n_per_m", f->se_k_n_m);
        cJSON_AddNumberToObject(m, "fit_lo_hz", f->fit_lo_hz);
        cJSON_AddNumberToObject(m, "fit_hi_hz", f->fit_hi_hz);
        cJSON_AddNumberToObject(m, "linewidth_bins", f->linewidth_bins);
        if (o->obd) cJSON_AddNumberToObject(m, "obd_gain", r[i].gain);
        cJSON_AddItemToArray(ms, m);
    }
    cJSON_AddItemToObject(j, "modes", ms);
    return afmt_json_emit(j) ? 1 : 0;
}

int afm_cmd_thermal(int argc, char **argv) {
    thermal_opts o;
    int pa = parse_args(argc, argv, &o);
    if (pa > 0) return 0;
    if (pa < 0) {
        thermal_usage(stderr);
        return 2;
    }
    static afm_config cfg;
    char err[AFM_ERR_LEN];
    if (afmt_config_load("thermal", o.config, &cfg)) return 2;
    afm_thermfit_tune_config(&cfg);
    if (afm_config_validate(&cfg, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin thermal: %s\n", err);
        return 2;
    }
    const double fs = cfg.sim.sample_rate_hz;
    double seg_s =
        isnan(o.segment_s) ? fmin(DEFAULT_SEGMENT_S, o.seconds / MIN_SEGMENTS) : o.segment_s;
    long nseg = 2 * (long)floor(seg_s * fs / 2 + 0.5);
    long nsamp = (long)floor(o.seconds * fs + 0.5);
    if (nseg < 16 || nseg > nsamp) {
        fprintf(stderr,
                "afmtwin thermal: a segment of %g s is %ld samples; it must be >= 16 samples "
                "and no longer than the run (%ld samples)\n",
                seg_s, nseg, nsamp);
        return 2;
    }
    static afm_thermfit_tune_result res;
    double *psd = NULL;
    if (afm_thermfit_tune(&cfg, o.seconds, nseg, o.obd, o.modes, &res, &psd, err, sizeof err)) {
        fprintf(stderr, "afmtwin thermal: %s\n", err);
        return 1;
    }
    if (res.skipped[0]) fprintf(stderr, "afmtwin thermal: not fitted: %s\n", res.skipped);
    int rc = 1, nr = res.n_modes;
    const mode_result *rr = res.modes;
    const double df = res.df_hz;
    if (o.psd_path) {
        FILE *f = fopen(o.psd_path, "w");
        if (!f) {
            snprintf(err, sizeof err, "cannot write %s: %s", o.psd_path, strerror(errno));
            goto fail;
        }
        fprintf(f, "# f_hz psd_m2_per_hz (afmtwin thermal, %s, %g s)\n", o.config, o.seconds);
        for (long k = 1; k <= nseg / 2; k++)
            fprintf(f, "%.10g %.6e\n", (double)k * df, psd[k]);
        fclose(f);
    }
    if (o.json)
        rc = print_json(&o, &cfg, res.n_samples, nseg, df, res.segments, rr, nr);
    else {
        print_text(&o, &cfg, res.n_samples, nseg, df, res.segments, res.cpu_s, rr, nr);
        rc = 0;
    }
    if (nr == 0) rc = 1;
    goto done;
fail:
    fprintf(stderr, "afmtwin thermal: %s\n", err);
    rc = 1;
done:
    free(psd);
    return rc;
}
