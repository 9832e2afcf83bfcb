/* SPDX-License-Identifier: MIT */
/* twind_opts.c -- the daemon's command line: its --help text and the parser that fills
 * twind_opts, each value range-checked with a message naming the option (exit 2 on a bad
 * one). Kept apart from afmtwind.c's start-up so that main reads as the start-up order. */
#include "twind.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef AFMTWIN_VERSION
#define AFMTWIN_VERSION "unknown"
#endif

static void usage(FILE *f) {
    fprintf(f,
            "usage: afmtwind --config FILE [options]\n"
            "\n"
            "Runs the AFM cantilever twin and talks LCM: commands on PREFIX{DITHER,SETPOINT,\n"
            "PARAM,CONTROL,TICK} (--lcm-url), outputs on PREFIX{HARMONICS,STATUS,TICK_DONE}\n"
            "(--lcm-out-url: by default the same udpm group, port + 1) and the sample\n"
            "stream PREFIX SAMPLES (--lcm-samples-url: port + 2). Every output message\n"
            "carries msg_seq (per channel, +1 each). Foreground;\n"
            "one status line a second on stderr. SIGTERM/SIGINT stop (a final status is\n"
            "published), SIGHUP reloads FILE (a bad file keeps the running config).\n"
            "\n"
            "options:\n"
            "  --config FILE          twin configuration (libconfig), required\n"
            "  --lcm-url URL          LCM URL of the commands (default: $LCM_DEFAULT_URL or\n"
            "                         udpm://239.255.76.67:7667?ttl=0)\n"
            "  --lcm-out-url URL      LCM URL of the outputs (default: --lcm-url with the udpm\n"
            "                         port + 1, so that the command socket carries commands only)\n"
            "  --lcm-samples-url URL  LCM URL of the sample stream (default: --lcm-url with the\n"
            "                         udpm port + 2, so that status and harmonics subscribers\n"
            "                         do not receive it)\n"
            "  --mode M               realtime (default), freerun or lockstep\n"
            "  --scheme S             the rt integrator's scheme (docs/realtime.md): auto (the\n"
            "                         default unless the config's sim.rt_scheme names one):\n"
            "                         both measured on this model before real time starts,\n"
            "                         accurate where its worst state fits 90%% of the budget,\n"
            "                         else fast; adaptive: accurate, handed over to fast while\n"
            "                         the loop falls behind and back when the margin returns;\n"
            "                         accurate or fast: forced (real time may be lost)\n"
            "  --prefix NAME_         channel prefix (default AFMTWIN_)\n"
            "  --cpu N                pin the integrator thread to CPU N\n"
            "  --chain-cpu N          pin the output-chain thread to CPU N\n"
            "  --aux-cpu N            pin the receive and publish threads (and LCM's) to CPU N\n"
            "                         (lockstep co-simulation on two cores: --cpu 0 --chain-cpu 1\n"
            "                         --aux-cpu 0, the controller on CPU 0: README)\n"
            "  --rt-priority N        SCHED_FIFO priority 1..99 (default 80)\n"
            "  --lcm-priority N       SCHED_FIFO priority of LCM's receive thread, which wakes\n"
            "                         for every datagram (default --rt-priority - 10, the\n"
            "                         receive thread's; below the output chain's (- 20) it\n"
            "                         preempts the chain less under a command stream but\n"
            "                         starves, and the socket drops commands, whenever the\n"
            "                         chain is behind)\n"
            "  --block-us N           real-time block length in microseconds (default 1000)\n"
            "  --batch-us N           realtime and freerun: while messages keep coming, the\n"
            "                         receive thread takes them in batches, waking at most\n"
            "                         every N us (default 250; 0: each as it arrives, one\n"
            "                         wake-up per message; lockstep: always 0)\n"
            "  --speed X              realtime: model seconds per wall second (default 1)\n"
            "  --max-lag-ms N         realtime: when the lag passes N ms the backlog is\n"
            "                         dropped and counted as a resync (default 100)\n"
            "  --ring-us N            buffer between integrator and output chain, in model\n"
            "                         microseconds (default 5000)\n"
            "  --harmonics-every K    publish every K-th period's harmonics (default: auto,\n"
            "                         at most --harmonics-max-hz records a second)\n"
            "  --harmonics-max-hz F   cap for the automatic choice (default 1000)\n"
            "  --exit-after S         stop after S seconds, as on SIGTERM (tests)\n"
            "  --start-time S         model time starts at S s instead of 0 (tests of a twin\n"
            "                         that has been up that long)\n"
            "  --quiet                no status line\n"
            "  --a0-track             recompute the status's A0 (free_amplitude_m) on a worker\n"
            "                         thread after each change of tone 0 or of the model;\n"
            "                         without it A0 is the start-up (or reloaded) config's and\n"
            "                         reads NaN once the drive differs. Its computations take\n"
            "                         ~5 %% of real time in the second they run\n"
            "  --help                 this text\n"
            "  --version              the version\n");
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

int twind_parse_args(int argc, char **argv, twind_opts *o) {
    *o = (twind_opts){.prefix = "AFMTWIN_",
                      .mode = TWIND_REALTIME,
                      .cpu = -1,
                      .chain_cpu = -1,
                      .aux_cpu = -1,
                      .rt_priority = 80,
                      .block_s = 1e-3,
                      .harmonics_max_hz = 1000.0,
                      .speed = 1.0,
                      .max_lag_s = 0.1,
                      .ring_s = 5e-3,
                      .batch_s = 250e-6};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        double x;
        if (!strcmp(a, "--help")) {
            usage(stdout);
            exit(0);
        } else if (!strcmp(a, "--version")) {
            printf("afmtwind %s\n", AFMTWIN_VERSION);
            exit(0);
        } else if (!strcmp(a, "--quiet")) {
            o->quiet = 1;
            continue;
        } else if (!strcmp(a, "--a0-track")) {
            o->a0_track = 1;
            continue;
        } else if (!v) {
            fprintf(stderr, "afmtwind: unknown option or missing value: %s\n", a);
            return -1;
        } else if (!strcmp(a, "--config")) {
            o->config_path = v;
        } else if (!strcmp(a, "--lcm-url")) {
            o->lcm_url = v;
        } else if (!strcmp(a, "--lcm-out-url")) {
            o->lcm_out_url = v;
        } else if (!strcmp(a, "--lcm-samples-url")) {
            o->lcm_samples_url = v;
        } else if (!strcmp(a, "--aux-cpu")) {
            if (parse_num(a, v, 0, 1023, &x) || x != floor(x)) return -1;
            o->aux_cpu = (int)x;
        } else if (!strcmp(a, "--chain-cpu")) {
            if (parse_num(a, v, 0, 1023, &x) || x != floor(x)) return -1;
            o->chain_cpu = (int)x;
        } else if (!strcmp(a, "--speed")) {
            if (parse_num(a, v, 1e-3, 1e3, &x)) return -1;
            o->speed = x;
        } else if (!strcmp(a, "--max-lag-ms")) {
            if (parse_num(a, v, 1, 1e6, &x)) return -1;
            o->max_lag_s = x * 1e-3;
        } else if (!strcmp(a, "--ring-us")) {
            if (parse_num(a, v, 100, 1e6, &x)) return -1;
            o->ring_s = x * 1e-6;
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
                fprintf(stderr,
                        "afmtwind: --mode must be realtime, freerun or lockstep, got '%s'\n", v);
                return -1;
            }
        } else if (!strcmp(a, "--scheme")) {
            if (!strcmp(v, "auto"))
                o->scheme = TWIND_SCHEME_AUTO;
            else if (!strcmp(v, "adaptive"))
                o->scheme = TWIND_SCHEME_ADAPTIVE;
            else if (!strcmp(v, "accurate"))
                o->scheme = TWIND_SCHEME_ACCURATE;
            else if (!strcmp(v, "fast"))
                o->scheme = TWIND_SCHEME_FAST;
            else {
                fprintf(stderr,
                        "afmtwind: --scheme must be auto, adaptive, accurate or fast, got '%s'\n",
                        v);
                return -1;
            }
        } else if (!strcmp(a, "--cpu")) {
            if (parse_num(a, v, 0, 1023, &x) || x != floor(x)) return -1;
            o->cpu = (int)x;
        } else if (!strcmp(a, "--rt-priority")) {
            if (parse_num(a, v, 1, 99, &x) || x != floor(x)) return -1;
            o->rt_priority = (int)x;
        } else if (!strcmp(a, "--lcm-priority")) {
            if (parse_num(a, v, 1, 99, &x) || x != floor(x)) return -1;
            o->lcm_priority = (int)x;
        } else if (!strcmp(a, "--block-us")) {
            if (parse_num(a, v, 10, 1e6, &x)) return -1;
            o->block_s = x * 1e-6;
        } else if (!strcmp(a, "--batch-us")) {
            if (parse_num(a, v, 0, 1e5, &x)) return -1;
            o->batch_s = x * 1e-6;
        } else if (!strcmp(a, "--harmonics-every")) {
            if (parse_num(a, v, 1, 1e9, &x) || x != floor(x)) return -1;
            o->harmonics_every = (int)x;
        } else if (!strcmp(a, "--harmonics-max-hz")) {
            if (parse_num(a, v, 1e-3, 1e9, &x)) return -1;
            o->harmonics_max_hz = x;
        } else if (!strcmp(a, "--start-time")) {
            if (parse_num(a, v, 0, 1e9, &x)) return -1;
            o->start_s = x;
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
