/* SPDX-License-Identifier: MIT */
/* cmd_soak.c -- `afmtwin soak`: a bounded, seeded command soak of a real-time afmtwind
 * (issue 12). Sends valid commands of every kind at random intervals (setpoint steps and
 * ramps from 1 um down to indentation, frequency and amplitude steps, multi-tone, live force,
 * damping and geometry changes, pause / step / run, reset), up to --max-rate-hz, for
 * --seconds, and checks as it goes:
 *  - every status of the run: the real-time factor of the last second of running
 *    (realtime_factor_1s, as a share of the daemon's --speed given as --speed) at least
 *    --min-rtf (0.99) and no resync, except that the second after a
 *    geometry rebuild may skip at most one block (counted and reported);
 *  - every command applied and echoed: the next command goes out once the previous one's seq
 *    (or a later one: commands apply in order) came back as seq_applied, in a samples message
 *    or the status, 250 ms at most; at the end the daemon counts as many received and
 *    applied, none rejected;
 *  - every output finite (samples, the harmonics' lock-in and peak force).
 * Drive amplitudes are chosen for free tip amplitudes of 15-85 nm (the model's linear
 * response at tone 0's frequency; 50 nm nominal), the usual AM-AFM range, whatever the config
 * drives at start. --log writes the commands sent (lcm-logger format, wall-clock times) for
 * `afmtwin lockstep --check` and `afmtwin replay`. The generator is xorshift64* from --seed: the
 * same seed sends the same commands (the times depend on the echoes). */
#include "afmtwin_cmds.h"
#include "lcm_tool.h"
#include "opts.h"

#include "runner/afm_cmd.h"
#include "config/afm_config.h"
#include "beam/afm_model.h"

#include "afmtwin_control_t.h"
#include "afmtwin_dither_t.h"
#include "afmtwin_harmonics_t.h"
#include "afmtwin_param_t.h"
#include "afmtwin_samples_t.h"
#include "afmtwin_setpoint_t.h"
#include "afmtwin_status_t.h"

#include <lcm/eventlog.h>
#include <lcm/lcm.h>
#include <math.h>
#include <sched.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SOAK_ECHO_WAIT_S 0.25
#define SOAK_WARMUP_S 1.5   /* the first whole second of running, after start-up */
#define SOAK_GEOMETRY_S 3.0 /* at most one geometry rebuild per this many seconds */
#ifdef SCHED_RESET_ON_FORK
#define SOAK_RESET_ON_FORK SCHED_RESET_ON_FORK
#else
#define SOAK_RESET_ON_FORK 0x40000000
#endif

enum {
    K_SETPOINT,
    K_RAMP,
    K_FREQ,
    K_AMP,
    K_MULTI,
    K_FORCE,
    K_DAMPING,
    K_GEOMETRY,
    K_PAUSE,
    K_STEP,
    K_RUN,
    K_RESET,
    N_KINDS
};
static const char *const kind_name[N_KINDS] = {
    "setpoint step", "setpoint ramp", "frequency step", "amplitude step", "multi-tone",
    "force param",   "damping param", "geometry param", "pause",          "step",
    "run",           "reset"};

typedef struct {
    const char *config, *url, *out_url, *samples_url, *prefix, *log;
    double seconds, max_rate_hz, block_s;
    int rt_priority; /* SCHED_FIFO priority of this tool, 0: normal scheduling */
    uint64_t seed;
    bool quiet;
    /* LCM */
    afmt_lcm lcm; /* commands out; outputs in, the samples on their own URL */
    afmt_channels ch;
    lcm_eventlog_t *logf;
    /* the twin */
    double fs, f1, a1, length_m, zeta1;
    bool paused;
    /* bookkeeping */
    uint64_t rng;
    int64_t seq, echoed_seq;
    long long sent[N_KINDS], n_sent, unechoed;
    double echo_lat[200000];
    long long n_lat;
    long long n_status, windows, bad_windows, resyncs0, resyncs_last, geometry_skips;
    double min_rtf, min_rtf_ok, speed, skipped0, skipped_last, t_start, last_geometry;
    long long nonfinite, samples_msgs, harm_msgs;
    afmtwin_status_t last; /* numbers only (strings not kept) */
    bool have_status;
    int recent[8]; /* kinds of the last commands sent, and when */
    double recent_t[8];
    int n_recent;
} soak_ctx;

/* The commands of the last 1.5 s, for a report of a slow window. */
static void recent_text(const soak_ctx *c, double now, char *buf, size_t len);

/* ---- random numbers (xorshift64*) ---- */
static uint64_t rnd(soak_ctx *c) {
    c->rng ^= c->rng >> 12;
    c->rng ^= c->rng << 25;
    c->rng ^= c->rng >> 27;
    return c->rng * 0x2545F4914F6CDD1DULL;
}
static double uni(soak_ctx *c, double lo, double hi) {
    return lo + (hi - lo) * (double)(rnd(c) >> 11) * 0x1.0p-53;
}
static double log_uni(soak_ctx *c, double lo, double hi) {
    return exp(uni(c, log(lo), log(hi)));
}

/* ---- outputs in ---- */

static void on_status(const void *msg, void *user) {
    const afmtwin_status_t *m = msg;
    soak_ctx *c = user;
    c->n_status++;
    if (m->seq_applied > c->echoed_seq) c->echoed_seq = m->seq_applied;
    double t = afmt_mono_s() - c->t_start;
    if (!c->have_status) {
        c->resyncs0 = c->resyncs_last = m->resyncs;
        c->skipped0 = c->skipped_last = m->resync_skipped_s;
    }
    if (t > SOAK_WARMUP_S && m->realtime_factor_1s > 0 && m->running) {
        c->windows++;
        double share = m->realtime_factor_1s / c->speed; /* of the speed asked for */
        if (share < c->min_rtf) c->min_rtf = share;
        bool slow = share < c->min_rtf_ok;
        if (slow && c->bad_windows++ < 10) {
            char why[512];
            recent_text(c, afmt_mono_s(), why, sizeof why);
            fprintf(stderr,
                    "afmtwin soak: t %.1f s: real-time factor of the last second %.4f (lag %.3g "
                    "s, chain lag %.3g s, overruns %lld; Z %.1f nm, fe %.0f Hz, A %.3g nm; "
                    "commands: %s)\n",
                    t, m->realtime_factor_1s / c->speed, m->lag_s, m->chain_lag_s,
                    (long long)m->overruns, m->separation_m * 1e9, m->fe_hz, m->amplitude_m * 1e9,
                    why);
        }
    }
    if (m->resyncs != c->resyncs_last) {
        double skipped = m->resync_skipped_s - c->skipped_last;
        bool after_geometry = afmt_mono_s() - c->last_geometry < 1.0;
        if (after_geometry && m->resyncs - c->resyncs_last == 1 && skipped <= c->block_s * 1.01) {
            c->geometry_skips++;
            fprintf(stderr,
                    "afmtwin soak: t %.1f s: one resync (%.3g ms skipped) right after a geometry "
                    "rebuild (allowed: at most one block)\n",
                    t, skipped * 1e3);
        } else {
            c->bad_windows++;
            fprintf(stderr,
                    "afmtwin soak: t %.1f s: %lld resync(s), %.3g ms of model time skipped\n", t,
                    (long long)(m->resyncs - c->resyncs_last), skipped * 1e3);
        }
    }
    c->resyncs_last = m->resyncs;
    c->skipped_last = m->resync_skipped_s;
    c->last = *m;
    c->last.last_reject = c->last.mode = c->last.can_state = c->last.can_last_reject = NULL;
    c->last.last_refusal = c->last.last_drop = c->last.pause_reason = NULL; /* freed after */
    c->have_status = true;
}

static void on_samples(const void *msg, void *user) {
    const afmtwin_samples_t *m = msg;
    soak_ctx *c = user;
    c->samples_msgs++;
    if (m->seq_applied > c->echoed_seq) c->echoed_seq = m->seq_applied;
    for (int i = 0; i < m->n; i++)
        if (!isfinite(m->deflection_m[i]) || !isfinite(m->obd_m[i]) || !isfinite(m->force_n[i]))
            c->nonfinite++;
}

static void on_harm(const void *msg, void *user) {
    const afmtwin_harmonics_t *m = msg;
    soak_ctx *c = user;
    c->harm_msgs++;
    if (!isfinite(m->lockin_amplitude_m) || !isfinite(m->peak_force_n)) c->nonfinite++;
}

static void pump(soak_ctx *c, double seconds) {
    double t_end = afmt_mono_s() + seconds;
    for (double left = seconds; left > 0; left = t_end - afmt_mono_s())
        afmt_lcm_handle(&c->lcm, (int)ceil(left * 1e3));
}

/* ---- commands out ---- */

#define PUBLISH(c, T, chan, msg)                                                                   \
    do {                                                                                           \
        uint8_t buf_[4096];                                                                        \
        int n_ = AFMT_ENCODE(T, msg, buf_, (int)sizeof buf_);                                      \
        if (n_ >= 0) send_raw(c, chan, buf_, n_);                                                  \
    } while (0)

static void send_raw(soak_ctx *c, const char *chan, const uint8_t *buf, int n) {
    lcm_publish(c->lcm.cmd, chan, buf, (unsigned)n);
    if (c->logf) {
        afmt_log_write(c->logf, afmt_wall_us(), chan, buf, n);
    }
}

static void send_setpoint(soak_ctx *c, double z, double rate) {
    afmtwin_setpoint_t m = {
        .utime = afmt_wall_us(), .seq = ++c->seq, .separation_m = z, .ramp_rate_m_s = rate};
    PUBLISH(c, afmtwin_setpoint_t, c->ch.cmd[AFM_CMD_SETPOINT], &m);
}

static void send_dither(soak_ctx *c, int n, double *f, double *a) {
    double ph[AFM_MAX_TONES] = {0};
    afmtwin_dither_t m = {.utime = afmt_wall_us(),
                          .seq = ++c->seq,
                          .n_tones = (int8_t)n,
                          .frequency_hz = f,
                          .amplitude_m = a,
                          .phase_rad = ph};
    PUBLISH(c, afmtwin_dither_t, c->ch.cmd[AFM_CMD_DITHER], &m);
}

static void send_param(soak_ctx *c, const char *name, double v) {
    char *names[1] = {(char *)name};
    afmtwin_param_t m = {
        .utime = afmt_wall_us(), .seq = ++c->seq, .n = 1, .name = names, .value = &v};
    PUBLISH(c, afmtwin_param_t, c->ch.cmd[AFM_CMD_PARAM], &m);
}

static void send_control(soak_ctx *c, int action, long long n) {
    afmtwin_control_t m = {
        .utime = afmt_wall_us(), .seq = ++c->seq, .action = (int8_t)action, .n_samples = n};
    PUBLISH(c, afmtwin_control_t, c->ch.cmd[AFM_CMD_CONTROL], &m);
}

/* One random command (valid for the twin as configured). */
static int one_command(soak_ctx *c) {
    if (c->paused) { /* paused: steps, then run */
        int k = rnd(c) % 3 ? K_STEP : K_RUN;
        if (k == K_STEP)
            send_control(c, AFMTWIN_CONTROL_T_STEP, (long long)uni(c, 1000, 14060));
        else
            send_control(c, AFMTWIN_CONTROL_T_RUN, 0);
        c->paused = k == K_STEP;
        return k;
    }
    double u = uni(c, 0, 1), now = afmt_mono_s();
    int k;
    if (u < 0.22)
        k = K_SETPOINT;
    else if (u < 0.34)
        k = K_RAMP;
    else if (u < 0.54)
        k = K_FREQ;
    else if (u < 0.66)
        k = K_AMP;
    else if (u < 0.72)
        k = K_MULTI;
    else if (u < 0.82)
        k = K_FORCE;
    else if (u < 0.87)
        k = K_DAMPING;
    else if (u < 0.90 && now - c->last_geometry > SOAK_GEOMETRY_S)
        k = K_GEOMETRY;
    else if (u < 0.96)
        k = K_PAUSE;
    else if (u < 0.98)
        k = K_RESET;
    else
        k = K_SETPOINT;
    double f[AFM_MAX_TONES], a[AFM_MAX_TONES];
    switch (k) {
    case K_SETPOINT: /* 1 um down to indentation (the free amplitude is ~50 nm) */
        send_setpoint(c, log_uni(c, 12e-9, 1e-6), 0.0);
        break;
    case K_RAMP:
        send_setpoint(c, log_uni(c, 12e-9, 1e-6), log_uni(c, 1e-5, 1e-2));
        break;
    case K_FREQ:
        f[0] = c->f1 + uni(c, -5e3, 5e3);
        a[0] = c->a1;
        send_dither(c, 1, f, a);
        break;
    case K_AMP:
        f[0] = c->f1;
        a[0] = c->a1 * uni(c, 0.3, 1.7); /* 15-85 nm free */
        send_dither(c, 1, f, a);
        break;
    case K_MULTI: {
        int n = 2 + (int)(rnd(c) % 3);
        f[0] = c->f1 + uni(c, -2e3, 2e3);
        a[0] = c->a1;
        for (int j = 1; j < n; j++) {
            f[j] = log_uni(c, 1e5, 3e6);
            a[j] = uni(c, 0.001e-9, 0.02e-9);
        }
        send_dither(c, n, f, a);
        break;
    }
    case K_FORCE:
        if (rnd(c) & 1)
            send_param(c, "forces.viscoelastic.eta_pa_s", uni(c, 400, 1200));
        else
            send_param(c, "forces.vdw_contact.hamaker_j", uni(c, 1.0e-19, 2.0e-19));
        break;
    case K_DAMPING:
        send_param(c, "model.damping_ratio[0]", c->zeta1 * uni(c, 0.8, 1.25));
        break;
    case K_GEOMETRY:
        send_param(c, "model.beam.length_m", c->length_m * uni(c, 0.99, 1.01));
        c->last_geometry = now;
        break;
    case K_PAUSE:
        send_control(c, AFMTWIN_CONTROL_T_PAUSE, 0);
        c->paused = true;
        break;
    case K_RESET:
        send_control(c, AFMTWIN_CONTROL_T_RESET, 0);
        break;
    }
    return k;
}

static void recent_text(const soak_ctx *c, double now, char *buf, size_t len) {
    buf[0] = 0;
    for (int i = 0; i < 8 && i < c->n_recent; i++) {
        int k = (c->n_recent - 1 - i) % 8;
        if (now - c->recent_t[k] > 1.5) break;
        size_t n = strlen(buf);
        snprintf(buf + n, len - n, "%s%s %.2f s ago", n ? ", " : "", kind_name[c->recent[k]],
                 now - c->recent_t[k]);
    }
}

static void usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin soak --config FILE [--seconds S] [--seed N] [--max-rate-hz R]\n"
            "                    [--log LOG] [--block-us US] [--rt-priority N] [--lcm-url URL]\n"
            "                    [--lcm-out-url URL] [--lcm-samples-url URL] [--prefix NAME_]\n"
            "                    [--quiet]\n\n"
            "A bounded command soak of a running afmtwind (realtime mode): random valid\n"
            "commands of every kind (setpoint steps and ramps from 1 um down to indentation,\n"
            "frequency and amplitude steps, multi-tone, force, damping and geometry changes,\n"
            "pause / step / run, reset) at random intervals, at most R a second, for S seconds;\n"
            "drive amplitudes for free tip amplitudes of 15-85 nm (the model's linear response),\n"
            "Z from 1 um down to 12 nm.\n"
            "Pass: every status after the first %.1f s shows a real-time factor over the last\n"
            "second of running of at least F (--min-rtf) and no resync (a geometry rebuild may "
            "skip one\n"
            "block: counted and reported), every command is echoed (seq_applied) within\n"
            "%.0f ms and counted applied, none rejected, and every output is finite.\n\n"
            "options:\n"
            "  --config FILE     the daemon's config (sample rate, drive, beam length, damping)\n"
            "  --seconds S       length of the soak (default 30)\n"
            "  --seed N          generator seed (default 1)\n"
            "  --max-rate-hz R   commands a second at most, 1..1000 (default 1000)\n"
            "  --log LOG         write the commands sent to LOG (afmtwin lockstep, replay)\n"
            "  --block-us US     the daemon's --block-us (default 1000): the skip allowance\n"
            "  --min-rtf F       the real-time factor a status must show, 0.5..1 (default 0.99;\n"
            "                    make test's short soak: 0.9, a shared machine dips now and then)\n"
            "  --speed X         the daemon's --speed (default 1): the real-time factor is\n"
            "                    judged as a share of X (model s per wall s / X)\n"
            "  --rt-priority N   run at SCHED_FIFO N (default 0: normal scheduling, below the\n"
            "                    daemon; this tool decodes every output message)\n"
            "  --lcm-url URL, --lcm-out-url URL, --lcm-samples-url URL, --prefix NAME_  as for\n"
            "                    afmtwin listen\n"
            "  --quiet           no summary\n\n"
            "Exit status 0 pass, 1 fail, 2 bad usage.\n",
            SOAK_WARMUP_S, SOAK_ECHO_WAIT_S * 1e3);
}

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* --block-us US: the block length, stored in seconds. */
static int parse_block_us(const char *v, void *dest) {
    double d;
    if (afmt_parse_double(v, &d) || !(d >= 10 && d <= 1e6)) return -1;
    *(double *)dest = d * 1e-6;
    return 0;
}

int afm_cmd_soak(int argc, char **argv) {
    static soak_ctx c;
    memset(&c, 0, sizeof c);
    c.prefix = AFMT_DEFAULT_PREFIX;
    c.seconds = 30;
    c.max_rate_hz = 1000;
    c.block_s = 1e-3;
    c.seed = 1;
    c.min_rtf = INFINITY;
    c.min_rtf_ok = 0.99;
    c.speed = 1;
    c.echoed_seq = -1;
    const afmt_opt opts[] = {
        AFMT_FLAG("--quiet", &c.quiet),
        AFMT_STRING("--config", &c.config),
        AFMT_STRING("--log", &c.log),
        AFMT_LCM_OPTS(&c.url, &c.out_url, &c.samples_url, &c.prefix),
        AFMT_DOUBLE("--seconds", &c.seconds, 1, 1e5, "seconds in 1..1e5"),
        AFMT_NUMBER("--seed", AFMT_OPT_U64, &c.seed, 0, 1.8e19, "an integer >= 0"),
        AFMT_DOUBLE("--max-rate-hz", &c.max_rate_hz, 1, 1000, "1..1000 Hz"),
        AFMT_DOUBLE("--min-rtf", &c.min_rtf_ok, 0.5, 1, "a real-time factor in 0.5..1"),
        AFMT_DOUBLE("--speed", &c.speed, 1e-3, 1e3, "the daemon's --speed, 1e-3..1e3"),
        AFMT_FN("--block-us", parse_block_us, &c.block_s, "10..1e6 us"),
        AFMT_INT("--rt-priority", &c.rt_priority, 0, 99, "a SCHED_FIFO priority in 0..99"),
        AFMT_OPTS_END,
    };
    int prc = afmt_opts_parse("soak", opts, argc, argv, 1);
    if (prc == AFMT_OPTS_HELP) usage(stdout);
    if (prc) return prc == AFMT_OPTS_HELP ? 0 : 2;
    if (!c.config) {
        fprintf(stderr, "afmtwin soak: --config FILE is required (see --help)\n");
        return 2;
    }
    static afm_config cfg;
    char err[AFM_ERR_LEN];
    if (afmt_config_load("soak", c.config, &cfg)) return 2;
    c.fs = cfg.sim.sample_rate_hz;
    c.f1 = cfg.drive.tones[0].frequency_hz;
    {
        afm_modal m;
        double re = 0, im = 0;
        if (afm_model_build(&cfg.model, &m, err, sizeof err)) {
            fprintf(stderr, "afmtwin soak: %s\n", err);
            return 2;
        }
        afm_model_tip_response(&m, 6.283185307179586 * c.f1, &re, &im);
        c.a1 = 50e-9 / hypot(re, im); /* 50 nm free amplitude */
    }
    c.length_m = cfg.model.beam.length_m;
    c.zeta1 = cfg.model.damping_ratio[0];
    c.rng = c.seed * 0x9E3779B97F4A7C15ULL + 0x2545F4914F6CDD1DULL;
    if (afmt_channels_init(&c.ch, c.prefix, err, sizeof err)) goto usage_err;
    /* Normal scheduling: this tool reads every output message (finite checks), and at a
     * real-time priority above the daemon's threads that work came out of the integrator's
     * core (blocks late). Below them it takes what they leave; its echo times then include
     * waiting for a CPU (the 250 ms bound leaves room). --rt-priority N puts it above. */
    if (c.rt_priority > 0) {
        struct sched_param prio = {.sched_priority = c.rt_priority};
        sched_setscheduler(0, SCHED_FIFO | SOAK_RESET_ON_FORK, &prio);
    }
    int orc = afmt_lcm_open(&c.lcm, c.url, c.out_url, c.samples_url,
                            AFMT_OPEN_CMD | AFMT_OPEN_SAMPLES, err, sizeof err);
    if (orc == -1) goto usage_err;
    if (orc) {
        fprintf(stderr, "afmtwin soak: %s\n", err);
        return 1;
    }
    /* Behind the wire checks (lcm_tool.h): a crafted output message is counted, not decoded. */
    afmt_checked_sub subs[3] = {{&afm_wire_status_t, on_status, &c, 0},
                                {&afm_wire_samples_t, on_samples, &c, 0},
                                {&afm_wire_harmonics_t, on_harm, &c, 0}};
    afmt_subscribe_checked(c.lcm.out, c.ch.out[AFMT_OUT_STATUS], &subs[0], 1000);
    afmt_subscribe_checked(c.lcm.samples, c.ch.out[AFMT_OUT_SAMPLES], &subs[1], 20000);
    afmt_subscribe_checked(c.lcm.out, c.ch.out[AFMT_OUT_HARMONICS], &subs[2], 20000);
    if (c.log && !(c.logf = lcm_eventlog_create(c.log, "w"))) {
        fprintf(stderr, "afmtwin soak: cannot write '%s'\n", c.log);
        return 1;
    }
    c.t_start = afmt_mono_s();
    c.last_geometry = -1e9;
    for (int i = 0; i < 50 && !c.have_status; i++)
        pump(&c, 0.1);
    if (!c.have_status) {
        fprintf(stderr, "afmtwin soak: no status from the daemon within 5 s\n");
        return 1;
    }
    /* the daemon's own counts before the soak */
    long long rx0 = c.last.received, ap0 = c.last.applied, rej0 = c.last.rejected;
    c.echoed_seq = c.seq = 0;
    while (afmt_mono_s() - c.t_start < c.seconds) {
        /* next interval: mostly tens of ms, sometimes a burst at the full rate */
        double gap = rnd(&c) % 8 == 0 ? 1.0 / c.max_rate_hz : log_uni(&c, 1.0 / c.max_rate_hz, 0.2);
        pump(&c, gap);
        int k = one_command(&c);
        c.recent[c.n_recent % 8] = k;
        c.recent_t[c.n_recent++ % 8] = afmt_mono_s();
        c.sent[k]++;
        c.n_sent++;
        double t0 = afmt_mono_s();
        while (c.echoed_seq < c.seq && afmt_mono_s() - t0 < SOAK_ECHO_WAIT_S)
            afmt_lcm_handle(&c.lcm, 5);
        if (c.echoed_seq < c.seq) {
            if (c.unechoed++ < 10)
                fprintf(stderr, "afmtwin soak: command %lld (%s) not echoed within %.0f ms\n",
                        (long long)c.seq, kind_name[k], SOAK_ECHO_WAIT_S * 1e3);
        } else if (c.n_lat < (long long)(sizeof c.echo_lat / sizeof c.echo_lat[0])) {
            c.echo_lat[c.n_lat++] = afmt_mono_s() - t0;
        }
    }
    if (c.paused) { /* leave it running */
        send_control(&c, AFMTWIN_CONTROL_T_RUN, 0);
        c.sent[K_RUN]++;
        c.n_sent++;
    }
    pump(&c, 0.5);
    if (c.logf) lcm_eventlog_destroy(c.logf);
    long long rx = c.last.received - rx0, ap = c.last.applied - ap0, rej = c.last.rejected - rej0;
    bool counts_ok = rx == c.n_sent && ap == c.n_sent && rej == 0;
    bool pass = counts_ok && c.bad_windows == 0 && c.unechoed == 0 && c.nonfinite == 0 &&
                c.windows > 0 && c.geometry_skips <= c.sent[K_GEOMETRY];
    qsort(c.echo_lat, (size_t)c.n_lat, sizeof c.echo_lat[0], cmp_d);
    if (!c.quiet) {
        printf("afmtwin soak: %s, %.0f s, seed %llu: %lld commands (", c.config, c.seconds,
               (unsigned long long)c.seed, c.n_sent);
        for (int k = 0; k < N_KINDS; k++)
            printf("%s%s %lld", k ? ", " : "", kind_name[k], c.sent[k]);
        printf(")\n");
        printf("  real time: %lld status windows checked, real-time factor of the last second "
               "min %.4f of the speed asked for (>= %g: %s); resyncs %lld (%.3g ms skipped), %lld "
               "of them right after "
               "a geometry rebuild (one block allowed each)\n",
               c.windows, c.min_rtf, c.min_rtf_ok, c.bad_windows ? "NO" : "yes",
               c.resyncs_last - c.resyncs0, (c.skipped_last - c.skipped0) * 1e3, c.geometry_skips);
        printf("  commands: daemon received %lld, applied %lld, rejected %lld of %lld sent; "
               "echoed %lld (not within %.0f ms: %lld); echo p50 %.2f ms, p99 %.2f ms, max %.2f "
               "ms\n",
               rx, ap, rej, c.n_sent, c.n_sent - c.unechoed, SOAK_ECHO_WAIT_S * 1e3, c.unechoed,
               c.n_lat ? c.echo_lat[(c.n_lat - 1) / 2] * 1e3 : NAN,
               c.n_lat ? c.echo_lat[(long long)ceil(0.99 * c.n_lat) - 1] * 1e3 : NAN,
               c.n_lat ? c.echo_lat[c.n_lat - 1] * 1e3 : NAN);
        printf("  outputs: %lld samples and %lld harmonics messages, %lld non-finite values\n",
               c.samples_msgs, c.harm_msgs, c.nonfinite);
        printf("  %s\n", pass ? "PASS" : "FAIL");
    }
    afmt_lcm_close(&c.lcm);
    return pass ? 0 : 1;
usage_err:
    fprintf(stderr, "afmtwin soak: %s\n", err);
    return 2;
}
