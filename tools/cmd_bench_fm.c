/* SPDX-License-Identifier: MIT */
/* cmd_bench_fm.c -- `afmtwin bench-fm`: what the internal FM control costs per sample (issue
 * 32: "at most a few ns per sample"), AM and FM side by side on the same config in one run.
 *
 * Three twins of one config, each settled at its operating point first: "am", the
 * integrator and the lock-in at tone 0 with the drive fixed (what an AM loop reads); "pll",
 * the same plus the PLL and amplitude controller (runner/afm_fm.h: an update and a tone-0
 * change every fm.update_samples samples, the lock-in retuned); "self", the same with the
 * self-excited drive (the delay line pushed every sample, a re-synthesised tone 0 every
 * update). Rounds alternate the three windows (a noisy machine slows all alike); per state
 * the median ns per sample, and FM less AM: the controllers' cost. Instructions are counted
 * by callgrind on one state at a time (--only; tools/bench-fm.sh:
 * --toggle-collect=bench_fm_window, the window alone). */
#include "afmtwin_cmds.h"
#include "lcm_tool.h"
#include "opts.h"

#include "config/afm_config.h"
#include "estimators/afm_lockin.h"
#include "integrators/afm_sim.h"
#include "runner/afm_fm.h"
#include "runner/afm_twin.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CAP 4096
#define MAX_ROUNDS 99
#define PI 3.14159265358979323846

/* The lumped FM probe of tests/test_fm.c at Z 3 nm (vdW attraction, A 10 pm). */
static const char *default_conf =
    "model = { kind = \"lumped\"; lumped = { stiffness_n_m = 40.0; resonance_hz = 300e3; }; "
    "quality_factor = [300.0]; };\n"
    "forces = { inclination_deg = 0.0; radius_m = 1e-8;\n"
    "  vdw_contact = { hamaker_j = 1.29e-19; a0_m = 2.4e-10; reduced_modulus_pa = 7e10; }; };\n"
    "drive = { separation_m = 3e-9; tones = ( { amplitude_m = 3.3333e-14; frequency_hz = 300e3; "
    "} ); };\n"
    "sim = { sample_rate_hz = 14.06e6; integrator = \"rt\"; rt_scheme = \"accurate\"; };\n"
    "lockin = { time_constant_s = 1e-4; order = 4; };\n"
    "fm = { amplitude_setpoint_m = 1e-11; pll_bandwidth_hz = 200.0; amplitude_bandwidth_hz = "
    "100.0; };\n";

typedef enum { B_AM = 0, B_PLL = 1, B_SELF = 2, B_N = 3 } bench_state;
static const char *const names[B_N] = {"am", "pll", "self"};

typedef struct {
    bench_state st;
    afm_sim *sim;
    afm_lockin lk;
    afm_fm fm;
    afm_sample buf[CAP];
    int n_upd; /* samples per update */
} bench_fm_twin;

static void usage(FILE *f) {
    fprintf(f, "usage: afmtwin bench-fm [--config FILE] [--rounds N] [--updates N] "
               "[--only am|pll|self]\n\n"
               "The cost per sample of the internal FM control against AM on one config\n"
               "(default: a lumped 300 kHz, Q 300 probe at Z 3 nm, A 10 pm, as tests/test_fm.c):\n"
               "am = integrator + lock-in at a fixed tone 0; pll = + the PLL and amplitude\n"
               "controller (runner/afm_fm.h); self = + the self-excited drive. Each twin is\n"
               "settled (locked) first; then --rounds rounds (default 7) alternate windows of\n"
               "--updates fm updates (default 200, of fm.update_samples samples); the median\n"
               "ns per sample per state and FM - AM. --only runs one state's window once (for\n"
               "callgrind --toggle-collect=bench_fm_window: tools/bench-fm.sh).\n");
}

/* n updates' samples of the AM twin t: the integrator, the lock-in at tone 0. */
static int am_run(bench_fm_twin *t, long n) {
    const afm_drive *d = afm_sim_drive(t->sim);
    for (long u = 0; u < n; u++) {
        if (afm_sim_run(t->sim, t->n_upd, t->buf) != AFM_SIM_OK) return -1;
        for (int i = 0; i < t->n_upd; i++)
            afm_lockin_push(&t->lk, t->buf[i].x_m, afm_drive_phase(d, 0, t->buf[i].t_s));
    }
    return 0;
}

/* The timed window: n updates' samples of t's state (noinline: callgrind's toggle; the
 * settling calls am_run and afm_fm_settle, not this). */
__attribute__((noinline)) int bench_fm_window(bench_fm_twin *t, long n);
__attribute__((noinline)) int bench_fm_window(bench_fm_twin *t, long n) {
    char err[256];
    if (t->st != B_AM)
        return afm_fm_run(&t->fm, t->sim, &t->lk, t->buf, CAP, n, NULL, NULL, err, sizeof err);
    return am_run(t, n);
}

static int twin_open(bench_fm_twin *t, const afm_config *cfg0, bench_state st) {
    char err[AFM_ERR_LEN];
    static afm_config cfg;
    cfg = *cfg0;
    cfg.fm.drive = st == B_SELF ? AFM_FM_DRIVE_SELF : AFM_FM_DRIVE_PLL;
    memset(t, 0, sizeof *t);
    t->st = st;
    t->n_upd = cfg.fm.update_samples;
    afm_modal m;
    if (!(t->sim = afm_twin_create(&cfg, &m, NULL, err, sizeof err)) ||
        afm_lockin_init(&t->lk, &cfg.lockin, afm_sim_dt(t->sim), err, sizeof err)) {
        fprintf(stderr, "afmtwin bench-fm: %s\n", err);
        return -1;
    }
    afm_fm_plant p;
    afm_fm_plant_of(&m, &p);
    double f0 = cfg.drive.n_tones > 0 ? cfg.drive.tones[0].frequency_hz : p.f0_hz;
    double a0 = cfg.drive.n_tones > 0 ? cfg.drive.tones[0].amplitude_m : 0.0;
    double tau_c = p.q / (PI * p.f0_hz), t_upd = t->n_upd * afm_sim_dt(t->sim);
    long settle = (long)ceil(20.0 * tau_c / t_upd);
    if (st == B_AM) return am_run(t, settle);
    if (afm_fm_init(&t->fm, &cfg.fm, &cfg.lockin, &p, cfg.sim.sample_rate_hz, f0, f0,
                    fmin(a0, cfg.fm.drive_max_m), err, sizeof err)) {
        fprintf(stderr, "afmtwin bench-fm: %s\n", err);
        return -1;
    }
    if (!(cfg.fm.amplitude_setpoint_m > 0)) afm_fm_hold_amplitude(&t->fm, 0.0);
    afm_fm_means mn;
    if (afm_fm_settle(&t->fm, t->sim, &t->lk, t->buf, CAP, (long)ceil(0.005 / t_upd), 60, 1e-3,
                      1e-3, NULL, NULL, &mn, err, sizeof err)) {
        fprintf(stderr, "afmtwin bench-fm: %s\n", err);
        return -1;
    }
    if (mn.lock != AFM_FM_LOCKED)
        fprintf(stderr, "afmtwin bench-fm: warning: %s did not lock (%s)\n", names[st],
                afm_fm_lock_name(mn.lock));
    return 0;
}

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int afm_cmd_bench_fm(int argc, char **argv) {
    const char *path = NULL;
    int rounds = 7, only_st = -1; /* --only: one bench_state, -1 all */
    static const afmt_choice only_choices[] = {
        {"am", B_AM}, {"pll", B_PLL}, {"self", B_SELF}, {NULL, 0}};
    long updates = 200;
    const afmt_opt opts[] = {
        AFMT_STRING("--config", &path),
        AFMT_CHOICE("--only", &only_st, only_choices),
        AFMT_INT("--rounds", &rounds, 1, MAX_ROUNDS, NULL),
        AFMT_LONG("--updates", &updates, 1, 1000000, NULL),
        AFMT_OPTS_END,
    };
    int prc = afmt_opts_parse("bench-fm", opts, argc, argv, 1);
    int rc = afmt_opts_done("bench-fm", prc == AFMT_OPTS_HELP ? 1 : prc ? -1 : 0, usage);
    if (rc >= 0) return rc;
    static afm_config cfg;
    char err[AFM_ERR_LEN];
    if (path ? afmt_config_load("bench-fm", path, &cfg)
             : afm_config_parse(default_conf, "bench-fm (built in)", &cfg, err, sizeof err)) {
        if (!path) fprintf(stderr, "afmtwin bench-fm: %s\n", err);
        return 2;
    }
    static bench_fm_twin tw[B_N];
    for (int s = 0; s < B_N; s++)
        if ((only_st < 0 || only_st == s) && twin_open(&tw[s], &cfg, (bench_state)s)) return 1;
    if (only_st >= 0) {
        rc = bench_fm_window(&tw[only_st], updates);
        printf("bench-fm %s: %ld samples in the window\n", names[only_st],
               updates * tw[only_st].n_upd);
        afm_sim_destroy(&tw[only_st].sim);
        return rc ? 1 : 0;
    }
    static double ns[B_N][MAX_ROUNDS];
    for (int r = 0; r < rounds; r++)
        for (int s = 0; s < B_N; s++) {
            double t0 = afmt_mono_s();
            if (bench_fm_window(&tw[s], updates)) {
                fprintf(stderr, "afmtwin bench-fm: %s failed\n", names[s]);
                return 1;
            }
            ns[s][r] = (afmt_mono_s() - t0) * 1e9 / (double)(updates * tw[s].n_upd);
        }
    double med[B_N];
    for (int s = 0; s < B_N; s++) {
        qsort(ns[s], (size_t)rounds, sizeof ns[s][0], cmp_d);
        med[s] = ns[s][rounds / 2];
    }
    printf("# bench-fm %s: %d rounds of %ld updates of %d samples per state, median ns per "
           "sample (wall clock, alternated)\n",
           path ? path : "(built-in lumped probe)", rounds, updates, tw[0].n_upd);
    printf("# %-6s %10s %12s   %s\n", "state", "ns/sample", "minus am", "what runs");
    printf("  %-6s %10.2f %12s   integrator + lock-in, tone 0 fixed\n", "am", med[B_AM], "-");
    printf("  %-6s %10.2f %12.2f   + PLL, amplitude PI, tone 0 set every update\n", "pll",
           med[B_PLL], med[B_PLL] - med[B_AM]);
    printf("  %-6s %10.2f %12.2f   + self-excited: delay line, tone 0 re-synthesised\n", "self",
           med[B_SELF], med[B_SELF] - med[B_AM]);
    printf("# locked: pll %s at %.4f Hz, self %s at %.4f Hz\n", afm_fm_lock_name(tw[B_PLL].fm.lock),
           tw[B_PLL].fm.freq_hz, afm_fm_lock_name(tw[B_SELF].fm.lock), tw[B_SELF].fm.freq_hz);
    for (int s = 0; s < B_N; s++)
        afm_sim_destroy(&tw[s].sim);
    return 0;
}
