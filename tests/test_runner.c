/* SPDX-License-Identifier: MIT */
/* test_runner.c -- the runner (afm_runner) the daemon and replay share:
 *  - determinism: two runners on default.conf get the same commands (setpoint ramp, dither
 *    change with a second tone, live force change, damping change with a model swap, pause,
 *    step, run, reset) at the same sample counts but run in different slice lengths
 *    (1000 vs 777 samples); every decimated sample of both streams, every period record and
 *    the final status must be bit-identical;
 *  - commands take effect: the ramp ends at its target at rate x time; seq_applied echoes;
 *    a rejected command (tick outside lockstep, damping without a model) changes nothing;
 *  - gating: paused runs advance only the STEP budget, lockstep only the tick budget;
 *  - blow-up: a lumped cantilever driven at resonance whose damping is then set to
 *    xi = 1e-9 grows without bound; the runner reports blow-ups, restarts from rest, and
 *    after AFM_RUNNER_BLOWUP_PAUSE of them pauses itself with the reason; drives past the
 *    plausibility limits are refused at create
 *    (samples advance as asked, outputs keep coming);
 *  - the integrator's per-step record (issue 28): on a tapping config with the accurate
 *    scheme the chain's period metrics are those of afm_cycle_push_ev fed directly with the
 *    simulator's records (and differ from the samples' path), through a Z ramp every sample
 *    keeps its own record whatever the slicing; with the fast scheme or sim.step_events =
 *    "off" the sample path as before;
 *  - am.control internal: a force param's model carries the new A0, the set-point follows. */
#include "runner/afm_a0.h"
#include "runner/afm_runner.h"
#include "check.h"
#include "estimators/afm_cycle.h"
#include "forces/afm_force.h"
#include "runner/afm_twin.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAXOUT 400000
#define PER (MAXOUT / AFM_MAX_OUTPUTS)

typedef struct {
    double *t, *x, *obd, *f;
    long n;                   /* all streams */
    long ns[AFM_MAX_OUTPUTS]; /* per stream: stream s fills [s * PER, s * PER + ns[s]) */
    afm_chain_period *per;
    long np;
    bool raw; /* take the period records raw and finish them one by one (as the daemon) */
} outlog;

static void log_init(outlog *o) {
    o->t = calloc(MAXOUT, sizeof(double));
    o->x = calloc(MAXOUT, sizeof(double));
    o->obd = calloc(MAXOUT, sizeof(double));
    o->f = calloc(MAXOUT, sizeof(double));
    o->per = calloc(20000, sizeof *o->per);
    o->n = o->np = 0;
    o->raw = false;
    memset(o->ns, 0, sizeof o->ns);
}

static void log_free(outlog *o) {
    free(o->t);
    free(o->x);
    free(o->obd);
    free(o->f);
    free(o->per);
}

static void drain(afm_runner *r, outlog *o) {
    for (int s = 0; s < afm_runner_n_streams(r); s++) {
        afm_chain_block b;
        while (afm_runner_take_block(r, s, &b, 0) > 0)
            for (int i = 0; i < b.n && o->ns[s] < PER; i++, o->n++) {
                long w = (long)s * PER + o->ns[s]++;
                o->t[w] = b.t_s[i];
                o->x[w] = b.x_m[i];
                o->obd[w] = b.obd_m[i];
                o->f[w] = b.f_n[i];
            }
    }
    afm_chain_period p[64];
    int n;
    while ((n = o->raw ? afm_runner_take_periods_raw(r, p, 64)
                       : afm_runner_take_periods(r, p, 64)) > 0)
        for (int i = 0; i < n && o->np < 20000; i++) {
            if (o->raw) afm_runner_period_finish(r, &p[i]);
            o->per[o->np++] = p[i];
        }
}

static int lookup(const char *name, int *e, int *i) {
    char err[AFM_ERR_LEN];
    return afm_param_lookup(name, e, i, err, sizeof err);
}

/* The script: command k applied when the runner has advanced at[k] samples. */
#define N_CMDS 9
static const long long at[N_CMDS] = {10000, 30000, 45000, 60000, 80000,
                                     80000, 80000, 90000, 110000};
static const long long total = 140000;

static afm_cmd script(int k, const afm_config *cfg0, afm_config *shadow, afm_runner_model **m) {
    afm_cmd c = {.seq = 100 + k};
    *m = NULL;
    int e, i;
    switch (k) {
    case 0: /* ramp Z 40 -> 30 nm at 1e-4 m/s: 100 us = 1406 samples */
        c.kind = AFM_CMD_SETPOINT;
        c.u.setpoint = (afm_cmd_setpoint){30e-9, 1e-4};
        break;
    case 1: /* tone 0 up 2 kHz, tone 1 starts at 1 MHz with phase 0.3 */
        c.kind = AFM_CMD_DITHER;
        c.u.dither = (afm_cmd_dither){2, {340112, 1e6}, {0.09e-9, 0.01e-9}, {0, 0.3}};
        break;
    case 2: /* live force change */
        c.kind = AFM_CMD_PARAM;
        lookup("forces.viscoelastic.eta_pa_s", &e, &i);
        c.u.param = (afm_cmd_param){1, {e}, {i}, {400.0}};
        break;
    case 3: /* damping: a model built "off the RT thread" from the shadow config */
        c.kind = AFM_CMD_PARAM;
        lookup("model.damping_ratio[0]", &e, &i);
        c.u.param = (afm_cmd_param){1, {e}, {i}, {0.002}};
        break;
    case 4:
        c.kind = AFM_CMD_CONTROL;
        c.u.control = (afm_cmd_control){AFM_CTL_PAUSE, 0};
        break;
    case 5:
        c.kind = AFM_CMD_CONTROL;
        c.u.control = (afm_cmd_control){AFM_CTL_STEP, 5000};
        break;
    case 6:
        c.kind = AFM_CMD_CONTROL;
        c.u.control = (afm_cmd_control){AFM_CTL_STEP, 5000};
        break;
    case 7:
        c.kind = AFM_CMD_CONTROL;
        c.u.control = (afm_cmd_control){AFM_CTL_RUN, 0};
        break;
    case 8:
        c.kind = AFM_CMD_CONTROL;
        c.u.control = (afm_cmd_control){AFM_CTL_RESET, 0};
        break;
    }
    (void)cfg0;
    if (c.kind == AFM_CMD_PARAM) {
        char err[AFM_ERR_LEN];
        afm_param_effect eff;
        afm_param_apply(shadow, &c.u.param, &eff, err, sizeof err);
        bool nc;
        if (afm_runner_cmd_needs_model(shadow, &c, &nc) || eff >= AFM_PARAM_DAMPING)
            *m = afm_runner_model_build(shadow, eff == AFM_PARAM_GEOMETRY, err, sizeof err);
    }
    return c;
}

/* Run the script in slices of `slice` samples; returns the final status. */
/* ring > 0: pipelined with a ring of that many items, the chain stage run here after each
 * slice (and whenever the integrator stage stalls on a full ring). */
static afm_runner_status play(const afm_config *cfg, long long slice, outlog *o, int *apply_fail,
                              int ring) {
    char err[AFM_ERR_LEN];
    afm_runner *r = ring > 0
                        ? afm_runner_create_pipelined(cfg, 4096, false, true, ring, err, sizeof err)
                        : afm_runner_create(cfg, 4096, false, err, sizeof err);
    afm_config shadow = *cfg;
    afm_runner_status st;
    *apply_fail = 0;
    int k = 0;
    long long done = 0;
    while (done < total || k < N_CMDS) {
        while (k < N_CMDS && at[k] <= done) {
            afm_runner_model *m;
            afm_cmd c = script(k, cfg, &shadow, &m);
            if (afm_runner_apply(r, &c, m ? &m : NULL, err, sizeof err)) {
                printf("  apply %d: %s\n", k, err);
                (*apply_fail)++;
            }
            afm_runner_model_destroy(&m);
            k++;
        }
        long long n = slice;
        if (k < N_CMDS && at[k] - done < n) n = at[k] - done;
        if (total - done < n) n = total - done;
        if (n <= 0 && k >= N_CMDS) break;
        long long adv = afm_runner_run(r, n);
        while (ring > 0 && adv < n && afm_runner_budget(r) > 0) { /* stalled: chain behind */
            while (afm_runner_chain_run(r, 0) > 0)
                drain(r, o);
            adv += afm_runner_run(r, n - adv);
        }
        if (ring > 0) {
            afm_runner_model *t;
            while (afm_runner_chain_run(r, 0) > 0)
                drain(r, o);
            while (afm_runner_take_trash(r, &t))
                afm_runner_model_destroy(&t);
        }
        if (adv == 0) { /* paused with no budget: nothing to wait for in a test */
            if (k < N_CMDS)
                done = at[k];
            else
                break;
        }
        done += adv;
        drain(r, o);
    }
    afm_runner_status_get(r, &st);
    afm_runner_destroy(&r);
    return st;
}

static void test_determinism(const afm_config *cfg) {
    outlog a, b;
    log_init(&a);
    log_init(&b);
    int fa, fb;
    b.raw = true; /* also checks afm_chain_period_finish against afm_chain_take_periods */
    afm_runner_status sa = play(cfg, 1000, &a, &fa, 0);
    afm_runner_status sb = play(cfg, 777, &b, &fb, 0);
    check_true(fa == 0 && fb == 0, "every scripted command applied");
    printf("  %ld decimated samples, %ld periods; model time %.6f s, %lld samples\n", a.n, a.np,
           sa.t_s, sa.samples);
    check_true(a.n > 5000 && a.np > 1000, "outputs produced");
    bool same = a.n == b.n && !memcmp(a.ns, b.ns, sizeof a.ns);
    for (int s = 0; s < AFM_MAX_OUTPUTS; s++)
        for (long i = (long)s * PER; same && i < (long)s * PER + a.ns[s]; i++)
            same = a.t[i] == b.t[i] && a.x[i] == b.x[i] && a.obd[i] == b.obd[i] && a.f[i] == b.f[i];
    check_true(same, "slices 1000 vs 777: every decimated sample bit-identical");
    same = a.np == b.np && memcmp(a.per, b.per, (size_t)a.np * sizeof *a.per) == 0;
    check_true(same, "slices 1000 vs 777 (records taken raw, finished one by one): every period "
                     "record bit-identical");
    check_true(sa.t_s == sb.t_s && sa.samples == sb.samples && sa.seq_applied == sb.seq_applied &&
                   sa.separation_m == sb.separation_m && sa.swaps == sb.swaps,
               "final status identical");
    check_true(sa.seq_applied == 108 && sa.applied == N_CMDS,
               "seq_applied echoes the last command (108)");
    check_true(sa.separation_m == 30e-9, "Z ramp ended exactly at the target 30 nm");
    check_true(sa.swaps == 1, "the damping change swapped one model in");
    check_rel(sa.fe_hz, 340112, 1e-12, "tone 0 frequency after the dither command");
    /* paused at 80000 with 2 x 5000 steps, run again from 90000: 140000 - 0 samples asked,
     * 10000 of them while paused */
    check_true(sa.samples == total, "samples advanced = asked (steps included)");
    /* The daemon's two-stage form: the same script through the ring (4 items, so that the
     * integrator stalls on a full ring again and again) gives the same bits. */
    outlog c;
    log_init(&c);
    int fc;
    afm_runner_status sc = play(cfg, 5000, &c, &fc, 4); /* 5000 > 4 x 1024 */
    check_true(fc == 0, "pipelined: every scripted command applied");
    same = a.n == c.n && !memcmp(a.ns, c.ns, sizeof a.ns);
    for (int s = 0; s < AFM_MAX_OUTPUTS; s++)
        for (long i = (long)s * PER; same && i < (long)s * PER + a.ns[s]; i++)
            same = a.t[i] == c.t[i] && a.x[i] == c.x[i] && a.obd[i] == c.obd[i] && a.f[i] == c.f[i];
    check_true(same, "pipelined (ring of 4) vs inline: every decimated sample bit-identical");
    same = a.np == c.np && memcmp(a.per, c.per, (size_t)a.np * sizeof *a.per) == 0;
    check_true(same, "pipelined vs inline: every period record bit-identical");
    check_true(sc.t_s == sa.t_s && sc.samples == sa.samples && sc.seq_applied == sa.seq_applied &&
                   sc.swaps == sa.swaps && sc.stalls > 0,
               "pipelined: same final status; the integrator stalled on the full ring");
    printf("  pipelined: %lld stalls on the 4-item ring\n", sc.stalls);
    log_free(&c);
    log_free(&a);
    log_free(&b);
}

/* A reload keeps seq_applied (it is no sender's command). */
static void test_reload_keeps_seq(const afm_config *cfg) {
    char err[AFM_ERR_LEN];
    afm_runner *r = afm_runner_create(cfg, 2048, false, err, sizeof err);
    afm_cmd c = {.kind = AFM_CMD_SETPOINT, .seq = 42, .u.setpoint = {30e-9, 0}};
    afm_runner_apply(r, &c, NULL, err, sizeof err);
    afm_runner_run(r, 1000);
    afm_runner_model *m = afm_runner_model_build(cfg, true, err, sizeof err);
    afm_cmd rl = {.kind = AFM_CMD_RELOAD, .seq = -1};
    int rc = afm_runner_apply(r, &rl, &m, err, sizeof err);
    afm_runner_model_destroy(&m);
    afm_runner_run(r, 1000);
    afm_runner_status st;
    afm_runner_status_get(r, &st);
    check_true(rc == 0 && st.seq_applied == 42 && st.swaps == 1,
               "reload applied, seq_applied still 42 (not the reload's -1)");
    check_true(st.separation_m == cfg->drive.separation_m, "reload: Z from the new config");
    afm_runner_destroy(&r);
}

static void test_ramp_and_rejects(const afm_config *cfg) {
    char err[AFM_ERR_LEN];
    afm_runner *r = afm_runner_create(cfg, 2048, false, err, sizeof err);
    afm_runner_status st;
    afm_cmd c = {.kind = AFM_CMD_SETPOINT, .seq = 5, .u.setpoint = {30e-9, 1e-4}};
    afm_runner_apply(r, &c, NULL, err, sizeof err);
    /* 50 us at 1e-4 m/s = 5 nm; Z moves every 64 samples (4.55 us) */
    afm_runner_run(r, 703);
    afm_runner_status_get(r, &st);
    check_abs(st.separation_m, 35e-9, 1e-4 * 64 / 14.06e6 + 1e-15,
              "ramp after 703 samples (50 us): Z = 35 nm within one 64-sample step");
    afm_runner_run(r, 2000);
    afm_runner_status_get(r, &st);
    check_true(st.separation_m == 30e-9 && st.separation_target_m == 30e-9, "ramp stops at 30 nm");
    afm_runner_status before = st;
    afm_cmd t = {.kind = AFM_CMD_TICK, .seq = 6, .u.tick = {100}};
    int rc = afm_runner_apply(r, &t, NULL, err, sizeof err);
    printf("  tick outside lockstep: %s\n", err);
    afm_runner_status_get(r, &st);
    check_true(rc == -1 && st.seq_applied == 5 && st.tick_budget == 0,
               "tick outside lockstep rejected, nothing changed");
    int e, i;
    lookup("model.damping_ratio[0]", &e, &i);
    afm_cmd p = {.kind = AFM_CMD_PARAM, .seq = 7, .u.param = {1, {e}, {i}, {0.01}}};
    rc = afm_runner_apply(r, &p, NULL, err, sizeof err);
    printf("  damping without a model: %s\n", err);
    afm_runner_status_get(r, &st);
    check_true(rc == -1 && st.seq_applied == 5 &&
                   afm_runner_config(r)->model.damping_ratio[0] == 0.0012,
               "damping change without a model rejected, config unchanged");
    afm_cmd bad = {.kind = AFM_CMD_SETPOINT, .seq = 8, .u.setpoint = {NAN, 0}};
    rc = afm_runner_apply(r, &bad, NULL, err, sizeof err);
    afm_runner_status_get(r, &st);
    check_true(rc == -1 && st.seq_applied == 5 && st.separation_m == before.separation_m,
               "NaN setpoint rejected by the runner too");
    /* geometry: new model with chain, starts at rest, model time continues */
    lookup("model.beam.length_m", &e, &i);
    afm_cmd g = {.kind = AFM_CMD_PARAM, .seq = 9, .u.param = {1, {e}, {i}, {120e-6}}};
    afm_config sh = *afm_runner_config(r);
    afm_param_effect eff;
    afm_param_apply(&sh, &g.u.param, &eff, err, sizeof err);
    bool nc = false;
    check_true(afm_runner_cmd_needs_model(afm_runner_config(r), &g, &nc) == 1 && nc,
               "a length change needs a model with a new chain");
    afm_runner_model *m = afm_runner_model_build(&sh, nc, err, sizeof err);
    double t0 = st.t_s;
    rc = afm_runner_apply(r, &g, &m, err, sizeof err);
    afm_runner_model_destroy(&m);
    afm_runner_status_get(r, &st);
    check_true(rc == 0 && st.t_s == t0 && st.seq_applied == 9 &&
                   afm_runner_config(r)->model.beam.length_m == 120e-6 && st.separation_m == 30e-9,
               "geometry swap: applied, model time and Z kept");
    check_true(afm_runner_run(r, 20000) == 20000, "runs on after the geometry swap");
    afm_runner_destroy(&r);
}

static void test_gating(const afm_config *cfg) {
    char err[AFM_ERR_LEN];
    afm_runner *r = afm_runner_create(cfg, 2048, true, err, sizeof err);
    check_true(afm_runner_run(r, 1000) == 0, "lockstep without ticks: nothing runs");
    afm_cmd t = {.kind = AFM_CMD_TICK, .seq = 1, .u.tick = {1500}};
    afm_runner_apply(r, &t, NULL, err, sizeof err);
    long long a = afm_runner_run(r, 1000), b = afm_runner_run(r, 1000), c = afm_runner_run(r, 1000);
    check_true(a == 1000 && b == 500 && c == 0, "tick 1500: runs 1000, 500, then waits");
    afm_cmd p = {.kind = AFM_CMD_CONTROL, .seq = 2, .u.control = {AFM_CTL_STEP, 300}};
    afm_runner_apply(r, &p, NULL, err, sizeof err);
    check_true(afm_runner_run(r, 1000) == 300 && afm_runner_run(r, 1000) == 0,
               "step 300 while paused: exactly 300 samples");
    afm_runner_destroy(&r);
}

/* Completions (afm_runner_take_done): one when a tick or step budget is used up, after its
 * samples, naming the last tick or step command and the samples run; ticks sent together
 * complete together; pipelined, the chain stage stops right after the marker. */
static void test_done(const afm_config *cfg) {
    char err[AFM_ERR_LEN];
    for (int pipelined = 0; pipelined < 2; pipelined++) {
        afm_runner *r =
            afm_runner_create_pipelined(cfg, 2048, true, pipelined, 16, err, sizeof err);
        afm_runner_done d = {0};
        long long got[5] = {-1, -1, -1, -1, -1}, where[5] = {0}, n = 0;
        afm_cmd t = {.kind = AFM_CMD_TICK, .seq = 7, .u.tick = {5000}};
        afm_runner_apply(r, &t, NULL, err, sizeof err);
        for (int k = 0; k < 4; k++) /* 4000 samples: not done yet */
            afm_runner_run(r, 1000);
        while (pipelined && afm_runner_chain_run(r, 0) > 0) {
        }
        bool early = afm_runner_take_done(r, &d);
        afm_runner_run(r, 5000);
        while (pipelined && afm_runner_chain_run(r, 0) > 0) {
        }
        if (afm_runner_take_done(r, &d)) got[n] = d.seq, where[n++] = d.samples;
        t.seq = 8;
        t.u.tick.n_samples = 3000;
        afm_runner_apply(r, &t, NULL, err, sizeof err);
        t.seq = 9;
        t.u.tick.n_samples = 2000;
        afm_runner_apply(r, &t, NULL, err, sizeof err);
        afm_runner_run(r, 100000);
        while (pipelined && afm_runner_chain_run(r, 0) > 0) {
        }
        if (afm_runner_take_done(r, &d)) got[n] = d.seq, where[n++] = d.samples;
        afm_cmd p = {.kind = AFM_CMD_CONTROL, .seq = 10, .u.control = {AFM_CTL_STEP, 300}};
        afm_runner_apply(r, &p, NULL, err, sizeof err);
        afm_runner_run(r, 1000);
        while (pipelined && afm_runner_chain_run(r, 0) > 0) {
        }
        if (afm_runner_take_done(r, &d)) got[n] = d.seq, where[n++] = d.samples;
        t.seq = 11; /* a tick while paused: runs, and completes, after RUN */
        t.u.tick.n_samples = 2000;
        afm_runner_apply(r, &t, NULL, err, sizeof err);
        long long none = afm_runner_run(r, 1000);
        afm_cmd run = {.kind = AFM_CMD_CONTROL, .seq = 12, .u.control = {AFM_CTL_RUN, 0}};
        afm_runner_apply(r, &run, NULL, err, sizeof err);
        afm_runner_run(r, 5000);
        while (pipelined && afm_runner_chain_run(r, 0) > 0) {
        }
        if (afm_runner_take_done(r, &d)) got[n] = d.seq, where[n++] = d.samples;
        bool again = afm_runner_take_done(r, &d);
        char what[160];
        snprintf(what, sizeof what,
                 "%s: completions tick 7 at 5000, ticks 8+9 at 10000, step 10 at 10300, tick 11 "
                 "(sent paused) after RUN at 12300, none early or twice",
                 pipelined ? "pipelined" : "inline");
        check_true(!early && !again && n == 4 && got[0] == 7 && where[0] == 5000 && got[1] == 9 &&
                       where[1] == 10000 && got[2] == 10 && where[2] == 10300 && none == 0 &&
                       got[3] == 11 && where[3] == 12300,
                   what);
        afm_runner_destroy(&r);
    }
}

/* Tones a dither command leaves out stop (removed from the drive: the integrator's cost
 * follows the tone count); naming one again starts it at the command's phase. */
static void test_tones_stop(const afm_config *cfg) {
    char err[AFM_ERR_LEN];
    afm_runner *r = afm_runner_create(cfg, 2048, false, err, sizeof err);
    afm_cmd c = {.kind = AFM_CMD_DITHER, .seq = 1};
    c.u.dither = (afm_cmd_dither){3, {338112, 1e6, 2e6}, {0.087e-9, 1e-11, 1e-11}, {0, 0, 0}};
    afm_runner_apply(r, &c, NULL, err, sizeof err);
    afm_runner_run(r, 3000);
    int n3 = afm_sim_drive(afm_runner_sim(r))->n;
    c.seq = 2;
    c.u.dither = (afm_cmd_dither){1, {338500}, {0.087e-9}, {0}};
    afm_runner_apply(r, &c, NULL, err, sizeof err);
    afm_runner_run(r, 3000);
    int n1 = afm_sim_drive(afm_runner_sim(r))->n;
    c.seq = 3;
    c.u.dither = (afm_cmd_dither){2, {338500, 1e6}, {0.087e-9, 1e-11}, {0, 0.7}};
    afm_runner_apply(r, &c, NULL, err, sizeof err);
    const afm_drive *d = afm_sim_drive(afm_runner_sim(r));
    afm_runner_status st;
    afm_runner_status_get(r, &st);
    check_true(n3 == 3 && n1 == 1 && d->n == 2 && fabs(d->phase_rad[1] - 0.7) < 1e-12 &&
                   d->t0_s[1] == st.t_s,
               "dither: tones left out stop (3 -> 1 tone), a tone named again starts at its phase");
    afm_runner_destroy(&r);
}

static void test_blowup(void) {
    afm_config cfg;
    char err[AFM_ERR_LEN];
    if (afm_config_load("config/thesis-1dof.conf", &cfg, err, sizeof err)) {
        check_true(false, err);
        return;
    }
    /* No contact, 0.5 um at resonance with Q = 100: a free amplitude of 50 um, within the
     * plausibility limit (100 um), so the runner takes it. */
    cfg.drive.separation_m = 1e-3;
    cfg.drive.tones[0].amplitude_m = 0.5e-6;
    afm_runner *r = afm_runner_create(&cfg, 4096, false, err, sizeof err);
    if (!r) {
        check_true(false, err);
        return;
    }
    afm_config big = cfg;
    big.drive.tones[0].amplitude_m = 1.05e-6; /* past the 1 um tone limit */
    afm_runner *r2 = afm_runner_create(&big, 4096, false, err, sizeof err);
    check_true(!r2 && strstr(err, "amplitude"), "create: a tone past 1 um refused");
    big.drive.tones[0].amplitude_m = 1e-6; /* at resonance, Q = 100: 100.5 um free */
    big.model.damping_ratio[0] = 0.004;
    r2 = afm_runner_create(&big, 4096, false, err, sizeof err);
    char name[AFM_ERR_LEN + 64];
    snprintf(name, sizeof name, "create: a drive predicting 125 um of free amplitude refused (%s)",
             r2 ? "created" : err);
    check_true(!r2 && strstr(err, "free tip"), name);
    afm_runner_destroy(&r2);
    /* Then the damping goes (xi 1e-9, Q 5e8: a limit no single command can see): |x| grows
     * by ~pi A per period and passes the 1 mm runaway bound after ~640 periods (~2 ms),
     * again and again: after AFM_RUNNER_BLOWUP_PAUSE of them the twin pauses itself. */
    afm_config t = cfg;
    int ent, idx;
    afm_param_lookup("model.damping_ratio[0]", &ent, &idx, err, sizeof err);
    afm_cmd c = {.kind = AFM_CMD_PARAM,
                 .seq = 5,
                 .u.param = {.n = 1, .entry = {ent}, .index = {idx}, .value = {1e-9}}};
    afm_param_apply(&t, &c.u.param, NULL, err, sizeof err);
    afm_runner_model *m = afm_runner_model_build(&t, false, err, sizeof err);
    check_true(m && afm_runner_apply(r, &c, &m, err, sizeof err) == 0, "damping taken away");
    afm_runner_model_destroy(&m);
    outlog o;
    log_init(&o);
    long long adv = 0;
    for (int i = 0; i < 100; i++) { /* at most 100 x 4096 samples = 29 ms */
        adv += afm_runner_run(r, 4096);
        drain(r, &o);
    }
    afm_runner_status st;
    afm_runner_status_get(r, &st);
    char why[400];
    afm_runner_pause_reason(&st, why, sizeof why);
    printf("  runaway: %lld blow-ups in %.4f s model time, last at %.6f s; %ld samples out\n"
           "  %s\n",
           st.blowups, st.t_s, st.last_blowup_t_s, o.n, why);
    check_true(st.blowups == AFM_RUNNER_BLOWUP_PAUSE,
               "runaway: blow-ups reported, it restarts, and after 3 it stops");
    check_true(!st.running && st.auto_paused && st.auto_pauses == 1 && strstr(why, "by itself") &&
                   strstr(why, "control run"),
               "recurring blow-ups: the twin paused itself, with the reason");
    check_true(adv == st.samples && adv < 409600 && afm_runner_run(r, 4096) == 0,
               "paused: no samples advance (no spinning through resets)");
    check_true(st.t_s > 3 * 1.5e-3 && st.t_s < 3 * 4e-3, "three runaways of ~2 ms each");
    check_true(o.n > 100, "outputs came between the blow-ups");
    bool finite = true;
    for (int s = 0; s < AFM_MAX_OUTPUTS; s++)
        for (long i = (long)s * PER; i < (long)s * PER + o.ns[s]; i++)
            finite &= isfinite(o.x[i]) && fabs(o.x[i]) < 1e-3;
    check_true(finite, "every published sample finite and below the 1 mm limit");
    /* control run resumes: it runs away again, three more times, and pauses again */
    afm_cmd run = {.kind = AFM_CMD_CONTROL, .seq = 6, .u.control = {AFM_CTL_RUN, 0}};
    afm_runner_apply(r, &run, NULL, err, sizeof err);
    afm_runner_status_get(r, &st);
    check_true(st.running && !st.auto_paused, "control run resumes");
    for (int i = 0; i < 100; i++) {
        afm_runner_run(r, 4096);
        drain(r, &o);
    }
    afm_runner_status_get(r, &st);
    check_true(st.blowups == 2 * AFM_RUNNER_BLOWUP_PAUSE && st.auto_pauses == 2 && !st.running,
               "resumed into the same runaway: paused again after 3 more");
    log_free(&o);
    afm_runner_destroy(&r);
}

/* Uptime: the daemon's real-time collapse of issue 12 came from the estimators' phase
 * trackers rebuilding their tables sample by sample once model time was large (the
 * rounding of t in theta = phi + w (t - t0) after a tone change). The same commands at the
 * same sample counts on a twin started at t = 0 and one started at t = 20 s (as a daemon up
 * 20 s): retract to 1 um, two frequency steps, an amplitude-only change, a ramp back. The
 * table rebuilds stay at about one per estimator and frequency change (before the fix:
 * hundreds of thousands), and the outputs do not depend on the uptime: the last period's
 * lock-in amplitude and first harmonic agree to 1e-6 (the integrator's own drive phase
 * carries w ulp(t) / 2 ~ 4e-9 rad of rounding at 20 s). */
static void test_uptime(const afm_config *cfg) {
    static const struct {
        long long at;
        int kind;
        double a, b;
    } cmds[] = {{20000, AFM_CMD_SETPOINT, 1e-6, 0},
                {40000, AFM_CMD_DITHER, 336000, 0.087e-9},
                {54000, AFM_CMD_DITHER, 336400, 0.087e-9},
                {68000, AFM_CMD_DITHER, 336400, 0.06e-9},
                {82000, AFM_CMD_SETPOINT, 40e-9, 2e-3}};
    const long long total_u = 120000;
    afm_chain_period last[2];
    long long rebuilds[2], periods[2];
    for (int run = 0; run < 2; run++) {
        char err[AFM_ERR_LEN];
        afm_runner *r = afm_runner_create(cfg, 4096, false, err, sizeof err);
        if (run == 1 && afm_runner_set_time(r, 20.0, err, sizeof err)) check_true(false, err);
        long long done = 0;
        int k = 0;
        periods[run] = 0;
        while (done < total_u) {
            while (k < 5 && cmds[k].at <= done) {
                afm_cmd c = {.seq = k + 1, .kind = cmds[k].kind};
                if (c.kind == AFM_CMD_SETPOINT)
                    c.u.setpoint = (afm_cmd_setpoint){cmds[k].a, cmds[k].b};
                else
                    c.u.dither = (afm_cmd_dither){1, {cmds[k].a}, {cmds[k].b}, {0}};
                if (afm_runner_apply(r, &c, NULL, err, sizeof err)) check_true(false, err);
                k++;
            }
            long long n = k < 5 ? cmds[k].at - done : total_u - done;
            done += afm_runner_run(r, n < 1024 ? n : 1024);
            afm_chain_block b;
            for (int st = 0; st < afm_runner_n_streams(r); st++)
                while (afm_runner_take_block(r, st, &b, 0) > 0) {
                }
            afm_chain_period p[64];
            int np;
            while ((np = afm_runner_take_periods(r, p, 64)) > 0) {
                last[run] = p[np - 1];
                periods[run] += np;
            }
        }
        afm_runner_status st;
        afm_runner_status_get(r, &st);
        rebuilds[run] = st.chain.estimator_rebuilds;
        afm_runner_destroy(&r);
    }
    double da = fabs(last[1].lockin_amplitude_m / last[0].lockin_amplitude_m - 1);
    double dh = fabs(last[1].harm.h[0].x_amp_m / last[0].harm.h[0].x_amp_m - 1);
    printf("  uptime 0 vs 20 s: table rebuilds %lld vs %lld, periods %lld vs %lld, last period "
           "lock-in %.6g vs %.6g nm (rel %.1e), A1 rel %.1e\n",
           rebuilds[0], rebuilds[1], periods[0], periods[1], last[0].lockin_amplitude_m * 1e9,
           last[1].lockin_amplitude_m * 1e9, da, dh);
    /* harm and lock-in: the first lock, and about one relock each per frequency change */
    check_true(rebuilds[1] <= 2 * (1 + 2) + 2 && rebuilds[0] <= 2 * (1 + 2) + 2,
               "uptime: at most ~1 table rebuild per estimator and frequency change, at t = 0 "
               "and at 20 s");
    check_true(periods[0] == periods[1], "uptime: the same number of periods at t = 0 and 20 s");
    check_true(da < 1e-6 && dh < 1e-6,
               "uptime: last period's lock-in amplitude and A1 the same at t = 0 and 20 s (1e-6)");
}

/* The estimators' phase (afm_chain.c) moves its origin every 2^20 samples: how the samples
 * are cut into pushes must not matter there either. Two twins, 1.2e6 samples (past the
 * first move at 1048576) run in slices of 1024 and 700: every period record bit for bit. */
static void test_phase_origin(const afm_config *cfg) {
    char err[AFM_ERR_LEN];
    static afm_chain_period rec[2][4096];
    long nrec[2] = {0, 0};
    for (int run = 0; run < 2; run++) {
        afm_runner *r = afm_runner_create(cfg, 4096, false, err, sizeof err);
        const long long slice = run ? 700 : 1024, total_s = 1200000;
        for (long long done = 0; done < total_s;) {
            long long n = total_s - done < slice ? total_s - done : slice;
            done += afm_runner_run(r, n);
            afm_chain_block b;
            for (int st = 0; st < afm_runner_n_streams(r); st++)
                while (afm_runner_take_block(r, st, &b, 0) > 0) {
                }
            afm_chain_period p[64];
            int np;
            while ((np = afm_runner_take_periods(r, p, 64)) > 0)
                for (int i = 0; i < np; i++) /* the records around the origin's move */
                    if (p[i].cycle.t_start_s > 0.070 && p[i].cycle.t_start_s < 0.080 &&
                        nrec[run] < 4096)
                        rec[run][nrec[run]++] = p[i];
        }
        afm_runner_destroy(&r);
    }
    bool same = nrec[0] == nrec[1] && nrec[0] > 3000;
    for (long i = 0; same && i < nrec[0]; i++)
        same = memcmp(&rec[0][i], &rec[1][i], sizeof rec[0][i]) == 0;
    printf("  phase origin move at 2^20 samples: %ld vs %ld period records around it\n", nrec[0],
           nrec[1]);
    check_true(same, "the period records around the phase origin's move are bit-identical for "
                     "slices of 1024 and 700 samples");
}

/* Issue 18: a raster over scan-grating.conf's grating, sliced 1024 and 700 samples at a time:
 * the tip's position is updated on a grid counted from create, so the samples and period
 * records are bit-identical; the status follows the raster to its end; a scan command to a
 * twin without a sample group is refused, nothing changed. The records' operating points
 * (stage Z, tip x, y, z_s, material) are those of the position update in force at the
 * sample the period ended on: against a third run sliced on the 64-sample update grid
 * (every ring item within one update, one push: its records can only take that update's), to
 * the bit, in all three (the chain takes an item's samples in one push and places each
 * record by where it ended: afm_chain_push_ev_ends). */
static void test_scan_slices(const afm_config *flat) {
    char err[AFM_ERR_LEN];
    afm_config cfg;
    if (afm_config_load("config/scan-grating.conf", &cfg, err, sizeof err)) {
        check_true(false, err);
        return;
    }
    /* 2 lines of 400 nm (two grating periods) at 1000 lines/s: 2 ms, 28120 samples */
    afm_cmd c = {.kind = AFM_CMD_SCAN,
                 .seq = 5,
                 .u.scan = {.mode = AFM_SCAN_RASTER,
                            .x_m = 0.0,
                            .y_m = 0.0,
                            .size_x_m = 4e-7,
                            .size_y_m = 1e-8,
                            .lines = 2,
                            .pixels = 16,
                            .line_rate_hz = 1000.0}};
    static afm_chain_period rec[3][2048];
    static afm_runner_oppoint ops[3][2048];
    static float xs[3][8192];
    long nrec[3] = {0, 0, 0}, nx[3] = {0, 0, 0};
    afm_runner_status st[3];
    int applied = 0;
    double xmax = 0.0;
    for (int run = 0; run < 3; run++) {
        afm_runner *r = afm_runner_create(&cfg, 4096, false, err, sizeof err);
        if (!r) {
            check_true(false, err);
            return;
        }
        const long long slices[3] = {1024, 700, AFM_RUNNER_SCAN_SAMPLES};
        const long long slice = slices[run], total_s = 40000, at_s = 2000;
        for (long long done = 0; done < total_s;) {
            if (done == at_s) {
                applied += afm_runner_apply(r, &c, NULL, err, sizeof err) == 0;
            }
            long long n = run == 2 ? slice - done % slice : slice; /* run 2: on the grid */
            if (done < at_s && done + n > at_s) n = at_s - done;
            if (done + n > total_s) n = total_s - done;
            done += afm_runner_run(r, n);
            afm_runner_status sm;
            afm_runner_status_get(r, &sm);
            if (run == 0 && sm.tip_x_m > xmax) xmax = sm.tip_x_m;
            afm_chain_block b;
            for (int k = 0; k < afm_runner_n_streams(r); k++)
                while (afm_runner_take_block(r, k, &b, 0) > 0)
                    for (int i = 0; i < b.n && k == 0 && nx[run] < 8192; i++)
                        xs[run][nx[run]++] = (float)b.x_m[i];
            afm_chain_period p[64];
            afm_runner_oppoint po[64];
            int np;
            while ((np = afm_runner_take_periods_op(r, p, po, 64)) > 0)
                for (int i = 0; i < np && nrec[run] < 2048; i++) {
                    ops[run][nrec[run]] = po[i];
                    rec[run][nrec[run]++] = p[i];
                }
        }
        afm_runner_status_get(r, &st[run]);
        afm_runner_destroy(&r);
    }
    bool same = nrec[0] == nrec[1] && nrec[0] > 100 && nx[0] == nx[1] && nx[0] > 1000 &&
                memcmp(xs[0], xs[1], sizeof(float) * (size_t)nx[0]) == 0;
    for (long i = 0; same && i < nrec[0]; i++)
        same = memcmp(&rec[0][i], &rec[1][i], sizeof rec[0][i]) == 0;
    /* the ops against the 64-sample run's, field by field; how many records changed place
     * (x or z_s) from the one before: the raster moves the tip under nearly every period */
    long op_bad = 0, moved = 0, edges = 0;
    for (int run = 0; run < 2; run++)
        for (long i = 0; i < nrec[run] && i < nrec[2]; i++) {
            const afm_runner_oppoint *a = &ops[run][i], *b = &ops[2][i];
            op_bad += a->z_m != b->z_m || a->tip_x_m != b->tip_x_m || a->tip_y_m != b->tip_y_m ||
                      a->true_height_m != b->true_height_m || a->material != b->material;
        }
    for (long i = 1; i < nrec[2]; i++) {
        moved += ops[2][i].tip_x_m != ops[2][i - 1].tip_x_m;
        edges += ops[2][i].true_height_m != ops[2][i - 1].true_height_m;
    }
    printf("  raster ops: %ld / %ld / %ld records, %ld of run 2's moved x, %ld moved z_s; %ld "
           "ops differ from the 64-sample run's\n",
           nrec[0], nrec[1], nrec[2], moved, edges, op_bad);
    check_true(nrec[2] == nrec[0] && nrec[1] == nrec[0] && op_bad == 0 && moved > nrec[2] / 3 &&
                   edges > 10,
               "scan: every period record's op (Z, x, y, z_s, material) is the position update "
               "in force at the sample its period ended on (= a run pushing one update at a time)");
    printf("  raster over the grating: %ld period records, %ld samples of stream 0, x up to %.1f "
           "nm, at the end (%.4g, %.4g) nm, mode %d\n",
           nrec[0], nx[0], xmax * 1e9, st[0].tip_x_m * 1e9, st[0].tip_y_m * 1e9, st[0].scan_mode);
    check_true(applied == 3 && same,
               "scan: a raster's outputs are bit-identical for slices of 1024 and 700 samples");
    check_true(st[0].sample_on && st[0].scan_mode == AFM_SCAN_HOLD && st[0].scan_line == -1 &&
                   xmax > 3.9e-7 && fabs(st[0].tip_x_m) < 1e-9 && st[0].tip_y_m > 0.9e-8 &&
                   st[0].seq_applied == 5 && st[0].separation_m == cfg.drive.separation_m,
               "scan: the raster runs to its end and holds; the status's Z is the stage's");
    /* no sample group: refused, nothing changed */
    afm_runner *r = afm_runner_create(flat, 4096, false, err, sizeof err);
    int rc = afm_runner_apply(r, &c, NULL, err, sizeof err);
    afm_runner_status sf;
    afm_runner_status_get(r, &sf);
    check_true(rc == -1 && strstr(err, "no sample group") && !sf.sample_on && sf.tip_x_m == 0 &&
                   sf.seq_applied == -1,
               "scan: refused without a sample group, nothing changed");
    afm_runner_destroy(&r);
}

/* am.control = "internal" (issue 18): a FORCE param moves the free amplitude (the squeeze
 * film's p2 here: A0 50.7 -> ~43 nm on default.conf), and the Z loop's set-point follows:
 * the model built for the command carries the new config's A0 (afm_runner_cmd_needs_model
 * asks for one), and the set-point becomes setpoint_ratio x that A0 exactly. Without the
 * internal loop no model is asked for. */
static void test_am_force_a0(const afm_config *cfg0) {
    char err[AFM_ERR_LEN];
    afm_config cfg = *cfg0;
    int ent, idx;
    afm_param_lookup("forces.squeeze.p2_n_s_m", &ent, &idx, err, sizeof err);
    afm_cmd c = {.kind = AFM_CMD_PARAM,
                 .seq = 3,
                 .u.param = {.n = 1, .entry = {ent}, .index = {idx}, .value = {1.5e-8}}};
    bool nc = true;
    check_true(afm_runner_cmd_needs_model(&cfg, &c, &nc) == 0,
               "am.control none: a force param needs no model");
    cfg.am.enabled = true;
    cfg.am.control = AFM_AM_CONTROL_INTERNAL;
    check_true(afm_runner_cmd_needs_model(&cfg, &c, &nc) == 1 && !nc,
               "am.control internal: a force param asks for a model (for its A0), no chain");
    afm_runner *r = afm_runner_create(&cfg, 4096, false, err, sizeof err);
    if (!r) {
        check_true(false, err);
        return;
    }
    afm_runner_status st0, st1;
    afm_runner_status_get(r, &st0);
    afm_config next = cfg;
    afm_param_apply(&next, &c.u.param, NULL, err, sizeof err);
    afm_a0 a0;
    afm_runner_model *m = afm_runner_model_build(&next, false, err, sizeof err);
    bool ok = m && afm_a0_compute(&next, &a0, err, sizeof err) == 0 &&
              afm_runner_apply(r, &c, &m, err, sizeof err) == 0;
    check_true(ok, "force param with its model applied");
    afm_runner_status_get(r, &st1);
    const double want = cfg.am.setpoint_ratio * a0.amplitude_m;
    printf("  am set-point %.6f nm -> %.6f nm (ratio x A0 of the new forces %.6f nm)\n",
           st0.am_setpoint_m * 1e9, st1.am_setpoint_m * 1e9, want * 1e9);
    check_true(ok && st1.am_setpoint_m == want &&
                   fabs(st1.am_setpoint_m / st0.am_setpoint_m - 1) > 1e-2,
               "the set-point follows the new forces' A0 (ratio x A0, exactly)");
    check_true(m != NULL, "the model is not swapped in: it comes back to the caller");
    afm_runner_model_destroy(&m);
    afm_runner_destroy(&r);
}

/* One param command: name[index] = v. */
static afm_cmd param_cmd(const char *name, double v, int64_t seq) {
    char err[AFM_ERR_LEN];
    int ent = 0, idx = -1;
    afm_param_lookup(name, &ent, &idx, err, sizeof err);
    return (afm_cmd){.kind = AFM_CMD_PARAM,
                     .seq = seq,
                     .u.param = {.n = 1, .entry = {ent}, .index = {idx}, .value = {v}}};
}

/* A0 of cfg at tone 0 (fe, ae). */
static double a0_at(const afm_config *cfg, double fe, double ae) {
    static afm_config t; /* large */
    char err[AFM_ERR_LEN];
    afm_a0 a0;
    t = *cfg;
    t.drive.tones[0].frequency_hz = fe;
    t.drive.tones[0].amplitude_m = ae;
    return afm_a0_compute(&t, &a0, err, sizeof err) ? NAN : a0.amplitude_m;
}

/* am.control = "internal" (issue 18): what moves the free amplitude A0 sets the Z loop's
 * reference again, what does not leaves it. A0 is the amplitude far from the sample: a
 * tip-sample force constant (the Hamaker constant here) leaves it bit for bit (afm_a0.h
 * switches the gap-dependent forces off), so no model is asked for and the set-point stays;
 * a dither that moves tone 0 (amplitude x1.5) comes with afm_runner_model_a0 and the
 * set-point becomes ratio x A0 at the new drive exactly (~x1.5: linear far from the
 * sample); a damping change after it brings the new model's A0 at the drive in force
 * (afm_runner_model_build_at), not at the config's tone 0 (which would be 1/1.5 of it). */
static void test_am_drive_a0(const afm_config *cfg0) {
    char err[AFM_ERR_LEN];
    static afm_config cfg, next;
    cfg = *cfg0;
    cfg.am.enabled = true;
    cfg.am.control = AFM_AM_CONTROL_INTERNAL;
    const double fe = cfg.drive.tones[0].frequency_hz, ae = cfg.drive.tones[0].amplitude_m;
    afm_runner *r = afm_runner_create(&cfg, 4096, false, err, sizeof err);
    if (!r) {
        check_true(false, err);
        return;
    }
    afm_runner_status st0, st1, st2, st3;
    afm_runner_status_get(r, &st0);
    /* a tip-sample force constant */
    afm_cmd h = param_cmd("forces.vdw_contact.hamaker_j", 3e-19, 3);
    bool nc = true;
    next = cfg;
    afm_param_apply(&next, &h.u.param, NULL, err, sizeof err);
    const double a0_h = a0_at(&next, fe, ae), a0_c = a0_at(&cfg, fe, ae);
    printf("  A0 %.9f nm; with the Hamaker constant 3e-19 J %.9f nm\n", a0_c * 1e9, a0_h * 1e9);
    check_true(a0_h == a0_c,
               "a tip-sample force constant leaves A0 bit for bit (far from the sample)");
    check_true(afm_runner_cmd_needs_model(&cfg, &h, &nc) == 0 &&
                   afm_runner_apply(r, &h, NULL, err, sizeof err) == 0,
               "am.control internal: a Hamaker param needs no model (no A0 to recompute)");
    afm_runner_status_get(r, &st1);
    check_true(st1.am_setpoint_m == st0.am_setpoint_m, "... and the set-point stays");
    /* a dither that moves tone 0 */
    afm_cmd_dither now = {.n_tones = 1, .frequency_hz = {fe}, .amplitude_m = {ae}};
    afm_cmd d = {.kind = AFM_CMD_DITHER,
                 .seq = 4,
                 .u.dither = {.n_tones = 1, .frequency_hz = {fe}, .amplitude_m = {1.5 * ae}}};
    afm_cmd same = d;
    same.u.dither.amplitude_m[0] = ae;
    check_true(afm_runner_dither_moves_a0(&cfg, &now, &d) &&
                   !afm_runner_dither_moves_a0(&cfg, &now, &same) &&
                   !afm_runner_dither_moves_a0(cfg0, &now, &d),
               "a dither moves A0 when tone 0 changes (and the loop is internal), not otherwise");
    afm_runner_model *m = afm_runner_model_a0(&cfg, &d.u.dither, err, sizeof err);
    bool ok = m && afm_runner_apply(r, &d, &m, err, sizeof err) == 0;
    afm_runner_model_destroy(&m);
    afm_runner_status_get(r, &st2);
    const double a0_d = a0_at(&cfg, fe, 1.5 * ae), want_d = cfg.am.setpoint_ratio * a0_d;
    printf("  dither tone 0 x1.5: set-point %.6f -> %.6f nm (ratio x A0 %.6f nm; x%.6f)\n",
           st1.am_setpoint_m * 1e9, st2.am_setpoint_m * 1e9, want_d * 1e9,
           st2.am_setpoint_m / st1.am_setpoint_m);
    check_true(
        ok && st2.am_setpoint_m == want_d &&
            fabs(st2.am_setpoint_m / st1.am_setpoint_m - 1.5) < 1e-3,
        "a dither of tone 0: the set-point is ratio x A0 at the new drive (x1.5 within 1e-3)");
    /* damping after the dither: the new model's A0 at the drive in force */
    afm_cmd q = param_cmd("model.damping_ratio[0]", 0.0015, 5);
    next = cfg;
    afm_param_apply(&next, &q.u.param, NULL, err, sizeof err);
    const afm_drive *dr = afm_sim_drive(afm_runner_sim(r));
    afm_cmd_dither in_force = {
        .n_tones = 1, .frequency_hz = {dr->freq_hz[0]}, .amplitude_m = {dr->amp_m[0]}};
    m = afm_runner_cmd_needs_model(&cfg, &q, &nc) == 1
            ? afm_runner_model_build_at(&next, nc, &in_force, err, sizeof err)
            : NULL;
    ok = m && afm_runner_apply(r, &q, &m, err, sizeof err) == 0;
    afm_runner_model_destroy(&m);
    afm_runner_status_get(r, &st3);
    const double want_q = cfg.am.setpoint_ratio * a0_at(&next, fe, 1.5 * ae);
    printf("  damping ratio 0.0015 after it: set-point %.6f nm (ratio x A0 at the drive in force "
           "%.6f nm; at the config's tone 0 it would be %.6f nm)\n",
           st3.am_setpoint_m * 1e9, want_q * 1e9,
           cfg.am.setpoint_ratio * a0_at(&next, fe, ae) * 1e9);
    check_true(
        ok && st3.am_setpoint_m == want_q && fabs(st3.am_setpoint_m / st2.am_setpoint_m - 1) > 0.05,
        "a damping change: the set-point is ratio x the new model's A0 at the drive in force");
    afm_runner_destroy(&r);
}

/* The period metrics of cfg's twin run directly: a simulator (with the record ring when ev)
 * and a chain of its own attached to it, fed each sample's record (afm_sim_events_at, as the
 * offline tools feed afm_cycle_push_ev, tools/cmd_approach.c) by afm_chain_push_ev, or none
 * (afm_chain_push: the samples' path). The chain gives afm_cycle_push_ev the drive phase
 * the runner's chain gives it (a period boundary next to the minimum of x goes to the same
 * period). n samples; up to max records into out. */
static long direct_cycle(const afm_config *cfg, long long n, bool ev, afm_cycle_metrics *out,
                         long max) {
    char err[AFM_ERR_LEN];
    afm_sim *s = afm_twin_create(cfg, NULL, NULL, err, sizeof err);
    afm_chain *c = s ? afm_chain_create(cfg, afm_sim_model(s), err, sizeof err) : NULL;
    if (!c || afm_chain_attach(c, s, err, sizeof err)) {
        check_true(false, err);
        afm_chain_destroy(&c);
        afm_sim_destroy(&s);
        return 0;
    }
    static afm_step_events ring[4096];
    static afm_sample smp[1000];
    static const afm_step_events *evp[1000];
    if (ev) afm_sim_set_events(s, ring, 4096);
    long np = 0;
    for (long long done = 0; done < n; done += 1000) {
        afm_sim_run(s, 1000, smp);
        for (int i = 0; i < 1000; i++)
            evp[i] = ev ? afm_sim_events_at(s, smp[i].t_s) : NULL;
        afm_chain_push_ev(c, smp, ev ? evp : NULL, 1000);
        afm_chain_block b;
        for (int st = 0; st < afm_chain_n_streams(c); st++)
            while (afm_chain_take_block(c, st, &b, 0) > 0) {
            }
        afm_chain_period p[64];
        int m;
        while ((m = afm_chain_take_periods(c, p, 64)) > 0)
            for (int i = 0; i < m && np < max; i++)
                out[np++] = p[i].cycle;
    }
    afm_chain_destroy(&c);
    afm_sim_destroy(&s);
    return np;
}

/* The period metrics of cfg's twin from afm_cycle_push_ev on every sample with its record
 * (afm_sim_events_at) and tone 0's phase by afm_drive_phase, exactly as tools/cmd_approach.c
 * feeds them: no chain (its choice of the samples whose record matters is not used). */
static long direct_cycle_plain(const afm_config *cfg, long long n, afm_cycle_metrics *out,
                               long max) {
    char err[AFM_ERR_LEN];
    afm_sim *s = afm_twin_create(cfg, NULL, NULL, err, sizeof err);
    if (!s) {
        check_true(false, err);
        return 0;
    }
    static afm_step_events ring[4096];
    static afm_sample smp[1000];
    afm_sim_set_events(s, ring, 4096);
    const afm_force_params *f = afm_sim_forces(s);
    const double z = afm_sim_separation(s);
    afm_cycle c;
    afm_cycle_init(&c, afm_force_contact_x(f, z), f->cos_alpha, err, sizeof err);
    afm_cycle_set_forces(&c, f, z);
    long np = 0;
    for (long long done = 0; done < n; done += 1000) {
        afm_sim_run(s, 1000, smp);
        for (int i = 0; i < 1000; i++) {
            double th = afm_drive_phase(afm_sim_drive(s), 0, smp[i].t_s);
            if (afm_cycle_push_ev(&c, &smp[i], th, afm_sim_events_at(s, smp[i].t_s)) == 1 &&
                np < max)
                out[np++] = c.out;
        }
    }
    afm_sim_destroy(&s);
    return np;
}

/* The runner's period metrics of cfg over n samples in slices of `slice`, after cmd (if any)
 * at sample 0; the status's ev_samples and samples into *ev_n, *n_s. */
static long runner_cycle(const afm_config *cfg, long long n, long long slice, const afm_cmd *cmd,
                         afm_cycle_metrics *out, long max, long long *ev_n, long long *n_s) {
    char err[AFM_ERR_LEN];
    afm_runner *r = afm_runner_create(cfg, 4096, false, err, sizeof err);
    if (!r) {
        check_true(false, err);
        return 0;
    }
    if (cmd) afm_runner_apply(r, cmd, NULL, err, sizeof err);
    long np = 0;
    for (long long done = 0; done < n;) {
        long long k = n - done < slice ? n - done : slice;
        done += afm_runner_run(r, k);
        afm_chain_block b;
        for (int st = 0; st < afm_runner_n_streams(r); st++)
            while (afm_runner_take_block(r, st, &b, 0) > 0) {
            }
        afm_chain_period p[64];
        int m;
        while ((m = afm_runner_take_periods(r, p, 64)) > 0)
            for (int i = 0; i < m && np < max; i++)
                out[np++] = p[i].cycle;
    }
    afm_runner_chain_status cs;
    afm_runner_chain_status_get(r, &cs);
    *ev_n = cs.ev_samples;
    *n_s = cs.samples;
    afm_runner_destroy(&r);
    return np;
}

/* Worst relative difference of energy, contact time and min deflection of a vs b (periods
 * matched by number; scale: the largest |value| of each metric in a). */
static double cycle_diff_e(const afm_cycle_metrics *a, const afm_cycle_metrics *b, long n,
                           double *w_e) {
    double se = 0, sc = 0, sm = 0, w = 0, we = 0;
    for (long i = 0; i < n; i++) {
        se = fmax(se, fabs(a[i].dissipated_energy_j));
        sc = fmax(sc, fabs(a[i].contact_time_s));
        sm = fmax(sm, fabs(a[i].min_deflection_m));
    }
    for (long i = 0; i < n; i++) {
        if (a[i].period != b[i].period) return INFINITY;
        we = fmax(we, fabs(a[i].dissipated_energy_j - b[i].dissipated_energy_j) / se);
        w = fmax(w, fabs(a[i].contact_time_s - b[i].contact_time_s) / sc);
        w = fmax(w, fabs(a[i].min_deflection_m - b[i].min_deflection_m) / sm);
    }
    if (w_e) {
        *w_e = we;
        return w;
    }
    return fmax(w, we);
}

static double cycle_diff(const afm_cycle_metrics *a, const afm_cycle_metrics *b, long n) {
    return cycle_diff_e(a, b, n, NULL);
}

static void test_step_events(void) {
    char err[AFM_ERR_LEN];
    afm_config cfg;
    if (afm_config_load("config/probe-q300.conf", &cfg, err, sizeof err)) {
        check_true(false, err);
        return;
    }
    /* A0 10 nm at Z 8 nm: repulsive tapping, viscoelastic contact; 60000 samples = 1280
       periods (settled) */
    cfg.sim.rt_scheme = AFM_RT_SCHEME_ACCURATE;
    cfg.forces.viscoelastic = true; /* a dissipative contact: energy well above rounding */
    cfg.forces.eta_pa_s = 800.0;
    const long long n = 60000;
    enum { MAXP = 1400 };
    static afm_cycle_metrics run[MAXP], dev[MAXP], dsm[MAXP], run2[MAXP];
    long long ev_n, n_s;
    long nr = runner_cycle(&cfg, n, 1000, NULL, run, MAXP, &ev_n, &n_s);
    long nd = direct_cycle(&cfg, n, true, dev, MAXP);
    long ns = direct_cycle(&cfg, n, false, dsm, MAXP);
    long nc = nr < nd ? nr : nd;
    double d_ev = cycle_diff(dev, run, nc), d_sm = cycle_diff(dsm, run, nc < ns ? nc : ns);
    printf("  step events, accurate scheme: %ld / %ld / %ld periods (runner / direct with records "
           "/ direct on samples), %lld of %lld samples with a record; runner vs records %.3g, "
           "vs samples %.3g (worst relative energy, contact time, min deflection)\n",
           nr, nd, ns, ev_n, n_s, d_ev, d_sm);
    check_true(
        nr > 1200 && labs(nr - nd) <= 1 && ev_n == n_s && n_s == n,
        "step events: every sample of the accurate scheme reaches the chain with its record");
    check_true(d_ev <= 1e-12,
               "step events: the runner's period metrics are afm_cycle_push_ev's on the sim's "
               "records (energy, contact time, min deflection within 1e-12 relative)");
    check_true(d_sm > 1e-9, "step events: ... and not the samples' estimate");
    /* afm_cycle_push_ev on every sample, no chain: the settled periods (from 300 on; in the
       transient a minimum next to a period boundary may fall on either side with the two
       phase computations' last bits). Those bits move the boundary by ~1e-16 of a period; the
       energy is a difference of work sums ~1e4 times larger than itself (F v over a period),
       so it is compared within 1e-10 of its largest value, the rest within 1e-12. */
    static afm_cycle_metrics pl[MAXP];
    long npl = direct_cycle_plain(&cfg, n, pl, MAXP);
    long nc2 = (npl < nr ? npl : nr) - 300;
    double d_pe = INFINITY,
           d_pl = nc2 > 0 ? cycle_diff_e(pl + 300, run + 300, nc2, &d_pe) : INFINITY;
    printf("  afm_cycle_push_ev on every sample (no chain): %ld periods; runner vs it from period "
           "300: contact time and min deflection %.3g, energy %.3g\n",
           npl, d_pl, d_pe);
    check_true(nc2 > 900 && d_pl <= 1e-12 && d_pe <= 1e-10,
               "step events: the runner's settled period metrics are those of afm_cycle_push_ev "
               "fed every sample's record directly (contact time, min deflection within 1e-12 "
               "relative, energy 1e-10)");
    /* off by the key: the sample path */
    afm_config off = cfg;
    off.sim.step_events = AFM_STEP_EVENTS_OFF;
    nr = runner_cycle(&off, n, 1000, NULL, run2, MAXP, &ev_n, &n_s);
    double d_off = cycle_diff(dsm, run2, nr < ns ? nr : ns);
    printf("  sim.step_events = \"off\": %lld samples with a record, runner vs samples %.3g\n",
           ev_n, d_off);
    check_true(ev_n == 0 && d_off <= 1e-12, "step events off: the samples' path");
    /* the fast scheme does not record: the sample path, as before */
    afm_config fast = cfg;
    fast.sim.rt_scheme = AFM_RT_SCHEME_FAST;
    nr = runner_cycle(&fast, n, 1000, NULL, run2, MAXP, &ev_n, &n_s);
    ns = direct_cycle(&fast, n, false, dsm, MAXP);
    d_off = cycle_diff(dsm, run2, nr < ns ? nr : ns);
    printf("  fast scheme: %lld samples with a record, runner vs samples %.3g\n", ev_n, d_off);
    check_true(ev_n == 0 && d_off <= 1e-12 && nr > 1200,
               "fast scheme: no record, the samples' path unchanged");
    /* a Z ramp (Z changes every 64 samples, inside items: sub-slices): every sample keeps its own
       record, the same records for slices of 1000 and 777 samples */
    afm_cmd c = {.kind = AFM_CMD_SETPOINT, .seq = 3, .u.setpoint = {7e-9, 1e-6}}; /* 1 ms */
    long long ev2, n2;
    nr = runner_cycle(&cfg, n, 1000, &c, run, MAXP, &ev_n, &n_s);
    long nr2 = runner_cycle(&cfg, n, 777, &c, run2, MAXP, &ev2, &n2);
    bool same = nr == nr2 && nr > 1200;
    for (long i = 0; same && i < nr; i++)
        same = memcmp(&run[i], &run2[i], sizeof run[i]) == 0;
    printf("  Z ramp 8 -> 7 nm: %lld / %lld samples with a record, %ld / %ld periods\n", ev_n, n_s,
           nr, nr2);
    check_true(same && ev_n == n_s && ev2 == n2,
               "step events through a Z ramp: every sample with its record, bit-identical for "
               "slices of 1000 and 777");
}

int main(void) {
    afm_config cfg;
    char err[AFM_ERR_LEN];
    if (afm_config_load("config/default.conf", &cfg, err, sizeof err)) {
        check_true(false, err);
        return check_done();
    }
    test_determinism(&cfg);
    test_reload_keeps_seq(&cfg);
    test_ramp_and_rejects(&cfg);
    test_gating(&cfg);
    test_done(&cfg);
    test_tones_stop(&cfg);
    test_blowup();
    test_uptime(&cfg);
    test_phase_origin(&cfg);
    test_scan_slices(&cfg);
    test_am_force_a0(&cfg);
    test_am_drive_a0(&cfg);
    test_step_events();
    return check_done();
}
