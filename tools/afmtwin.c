/* SPDX-License-Identifier: MIT */
/* afmtwin.c -- entry point of the `afmtwin` tool: dispatches to one subcommand per job. */
#include "afmtwin_cmds.h"

#include <stdio.h>
#include <string.h>

#ifndef AFMTWIN_VERSION
#define AFMTWIN_VERSION "unknown"
#endif

typedef struct {
    const char *name;
    int (*run)(int argc, char **argv);
    const char *summary;
} command;

static const command commands[] = {
    {"modes", afm_cmd_modes, "eigenfrequencies, MAC, stiffness and effective mass of a model"},
    {"sweep", afm_cmd_sweep, "stepwise frequency sweep to steady state, with harmonics"},
    {"continue", afm_cmd_continue,
     "continuation of periodic orbits: branches, stability, LPC / PD / NS, period doubling"},
    {"map", afm_cmd_map,
     "map over two parameters (fe, Z, Ae) of settled orbits, lines on MPI ranks"},
    {"plan", afm_cmd_plan, "imaging / patterning point pairs from a map, ranked by jump margin"},
    {"approach", afm_cmd_approach, "approach / retract curve in Z: amplitude, phase, forces"},
    {"force-curve", afm_cmd_force_curve,
     "quasi-static force-distance curve: snap-in, adhesion, pull-off, contact slope"},
    {"plot", afm_cmd_plot,
     "gnuplot PNGs: sweep, approach, scan, continue, force-curve, map, trace, ..."},
    {"curve", afm_cmd_curve, "approach-style curve from a log of the daemon outputs"},
    {"scan", afm_cmd_scan, "image a sample with the reference controller: height, phase, force"},
    {"bench", afm_cmd_bench, "integrator speed and accuracy side by side"},
    {"bench-states", afm_cmd_bench_states,
     "integrator and chain cost per sample in every state, and of a Z change"},
    {"bench-fm", afm_cmd_bench_fm,
     "cost per sample of the internal FM control (PLL, self-excited) against AM"},
    {"bench-scheme", afm_cmd_bench_scheme,
     "which rt scheme afmtwind --scheme auto runs on each shipped config here"},
    {"thermal", afm_cmd_thermal,
     "thermal tune: PSD of the Brownian motion, eq. 5.1 fit of f, Q, k"},
    {"send", afm_cmd_send, "publish one command to the daemon (validated as the daemon does)"},
    {"listen", afm_cmd_listen, "print what the daemon publishes (samples, harmonics, status)"},
    {"replay", afm_cmd_replay, "run the commands of an LCM log in model time, outputs to a log"},
    {"lockstep", afm_cmd_lockstep,
     "co-simulate: a command log against a lockstep daemon, checked against replay"},
    {"bench-daemon", afm_cmd_bench_daemon, "real-time factor and command latency of afmtwind"},
    {"soak", afm_cmd_soak, "bounded random command soak of a real-time afmtwind, with checks"},
    {"can-send", afm_cmd_can_send, "encode a command into CAN frames (cansend format), send them"},
    {"flood", afm_cmd_flood, "a bounded junk flood on the command channels (robustness tests)"},
};

static void usage(FILE *f) {
    fprintf(f, "usage: afmtwin COMMAND [OPTIONS]\n\n"
               "A digital twin of a tapping-mode AFM cantilever (see README.md).\n\ncommands:\n");
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        fprintf(f, "  %-12s %s\n", commands[i].name, commands[i].summary);
    fprintf(f, "  help         this text\n  --version    the version\n\n"
               "`afmtwin COMMAND --help` describes every option.\n");
}

int main(int argc, char **argv) {
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    if (!strcmp(argv[1], "help") || !strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
        usage(stdout);
        return 0;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("afmtwin %s\n", AFMTWIN_VERSION);
        return 0;
    }
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        if (!strcmp(argv[1], commands[i].name)) return commands[i].run(argc - 1, argv + 1);
    fprintf(stderr, "afmtwin: unknown command '%s'\n", argv[1]);
    usage(stderr);
    return 2;
}
