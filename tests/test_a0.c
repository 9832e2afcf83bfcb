/* SPDX-License-Identifier: MIT */
/* test_a0.c -- the one free amplitude A0 (issue 30, runner/afm_a0.h), run from the
 * repository root.
 *
 *  - A0 is what the twin itself settles to far from the sample: on default.conf and
 *    nchv.conf, the twin of the config with every tip force on (as the daemon runs it), at
 *    Z = 1 um, settled from rest (tolerance 1e-10, the sweep's dwell), gives harmonic 1 equal
 *    to A0 within 1e-5, and its lock-in (config group lockin) equal within 1e-4.
 *  - The linear response with the far-field squeeze damping agrees within 1e-5 (accurate
 *    scheme), the linear response without the squeeze film (what `afmtwin approach` printed
 *    as "free" before: 57.27 nm on default.conf against 50.65 nm measured) does not: A0 is
 *    more than 5 % below it there.
 *  - The warm start settles: A0 is reported settled in well under the cap on the shipped
 *    configs used here, and its lag is 90 deg (to 0.1) at mode 1's resonance.
 * tests/test_a0.sh checks that approach, scan and the daemon's runner (replay at Z 1 um) give
 * this A0; tests/test_client.sh that hil_pi measures it through a real-time daemon. */
#include "beam/afm_model.h"
#include "config/afm_config.h"
#include "estimators/afm_lockin.h"
#include "runner/afm_a0.h"
#include "runner/afm_twin.h"
#include "check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define TWO_PI 6.283185307179586476925286766559

typedef struct {
    afm_lockin lk;
} lk_ctx;

static void on_samples(void *ctx, const afm_sim *s, const afm_sample *p, int n) {
    lk_ctx *c = ctx;
    const afm_drive *d = afm_sim_drive(s);
    for (int i = 0; i < n; i++)
        afm_lockin_push(&c->lk, p[i].x_m, afm_drive_phase(d, 0, p[i].t_s));
}

/* The twin of cfg as it is (all tip forces) at Z = 1 um, settled from rest: harmonic 1 and
 * the lock-in amplitude. */
static int measure_far(const afm_config *cfg0, double *h1, double *lockin) {
    static afm_config cfg;
    cfg = *cfg0;
    cfg.drive.separation_m = AFM_A0_Z_M;
    char err[256];
    afm_sim *s = afm_twin_create(&cfg, NULL, NULL, err, sizeof err);
    if (!check_true(s != NULL, s ? "twin at Z 1 um" : err)) return -1;
    static afm_sweep w;
    static lk_ctx lc;
    const int ks[1] = {1};
    int rc = -1;
    if (!check_true(afm_sweep_init(&w, cfg.sim.sample_rate_hz, cfg.drive.tones[0].frequency_hz,
                                   1e-10, 40000, ks, 1, err, sizeof err) == 0 &&
                        afm_lockin_init(&lc.lk, &cfg.lockin, afm_sim_dt(s), err, sizeof err) == 0,
                    "sweep and lock-in init"))
        goto out;
    w.on_samples = on_samples;
    w.on_samples_ctx = &lc;
    afm_orbit o;
    int st = afm_sweep_dwell(&w, s, &o, err, sizeof err);
    check_true(st == 1, "the twin at Z 1 um settles from rest (tolerance 1e-10)");
    *h1 = o.harmonics[0].x_amp_m;
    *lockin = afm_lockin_amplitude(&lc.lk);
    rc = 0;
    afm_sweep_destroy(&w);
out:
    afm_sim_destroy(&s);
    return rc;
}

static void one_config(const char *path) {
    static afm_config cfg;
    char err[256], what[320];
    int rc = afm_config_load(path, &cfg, err, sizeof err);
    snprintf(what, sizeof what, "%s loads%s%s", path, rc ? ": " : "", rc ? err : "");
    if (!check_true(rc == 0, what)) return;
    cfg.sim.rt_scheme = AFM_RT_SCHEME_ACCURATE;
    afm_a0 a0;
    snprintf(err, sizeof err, "%s: afm_a0_compute", path);
    if (!check_true(afm_a0_compute(&cfg, &a0, err, sizeof err) == 0, err)) return;
    printf("# %s: A0 %.6f nm, lag %.4f deg (%d periods, settled %d); linear with the "
           "far-field squeeze %.6f nm\n",
           path, a0.amplitude_m * 1e9, a0.lag_deg, a0.periods, a0.settled,
           a0.linear_amplitude_m * 1e9);
    snprintf(what, sizeof what, "%s: A0 settled (warm start) within 5000 periods", path);
    check_true(a0.settled && a0.periods < 5000, what);
    snprintf(what, sizeof what, "%s: A0 lag 90 deg at resonance", path);
    check_abs(a0.lag_deg, 90.0, 0.1, what);
    snprintf(what, sizeof what, "%s: A0 = linear response with the far-field squeeze", path);
    check_rel(a0.amplitude_m, a0.linear_amplitude_m, 1e-5, what);
    /* the old "free (tip forces off)": the model's response without any tip force */
    afm_modal m;
    double re, im;
    snprintf(err, sizeof err, "%s: model", path);
    if (!check_true(afm_model_build(&cfg.model, &m, err, sizeof err) == 0, err)) return;
    afm_model_tip_response(&m, TWO_PI * cfg.drive.tones[0].frequency_hz, &re, &im);
    double old_free = cfg.drive.tones[0].amplitude_m * hypot(re, im);
    printf("# %s: the model's response without the squeeze film %.6f nm (not A0)\n", path,
           old_free * 1e9);
    snprintf(what, sizeof what, "%s: A0 is not the response without the squeeze film", path);
    check_true(a0.amplitude_m < 0.95 * old_free, what);
    double h1 = NAN, lk = NAN;
    if (measure_far(&cfg, &h1, &lk)) return;
    printf("# %s: the twin at Z 1 um, all forces on: harmonic 1 %.6f nm, lock-in %.6f nm\n", path,
           h1 * 1e9, lk * 1e9);
    snprintf(what, sizeof what, "%s: A0 = harmonic 1 of the twin at Z 1 um (1e-5)", path);
    check_rel(a0.amplitude_m, h1, 1e-5, what);
    snprintf(what, sizeof what, "%s: A0 = lock-in amplitude of the twin at Z 1 um (1e-4)", path);
    check_rel(a0.amplitude_m, lk, 1e-4, what);
}

int main(void) {
    one_config("config/default.conf");
    one_config("config/nchv.conf");
    /* a bad config: no tone */
    static afm_config cfg;
    char err[256];
    if (check_true(afm_config_load("config/default.conf", &cfg, err, sizeof err) == 0,
                   "config/default.conf loads")) {
        cfg.drive.n_tones = 0;
        afm_a0 a0;
        check_true(afm_a0_compute(&cfg, &a0, err, sizeof err) != 0, "no tone 0: refused");
    }
    return check_done();
}
