/* SPDX-License-Identifier: MIT */
/* cmd_bench_states.c -- `afmtwin bench-states`: the cost per sample of the integrator and of
 * the output chain in every state a controller can put the twin in (issue 12: the cost must
 * be bounded in all of them), and the cost of a Z change.
 *
 * Method: the daemon's own code path (afm_runner, pipelined, its two stages run alternately
 * on this thread and timed apart, one ring item of 1024 samples at a time) on a config
 * (default config/default.conf), started at a model time of --uptime seconds (default 20:
 * what a daemon up that long meets; the rounding of large sample times was what made the
 * daemon collapse). Each state starts from a fresh twin settled tapping for 30 ms, then its
 * commands (models for geometry and damping changes built beforehand, off the clock, as
 * the daemon's receive thread does), then a timed window. Per state: mean ns per sample and
 * the worst ring item of each stage, and the estimators' table rebuilds; `--runs` repeats
 * give the median of the means and the median of the worst items. The rt integrator's scheme
 * is the one the daemon would run (--scheme auto: the config's sim.rt_scheme when it names
 * one, else the daemon's start-up measurement at 1x, daemon/scheme.c), so that the bench
 * measures what runs (issue 29: on default.conf the daemon picks fast on a slow machine,
 * while the engine's own auto is the accurate scheme). */
#include "afmtwin_cmds.h"
#include "json_out.h"
#include "lcm_tool.h"
#include "opts.h"

#include "runner/afm_cmd.h"
#include "config/afm_config.h"
#include "runner/afm_runner.h"
#include "runner/afm_scheme_cost.h"
#include "transport/afm_io_records.h"
#include "integrators/afm_sim.h"
#include "integrators/afm_sim_live.h"
#include "runner/afm_twin.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define ITEM AFM_RUNNER_SLOT_SAMPLES
#define BENCH_PRIO 70 /* SCHED_FIFO when permitted: as the daemon's stages, not preempted */
#ifdef SCHED_RESET_ON_FORK
#define BENCH_RESET_ON_FORK SCHED_RESET_ON_FORK
#else
#define BENCH_RESET_ON_FORK 0x40000000
#endif
#define SETTLE_S 0.03
#define MAX_RUNS 99

typedef enum {
    ST_TAPPING,
    ST_FREE_FAR,
    ST_RETRACTED,
    ST_PLUNGE,
    ST_FREQ_STEPS,
    ST_Z_RAMP,
    ST_HARD_CONTACT,
    ST_HARDEST,
    ST_MULTITONE,
    ST_MULTI_HARD,
    ST_BIMODAL,
    ST_SOAK_MIX,
    ST_SOAK_MIX1,
    ST_SOAK_MIX2,
    ST_PAUSE_RESUME,
    ST_RESET,
    ST_GEOMETRY,
    ST_DAMPING,
    ST_FM_1024,
    ST_FM_64,
    ST_FM_SELF,
    ST_SAMPLE_FLAT,
    ST_SAMPLE_HOLD,
    ST_SAMPLE_RASTER,
    ST_SAMPLE_RASTER_AM,
    N_STATES
} state_id;

static const struct {
    const char *name;
    double window_s; /* timed model time */
} states[N_STATES] = {
    [ST_TAPPING] = {"tapping, Z 40 nm (steady)", 0.01},
    [ST_FREE_FAR] = {"free, far from resonance (Z 1 um, 300 kHz)", 0.01},
    [ST_RETRACTED] = {"just retracted (Z 40 nm -> 1 um), first 5 ms", 0.005},
    [ST_PLUNGE] = {"Z step 1 um -> 12 nm, drive x 1.7, first 5 ms", 0.005},
    [ST_FREQ_STEPS] = {"frequency step every 1024 samples (338 -> 342 kHz)", 0.01},
    [ST_Z_RAMP] = {"Z ramp 40 -> 20 nm at 2 mm/s", 0.01},
    [ST_HARD_CONTACT] = {"hard contact (Z 15 nm)", 0.01},
    [ST_HARDEST] = {"hardest soak contact (Z 12 nm, drive x 1.7)", 0.01},
    [ST_MULTITONE] = {"multi-tone (4 tones)", 0.01},
    [ST_MULTI_HARD] = {"4 tones in the hardest soak contact", 0.01},
    [ST_BIMODAL] = {"bimodal: + 0.02 nm at mode 2, tapping Z 15 nm", 0.01},
    [ST_SOAK_MIX] = {"a soak's 4-tone mix, 342.5 kHz, Z 17.8 nm", 0.01},
    [ST_SOAK_MIX1] = {"the same, tone 0 alone", 0.01},
    [ST_SOAK_MIX2] = {"a soak's 4-tone contact, Z 15.6 nm (seed 1)", 0.01},
    [ST_PAUSE_RESUME] = {"paused, 5 steps of 1000, resumed: first 5 ms", 0.005},
    [ST_RESET] = {"after a reset (from rest), first 5 ms", 0.005},
    [ST_GEOMETRY] = {"after a geometry rebuild (length +1 %), first 5 ms", 0.005},
    [ST_DAMPING] = {"after a damping change (model swap), first 5 ms", 0.005},
    [ST_FM_1024] = {"FM: internal PLL + amplitude, update every 1024", 0.01},
    [ST_FM_64] = {"FM: internal PLL + amplitude, update every 64", 0.01},
    [ST_FM_SELF] = {"FM: self-excited drive + amplitude, update every 1024", 0.01},
    [ST_SAMPLE_FLAT] = {"sample: none, flat as held (gap Z - 5 nm, Er x 2)", 0.01},
    [ST_SAMPLE_HOLD] = {"sample: a grating under the tip, holding (Z 40 nm)", 0.01},
    [ST_SAMPLE_RASTER] = {"sample: rastering the grating, 10 lines/s (Z 40 nm)", 0.01},
    [ST_SAMPLE_RASTER_AM] = {"sample: rastering it under am.control internal", 0.01},
};

/* The sample of the sample states (issue 18): a grating of 5 nm lines, pitch 100 nm, along
 * x, 10 nm edges, its lines a second material (Er x 2), so that a raster crosses heights and
 * materials; the tip starts over a line's middle (z_s = BENCH_LINE_M exactly there). */
#define BENCH_LINE_M 5e-9
static void bench_sample(afm_config *c) {
    afm_cfg_sample *s = &c->sample;
    memset(s, 0, sizeof *s);
    s->enabled = true;
    s->n_features = 1;
    s->features[0] = (afm_cfg_feature){.kind = AFM_FEATURE_GRATING,
                                       .height_m = BENCH_LINE_M,
                                       .position_m = -25e-9,
                                       .pitch_m = 100e-9,
                                       .duty = 0.5,
                                       .edge_m = 10e-9,
                                       .material = 1};
    s->n_materials = 1;
    s->materials[0] = (afm_cfg_material){.reduced_modulus_pa = 2.0 * c->forces.reduced_modulus_pa,
                                         .hamaker_j = NAN,
                                         .a0_m = NAN,
                                         .eta_pa_s = NAN};
}

/* The holding state's physics without a sample (issue 18): no sample group, the stage Z less
 * the line's height (the gap lat_gap hands the integrator, the same double), the line's
 * material (Er x 2). Holding must cost what this costs: the sample model's own cost is the
 * difference between the two rows (and what the rasters add to it), not the harder tapping
 * on the line, which a flat sample at that gap costs as well. */
static void bench_flat_as_held(afm_config *c) {
    memset(&c->sample, 0, sizeof c->sample);
    c->drive.separation_m = c->drive.separation_m - BENCH_LINE_M;
    c->forces.reduced_modulus_pa = 2.0 * c->forces.reduced_modulus_pa;
}

typedef struct {
    double int_ns, chain_ns;         /* mean per sample over the window */
    double int_worst, chain_worst;   /* the worst ring item, ns per sample */
    long long rebuilds, applied_bad; /* estimator table rebuilds in the window; failed commands */
    long long samples_run;           /* every sample afm_runner_run took for the state (settling,
                                      * set-up and window: what a callgrind count divides by) */
} state_result;

typedef struct {
    afm_runner *r;
    const afm_config *cfg;
    afm_config shadow;
    long long seq;
    double sum_i, sum_c, worst_i, worst_c;
    long long n, bad;
    long long all;     /* samples run, timed or not */
    long long periods; /* period records taken (which ones are finished: drain) */
    bool timing;
} bench_twin;

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int n) {
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Take every output the chain stage made (as the daemon's chain thread: blocks by pointer,
 * period records raw, finished as daemon/chain_loop.c does with its defaults: every k-th
 * for at most 1000 harmonics records a second, and the newest of each take for the status). */
static void drain(bench_twin *t) {
    afm_runner *r = t->r;
    afm_chain_block b;
    for (int s = 0; s < afm_runner_n_streams(r); s++)
        while (afm_runner_take_block(r, s, &b, 0) > 0) {
        }
    static afm_chain_period p[64]; /* large */
    afm_runner_chain_status st;
    afm_runner_chain_status_get(r, &st);
    const int every = afm_io_harmonics_every(0, st.fe_hz, 1000.0);
    int n, newest = -1;
    bool finished = false;
    for (;;) { /* the records before the next published one skipped uncopied, as the daemon */
        int w = afm_runner_periods_waiting(r);
        long long to_pub = (every - t->periods % every) % every;
        if (w > 1 && to_pub > 0)
            t->periods += afm_runner_skip_periods(r, to_pub < w - 1 ? (int)to_pub : w - 1);
        if ((n = afm_runner_take_periods_raw(r, p, every == 1 ? 64 : 1)) <= 0) break;
        newest = n - 1;
        finished = false;
        for (int i = 0; i < n; i++) {
            if (t->periods++ % every != 0) continue;
            afm_runner_period_finish(r, &p[i]);
            finished = i == newest;
        }
    }
    if (newest >= 0 && !finished) afm_runner_period_finish(r, &p[newest]);
    afm_runner_model *m;
    while (afm_runner_take_trash(r, &m))
        afm_runner_model_destroy(&m);
    afm_runner_done dn; /* as the daemon's chain thread: a completion is taken */
    afm_runner_take_done(r, &dn);
}

/* Run n samples item by item: integrator stage, then chain stage, each timed. Returns the
 * samples advanced (less than n when paused without budget). */
static long long run(bench_twin *t, long long n) {
    long long done = 0;
    while (done < n) {
        long long k = n - done < ITEM ? n - done : ITEM;
        double t0 = afmt_mono_s();
        long long adv = afm_runner_run(t->r, k);
        double t1 = afmt_mono_s();
        afm_runner_chain_run(t->r, 0);
        drain(t);
        double t2 = afmt_mono_s();
        if (adv <= 0) break;
        t->all += adv;
        if (t->timing) {
            double ni = (t1 - t0) * 1e9, nc = (t2 - t1) * 1e9;
            t->sum_i += ni;
            t->sum_c += nc;
            t->n += adv;
            t->worst_i = fmax(t->worst_i, ni / (double)adv);
            t->worst_c = fmax(t->worst_c, nc / (double)adv);
        }
        done += adv;
    }
    return done;
}

/* Apply c (timed as integrator work when timing: the daemon's RT thread applies commands);
 * a model for damping and geometry changes is built first, off the clock. */
static void apply(bench_twin *t, afm_cmd *c) {
    char err[AFM_ERR_LEN];
    c->seq = ++t->seq;
    afm_runner_model *m = NULL;
    bool nc = false;
    if (afm_runner_cmd_needs_model(&t->shadow, c, &nc)) {
        afm_config next = t->shadow;
        if (afm_param_apply(&next, &c->u.param, NULL, err, sizeof err) ||
            !(m = afm_runner_model_build(&next, nc, err, sizeof err))) {
            t->bad++;
            return;
        }
    }
    if (c->kind == AFM_CMD_PARAM) afm_param_apply(&t->shadow, &c->u.param, NULL, err, sizeof err);
    double t0 = afmt_mono_s();
    int rc = afm_runner_apply(t->r, c, m ? &m : NULL, err, sizeof err);
    if (t->timing) t->sum_i += (afmt_mono_s() - t0) * 1e9;
    if (rc) {
        fprintf(stderr, "afmtwin bench-states: %s\n", err);
        t->bad++;
    }
    afm_runner_model_destroy(&m);
}

static afm_cmd setpoint(double z_m, double rate_m_s) {
    afm_cmd c = {.kind = AFM_CMD_SETPOINT};
    c.u.setpoint = (afm_cmd_setpoint){z_m, rate_m_s};
    return c;
}

static afm_cmd dither(int n, const double *f_hz, const double *a_m) {
    afm_cmd c = {.kind = AFM_CMD_DITHER};
    c.u.dither.n_tones = n;
    for (int j = 0; j < n; j++) {
        c.u.dither.frequency_hz[j] = f_hz[j];
        c.u.dither.amplitude_m[j] = a_m[j];
    }
    return c;
}

static afm_cmd control(afm_cmd_action a, long long n) {
    afm_cmd c = {.kind = AFM_CMD_CONTROL};
    c.u.control = (afm_cmd_control){a, n};
    return c;
}

static afm_cmd param1(const char *name, double v) {
    afm_cmd c = {.kind = AFM_CMD_PARAM};
    int e = 0, i = 0;
    char err[AFM_ERR_LEN];
    afm_param_lookup(name, &e, &i, err, sizeof err);
    c.u.param = (afm_cmd_param){1, {e}, {i}, {v}};
    return c;
}

/* One state on a fresh twin: settle, set up, time the window. */
static int run_state(const afm_config *cfg, double uptime_s, state_id id, state_result *out) {
    char err[AFM_ERR_LEN];
    bench_twin t = {.cfg = cfg, .shadow = *cfg};
    if (id == ST_FM_1024 || id == ST_FM_64 || id == ST_FM_SELF) {
        /* the runner's FM loops move tone 0 (issue 32); self-excited, it is re-synthesised
         * (a phase jump) at every update */
        t.shadow.fm.enabled = true;
        t.shadow.fm.control = AFM_FM_CONTROL_INTERNAL;
        t.shadow.fm.update_samples = id == ST_FM_64 ? 64 : 1024;
        if (id == ST_FM_SELF) t.shadow.fm.drive = AFM_FM_DRIVE_SELF;
    }
    if (id == ST_SAMPLE_HOLD || id == ST_SAMPLE_RASTER || id == ST_SAMPLE_RASTER_AM)
        bench_sample(&t.shadow);
    if (id == ST_SAMPLE_FLAT) bench_flat_as_held(&t.shadow);
    if (id == ST_SAMPLE_RASTER_AM) { /* the runner's reference PI moves Z (issue 18) */
        t.shadow.am.enabled = true;
        t.shadow.am.control = AFM_AM_CONTROL_INTERNAL;
    }
    t.r = afm_runner_create_pipelined(&t.shadow, ITEM, false, true, 8, err, sizeof err);
    if (!t.r || afm_runner_set_time(t.r, uptime_s, err, sizeof err)) {
        fprintf(stderr, "afmtwin bench-states: %s\n", err);
        afm_runner_destroy(&t.r);
        return -1;
    }
    const double fs = cfg->sim.sample_rate_hz, fe = cfg->drive.tones[0].frequency_hz;
    const double ae = cfg->drive.tones[0].amplitude_m;
    long long win = llround(states[id].window_s * fs);
    run(&t, llround(SETTLE_S * fs));
    afm_runner_status st0;
    afm_runner_chain_status cs0, cs1;
    afm_runner_status_get(t.r, &st0);
    afm_cmd c;
    switch (id) {
    case ST_FREE_FAR: {
        double f = 300e3;
        c = setpoint(1e-6, 0);
        apply(&t, &c);
        c = dither(1, &f, &ae);
        apply(&t, &c);
        run(&t, llround(0.005 * fs));
        break;
    }
    case ST_HARD_CONTACT:
        c = setpoint(15e-9, 0);
        apply(&t, &c);
        run(&t, llround(0.005 * fs));
        break;
    case ST_PLUNGE: { /* far away, driven hard; timed from the step into the sample */
        double a = 1.7 * ae;
        c = setpoint(1e-6, 0);
        apply(&t, &c);
        c = dither(1, &fe, &a);
        apply(&t, &c);
        run(&t, llround(0.01 * fs));
        break;
    }
    case ST_HARDEST: { /* the hardest tapping `afmtwin soak` asks for */
        double a = 1.7 * ae;
        c = setpoint(12e-9, 0);
        apply(&t, &c);
        c = dither(1, &fe, &a);
        apply(&t, &c);
        run(&t, llround(0.005 * fs));
        break;
    }
    case ST_BIMODAL: { /* a second tone at the model's mode 2: bimodal AM-AFM */
        const afm_modal *md = afm_sim_model(afm_runner_sim(t.r));
        const double f[2] = {fe, md->n > 1 ? md->omega_rad_s[1] / 6.283185307179586 : 2e6};
        const double a[2] = {ae, 0.02e-9};
        c = setpoint(15e-9, 0);
        apply(&t, &c);
        c = dither(2, f, a);
        apply(&t, &c);
        run(&t, llround(0.005 * fs));
        break;
    }
    case ST_SOAK_MIX:  /* the state the soak of seed 1 found slowest (default.conf) */
    case ST_SOAK_MIX1: /* the same, tone 0 alone */
    case ST_SOAK_MIX2: /* the soak of seed 1 at 7.85 s: 1.35x the budget before issue 12 */
    {
        static const struct {
            double z_m, f_hz[4], a_m[4];
        } mix[2] = {{17.8e-9,
                     {342479, 590778, 141987, 838028},
                     {0.076e-9, 0.0121e-9, 0.00331e-9, 0.0163e-9}},
                    {15.62e-9,
                     {337945.868, 403324.829, 227633.019, 756669.365},
                     {0.07595e-9, 0.012589e-9, 0.01431e-9, 0.0040618e-9}}};
        int k = id == ST_SOAK_MIX2;
        c = setpoint(mix[k].z_m, 0);
        apply(&t, &c);
        c = dither(id == ST_SOAK_MIX1 ? 1 : 4, mix[k].f_hz, mix[k].a_m);
        apply(&t, &c);
        run(&t, llround(0.01 * fs));
        break;
    }
    case ST_MULTITONE:
    case ST_MULTI_HARD: {
        const double f[4] = {fe, 2.07e6, 1e6, 500e3};
        const double a[4] = {id == ST_MULTI_HARD ? 1.7 * ae : ae, 0.02e-9, 0.01e-9, 0.01e-9};
        if (id == ST_MULTI_HARD) {
            c = setpoint(12e-9, 0);
            apply(&t, &c);
        }
        c = dither(4, f, a);
        apply(&t, &c);
        run(&t, llround(0.005 * fs));
        break;
    }
    default:
        break;
    }
    afm_runner_chain_status_get(t.r, &cs0);
    t.timing = true;
    switch (id) {
    case ST_RETRACTED:
        c = setpoint(1e-6, 0);
        apply(&t, &c);
        break;
    case ST_PLUNGE:
        c = setpoint(12e-9, 0);
        apply(&t, &c);
        break;
    case ST_Z_RAMP:
        c = setpoint(20e-9, 2e-3);
        apply(&t, &c);
        break;
    case ST_PAUSE_RESUME:
        c = control(AFM_CTL_PAUSE, 0);
        apply(&t, &c);
        for (int k = 0; k < 5; k++) {
            c = control(AFM_CTL_STEP, 1000);
            apply(&t, &c);
            run(&t, 1000);
        }
        c = control(AFM_CTL_RUN, 0);
        apply(&t, &c);
        break;
    case ST_RESET:
        c = control(AFM_CTL_RESET, 0);
        apply(&t, &c);
        break;
    case ST_GEOMETRY:
        c = param1("model.beam.length_m", cfg->model.beam.length_m * 1.01);
        apply(&t, &c);
        break;
    case ST_DAMPING:
        c = param1("model.damping_ratio[0]", cfg->model.damping_ratio[0] * 1.1);
        apply(&t, &c);
        break;
    case ST_SAMPLE_RASTER:
    case ST_SAMPLE_RASTER_AM: /* 400 nm lines from x -200 nm: four grating periods a line */
        c = (afm_cmd){.kind = AFM_CMD_SCAN};
        c.u.scan = (afm_cmd_lateral){.mode = AFM_SCAN_RASTER,
                                     .x_m = -200e-9,
                                     .size_x_m = 400e-9,
                                     .size_y_m = 0,
                                     .lines = 10,
                                     .pixels = 64,
                                     .line_rate_hz = 10};
        apply(&t, &c);
        break;
    default:
        break;
    }
    if (id == ST_FREQ_STEPS) {
        long long steps = win / ITEM;
        for (long long k = 0; k < steps; k++) {
            double f = fe + 4000.0 * (double)(k + 1) / (double)steps;
            c = dither(1, &f, &ae);
            apply(&t, &c);
            run(&t, ITEM);
        }
    } else {
        run(&t, win);
    }
    afm_runner_chain_status_get(t.r, &cs1);
    out->int_ns = t.n > 0 ? t.sum_i / (double)t.n : NAN;
    out->chain_ns = t.n > 0 ? t.sum_c / (double)t.n : NAN;
    out->int_worst = t.worst_i;
    out->chain_worst = t.worst_c;
    out->rebuilds = cs1.chain.estimator_rebuilds - cs0.chain.estimator_rebuilds;
    out->samples_run = t.all;
    out->applied_bad = t.bad;
    afm_runner_destroy(&t.r);
    return 0;
}

/* ns per afm_sim_set_separation on a settled simulator of cfg (the Z-only path; each call
 * followed by 64 samples, as a ramp), and per same-valued tone change (the full resync). */
static int z_change_cost(const afm_config *cfg, double *z_ns, double *full_ns) {
    char err[AFM_ERR_LEN];
    afm_sim *s = afm_twin_create(cfg, NULL, NULL, err, sizeof err);
    if (!s) {
        fprintf(stderr, "afmtwin bench-states: %s\n", err);
        return -1;
    }
    static afm_sample buf[64];
    for (int k = 0; k < 2000; k++)
        afm_sim_run(s, 64, buf);
    const int n = 20000;
    double z0 = afm_sim_separation(s), tz = 0, tf = 0;
    const afm_drive *d = afm_sim_drive(s);
    double a = d->amp_m[0], f = d->omega_rad_s[0] / 6.283185307179586476925286766559;
    for (int k = 0; k < n; k++) {
        double t0 = afmt_mono_s();
        afm_sim_set_separation(s, z0 + 1e-12 * (k & 1));
        double t1 = afmt_mono_s();
        afm_sim_run(s, 64, buf);
        double t2 = afmt_mono_s();
        afm_sim_set_tone(s, 0, a, f);
        double t3 = afmt_mono_s();
        afm_sim_run(s, 64, buf);
        tz += t1 - t0;
        tf += t3 - t2;
    }
    *z_ns = tz * 1e9 / n;
    *full_ns = tf * 1e9 / n;
    afm_sim_destroy(&s);
    return 0;
}

/* cfg's rt scheme (and step record) as the daemon would run it at 1x: want
 * AFM_RT_SCHEME_ACCURATE or _FAST forced; AFM_RT_SCHEME_AUTO the config's sim.rt_scheme when it
 * names one, else daemon/scheme.c's choice (both measured with afm_scheme_cost_measure; accurate
 * when its worst state fits AFM_SCHEME_FIT_SHARE of 1 / rate, without the step record if only that
 * fits under sim.step_events auto). *why says what was picked (stderr). 0, or -1 with why the
 * error. */
static int pick_scheme(afm_config *cfg, int want, char *why, size_t len) {
    const bool acc = want == AFM_RT_SCHEME_ACCURATE, fast = want == AFM_RT_SCHEME_FAST;
    if (cfg->sim.integrator != AFM_INTEGRATOR_RT) {
        snprintf(why, len, "scheme: - (not the rt integrator)");
    } else if (acc || fast || cfg->sim.rt_scheme != AFM_RT_SCHEME_AUTO) {
        if (acc || fast) cfg->sim.rt_scheme = acc ? AFM_RT_SCHEME_ACCURATE : AFM_RT_SCHEME_FAST;
        snprintf(why, len, "scheme: %s (%s)",
                 cfg->sim.rt_scheme == AFM_RT_SCHEME_ACCURATE ? "accurate" : "fast",
                 acc || fast ? "--scheme" : "config sim.rt_scheme");
    } else {
        const double fit_ns = AFM_SCHEME_FIT_SHARE * 1e9 / cfg->sim.sample_rate_hz;
        afm_scheme_cost ca, cf;
        if (afm_scheme_cost_measure(cfg, AFM_RT_SCHEME_ACCURATE, &ca, why, len) ||
            afm_scheme_cost_measure(cfg, AFM_RT_SCHEME_FAST, &cf, why, len))
            return -1;
        bool use_acc = ca.worst_ns <= fit_ns, no_rec = false, tried = false;
        if (!use_acc && ca.step_events && cfg->sim.step_events == AFM_STEP_EVENTS_AUTO) {
            tried = true;
            static afm_config c; /* large */
            c = *cfg;
            c.sim.step_events = AFM_STEP_EVENTS_OFF;
            if (afm_scheme_cost_measure(&c, AFM_RT_SCHEME_ACCURATE, &ca, why, len)) return -1;
            use_acc = no_rec = ca.worst_ns <= fit_ns;
        }
        if (no_rec) cfg->sim.step_events = AFM_STEP_EVENTS_OFF;
        cfg->sim.rt_scheme = use_acc ? AFM_RT_SCHEME_ACCURATE : AFM_RT_SCHEME_FAST;
        snprintf(why, len,
                 "scheme: %s (auto, as afmtwind at 1x: accurate %.0f ns%s %s %.0f ns, "
                 "fast %.0f ns)",
                 use_acc ? "accurate" : "fast", ca.worst_ns,
                 tried ? " without the step record" : "", use_acc ? "<=" : ">", fit_ns,
                 cf.worst_ns);
    }
    return 0;
}

static void usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin bench-states [--config FILE] [--uptime S] [--runs N] [--only TEXT]\n"
            "                            [--scheme auto|accurate|fast] [--json]\n\n"
            "Cost per sample of the integrator and of the output chain (OBD, decimators,\n"
            "estimators) in every state a controller can put the twin in: steady tapping,\n"
            "free far from resonance, just retracted, a frequency step every ring item, a Z\n"
            "ramp, hard contact, four tones, paused and resumed, after a reset, after a\n"
            "geometry rebuild and a damping change, the internal FM loops (fm.control =\n"
            "internal) moving tone 0 every 1024 and every 64 samples, a sample under the tip\n"
            "(a grating: holding, rastering, rastering under am.control internal); and the cost of "
            "one Z\n"
            "change (a ramp makes one every 64 samples). The daemon's code path (afm_runner, both "
            "stages timed\n"
            "apart on this thread, 1024 samples at a time), started at model time --uptime.\n"
            "Per state: mean ns/sample and the worst 1024-sample item of each stage (median\n"
            "over --runs repeats), and the estimators' table rebuilds.\n\n"
            "options:\n"
            "  --config FILE  the twin (default config/default.conf)\n"
            "  --uptime S     model time the twin starts at (default 20 s; 0..1e6)\n"
            "  --runs N       repeats per state, 1..%d (default 3)\n"
            "  --only TEXT    only the states whose name contains TEXT (e.g. for a profile)\n"
            "  --scheme S     the rt integrator's scheme: auto (default: what afmtwind at 1x\n"
            "                 would run: the config's sim.rt_scheme if it names one, else both\n"
            "                 measured on this machine as the daemon's --scheme auto does),\n"
            "                 accurate or fast (forced; other integrators have no schemes)\n"
            "  --json         one JSON object on stdout (per state also samples_run: every\n"
            "                 sample the integrator took for it, settling included: what a\n"
            "                 callgrind count of afm_runner_run divides by; tools/bench-ir.sh)\n"
            "  --no-fifo      keep the caller's scheduling (default: SCHED_FIFO 70 when\n"
            "                 permitted, as the daemon's stages). For profilers: under\n"
            "                 callgrind a run takes minutes, and at SCHED_FIFO it holds a\n"
            "                 CPU from everything below it for all of them, for nothing\n"
            "                 (callgrind's counts do not depend on scheduling)\n"
            "  --help         this text\n",
            MAX_RUNS);
}

int afm_cmd_bench_states(int argc, char **argv) {
    const char *path = "config/default.conf", *only = NULL;
    double uptime = 20.0;
    int runs = 3, scheme = AFM_RT_SCHEME_AUTO;
    static const afmt_choice scheme_choices[] = {{"auto", AFM_RT_SCHEME_AUTO},
                                                 {"accurate", AFM_RT_SCHEME_ACCURATE},
                                                 {"fast", AFM_RT_SCHEME_FAST},
                                                 {NULL, 0}};
    bool json = false, no_fifo = false;
    const afmt_opt opts[] = {
        AFMT_FLAG("--json", &json),
        AFMT_FLAG("--no-fifo", &no_fifo),
        AFMT_STRING("--config", &path),
        AFMT_STRING("--only", &only),
        AFMT_CHOICE("--scheme", &scheme, scheme_choices),
        AFMT_DOUBLE("--uptime", &uptime, 0, 1e6, "0..1e6 s"),
        AFMT_INT("--runs", &runs, 1, MAX_RUNS, NULL),
        AFMT_OPTS_END,
    };
    int prc = afmt_opts_parse("bench-states", opts, argc, argv, 1);
    if (prc == AFMT_OPTS_HELP) usage(stdout);
    if (prc) return prc == AFMT_OPTS_HELP ? 0 : 2;
    static afm_config cfg;
    if (afmt_config_load("bench-states", path, &cfg)) return 2;
    char why[256];
    if (pick_scheme(&cfg, scheme, why, sizeof why)) {
        fprintf(stderr, "afmtwin bench-states: %s\n", why);
        return 2;
    }
    /* SCHED_FIFO as the daemon's threads: otherwise a 4 ms time slice of another process
     * lands in a window now and then (seen as a worst item of ~4000 ns/sample) */
    struct sched_param prio = {.sched_priority = BENCH_PRIO};
    bool fifo = !no_fifo && sched_setscheduler(0, SCHED_FIFO | BENCH_RESET_ON_FORK, &prio) == 0;
    state_result res[N_STATES];
    bool ran[N_STATES]; /* --only: the states not run are left out of every table */
    double v[4][MAX_RUNS];
    int failed = 0, n_ran = 0;
    for (int s = 0; s < N_STATES; s++) {
        state_result one[MAX_RUNS];
        ran[s] = !only || strstr(states[s].name, only);
        if (!ran[s]) {
            memset(&res[s], 0, sizeof res[s]);
            continue;
        }
        n_ran++;
        for (int k = 0; k < runs; k++)
            if (run_state(&cfg, uptime, (state_id)s, &one[k])) return 1;
        for (int k = 0; k < runs; k++) {
            v[0][k] = one[k].int_ns;
            v[1][k] = one[k].chain_ns;
            v[2][k] = one[k].int_worst;
            v[3][k] = one[k].chain_worst;
        }
        res[s] = one[runs / 2];
        res[s].int_ns = median(v[0], runs);
        res[s].chain_ns = median(v[1], runs);
        res[s].int_worst = median(v[2], runs);
        res[s].chain_worst = median(v[3], runs);
        failed += one[0].applied_bad > 0;
    }
    if (n_ran == 0) {
        fprintf(stderr,
                "afmtwin bench-states: --only '%s' names no state (afmtwin bench-states "
                "--help lists them)\n",
                only);
        return 2;
    }
    double zc = NAN, full = NAN;
    z_change_cost(&cfg, &zc, &full);
    const double budget = 1e9 / cfg.sim.sample_rate_hz;
    int wi = -1, wc = -1;
    for (int s = 0; s < N_STATES; s++) {
        if (!ran[s]) continue;
        if (wi < 0 || res[s].int_ns > res[wi].int_ns) wi = s;
        if (wc < 0 || res[s].chain_ns > res[wc].chain_ns) wc = s;
    }
    if (json) {
        cJSON *root = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(root, "states");
        cJSON_AddStringToObject(root, "config", path);
        cJSON_AddNumberToObject(root, "uptime_s", uptime);
        cJSON_AddNumberToObject(root, "runs", runs);
        cJSON_AddNumberToObject(root, "budget_ns_per_sample", budget);
        cJSON_AddBoolToObject(root, "sched_fifo", fifo);
        cJSON_AddStringToObject(root, "scheme", why);
        for (int s = 0; s < N_STATES; s++) {
            if (!ran[s]) continue;
            cJSON *e = cJSON_CreateObject();
            cJSON_AddStringToObject(e, "state", states[s].name);
            cJSON_AddNumberToObject(e, "integrator_ns_per_sample", res[s].int_ns);
            cJSON_AddNumberToObject(e, "chain_ns_per_sample", res[s].chain_ns);
            cJSON_AddNumberToObject(e, "integrator_worst_item_ns_per_sample", res[s].int_worst);
            cJSON_AddNumberToObject(e, "chain_worst_item_ns_per_sample", res[s].chain_worst);
            cJSON_AddNumberToObject(e, "estimator_rebuilds", (double)res[s].rebuilds);
            cJSON_AddNumberToObject(e, "samples_run", (double)res[s].samples_run);
            cJSON_AddItemToArray(arr, e);
        }
        cJSON_AddStringToObject(root, "worst_integrator_state", states[wi].name);
        cJSON_AddStringToObject(root, "worst_chain_state", states[wc].name);
        if (isfinite(zc)) cJSON_AddNumberToObject(root, "z_change_ns", zc);
        if (isfinite(full)) cJSON_AddNumberToObject(root, "full_change_ns", full);
        afmt_json_emit(root);
        return failed ? 1 : 0;
    }
    printf("afmtwin bench-states: %s at model time %g s (the daemon's path: afm_runner, both "
           "stages timed apart, 1024 samples at a time, %s); median of %d runs; real time: %.1f "
           "ns per sample\n",
           path, uptime,
           fifo      ? "SCHED_FIFO 70"
           : no_fifo ? "normal priority: --no-fifo"
                     : "normal priority: SCHED_FIFO refused",
           runs, budget);
    printf("  %s\n", why);
    printf("  %-52s %21s %21s %8s %9s\n", "state", "integrator ns/sample", "chain ns/sample",
           "1 core", "rebuilds");
    printf("  %-52s %10s %10s %10s %10s %8s\n", "", "mean", "worst item", "mean", "worst item",
           "RT f.");
    for (int s = 0; s < N_STATES; s++)
        if (ran[s])
            printf("  %-52s %10.1f %10.1f %10.1f %10.1f %8.3f %9lld\n", states[s].name,
                   res[s].int_ns, res[s].int_worst, res[s].chain_ns, res[s].chain_worst,
                   budget / (res[s].int_ns + res[s].chain_ns), res[s].rebuilds);
    printf("  worst state: integrator %.1f ns/sample (%s), chain %.1f ns/sample (%s); on two "
           "cores each stage alone must stay below %.1f\n",
           res[wi].int_ns, states[wi].name, res[wc].chain_ns, states[wc].name, budget);
    printf("  Z change (afm_sim_set_separation, the Z-only path; a ramp makes one every %d "
           "samples = %.0f ns): %.0f ns per change; a full resync (same-valued tone change) "
           "%.0f ns\n",
           AFM_RUNNER_RAMP_SAMPLES, AFM_RUNNER_RAMP_SAMPLES * budget, zc, full);
    return failed ? 1 : 0;
}
