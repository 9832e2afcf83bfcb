/* SPDX-License-Identifier: MIT */
/* twind_opts.c -- the daemon's command line: its --help text and its option table, parsed
 * by the parser afmtwin's tools use (cli/afm_opts.h), so that a bad value is refused in the
 * same words (exit 2). Kept apart from afmtwind.c's start-up so that main reads as the
 * start-up order. */
#include "twind.h"

#include "cli/afm_opts.h"

#include <stdio.h>
#include <stdlib.h>

#ifndef AFMTWIN_VERSION
#define AFMTWIN_VERSION "unknown"
#endif

static void usage(FILE *f) {
    fprintf(f,
            "usage: afmtwind --config FILE [options]\n"
            "\n"
            "Runs the AFM cantilever twin and talks LCM: commands on PREFIX{DITHER,SETPOINT,\n"
            "PARAM,CONTROL,TICK,SCAN} (--lcm-url), outputs on PREFIX{HARMONICS,STATUS,\n"
            "TICK_DONE} (--lcm-out-url: by default the same udpm group, port + 1) and the\n"
            "sample stream PREFIXSAMPLES (--lcm-samples-url: port + 2). Every output message\n"
            "carries msg_seq (per channel, +1 each). Foreground; one status line a second\n"
            "on stderr. SIGTERM/SIGINT stop (a final status is published), SIGHUP reloads\n"
            "FILE (a bad file keeps the running config).\n"
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
            "  --applied-log FILE     write every command the twin applied, stamped with the\n"
            "                         sample it applied at, and the scheme in force, to the\n"
            "                         LCM log FILE: `afmtwin replay --applied --in FILE`\n"
            "                         gives this run's outputs bit for bit (a log of arrival\n"
            "                         times cannot: commands apply at the next ring item)\n"
            "  --help                 this text\n"
            "  --version              the version\n");
}

/* --mode and --scheme: the words into the enums (AFMT_CHOICE stores an int). */
_Static_assert(sizeof(twind_mode) == sizeof(int), "--mode is stored as an int");
_Static_assert(sizeof(twind_scheme) == sizeof(int), "--scheme is stored as an int");
static const afmt_choice mode_choices[] = {{"realtime", TWIND_REALTIME},
                                           {"freerun", TWIND_FREERUN},
                                           {"lockstep", TWIND_LOCKSTEP},
                                           {NULL, 0}};
static const afmt_choice scheme_choices[] = {{"auto", TWIND_SCHEME_AUTO},
                                             {"adaptive", TWIND_SCHEME_ADAPTIVE},
                                             {"accurate", TWIND_SCHEME_ACCURATE},
                                             {"fast", TWIND_SCHEME_FAST},
                                             {NULL, 0}};

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
    /* the options given in other units than the fields' (ms, us), and the flags as bools */
    double max_lag_ms = o->max_lag_s * 1e3, ring_us = o->ring_s * 1e6, block_us = o->block_s * 1e6,
           batch_us = o->batch_s * 1e6;
    bool quiet = false, a0_track = false, version = false;
    const afmt_opt opts[] = {
        AFMT_STRING("--config", &o->config_path),
        AFMT_STRING("--lcm-url", &o->lcm_url),
        AFMT_STRING("--lcm-out-url", &o->lcm_out_url),
        AFMT_STRING("--lcm-samples-url", &o->lcm_samples_url),
        AFMT_STRING("--prefix", &o->prefix),
        AFMT_CHOICE("--mode", &o->mode, mode_choices),
        AFMT_CHOICE("--scheme", &o->scheme, scheme_choices),
        AFMT_INT("--cpu", &o->cpu, 0, 1023, NULL),
        AFMT_INT("--chain-cpu", &o->chain_cpu, 0, 1023, NULL),
        AFMT_INT("--aux-cpu", &o->aux_cpu, 0, 1023, NULL),
        AFMT_INT("--rt-priority", &o->rt_priority, 1, 99, NULL),
        AFMT_INT("--lcm-priority", &o->lcm_priority, 1, 99, NULL),
        AFMT_DOUBLE("--block-us", &block_us, 10, 1e6, NULL),
        AFMT_DOUBLE("--batch-us", &batch_us, 0, 1e5, NULL),
        AFMT_DOUBLE("--speed", &o->speed, 1e-3, 1e3, NULL),
        AFMT_DOUBLE("--max-lag-ms", &max_lag_ms, 1, 1e6, NULL),
        AFMT_DOUBLE("--ring-us", &ring_us, 100, 1e6, NULL),
        AFMT_INT("--harmonics-every", &o->harmonics_every, 1, 1e9, NULL),
        AFMT_DOUBLE("--harmonics-max-hz", &o->harmonics_max_hz, 1e-3, 1e9, NULL),
        AFMT_DOUBLE("--start-time", &o->start_s, 0, 1e9, NULL),
        AFMT_DOUBLE("--exit-after", &o->exit_after_s, 0, 1e9, NULL),
        AFMT_FLAG("--quiet", &quiet),
        AFMT_STRING("--applied-log", &o->applied_log),
        AFMT_FLAG("--a0-track", &a0_track),
        AFMT_FLAG("--version", &version),
        AFMT_OPTS_END,
    };
    int rc = afm_opts_parse("afmtwind", opts, argc, argv, 1);
    if (rc == AFMT_OPTS_HELP) {
        usage(stdout);
        exit(0);
    }
    if (rc != AFMT_OPTS_OK) return -1;
    if (version) {
        printf("afmtwind %s\n", AFMTWIN_VERSION);
        exit(0);
    }
    o->quiet = quiet;
    o->a0_track = a0_track;
    o->max_lag_s = max_lag_ms * 1e-3;
    o->ring_s = ring_us * 1e-6;
    o->block_s = block_us * 1e-6;
    o->batch_s = batch_us * 1e-6;
    if (!o->config_path) {
        fprintf(stderr, "afmtwind: --config FILE is required (see --help)\n");
        return -1;
    }
    return 0;
}
