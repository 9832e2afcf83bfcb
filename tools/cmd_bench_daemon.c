/* SPDX-License-Identifier: MIT */
/* cmd_bench_daemon.c -- `afmtwin bench-daemon`: what afmtwind sustains, measured from
 * outside over LCM inside a private network namespace: the real-time factor while tapping
 * with all outputs on (overruns, lag), and the latency from a setpoint command to the first
 * samples message that reflects it (p50, p99, max).
 *
 * Method, per config: start the daemon (realtime mode, default outputs), make it tap
 * (tone 0 at the model's f1, 50 nm free amplitude, Z = 35 nm, as the integrator bench's NCHV
 * case), wait 1 s, then (a) read status for --seconds: real-time factor = model time
 * advanced / wall time between the first and last status received here; overruns and lag
 * from the daemon's status; (b) send --commands setpoints (Z alternating 35 / 35.5 nm, each
 * with a new seq) one after the other, each after a pseudo-random pause of 0..2 ms (so that
 * commands land at every phase of the daemon's block), and time on CLOCK_MONOTONIC from
 * just before lcm_publish to the arrival of the first samples message whose seq_applied is
 * the command's. Both clocks are this process's, so no clock offsets enter.
 *
 * Then lockstep co-simulation: the daemon in --mode lockstep, tapping as above, driven by
 * `afmtwin lockstep --bench` (in this process) with ticks of 1 ms and of 0.1 ms of model time,
 * each sent after the previous one's completion (tick_done_t) arrived: ticks per second and
 * model time over wall time, against the targets 0.9 (1 ms) and 0.3 (0.1 ms); --no-lockstep
 * leaves it out (the latency alone in ~20 s a config). */
#include "afmtwin_cmds.h"
#include "lcm_tool.h"
#include "opts.h"

#include "afmtwin_harmonics_t.h"
#include "afmtwin_samples_t.h"
#include "afmtwin_setpoint_t.h"
#include "afmtwin_dither_t.h"
#include "afmtwin_status_t.h"

#include <errno.h>
#include <fcntl.h>
#include <lcm/lcm.h>
#include <math.h>
#include <sched.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

/* The default command URL (--lcm-url): LCM's group and port with 4 MiB receive buffers; the
 * outputs then go to port 7668 and the samples to 7669 (afm_lcm_urls, afm_lcm_samples_urls:
 * the command URL with the port + 1 and + 2, afmtwind's defaults too, afmtwin_lcm_layout.h),
 * so that the daemon's command socket carries commands only. */
#define BD_URL "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304"
#define BD_MAX_CMDS 100000
#define BD_CLIENT_PRIO 90 /* above afmtwind's threads (80 and below) */
#define BD_CLIENT_PRIO_TEXT "90"
#ifdef SCHED_RESET_ON_FORK
#define BD_RESET_ON_FORK SCHED_RESET_ON_FORK
#else
#define BD_RESET_ON_FORK 0x40000000 /* Linux's value (sched.h hides it without _GNU_SOURCE) */
#endif
#define BD_WAIT_S 0.25          /* a command not seen applied by then counts as lost */
#define BD_TAP_FREQ_HZ 338112.0 /* model f1 of the NCHV beam (`afmtwin modes`) */
#define BD_TAP_AMP_M 0.087e-9   /* 50 nm free amplitude at f1 (config/default.conf) */
#define BD_TAP_Z_M 35e-9        /* Z = 0.7 x free amplitude */

typedef struct {
    const char *daemon;
    const char *url, *out_url, *samples_url, *prefix; /* as given (NULL: default), passed on */
    afmt_channels ch;                                 /* of prefix */
    const char *configs[8];
    int n_configs;
    int commands;
    double seconds;
    bool inside, json;
    bool no_lockstep; /* --no-lockstep: parts (a)-(c) only */
} bd_opts;

/* What one status says about keeping up: received at wall_s (this process's
 * CLOCK_MONOTONIC, s) at the daemon's model time model_s (s), its counters then. */
typedef struct {
    double wall_s, model_s;
    long long overruns, stalls, resyncs;
} bd_point;

typedef struct {
    /* status */
    int n_status;
    bd_point first, last; /* the first and the last status of the window */
    long long last_rejected, last_received, last_applied;
    double last_lag, last_rtf;
    /* harmonics (tapping check) */
    double contact_time_s, indentation_m, lockin_m;
    int n_harm;
    char scheme[16]; /* the rt scheme the daemon runs (status rt_scheme) */
    /* latency */
    int64_t want_seq;
    bool got;
    double t_got;
} bd_state;

static void bd_usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin bench-daemon [--daemon PATH] [--config FILE]... [--commands N]\n"
            "                            [--seconds S] [--json] [--no-netns] [--no-lockstep]\n"
            "                            [--lcm-url URL] [--lcm-out-url URL]\n"
            "                            [--lcm-samples-url URL] [--prefix NAME_]\n\n"
            "Benchmarks the running daemon from outside, over LCM, inside a private network\n"
            "namespace (unshare -n; loopback with a multicast route, nothing else):\n"
            "  real-time factor  model seconds per wall second while tapping with all outputs\n"
            "                    on (samples of every stream, harmonics, status), with the\n"
            "                    daemon's overruns and lag\n"
            "  latency           from sending a setpoint to the first samples message that\n"
            "                    carries its seq (p50, p99, max over N commands); the daemon's\n"
            "                    goal is p99 within one output block + 200 us\n"
            "  lockstep          afmtwind --mode lockstep driven by afmtwin lockstep --bench:\n"
            "                    ticks of 1 ms and 0.1 ms, each sent when the previous one's\n"
            "                    completion arrived; ticks/s and x real time (targets 0.9\n"
            "                    and 0.3), in lockstep's auto scheme (accurate: no deadline)\n"
            "                    and in the fast one, unpinned and with the round trip on\n"
            "                    CPU 0; a tick cannot run faster than its scheme integrates\n\n"
            "options:\n"
            "  --daemon PATH   afmtwind to run (default: afmtwind next to this afmtwin)\n"
            "  --config FILE   config to run (repeatable; default config/nchv.conf and\n"
            "                  config/default.conf); the twin is set to tap: tone 0 at\n"
            "                  338.112 kHz, 0.087 nm (50 nm free), Z 35 nm\n"
            "  --commands N    setpoint commands for the latency (default 1000, >= 10)\n"
            "  --seconds S     real-time factor window (default 5)\n"
            "  --json          one JSON object per config (and per lockstep run)\n"
            "  --lcm-url URL   the daemon's command URL, given to afmtwind and lockstep\n"
            "                  (default " BD_URL ")\n"
            "  --lcm-out-url URL  its output URL (default: --lcm-url with the udpm port + 1)\n"
            "  --lcm-samples-url URL  its sample stream's URL (default: --lcm-url with the udpm\n"
            "                  port + 2)\n"
            "  --prefix NAME_  channel-name prefix, given to afmtwind (default " AFMT_DEFAULT_PREFIX
            ")\n"
            "  --no-netns      run in the current network namespace (already private)\n"
            "  --no-lockstep   leave out the lockstep runs (the real-time factor and the\n"
            "                  latency only: ~20 s a config instead of ~1 min)\n"
            "  --help          this text\n\n"
            "Exit status 0 when every run completed (whatever the numbers), 1 otherwise.\n");
}

/* ---- LCM handlers ---------------------------------------------------------------------- */

static void on_status(const void *msg, void *u) {
    const afmtwin_status_t *m = msg;
    bd_state *s = u;
    bd_point p = {.wall_s = afmt_mono_s(),
                  .model_s = m->model_time_s,
                  .overruns = m->overruns,
                  .stalls = m->chain_stalls,
                  .resyncs = m->resyncs};
    if (s->n_status++ == 0) s->first = p;
    s->last = p;
    s->last_applied = m->applied;
    s->last_lag = m->lag_s;
    s->last_rtf = m->realtime_factor;
    s->last_rejected = m->rejected;
    s->last_received = m->received;
    snprintf(s->scheme, sizeof s->scheme, "%s", m->rt_scheme ? m->rt_scheme : "?");
}

static void on_harm(const void *msg, void *u) {
    const afmtwin_harmonics_t *m = msg;
    bd_state *s = u;
    s->contact_time_s = m->contact_time_s;
    s->indentation_m = m->indentation_m;
    s->lockin_m = m->lockin_amplitude_m;
    s->n_harm++;
}

static void on_samples(const void *msg, void *u) {
    const afmtwin_samples_t *m = msg;
    bd_state *s = u;
    if (!s->got && s->want_seq >= 0 && m->seq_applied == s->want_seq) {
        s->got = true;
        s->t_got = afmt_mono_s();
    }
}

static void pump(afmt_lcm *l, double seconds) {
    double end = afmt_mono_s() + seconds;
    for (;;) {
        double left = end - afmt_mono_s();
        if (left <= 0) return;
        afmt_lcm_handle(l, (int)ceil(left * 1e3));
    }
}

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* ---- one config ------------------------------------------------------------------------ */

typedef struct {
    bool ok;
    char err[256];
    double rtf, overruns_per_s, lag_s, block_s;
    long long overruns;
    double contact_time_s, indentation_m, lockin_m;
    int n_lat, lost;
    double p50, p99, max, mean;
    long long rejected, received, applied, sent;
    long long chain_stalls, resyncs;
    long long burst_sent, burst_received, burst_applied;
    bool client_fifo; /* this client ran at SCHED_FIFO BD_CLIENT_PRIO */
    char warn[512];
} bd_result;

/* Runs afmtwind on config with this bench's URLs and prefix, its stderr to errfile (NULL:
 * /dev/null), plus the extra arguments (NULL-terminated, up to 16). The child's pid, or -1. */
static pid_t start_daemon(const bd_opts *o, const char *config, const char *errfile,
                          const char *const *extra) {
    pid_t pid = fork();
    if (pid != 0) return pid;
    int fd =
        errfile ? open(errfile, O_WRONLY | O_CREAT | O_TRUNC, 0600) : open("/dev/null", O_WRONLY);
    if (fd >= 0) {
        dup2(fd, 2);
        close(fd);
    }
    const char *argv[32];
    int n = 0;
    argv[n++] = o->daemon;
    argv[n++] = "--config";
    argv[n++] = config;
    argv[n++] = "--lcm-url";
    argv[n++] = o->url;
    if (o->out_url) {
        argv[n++] = "--lcm-out-url";
        argv[n++] = o->out_url;
    }
    if (o->samples_url) {
        argv[n++] = "--lcm-samples-url";
        argv[n++] = o->samples_url;
    }
    argv[n++] = "--prefix";
    argv[n++] = o->prefix;
    argv[n++] = "--quiet";
    for (int i = 0; extra && extra[i] && i < 16; i++)
        argv[n++] = extra[i];
    argv[n] = NULL;
    execv(o->daemon, (char *const *)argv);
    fprintf(stderr, "cannot run %s: %s\n", o->daemon, strerror(errno));
    _exit(127);
}

static void read_warnings(const char *errfile, char *out, size_t len) {
    FILE *f = fopen(errfile, "r");
    out[0] = 0;
    if (!f) return;
    char line[512];
    while (fgets(line, sizeof line, f)) {
        char *w = strstr(line, "warning:");
        if (w && strlen(out) + strlen(w) + 2 < len) {
            line[strcspn(line, "\n")] = 0;
            strcat(out, out[0] ? "; " : "");
            strcat(out, w + 9);
        }
    }
    fclose(f);
}

static double block_from_errfile(const char *errfile) {
    FILE *f = fopen(errfile, "r");
    if (!f) return NAN;
    char line[512];
    double us = NAN;
    while (fgets(line, sizeof line, f)) {
        char *b = strstr(line, "samples (");
        if (b && sscanf(b, "samples (%lf us)", &us) == 1) break;
    }
    fclose(f);
    return us * 1e-6;
}

/* The tapping operating point: tone 0 at f1 for 50 nm free, Z 35 nm (seq 1 and 2). */
static void send_tap(const bd_opts *o, lcm_t *cmd) {
    double f = BD_TAP_FREQ_HZ, a = BD_TAP_AMP_M, ph = 0;
    afmtwin_dither_t dm = {.utime = afmt_wall_us(),
                           .seq = 1,
                           .n_tones = 1,
                           .frequency_hz = &f,
                           .amplitude_m = &a,
                           .phase_rad = &ph};
    afmtwin_setpoint_t sp = {.utime = afmt_wall_us(), .seq = 2, .separation_m = BD_TAP_Z_M};
    afmtwin_dither_t_publish(cmd, o->ch.cmd[AFM_CMD_DITHER], &dm);
    afmtwin_setpoint_t_publish(cmd, o->ch.cmd[AFM_CMD_SETPOINT], &sp);
}

/* Back to normal scheduling after a config's run. */
static void client_normal(const bd_result *r) {
    if (!r->client_fifo) return;
    struct sched_param p0 = {.sched_priority = 0};
    sched_setscheduler(0, SCHED_OTHER, &p0);
}

/* (a) The real-time factor over o->seconds of status: model time advanced / wall time
 * between the first and last status received here; overruns, stalls, resyncs and lag from
 * the daemon's status, and the tapping check from its harmonics. 0, or -1 with r->err. */
static int measure_rtf(const bd_opts *o, afmt_lcm *lcm, bd_state *s, bd_result *r) {
    s->n_status = 0;
    pump(lcm, o->seconds);
    if (s->n_status < 2 || s->last.wall_s <= s->first.wall_s) {
        snprintf(r->err, sizeof r->err, "too few status messages (%d)", s->n_status);
        return -1;
    }
    double wall_s = s->last.wall_s - s->first.wall_s;
    r->rtf = (s->last.model_s - s->first.model_s) / wall_s;
    r->overruns = s->last.overruns - s->first.overruns;
    r->overruns_per_s = (double)r->overruns / wall_s;
    r->chain_stalls = s->last.stalls - s->first.stalls;
    r->resyncs = s->last.resyncs - s->first.resyncs;
    r->lag_s = s->last_lag;
    r->contact_time_s = s->contact_time_s;
    r->indentation_m = s->indentation_m;
    r->lockin_m = s->lockin_m;
    return 0;
}

/* (b) Latency: o->commands setpoints (Z 35 / 35.5 nm), each after a pseudo-random pause of
 * 0..2 ms, timed from just before publishing to the first samples message that carries its
 * seq (lost after BD_WAIT_S); p50, p99, max and mean (s). */
static void measure_latency(const bd_opts *o, afmt_lcm *lcm, bd_state *s, bd_result *r) {
    static double lat[BD_MAX_CMDS];
    unsigned long long lcg = 12345;
    for (int i = 0; i < o->commands; i++) {
        lcg = lcg * 6364136223846793005ULL + 1442695040888963407ULL;
        pump(lcm, (double)(lcg >> 40) / (double)(1ULL << 24) * 2e-3);
        afmtwin_setpoint_t c = {
            .utime = afmt_wall_us(), .seq = 100 + i, .separation_m = (i & 1) ? 35.5e-9 : 35e-9};
        s->want_seq = c.seq;
        s->got = false;
        double t0 = afmt_mono_s();
        afmtwin_setpoint_t_publish(lcm->cmd, o->ch.cmd[AFM_CMD_SETPOINT], &c);
        r->sent++;
        while (!s->got && afmt_mono_s() - t0 < BD_WAIT_S)
            afmt_lcm_handle(lcm, 100);
        if (s->got)
            lat[r->n_lat++] = s->t_got - t0;
        else
            r->lost++;
    }
    if (r->n_lat == 0) return;
    double sum = 0;
    for (int i = 0; i < r->n_lat; i++)
        sum += lat[i];
    qsort(lat, (size_t)r->n_lat, sizeof lat[0], cmp_d);
    r->p50 = lat[(r->n_lat - 1) / 2];
    r->p99 = lat[(int)ceil(0.99 * r->n_lat) - 1];
    r->max = lat[r->n_lat - 1];
    r->mean = sum / r->n_lat;
}

/* (c) Loss under load: a burst of o->commands setpoints 100 us apart (10 per 1 ms block,
 * well inside the command queue) while all outputs flow; every one must be applied. */
static void measure_burst(const bd_opts *o, afmt_lcm *lcm, bd_state *s, bd_result *r) {
    pump(lcm, 0.3);
    long long applied0 = s->last_applied, received0 = s->last_received;
    for (int i = 0; i < o->commands; i++) {
        afmtwin_setpoint_t c = {
            .utime = afmt_wall_us(), .seq = 1000000 + i, .separation_m = (i & 1) ? 35.5e-9 : 35e-9};
        afmtwin_setpoint_t_publish(lcm->cmd, o->ch.cmd[AFM_CMD_SETPOINT], &c);
        r->sent++;
        pump(lcm, 100e-6);
    }
    pump(lcm, 0.5);
    r->burst_sent = o->commands;
    r->burst_received = s->last_received - received0;
    r->burst_applied = s->last_applied - applied0;
}

/* SIGTERM to the daemon and wait: an unclean exit fails a run that was ok. */
static void stop_daemon(pid_t pid, bd_result *r) {
    kill(pid, SIGTERM);
    int st = 0;
    waitpid(pid, &st, 0);
    if (r->ok && !(WIFEXITED(st) && WEXITSTATUS(st) == 0)) {
        r->ok = false;
        snprintf(r->err, sizeof r->err, "the daemon did not exit cleanly (status %d)", st);
    }
}

/* One config: start the daemon, wait for its status, make it tap, then (a), (b), (c) of
 * the file's comment; fills r (r->ok, or r->err). */
static void bench_config(const bd_opts *o, const char *config, bd_result *r) {
    memset(r, 0, sizeof *r);
    char errfile[] = "/tmp/afmtwin-bench-daemon.XXXXXX";
    int efd = mkstemp(errfile);
    if (efd >= 0) close(efd);
    /* The client runs above the daemon's SCHED_FIFO threads, as a HIL controller on the same
     * host must: on two cores, busy daemon threads would otherwise keep a normal-priority
     * thread off the CPU until the integrator sleeps at the end of its block, and the latency
     * measured would be the scheduler's, not the daemon's. Set before lcm_create, so that
     * LCM's own receive thread inherits it; SCHED_RESET_ON_FORK keeps it from the daemon. */
    struct sched_param prio = {.sched_priority = BD_CLIENT_PRIO};
    r->client_fifo = sched_setscheduler(0, SCHED_FIFO | BD_RESET_ON_FORK, &prio) == 0;
    afmt_lcm lcm; /* outputs in (the samples on their own URL); commands out (never subscribed) */
    if (afmt_lcm_open(&lcm, o->url, o->out_url, o->samples_url, AFMT_OPEN_CMD | AFMT_OPEN_SAMPLES,
                      r->err, sizeof r->err)) {
        unlink(errfile);
        client_normal(r);
        return;
    }
    bd_state s = {.want_seq = -1};
    /* Raw subscriptions behind the wire checks (lcm_tool.h): crafted output messages are
     * counted, never decoded unchecked. */
    afmt_checked_sub subs[3] = {{&afm_wire_status_t, on_status, &s, 0},
                                {&afm_wire_harmonics_t, on_harm, &s, 0},
                                {&afm_wire_samples_t, on_samples, &s, 0}};
    afmt_subscribe_checked(lcm.out, o->ch.out[AFMT_OUT_STATUS], &subs[0], 1000);
    afmt_subscribe_checked(lcm.out, o->ch.out[AFMT_OUT_HARMONICS], &subs[1], 10000);
    afmt_subscribe_checked(lcm.samples, o->ch.out[AFMT_OUT_SAMPLES], &subs[2], 10000);
    pid_t pid = start_daemon(o, config, errfile, NULL);
    if (pid < 0) {
        snprintf(r->err, sizeof r->err, "fork failed");
    } else {
        for (int i = 0; i < 50 && s.n_status == 0; i++) /* up? */
            pump(&lcm, 0.1);
        if (s.n_status == 0) {
            snprintf(r->err, sizeof r->err, "no status from %s within 5 s", o->daemon);
        } else {
            r->block_s = block_from_errfile(errfile);
            send_tap(o, lcm.cmd);
            r->sent = 2;
            pump(&lcm, 1.0);
            if (measure_rtf(o, &lcm, &s, r) == 0) {
                measure_latency(o, &lcm, &s, r);
                measure_burst(o, &lcm, &s, r);
                r->rejected = s.last_rejected;
                r->received = s.last_received;
                r->applied = s.last_applied;
                r->ok = r->n_lat > 0;
                if (!r->ok) snprintf(r->err, sizeof r->err, "no command was seen applied");
            }
        }
        stop_daemon(pid, r);
        read_warnings(errfile, r->warn, sizeof r->warn);
    }
    afmt_lcm_close(&lcm);
    unlink(errfile);
    client_normal(r);
}

/* ---- lockstep -------------------------------------------------------------------------- */

/* Lockstep co-simulation throughput on one config (text or JSON lines from afmtwin
 * lockstep --bench), in the scheme lockstep's auto takes (the accurate one: lockstep has no
 * deadline) and in the fast one, each unpinned and with the round trip's hand-overs kept on
 * one core (the integrator, receive and publish threads and the client on CPU 0, the chain on
 * CPU 1: a wake-up across cores costs ~24 us on this VM, on one core ~4 us). The targets
 * (0.9 x with 1 ms ticks, 0.3 x with 0.1 ms) are of the round trip's overhead; a tick cannot
 * run faster than its scheme integrates (`afmtwin bench-scheme`). Returns 0, or 1 when a
 * run failed. */
static int bench_lockstep(const bd_opts *o, const char *config) {
    static const char *const schemes[2] = {"auto", "fast"};
    int rc = 0;
    if (!o->json)
        printf("  lockstep (afmtwind --mode lockstep; each tick sent after the previous one's "
               "completion arrived; targets 0.9 x real time with 1 ms ticks, 0.3 x with 0.1 ms; "
               "a tick is bounded by its scheme's integration cost):\n");
    for (int run = 0; run < 4 && rc == 0; run++) {
        const int sch = run / 2, pin = run % 2;
        const char *extra[] = {"--mode",      "lockstep", "--scheme",  schemes[sch], "--cpu", "0",
                               "--chain-cpu", "1",        "--aux-cpu", "0",          NULL};
        if (!pin) extra[4] = NULL; /* unpinned: the CPU plan left out */
        pid_t pid = start_daemon(o, config, NULL, extra);
        afmt_lcm lcm = {0};
        char err[256];
        if (pid < 0 || afmt_lcm_open(&lcm, o->url, o->out_url, o->samples_url, AFMT_OPEN_CMD, err,
                                     sizeof err)) {
            if (pid > 0) {
                kill(pid, SIGTERM);
                waitpid(pid, NULL, 0);
            }
            rc = 1;
            break;
        }
        bd_state st = {.want_seq = -1}; /* up: its status arrives */
        afmt_checked_sub sub = {&afm_wire_status_t, on_status, &st, 0};
        afmt_subscribe_checked(lcm.out, o->ch.out[AFMT_OUT_STATUS], &sub, 1000);
        for (int i = 0; i < 100 && st.n_status == 0; i++)
            pump(&lcm, 0.1);
        send_tap(o, lcm.cmd); /* applied with the first tick */
        afmt_lcm_close(&lcm); /* and the subscription */
        if (o->json)
            printf("{\"config\":\"%s\",\"lockstep_scheme_option\":\"%s\",\"lockstep_scheme\":"
                   "\"%s\",\"pinned\":%s}\n",
                   config, schemes[sch], st.scheme[0] ? st.scheme : "?", pin ? "true" : "false");
        else
            printf("   --scheme %s (runs %s), %s:\n", schemes[sch], st.scheme[0] ? st.scheme : "?",
                   pin ? "pinned (afmtwind --cpu 0 --chain-cpu 1 --aux-cpu 0, "
                         "afmtwin lockstep --cpu 0)"
                       : "unpinned");
        static const char *const ticks[2] = {"1000", "100"};
        for (int k = 0; k < 2; k++) {
            char secs[32];
            snprintf(secs, sizeof secs, "%g", o->seconds > 3 ? 3.0 : o->seconds);
            char *argv[24];
            int argc = 0;
            argv[argc++] = "lockstep";
            argv[argc++] = "--bench";
            argv[argc++] = secs;
            argv[argc++] = "--tick-us";
            argv[argc++] = (char *)ticks[k];
            argv[argc++] = "--lcm-url";
            argv[argc++] = (char *)o->url;
            if (o->out_url) {
                argv[argc++] = "--lcm-out-url";
                argv[argc++] = (char *)o->out_url;
            }
            if (o->samples_url) {
                argv[argc++] = "--lcm-samples-url";
                argv[argc++] = (char *)o->samples_url;
            }
            argv[argc++] = "--prefix";
            argv[argc++] = (char *)o->prefix;
            argv[argc++] = "--config";
            argv[argc++] = (char *)config;
            if (pin) {
                argv[argc++] = "--cpu";
                argv[argc++] = "0";
            }
            argv[argc++] = o->json ? "--json" : "--quiet";
            argv[argc] = NULL;
            fflush(stdout);
            if (afm_cmd_lockstep(argc, argv) != 0) rc = 1;
            fflush(stdout);
        }
        kill(pid, SIGTERM);
        waitpid(pid, NULL, 0);
    }
    return rc;
}

/* ---- driver ---------------------------------------------------------------------------- */

static int reexec_in_netns(int argc, char **argv) {
    static char self[4096];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0) {
        fprintf(stderr, "afmtwin bench-daemon: cannot find my own executable\n");
        return 1;
    }
    self[n] = 0;
    char *args[64];
    int k = 0;
    args[k++] = "unshare";
    args[k++] = "-n";
    args[k++] = "sh";
    args[k++] = "-c";
    args[k++] = "ip link set lo up && ip link set lo multicast on && "
                "ip route add 224.0.0.0/4 dev lo && exec \"$@\"";
    args[k++] = "afmtwin";
    args[k++] = self;
    args[k++] = "bench-daemon";
    args[k++] = "--inside";
    for (int i = 1; i < argc && k < 62; i++)
        args[k++] = argv[i];
    args[k] = NULL;
    fflush(stdout);
    execvp("unshare", args);
    fprintf(stderr,
            "afmtwin bench-daemon: cannot run unshare: %s (try --no-netns inside a "
            "private namespace)\n",
            strerror(errno));
    return 1;
}

/* --config FILE: one more of at most 8 configurations. */
static int add_config(const char *v, void *dest) {
    bd_opts *o = dest;
    if (o->n_configs >= 8) return -1;
    o->configs[o->n_configs++] = v;
    return 0;
}

int afm_cmd_bench_daemon(int argc, char **argv) {
    bd_opts o = {.commands = 1000, .seconds = 5.0, .url = BD_URL, .prefix = AFMT_DEFAULT_PREFIX};
    static char daemon_path[4096];
    bool no_netns = false;
    const afmt_opt opts[] = {
        AFMT_FLAG("--inside", &o.inside),
        AFMT_FLAG("--no-netns", &no_netns),
        AFMT_FLAG("--json", &o.json),
        AFMT_FLAG("--no-lockstep", &o.no_lockstep),
        AFMT_STRING("--daemon", &o.daemon),
        AFMT_LCM_OPTS(&o.url, &o.out_url, &o.samples_url, &o.prefix),
        AFMT_FN("--config", add_config, &o, "a file, 8 --config at most"),
        AFMT_INT("--commands", &o.commands, 10, BD_MAX_CMDS, NULL),
        AFMT_DOUBLE("--seconds", &o.seconds, 1, 3600, "1..3600"),
        AFMT_OPTS_END,
    };
    int prc = afmt_opts_parse("bench-daemon", opts, argc, argv, 1);
    if (prc == AFMT_OPTS_HELP) bd_usage(stdout);
    if (prc) return prc == AFMT_OPTS_HELP ? 0 : 2;
    char err[256];
    if (afmt_channels_init(&o.ch, o.prefix, err, sizeof err)) {
        fprintf(stderr, "afmtwin bench-daemon: %s\n", err);
        return 2;
    }
    if (!o.inside && !no_netns) return reexec_in_netns(argc, argv);
    if (!o.daemon) {
        ssize_t n = readlink("/proc/self/exe", daemon_path, sizeof daemon_path - 2);
        if (n <= 0) {
            fprintf(stderr, "afmtwin bench-daemon: give --daemon PATH\n");
            return 2;
        }
        daemon_path[n] = 0;
        strcat(daemon_path, "d"); /* .../afmtwin -> .../afmtwind */
        o.daemon = daemon_path;
    }
    if (access(o.daemon, X_OK)) {
        fprintf(stderr, "afmtwin bench-daemon: %s is not executable (give --daemon PATH)\n",
                o.daemon);
        return 2;
    }
    if (o.n_configs == 0) {
        o.configs[o.n_configs++] = "config/nchv.conf";
        o.configs[o.n_configs++] = "config/default.conf";
    }
    if (!o.json)
        printf("\nafmtwin bench-daemon: afmtwind in realtime mode over LCM (private network "
               "namespace), tapping at %.3f kHz, %.3g nm base amplitude, Z %.0f nm; %g s "
               "real-time window, %d setpoint commands\n",
               BD_TAP_FREQ_HZ * 1e-3, BD_TAP_AMP_M * 1e9, BD_TAP_Z_M * 1e9, o.seconds, o.commands);
    int rc = 0;
    for (int c = 0; c < o.n_configs; c++) {
        bd_result r;
        bench_config(&o, o.configs[c], &r);
        if (!r.ok) rc = 1;
        if (o.json) {
            printf("{\"config\":\"%s\",\"ok\":%s,\"error\":\"%s\",\"realtime_factor\":%.6g,"
                   "\"overruns\":%lld,\"overruns_per_s\":%.6g,\"lag_s\":%.6g,\"block_s\":%.6g,"
                   "\"tapping\":{\"contact_time_s\":%.6g,\"indentation_m\":%.6g,"
                   "\"lockin_amplitude_m\":%.6g},\"latency_s\":{\"n\":%d,\"lost\":%d,"
                   "\"p50\":%.6g,\"p99\":%.6g,\"max\":%.6g,\"mean\":%.6g},\"received\":%lld,"
                   "\"rejected\":%lld,\"applied\":%lld,\"sent\":%lld,\"chain_stalls\":%lld,"
                   "\"resyncs\":%lld,\"burst\":{\"sent\":%lld,\"received\":%lld,"
                   "\"applied\":%lld,\"lost\":%lld}}\n",
                   o.configs[c], r.ok ? "true" : "false", r.err, r.rtf, r.overruns,
                   r.overruns_per_s, r.lag_s, r.block_s, r.contact_time_s, r.indentation_m,
                   r.lockin_m, r.n_lat, r.lost, r.p50, r.p99, r.max, r.mean, r.received, r.rejected,
                   r.applied, r.sent, r.chain_stalls, r.resyncs, r.burst_sent, r.burst_received,
                   r.burst_applied, r.burst_sent - r.burst_applied);
            if (!o.no_lockstep) bench_lockstep(&o, o.configs[c]);
            continue;
        }
        printf("\n%s (daemon)", o.configs[c]);
        if (!r.ok) {
            printf(": FAILED: %s\n", r.err);
            continue;
        }
        printf(": block %.0f us\n", r.block_s * 1e6);
        printf("  tapping: lock-in amplitude %.4g nm, contact %.4g ns per period, indentation "
               "%.3g nm\n",
               r.lockin_m * 1e9, r.contact_time_s * 1e9, r.indentation_m * 1e9);
        /* Model time in status advances by whole blocks, so the factor over the window is
         * known to +-2 blocks / window; realtime mode never runs faster than 1.0. */
        double res = 2.0 * r.block_s / o.seconds;
        bool kept = r.rtf >= 1.0 - res && r.resyncs == 0;
        printf(
            "  real-time factor %.4f (+-%.4f: %s), overruns %lld in %.0f s (%.0f/s), lag %.3g s, "
            "chain stalls %lld, resyncs %lld\n",
            r.rtf, res, kept ? "real time sustained" : "BELOW real time", r.overruns, o.seconds,
            r.overruns_per_s, r.lag_s, r.chain_stalls, r.resyncs);
        double goal = r.block_s + 200e-6;
        printf("  setpoint -> first samples: p50 %.3f ms, p99 %.3f ms, max %.3f ms, mean %.3f ms "
               "(%d commands, %d not seen applied within %.0f ms)"
               "; goal p99 <= %.3f ms: %s\n",
               r.p50 * 1e3, r.p99 * 1e3, r.max * 1e3, r.mean * 1e3, r.n_lat, r.lost,
               BD_WAIT_S * 1e3, goal * 1e3, r.p99 <= goal ? "met" : "MISSED");
        printf("  (the client ran %s)\n",
               r.client_fifo ? "at SCHED_FIFO " BD_CLIENT_PRIO_TEXT " above the daemon's threads"
                             : "at normal priority: SCHED_FIFO refused (no CAP_SYS_NICE); "
                               "its receive times include waiting for a CPU");
        printf("  commands under load (%lld setpoints 100 us apart, all outputs on): received "
               "%lld, applied %lld, lost %lld; in all sent %lld, the daemon received %lld, "
               "applied %lld, rejected %lld\n",
               r.burst_sent, r.burst_received, r.burst_applied, r.burst_sent - r.burst_applied,
               r.sent, r.received, r.applied, r.rejected);
        if (r.warn[0]) printf("  daemon warnings: %s\n", r.warn);
        if (!o.no_lockstep && bench_lockstep(&o, o.configs[c])) rc = 1;
    }
    return rc;
}
