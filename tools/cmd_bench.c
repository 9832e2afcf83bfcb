/* SPDX-License-Identifier: MIT */
/* cmd_bench.c -- `afmtwin bench`: the rt integrator, ARKODE fixed-step ERK at equal accuracy
 * and CVODE, timed and compared side by side on tapping models.
 *
 * Method, per model: settle the tapping orbit with rt (thousands of periods: cheap), take
 * its modal state and drive phase, start every integrator from exactly that state, run
 * `periods` excitation periods and compare the last one with CVODE sample by sample. ERK's
 * substeps are raised until its error is no worse than rt's. Then each integrator keeps
 * running on its orbit and `runs` timed blocks of samples give median and minimum cost. */
#include "afmtwin_cmds.h"
#include "opts.h"
#include "json_out.h"

#include "estimators/afm_chain.h"
#include "config/afm_config.h"
#include "forces/afm_force.h"
#include "runner/afm_twin.h"
#include "beam/afm_model.h"
#include "integrators/afm_sim.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static const double two_pi = 6.283185307179586476925286766559;

/* The models and operating points. An operating point is given as the free (linear)
 * tip amplitude and the set-point ratio Z / free amplitude, the usual tapping-mode
 * description; the drive amplitude A and Z follow from the model's linear response at the
 * config's drive frequency, so the tip taps whatever the model's resonance. 0 keeps the
 * config's value. Overrides, and why:
 *  - thesis-1dof: none (20 nm free, Z 14 nm: taps).
 *  - thesis-fig-4-2 (84.053 kHz, above the 80.8 kHz resonance): from rest the orbit
 *    settles on the low branch (13.4 nm) that never reaches Z = 30 nm; Z = 0.7 x free.
 *  - thesis-fig-4-13: 22.7 nm free never reaches Z = 45 nm; Z = 0.7 x free.
 *  - nchv: the model's first mode is 338 kHz, so the 323.352 kHz drive gives 7.2 nm free,
 *    no contact at Z = 31 nm; 50 nm free and Z = 35 nm as in the numerics.md prototype. */
typedef struct {
    const char *file;
    double free_amp_m; /* linear tip amplitude to drive to (m), 0 = config amplitude */
    double setpoint;   /* Z / free amplitude, 0 = config Z */
    bool chain;        /* also time the output chain on this case's rt orbit */
} bench_case;

static const bench_case bench_cases[] = {
    {"thesis-1dof.conf", 0.0, 0.0, false},
    {"thesis-fig-4-2.conf", 0.0, 0.7, false},
    {"thesis-fig-4-13.conf", 0.0, 0.7, false},
    {"nchv.conf", 50e-9, 0.7, true},
};

/* The chain case's sensor and outputs (nchv.conf has no obd/output groups): those of
 * config/default.conf, so the noise generator and the ADC are in the timed path. */
#define CHAIN_NOISE_M_RTHZ 50e-15
#define CHAIN_ADC_BITS 16
#define CHAIN_FULL_SCALE_M 200e-9
static const int chain_decimation[] = {16, 256};
#define N_CASES ((int)(sizeof bench_cases / sizeof bench_cases[0]))

/* rt: the accurate scheme (every offline tool's); rt-fast: the fast one (what afmtwind
 * --scheme auto runs where the accurate one does not fit the budget; its chain row) */
enum { ROW_RT, ROW_RT_FAST, ROW_ERK, ROW_REF, N_ROWS };
static const char *const row_name[N_ROWS] = {"rt", "rt-fast", "arkode-erk", "reference"};

/* ERK substeps tried, in order, until its error is <= rt's. */
static const int erk_substeps[] = {1,  2,  3,  4,  5,  6,  7,  8,  10,  12,  14,  16,  20,  24,
                                   28, 32, 40, 48, 56, 64, 80, 96, 128, 160, 192, 256, 384, 512};
#define N_ERK_SUBSTEPS ((int)(sizeof erk_substeps / sizeof erk_substeps[0]))

typedef struct {
    bool ok;
    int substeps; /* substeps per sample; 0 = engine default (rt), -1 = adaptive (CVODE) */
    double ns_med, ns_min, rt_factor, err_rel;
    char note[160];
} bench_row;

typedef struct {
    const char *config;
    bool ok;
    char err[AFM_ERR_LEN];
    int n_modes;
    double z_m, amp_m, freq_hz, rate_hz;
    double free_amp_m;       /* linear tip amplitude at this drive (no tip force) */
    double settle_s;         /* model time settled with rt */
    double tip_amp_m;        /* (max - min) / 2 of x over the compared period (CVODE) */
    double contact_fraction; /* share of those samples with the gap below a0 */
    double peak_force_n;     /* largest tip force over that period */
    double ref_check;        /* CVODE at ref_rtol vs CVODE at ref_rtol / 100 */
    double ref_rtol;
    bench_row row[N_ROWS];
    /* "chain": rt integrator + afm_chain (OBD, decimation, estimators), timed per block
     * side by side in the same runs */
    bool has_chain, chain_ok;
    double chain_int_ns, chain_ns, chain_total_ns, chain_rt_factor, chain_overhead_pct;
    double chain_fastest_ns; /* the fastest run's total */
    int chain_runs;
    char chain_note[AFM_ERR_LEN];
} bench_result;

typedef struct {
    bool json, quick;
    int runs, periods;
    double settle_tau; /* settle for this many of the slowest modal decay times */
    const char *dir;
    long n_time[N_ROWS]; /* samples per timed run */
} bench_opts;

static void bench_usage(FILE *f) {
    fprintf(
        f, "usage: afmtwin bench [--json] [--runs N] [--quick] [--periods K] [--config-dir DIR]\n\n"
           "Times the rt integrator, ARKODE fixed-step ERK and CVODE while tapping, on\n"
           "thesis-1dof.conf, thesis-fig-4-2.conf, thesis-fig-4-13.conf and nchv.conf.\n"
           "Every integrator starts from one rt-settled state; error_rel is max |x - x_cvode| /\n"
           "amplitude over the last of K excitation periods. ERK's substeps are raised until\n"
           "its error_rel is <= rt's (equal accuracy).\n\n"
           "options:\n"
           "  --json            one JSON object {\"cases\": [...], \"ratios\": [...]} on stdout\n"
           "  --runs N          timed runs per integrator, median and min reported (default 5)\n"
           "  --quick           shorter settling and timed runs (default runs 2)\n"
           "  --periods K       periods run before the compared one ends (default 5)\n"
           "  --config-dir DIR  where the .conf files are (default config)\n"
           "  --help            this text\n");
}

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* |x_tip / ub| of the linear model (no tip force) for a base tone at w rad/s:
 * |sum_i tip_i (-base_k_i + base_m_i w^2) / (w_i^2 - w^2 + 2 i xi_i w_i w)|. */
/* |x_tip / x_base| of the linear model at w (free amplitude per base amplitude). */
static double linear_gain(const afm_modal *m, double w) {
    double re, im;
    afm_model_tip_response(m, w, &re, &im);
    return hypot(re, im);
}

/* Load a case: config (with overrides), modal model, force constants. */
static int load_case(const bench_opts *o, const bench_case *bc, afm_config *cfg, afm_modal *m,
                     afm_force_params *f, char *err, size_t errlen) {
    char path[512];
    snprintf(path, sizeof path, "%s/%s", o->dir, bc->file);
    if (afm_config_load(path, cfg, err, errlen) != 0) return -1;
    if (afm_model_build(&cfg->model, m, err, errlen) != 0) return -1;
    afm_cfg_tone *t = &cfg->drive.tones[0];
    double gain = linear_gain(m, two_pi * t->frequency_hz);
    if (bc->free_amp_m > 0) t->amplitude_m = bc->free_amp_m / gain;
    if (bc->setpoint > 0) cfg->drive.separation_m = bc->setpoint * gain * t->amplitude_m;
    if (afm_config_validate(cfg, err, errlen) != 0) return -1;
    return afm_twin_forces(cfg, m, NULL, f, err, errlen);
}

/* A simulator of kind k on cfg's drive, started from (q, qd) if q is non-NULL. */
static afm_sim *make_sim(const afm_config *cfg, const afm_modal *m, const afm_force_params *f,
                         afm_integrator_kind k, int substeps, double rtol, const double *q,
                         const double *qd, char *err, size_t errlen) {
    afm_cfg_sim sc = cfg->sim;
    sc.integrator = k;
    if (k == AFM_INTEGRATOR_RT && sc.rt_scheme == AFM_RT_SCHEME_AUTO)
        sc.rt_scheme = AFM_RT_SCHEME_ACCURATE;
    if (substeps > 0) sc.rt_substeps_contact = substeps;
    if (rtol > 0) sc.ref_rtol = rtol;
    afm_sim *s = afm_sim_create(m, f, &cfg->drive, &sc, err, errlen);
    if (s && q && afm_sim_set_state(s, q, qd) != AFM_SIM_OK) {
        snprintf(err, errlen, "bench: settled state is not finite");
        afm_sim_destroy(&s);
    }
    return s;
}

#define CHUNK 1024
static afm_sample chunk[CHUNK];

/* Run n samples; x (n entries, may be NULL) receives the tip displacement and f the force. */
static int run_collect(afm_sim *s, long n, double *x, double *f) {
    for (long done = 0; done < n;) {
        int k = n - done < CHUNK ? (int)(n - done) : CHUNK;
        int rc = afm_sim_run(s, k, chunk);
        if (rc != AFM_SIM_OK) return rc;
        for (int i = 0; i < k; i++) {
            if (x) x[done + i] = chunk[i].x_m;
            if (f) f[done + i] = chunk[i].f_n;
        }
        done += k;
    }
    return AFM_SIM_OK;
}

/* max |x - xr| / amp over samples [from, n). */
static double err_rel(const double *x, const double *xr, long from, long n, double amp) {
    double e = 0.0;
    for (long i = from; i < n; i++) {
        double d = fabs(x[i] - xr[i]);
        if (!isfinite(d)) return INFINITY;
        e = fmax(e, d);
    }
    return e / amp;
}

/* Time `runs` blocks of nsamp samples on the running orbit (samples written to a buffer,
 * as the twin does). Fills median and minimum ns per sample. */
static int time_runs(afm_sim *s, long nsamp, int runs, bench_row *r) {
    double *t = malloc((size_t)runs * sizeof *t);
    if (!t) return -1;
    int rc = AFM_SIM_OK;
    for (int k = 0; k < runs && rc == AFM_SIM_OK; k++) {
        double t0 = now_s();
        rc = run_collect(s, nsamp, NULL, NULL);
        t[k] = (now_s() - t0) * 1e9 / (double)nsamp;
    }
    if (rc == AFM_SIM_OK) {
        qsort(t, (size_t)runs, sizeof *t, cmp_double);
        r->ns_min = t[0];
        r->ns_med = runs % 2 ? t[runs / 2] : 0.5 * (t[runs / 2 - 1] + t[runs / 2]);
        r->rt_factor = afm_sim_dt(s) / (r->ns_med * 1e-9);
    }
    free(t);
    return rc;
}

static const char *rc_text(int rc) {
    switch (rc) {
    case AFM_SIM_EBLOWUP:
        return "state blew up";
    case AFM_SIM_ESOLVER:
        return "SUNDIALS solver failure";
    case AFM_SIM_EINVAL:
        return "invalid argument";
    default:
        return "failed";
    }
}

/* Time the rt integrator and the output chain on s's running orbit: every block of CHUNK
 * samples is integrated, then pushed through the chain, each timed on its own, over
 * `runs` runs of nsamp samples. The RT factor is the median run's (of the totals per
 * run); the integrator and chain parts are their own medians. */
static void time_chain(afm_sim *s, const afm_config *cfg0, const afm_modal *m, long nsamp, int runs,
                       bench_result *res) {
    afm_config cfg = *cfg0;
    cfg.obd.enabled = true;
    cfg.obd.noise_density_m_rthz = CHAIN_NOISE_M_RTHZ;
    cfg.obd.adc_bits = CHAIN_ADC_BITS;
    cfg.obd.full_scale_m = CHAIN_FULL_SCALE_M;
    cfg.output.n_outputs = (int)(sizeof chain_decimation / sizeof chain_decimation[0]);
    memcpy(cfg.output.decimation, chain_decimation, sizeof chain_decimation);
    res->has_chain = true;
    afm_chain *c = afm_chain_create(&cfg, m, res->chain_note, sizeof res->chain_note);
    if (!c) return;
    if (afm_chain_attach(c, s, res->chain_note, sizeof res->chain_note) != 0) {
        afm_chain_destroy(&c);
        return;
    }
    double *ti = malloc((size_t)runs * sizeof *ti), *tc = malloc((size_t)runs * sizeof *tc);
    double *tt = malloc((size_t)runs * sizeof *tt);
    afm_chain_period per[64];
    afm_chain_block b;
    int rc = ti && tc && tt ? AFM_SIM_OK : AFM_SIM_EINVAL;
    /* run -1 is not timed: it touches the chain's rings and tables for the first time (the
     * daemon locks and touches its memory at start-up) */
    for (int k = -1; k < runs && rc == AFM_SIM_OK; k++) {
        double sum_i = 0, sum_c = 0;
        for (long done = 0; done < nsamp && rc == AFM_SIM_OK;) {
            int n = nsamp - done < CHUNK ? (int)(nsamp - done) : CHUNK;
            double t0 = now_s();
            rc = afm_sim_run(s, n, chunk);
            double t1 = now_s();
            afm_chain_push(c, chunk, n);
            /* drain as the daemon would (cheap: pointers into the rings; the period records
             * raw: the daemon finishes only the ones it publishes, by default 1 kHz of them,
             * afm_chain_period_finish ~0.5 us each) */
            for (int st = 0; st < afm_chain_n_streams(c); st++)
                while (afm_chain_take_block(c, st, &b, 0) > 0) {
                }
            while (afm_chain_take_periods_raw(c, per, 64) > 0) {
            }
            double t2 = now_s();
            sum_i += t1 - t0;
            sum_c += t2 - t1;
            done += n;
        }
        if (k < 0) continue;
        ti[k] = sum_i * 1e9 / (double)nsamp;
        tc[k] = sum_c * 1e9 / (double)nsamp;
        tt[k] = ti[k] + tc[k];
    }
    if (rc == AFM_SIM_OK) {
        qsort(ti, (size_t)runs, sizeof *ti, cmp_double);
        qsort(tc, (size_t)runs, sizeof *tc, cmp_double);
        qsort(tt, (size_t)runs, sizeof *tt, cmp_double);
        int h = runs / 2;
        res->chain_int_ns = runs % 2 ? ti[h] : 0.5 * (ti[h - 1] + ti[h]);
        res->chain_ns = runs % 2 ? tc[h] : 0.5 * (tc[h - 1] + tc[h]);
        res->chain_total_ns = runs % 2 ? tt[h] : 0.5 * (tt[h - 1] + tt[h]);
        res->chain_fastest_ns = tt[0];
        res->chain_runs = runs;
        res->chain_rt_factor = afm_sim_dt(s) / (res->chain_total_ns * 1e-9);
        res->chain_overhead_pct = 100.0 * res->chain_ns / res->chain_int_ns;
        afm_chain_stats st = afm_chain_stats_get(c);
        snprintf(res->chain_note, sizeof res->chain_note,
                 "%lld periods estimated, %lld ADC clamps, %lld non-finite", st.periods,
                 st.obd_saturated, st.nonfinite);
        res->chain_ok = st.periods > 0;
    } else {
        snprintf(res->chain_note, sizeof res->chain_note, "integrator: %s", rc_text(rc));
    }
    free(ti);
    free(tc);
    free(tt);
    afm_chain_destroy(&c);
}

/* One model's runs: its config (the tones' phases set to the settled state's), model and
 * forces, the settled state every run starts from, the compared window and the simulators
 * kept for timing. */
typedef struct {
    afm_config cfg;
    afm_modal m;
    afm_force_params f;
    double q0[AFM_MAX_MODES], qd0[AFM_MAX_MODES]; /* settled modal state (m, m/s) */
    long n_cmp;                                   /* samples each compared run takes */
    long win, from;        /* samples in one period; first sample of the compared last one */
    double *xr, *fr;       /* the reference's tip deflection (m) and force (N) */
    double *x;             /* the run compared with it (m) */
    afm_sim *sims[N_ROWS]; /* kept for the timing */
    char *err;
    size_t errlen;
} bench_run;

/* 1. Settle with rt for settle_tau slowest decay times 1 / (xi_i w_i) (res->settle_s); the
 * settled state into b->q0, b->qd0 and the tones' phases into b->cfg, so that every later
 * simulator starts at t = 0 where this one stopped. 0, or -1 with b->err. */
static int bench_settle(const bench_opts *o, bench_run *b, bench_result *res) {
    double tau = 0.0;
    for (int i = 0; i < b->m.n; i++)
        tau = fmax(tau, 1.0 / (b->m.xi[i] * b->m.omega_rad_s[i]));
    long n_settle = (long)ceil(o->settle_tau * tau * res->rate_hz);
    afm_sim *s =
        make_sim(&b->cfg, &b->m, &b->f, AFM_INTEGRATOR_RT, 0, 0, NULL, NULL, b->err, b->errlen);
    if (!s) return -1;
    int rc = run_collect(s, n_settle, NULL, NULL);
    if (rc != AFM_SIM_OK) {
        snprintf(b->err, b->errlen, "settling with rt: %s", rc_text(rc));
        afm_sim_destroy(&s);
        return -1;
    }
    res->settle_s = afm_sim_time(s);
    afm_sim_get_state(s, b->q0, b->qd0);
    const afm_drive *d = afm_sim_drive(s);
    for (int j = 0; j < d->n && j < b->cfg.drive.n_tones; j++)
        b->cfg.drive.tones[j].phase_rad = afm_drive_phase_mod(d, j, afm_sim_time(s));
    afm_sim_destroy(&s);
    return 0;
}

/* The compared window: K periods run, the last one compared; buffers for it. 0, or -1. */
static int bench_window(const bench_opts *o, bench_run *b, const bench_result *res) {
    double period_samples = res->rate_hz / res->freq_hz;
    b->win = (long)ceil(period_samples);
    b->n_cmp = (long)ceil(o->periods * period_samples);
    b->from = b->n_cmp - b->win;
    b->xr = malloc((size_t)b->n_cmp * sizeof *b->xr);
    b->x = malloc((size_t)b->n_cmp * sizeof *b->x);
    b->fr = malloc((size_t)b->n_cmp * sizeof *b->fr);
    if (b->xr && b->x && b->fr) return 0;
    snprintf(b->err, b->errlen, "out of memory");
    return -1;
}

/* 2. Reference: CVODE over the window (b->xr, b->fr), the orbit's amplitude, contact
 * fraction and peak force from its last period, and a check of the reference itself
 * against a 100x tighter tolerance. 0, or -1 with b->err. */
static int bench_reference(bench_run *b, bench_result *res) {
    afm_sim *ref = make_sim(&b->cfg, &b->m, &b->f, AFM_INTEGRATOR_REFERENCE, 0, 0, b->q0, b->qd0,
                            b->err, b->errlen);
    if (!ref) return -1;
    int rc = run_collect(ref, b->n_cmp, b->xr, b->fr);
    if (rc != AFM_SIM_OK) {
        snprintf(b->err, b->errlen, "reference run: %s", rc_text(rc));
        afm_sim_destroy(&ref);
        return -1;
    }
    double xmin = INFINITY, xmax = -INFINITY, xc = afm_force_contact_x(&b->f, res->z_m);
    long n_contact = 0;
    res->peak_force_n = -INFINITY;
    for (long i = b->from; i < b->n_cmp; i++) {
        xmin = fmin(xmin, b->xr[i]);
        xmax = fmax(xmax, b->xr[i]);
        n_contact += b->f.vdw_contact && b->xr[i] < xc;
        res->peak_force_n = fmax(res->peak_force_n, b->fr[i]);
    }
    res->tip_amp_m = 0.5 * (xmax - xmin);
    res->contact_fraction = (double)n_contact / (double)b->win;
    if (!(res->tip_amp_m > 0)) {
        snprintf(b->err, b->errlen, "the reference orbit does not move");
        afm_sim_destroy(&ref);
        return -1;
    }
    b->sims[ROW_REF] = ref;
    res->row[ROW_REF].ok = true;
    res->row[ROW_REF].substeps = -1;
    res->row[ROW_REF].err_rel = 0.0;

    afm_sim *tight = make_sim(&b->cfg, &b->m, &b->f, AFM_INTEGRATOR_REFERENCE, 0,
                              res->ref_rtol / 100, b->q0, b->qd0, b->err, b->errlen);
    if (!tight) return -1;
    rc = run_collect(tight, b->n_cmp, b->x, NULL);
    afm_sim_destroy(&tight);
    res->ref_check =
        rc == AFM_SIM_OK ? err_rel(b->x, b->xr, b->from, b->n_cmp, res->tip_amp_m) : NAN;
    snprintf(res->row[ROW_REF].note, sizeof res->row[ROW_REF].note,
             "CVODE BDF rtol %.0e; vs rtol %.0e: %.2e", res->ref_rtol, res->ref_rtol / 100,
             res->ref_check);
    return 0;
}

/* 3. rt from the same state, its error against the reference. 0, or -1 (no simulator). */
static int bench_rt(bench_run *b, bench_result *res) {
    bench_row *rr = &res->row[ROW_RT];
    rr->substeps = b->cfg.sim.rt_substeps_contact;
    b->sims[ROW_RT] =
        make_sim(&b->cfg, &b->m, &b->f, AFM_INTEGRATOR_RT, 0, 0, b->q0, b->qd0, b->err, b->errlen);
    if (!b->sims[ROW_RT]) return -1;
    int rc = run_collect(b->sims[ROW_RT], b->n_cmp, b->x, NULL);
    if (rc == AFM_SIM_OK) {
        rr->ok = true;
        rr->err_rel = err_rel(b->x, b->xr, b->from, b->n_cmp, res->tip_amp_m);
    } else {
        snprintf(rr->note, sizeof rr->note, "%s", rc_text(rc));
        afm_sim_destroy(&b->sims[ROW_RT]);
    }
    /* the fast scheme from the same state */
    bench_row *rf = &res->row[ROW_RT_FAST];
    rf->substeps = b->cfg.sim.rt_substeps_contact;
    afm_config cf = b->cfg;
    cf.sim.rt_scheme = AFM_RT_SCHEME_FAST;
    b->sims[ROW_RT_FAST] =
        make_sim(&cf, &b->m, &b->f, AFM_INTEGRATOR_RT, 0, 0, b->q0, b->qd0, b->err, b->errlen);
    if (!b->sims[ROW_RT_FAST]) return -1;
    rc = run_collect(b->sims[ROW_RT_FAST], b->n_cmp, b->x, NULL);
    if (rc == AFM_SIM_OK) {
        rf->ok = true;
        rf->err_rel = err_rel(b->x, b->xr, b->from, b->n_cmp, res->tip_amp_m);
    } else {
        snprintf(rf->note, sizeof rf->note, "%s", rc_text(rc));
        afm_sim_destroy(&b->sims[ROW_RT_FAST]);
    }
    return 0;
}

/* 4. ERK: the fewest substeps (of erk_substeps) whose error is at most rt's. 0, or -1. */
static int bench_erk(bench_run *b, bench_result *res) {
    const bench_row *rr = &res->row[ROW_RT];
    bench_row *re = &res->row[ROW_ERK];
    double best = INFINITY;
    int best_sub = 0;
    for (int c = 0; c < N_ERK_SUBSTEPS && rr->ok; c++) {
        afm_sim *e = make_sim(&b->cfg, &b->m, &b->f, AFM_INTEGRATOR_ARKODE_ERK, erk_substeps[c], 0,
                              b->q0, b->qd0, b->err, b->errlen);
        if (!e) return -1;
        int rc = run_collect(e, b->n_cmp, b->x, NULL);
        double er =
            rc == AFM_SIM_OK ? err_rel(b->x, b->xr, b->from, b->n_cmp, res->tip_amp_m) : INFINITY;
        if (er < best) {
            best = er;
            best_sub = erk_substeps[c];
        }
        if (er <= rr->err_rel) {
            b->sims[ROW_ERK] = e;
            re->ok = true;
            re->substeps = erk_substeps[c];
            re->err_rel = er;
            break;
        }
        afm_sim_destroy(&e);
    }
    if (!rr->ok)
        snprintf(re->note, sizeof re->note, "skipped: rt failed");
    else if (!re->ok)
        snprintf(re->note, sizeof re->note,
                 "never as accurate as rt up to %d substeps (best %.2e at %d)",
                 erk_substeps[N_ERK_SUBSTEPS - 1], best, best_sub);
    return 0;
}

/* 5. Timing on the running orbits, and the output chain's cost behind rt. */
static void bench_timing(const bench_opts *o, const bench_case *bc, bench_run *b,
                         bench_result *res) {
    for (int r = 0; r < N_ROWS; r++) {
        if (!b->sims[r]) continue;
        int rc = time_runs(b->sims[r], o->n_time[r], o->runs, &res->row[r]);
        if (rc != AFM_SIM_OK) {
            res->row[r].ok = false;
            snprintf(res->row[r].note, sizeof res->row[r].note, "timing: %s", rc_text(rc));
        }
    }
    if (bc->chain && b->sims[ROW_RT_FAST] && res->row[ROW_RT_FAST].ok)
        /* more runs than the integrator rows: the one-core verdict should not hang on a
         * burst of load from elsewhere on this shared machine. Behind the fast scheme: the
         * one the daemon runs here (afmtwin bench-scheme) */
        time_chain(b->sims[ROW_RT_FAST], &b->cfg, &b->m, o->n_time[ROW_RT_FAST], 4 * o->runs + 1,
                   res);
}

/* Everything for one model (steps 1-5 above); fills res. Returns 0, or -1 with res->err. */
static int bench_one(const bench_opts *o, const bench_case *bc, bench_result *res) {
    bench_run b = {.err = res->err, .errlen = sizeof res->err};
    memset(res, 0, sizeof *res);
    res->config = bc->file;
    for (int r = 0; r < N_ROWS; r++) {
        res->row[r].err_rel = res->row[r].ns_med = res->row[r].ns_min = NAN;
        res->row[r].rt_factor = NAN;
    }
    if (load_case(o, bc, &b.cfg, &b.m, &b.f, b.err, b.errlen) != 0) return -1;
    res->n_modes = b.m.n;
    res->z_m = b.cfg.drive.separation_m;
    res->amp_m = b.cfg.drive.tones[0].amplitude_m;
    res->freq_hz = b.cfg.drive.tones[0].frequency_hz;
    res->free_amp_m = res->amp_m * linear_gain(&b.m, two_pi * res->freq_hz);
    res->rate_hz = b.cfg.sim.sample_rate_hz;
    res->ref_rtol = b.cfg.sim.ref_rtol > 0 ? b.cfg.sim.ref_rtol : 1e-10;

    int rc = -1;
    if (bench_settle(o, &b, res) == 0 && bench_window(o, &b, res) == 0 &&
        bench_reference(&b, res) == 0 && bench_rt(&b, res) == 0 && bench_erk(&b, res) == 0) {
        bench_timing(o, bc, &b, res);
        res->ok = true;
        rc = 0;
    }
    for (int r = 0; r < N_ROWS; r++)
        afm_sim_destroy(&b.sims[r]);
    free(b.xr);
    free(b.x);
    free(b.fr);
    return rc;
}

static double ratio_erk_rt(const bench_result *r) {
    const bench_row *a = &r->row[ROW_ERK], *b = &r->row[ROW_RT];
    return (a->ok && b->ok) ? a->ns_med / b->ns_med : NAN;
}

static void print_text(const bench_opts *o, const bench_result *res, int n) {
    printf("afmtwin bench: %d timed runs per integrator (median, min); every integrator starts "
           "from one rt-settled tapping state;\nerror_rel = max |x - x_cvode| / amplitude over "
           "excitation period %d of %d.\n",
           o->runs, o->periods, o->periods);
    for (int c = 0; c < n; c++) {
        const bench_result *r = &res[c];
        printf("\n%s", r->config);
        if (!r->ok) {
            printf(": FAILED: %s\n", r->err);
            continue;
        }
        printf(": %d modes, Z %.4g nm, base amplitude %.4g nm at %.6g kHz (free tip amplitude "
               "%.4g nm), settled %.3g ms\n",
               r->n_modes, r->z_m * 1e9, r->amp_m * 1e9, r->freq_hz * 1e-3, r->free_amp_m * 1e9,
               r->settle_s * 1e3);
        printf("  tip amplitude %.4g nm, in contact %.1f %% of the period, peak force %.4g nN; "
               "sample rate %.6g MHz (real time: %.1f ns per sample)\n",
               r->tip_amp_m * 1e9, 100 * r->contact_fraction, r->peak_force_n * 1e9,
               r->rate_hz * 1e-6, 1e9 / r->rate_hz);
        printf("  %-11s %9s %14s %14s %10s %10s\n", "integrator", "substeps", "ns/sample med",
               "ns/sample min", "RT factor", "error_rel");
        for (int k = 0; k < N_ROWS; k++) {
            const bench_row *w = &r->row[k];
            char sub[16];
            if (w->substeps < 0)
                snprintf(sub, sizeof sub, "adaptive");
            else if (w->substeps == 0)
                snprintf(sub, sizeof sub, "default");
            else
                snprintf(sub, sizeof sub, "%d", w->substeps);
            printf("  %-11s %9s %14.1f %14.1f %10.4g %10.2e", row_name[k], sub, w->ns_med,
                   w->ns_min, w->rt_factor, w->err_rel);
            if (w->note[0]) printf("  (%s)", w->note);
            printf("\n");
        }
        double q = ratio_erk_rt(r);
        if (isfinite(q))
            printf("  rt is %.1fx faster than arkode-erk at equal accuracy (%d substeps)\n", q,
                   r->row[ROW_ERK].substeps);
        if (r->has_chain) {
            printf("  chain (rt-fast + OBD %.0f fm/rtHz %d-bit +-%.0f nm, decimation 16 and 256, "
                   "harmonics/lock-in/cycle), same runs:\n",
                   CHAIN_NOISE_M_RTHZ * 1e15, CHAIN_ADC_BITS, CHAIN_FULL_SCALE_M * 1e9);
            if (r->chain_ok)
                printf(
                    "    integrator %.1f ns + chain %.1f ns (medians) = %.1f ns/sample (median of "
                    "%d runs; fastest %.1f), RT factor %.4g, chain overhead %.1f %% of the "
                    "integrator (%s)\n",
                    r->chain_int_ns, r->chain_ns, r->chain_total_ns, r->chain_runs,
                    r->chain_fastest_ns, r->chain_rt_factor, r->chain_overhead_pct, r->chain_note);
            else
                printf("    FAILED: %s\n", r->chain_note);
        }
    }
}

static int print_json(const bench_opts *o, const bench_result *res, int n) {
    cJSON *root = cJSON_CreateObject(), *cases = cJSON_CreateArray(), *ratios = cJSON_CreateArray();
    cJSON_AddNumberToObject(root, "runs", o->runs);
    cJSON_AddNumberToObject(root, "periods", o->periods);
    cJSON_AddBoolToObject(root, "quick", o->quick);
    for (int c = 0; c < n; c++) {
        const bench_result *r = &res[c];
        if (!r->ok) {
            cJSON *e = cJSON_CreateObject();
            cJSON_AddStringToObject(e, "config", r->config);
            cJSON_AddStringToObject(e, "error", r->err);
            cJSON_AddItemToArray(cases, e);
            continue;
        }
        for (int k = 0; k < N_ROWS; k++) {
            const bench_row *w = &r->row[k];
            cJSON *e = cJSON_CreateObject();
            cJSON_AddStringToObject(e, "config", r->config);
            cJSON_AddStringToObject(e, "integrator", row_name[k]);
            afmt_json_num(e, "ns_per_sample", w->ns_med);
            afmt_json_num(e, "ns_per_sample_min", w->ns_min);
            afmt_json_num(e, "realtime_factor", w->rt_factor);
            afmt_json_num(e, "error_rel", w->err_rel);
            if (w->substeps < 0)
                cJSON_AddNullToObject(e, "substeps"); /* adaptive */
            else
                cJSON_AddNumberToObject(e, "substeps", w->substeps); /* 0: engine default */
            cJSON_AddBoolToObject(e, "ok", w->ok);
            if (w->note[0]) cJSON_AddStringToObject(e, "note", w->note);
            cJSON_AddNumberToObject(e, "n_modes", r->n_modes);
            cJSON_AddNumberToObject(e, "sample_rate_hz", r->rate_hz);
            cJSON_AddNumberToObject(e, "separation_m", r->z_m);
            cJSON_AddNumberToObject(e, "drive_amplitude_m", r->amp_m);
            cJSON_AddNumberToObject(e, "drive_frequency_hz", r->freq_hz);
            cJSON_AddNumberToObject(e, "free_amplitude_m", r->free_amp_m);
            cJSON_AddNumberToObject(e, "tip_amplitude_m", r->tip_amp_m);
            cJSON_AddNumberToObject(e, "contact_fraction", r->contact_fraction);
            cJSON_AddNumberToObject(e, "peak_force_n", r->peak_force_n);
            cJSON_AddNumberToObject(e, "settle_s", r->settle_s);
            if (k == ROW_REF) {
                cJSON_AddNumberToObject(e, "rtol", r->ref_rtol);
                afmt_json_num(e, "error_rel_vs_rtol_div_100", r->ref_check);
            }
            cJSON_AddItemToArray(cases, e);
        }
        cJSON *q = cJSON_CreateObject();
        cJSON_AddStringToObject(q, "config", r->config);
        afmt_json_num(q, "arkode_over_rt_ns_per_sample", ratio_erk_rt(r));
        cJSON_AddNumberToObject(q, "arkode_substeps", r->row[ROW_ERK].substeps);
        cJSON_AddItemToArray(ratios, q);
        if (r->has_chain) {
            cJSON *ch = cJSON_CreateObject();
            cJSON_AddStringToObject(ch, "config", r->config);
            cJSON_AddStringToObject(ch, "integrator", "rt");
            cJSON_AddBoolToObject(ch, "ok", r->chain_ok);
            afmt_json_num(ch, "integrator_ns_per_sample", r->chain_int_ns);
            afmt_json_num(ch, "chain_ns_per_sample", r->chain_ns);
            afmt_json_num(ch, "ns_per_sample", r->chain_total_ns);
            afmt_json_num(ch, "fastest_ns_per_sample", r->chain_fastest_ns);
            cJSON_AddNumberToObject(ch, "runs", r->chain_runs);
            afmt_json_num(ch, "realtime_factor", r->chain_rt_factor);
            afmt_json_num(ch, "chain_overhead_pct", r->chain_overhead_pct);
            cJSON_AddNumberToObject(ch, "obd_noise_density_m_rthz", CHAIN_NOISE_M_RTHZ);
            cJSON_AddNumberToObject(ch, "obd_adc_bits", CHAIN_ADC_BITS);
            cJSON *dec = cJSON_AddArrayToObject(ch, "decimation");
            for (size_t i = 0; i < sizeof chain_decimation / sizeof chain_decimation[0]; i++)
                cJSON_AddItemToArray(dec, cJSON_CreateNumber(chain_decimation[i]));
            cJSON_AddBoolToObject(ch, "estimators", true);
            if (r->chain_note[0]) cJSON_AddStringToObject(ch, "note", r->chain_note);
            cJSON_AddItemToObject(root, "chain", ch);
        }
    }
    cJSON_AddItemToObject(root, "cases", cases);
    cJSON_AddItemToObject(root, "ratios", ratios);
    return afmt_json_emit(root) ? 1 : 0;
}

int afm_cmd_bench(int argc, char **argv) {
    bench_opts o = {.runs = 0, .periods = 5, .dir = "config"};
    const afmt_opt opts[] = {
        AFMT_FLAG("--json", &o.json),
        AFMT_FLAG("--quick", &o.quick),
        AFMT_INT("--runs", &o.runs, 1, 1000, NULL),
        AFMT_INT("--periods", &o.periods, 1, 1000, NULL),
        AFMT_STRING("--config-dir", &o.dir),
        AFMT_OPTS_END,
    };
    int prc = afmt_opts_parse("bench", opts, argc, argv, 1);
    if (prc == AFMT_OPTS_HELP) bench_usage(stdout);
    if (prc == AFMT_OPTS_BAD) bench_usage(stderr);
    if (prc) return prc == AFMT_OPTS_HELP ? 0 : 2;
    if (o.runs == 0) o.runs = o.quick ? 2 : 5;
    /* 40 decay times leave e^-40 of the start transient in the linear part. Timed blocks
     * are ~10-50 ms each at the costs numerics.md measured. */
    o.settle_tau = o.quick ? 20.0 : 40.0;
    long scale = o.quick ? 10 : 1;
    o.n_time[ROW_RT] = 100000 / scale;
    o.n_time[ROW_RT_FAST] = 100000 / scale;
    o.n_time[ROW_ERK] = 5000 / scale;
    o.n_time[ROW_REF] = 500 / scale;

    bench_result *res = calloc(N_CASES, sizeof *res);
    if (!res) {
        fprintf(stderr, "afmtwin bench: out of memory\n");
        return 1;
    }
    int failed = 0;
    for (int c = 0; c < N_CASES; c++) {
        if (bench_one(&o, &bench_cases[c], &res[c]) != 0) {
            failed++;
            if (o.json) /* the text table shows it in place */
                fprintf(stderr, "afmtwin bench: %s: %s\n", bench_cases[c].file, res[c].err);
        }
    }
    int rc = o.json ? print_json(&o, res, N_CASES) : (print_text(&o, res, N_CASES), 0);
    free(res);
    return (rc != 0 || failed) ? 1 : 0;
}
