/* SPDX-License-Identifier: MIT */
/* afmtwind.c -- the daemon's main: options, start-up in order (config, memory lock,
 * runner, queues, transport, threads), signals, the once-a-second status line, and a clean
 * shutdown in reverse order. */
#include "twind.h"

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define CMD_Q_LEN 256
#define TRASH_Q_LEN 64
#define RTREJ_Q_LEN 64
#define SAMPLES_Q_LEN 256 /* records of up to AFM_IO_MAX_BLOCK samples (~8 MB in all) */
#define HARM_Q_LEN 4096

static void usage(FILE *f) {
    fprintf(f,
            "usage: afmtwind --config FILE [options]\n"
            "\n"
            "Runs the AFM cantilever twin and talks LCM: commands on PREFIX{DITHER,SETPOINT,\n"
            "PARAM,CONTROL,TICK}, outputs on PREFIX{SAMPLES,HARMONICS,STATUS}. Foreground;\n"
            "one status line a second on stderr. SIGTERM/SIGINT stop (a final status is\n"
            "published), SIGHUP reloads FILE (a bad file keeps the running config).\n"
            "\n"
            "options:\n"
            "  --config FILE          twin configuration (libconfig), required\n"
            "  --lcm-url URL          LCM provider URL (default: $LCM_DEFAULT_URL or udpm)\n"
            "  --mode M               realtime (default), freerun or lockstep\n"
            "  --prefix NAME_         channel prefix (default AFMTWIN_)\n"
            "  --cpu N                pin the real-time thread to CPU N\n"
            "  --rt-priority N        SCHED_FIFO priority 1..99 (default 80)\n"
            "  --block-us N           real-time block length in microseconds (default 1000)\n"
            "  --harmonics-every K    publish every K-th period's harmonics (default: auto,\n"
            "                         at most --harmonics-max-hz records a second)\n"
            "  --harmonics-max-hz F   cap for the automatic choice (default 1000)\n"
            "  --exit-after S         stop after S seconds, as on SIGTERM (tests)\n"
            "  --quiet                no status line\n"
            "  --help                 this text\n");
}

const char *twind_mode_name(twind_mode m) {
    switch (m) {
    case TWIND_REALTIME: return "realtime";
    case TWIND_FREERUN: return "freerun";
    case TWIND_LOCKSTEP: return "lockstep";
    }
    return "?";
}

int64_t twind_utime_now(void) {
    struct timespec t;
    clock_gettime(CLOCK_REALTIME, &t);
    return (int64_t)t.tv_sec * 1000000 + t.tv_nsec / 1000;
}

double twind_mono_now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int parse_num(const char *opt, const char *s, double lo, double hi, double *out) {
    char *end;
    errno = 0;
    double v = s ? strtod(s, &end) : NAN;
    if (!s || errno || end == s || *end || !(v >= lo && v <= hi)) {
        fprintf(stderr, "afmtwind: %s needs a number in [%g, %g], got '%s'\n", opt, lo, hi,
                s ? s : "(nothing)");
        return -1;
    }
    *out = v;
    return 0;
}

static int parse_args(int argc, char **argv, twind_opts *o) {
    *o = (twind_opts){.prefix = "AFMTWIN_", .mode = TWIND_REALTIME, .cpu = -1,
                      .rt_priority = 80, .block_s = 1e-3, .harmonics_max_hz = 1000.0};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        double x;
        if (!strcmp(a, "--help")) {
            usage(stdout);
            exit(0);
        } else if (!strcmp(a, "--quiet")) {
            o->quiet = 1;
            continue;
        } else if (!v) {
            fprintf(stderr, "afmtwind: unknown option or missing value: %s\n", a);
            return -1;
        } else if (!strcmp(a, "--config")) {
            o->config_path = v;
        } else if (!strcmp(a, "--lcm-url")) {
            o->lcm_url = v;
        } else if (!strcmp(a, "--prefix")) {
            o->prefix = v;
        } else if (!strcmp(a, "--mode")) {
            if (!strcmp(v, "realtime"))
                o->mode = TWIND_REALTIME;
            else if (!strcmp(v, "freerun"))
                o->mode = TWIND_FREERUN;
            else if (!strcmp(v, "lockstep"))
                o->mode = TWIND_LOCKSTEP;
            else {
                fprintf(stderr, "afmtwind: --mode must be realtime, freerun or lockstep, got '%s'\n", v);
                return -1;
            }
        } else if (!strcmp(a, "--cpu")) {
            if (parse_num(a, v, 0, 1023, &x) || x != floor(x)) return -1;
            o->cpu = (int)x;
        } else if (!strcmp(a, "--rt-priority")) {
            if (parse_num(a, v, 1, 99, &x) || x != floor(x)) return -1;
            o->rt_priority = (int)x;
        } else if (!strcmp(a, "--block-us")) {
            if (parse_num(a, v, 10, 1e6, &x)) return -1;
            o->block_s = x * 1e-6;
        } else if (!strcmp(a, "--harmonics-every")) {
            if (parse_num(a, v, 1, 1e9, &x) || x != floor(x)) return -1;
            o->harmonics_every = (int)x;
        } else if (!strcmp(a, "--harmonics-max-hz")) {
            if (parse_num(a, v, 1e-3, 1e9, &x)) return -1;
            o->harmonics_max_hz = x;
        } else if (!strcmp(a, "--exit-after")) {
            if (parse_num(a, v, 0, 1e9, &x)) return -1;
            o->exit_after_s = x;
        } else {
            fprintf(stderr, "afmtwind: unknown option %s (see --help)\n", a);
            return -1;
        }
        i++;
    }
    if (!o->config_path) {
        fprintf(stderr, "afmtwind: --config FILE is required (see --help)\n");
        return -1;
    }
    return 0;
}

static void status_line(twind *d, twind_rtf_state *rs, char *buf, size_t len) {
    afm_io_status s;
    twind_status_fill(d, &s, rs);
    twind_snapshot snap;
    twind_snap_read(d, &snap);
    snprintf(buf, len,
             "t %.6f s  rtf %.3f  busy %.0f%%  lag %.4f s  overruns %lld  rx %lld  rej %lld  "
             "blowups %lld  seq %lld  Z %.3f nm  fe %.1f Hz  A %.4g nm  %s",
             s.model_time_s, s.realtime_factor, 100.0 * snap.busy_fraction, s.lag_s,
             (long long)s.overruns, (long long)s.received, (long long)s.rejected,
             (long long)s.blowups, (long long)s.seq_applied, s.separation_m * 1e9, s.fe_hz,
             s.amplitude_m * 1e9, s.running ? "running" : "paused");
    if (snap.samples_dropped || snap.harm_dropped || snap.st.chain.periods_dropped) {
        size_t n = strlen(buf);
        snprintf(buf + n, len - n, "  DROPPED: %lld sample blocks, %lld harmonics, %lld periods",
                 snap.samples_dropped, snap.harm_dropped, snap.st.chain.periods_dropped);
    }
}

int main(int argc, char **argv) {
    static twind d; /* large (config copies); zero-initialised */
    char err[AFM_ERR_LEN];
    int rc = 1;
    if (parse_args(argc, argv, &d.opt)) {
        usage(stderr);
        return 2;
    }
    afm_config cfg;
    if (afm_config_load(d.opt.config_path, &cfg, err, sizeof err)) {
        fprintf(stderr, "afmtwind: %s\n", err);
        return 1;
    }
    d.shadow = cfg;

    /* Signals go to main only (sigtimedwait); threads inherit the mask. */
    sigset_t sigs;
    sigemptyset(&sigs);
    sigaddset(&sigs, SIGTERM);
    sigaddset(&sigs, SIGINT);
    sigaddset(&sigs, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &sigs, NULL);

    twind_rt_setup_process(d.rt_warn, sizeof d.rt_warn);
    long long block = llround(d.opt.block_s * cfg.sim.sample_rate_hz);
    if (block < 1) block = 1;
    if (block > (1 << 20)) block = 1 << 20;
    d.runner = afm_runner_create(&cfg, (int)block, d.opt.mode == TWIND_LOCKSTEP, err, sizeof err);
    if (!d.runner) {
        fprintf(stderr, "afmtwind: %s: %s\n", d.opt.config_path, err);
        return 1;
    }
    pthread_mutex_init(&d.lock, NULL);
    sem_init(&d.out_sem, 0, 0);
    if (afm_spsc_init(&d.cmd_q, CMD_Q_LEN, sizeof(twind_cmd_item), err, sizeof err) ||
        afm_spsc_init(&d.trash_q, TRASH_Q_LEN, sizeof(afm_runner_model *), err, sizeof err) ||
        afm_spsc_init(&d.rtrej_q, RTREJ_Q_LEN, sizeof(twind_reason), err, sizeof err) ||
        afm_spsc_init(&d.samples_q, SAMPLES_Q_LEN, sizeof(afm_io_samples), err, sizeof err) ||
        afm_spsc_init(&d.harm_q, HARM_Q_LEN, sizeof(afm_io_harmonics), err, sizeof err)) {
        fprintf(stderr, "afmtwind: %s\n", err);
        goto out;
    }
    afm_io_sink sink = twind_sink(&d);
    d.io = afm_lcm_io_create(d.opt.lcm_url, d.opt.prefix, &sink, err, sizeof err);
    if (!d.io) {
        fprintf(stderr, "afmtwind: %s\n", err);
        goto out;
    }
    pthread_t t_rt, t_recv, t_pub;
    if (pthread_create(&t_recv, NULL, twind_recv_main, &d) ||
        pthread_create(&t_pub, NULL, twind_pub_main, &d) ||
        pthread_create(&t_rt, NULL, twind_rt_main, &d)) {
        fprintf(stderr, "afmtwind: cannot start threads\n");
        exit(1); /* threads may be running: no orderly way back */
    }
    double fs = cfg.sim.sample_rate_hz;
    fprintf(stderr,
            "afmtwind: %s, %s mode, %s integrator at %.6g MHz, block %lld samples (%.0f us), "
            "channels %s*, LCM %s\n",
            d.opt.config_path, twind_mode_name(d.opt.mode),
            afm_sim_integrator_name(afm_runner_sim(d.runner)), fs * 1e-6, block,
            (double)block / fs * 1e6, d.opt.prefix, d.opt.lcm_url ? d.opt.lcm_url : "default");
    twind_notify_ready();

    double t_start = twind_mono_now();
    twind_rtf_state rs = {0, 0, 0};
    long long last_beat = -1;
    int warned = 0;
    for (;;) {
        struct timespec one = {1, 0};
        int sig = sigtimedwait(&sigs, NULL, &one);
        if (!warned && d.rt_warn[0]) { /* the RT thread sets up its scheduling at start */
            fprintf(stderr, "afmtwind: warning: %s\n", d.rt_warn);
            warned = 1;
        }
        if (sig == SIGTERM || sig == SIGINT) {
            fprintf(stderr, "afmtwind: %s: stopping\n", sig == SIGTERM ? "SIGTERM" : "SIGINT");
            break;
        }
        if (sig == SIGHUP) {
            fprintf(stderr, "afmtwind: SIGHUP: reloading %s\n", d.opt.config_path);
            atomic_store(&d.reload, 1);
            continue;
        }
        char line[512];
        status_line(&d, &rs, line, sizeof line);
        if (!d.opt.quiet) fprintf(stderr, "afmtwind: %s\n", line);
        twind_notify_status(line);
        twind_snapshot s;
        twind_snap_read(&d, &s);
        if (s.heartbeat != last_beat) twind_notify_watchdog(); /* only while the loop turns */
        last_beat = s.heartbeat;
        if (d.opt.exit_after_s > 0 && twind_mono_now() - t_start >= d.opt.exit_after_s) {
            fprintf(stderr, "afmtwind: --exit-after %g s: stopping\n", d.opt.exit_after_s);
            break;
        }
    }
    twind_notify_stopping();
    atomic_store(&d.stop, 1);
    pthread_join(t_rt, NULL);
    pthread_join(t_pub, NULL);
    pthread_join(t_recv, NULL);
    {
        twind_cmd_item it;
        while (afm_spsc_pop(&d.cmd_q, &it)) /* commands that came too late */
            afm_runner_model_destroy(&it.model);
        char line[512];
        status_line(&d, &rs, line, sizeof line);
        fprintf(stderr, "afmtwind: final: %s\n", line);
    }
    rc = 0;
out:
    afm_io_destroy(&d.io);
    afm_spsc_destroy(&d.harm_q);
    afm_spsc_destroy(&d.samples_q);
    afm_spsc_destroy(&d.rtrej_q);
    afm_spsc_destroy(&d.trash_q);
    afm_spsc_destroy(&d.cmd_q);
    sem_destroy(&d.out_sem);
    afm_runner_destroy(&d.runner);
    return rc;
}
